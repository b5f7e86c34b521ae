"""What calling rbsm from Python costs over the Rust run, on a 10⁴-element scene.

    python python/benches/overhead.py        # writes python/benches/overhead.md

A 100 × 100 rigid grid (element-wise), 2000 steps. Each round, interleaved:
- `rbsm.run(scene, steps=...)`: the wall time of the Python call, against the run's own
  `wall_time_s` (setup and stepping, measured inside Rust): the difference is what Python adds
  (reading the scene, building the numpy arrays, the result objects);
- the same run through the command line (`rbsm run --out DIR`, a new process that writes its
  files), for scale.
Medians of the rounds, with their range.
"""

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rbsm

ROOT = Path(__file__).resolve().parents[2]
ROUNDS = 7
STEPS = 2000
SCENE = {
    "name": "grid_10k",
    "thickness": 0.1,
    "formulation": {"kind": "rigid"},
    "evaluator": "element-wise",
    "materials": {"c": {"E": 3.0e10, "nu": 0.2, "rho": 2400.0}},
    "bodies": [
        {
            "name": "plate",
            "material": "c",
            "mesh": {"kind": "grid", "origin": [0, 0], "size": [10.0, 10.0], "cells": [100, 100]},
            "supports": [{"edge": "left", "kind": "ground-spring"}],
            "loads": [{"kind": "traction", "edge": "right", "value": [0.0, -1.0e5]}],
        }
    ],
    "time": {"dt_factor": 0.9, "steps": STEPS},
    "output": {"every": 100, "probes": [{"name": "tip_v", "at": [9.95, 5.0], "dof": "v"}]},
}


def spread(x):
    return f"{statistics.median(x):.4f} ({min(x):.4f}–{max(x):.4f})"


def main():
    binary = ROOT / "target" / "release" / "rbsm"
    if not binary.exists():
        subprocess.run(["cargo", "build", "--release", "--bin", "rbsm"], cwd=ROOT, check=True)
    rows = {"python": [], "rust": [], "overhead": [], "scene": [], "cli": []}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "grid_10k.json"
        path.write_text(json.dumps(SCENE))
        rbsm.run(path, steps=10)  # warm the caches and the thread pool
        for _ in range(ROUNDS):
            t0 = time.perf_counter()
            scene = rbsm.Scene(SCENE)
            t1 = time.perf_counter()
            r = rbsm.run(scene, steps=STEPS)
            t2 = time.perf_counter()
            rows["scene"].append(t1 - t0)
            rows["python"].append(t2 - t0)
            rows["rust"].append(r.summary["wall_time_s"])
            rows["overhead"].append((t2 - t0) - r.summary["wall_time_s"])
            t0 = time.perf_counter()
            subprocess.run(
                [str(binary), "--quiet", "run", str(path), "--out", str(Path(tmp) / "out")],
                check=True,
            )
            rows["cli"].append(time.perf_counter() - t0)
    elements = r.U.shape[0]
    over = statistics.median(rows["overhead"])
    text = f"""# The cost of the Python call

Regenerate with `python python/benches/overhead.py` (the package installed: `pip install ./python`).

A {elements}-element rigid grid (element-wise, {STEPS} steps, a history row every 100 steps),
{ROUNDS} rounds interleaved; times in seconds, median (range).

| what | s |
|---|---:|
| `rbsm.Scene(dict)` + `rbsm.run(scene)`, the whole Python call | {spread(rows["python"])} |
| the run inside Rust (`summary["wall_time_s"]`: setup and stepping) | {spread(rows["rust"])} |
| what Python adds (the call less the run inside Rust) | {spread(rows["overhead"])} |
| of which reading and validating the scene (`rbsm.Scene(dict)`) | {spread(rows["scene"])} |
| the command line, `rbsm run --out DIR` (a new process; writes its files) | {spread(rows["cli"])} |

Python adds {over * 1e3:.1f} ms to a run of {statistics.median(rows["rust"]):.3f} s
({over / statistics.median(rows["rust"]):.1%}): the scene is read twice (once to validate it in
`rbsm.Scene`, once by the run), and `U`, `V`, the centroids and the history become numpy arrays.
"""
    out = Path(__file__).with_name("overhead.md")
    out.write_text(text)
    print(text)
    print("wrote", out, file=sys.stderr)


if __name__ == "__main__":
    main()

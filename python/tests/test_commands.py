"""The commands from Python equal the command line's to the bit, refuse bad scenes with the
key, release the GIL, and stop on Ctrl-C with the run up to there."""

import csv
import json
import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import rbsm


def cli_json(cli, *args):
    out = subprocess.run([str(cli), "--json", "--quiet", *map(str, args)], capture_output=True)
    return out.returncode, json.loads(out.stdout)


def read_history(path: Path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


@pytest.mark.parametrize(
    "name, steps",
    [("cantilever.json", 3000), ("cantilever_hybrid.json", 1500), ("tension_bar.json", 2000)],
)
def test_run_equals_the_command_line_to_the_bit(cli, scenes, tmp_path, name, steps):
    scene = scenes / name
    code, summary = cli_json(cli, "run", scene, "--out", tmp_path / "cli", "--steps", steps)
    assert code == 0, summary
    r = rbsm.run(scene, steps=steps)
    assert r.status == "ok" and r.summary["steps"] == summary["steps"] == steps
    header, rows = read_history(tmp_path / "cli" / "history.csv")
    assert list(r.history) == header
    got = np.column_stack([r.history[c] for c in header])
    assert got.shape == rows.shape
    assert np.array_equal(got, rows), "the history differs from the command line's"
    state = json.loads((tmp_path / "cli" / "final_state.json").read_text())
    assert np.array_equal(r.U, np.array([e["U"] for e in state["elements"]]))
    assert np.array_equal(r.V, np.array([e["V"] for e in state["elements"]]))
    assert np.array_equal(r.centroids, np.array([e["centroid"] for e in state["elements"]]))
    assert r.t == state["t"]
    assert (r.interfaces is None) == ("interfaces" not in state)
    if r.interfaces is not None:
        assert r.interfaces == state["interfaces"]
    for key in ("dt", "dt_crit", "dt_safe", "energy", "elements", "dofs", "failure"):
        assert r.summary.get(key) == summary.get(key), key
    # Written files, when asked for, are the command line's byte for byte (the summary holds
    # timings, so it is compared above by its figures).
    rbsm.run(scene, steps=steps, out=tmp_path / "py")
    for f in ("history.csv", "final_state.json"):
        assert (tmp_path / "py" / f).read_bytes() == (tmp_path / "cli" / f).read_bytes(), f


def test_run_writes_nothing_unless_asked(scenes, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    # The bar pulse asks for VTK frames: without `out` none is written.
    rbsm.run(scenes / "bar_pulse.json", steps=50)
    assert list(tmp_path.iterdir()) == []


def test_options_equal_the_command_line(cli, scenes, tmp_path):
    scene = scenes / "cantilever.json"
    code, summary = cli_json(
        cli, "run", scene, "--out", tmp_path, "--steps", 400, "--dt-factor", 0.5,
        "--evaluator", "assembled",
    )
    assert code == 0
    r = rbsm.run(scene, steps=400, dt_factor=0.5, evaluator="assembled")
    assert r.summary["evaluator"] == summary["evaluator"] == "assembled"
    assert r.summary["dt"] == summary["dt"]
    state = json.loads((tmp_path / "final_state.json").read_text())
    assert np.array_equal(r.U, np.array([e["U"] for e in state["elements"]]))


def test_eigen_static_stability_and_check_equal_the_command_line(cli, scenes):
    scene = scenes / "cantilever.json"
    _, e = cli_json(cli, "eigen", scene, "--modes", 4)
    r = rbsm.eigen(scene, modes=4)
    assert list(r.frequencies_hz) == e["frequencies_hz"]
    assert r.omega_max == e["omega_max"] and r.dt_crit == e["dt_crit"]
    assert r.shapes.shape == (4, 640, 3)
    # M-normalised shapes: φᵀ M φ = 1 is the library's; here they are at least not zero.
    assert np.all(np.abs(r.shapes).reshape(4, -1).max(axis=1) > 0)
    _, s = cli_json(cli, "static", scene)
    st = rbsm.static(scene)
    assert st.energy == s["energy"]
    assert np.array_equal(st.U, np.array([el["U"] for el in s["elements"]]))
    _, c = cli_json(cli, "check", scene)
    ch = rbsm.check(scene)
    assert ch.report == c and ch.dt_crit == c["dt_crit"]
    _, b = cli_json(cli, "stability", scene, "--fractions", "0.5,1.05", "--steps", 300)
    st = rbsm.stability(scene, fractions=[0.5, 1.05], steps=300)
    assert st.dt_crit == b["dt_crit"] and st.empirical_dt == b["empirical"]["dt"]
    assert [f["status"] for f in st.fractions] == [f["status"] for f in b["fractions"]]
    assert all(f["history"].shape[1] == 3 for f in st.fractions)


def test_effective_equals_the_command_line(cli, scenes):
    scene = scenes / "voronoi_panel.json"
    code, report = cli_json(cli, "effective", scene)
    assert code == 0, report
    r = rbsm.effective(scene)
    assert r == {**report, "seconds": r["seconds"]}
    assert r["material"] == [2.0e10, 0.25] and 0.0 < r["poisson"] < 0.25


def test_effective_of_the_poisson_corrected_cells(scenes):
    # The same 400 cells with the `rigid-poisson` formulation keep the rock's ν.
    r = rbsm.effective(scenes / "voronoi_panel_poisson.json")
    assert abs(r["poisson"] / 0.25 - 1) < 0.02 and abs(r["young"] / 2.0e10 - 1) < 0.02


def test_limit_equals_the_command_line(cli, scenes, tmp_path):
    scene = scenes / "squeeze.json"
    code, report = cli_json(cli, "limit", scene)
    assert code == 0, report
    r = rbsm.limit(scene, out=tmp_path / "limit")
    assert r.report == {**report, "seconds": r.report["seconds"]}
    # The squeeze's closed form, 2 c over its 0.5 m width (c = 1e5 Pa).
    assert abs(r.collapse - 1e5) < 1e-6 * 1e5
    assert r.velocities.shape == (r.centroids.shape[0], 3)
    assert r.tractions.shape[1:] == (2, 2)
    assert (tmp_path / "limit" / "mechanism.vtu").exists()
    with pytest.raises(ValueError, match="on"):
        rbsm.limit(scene, on="wind")
    with pytest.raises(ValueError, match="points"):
        rbsm.limit(scene, points="middle")
    # Rigid: no strain rates, no element stresses.
    assert r.strain_rates.shape == (0, 3) and r.stresses.shape == (0, 3)


def test_limit_of_plastic_hybrid_elements_equals_the_command_line(cli, scenes):
    scene = scenes / "footing_hybrid.json"
    for points in ["gauss", "ends"]:
        code, report = cli_json(cli, "limit", scene, "--points", points)
        assert code == 0, report
        r = rbsm.limit(scene, points=points)
        assert r.report == {**report, "seconds": r.report["seconds"]}
        n = r.centroids.shape[0]
        assert r.report["yielding_elements"] == n
        assert r.strain_rates.shape == (n, 3) and r.stresses.shape == (n, 3)
        # Every element's stress at collapse lies inside Tresca's circle, R <= c.
        s = r.stresses
        radius = np.hypot(0.5 * (s[:, 0] - s[:, 1]), s[:, 2])
        assert radius.max() <= 1e5 * (1 + 1e-6)


def test_scenes_from_a_dict_a_string_and_a_file_are_the_same(scenes):
    path = scenes / "cantilever.json"
    text = path.read_text()
    a = rbsm.run(path, steps=200)
    b = rbsm.run(rbsm.Scene(json.loads(text)), steps=200)
    c = rbsm.run(rbsm.Scene.from_json(text), steps=200)
    assert np.array_equal(a.U, b.U) and np.array_equal(a.U, c.U)


def bad_scene(scenes):
    scene = json.loads((scenes / "cantilever.json").read_text())
    scene["materials"][next(iter(scene["materials"]))]["nu"] = 0.7
    return scene


def test_a_bad_scene_raises_with_the_key_and_the_command_lines_message(cli, scenes, tmp_path):
    scene = bad_scene(scenes)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(scene))
    code, out = cli_json(cli, "check", path)
    assert code == 1
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.Scene(scene)
    e = err.value
    assert (e.kind, e.key, e.message) == (
        out["error"]["kind"],
        out["error"]["key"],
        out["error"]["message"],
    )
    assert e.key.endswith(".nu") and isinstance(e, ValueError)
    # A file's parse error names the file, as the command line does.
    broken = tmp_path / "broken.json"
    broken.write_text('{"name": ')
    code, out = cli_json(cli, "check", broken)
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.Scene(broken)
    assert err.value.key == out["error"]["key"] == str(broken)
    assert err.value.message == out["error"]["message"]


def test_bad_options_raise_with_their_name(scenes):
    scene = scenes / "cantilever.json"
    for kwargs, key in [
        ({"evaluator": "fast"}, "evaluator"),
        ({"dt": 1e-6, "dt_factor": 0.5}, "dt"),
        ({"threads": 0}, "threads"),
        ({"steps": 0}, "--steps"),
        # Negative counts: named, not Python's OverflowError.
        ({"threads": -1}, "threads"),
        ({"steps": -1}, "steps"),
    ]:
        with pytest.raises(rbsm.SceneError) as err:
            rbsm.run(scene, **kwargs)
        assert err.value.key == key, (kwargs, err.value)
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.eigen(scene, method="fastest")
    assert err.value.key == "method"
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.eigen(scene, modes=-1)
    assert err.value.key == "modes"
    for kwargs, key in [({"on": "wind"}, "on"), ({"points": "mid"}, "points")]:
        with pytest.raises(rbsm.SceneError) as err:
            rbsm.limit(scenes / "squeeze.json", **kwargs)
        assert err.value.key == key, (kwargs, err.value)
    with pytest.raises(rbsm.OutputError):
        rbsm.run(scene, steps=10, out="/proc/no/such/folder")


def test_results_do_not_depend_on_the_thread_count(scenes):
    scene = scenes / "voronoi_panel.json"
    one = rbsm.run(scene, steps=300, threads=1)
    two = rbsm.run(scene, steps=300, threads=2)
    assert np.array_equal(one.U, two.U)
    assert one.summary["threads"] == 1 and two.summary["threads"] == 2


def test_the_gil_is_released_while_rust_computes(scenes):
    counted = []
    result = {}

    def work():
        result["r"] = rbsm.run(scenes / "cantilever.json", steps=60000, threads=1)

    t = threading.Thread(target=work)
    t.start()
    n = 0
    while t.is_alive():
        n += 1
        time.sleep(0)
    t.join()
    counted.append(n)
    wall = result["r"].summary["wall_time_s"]
    assert wall > 0.2, "the run is too short to tell"
    # With the GIL held by the run this thread could not have looped at all meanwhile.
    assert n > 1000, f"{n} iterations of Python during {wall:.2f} s of Rust"


def test_ctrl_c_stops_a_run_cleanly(scenes, tmp_path):
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    start = time.perf_counter()
    timer.start()
    with pytest.raises(rbsm.Interrupted) as err:
        rbsm.run(scenes / "cantilever.json", steps=10**8, out=tmp_path, threads=1)
    elapsed = time.perf_counter() - start
    assert isinstance(err.value, KeyboardInterrupt)
    r = err.value.result
    assert r.status == "interrupted" and 0 < r.summary["steps"] < 10**8
    assert elapsed < 5.0, f"stopped {elapsed:.1f} s after the start"
    # Complete outputs up to the step reached.
    state = json.loads((tmp_path / "final_state.json").read_text())
    assert np.array_equal(r.U, np.array([e["U"] for e in state["elements"]]))
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["steps"] == r.summary["steps"]


def test_polygons_follow_the_displacement(scenes):
    scene = scenes / "cantilever.json"
    still = rbsm.polygons(scene)
    assert len(still) == 640 and all(p.shape == (4, 2) for p in still)
    U = np.zeros((640, 3))
    U[:, 0] = 1e-3
    moved = rbsm.polygons(scene, U, scale=2.0)
    assert np.allclose(moved[7] - still[7], [[2e-3, 0.0]] * 4, rtol=0, atol=1e-15)
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.polygons(scene, np.zeros((3, 3)))
    assert err.value.key == "U"


def test_type_stubs_let_a_checker_find_a_wrong_call(tmp_path):
    import mypy.api as mypy
    good = tmp_path / "good.py"
    good.write_text(
        "import rbsm\n"
        "r = rbsm.run('s.json', steps=10, dt_factor=0.5)\n"
        "x: float = r.t\n"
        "e = rbsm.eigen('s.json', modes=3)\n"
        "f: float = float(e.frequencies_hz[0])\n"
    )
    bad = tmp_path / "bad.py"
    bad.write_text("import rbsm\nr = rbsm.run('s.json', steps='many')\ny: str = r.t\n")
    out, _, code = mypy.run([str(good), "--strict", "--ignore-missing-imports"])
    assert code == 0, out
    out, _, code = mypy.run([str(bad), "--ignore-missing-imports"])
    assert code == 1 and '"steps"' in out and "[arg-type]" in out and "[assignment]" in out, out


def misspelt_key(scenes):
    """The tension bar with `tensile_strength` misspelt, as a user might write it."""
    scene = json.loads((scenes / "tension_bar.json").read_text())
    law = scene["materials"]["concrete"]["interface"]
    law["tensile_strenght"] = law.pop("tensile_strength")
    return scene


def test_a_key_at_fault_is_named_by_its_json_path_from_a_dict_a_string_and_a_file(
    cli, scenes, tmp_path
):
    scene = misspelt_key(scenes)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(scene, indent=2))
    code, out = cli_json(cli, "check", path)
    assert code == 1
    key = "materials.concrete.interface.tensile_strenght"
    for source in (scene, json.dumps(scene), path):
        with pytest.raises(rbsm.SceneError) as err:
            rbsm.Scene(source)
        e = err.value
        assert (e.kind, e.key) == ("scene", key), source
        assert (e.kind, e.key, e.message) == (
            out["error"]["kind"],
            out["error"]["key"],
            out["error"]["message"],
        )
        # Named by its path, not by a line and column of text the user never saw (a dict).
        assert "line" not in str(e) and "`tensile_strength`" in e.message, str(e)
    # A key missing inside a kind is named by the path it should have.
    scene = json.loads((scenes / "cantilever.json").read_text())
    scene["formulation"] = {"kind": "hybrid"}
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.Scene(scene)
    assert err.value.key == "formulation.penalty"


def test_a_number_json_cannot_hold_is_named_by_its_json_path(scenes):
    scene = json.loads((scenes / "cantilever.json").read_text())
    scene["materials"]["concrete"]["E"] = float("nan")
    scene["bodies"][0]["loads"][0]["value"][1] = float("-inf")
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.Scene(scene)
    e = err.value
    assert (e.kind, e.key) == ("scene", "materials.concrete.E"), str(e)
    assert "finite" in e.message and "nan" in e.message, str(e)
    scene["materials"]["concrete"]["E"] = 3e10
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.Scene(scene)
    assert err.value.key == "bodies[0].loads[0].value[1]", str(err.value)


def test_an_input_file_that_cannot_be_read_is_a_scene_error(scenes, tmp_path):
    missing = tmp_path / "nope.json"
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.Scene(missing)
    e = err.value
    assert not isinstance(e, rbsm.OutputError)
    assert (e.kind, e.key) == ("io", str(missing)) and "No such file" in e.message
    for call in (rbsm.run, rbsm.check, rbsm.eigen):
        with pytest.raises(rbsm.SceneError) as err:
            call(missing)
        assert (err.value.kind, err.value.key) == ("io", str(missing))


def test_a_run_that_diverges_raises_with_its_step_time_and_reason(cli, scenes, tmp_path):
    scene = scenes / "cantilever.json"
    # 1e-4 s is about 25 times the cantilever's Δt_crit.
    code, _ = cli_json(cli, "run", scene, "--dt", "1e-4", "--steps", "400", "--out", tmp_path / "cli")
    assert code == 3
    summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    with pytest.raises(rbsm.DivergedError) as err:
        rbsm.run(scene, dt=1e-4, steps=400, out=tmp_path / "py")
    e = err.value
    assert e.result.status == "diverged" and e.result.reason == summary["reason"]
    assert summary["reason"] in str(e) and "energy" in e.reason
    assert summary["reason"].startswith(f"step {e.step}, t = ")
    assert summary["reason"].endswith(f" s: {e.reason}")
    assert 0 < e.step <= 400 and e.t == pytest.approx(e.step * 1e-4, rel=1e-12)
    assert np.all(np.isfinite(e.result.U))
    # Its files are written, as the command line's.
    assert json.loads((tmp_path / "py" / "summary.json").read_text())["reason"] == e.result.reason
    # Asked to warn, it returns the run with its reason.
    with pytest.warns(rbsm.DivergedWarning, match="diverged"):
        r = rbsm.run(scene, dt=1e-4, steps=400, on_diverge="warn")
    assert r.status == "diverged" and r.reason == e.result.reason
    assert rbsm.run(scene, steps=100).reason is None
    with pytest.raises(ValueError, match="on_diverge"):
        rbsm.run(scene, steps=10, on_diverge="ignore")


def read_vtu_lines(path):
    """The points of a crack frame and its `interface` and `interface_status` cell data (VTK
    XML, binary: base64 with a UInt64 byte count before each array)."""
    import base64
    import xml.etree.ElementTree as ET

    arrays = {}
    root = ET.parse(path).getroot()
    assert root.get("header_type") == "UInt64", root.attrib
    for a in root.iter("DataArray"):
        assert a.get("format") == "binary", a.attrib
        raw = base64.b64decode(a.text.strip())
        dtype = {"Float64": "<f8", "Int32": "<i4", "Int64": "<i8", "UInt64": "<u8", "UInt8": "u1"}[a.get("type")]
        arrays[a.get("Name") or "Points"] = np.frombuffer(raw[8:], dtype=dtype)
    return arrays


def test_interface_lines_are_the_crack_frames_lines(scenes, tmp_path):
    scene = json.loads((scenes / "tension_bar.json").read_text())
    scene["output"]["vtk"] = True
    r = rbsm.run(scene, out=tmp_path)
    lines = r.interface_lines
    n = len(r.interfaces)
    assert n > 0 and lines.ends.shape == (n, 2, 2) and lines.reference_ends.shape == (n, 2, 2)
    assert list(lines.index) == [i["interface"] for i in r.interfaces]
    assert [lines.STATUS[c] for c in lines.status] == [i["status"] for i in r.interfaces]
    for name in ("opening", "slip", "dissipated"):
        assert list(getattr(lines, name)) == [i[name] for i in r.interfaces], name
    # The bar cracked through: broken interfaces, counted as the summary counts them.
    failure = r.summary["failure"]
    assert (lines.status == lines.BROKEN).sum() == failure["broken"] > 0, failure
    assert (lines.status == lines.RELEASED).sum() == failure["released"]
    # The ends are where the last crack frame draws them.
    frames = sorted((tmp_path / "cracks").glob("step_*.vtu"))
    vtu = read_vtu_lines(frames[-1])
    points = vtu["Points"].reshape(-1, 3)[:, :2]
    assert np.array_equal(vtu["interface"], lines.index)
    assert np.array_equal(vtu["interface_status"], lines.status)
    assert np.allclose(points.reshape(n, 2, 2), lines.ends, rtol=0, atol=1e-15)
    # Pulled along x: the cracks opened, so their ends moved away from the reference.
    moved = np.abs(lines.ends - lines.reference_ends).max()
    assert 0 < moved < 0.01
    # A scene whose interfaces cannot fail has none.
    assert rbsm.run(scenes / "cantilever.json", steps=10).interface_lines is None

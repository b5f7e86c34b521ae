"""Sweeps: the same table on local processes, on a Dask cluster and from `rbsm tradeoff`;
failed points reported, killed workers survived, studies resumed."""

import json
import multiprocessing
import os
import signal
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

import rbsm

GRID = {"dt_factor": [0.9, 0.5], "refine": [1, 2]}
#: What a point computes; its costs are timings, which differ from run to run.
FIGURES = ["dt_factor", "refine", "elements", "dofs", "dt", "dt_crit", "steps", "status", "error"]


@pytest.fixture(scope="module")
def column(scenes):
    return rbsm.Scene(scenes / "column_step.json")


@pytest.fixture(scope="module")
def local(column):
    return rbsm.sweep(column, GRID, workers=2)


def test_a_local_sweep_equals_rbsm_tradeoff(cli, scenes, tmp_path, local):
    out = subprocess.run(
        [str(cli), "--json", "--quiet", "tradeoff", scenes / "column_step.json",
         "--sweep", "dt_factor=0.9,0.5", "--sweep", "refine=1,2", "--out", tmp_path],
        capture_output=True, check=True,
    )
    report = json.loads(out.stdout)
    assert isinstance(local, pd.DataFrame) and len(local) == 4
    assert local.attrs["reference"] == report["reference"]
    for row, p in zip(local.to_dict("records"), report["points"]):
        assert [row["dt_factor"], row["refine"]] == [float(p["settings"][0][1]), int(p["settings"][1][1])]
        # (`pareto` depends on the wall times, which differ from run to run.)
        for k in ("elements", "dofs", "dt", "dt_crit", "steps", "status", "error"):
            assert row[k] == p[k], k
        assert row["runs"] >= 1 and row["wall_min_s"] <= row["wall_s"] <= row["wall_max_s"]
    # The refined runs are more accurate against the closed form of the bar.
    assert local.error[1] < local.error[0] and local.error[3] < local.error[2]


def test_a_sweep_over_the_formulations(column):
    # The `formulation` key takes every kind a scene can name, `rigid-poisson` included.
    table = rbsm.sweep(column, {"formulation": ["rigid", "rigid-poisson"]}, workers=1)
    assert list(table.formulation) == ["rigid", "rigid-poisson"]
    assert list(table.status) == ["ok", "ok"]


def test_a_dask_sweep_equals_the_local_one(column, local, cluster):
    on_dask = rbsm.sweep(column, GRID, executor=cluster)
    pd.testing.assert_frame_equal(on_dask[FIGURES], local[FIGURES])


def test_a_list_of_records_without_pandas(column):
    records = rbsm.sweep(column, {"dt_factor": [0.5]}, as_frame=False, workers=1)
    assert isinstance(records, list) and records[0]["status"] == "ok"
    assert records[0]["reference"].startswith("closed form of the bar")


def test_a_failed_point_is_reported_and_the_others_are_kept(column):
    # A penalty of 1e300 makes ω⁴ overflow: the setup refuses it, on the worker.
    table = rbsm.sweep(column, {"penalty": [10, 1e300]}, workers=2)
    assert table.status[0] == "ok" and not np.isnan(table.dt[0])
    assert table.status[1].startswith("failed: SceneError") and np.isnan(table.dt[1])


def test_bad_keys_and_values_are_refused_before_any_point_runs(column):
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.sweep(column, {"speed": [1]})
    assert err.value.key == "--sweep" and "allowed: dt, dt_factor" in err.value.message
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.sweep(column, {"refine": [1, 0]})
    assert err.value.key == "--sweep refine"
    with pytest.raises(TypeError):
        rbsm.sweep(column, {"refine": 2})


def test_a_study_resumes_from_its_store(column, tmp_path):
    store = tmp_path / "study.jsonl"
    ran = []
    first = rbsm.sweep(column, {"dt_factor": [0.9, 0.5]}, store=store, progress=ran.append, workers=2)
    assert len(ran) == 2 and len(store.read_text().splitlines()) == 2
    ran.clear()
    second = rbsm.sweep(
        column, {"dt_factor": [0.9, 0.5, 0.25]}, store=store, progress=ran.append, workers=2
    )
    assert [r["settings"] for r in ran] == [[("dt_factor", "0.25")]]
    assert list(second.dt[:2]) == list(first.dt)
    assert second.status.tolist() == ["ok"] * 3
    # A store of another scene is refused.
    other = column.to_dict()
    other["name"] = "another"
    with pytest.raises(ValueError, match="another scene"):
        rbsm.sweep(rbsm.Scene(other), {"dt_factor": [0.5]}, store=store)


def kill_one(pids):
    """Kills the first of `pids` still alive, once; returns whether it did."""
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
            return True
        except ProcessLookupError:
            continue
    return False


def test_a_killed_local_worker_loses_no_point(column):
    killed = []
    # Processes of other tests (a Dask cluster's) are not the sweep's.
    others = {p.pid for p in multiprocessing.active_children()}

    def progress(_):
        if not killed:
            pool = [p.pid for p in multiprocessing.active_children() if p.pid not in others]
            killed.append(kill_one(pool))

    table = rbsm.sweep(column, {"dt_factor": [0.9, 0.7, 0.5, 0.3, 0.2, 0.1]}, progress=progress, workers=2)
    assert killed == [True]
    assert table.status.tolist() == ["ok"] * 6, table.status.tolist()


def test_a_killed_dask_worker_loses_no_point(column, cluster):
    before = cluster.run(os.getpid)
    killed = []

    def progress(_):
        if not killed:
            killed.append(kill_one(list(before.values())))

    grid = {"dt_factor": [0.9, 0.7, 0.5, 0.3, 0.2, 0.1]}
    table = rbsm.sweep(column, grid, executor=cluster, progress=progress)
    assert killed == [True]
    assert table.status.tolist() == ["ok"] * 6, table.status.tolist()
    # The nanny started a new worker in place of the killed one.
    cluster.wait_for_workers(2, timeout=60)
    assert set(cluster.run(os.getpid).values()) != set(before.values())


def test_a_sweep_whose_every_point_fails_raises_with_the_first_reason(column):
    # A penalty of 1e300 or more makes ω⁴ overflow: the setup refuses it on the worker.
    with pytest.raises(rbsm.SweepFailed) as err:
        rbsm.sweep(column, {"penalty": [1e300, 1e301]}, workers=2)
    e = err.value
    assert isinstance(e, RuntimeError) and len(e.failures) == 2
    assert [s for s, _ in e.failures] == [[("penalty", "1e+300")], [("penalty", "1e+301")]]
    assert all(why.startswith("SceneError") for _, why in e.failures)
    assert "every point of the sweep failed (2 of 2)" in str(e)
    assert "penalty=1e+300" in str(e) and e.failures[0][1] in str(e)
    assert "__main__" not in str(e)


def test_a_script_without_the_main_guard_fails_loudly(scenes, tmp_path):
    # Its spawned workers import it and die as they start: the sweep raises and says why.
    script = tmp_path / "unguarded.py"
    script.write_text(
        "import rbsm\n"
        f"scene = rbsm.Scene({str(scenes / 'column_step.json')!r})\n"
        "rbsm.sweep(scene, {'dt_factor': [0.5]}, workers=1)\n"
    )
    out = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600, cwd=tmp_path
    )
    assert out.returncode == 1, out.stderr[-2000:]
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith("rbsm.study.SweepFailed: every point of the sweep failed"), last
    assert "its worker process died 3 times" in last and 'if __name__ == "__main__":' in last

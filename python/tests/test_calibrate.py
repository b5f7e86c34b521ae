"""``rbsm.calibrate`` runs the command line's calibration, on local processes or on Dask, and
refuses a bad calibration file by its key."""

import json
import subprocess

import pytest

import rbsm

#: Squares, where the facets' strengths are the material's: a calibration of a few seconds.
SPEC = {
    "name": "squares",
    "rho": 2400,
    "width": 0.05,
    "targets": {
        "E": 3e10,
        "nu": 0.2,
        "tensile_strength": 3e6,
        "fracture_energy": 100,
        "compressive_strength": 3e7,
    },
    "cells": {"kind": "grid", "sizes": [0.0125, 0.01], "seeds": [1]},
}


def figures(report):
    """What a calibration computes (its timings differ from run to run)."""
    return report["material"], report["rounds"], report["sizes"], report["converged"]


@pytest.fixture(scope="module")
def local():
    return rbsm.calibrate(SPEC, workers=2)


def test_a_local_calibration_equals_rbsm_calibrate(cli, local, tmp_path):
    path = tmp_path / "squares.json"
    path.write_text(json.dumps(SPEC))
    out = subprocess.run(
        [str(cli), "--json", "--quiet", "calibrate", str(path)], capture_output=True, check=True
    )
    assert figures(json.loads(out.stdout)) == figures(local)
    law = local["material"]["interface"]
    assert law["kind"] == "facet"
    assert abs(law["tensile_strength"] / 3e6 - 1) < 1e-3


def test_a_dask_calibration_equals_the_local_one(local, cluster):
    assert figures(rbsm.calibrate(SPEC, executor=cluster)) == figures(local)


def test_the_calibrated_material_runs_in_a_scene(local, scenes):
    scene = json.loads((scenes / "tension_bar.json").read_text())
    scene["materials"] = {"squares": local["material"]}
    scene["bodies"][0]["material"] = "squares"
    scene["time"]["end"] = 1e-4
    r = rbsm.run(rbsm.Scene(scene, base_dir=scenes))
    assert r.summary["status"] == "ok"


def test_a_bad_target_is_refused_by_its_key():
    spec = json.loads(json.dumps(SPEC))
    spec["targets"]["fracture_energy"] = -1
    with pytest.raises(rbsm.SceneError, match="targets.fracture_energy"):
        rbsm.calibrate(spec)


def test_a_target_json_cannot_hold_is_refused_by_its_key():
    spec = json.loads(json.dumps(SPEC))
    spec["targets"]["tensile_strength"] = float("nan")
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.calibrate(spec)
    assert (err.value.kind, err.value.key) == ("scene", "targets.tensile_strength")


def test_a_calibration_file_that_cannot_be_read_is_a_scene_error(tmp_path):
    missing = tmp_path / "nope.json"
    with pytest.raises(rbsm.SceneError) as err:
        rbsm.calibrate(missing)
    e = err.value
    assert (e.kind, e.key) == ("io", str(missing)) and "No such file" in e.message, str(e)

"""Shared fixtures: the repository's scenes and the `rbsm` command line built from the same
library, which the package's results must equal to the bit."""

import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "examples" / "scenes"


@pytest.fixture(scope="session")
def cli() -> Path:
    """The release `rbsm` binary (built if it is not there yet)."""
    binary = ROOT / "target" / "release" / "rbsm"
    if not binary.exists():
        subprocess.run(
            ["cargo", "build", "--release", "--quiet", "--bin", "rbsm"], cwd=ROOT, check=True
        )
    return binary


@pytest.fixture(scope="session")
def scenes() -> Path:
    return SCENES


@pytest.fixture(scope="session")
def cluster():
    """A local Dask cluster of two worker processes (skipped without ``distributed``)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as c, distributed.Client(c) as client:
        yield client

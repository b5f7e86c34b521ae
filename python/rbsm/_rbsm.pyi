"""Type stubs of the Rust extension `rbsm._rbsm` (python/src/lib.rs). Use the wrappers of the
`rbsm` package; these are its low-level calls. A scene is passed as `(path, text, base_dir)`:
a file path, or JSON text with the folder its relative paths start from."""

from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

__version__: str

class SceneError(ValueError):
    kind: str
    key: str
    message: str

class OutputError(OSError):
    kind: str
    key: str
    message: str

def validate(path: Optional[str], text: Optional[str], base_dir: Optional[str]) -> str: ...
def run(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    out: Optional[str] = None,
    evaluator: Optional[str] = None,
    dt: Optional[float] = None,
    dt_factor: Optional[float] = None,
    steps: Optional[int] = None,
    exact_dt_crit: bool = False,
    resume: bool = False,
    threads: Optional[int] = None,
) -> Dict[str, Any]: ...
def static(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    out: Optional[str] = None,
    threads: Optional[int] = None,
) -> Dict[str, Any]: ...
def effective(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    threads: Optional[int] = None,
) -> str: ...
def limit(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    on: Optional[str] = None,
    points: str = "gauss",
    out: Optional[str] = None,
    threads: Optional[int] = None,
) -> Dict[str, Any]: ...
def eigen(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    modes: int = 10,
    method: str = "auto",
    out: Optional[str] = None,
    vtk: Optional[str] = None,
    svg: Optional[str] = None,
    threads: Optional[int] = None,
) -> Dict[str, Any]: ...
def stability(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    fractions: Sequence[float] = ...,
    steps: int = 2000,
    out: Optional[str] = None,
    threads: Optional[int] = None,
) -> Dict[str, Any]: ...
def check(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    evaluator: Optional[str] = None,
    dt: Optional[float] = None,
    threads: Optional[int] = None,
) -> str: ...
def study_check(key: str, value: str) -> None: ...
def calibration_next(spec: str, done: List[str]) -> str: ...
def calibration_job(spec: str, job: str, threads: Optional[int] = None) -> str: ...
def study_point(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    settings: Sequence[Tuple[str, str]],
    threads: Optional[int] = None,
) -> str: ...
def study_report(
    path: Optional[str], text: Optional[str], base_dir: Optional[str], points: List[str]
) -> str: ...
def polygons(
    path: Optional[str],
    text: Optional[str],
    base_dir: Optional[str],
    u: Optional[List[float]] = None,
    scale: float = 1.0,
) -> Tuple[np.ndarray, List[int]]: ...
def schema() -> str: ...

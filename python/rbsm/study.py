"""Studies: a scene run at every combination of a few settings, on local processes or on any
cluster a Dask ``distributed.Client`` reaches. Each point is one task holding the whole scene
(its JSON text), so a worker needs only the installed package; its errors and costs are those
of ``rbsm tradeoff``, scored once every point is in.
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import itertools
import json
import math
import multiprocessing
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

Done = Callable[[Dict[str, Any]], None]

from . import _rbsm

if TYPE_CHECKING:
    from . import Scene

Settings = List[Tuple[str, str]]

#: How often a point is tried again after its worker died before it is reported as failed.
RETRIES = 2

#: Why a point failed when its local worker process kept dying.
DIED = "its worker process died {} times"


class SweepFailed(RuntimeError):
    """Every point of a sweep failed: nothing was measured, so there is no table to return.
    ``failures`` lists each point's settings and why it failed, in sweep order."""

    def __init__(self, failures: List[Tuple[Settings, str]], local: bool) -> None:
        self.failures = failures
        settings, why = failures[0]
        shown = ", ".join(f"{k}={v}" for k, v in settings)
        message = (
            f"every point of the sweep failed ({len(failures)} of {len(failures)}); "
            f"the first ({shown}): {why}"
        )
        if local and all(w.startswith(DIED.split("{")[0]) for _, w in failures):
            message += (
                ". Local workers are spawned processes that import the main script: a script "
                "that calls rbsm.sweep at its top level needs `if __name__ == \"__main__\":` "
                "around that code, or its workers die as they start"
            )
        super().__init__(message)


def _failed(payload: Dict[str, Any], why: str) -> Dict[str, Any]:
    """The result of a point that failed: its settings and why."""
    return {"settings": payload["settings"], "measured": None, "failure": why}


def _point(payload: Dict[str, Any]) -> Dict[str, Any]:
    """One point, run on a worker: its measure (JSON) or why it failed. Never raises for a
    failure of the point itself, so that one bad point cannot stop a study."""
    settings = [tuple(p) for p in payload["settings"]]
    try:
        measured = _rbsm.study_point(
            None, payload["text"], payload["base_dir"], settings, threads=payload["threads"]
        )
        return {"settings": payload["settings"], "measured": measured, "failure": None}
    except Exception as e:  # noqa: BLE001 - reported in the table, not lost
        return _failed(payload, f"{type(e).__name__}: {e}")


def _text(value: Any) -> str:
    """A setting's value as ``rbsm tradeoff --sweep`` reads it (floats to the bit)."""
    return repr(value) if isinstance(value, float) else str(value)


def _combinations(grid: Mapping[str, Sequence[Any]]) -> List[Tuple[Settings, Dict[str, Any]]]:
    """Every combination of the grid's values, the first key varying slowest (as
    ``rbsm tradeoff``): the settings as text, and as given."""
    keys = list(grid)
    for k in keys:
        values = grid[k]
        if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
            raise TypeError(f"sweep key `{k}`: give a list of values, not {values!r}")
    out = []
    for combo in itertools.product(*(list(grid[k]) for k in keys)):
        out.append(([(k, _text(v)) for k, v in zip(keys, combo)], dict(zip(keys, combo))))
    return out


class _Store:
    """The points already done, one JSON line each, so that a study resumes where it stopped.
    A line names the scene by a hash of its text; a store of another scene is refused."""

    def __init__(self, path: Optional[Union[str, "os.PathLike[str]"]], scene_hash: str) -> None:
        self.path = None if path is None else Path(path)
        self.hash = scene_hash
        self.done: Dict[str, str] = {}
        if self.path is None or not self.path.exists():
            return
        for n, line in enumerate(self.path.read_text(encoding="utf-8").splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                # A line cut off by a crash: the point runs again.
                continue
            if rec.get("scene") != self.hash:
                raise ValueError(
                    f"{self.path}: line {n} belongs to a study of another scene; "
                    "give another store"
                )
            if rec.get("measured") is not None:
                self.done[_key(rec["settings"])] = rec["measured"]

    def add(self, result: Dict[str, Any]) -> None:
        if self.path is None or result["measured"] is None:
            return
        line = json.dumps({"scene": self.hash, **result})
        with open(self.path, "a", encoding="utf-8") as f:
            f.write(line + "\n")
            f.flush()
            os.fsync(f.fileno())


def _key(settings: Sequence[Sequence[str]]) -> str:
    return json.dumps([list(p) for p in settings])


def _is_dask_client(executor: Any) -> bool:
    return type(executor).__module__.startswith("distributed") and hasattr(
        executor, "scheduler_info"
    )


Task = Callable[[Dict[str, Any]], Dict[str, Any]]
Failed = Callable[[Dict[str, Any], str], Dict[str, Any]]


def _run_dask(
    client: Any, payloads: List[Dict[str, Any]], done: Done, task: Task, failed: Failed
) -> None:
    """Every payload on the cluster; a task whose worker died is run again by the scheduler
    (``distributed.scheduler.allowed-failures``); one that still fails is reported."""
    from distributed import as_completed

    futures = {client.submit(task, p, pure=False): p for p in payloads}
    _collect(futures, as_completed(list(futures)), done, failed)  # type: ignore[no-untyped-call]


def _run_local(
    payloads: List[Dict[str, Any]],
    workers: Optional[int],
    done: Done,
    task: Task,
    failed: Failed,
) -> None:
    """Every payload on local processes (spawned: scripts need the usual
    ``if __name__ == "__main__":``). A process that dies breaks the pool: the points it took
    with it run again in a new pool, each at most ``RETRIES`` more times."""
    tries = {id(p): 0 for p in payloads}
    left = list(payloads)
    context = multiprocessing.get_context("spawn")
    while left:
        broken = []
        with cf.ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
            futures = {pool.submit(task, p): p for p in left}
            for future in cf.as_completed(futures):
                payload = futures[future]
                try:
                    done(future.result())
                except cf.process.BrokenProcessPool:
                    broken.append(payload)
        left = []
        for p in broken:
            tries[id(p)] += 1
            if tries[id(p)] > RETRIES:
                done(failed(p, DIED.format(tries[id(p)])))
            else:
                left.append(p)


def _run_executor(
    executor: cf.Executor, payloads: List[Dict[str, Any]], done: Done, task: Task, failed: Failed
) -> None:
    futures = {executor.submit(task, p): p for p in payloads}
    _collect(futures, cf.as_completed(futures), done, failed)


def _run(
    executor: Any,
    payloads: List[Dict[str, Any]],
    workers: Optional[int],
    done: Done,
    task: Task,
    failed: Failed,
) -> None:
    """Every payload through ``task`` on local processes (``executor=None``), a Dask
    ``distributed.Client`` or a ``concurrent.futures.Executor``; each result to ``done``."""
    if not payloads:
        pass
    elif executor is None:
        _run_local(payloads, workers, done, task, failed)
    elif _is_dask_client(executor):
        _run_dask(executor, payloads, done, task, failed)
    elif isinstance(executor, cf.Executor):
        _run_executor(executor, payloads, done, task, failed)
    else:
        raise TypeError(
            "executor: give None (local processes), a dask distributed.Client or a "
            f"concurrent.futures.Executor, not {type(executor).__name__}"
        )


def _collect(
    futures: Dict[Any, Dict[str, Any]], finished: Iterable[Any], done: Done, failed: Failed
) -> None:
    """Hands each finished future's result to `done`; a future that raised (a task that could
    not run: KilledWorker and the like) is a failed point."""
    for future in finished:
        try:
            done(future.result())
        except Exception as e:  # noqa: BLE001 - reported in the table, not lost
            done(failed(futures[future], f"{type(e).__name__}: {e}"))


#: The columns of a study's table after the swept keys.
COLUMNS = (
    "elements",
    "dofs",
    "dt",
    "dt_crit",
    "steps",
    "setup_s",
    "stepping_s",
    "wall_s",
    "runs",
    "wall_min_s",
    "wall_max_s",
    "peak_mib",
    "status",
    "error",
    "pareto",
)


def sweep(
    scene: Any,
    grid: Mapping[str, Sequence[Any]],
    executor: Any = None,
    *,
    store: Optional[Union[str, "os.PathLike[str]"]] = None,
    threads: Optional[int] = 1,
    workers: Optional[int] = None,
    as_frame: Optional[bool] = None,
    progress: Optional[Callable[[Dict[str, Any]], None]] = None,
) -> Any:
    """Runs ``scene`` at every combination of ``grid`` (keys of ``rbsm tradeoff --sweep``:
    ``dt``, ``dt_factor``, ``refine``, ``formulation``, ``penalty``, ``evaluator``,
    ``contact``, ``seed``) and returns a table: one record per point, in sweep order, with
    the swept values, then ``elements``, ``dofs``, ``dt``, ``dt_crit``, ``steps``, the costs
    (``setup_s``, ``stepping_s``, ``wall_s``: medians of ``runs`` runs, with the range
    ``wall_min_s``–``wall_max_s``; ``peak_mib``), ``status``, ``error`` against the reference
    and ``pareto``.

    - ``executor=None``: local processes (``workers`` of them, all cores by default);
      a Dask ``distributed.Client``: its cluster; any ``concurrent.futures.Executor``: that.
    - ``threads``: Rust threads per point (1: the points run side by side).
    - ``store``: a file where each finished point is kept; calling again with the same store
      runs only the points not done yet.
    - A point that fails (a refused setting, a worker that died) is reported with status
      ``failed: <why>``, not lost; the others are scored without it. When every point fails
      there is nothing to score: :class:`SweepFailed` is raised, naming the first failure.
    - The table is a pandas DataFrame when pandas is installed (``as_frame=False``: a list of
      dicts, each with the ``reference`` and ``error_definition``); a DataFrame names them in
      its ``attrs``.
    """
    from . import Scene

    s = scene if isinstance(scene, Scene) else Scene(scene)
    text, base_dir = s.portable()
    scene_hash = hashlib.sha256(text.encode()).hexdigest()[:16]
    combos = _combinations(grid)
    for settings, _ in combos:
        for k, v in settings:
            # Refused here, naming the key, before any task leaves.
            _rbsm.study_check(k, v)
    saved = _Store(store, scene_hash)
    results: Dict[str, Dict[str, Any]] = {}
    for settings, _ in combos:
        k = _key(settings)
        if k in saved.done:
            results[k] = {"settings": settings, "measured": saved.done[k], "failure": None}
    payloads = [
        {"text": text, "base_dir": base_dir, "settings": settings, "threads": threads}
        for settings, _ in combos
        if _key(settings) not in results
    ]

    def done(result: Dict[str, Any]) -> None:
        results[_key(result["settings"])] = result
        saved.add(result)
        if progress is not None:
            progress(result)

    _run(executor, payloads, workers, done, _point, _failed)
    ordered = [results[_key(settings)] for settings, _ in combos]
    if ordered and all(r["measured"] is None for r in ordered):
        failures = [
            ([(str(k), str(v)) for k, v in r["settings"]], str(r["failure"])) for r in ordered
        ]
        raise SweepFailed(failures, local=executor is None)
    return _table(s, combos, results, as_frame)


def _table(
    scene: "Scene",
    combos: List[Tuple[Settings, Dict[str, Any]]],
    results: Dict[str, Dict[str, Any]],
    as_frame: Optional[bool],
) -> Any:
    ordered = [results[_key(settings)] for settings, _ in combos]
    measured = [r["measured"] for r in ordered if r["measured"] is not None]
    reference = definition = None
    points: List[Optional[Dict[str, Any]]] = []
    if measured:
        try:
            report = json.loads(_rbsm.study_report(*scene._source(), measured))
            reference, definition = report["reference"], report["error"]
            scored = iter(report["points"])
        except _rbsm.SceneError as e:
            # No reference (every run diverged): the points keep their figures, no error.
            definition = str(e)
            scored = iter(json.loads(m)["point"] for m in measured)
        points = [next(scored) if r["measured"] is not None else None for r in ordered]
    else:
        points = [None] * len(ordered)
    records = []
    for (settings, given), r, p in zip(combos, ordered, points or [None] * len(ordered)):
        rec: Dict[str, Any] = dict(given)
        if p is None:
            rec.update({c: math.nan for c in COLUMNS})
            rec.update(status=f"failed: {r['failure']}", error=math.nan, pareto=False)
        else:
            rec.update(
                elements=p["elements"],
                dofs=p["dofs"],
                dt=p["dt"],
                dt_crit=p["dt_crit"],
                steps=p["steps"],
                setup_s=p["setup_s"],
                stepping_s=p["stepping_s"],
                wall_s=p["wall_s"],
                runs=p["runs"],
                wall_min_s=p["wall_range_s"][0],
                wall_max_s=p["wall_range_s"][1],
                peak_mib=math.nan if p["peak_mib"] is None else p["peak_mib"],
                status=p["status"],
                error=math.nan if p["error"] is None else p["error"],
                pareto=p["pareto"],
            )
        records.append(rec)
    if as_frame is not False:
        try:
            import pandas as pd  # type: ignore[import-untyped]
        except ImportError:
            if as_frame:
                raise
        else:
            frame = pd.DataFrame.from_records(records)
            frame.attrs.update(scene=scene.name, reference=reference, error_definition=definition)
            return frame
    return [dict(r, reference=reference, error_definition=definition) for r in records]


def _job(payload: Dict[str, Any]) -> Dict[str, Any]:
    """One specimen run of a calibration, on a worker: what it measured (JSON) or why it
    failed."""
    try:
        measured = _rbsm.calibration_job(payload["spec"], payload["job"], threads=payload["threads"])
        return {"job": payload["job"], "measured": measured, "failure": None}
    except Exception as e:  # noqa: BLE001 - raised by the caller, naming the job
        return _job_failed(payload, f"{type(e).__name__}: {e}")


def _job_failed(payload: Dict[str, Any], why: str) -> Dict[str, Any]:
    return {"job": payload["job"], "measured": None, "failure": why}


def _read_input(path: Path) -> str:
    """The text of an input file; one that cannot be read raises :class:`SceneError` of kind
    ``io`` with the file as ``key``, as a scene file does."""
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        why = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        error = _rbsm.SceneError(f"{path}: {why}")
        error.kind, error.key, error.message = "io", str(path), why
        raise error from e


class CalibrationFailed(RuntimeError):
    """A specimen run of a calibration failed; ``job`` is the run (test, cell size, seed,
    material) and the message says why."""

    def __init__(self, job: Dict[str, Any], why: str) -> None:
        self.job = job
        super().__init__(
            f"the {job['test']} specimen of cell size {job['size']}, seed {job['seed']} "
            f"(round {job['round']}) failed: {why}"
        )


def calibrate(
    spec: Union[str, "os.PathLike[str]", Mapping[str, Any]],
    executor: Any = None,
    *,
    threads: Optional[int] = 1,
    workers: Optional[int] = None,
    progress: Optional[Callable[[int, int, Optional[Dict[str, Any]]], None]] = None,
) -> Dict[str, Any]:
    """``rbsm calibrate``: the facet law of a Voronoi material calibrated to its measured
    ``E``, ``nu``, ``tensile_strength``, ``fracture_energy`` and ``compressive_strength``
    (``docs/calibrate.md``). ``spec`` is a calibration file's path or its content as a
    dict. Each round's specimen runs are tasks on ``executor`` (``None``: local processes,
    ``workers`` of them; a Dask ``distributed.Client``: its cluster; any
    ``concurrent.futures.Executor``), each on ``threads`` Rust threads; the rounds and the
    report are the command line's (``rbsm calibrate --json``), returned as a dict whose
    ``material`` is the block for a scene's ``materials``. ``progress(round, runs, last)`` is
    called before each round, ``last`` being the fracture round just measured (a row of the
    report's ``rounds``) or ``None``. A run that fails raises :class:`CalibrationFailed`.
    """
    if isinstance(spec, Mapping):
        from . import _json_text

        text = _json_text(spec)
    else:
        text = _read_input(Path(spec))
    done: List[str] = []
    while True:
        step = json.loads(_rbsm.calibration_next(text, done))
        if "report" in step:
            return step["report"]  # type: ignore[no-any-return]
        jobs = step["jobs"]
        if progress is not None:
            progress(jobs[0]["round"], len(jobs), step["last"])
        payloads: List[Dict[str, Any]] = [
            {"spec": text, "job": json.dumps(j), "threads": threads} for j in jobs
        ]
        results: Dict[str, Dict[str, Any]] = {}

        def finished(result: Dict[str, Any]) -> None:
            results[result["job"]] = result

        _run(executor, payloads, workers, finished, _job, _job_failed)
        for p in payloads:
            r = results[p["job"]]
            if r["measured"] is None:
                raise CalibrationFailed(json.loads(p["job"]), r["failure"])
            done.append(r["measured"])

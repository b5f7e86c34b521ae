"""rbsm: the Rigid-Bodies-Spring Model in 2D with explicit dynamics, from Python.

The same library as the ``rbsm`` command line, called in process: a scene in, numpy arrays out,
no files unless asked for. Rust computes with the GIL released; Ctrl-C stops a run at its next
step and raises :class:`Interrupted`, which carries the run up to there.

>>> import rbsm
>>> scene = rbsm.Scene("examples/scenes/cantilever.json")
>>> modes = rbsm.eigen(scene, modes=3)
>>> r = rbsm.run(scene, steps=2000)
>>> r.history["total"][-1], r.U.shape

Studies of many runs (time steps, refinements, Voronoi seeds) go through :func:`sweep`, on local
processes or on a Dask cluster.
"""

from __future__ import annotations

import json
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _rbsm
from ._rbsm import OutputError, SceneError

__version__: str = _rbsm.__version__

__all__ = [
    "Scene",
    "SceneError",
    "OutputError",
    "Interrupted",
    "DivergedError",
    "DivergedWarning",
    "SweepFailed",
    "CalibrationFailed",
    "RunResult",
    "InterfaceLines",
    "StaticResult",
    "LimitResult",
    "EigenResult",
    "StabilityResult",
    "CheckResult",
    "run",
    "static",
    "effective",
    "limit",
    "eigen",
    "stability",
    "check",
    "polygons",
    "schema",
    "sweep",
    "calibrate",
]

PathLike = Union[str, "os.PathLike[str]"]


class Scene:
    """A scene, read and validated as ``rbsm check`` reads it (the schema is ``docs/scene.md``).

    ``Scene(x)`` takes a file path, a ``dict`` or a JSON string (one that starts with ``{``).
    A bad scene raises :class:`SceneError` with ``key`` the JSON path of the key at fault
    (``materials.concrete.interface.tensile_strenght``) and the message the command line
    prints; a scene file that cannot be read raises it too, with ``kind`` ``io`` and ``key``
    the file. Relative mesh paths (gmsh files) start at the scene file's
    folder, or at ``base_dir`` for a dict or a string (default: the current folder).
    """

    def __init__(
        self,
        source: Union[PathLike, Mapping[str, Any]],
        *,
        base_dir: Optional[PathLike] = None,
    ) -> None:
        if isinstance(source, Mapping):
            self._set(text=_json_text(source), base_dir=base_dir)
        elif isinstance(source, str) and source.lstrip().startswith("{"):
            self._set(text=source, base_dir=base_dir)
        elif isinstance(source, (str, os.PathLike)):
            self._set(path=os.fspath(source))
        else:
            raise TypeError(
                f"a scene is a file path, a dict or a JSON string, not {type(source).__name__}"
            )

    def _set(
        self,
        path: Optional[str] = None,
        text: Optional[str] = None,
        base_dir: Optional[PathLike] = None,
    ) -> None:
        self._path = path
        self._text = text
        self._dir = None if base_dir is None else os.fspath(base_dir)
        self.name: str = _rbsm.validate(*self._source())

    @classmethod
    def from_file(cls, path: PathLike) -> "Scene":
        """The scene in the JSON file ``path``."""
        scene = cls.__new__(cls)
        scene._set(path=os.fspath(path))
        return scene

    @classmethod
    def from_dict(cls, scene: Mapping[str, Any], base_dir: Optional[PathLike] = None) -> "Scene":
        """The scene given as a dict (the JSON file's content)."""
        return cls(scene, base_dir=base_dir)

    @classmethod
    def from_json(cls, text: str, base_dir: Optional[PathLike] = None) -> "Scene":
        """The scene given as JSON text."""
        scene = cls.__new__(cls)
        scene._set(text=text, base_dir=base_dir)
        return scene

    def _source(self) -> Tuple[Optional[str], Optional[str], Optional[str]]:
        return (self._path, self._text, self._dir)

    @property
    def json(self) -> str:
        """The scene's JSON text."""
        if self._text is not None:
            return self._text
        assert self._path is not None
        return Path(self._path).read_text(encoding="utf-8")

    def to_dict(self) -> Dict[str, Any]:
        """The scene as a dict (a copy: changing it leaves the scene as it is)."""
        scene: Dict[str, Any] = json.loads(self.json)
        return scene

    def portable(self) -> Tuple[str, Optional[str]]:
        """The scene as ``(JSON text, folder of its relative paths)``: what a worker of a
        cluster needs to read it without the file."""
        if self._path is not None:
            return (self.json, str(Path(self._path).resolve().parent))
        return (self.json, self._dir)

    def __repr__(self) -> str:
        where = f" from {self._path}" if self._path else ""
        return f"Scene({self.name!r}{where})"


SceneLike = Union[Scene, PathLike, Mapping[str, Any]]


def _json_text(data: Mapping[str, Any]) -> str:
    """``data`` as JSON text. A number that is not finite (``nan``, ``inf``), which JSON
    cannot hold, raises :class:`SceneError` of kind ``scene`` with its JSON path as ``key``,
    as the scene's reader names a number out of its range."""

    def check(x: Any, path: str) -> None:
        if isinstance(x, float) and not np.isfinite(x):
            message = f"must be a finite number, got {x}"
            error = SceneError(f"scene: `{path}`: {message}")
            error.kind, error.key, error.message = "scene", path, message
            raise error
        if isinstance(x, Mapping):
            for k, v in x.items():
                check(v, f"{path}.{k}" if path else str(k))
        elif isinstance(x, (list, tuple)):
            for k, v in enumerate(x):
                check(v, f"{path}[{k}]")

    check(data, "")
    return json.dumps(data)


def _scene(scene: SceneLike) -> Scene:
    return scene if isinstance(scene, Scene) else Scene(scene)


def _opt(p: Optional[PathLike]) -> Optional[str]:
    return None if p is None else os.fspath(p)


@dataclass
class InterfaceLines:
    """The interfaces that can fail, as arrays in the order of ``final_state.json``'s
    ``interfaces`` (the crack frames' lines), for drawing cracks with matplotlib::

        from matplotlib.collections import LineCollection
        lines = r.interface_lines
        ax.add_collection(LineCollection(lines.ends[lines.status >= lines.BROKEN], color="red"))
    """

    ELASTIC = 0
    YIELDING = 1
    BROKEN = 2
    RELEASED = 3
    #: The names of the ``status`` codes, by code.
    STATUS = ("elastic", "yielding", "broken", "released")

    index: np.ndarray
    """Each line's interface among the model's interfaces, ``(n,)``."""
    ends: np.ndarray
    """The two ends of each interface's edge at the end of the run, ``(n, 2, 2)`` (m): each end
    midway between where its two elements put it, with their finite rotations (as
    ``cracks/step_*.vtu``)."""
    reference_ends: np.ndarray
    """The same ends before any motion, ``(n, 2, 2)`` (m)."""
    status: np.ndarray
    """``0`` elastic, ``1`` yielding, ``2`` broken, ``3`` released to contact, ``(n,)``."""
    opening: np.ndarray
    """Mean plastic opening (m), ``(n,)``."""
    slip: np.ndarray
    """Mean plastic slip (m), ``(n,)``."""
    dissipated: np.ndarray
    """Work of the strength and of friction on each interface (J), ``(n,)``."""


@dataclass
class RunResult:
    """What ``rbsm run`` ends with: ``summary.json`` as a dict, the history as one numpy
    array per column of ``history.csv``, and the final state."""

    summary: Dict[str, Any]
    """``summary.json``: status, steps, ``dt``, ``dt_crit``, energies, timings, warnings."""
    history: Dict[str, np.ndarray]
    """The columns of ``history.csv`` (``t``, the energies, clamps, probes), one array each."""
    t: float
    """Time reached (s)."""
    U: np.ndarray
    """Final displacements, ``(elements, dofs)``."""
    V: np.ndarray
    """Final velocities, ``(elements, dofs)``."""
    centroids: np.ndarray
    """Reference centroids, ``(elements, 2)``."""
    dofs: List[str]
    """The DOF names of a row of ``U`` (``u``, ``v``, ``theta``, then strains for hybrid)."""
    interfaces: Optional[List[Dict[str, Any]]] = None
    """The failing interfaces' state at the end (status, opening, slip, dissipated); ``None``
    when no interface can fail."""
    interface_lines: Optional[InterfaceLines] = None
    """The same interfaces as arrays, with their end points (for drawing cracks); ``None``
    when no interface can fail."""

    @property
    def status(self) -> str:
        """``ok``, ``diverged`` or ``interrupted``."""
        return str(self.summary["status"])

    @property
    def reason(self) -> Optional[str]:
        """Why the run stopped early, with the step and the time (``summary["reason"]``);
        ``None`` for a run that took every step."""
        reason = self.summary.get("reason")
        return None if reason is None else str(reason)

    def to_pandas(self) -> Any:
        """The history as a pandas DataFrame (pandas must be installed)."""
        import pandas as pd  # type: ignore[import-untyped]

        return pd.DataFrame(self.history)


class Interrupted(KeyboardInterrupt):
    """Ctrl-C stopped a run at its next step: ``result`` holds the run up to there (status
    ``interrupted``; with ``out``, its files are complete)."""

    def __init__(self, result: RunResult) -> None:
        super().__init__(
            f"run interrupted at step {result.summary['steps']} (t = {result.t:e} s); "
            "the run up to there is in this exception's `result`"
        )
        self.result = result


class DivergedError(RuntimeError):
    """A run that went unstable: the guard stopped it at ``step`` (time ``t``, s) for
    ``reason`` (what it saw: energy growth or a NaN). ``result`` holds the run up to the last
    state that passed the guard, with ``result.reason`` the summary's (step, time and reason in
    one line); with ``out``, its files are written, as the command line's exit code 3 leaves
    them."""

    def __init__(self, result: RunResult) -> None:
        self.result = result
        stopped = result.reason or "diverged"
        m = _STOPPED.match(stopped)
        self.step: int = int(m.group(1)) if m else int(result.summary["steps"])
        self.t: float = float(m.group(2)) if m else result.t
        self.reason: str = stopped[m.end():] if m else stopped
        super().__init__(f"the run diverged at {stopped}")


class DivergedWarning(RuntimeWarning):
    """Issued instead of :class:`DivergedError` by ``run(..., on_diverge="warn")``."""


#: How the summary's ``reason`` names where a run stopped.
_STOPPED = re.compile(r"step (\d+), t = (\S+) s: ", re.DOTALL)


def run(
    scene: SceneLike,
    *,
    out: Optional[PathLike] = None,
    evaluator: Optional[str] = None,
    dt: Optional[float] = None,
    dt_factor: Optional[float] = None,
    steps: Optional[int] = None,
    exact_dt_crit: bool = False,
    resume: bool = False,
    threads: Optional[int] = None,
    on_diverge: str = "raise",
) -> RunResult:
    """``rbsm run``: explicit central difference over the scene. The options are the command
    line's (``--evaluator``, ``--dt``, ``--dt-factor``, ``--steps``, ``--exact-dt-crit``,
    ``--resume``, ``--threads``). Writes ``summary.json``, ``history.csv``,
    ``final_state.json`` and the frames the scene asks for into ``out`` only when it is given;
    ``resume=True`` goes on from the checkpoint in ``out``. A run that diverges raises
    :class:`DivergedError` (with the step, the time, the reason and the run up to there);
    with ``on_diverge="warn"`` it issues a :class:`DivergedWarning` and returns with status
    ``diverged`` and its ``reason``. Ctrl-C raises :class:`Interrupted`."""
    if on_diverge not in ("raise", "warn"):
        raise ValueError(f"on_diverge: give \"raise\" or \"warn\", not {on_diverge!r}")
    s = _scene(scene)
    d = _rbsm.run(
        *s._source(),
        out=_opt(out),
        evaluator=evaluator,
        dt=dt,
        dt_factor=dt_factor,
        steps=steps,
        exact_dt_crit=exact_dt_crit,
        resume=resume,
        threads=threads,
    )
    history = {name: d["history"][:, k].copy() for k, name in enumerate(d["columns"])}
    result = RunResult(
        summary=json.loads(d["summary"]),
        history=history,
        t=d["t"],
        U=d["U"],
        V=d["V"],
        centroids=d["centroids"],
        dofs=list(d["dofs"]),
        interfaces=None if d["interfaces"] is None else json.loads(d["interfaces"]),
        interface_lines=None
        if d["interface_lines"] is None
        else InterfaceLines(**d["interface_lines"]),
    )
    if d["interrupted"]:
        raise Interrupted(result)
    if result.status == "diverged":
        if on_diverge == "raise":
            raise DivergedError(result)
        warnings.warn(f"the run diverged at {result.reason}", DivergedWarning, stacklevel=2)
    return result


@dataclass
class StaticResult:
    """``rbsm static``: the linear static solution ``K_ff U_f = P_f``."""

    report: Dict[str, Any]
    """``rbsm static --json``: every element and interface (tractions), the strain energy."""
    U: np.ndarray
    """Displacements, ``(elements, dofs)``."""
    centroids: np.ndarray
    dofs: List[str]

    @property
    def energy(self) -> float:
        """Strain energy ``½ Uᵀ K U`` (J)."""
        return float(self.report["energy"])


def static(
    scene: SceneLike, *, out: Optional[PathLike] = None, threads: Optional[int] = None
) -> StaticResult:
    """``rbsm static``: sparse Cholesky of the free DOFs, loads at their full value; with
    ``out``, the command line's files."""
    d = _rbsm.static(*_scene(scene)._source(), out=_opt(out), threads=threads)
    return StaticResult(json.loads(d["report"]), d["U"], d["centroids"], list(d["dofs"]))


def effective(scene: SceneLike, *, threads: Optional[int] = None) -> Dict[str, Any]:
    """``rbsm effective --json``: the effective elastic constants of the scene's mesh and
    formulation (its one body strained uniformly three times): ``stiffness`` (``C``, Pa, Voigt
    with engineering shear), ``young``, ``poisson`` (the isotropic fit), ``material``,
    ``anisotropy``, ``scatter`` (of the element stresses), ``elements``,
    ``boundary_elements``, ``seconds``."""
    return json.loads(_rbsm.effective(*_scene(scene)._source(), threads=threads))


@dataclass
class LimitResult:
    """``rbsm limit``: the collapse load of the scene's discrete model by conic programming."""

    report: Dict[str, Any]
    """``rbsm limit --json``: what grows, the collapse load, the program's size and time."""
    velocities: np.ndarray
    """The collapse mechanism, ``(elements, 3)``: ``u̇, v̇, θ̇`` per element, scaled so that the
    largest speed of an element's vertex is 1, rotations and strain rates included (one
    optimal field: motions that cost nothing may be part of it)."""
    tractions: np.ndarray
    """Tractions at collapse, ``(interfaces, 2, 2)``: ``[σ, τ]`` (Pa) at each Gauss point."""
    centroids: np.ndarray
    strain_rates: np.ndarray
    """The mechanism's plastic strain rates ``[ε̇_x, ε̇_y, γ̇_xy]`` per element on the scale of
    ``velocities`` (hybrid; ``(0, 3)`` for a rigid model)."""
    stresses: np.ndarray
    """The elements' stresses at collapse ``[σ_x, σ_y, τ_xy]`` (Pa; zero for an element without
    a strength; ``(0, 3)`` when none has one)."""

    @property
    def collapse(self) -> float:
        """The load factor at collapse, or the moving clamp's reaction (N)."""
        return float(self.report["collapse"])


def limit(
    scene: SceneLike,
    *,
    on: Optional[str] = None,
    points: str = "gauss",
    out: Optional[PathLike] = None,
    threads: Optional[int] = None,
) -> LimitResult:
    """``rbsm limit``: the collapse load under ``on`` (``"loads"``, ``"gravity"`` or
    ``"clamps"``; the scene's moving clamp, else its loads, else gravity when ``None``), the
    interface strengths checked at ``points`` (``"gauss"`` or ``"ends"``); with ``out``, the
    command line's files."""
    d = _rbsm.limit(
        *_scene(scene)._source(), on=on, points=points, out=_opt(out), threads=threads
    )
    return LimitResult(
        json.loads(d["report"]),
        d["velocities"],
        d["tractions"],
        d["centroids"],
        d["strain_rates"],
        d["stresses"],
    )


@dataclass
class EigenResult:
    """``rbsm eigen``: the lowest modes of ``K φ = ω² M φ`` and ``ω_max``."""

    report: Dict[str, Any]
    frequencies_hz: np.ndarray
    """The lowest modes' frequencies (Hz), ascending."""
    omega: np.ndarray
    """Their circular frequencies (rad/s)."""
    omega_max: float
    """The largest circular frequency (rad/s)."""
    dt_crit: float
    """The stability limit of central difference (s): ``2 / ω_max``, over ``√(1 + α)`` with the
    scene's local damping ``α`` (``report["local_damping_factor"]``), as a run takes it."""
    shapes: np.ndarray
    """``M``-normalised mode shapes, ``(modes, elements, dofs)`` (zero on fixed DOFs)."""
    centroids: np.ndarray
    dofs: List[str]


def eigen(
    scene: SceneLike,
    *,
    modes: int = 10,
    method: str = "auto",
    out: Optional[PathLike] = None,
    vtk: Optional[PathLike] = None,
    svg: Optional[PathLike] = None,
    threads: Optional[int] = None,
) -> EigenResult:
    """``rbsm eigen``: ``modes`` lowest modes by ``method`` (``auto``, ``dense``, ``sparse``)
    and ``ω_max`` to full precision; ``out``, ``vtk`` and ``svg`` write the command line's
    files."""
    d = _rbsm.eigen(
        *_scene(scene)._source(),
        modes=modes,
        method=method,
        out=_opt(out),
        vtk=_opt(vtk),
        svg=_opt(svg),
        threads=threads,
    )
    r = json.loads(d["report"])
    return EigenResult(
        report=r,
        frequencies_hz=np.asarray(r["frequencies_hz"], dtype=float),
        omega=np.asarray(r["omega"], dtype=float),
        omega_max=float(r["omega_max"]),
        dt_crit=float(r["dt_crit"]),
        shapes=d["shapes"],
        centroids=d["centroids"],
        dofs=list(d["dofs"]),
    )


@dataclass
class StabilityResult:
    """``rbsm stability``: the exact ``Δt_crit``, the cheap bounds, the empirical limit and
    the runs at fractions of ``Δt_crit``."""

    report: Dict[str, Any]
    omega_max: float
    dt_crit: float
    """The exact critical time step (s)."""
    empirical_dt: float
    """The largest step found stable by bisection (s)."""
    fractions: List[Dict[str, Any]] = field(default_factory=list)
    """One dict per fraction run (``fraction``, ``dt``, ``status``, ``reason``: why a diverged
    run stopped, else ``None``; ``max_relative_drift``: ``None`` for a diverged run), with its
    ``history``: ``(rows, 3)`` of ``(t, total, kinetic + elastic)``."""


def stability(
    scene: SceneLike,
    *,
    fractions: Sequence[float] = (0.9, 0.99, 1.01),
    steps: int = 2000,
    out: Optional[PathLike] = None,
    threads: Optional[int] = None,
) -> StabilityResult:
    """``rbsm stability``: exact ``Δt_crit``, bounds, empirical limit, and a run of ``steps``
    steps at each fraction of ``Δt_crit``; ``out`` writes their energy histories as CSV."""
    d = _rbsm.stability(
        *_scene(scene)._source(),
        fractions=list(fractions),
        steps=steps,
        out=_opt(out),
        threads=threads,
    )
    r = json.loads(d["report"])
    runs = [dict(f, history=h) for f, h in zip(r["fractions"], d["histories"])]
    return StabilityResult(
        report=r,
        omega_max=float(r["omega_max"]),
        dt_crit=float(r["dt_crit"]),
        empirical_dt=float(r["empirical"]["dt"]),
        fractions=runs,
    )


@dataclass
class CheckResult:
    """``rbsm check``: what the scene models, ``Δt_crit`` and the warnings."""

    report: Dict[str, Any]

    def __getattr__(self, key: str) -> Any:
        try:
            return self.report[key]
        except KeyError:
            raise AttributeError(key) from None


def check(
    scene: SceneLike,
    *,
    evaluator: Optional[str] = None,
    dt: Optional[float] = None,
    threads: Optional[int] = None,
) -> CheckResult:
    """``rbsm check``: elements, interfaces, DOFs, supports, loads, contact, ``Δt_crit``
    (exact), ``dt_safe``, the time step and the memory; the report's keys are attributes."""
    text = _rbsm.check(*_scene(scene)._source(), evaluator=evaluator, dt=dt, threads=threads)
    return CheckResult(json.loads(text))


def polygons(
    scene: SceneLike, U: Optional[np.ndarray] = None, scale: float = 1.0
) -> List[np.ndarray]:
    """The scene's elements as polygons, one ``(vertices, 2)`` array each, moved by
    ``N_e(x) U_e × scale`` when ``U`` (``(elements, dofs)``, as results give it) is given:
    ready for ``matplotlib.collections.PolyCollection``."""
    u = None if U is None else [float(x) for x in np.asarray(U, dtype=float).ravel()]
    xy, offsets = _rbsm.polygons(*_scene(scene)._source(), u=u, scale=scale)
    return [xy[a:b] for a, b in zip(offsets[:-1], offsets[1:])]


def schema() -> Dict[str, Any]:
    """The JSON Schema of scene files (``rbsm schema``)."""
    schema: Dict[str, Any] = json.loads(_rbsm.schema())
    return schema


from .study import CalibrationFailed, SweepFailed, calibrate, sweep  # noqa: E402  (the study uses the names above)

//! `rbsm._rbsm`: the Rust side of the Python package. Each function takes a scene as a file
//! path or as JSON text (with the folder its relative mesh paths start from), runs one command
//! of the library with the command line's options, and returns plain Python values: JSON text
//! for the reports, numpy arrays for everything indexed by element, DOF, mode or step. The
//! Python package (`python/rbsm`) wraps them in typed results.
//!
//! Rust computes with the GIL released; the calling thread meanwhile looks for Ctrl-C every
//! 20 ms, and a run stops at its next step with complete results (status `interrupted`).

use numpy::{PyArray1, PyArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rbsm::analysis::run::{self, RunParams, Silent};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::analysis::{check, effective, eigen, stability, statics, tradeoff};
use rbsm::input::scene::{EvaluatorKind, Scene};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::sync::Arc;
use std::time::Duration;

create_exception!(
    _rbsm,
    SceneError,
    PyValueError,
    "A scene (or an option) that rbsm refuses: `kind` is `scene` (`key`: the JSON path of the key \
     at fault, or the option), `mesh` (`key`: the body and cell), `parse` (`key`: the file, or \
     `<json>`: not JSON) or `io` (`key`: an input file, the scene's or a mesh's, that cannot be \
     read); `message` says what is wrong and what is allowed."
);
create_exception!(
    _rbsm,
    OutputError,
    PyOSError,
    "An output file or folder rbsm could not write (or a checkpoint it could not read back): \
     `key` is the file, `message` what the system said."
);

/// The library's error as a Python exception carrying `kind`, `key` and `message`: a
/// `SceneError`, or an `OutputError` for a file that could not be written.
fn py_error(e: rbsm::error::Error) -> PyErr {
    raise_failed(Failed::from(e))
}

/// An error of the library, and whether it arose reading the input (the scene and the mesh
/// files it names), where a file that cannot be read is the scene's fault, not the output's.
struct Failed {
    error: rbsm::error::Error,
    input: bool,
}

impl From<rbsm::error::Error> for Failed {
    fn from(error: rbsm::error::Error) -> Self {
        Failed {
            error,
            input: false,
        }
    }
}

/// An error while reading the input.
fn input(error: rbsm::error::Error) -> Failed {
    Failed { error, input: true }
}

/// The Python exception of `f`: `SceneError`, or `OutputError` for an I/O error past the input.
fn raise_failed(f: Failed) -> PyErr {
    let text = f.error.to_string();
    let (kind, key, message) = f.error.parts();
    let err = if kind == "io" && !f.input {
        OutputError::new_err(text)
    } else {
        SceneError::new_err(text)
    };
    Python::attach(|py| {
        let value = err.value(py);
        for (name, v) in [
            ("kind", kind.to_string()),
            ("key", key),
            ("message", message),
        ] {
            // Setting an attribute on a fresh exception instance does not fail.
            let _ = value.setattr(name, v);
        }
    });
    err
}

/// An option refused, named as the command line names it.
fn option_error(key: &str, message: &str) -> PyErr {
    py_error(rbsm::error::Error::scene(key, message))
}

/// The scene from a file (`path`) or from JSON `text` whose relative paths start at `base_dir`.
fn scene(
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
) -> PyResult<Scene> {
    match (path, text) {
        (Some(path), None) => Scene::from_file(path),
        (None, Some(text)) => match base_dir {
            Some(dir) => Scene::from_json_in(&text, &dir),
            None => Scene::from_json(&text),
        },
        _ => {
            return Err(PyValueError::new_err(
                "give a scene path or its JSON text, not both",
            ))
        }
    }
    .map_err(|e| raise_failed(input(e)))
}

/// The option `key`'s `value` as a count of at least `least`: a negative or too small one is
/// refused by its key (as the command line refuses it), not by Python's `OverflowError`.
fn count(key: &str, value: i64, least: u64) -> PyResult<u64> {
    match u64::try_from(value) {
        Ok(v) if v >= least => Ok(v),
        _ => Err(option_error(
            key,
            &format!("must be ≥ {least}, got {value}"),
        )),
    }
}

/// The option `key` named `name`, refused as the command line refuses it.
fn named<T: std::str::FromStr<Err = String>>(key: &str, name: &str) -> PyResult<T> {
    name.parse().map_err(|why: String| option_error(key, &why))
}

fn evaluator(name: Option<String>) -> PyResult<Option<EvaluatorKind>> {
    name.map(|name| named("evaluator", &name)).transpose()
}

/// Runs `work` with the GIL released, on `threads` worker threads (all cores by default), while
/// the calling thread looks for signals every 20 ms. The first signal's exception (Ctrl-C:
/// `KeyboardInterrupt`) raises `stop` and is returned beside the result, which `work` still
/// completes.
fn detached<R: Send>(
    py: Python<'_>,
    threads: Option<i64>,
    stop: Option<&Arc<AtomicBool>>,
    work: impl FnOnce() -> R + Send,
) -> PyResult<(R, Option<PyErr>)> {
    let pool = match threads.map(|n| count("threads", n, 1)).transpose()? {
        Some(n) => Some(
            rayon::ThreadPoolBuilder::new()
                .num_threads(n as usize)
                .build()
                .map_err(|e| option_error("threads", &e.to_string()))?,
        ),
        None => None,
    };
    let (result, signal) = py.detach(|| {
        std::thread::scope(|s| {
            let (done, finished) = std::sync::mpsc::channel();
            let worker = s.spawn(move || {
                let r = match &pool {
                    Some(pool) => pool.install(work),
                    None => work(),
                };
                // The caller wakes at once, not at its next look for signals.
                let _ = done.send(());
                r
            });
            let mut signal = None;
            // Until the worker has sent, or has gone (a panic drops the sender).
            while let Err(RecvTimeoutError::Timeout) = finished.recv_timeout(LOOK_FOR_SIGNALS) {
                if signal.is_none() {
                    if let Err(e) = Python::attach(|py| py.check_signals()) {
                        if let Some(stop) = stop {
                            stop.store(true, Ordering::Relaxed);
                        }
                        signal = Some(e);
                    }
                }
            }
            (worker.join(), signal)
        })
    });
    match result {
        Ok(r) => Ok((r, signal)),
        Err(panic) => std::panic::resume_unwind(panic),
    }
}

/// How often the calling thread looks for signals while Rust computes.
const LOOK_FOR_SIGNALS: Duration = Duration::from_millis(20);

/// A flat vector as a numpy array of `rows × (len / rows)`.
fn matrix<'py>(py: Python<'py>, data: Vec<f64>, cols: usize) -> PyResult<Bound<'py, PyAny>> {
    let rows = data.len().checked_div(cols).unwrap_or(0);
    Ok(PyArray1::from_vec(py, data)
        .reshape([rows, cols])?
        .into_any())
}

/// The reference centroids of `setup`'s elements, `(elements, 2)`.
fn centroids<'py>(py: Python<'py>, setup: &Setup) -> PyResult<Bound<'py, PyAny>> {
    let c = setup
        .model
        .elements
        .iter()
        .flat_map(|e| [e.props.centroid.x, e.props.centroid.y])
        .collect();
    matrix(py, c, 2)
}

fn json(value: &impl serde::Serialize) -> String {
    serde_json::to_string(value).expect("reports serialise")
}

/// `rbsm run`: returns the summary (JSON), the history (column names and a `(rows, columns)`
/// array), the final `t`, `U`, `V` (`(elements, ndof)`), the centroids, the failing interfaces
/// (JSON, or `None`) and whether a signal stopped it. Writes the run's files into `out` only
/// when given.
#[pyfunction]
#[pyo3(name = "run", signature = (path, text, base_dir, out=None, evaluator=None, dt=None, dt_factor=None,
    steps=None, exact_dt_crit=false, resume=false, threads=None))]
#[allow(clippy::too_many_arguments)]
fn run_py<'py>(
    py: Python<'py>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    out: Option<PathBuf>,
    evaluator: Option<String>,
    dt: Option<f64>,
    dt_factor: Option<f64>,
    steps: Option<i64>,
    exact_dt_crit: bool,
    resume: bool,
    threads: Option<i64>,
) -> PyResult<Bound<'py, PyDict>> {
    if dt.is_some() && dt_factor.is_some() {
        return Err(option_error("dt", "give `dt` or `dt_factor`, not both"));
    }
    let scene = scene(path, text, base_dir)?;
    let overrides = Overrides {
        evaluator: self::evaluator(evaluator)?,
        dt,
        dt_factor,
        steps: steps.map(|n| count("steps", n, 0)).transpose()?,
        exact_dt_crit,
        ..Default::default()
    };
    let stop = Arc::new(AtomicBool::new(false));
    let params = RunParams {
        resume,
        interrupt: Some(stop.clone()),
        keep_history: true,
    };
    let (outcome, signal) = detached(py, threads, Some(&stop), || {
        let setup = Setup::new(&scene, &overrides).map_err(input)?;
        let outcome = run::simulate(&setup, &params, out.as_deref(), &mut Silent)?;
        Ok::<_, Failed>((setup, outcome))
    })?;
    let (setup, o) = match outcome {
        Ok(r) => r,
        // A signal during the setup: the setup finished, and its error (if any) comes second.
        Err(e) => return Err(signal.unwrap_or_else(|| raise_failed(e))),
    };
    let ndof = setup.model.formulation.ndof();
    let d = PyDict::new(py);
    let lines = match &o.interfaces {
        Some(list) => interface_lines(py, &setup.model, &o.u, list)?.into_any(),
        None => py.None().into_bound(py),
    };
    d.set_item("interface_lines", lines)?;
    d.set_item("summary", json(&o.summary))?;
    d.set_item("columns", &o.columns)?;
    d.set_item("history", matrix(py, o.history, o.columns.len())?)?;
    d.set_item("t", o.t)?;
    d.set_item("U", matrix(py, o.u, ndof)?)?;
    d.set_item("V", matrix(py, o.v, ndof)?)?;
    d.set_item("centroids", centroids(py, &setup)?)?;
    d.set_item("dofs", setup.model.formulation.dof_names().to_vec())?;
    d.set_item("interfaces", o.interfaces.as_ref().map(json))?;
    d.set_item("interrupted", signal.is_some())?;
    Ok(d)
}

/// The failing interfaces `list` (in the order of `final_state.json`) as arrays: `index` (among
/// the model's interfaces), `ends` `(n, 2, 2)`, the two ends of each edge where the
/// displacements `u` put it (as the crack frames draw it: each end midway between where its two
/// elements put it, with their finite rotations), `reference_ends` likewise before any motion,
/// `status` (the crack frames' codes: 0 elastic, 1 yielding, 2 broken, 3 released), `opening`,
/// `slip` (m) and `dissipated` (J).
fn interface_lines<'py>(
    py: Python<'py>,
    model: &rbsm::model::Model,
    u: &[f64],
    list: &[rbsm::force::failure::InterfaceFailure],
) -> PyResult<Bound<'py, PyDict>> {
    use rbsm::output::vtk::{interface_edge, status_code, Placement};
    let n = list.len();
    let (mut ends, mut reference) = (Vec::with_capacity(4 * n), Vec::with_capacity(4 * n));
    for f in list {
        let i = &model.interfaces[f.interface];
        for p in interface_edge(model, u, i, Placement::Current) {
            ends.extend([p.x, p.y]);
        }
        reference.extend([i.p1.x, i.p1.y, i.p2.x, i.p2.y]);
    }
    let column = |value: fn(&rbsm::force::failure::InterfaceFailure) -> f64| {
        PyArray1::from_vec(py, list.iter().map(value).collect())
    };
    let d = PyDict::new(py);
    let index: Vec<u64> = list.iter().map(|f| f.interface as u64).collect();
    d.set_item("index", PyArray1::from_vec(py, index))?;
    d.set_item("ends", PyArray1::from_vec(py, ends).reshape([n, 2, 2])?)?;
    d.set_item(
        "reference_ends",
        PyArray1::from_vec(py, reference).reshape([n, 2, 2])?,
    )?;
    let status: Vec<i32> = list.iter().map(|f| status_code(f.status)).collect();
    d.set_item("status", PyArray1::from_vec(py, status))?;
    d.set_item("opening", column(|f| f.opening))?;
    d.set_item("slip", column(|f| f.slip))?;
    d.set_item("dissipated", column(|f| f.dissipated))?;
    Ok(d)
}

/// `rbsm effective`: the report (JSON).
#[pyfunction]
#[pyo3(name = "effective", signature = (path, text, base_dir, threads=None))]
fn effective_py(
    py: Python<'_>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    threads: Option<i64>,
) -> PyResult<String> {
    let scene = scene(path, text, base_dir)?;
    let (result, signal) = detached(py, threads, None, || {
        let setup = Setup::new(&scene, &Overrides::no_step()).map_err(input)?;
        Ok::<_, Failed>(effective::analyse(&setup)?)
    })?;
    raise(signal)?;
    Ok(json(&result.map_err(raise_failed)?))
}

/// `rbsm static`: the report (JSON), `U` as `(elements, ndof)` and the centroids.
#[pyfunction]
#[pyo3(name = "static", signature = (path, text, base_dir, out=None, threads=None))]
fn static_py<'py>(
    py: Python<'py>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    out: Option<PathBuf>,
    threads: Option<i64>,
) -> PyResult<Bound<'py, PyDict>> {
    let scene = scene(path, text, base_dir)?;
    let (result, signal) = detached(py, threads, None, || {
        let setup = Setup::new(&scene, &Overrides::no_step()).map_err(input)?;
        let report = statics::analyse(&setup)?;
        if let Some(dir) = &out {
            statics::write(dir, &setup, &report)?;
        }
        Ok::<_, Failed>((setup, report))
    })?;
    raise(signal)?;
    let (setup, mut report) = result.map_err(raise_failed)?;
    let ndof = setup.model.formulation.ndof();
    let d = PyDict::new(py);
    d.set_item("report", json(&report))?;
    d.set_item("U", matrix(py, std::mem::take(&mut report.u), ndof)?)?;
    d.set_item("centroids", centroids(py, &setup)?)?;
    d.set_item("dofs", setup.model.formulation.dof_names().to_vec())?;
    Ok(d)
}

/// `rbsm limit`: the report (JSON), the mechanism's velocities as `(elements, 3)` and plastic
/// strain rates as `(elements, 3)` (hybrid; `(0, 3)` rigid), the tractions at collapse as
/// `(interfaces, 2, 2)`, the elements' stresses as `(elements, 3)` (`(0, 3)` when no element has
/// a strength) and the centroids; with `out`, the command line's files.
#[pyfunction]
#[pyo3(name = "limit", signature = (path, text, base_dir, on=None, points="gauss".to_string(), out=None, threads=None))]
#[allow(clippy::too_many_arguments)]
fn limit_py<'py>(
    py: Python<'py>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    on: Option<String>,
    points: String,
    out: Option<PathBuf>,
    threads: Option<i64>,
) -> PyResult<Bound<'py, PyDict>> {
    use rbsm::analysis::collapse::{self, Multiplier, Points};
    let points: Points = points
        .parse()
        .map_err(|e: String| option_error("points", &e))?;
    let on = match on.as_deref() {
        None => None,
        Some("loads") => Some(Multiplier::Loads),
        Some("gravity") => Some(Multiplier::Gravity),
        Some("clamps") => Some(Multiplier::Clamps),
        Some(other) => {
            return Err(option_error(
                "on",
                &format!("{other:?} is not one of loads, gravity, clamps"),
            ))
        }
    };
    let scene = scene(path, text, base_dir)?;
    let (result, signal) = detached(py, threads, None, || {
        let setup = Setup::new(&scene, &Overrides::no_step()).map_err(input)?;
        let report = collapse::analyse(&setup, on, points)?;
        if let Some(dir) = &out {
            collapse::write(dir, &setup, &report)?;
        }
        Ok::<_, Failed>((setup, report))
    })?;
    raise(signal)?;
    let (setup, report) = result.map_err(raise_failed)?;
    let d = PyDict::new(py);
    d.set_item("report", json(&report))?;
    let velocities = report.velocities.iter().flatten().copied().collect();
    d.set_item("velocities", matrix(py, velocities, 3)?)?;
    let rates = report.strain_rates.iter().flatten().copied().collect();
    d.set_item("strain_rates", matrix(py, rates, 3)?)?;
    let stresses = report.stresses.iter().flatten().copied().collect();
    d.set_item("stresses", matrix(py, stresses, 3)?)?;
    let n = report.tractions.len();
    let tractions: Vec<f64> = report
        .tractions
        .iter()
        .flatten()
        .flatten()
        .copied()
        .collect();
    d.set_item(
        "tractions",
        PyArray1::from_vec(py, tractions).reshape([n, 2, 2])?,
    )?;
    d.set_item("centroids", centroids(py, &setup)?)?;
    Ok(d)
}

/// A signal that arrived during an analysis that cannot stop half way: raised once it is done.
fn raise(signal: Option<PyErr>) -> PyResult<()> {
    signal.map_or(Ok(()), Err)
}

/// `rbsm eigen`: the report (JSON), the mode shapes as `(modes, elements, ndof)` and the
/// centroids; with `out`, `vtk` or `svg`, the command line's files.
#[pyfunction]
#[pyo3(name = "eigen", signature = (path, text, base_dir, modes=10, method="auto".to_string(), out=None,
    vtk=None, svg=None, threads=None))]
#[allow(clippy::too_many_arguments)]
fn eigen_py<'py>(
    py: Python<'py>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    modes: i64,
    method: String,
    out: Option<PathBuf>,
    vtk: Option<PathBuf>,
    svg: Option<PathBuf>,
    threads: Option<i64>,
) -> PyResult<Bound<'py, PyDict>> {
    let method: eigen::Method = named("method", &method)?;
    let scene = scene(path, text, base_dir)?;
    let params = eigen::EigenParams {
        modes: count("modes", modes, 0)? as usize,
        method,
    };
    let (result, signal) = detached(py, threads, None, || {
        let setup = Setup::new(&scene, &Overrides::exact()).map_err(input)?;
        let report = eigen::analyse(&setup, &params)?;
        let files = eigen::Files {
            out: out.as_deref(),
            vtk: vtk.as_deref(),
            svg: svg.as_deref(),
        };
        files.write(&setup, &report)?;
        Ok::<_, Failed>((setup, report))
    })?;
    raise(signal)?;
    let (setup, report) = result.map_err(raise_failed)?;
    let (ne, ndof) = (setup.model.elements.len(), setup.model.formulation.ndof());
    let k = report.modes.shapes.len();
    let shapes: Vec<f64> = report.modes.shapes.iter().flatten().copied().collect();
    let d = PyDict::new(py);
    d.set_item("report", json(&report))?;
    d.set_item(
        "shapes",
        PyArray1::from_vec(py, shapes).reshape([k, ne, ndof])?,
    )?;
    d.set_item("centroids", centroids(py, &setup)?)?;
    d.set_item("dofs", setup.model.formulation.dof_names().to_vec())?;
    Ok(d)
}

/// `rbsm stability`: the report (JSON) and each fraction run's energy history as
/// `(rows, 3)` arrays of `(t, total, kinetic + elastic)`.
#[pyfunction]
#[pyo3(name = "stability", signature = (path, text, base_dir, fractions=vec![0.9, 0.99, 1.01], steps=2000,
    out=None, threads=None))]
#[allow(clippy::too_many_arguments)]
fn stability_py<'py>(
    py: Python<'py>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    fractions: Vec<f64>,
    steps: i64,
    out: Option<PathBuf>,
    threads: Option<i64>,
) -> PyResult<Bound<'py, PyDict>> {
    let scene = scene(path, text, base_dir)?;
    let params = stability::StabilityParams {
        fractions,
        steps: count("steps", steps, 0)?,
    };
    let (result, signal) = detached(py, threads, None, || {
        let setup = Setup::new(&scene, &Overrides::exact()).map_err(input)?;
        let report = stability::analyse(&setup, &params)?;
        if let Some(dir) = &out {
            stability::write_fraction_histories(dir, &report.fractions)?;
        }
        Ok::<_, Failed>(report)
    })?;
    raise(signal)?;
    let report = result.map_err(raise_failed)?;
    let d = PyDict::new(py);
    d.set_item("report", json(&report))?;
    let histories = report
        .fractions
        .iter()
        .map(|f| {
            let flat = f.history.iter().flat_map(|h| [h.0, h.1, h.2]).collect();
            matrix(py, flat, 3)
        })
        .collect::<PyResult<Vec<_>>>()?;
    d.set_item("histories", histories)?;
    Ok(d)
}

/// `rbsm check`: the report (JSON).
#[pyfunction]
#[pyo3(name = "check", signature = (path, text, base_dir, evaluator=None, dt=None, threads=None))]
fn check_py(
    py: Python<'_>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    evaluator: Option<String>,
    dt: Option<f64>,
    threads: Option<i64>,
) -> PyResult<String> {
    let scene = scene(path, text, base_dir)?;
    // The setup a run takes, so that its `dt` is the run's (`rbsm check`).
    let overrides = Overrides {
        evaluator: self::evaluator(evaluator)?,
        dt,
        ..Default::default()
    };
    // `check` reads the input and writes nothing: every error is the input's.
    let (result, signal) = detached(py, threads, None, || {
        check::check(&Setup::new(&scene, &overrides)?)
    })?;
    raise(signal)?;
    Ok(json(&result.map_err(|e| raise_failed(input(e)))?))
}

/// The settings of a sweep point as `(key, value)` pairs of `rbsm tradeoff --sweep`.
fn settings(pairs: Vec<(String, String)>) -> PyResult<Vec<(tradeoff::Key, String)>> {
    pairs
        .into_iter()
        .map(|(k, v)| {
            let key = tradeoff::Key::named(&k).map_err(py_error)?;
            key.check(&v).map_err(py_error)?;
            Ok((key, v))
        })
        .collect()
}

/// Refuses a sweep key or value as `rbsm tradeoff --sweep` does.
#[pyfunction]
fn study_check(key: String, value: String) -> PyResult<()> {
    settings(vec![(key, value)]).map(|_| ())
}

/// One point of a study (`rbsm tradeoff`'s, run alone): its figures and measure as JSON, for
/// [`study_report`] to score with the others.
#[pyfunction]
#[pyo3(signature = (path, text, base_dir, settings, threads=None))]
fn study_point(
    py: Python<'_>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    settings: Vec<(String, String)>,
    threads: Option<i64>,
) -> PyResult<String> {
    let scene = scene(path, text, base_dir)?;
    let settings = self::settings(settings)?;
    // A point writes no file: every error is the input's.
    let (result, signal) = detached(py, threads, None, || {
        tradeoff::Study::new(&scene)?.point(settings)
    })?;
    raise(signal)?;
    Ok(json(&result.map_err(|e| raise_failed(input(e)))?))
}

/// The report of a study's points (each as [`study_point`] returned it): errors against the
/// reference and the Pareto front, as JSON.
#[pyfunction]
#[pyo3(signature = (path, text, base_dir, points))]
fn study_report(
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    points: Vec<String>,
) -> PyResult<String> {
    let scene = scene(path, text, base_dir)?;
    let runs = points
        .iter()
        .map(|p| serde_json::from_str::<tradeoff::Measured>(p))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| PyValueError::new_err(format!("not a point of a study: {e}")))?;
    let report = tradeoff::Study::new(&scene)
        .and_then(|s| s.report(runs))
        .map_err(py_error)?;
    Ok(json(&report))
}

/// `rbsm calibrate`'s next round from the results so far (each as [`calibration_job`]
/// returned it): `{"jobs": [...], "last": {...}}` to run (`last`: the fracture round just
/// measured, or null), or `{"report": {...}}` when done, as JSON.
#[pyfunction]
fn calibration_next(spec: String, done: Vec<String>) -> PyResult<String> {
    use rbsm::analysis::calibrate;
    let spec = calibrate::CalibrationSpec::from_json(&spec).map_err(py_error)?;
    let done = done
        .iter()
        .map(|m| serde_json::from_str::<calibrate::Measured>(m))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| PyValueError::new_err(format!("not a calibration result: {e}")))?;
    Ok(match calibrate::next(&spec, &done).map_err(py_error)? {
        calibrate::Next::Run { jobs, last } => {
            json(&serde_json::json!({ "jobs": jobs, "last": last }))
        }
        calibrate::Next::Done(report) => json(&serde_json::json!({ "report": report })),
    })
}

/// One specimen run of a calibration (a job of [`calibration_next`], as JSON): what it
/// measured, as JSON.
#[pyfunction]
#[pyo3(signature = (spec, job, threads=None))]
fn calibration_job(
    py: Python<'_>,
    spec: String,
    job: String,
    threads: Option<i64>,
) -> PyResult<String> {
    use rbsm::analysis::calibrate;
    let spec = calibrate::CalibrationSpec::from_json(&spec).map_err(py_error)?;
    let job: calibrate::Job = serde_json::from_str(&job)
        .map_err(|e| PyValueError::new_err(format!("not a calibration job: {e}")))?;
    let (result, signal) = detached(py, threads, None, || calibrate::specimen(&spec, &job))?;
    raise(signal)?;
    Ok(json(&result.map_err(py_error)?))
}

/// The scene's elements as polygons: their vertices `(n, 2)` (moved by `N_e(x) U_e × scale`
/// when `U` is given, `(elements, ndof)`), and where each element's vertices start
/// (`elements + 1` offsets).
#[pyfunction]
#[pyo3(signature = (path, text, base_dir, u=None, scale=1.0))]
fn polygons<'py>(
    py: Python<'py>,
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
    u: Option<Vec<f64>>,
    scale: f64,
) -> PyResult<(Bound<'py, PyAny>, Vec<usize>)> {
    let scene = scene(path, text, base_dir)?;
    let model = rbsm::model::Model::build(&scene).map_err(|e| raise_failed(input(e)))?;
    let ndof = model.formulation.ndof();
    if let Some(u) = &u {
        if u.len() != model.elements.len() * ndof {
            return Err(option_error(
                "U",
                &format!(
                    "must hold {} × {ndof} values (elements × DOFs), got {}",
                    model.elements.len(),
                    u.len()
                ),
            ));
        }
    }
    let (mut xy, mut offsets) = (Vec::new(), vec![0]);
    for body in &model.bodies {
        for c in 0..body.mesh.n_cells() {
            let e = body.first_element + c;
            let centroid = model.elements[e].props.centroid;
            for &k in body.mesh.cell(c) {
                let mut x = body.mesh.vertices[k as usize];
                if let Some(u) = &u {
                    let ue = &u[e * ndof..(e + 1) * ndof];
                    x += model.formulation.displacement(ue, x - centroid) * scale;
                }
                xy.extend([x.x, x.y]);
            }
            offsets.push(xy.len() / 2);
        }
    }
    Ok((matrix(py, xy, 2)?, offsets))
}

/// Reads and validates a scene; returns its name.
#[pyfunction]
#[pyo3(signature = (path, text, base_dir))]
fn validate(
    path: Option<PathBuf>,
    text: Option<String>,
    base_dir: Option<PathBuf>,
) -> PyResult<String> {
    Ok(scene(path, text, base_dir)?.name)
}

/// The JSON Schema of scene files (`rbsm schema`).
#[pyfunction]
fn schema() -> String {
    json(&rbsm::input::scene::schema())
}

/// The Rust side of the `rbsm` Python package.
#[pymodule]
fn _rbsm(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add("OutputError", m.py().get_type::<OutputError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    for f in [
        wrap_pyfunction!(run_py, m)?,
        wrap_pyfunction!(static_py, m)?,
        wrap_pyfunction!(effective_py, m)?,
        wrap_pyfunction!(limit_py, m)?,
        wrap_pyfunction!(eigen_py, m)?,
        wrap_pyfunction!(stability_py, m)?,
        wrap_pyfunction!(check_py, m)?,
        wrap_pyfunction!(calibration_next, m)?,
        wrap_pyfunction!(calibration_job, m)?,
        wrap_pyfunction!(study_check, m)?,
        wrap_pyfunction!(study_point, m)?,
        wrap_pyfunction!(study_report, m)?,
        wrap_pyfunction!(polygons, m)?,
        wrap_pyfunction!(schema, m)?,
        wrap_pyfunction!(validate, m)?,
    ] {
        m.add_function(f)?;
    }
    Ok(())
}

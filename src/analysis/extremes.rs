//! The method at its extremes (issue 6, validation §10): each case builds its scene, measures
//! the figure it is about and reports what the code did (ran stably, warned, stopped or
//! refused). The validation report prints the figures; `tests/extremes.rs` asserts them.

use crate::analysis::eigen;
use crate::analysis::free::FreeSystem;
use crate::analysis::setup::{Overrides, Setup};
use crate::analysis::statics;
use crate::error::Result;
use crate::input::scene::Scene;
use crate::model::checks;
use crate::model::Model;
use crate::step::integrator::Status;

/// A scene of one body; `formulation` and `mesh` are JSON objects, `supports`, `loads` arrays,
/// `extra` more top-level keys (with a leading comma) or nothing.
fn scene(
    formulation: &str,
    plane: &str,
    nu: f64,
    mesh: &str,
    supports: &str,
    loads: &str,
    initial: &str,
    time: &str,
) -> Result<Scene> {
    Scene::from_json(&format!(
        r#"{{"name": "extreme", "plane": "{plane}", "thickness": 1.0, "formulation": {formulation}, "evaluator": "element-wise",
            "materials": {{"m": {{"E": 2e10, "nu": {nu}, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {mesh}, "supports": {supports}, "loads": {loads}, "initial": {initial}}}],
            "time": {time}}}"#
    ))
}

const RIGID: &str = r#"{"kind": "rigid"}"#;
const PATCH: &str = r#"{"kind": "voronoi", "origin": [0, 0], "size": [1.2, 0.8], "sites": 60, "seed": 5, "lloyd": 30}"#;
const ROLLERS: &str = r#"[{"edge": "left", "kind": "ground-spring", "components": ["n"]}, {"edge": "bottom", "kind": "ground-spring", "components": ["n"]}]"#;
const TENSION: &str = r#"[{"kind": "traction", "edge": "right", "value": [1e6, 0]}]"#;

/// A free run of `steps` steps at `fraction × Δt_crit`.
#[derive(Debug, Clone)]
pub struct Run {
    /// `dt / Δt_crit`.
    pub fraction: f64,
    /// Steps taken.
    pub steps: u64,
    /// `ok` or `diverged at step …: reason`.
    pub status: String,
    /// Largest energy drift over the largest energy.
    pub drift: f64,
    /// Whether the state left by the run is finite (the guard rolls back to the last good one).
    pub finite: bool,
}

/// Steps `p` at `fraction × Δt_crit`.
pub fn run_at(p: &Setup, fraction: f64, steps: u64) -> Result<Run> {
    let mut cd = p.integrator(fraction * p.dt_crit);
    let status = cd.run(steps, steps, |_, _| Ok(()), |_| ())?;
    let status = status.describe();
    let finite = cd.u.iter().chain(cd.velocity()).all(|x| x.is_finite());
    Ok(Run {
        fraction,
        steps: cd.step,
        status,
        drift: cd.max_relative_drift(),
        finite,
    })
}

/// Largest `ω_max` by Lanczos (what the runs use) against the dense eigenvalues of the same
/// model: their relative difference.
pub fn lanczos_against_dense(p: &Setup) -> Result<f64> {
    let sys = FreeSystem::new(&p.model, &p.mass);
    let dense = eigen::dense_modes(&sys, &p.mass, 1)?;
    let top = dense.omega_max;
    Ok((p.omega_max - top).abs() / top)
}

/// 10.1: the hybrid penalty `p`. The tension patch on a Voronoi mesh (validation §3): the
/// static error against the continuum, `Δt_crit` against the rigid one, a stable run.
#[derive(Debug, Clone)]
pub struct Penalty {
    /// Penalty factor `p`.
    pub p: f64,
    /// Static error of the patch against the continuum, relative.
    pub patch_error: f64,
    /// `Δt_crit(p) / Δt_crit(rigid)`, and the same times `√p` (constant when `1/√p` holds).
    pub dt_ratio: f64,
    /// `dt_ratio · √p`.
    pub dt_ratio_sqrt_p: f64,
    /// A free run at 0.9 `Δt_crit`.
    pub run: Run,
    /// What the checks warned.
    pub warnings: Vec<String>,
}

/// Validation §10.1: the tension patch at penalty `p`.
pub fn penalty(p: f64) -> Result<Penalty> {
    let time = r#"{"dt_factor": 0.9, "steps": 1}"#;
    let hybrid = format!(r#"{{"kind": "hybrid", "penalty": {p}}}"#);
    let s = scene(&hybrid, "stress", 0.2, PATCH, ROLLERS, TENSION, "{}", time)?;
    let model = Model::build(&s)?;
    let u = statics::solve(&model)?.u;
    let (sigma, e, nu) = (1e6, 2e10, 0.2);
    let exact = |x: crate::mesh::geometry::Vec2| (sigma / e * x.x, -nu * sigma / e * x.y);
    let scale = model
        .elements
        .iter()
        .map(|el| {
            let (a, b) = exact(el.props.centroid);
            a.hypot(b)
        })
        .fold(0.0, f64::max);
    let patch_error = model
        .elements
        .iter()
        .enumerate()
        .map(|(k, el)| {
            let (a, b) = exact(el.props.centroid);
            (u[6 * k] - a).hypot(u[6 * k + 1] - b)
        })
        .fold(0.0, f64::max)
        / scale;
    let hyb = Setup::new(&s, &Overrides::default())?;
    let rigid = Setup::new(
        &scene(RIGID, "stress", 0.2, PATCH, ROLLERS, TENSION, "{}", time)?,
        &Overrides::default(),
    )?;
    let dt_ratio = hyb.dt_crit / rigid.dt_crit;
    let run = run_at(&hyb, 0.9, 4000)?;
    let warnings = checks::warnings(&hyb.model, hyb.dt, hyb.dt_crit);
    Ok(Penalty {
        p,
        patch_error,
        dt_ratio,
        dt_ratio_sqrt_p: dt_ratio * p.sqrt(),
        run,
        warnings,
    })
}

/// A stable run at 0.9 and an unstable one just above the limit, the Lanczos–dense agreement and
/// the warnings of a prepared model.
#[derive(Debug, Clone)]
pub struct Limits {
    /// Number of elements.
    pub elements: usize,
    /// Largest over smallest element size `√A`.
    pub sizes: f64,
    /// Critical time step (s).
    pub dt_crit: f64,
    /// Relative difference of Lanczos `ω_max` from the dense one.
    pub lanczos_error: f64,
    /// A run at 0.9 `Δt_crit`.
    pub stable: Run,
    /// A run just above `Δt_crit`.
    pub above: Run,
    /// What the checks warned.
    pub warnings: Vec<String>,
}

fn limits(p: &Setup, steps: u64) -> Result<Limits> {
    let sizes = p.model.elements.iter().map(|e| e.props.area.sqrt());
    let (lo, hi) = sizes.fold((f64::INFINITY, 0.0f64), |a, s| (a.0.min(s), a.1.max(s)));
    Ok(Limits {
        elements: p.model.elements.len(),
        sizes: hi / lo,
        dt_crit: p.dt_crit,
        lanczos_error: lanczos_against_dense(p)?,
        stable: run_at(p, 0.9, steps)?,
        above: run_at(p, 1.02, steps)?,
        warnings: checks::warnings(&p.model, 0.9 * p.dt_crit, p.dt_crit),
    })
}

/// 10.2: a stack of 10 elements `ratio` times wider than tall on a ground spring, set moving
/// by an initial velocity and spin (`formulation` is a JSON object).
pub fn stack_scene(ratio: f64, formulation: &str) -> String {
    let h = 1.0 / ratio;
    format!(
        r#"{{"name": "stack", "plane": "stress", "thickness": 1.0, "formulation": {formulation}, "evaluator": "element-wise",
            "materials": {{"m": {{"E": 2e10, "nu": 0.2, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {{"kind": "grid", "origin": [0, 0], "size": [1.0, {}], "cells": [1, 10]}},
                "supports": [{{"edge": "bottom", "kind": "ground-spring"}}],
                "initial": {{"velocity": [0.1, 0.2], "angular_velocity": 0.3}}}}],
            "time": {{"dt_factor": 0.9, "steps": 1}}}}"#,
        10.0 * h
    )
}

/// 10.2: [`stack_scene`] prepared, with its limits.
pub fn aspect(ratio: f64, formulation: &str) -> Result<Limits> {
    limits(
        &Setup::new(
            &Scene::from_json(&stack_scene(ratio, formulation))?,
            &Overrides::default(),
        )?,
        20_000,
    )
}

/// The polygons of a quarter annulus from radius `r0` to `r0 · ratio`, 4 sectors over 90°, with
/// rings growing by the sector's angle so that every cell is near square: sizes span
/// `1:ratio` in one conforming mesh.
pub fn graded_quarter_annulus(r0: f64, ratio: f64) -> (Vec<[f64; 2]>, Vec<Vec<usize>>) {
    let sectors = 4;
    let dtheta = std::f64::consts::FRAC_PI_2 / sectors as f64;
    let growth = 1.0 + dtheta;
    let rings = (ratio.ln() / growth.ln()).ceil() as usize;
    let radius = |i: usize| r0 * ratio.powf(i as f64 / rings as f64);
    let mut vertices = Vec::new();
    for i in 0..=rings {
        for j in 0..=sectors {
            let (s, c) = (j as f64 * dtheta).sin_cos();
            vertices.push([radius(i) * c, radius(i) * s]);
        }
    }
    let at = |i: usize, j: usize| i * (sectors + 1) + j;
    let cells = (0..rings)
        .flat_map(|i| {
            (0..sectors).map(move |j| vec![at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)])
        })
        .collect();
    (vertices, cells)
}

/// 10.3: element sizes spanning `1:ratio` in one mesh (a graded quarter annulus on rollers,
/// set moving by an initial velocity).
pub fn size_ratio(ratio: f64) -> Result<Limits> {
    let (v, c) = graded_quarter_annulus(1e-3, ratio);
    let mesh = format!(
        r#"{{"kind": "polygons", "vertices": {}, "cells": {}}}"#,
        serde_json::to_string(&v).expect("numbers"),
        serde_json::to_string(&c).expect("numbers")
    );
    let s = scene(
        RIGID,
        "stress",
        0.2,
        &mesh,
        ROLLERS,
        "[]",
        r#"{"velocity": [0.1, 0.2]}"#,
        r#"{"dt_factor": 0.9, "steps": 1}"#,
    )?;
    limits(&Setup::new(&s, &Overrides::default())?, 20_000)
}

/// 10.4: the Poisson ratio. The tension patch, static: the effective `ν` fitted to the element
/// displacements (`u = a x`, `v = b y`, `ν = −b/a`) and the error against the continuum.
#[derive(Debug, Clone)]
pub struct Poisson {
    /// Poisson's ratio of the input.
    pub nu: f64,
    /// `rigid` or `hybrid`.
    pub formulation: &'static str,
    /// `ν` fitted from the displacements.
    pub nu_effective: f64,
    /// `E` fitted from `σ/a`, over the input `E`.
    pub e_ratio: f64,
    /// Critical time step (s).
    pub dt_crit: f64,
    /// A free run at 0.9 `Δt_crit`.
    pub run: Run,
    /// What the checks warned.
    pub warnings: Vec<String>,
}

/// Validation §10.4: the tension patch at Poisson's ratio `nu`, rigid or hybrid, in `plane` (`stress`, `strain`).
pub fn poisson(nu: f64, hybrid: bool, plane: &str) -> Result<Poisson> {
    let f = if hybrid {
        r#"{"kind": "hybrid", "penalty": 1000}"#
    } else {
        RIGID
    };
    let s = scene(
        f,
        plane,
        nu,
        PATCH,
        ROLLERS,
        TENSION,
        "{}",
        r#"{"dt_factor": 0.9, "steps": 1}"#,
    )?;
    let model = Model::build(&s)?;
    let u = statics::solve(&model)?.u;
    let nd = model.formulation.ndof();
    let (mut sxu, mut sxx, mut syv, mut syy) = (0.0, 0.0, 0.0, 0.0);
    for (k, el) in model.elements.iter().enumerate() {
        let x = el.props.centroid;
        sxu += x.x * u[nd * k];
        sxx += x.x * x.x;
        syv += x.y * u[nd * k + 1];
        syy += x.y * x.y;
    }
    let (a, b) = (sxu / sxx, syv / syy);
    // The plane-stress continuum answer a = σ/E; plane strain has a = σ(1 − ν²)/E.
    let e_plane = if plane == "strain" {
        2e10 / (1.0 - nu * nu)
    } else {
        2e10
    };
    let p = Setup::new(&s, &Overrides::default())?;
    Ok(Poisson {
        nu,
        formulation: if hybrid { "hybrid" } else { "rigid" },
        nu_effective: -b / a,
        e_ratio: 1e6 / a / e_plane,
        dt_crit: p.dt_crit,
        run: run_at(&p, 0.9, 4000)?,
        warnings: checks::warnings(&p.model, p.dt, p.dt_crit),
    })
}

/// 10.5: a long undamped run: a 10-element column vibrating freely at 0.9 `Δt_crit`; the largest
/// relative energy drift after each of `checkpoints` steps (central difference conserves its
/// discrete energy exactly on a linear system, so only round-off moves it).
pub fn long_run(checkpoints: &[u64]) -> Result<Vec<(u64, f64)>> {
    let mesh = r#"{"kind": "grid", "origin": [0, 0], "size": [1.0, 0.1], "cells": [10, 1]}"#;
    let s = scene(
        RIGID,
        "stress",
        0.2,
        mesh,
        r#"[{"edge": "left", "kind": "ground-spring"}]"#,
        "[]",
        r#"{"velocity": [1.0, 0.5]}"#,
        r#"{"dt_factor": 0.9, "steps": 1}"#,
    )?;
    let p = Setup::new(&s, &Overrides::default())?;
    let mut cd = p.integrator(p.dt);
    let mut out = Vec::new();
    for &n in checkpoints {
        let status = cd.run(n - cd.step, 100_000, |_, _| Ok(()), |_| ())?;
        if status != Status::Ok {
            break;
        }
        out.push((n, cd.max_relative_drift()));
    }
    Ok(out)
}

/// 10.6: large rigid rotations in contact: a square block spun at `spin` rad/s and dropped on
/// the ground with friction `μ = 0.3`, for `time` seconds.
#[derive(Debug, Clone)]
pub struct Tumble {
    /// `[cells, cells]` elements.
    pub cells: usize,
    /// The largest rotation reached (rad) and the energy drift.
    pub max_rotation: f64,
    /// The run.
    pub run: Run,
    /// The largest elastic energy over the kinetic energy at the start: spurious strain of the
    /// small-rotation interface springs when the block is meshed.
    pub spurious: f64,
    /// What the checks warned.
    pub warnings: Vec<String>,
}

/// Validation §10.6: a block of `cells × cells` elements spun at `spin` rad/s onto the ground for `time` s.
pub fn tumble(cells: usize, spin: f64, time: f64) -> Result<Tumble> {
    let json = format!(
        r#"{{"name": "tumble", "thickness": 0.1, "formulation": {{"kind": "rigid"}}, "gravity": [0, -9.81],
            "materials": {{"m": {{"E": 1e8, "nu": 0.2, "rho": 1000}}}},
            "bodies": [{{"name": "block", "material": "m",
                "mesh": {{"kind": "grid", "origin": [-0.05, 0.05], "size": [0.1, 0.1], "cells": [{cells}, {cells}]}},
                "initial": {{"angular_velocity": {spin}, "velocity": [0.5, 0]}}}}],
            "ground": [{{"from": [-50, 0], "to": [50, 0]}}],
            "contact": {{"model": "edge-to-edge", "friction": 0.3}},
            "time": {{"dt_factor": 0.5, "end": {time}}}}}"#
    );
    let s = Scene::from_json(&json)?;
    let p = Setup::new(&s, &Overrides::default())?;
    let mut cd = p.integrator(p.dt);
    let (mut max_rotation, mut meshed_rotation, mut max_elastic, mut kinetic0) =
        (0.0f64, 0.0f64, 0.0f64, None);
    let status = cd.run(
        p.steps,
        20,
        |snap, e| {
            kinetic0.get_or_insert(e.kinetic);
            max_elastic = max_elastic.max(e.elastic);
            max_rotation = max_rotation.max(checks::largest_rotation(&p.model, snap.u, false));
            meshed_rotation = meshed_rotation.max(checks::largest_rotation(&p.model, snap.u, true));
            Ok(())
        },
        |_| (),
    )?;
    let status = status.describe();
    let finite = cd.u.iter().all(|x| x.is_finite());
    let mut warnings = checks::warnings(&p.model, p.dt, p.dt_crit);
    warnings.extend(checks::rotation_warning(meshed_rotation));
    Ok(Tumble {
        cells,
        max_rotation,
        run: Run {
            fraction: p.dt / p.dt_crit,
            steps: cd.step,
            status,
            drift: cd.max_relative_drift(),
            finite,
        },
        spurious: max_elastic / kinetic0.unwrap_or(f64::NAN),
        warnings,
    })
}

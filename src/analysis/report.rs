//! The JSON answers of the analysis commands (the README's *Commands*): `check`, `static`, `eigen`,
//! `stability`.

use crate::analysis::eigen::{self, Method, Modes};
use crate::error::{Error, Result};
use crate::force::evaluator;
use crate::model::mass::Mass;
use crate::model::Model;
use crate::input::scene::{EvaluatorKind, Scene};
use crate::analysis::stability::{self, Bound, FractionRun};
use crate::analysis::statics;
use crate::analysis::free::FreeSystem;
use serde::Serialize;
use std::path::Path;

#[derive(Serialize)]
/// One element of `rbsm static --json`.
pub struct StaticElement {
    /// Reference centroid (m).
    pub centroid: [f64; 2],
    #[serde(rename = "U")]
    /// Its DOFs `U_e` (m, rad, strains).
    pub u: Vec<f64>,
    /// `(σ_x, σ_y, τ_xy) = D ε` (Pa), hybrid only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stress: Option<[f64; 3]>,
}

#[derive(Serialize)]
/// One interface of `rbsm static --json`.
pub struct StaticInterface {
    /// The first element.
    pub a: u32,
    /// The other element, or `null` for a ground spring.
    pub b: Option<u32>,
    /// Midpoint of the edge (m).
    pub midpoint: [f64; 2],
    /// Unit normal from `a` to `b`.
    pub normal: [f64; 2],
    /// `[t_n, t_s]` (Pa) at the midpoint.
    pub traction: [f64; 2],
}

/// `rbsm static --json`.
#[derive(Serialize)]
pub struct StaticReport {
    /// Every element.
    pub elements: Vec<StaticElement>,
    /// Every interface, ground springs included.
    pub interfaces: Vec<StaticInterface>,
    /// Strain energy `½ Uᵀ K U` (J).
    pub energy: f64,
}

/// Solves the static problem of a scene; the report, the model and its displacements `U`.
pub fn static_report(scene: &Scene) -> Result<(StaticReport, Model, Vec<f64>)> {
    let model = Model::build(scene)?;
    let sol = statics::solve(&model)?;
    let nd = model.formulation.ndof();
    let elements = model
        .elements
        .iter()
        .enumerate()
        .map(|(e, el)| {
            let u = &sol.u[e * nd..(e + 1) * nd];
            StaticElement {
                centroid: [el.props.centroid.x, el.props.centroid.y],
                u: u.to_vec(),
                stress: crate::output::element_stress(&model, e, u),
            }
        })
        .collect();
    let interfaces = model
        .interfaces
        .iter()
        .map(|i| StaticInterface {
            a: i.a,
            b: (i.b != crate::model::GROUND).then_some(i.b),
            midpoint: [i.midpoint().x, i.midpoint().y],
            normal: [i.normal.x, i.normal.y],
            traction: statics::midpoint_traction(&model, i, &sol.u),
        })
        .collect();
    Ok((
        StaticReport {
            elements,
            interfaces,
            energy: sol.energy,
        },
        model,
        sol.u,
    ))
}

/// Writes what `rbsm static --out DIR` gives: `summary.json` (the report), `final_state.json`
/// (`U`, zero `V`), `probes.csv` (`probe,value,unit` for the scene's probes) and the frame
/// `static.vtu` with its collection `series.pvd`.
pub fn write_static(
    dir: &Path,
    scene: &Scene,
    report: &StaticReport,
    model: &Model,
    u: &[f64],
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    crate::output::write_json(&dir.join("summary.json"), report)?;
    let v = vec![0.0; u.len()];
    crate::output::write_final_state(dir, model, 0.0, u, &v)?;
    write_probe_rows(
        dir,
        scene,
        model,
        &["case"],
        &[(vec!["static".to_string()], u)],
    )?;
    crate::output::vtk::write_frame(
        &dir.join("static.vtu"),
        model,
        u,
        &v,
        crate::output::vtk::Placement::Linear,
    )?;
    crate::output::vtk::write_collection(&dir.join("series.pvd"), &[(0.0, "static.vtu".into())])
}

/// Writes what `rbsm eigen --out DIR` gives: `summary.json` (the report), the shapes as
/// `mode_NNN.vtu` with `modes.pvd`, and `probes.csv` (per mode its number, frequency and each
/// probe of the `M`-normalised shape).
pub fn write_eigen(
    dir: &Path,
    scene: &Scene,
    report: &EigenReport,
    model: &Model,
    modes: &Modes,
) -> Result<()> {
    crate::output::vtk::write_mode_shapes(dir, model, &modes.shapes)?;
    crate::output::write_json(&dir.join("summary.json"), report)?;
    let rows: Vec<(Vec<String>, &[f64])> = modes
        .shapes
        .iter()
        .zip(&report.frequencies_hz)
        .enumerate()
        .map(|(k, (shape, f))| {
            (
                vec![(k + 1).to_string(), format!("{f:e}")],
                shape.as_slice(),
            )
        })
        .collect();
    write_probe_rows(dir, scene, model, &["mode", "frequency_hz"], &rows)
}

/// `probes.csv`: the columns `keys`, then one column per probe of `scene` (its unit in the
/// header, `name (m)`), a row per `(key values, displacements)`.
fn write_probe_rows(
    dir: &Path,
    scene: &Scene,
    model: &Model,
    keys: &[&str],
    rows: &[(Vec<String>, &[f64])],
) -> Result<()> {
    let probes = crate::analysis::run::probes(scene, model)?;
    if probes.is_empty() {
        return Ok(());
    }
    let mut text = keys.join(",");
    for p in &probes {
        text.push_str(&format!(",{} ({})", p.name, p.unit()));
    }
    text.push('\n');
    for (key, u) in rows {
        text.push_str(&key.join(","));
        for p in &probes {
            text.push_str(&format!(",{:e}", p.value(u)));
        }
        text.push('\n');
    }
    crate::output::write_atomic(&dir.join("probes.csv"), text.as_bytes())
}

/// `rbsm eigen --json`.
#[derive(Serialize)]
pub struct EigenReport {
    /// Free DOFs.
    pub dofs: usize,
    /// Frequencies of the lowest modes (Hz).
    pub frequencies_hz: Vec<f64>,
    /// Their circular frequencies `ω` (rad/s).
    pub omega: Vec<f64>,
    /// Largest circular frequency (rad/s).
    pub omega_max: f64,
    /// `2/ω_max` (s).
    pub dt_crit: f64,
    /// `dense` or `sparse`.
    pub method: &'static str,
}

/// The lowest `n_modes` modes of a scene, and the model and modes for mode-shape output.
pub fn eigen_report(
    scene: &Scene,
    n_modes: usize,
    method: Method,
) -> Result<(EigenReport, Model, Modes)> {
    let model = Model::build(scene)?;
    let mass = Mass::new(&model);
    let sys = FreeSystem::new(&model, &mass);
    let ev = evaluator::build(&model, EvaluatorKind::Assembled);
    let modes = eigen::modes(&sys, ev.as_ref(), &mass, n_modes, method)?;
    let report = EigenReport {
        dofs: sys.n(),
        frequencies_hz: modes
            .omega
            .iter()
            .map(|w| w / (2.0 * std::f64::consts::PI))
            .collect(),
        omega: modes.omega.clone(),
        omega_max: modes.omega_max,
        dt_crit: stability::critical_time_step(modes.omega_max),
        method: modes.method,
    };
    Ok((report, model, modes))
}

#[derive(Serialize)]
/// The empirical stability limit found by bisection.
pub struct Empirical {
    /// Largest stable time step found (s).
    pub dt: f64,
    /// Its ratio to `Δt_crit`.
    pub ratio: f64,
}

/// `rbsm stability --json`.
#[derive(Serialize)]
pub struct StabilityReport {
    /// Largest circular frequency (rad/s).
    pub omega_max: f64,
    /// `2/ω_max` (s).
    pub dt_crit: f64,
    /// The cheap estimates and how they compare.
    pub bounds: Vec<Bound>,
    /// The limit found by running.
    pub empirical: Empirical,
    /// The runs at the asked fractions of `Δt_crit`.
    pub fractions: Vec<FractionRun>,
}

/// The exact limit, the bounds, the empirical limit (bisection to `1e-4`) and undamped runs at
/// the given fractions of `Δt_crit`, each `steps` long.
pub fn stability_report(scene: &Scene, fractions: &[f64], steps: u64) -> Result<StabilityReport> {
    let model = Model::build(scene)?;
    let mass = Mass::new(&model);
    let sys = FreeSystem::new(&model, &mass);
    let ev = evaluator::build(&model, scene.evaluator);
    let omega_max = if sys.n() <= eigen::DENSE_LIMIT {
        eigen::dense_modes(&sys, &mass, 0)?.omega_max
    } else {
        eigen::omega_max(&model, ev.as_ref(), &mass)
    };
    let dt_crit = stability::critical_time_step(omega_max);
    let bounds = stability::bounds(&model, &sys, &mass, dt_crit);
    let (dt, ratio) = stability::empirical_limit(&model, ev.as_ref(), &mass, dt_crit, steps, 1e-4);
    let fractions = fractions
        .iter()
        .map(|&f| stability::run_at_fraction(&model, ev.as_ref(), &mass, dt_crit, f, steps))
        .collect();
    Ok(StabilityReport {
        omega_max,
        dt_crit,
        bounds,
        empirical: Empirical { dt, ratio },
        fractions,
    })
}

/// `rbsm check --json`: what a run of the scene would model, without running it.
#[derive(Serialize)]
pub struct CheckReport {
    /// The scene's name.
    pub scene: String,
    /// `rigid` or `hybrid`.
    pub formulation: &'static str,
    /// `assembled` or `element-wise`.
    pub evaluator: &'static str,
    /// Number of bodies.
    pub bodies: usize,
    /// Number of elements.
    pub elements: usize,
    /// Interfaces between two elements, and ground springs (supports).
    pub interfaces: usize,
    /// Boundary edges tied to ground by springs.
    pub ground_springs: usize,
    /// Free DOFs.
    pub dofs: usize,
    /// DOFs fixed by clamps.
    pub fixed_dofs: usize,
    /// Point loads that the tractions and forces become.
    pub loads: usize,
    /// Gravitational acceleration (m/s²).
    pub gravity: [f64; 2],
    /// `None` without a `contact` section: then no contact work is done.
    pub contact: Option<ContactCheck>,
    /// Largest circular frequency (rad/s) and `Δt_crit = 2/ω_max` (s).
    pub omega_max: f64,
    /// `2/ω_max` (s).
    pub dt_crit: f64,
    /// The time step a run would take (s), its ratio to `Δt_crit`, and the steps.
    pub dt: f64,
    /// `dt / Δt_crit`.
    pub dt_ratio: f64,
    /// Steps a run would take.
    pub steps: u64,
    /// Bytes a run holds for stepping: the evaluator's data, `M` and `M⁻¹`, and the
    /// integrator's vectors (`U`, `v`, force, averaged velocity, and the guard's `U`, `v`).
    pub memory_bytes: usize,
    /// What the checks warn about the scene.
    pub warnings: Vec<String>,
}

/// The contact a run would model.
#[derive(Serialize)]
pub struct ContactCheck {
    /// `edge-to-edge` or `point`.
    pub model: &'static str,
    /// Vertices that can touch and edges they can touch (ground segments included).
    pub vertices: usize,
    /// Edges that can be touched, ground segments included.
    pub edges: usize,
    /// Vertex–edge pairs near enough to be tested at the start, and those in contact there.
    pub pairs_tested_at_start: u64,
    /// Vertex–edge pairs in contact at the start.
    pub pairs_in_contact_at_start: usize,
}

/// Validates `scene` and everything a run would build (mesh, model, probes, `Δt_crit`, the
/// time step) without stepping.
pub fn check_report(scene: &Scene, opts: &crate::analysis::run::RunOptions) -> Result<CheckReport> {
    let p = crate::analysis::run::Prepared::new(scene, opts)?;
    crate::analysis::run::probes(scene, &p.model)?;
    let m = &p.model;
    let contact = crate::force::contact::Contact::new(m).map(|mut c| {
        let n = m.n_dofs();
        c.apply(
            0,
            &vec![0.0; n],
            &m.initial_velocity,
            p.dt,
            &mut vec![0.0; n],
        );
        let (vertices, edges) = c.extent();
        ContactCheck {
            model: c.settings.model.name(),
            vertices,
            edges,
            pairs_tested_at_start: c.stats.tests,
            pairs_in_contact_at_start: c.live(),
        }
    });
    let ground_springs = m
        .interfaces
        .iter()
        .filter(|i| i.b == crate::model::GROUND)
        .count();
    let mass_bytes = 8 * p.mass.triplets().len() * if p.mass.is_diagonal() { 2 } else { 4 };
    Ok(CheckReport {
        scene: m.name.clone(),
        formulation: m.formulation.name(),
        evaluator: p.evaluator.kind().name(),
        bodies: m.bodies.len(),
        elements: m.elements.len(),
        interfaces: m.interfaces.len() - ground_springs,
        ground_springs,
        dofs: m.n_dofs(),
        fixed_dofs: m.fixed.len(),
        loads: m.loads.len(),
        gravity: [m.gravity.x, m.gravity.y],
        contact,
        omega_max: p.omega_max,
        dt_crit: p.dt_crit,
        dt: p.dt,
        dt_ratio: p.dt / p.dt_crit,
        steps: p.steps,
        memory_bytes: p.evaluator.bytes() + mass_bytes + 6 * 8 * m.n_dofs(),
        warnings: crate::model::checks::warnings(m, p.dt, p.dt_crit),
    })
}

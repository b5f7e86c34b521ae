//! The JSON answers of the analysis commands (DESIGN.md §9): `static`, `eigen`, `stability`.

use crate::error::Result;
use crate::eigen::{self, Method, Modes};
use crate::evaluator;
use crate::mass::Mass;
use crate::model::Model;
use crate::scene::{EvaluatorKind, Scene};
use crate::stability::{self, Bound, FractionRun};
use crate::statics;
use crate::system::FreeSystem;
use serde::Serialize;

#[derive(Serialize)]
pub struct StaticElement {
    pub centroid: [f64; 2],
    #[serde(rename = "U")]
    pub u: Vec<f64>,
    /// `(σ_x, σ_y, τ_xy) = D ε` (Pa), hybrid only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stress: Option<[f64; 3]>,
}

#[derive(Serialize)]
pub struct StaticInterface {
    pub a: u32,
    /// The other element, or `null` for a ground spring.
    pub b: Option<u32>,
    pub midpoint: [f64; 2],
    pub normal: [f64; 2],
    /// `[t_n, t_s]` (Pa) at the midpoint.
    pub traction: [f64; 2],
}

/// `rbsm static --json`.
#[derive(Serialize)]
pub struct StaticReport {
    pub elements: Vec<StaticElement>,
    pub interfaces: Vec<StaticInterface>,
    /// Strain energy `½ Uᵀ K U` (J).
    pub energy: f64,
}

/// Solves the static problem of a scene.
pub fn static_report(scene: &Scene) -> Result<StaticReport> {
    let model = Model::build(scene)?;
    let sol = statics::solve(&model)?;
    let nd = model.formulation.ndof();
    let elements = model
        .elements
        .iter()
        .enumerate()
        .map(|(e, el)| {
            let u = &sol.u[e * nd..(e + 1) * nd];
            StaticElement { centroid: [el.props.centroid.x, el.props.centroid.y], u: u.to_vec(), stress: crate::output::element_stress(&model, e, u) }
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
    Ok(StaticReport { elements, interfaces, energy: sol.energy })
}

/// `rbsm eigen --json`.
#[derive(Serialize)]
pub struct EigenReport {
    /// Free DOFs.
    pub dofs: usize,
    pub frequencies_hz: Vec<f64>,
    pub omega: Vec<f64>,
    pub omega_max: f64,
    pub dt_crit: f64,
    pub method: &'static str,
}

/// The lowest `n_modes` modes of a scene, and the model and modes for mode-shape output.
pub fn eigen_report(scene: &Scene, n_modes: usize, method: Method) -> Result<(EigenReport, Model, Modes)> {
    let model = Model::build(scene)?;
    let mass = Mass::new(&model);
    let sys = FreeSystem::new(&model, &mass);
    let ev = evaluator::build(&model, EvaluatorKind::Assembled);
    let modes = eigen::modes(&sys, ev.as_ref(), &mass, n_modes, method)?;
    let report = EigenReport {
        dofs: sys.n(),
        frequencies_hz: modes.omega.iter().map(|w| w / (2.0 * std::f64::consts::PI)).collect(),
        omega: modes.omega.clone(),
        omega_max: modes.omega_max,
        dt_crit: stability::critical_time_step(modes.omega_max),
        method: modes.method,
    };
    Ok((report, model, modes))
}

#[derive(Serialize)]
pub struct Empirical {
    pub dt: f64,
    pub ratio: f64,
}

/// `rbsm stability --json`.
#[derive(Serialize)]
pub struct StabilityReport {
    pub omega_max: f64,
    pub dt_crit: f64,
    pub bounds: Vec<Bound>,
    pub empirical: Empirical,
    pub fractions: Vec<FractionRun>,
}

/// The exact limit, the bounds, the empirical limit (bisection to `1e-4`) and undamped runs at
/// the given fractions of `Δt_crit`, each `steps` long.
pub fn stability_report(scene: &Scene, fractions: &[f64], steps: u64) -> Result<StabilityReport> {
    let model = Model::build(scene)?;
    let mass = Mass::new(&model);
    let sys = FreeSystem::new(&model, &mass);
    let ev = evaluator::build(&model, scene.evaluator);
    let omega_max = if sys.n() <= eigen::DENSE_LIMIT { eigen::dense_modes(&sys, &mass, 0)?.omega_max } else { eigen::omega_max(ev.as_ref(), &mass) };
    let dt_crit = stability::critical_time_step(omega_max);
    let bounds = stability::bounds(&model, &sys, &mass, dt_crit);
    let (dt, ratio) = stability::empirical_limit(&model, ev.as_ref(), &mass, dt_crit, steps, 1e-4);
    let fractions = fractions.iter().map(|&f| stability::run_at_fraction(&model, ev.as_ref(), &mass, dt_crit, f, steps)).collect();
    Ok(StabilityReport { omega_max, dt_crit, bounds, empirical: Empirical { dt, ratio }, fractions })
}

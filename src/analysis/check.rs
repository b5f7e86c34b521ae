//! `rbsm check`: what a run of a scene would model (elements, interfaces, DOFs, contact,
//! `Δt_crit`, the time step, the memory), without running it.

use crate::analysis::setup::Setup;
use crate::analysis::Report;
use crate::error::Result;
use crate::output::count;
use serde::Serialize;

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
    /// Interfaces between two elements (ground springs apart).
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
    /// The step proven stable without `ω_max` (s), what `run` checks a given `dt` against
    /// ([`crate::analysis::limit::Limit`]).
    pub dt_safe: f64,
    /// The time step a run would take (s), its ratio to `Δt_crit`, and the steps.
    pub dt: f64,
    /// `dt / Δt_crit`.
    pub dt_ratio: f64,
    /// Steps a run would take.
    pub steps: u64,
    /// Whether a run at `dt` would diverge: `dt` above `Δt_crit` (or above `2/ω_floor`, the
    /// proven upper bound of `Δt_crit`); `rbsm check` then exits with [`UNSTABLE_EXIT`].
    pub unstable: bool,
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

/// The exit code of `rbsm check` for a valid scene whose run would diverge
/// ([`CheckReport::unstable`]); 1 is bad input, 2 a usage error, 3 a diverged run, 130 an
/// interrupted one.
pub const UNSTABLE_EXIT: u8 = 4;

/// Checks everything a run of the setup would build (mesh, model, probes, `Δt_crit` to full
/// precision, the time step; the setup has built the rest) without stepping. The time step
/// reported is the setup's: that of a run when the setup is built as a run's (a `dt_factor`
/// taken of `Δt_crit` to [`crate::analysis::limit::FOR_STEP`]).
///
/// # Errors
/// A probe of the scene names an element outside the model, a point `at` in no element or a DOF the
/// formulation does not have ([`Setup::probes`]).
pub fn check(p: &Setup) -> Result<CheckReport> {
    p.probes()?;
    let m = &p.model;
    let contact = p.contact.clone().map(|mut c| {
        let n = m.n_dofs();
        c.apply(
            &*m.law,
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
    let ground_springs = m.ground_springs();
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
        omega_max: p.omega_max(),
        dt_crit: p.dt_crit(),
        dt_safe: p.limit.dt_safe(),
        dt: p.dt,
        dt_ratio: p.dt / p.dt_crit(),
        steps: p.steps,
        unstable: p.dt > p.dt_crit() || p.dt > p.limit.dt_ceiling(),
        memory_bytes: p.evaluator.bytes() + mass_bytes + 6 * 8 * m.n_dofs(),
        warnings: dt_warnings(p),
    })
}

/// The model's warnings, and the time step's against the exact `Δt_crit` that `check` has
/// computed (the run's own warning speaks of what a run knows: the proven-safe step, or its
/// Lanczos estimate).
fn dt_warnings(p: &Setup) -> Vec<String> {
    let mut warnings = crate::model::checks::warnings(&p.model);
    let exact = p.dt_crit();
    if let Some(mut w) = crate::analysis::limit::above_limit(p.dt, exact, 6) {
        if let Some(run) = p.limit.dt_crit().filter(|&run| run > exact && p.dt <= run) {
            w += &format!(
                ". The run takes `dt_factor` of its own Δt_crit, {run:.6e} s, which Lanczos \
                 settles to 1e-4 and which lies {:.1e} above the exact one: so close to 1, lower \
                 `dt_factor` or pass `--exact-dt-crit`",
                run / exact - 1.0
            );
        }
        warnings.push(w);
    }
    warnings
}

impl Report for CheckReport {
    fn text(&self) -> String {
        let r = self;
        let mut t = format!("{}: valid\n", r.scene);
        t += &format!(
            "  {}, {} ({} formulation, {} evaluator)\n",
            count(r.bodies, "body", "bodies"),
            count(r.elements, "element", "elements"),
            r.formulation,
            r.evaluator
        );
        t += &format!(
            "  {} between elements, {}; {}, {} fixed\n",
            count(r.interfaces, "interface", "interfaces"),
            count(r.ground_springs, "ground spring", "ground springs"),
            count(r.dofs, "DOF", "DOFs"),
            r.fixed_dofs
        );
        t += &format!(
            "  {}; {}\n",
            count(r.loads, "point load", "point loads"),
            match r.gravity {
                [0.0, 0.0] => "no gravity".to_string(),
                [x, y] => format!("gravity ({x}, {y}) m/s²"),
            }
        );
        t += &match &r.contact {
            None => "  contact: none declared (no contact search)\n".to_string(),
            Some(c) => format!(
                "  contact: {}, {} against {}; at the start {} tested, {} in contact\n",
                c.model,
                count(c.vertices, "vertex", "vertices"),
                count(c.edges, "edge", "edges"),
                count(c.pairs_tested_at_start as usize, "pair", "pairs"),
                c.pairs_in_contact_at_start
            ),
        };
        t += &format!(
            "  ω_max = {:.6e} rad/s, Δt_crit = {:.6e} s (proven-safe step without it: {:.4} Δt_crit)\n",
            r.omega_max,
            r.dt_crit,
            r.dt_safe / r.dt_crit
        );
        t += &format!(
            "  dt = {:.6e} s = {:.4} Δt_crit, {}\n",
            r.dt,
            r.dt_ratio,
            count(r.steps as usize, "step", "steps")
        );
        t += &format!(
            "  memory for stepping: {}",
            crate::output::human_bytes(r.memory_bytes)
        );
        for w in &r.warnings {
            t += &format!("\n  warning: {w}");
        }
        if r.unstable {
            t += &format!(
                "\n  unstable: a run at this dt would diverge (exit code {UNSTABLE_EXIT})"
            );
        }
        t
    }
}

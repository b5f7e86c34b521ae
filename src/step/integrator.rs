//! Explicit central difference in velocity form (paper_notes.md item 9), with energy bookkeeping
//! and a
//! divergence guard:
//!
//! `v^{n+½} = v^{n−½} + Δt M⁻¹ (P(t_n) − f_int(U^n) + f_c^n)`, `U^{n+1} = U^n + Δt v^{n+½}`,
//! started with `v^{−½} = v^0 − ½ Δt a^0`. With mass-proportional damping `C = α M` the velocity
//! update is `v^{n+½} = ((1 − αΔt/2) v^{n−½} + Δt a^n) / (1 + αΔt/2)`. The contact forces
//! `f_c^n` come from the [`Contact`] of the model, built only when its scene declares contact.

use crate::error::Result;
use crate::force::contact::Contact;
use crate::force::evaluator::{Evaluator, GroupedStep};
use crate::force::failure::{FailureState, PlasticForces};
use crate::force::yielding::{ElementState, PlasticElements};
use crate::input::names::named;
use crate::model::law::InterfaceLaw;
use crate::model::loads::Loads;
use crate::model::mass::{Mass, Update};
use crate::model::{Model, Prescribed};
use crate::parallel::{for_each_chunk, STREAM_CHUNK};
use crate::step::balance::Balance;
use crate::step::grouped::{Groups, MIN_STRETCH};
use crate::step::local::LocalDamping;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The energies at one time (J); `total = kinetic + elastic + contact + potential + fracture +
/// friction + plastic + damping − external_work` is constant, up to the integrator's error.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Energy {
    /// Time (s).
    pub t: f64,
    /// Kinetic energy `½ vᵀ M v` (J).
    pub kinetic: f64,
    /// Elastic energy `½ Uᵀ K U` of the springs and, hybrid, of the elements' interiors (J).
    pub elastic: f64,
    /// Minus the work of the contact forces: stored in the contact springs plus what friction took
    /// from the motion (J).
    pub contact: f64,
    /// Gravitational potential energy relative to the initial configuration.
    pub potential: f64,
    /// Work done by the applied loads and the moving clamps since the start.
    pub external_work: f64,
    /// Work of the interfaces' strengths (tension and cohesion) so far (J; failing laws).
    pub fracture: f64,
    /// Work of friction on the interfaces so far (J; failing laws).
    pub friction: f64,
    /// Work of the plastic flow of the elements so far (J; hybrid elements that yield).
    #[serde(default)]
    pub plastic: f64,
    /// Work of the damping so far, mass-proportional and local (J).
    pub damping: f64,
    /// `kinetic + elastic + contact + potential + fracture + friction + plastic + damping −
    /// external_work` (J).
    pub total: f64,
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Status {
    /// Every step was taken.
    Ok,
    /// Stopped at `step` (time `t`) because the interrupt flag was raised
    /// ([`CentralDifference::stop_on`]); that step was recorded like a last one.
    Interrupted {
        /// The step reached.
        step: u64,
        /// Its time (s).
        t: f64,
    },
    /// Stopped at `step` (time `t`) for `reason`; the state is the last one that passed the guard.
    Diverged {
        /// The step at which the guard failed.
        step: u64,
        /// Its time (s).
        t: f64,
        /// What the guard saw: energy growth or a NaN.
        reason: String,
    },
}

/// The state at a recorded step: displacements `U^n` and velocities `v^n`.
pub struct Snapshot<'a> {
    /// Step number `n`.
    pub step: u64,
    /// Time `t_n` (s).
    pub t: f64,
    /// Displacements `U^n`, `ndof` per element (m, rad and strains).
    pub u: &'a [f64],
    /// Whole-step velocities `v^n` (m/s, rad/s, 1/s).
    pub v: &'a [f64],
    /// Each moving clamp's reaction along its velocity (N): what it pushes the body with.
    pub reactions: &'a [f64],
    /// Each moving clamp's largest reaction so far, over every step (not only the recorded
    /// ones), and the time it was reached: `[R (N), t (s)]`.
    pub peaks: &'a [[f64; 2]],
    /// The state of the failing interfaces, when the model has any.
    pub failure: Option<&'a FailureState>,
    /// The plastic state of the elements, when some may yield.
    pub elements: Option<&'a ElementState>,
}

/// The kinetic plus elastic energy may not exceed this multiple of the energy put in (the
/// initial energy plus the work of loads and gravity to the end of the step under way) before
/// a run counts as diverged. A mode
/// stepped at `f Δt_crit` holds up to `1/(1 − f²)` times its conserved energy as strain at its
/// turning points; when the integrator knows `Δt_crit` ([`CentralDifference::set_stability_limit`])
/// the limit is widened by that factor, so that a stable run at 0.999 `Δt_crit` is not stopped.
/// An unstable run grows geometrically and crosses it within a few hundred steps.
pub const GROWTH_LIMIT: f64 = 4.0;

/// The energy balance (the total energy, every work and dissipation booked) may not move by
/// more than this fraction of the energy put in before a run counts as diverged. A run whose
/// energy stays bounded but whose books break (contact stepped above its own limit, which
/// pumps energy in and takes it out at each impact) is stopped so; a stable run keeps its
/// balance to the step's error, 1e-3 of the energy put in on the bundled scenes.
pub const BALANCE_LIMIT: f64 = 0.1;

/// Steps between two divergence checks when no output is due sooner.
pub const CHECK_EVERY: u64 = 100;

/// The last state that passed the divergence guard: a run that diverges returns to it.
#[derive(Debug, Default)]
struct Good {
    step: u64,
    t: f64,
    u: Vec<f64>,
    /// Whole-step velocities `v^n`.
    velocity: Vec<f64>,
    /// The energy bookkeeping of that state, so that a diverged run reports its drift and
    /// works up to it, not the rejected steps'.
    ledger: EnergyLedger,
}

/// Central-difference time stepping of one model with one evaluator.
pub struct CentralDifference<'a> {
    evaluator: &'a dyn Evaluator,
    mass: &'a Mass,
    loads: &'a Loads,
    /// Mass-proportional damping `α` (1/s): the model's, or none ([`CentralDifference::undamped`]).
    damping: f64,
    /// Local non-viscous damping, when the model has it ([`crate::step::local`]).
    local: Option<LocalDamping>,
    /// The unbalanced-force ratio and its stop, when the model has one
    /// ([`crate::step::balance`]).
    balance: Option<Balance>,
    /// The step and time at which the run settled below its ratio, once it has.
    settled: Option<(u64, f64)>,
    /// Time step `Δt` (s), fixed at construction.
    dt: f64,
    /// Time `t_n` of the current state (s).
    pub t: f64,
    /// Steps taken, `n`.
    pub step: u64,
    /// Displacements `U^n`.
    pub u: Vec<f64>,
    /// Half-step velocities `v^{n−½}`.
    pub v: Vec<f64>,
    force: Vec<f64>,
    /// Whether `force` is all zero, as a fused step leaves it.
    force_clear: bool,
    scratch: Vec<f64>,
    /// Contact state and forces; `None` for a scene without contact.
    pub contact: Option<Contact>,
    /// The model's interface law, which gives the contact springs their traction.
    law: &'a dyn InterfaceLaw,
    /// The elements where `−P − f_c` can be non-zero, when the loads name them (no gravity, no
    /// contact): a fused step reads `force` only there.
    loaded: Option<Vec<u32>>,
    /// The energy bookkeeping: what was put in and taken out so far.
    ledger: EnergyLedger,
    /// The last state that passed the guard, to which a diverged run is rolled back.
    good: Good,
    /// The failing interfaces' state at the step of `good`.
    good_failure: FailureState,
    /// Whether `v` already holds `v^{n+½}` of the current step `n`: a run ended there after its
    /// last record, and the next step only has `U` left to move.
    pending: bool,
    /// `Δt / Δt_crit` when the caller knows `Δt_crit`: the guard then allows for the energy
    /// that the averaged velocity misses in stable modes near the limit.
    fraction: Option<f64>,
    /// Raised from outside (a signal handler) to stop the run at the next step.
    interrupt: Option<Arc<AtomicBool>>,
    /// The plastic forces and the state of the failing interfaces, when the model has any.
    failure: Option<(&'a dyn PlasticForces, FailureState)>,
    /// The elements that may yield and their plastic state, when the model has any.
    elements: Option<(&'a PlasticElements, ElementState)>,
    /// The elements' plastic state at the step of `good`.
    good_elements: ElementState,
    /// The moving clamps, their element masses (kg) per DOF, and their reactions at the last
    /// check.
    prescribed: &'a [Prescribed],
    clamp_mass: Vec<Vec<f64>>,
    reactions: Vec<f64>,
    /// Each moving clamp's largest reaction over every step so far and its time `[R, t]`.
    peaks: Vec<[f64; 2]>,
    /// The state in groups of four elements, for a fused step that goes in lanes
    /// ([`crate::step::grouped`]): the steps between two checks run on it.
    groups: Option<Groups>,
}

named! {
    /// How a run ended, without where or why: the `status` of `summary.json` (`ok`,
    /// `interrupted` or `diverged`, the README's *Outputs*).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum RunStatus {
        /// Every step was taken.
        "ok" => Ok,
        /// Stopped by the interrupt flag.
        "interrupted" => Interrupted,
        /// Stopped by the guard.
        "diverged" => Diverged,
    }
}

impl Status {
    /// The kind of ending, without its details.
    pub fn kind(&self) -> RunStatus {
        match self {
            Status::Ok => RunStatus::Ok,
            Status::Interrupted { .. } => RunStatus::Interrupted,
            Status::Diverged { .. } => RunStatus::Diverged,
        }
    }

    /// Where a run stopped early, and why when it diverged: `at step N (t = T s)` or
    /// `at step N (t = T s): reason`; `None` for [`Status::Ok`].
    pub fn detail(&self) -> Option<String> {
        match self {
            Status::Ok => None,
            Status::Interrupted { step, t } => Some(format!("at step {step} (t = {t:.6e} s)")),
            Status::Diverged { step, t, reason } => {
                Some(format!("at step {step} (t = {t:.6e} s): {reason}"))
            }
        }
    }

    /// `ok`, `interrupted at step N (t = T s)` or `diverged at step N (t = T s): reason`: the
    /// kind followed by the [`detail`](Status::detail).
    pub fn describe(&self) -> String {
        match self.detail() {
            None => self.kind().to_string(),
            Some(detail) => format!("{} {detail}", self.kind()),
        }
    }
}

/// The energy bookkeeping of a run (J): the contact energy and the loads' work so far, and
/// what the guard and the drift measure keep.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
struct EnergyLedger {
    /// Contact energy at `t_n`: minus the work of the contact forces (`Contact::apply`).
    contact_energy: f64,
    /// Work of the applied loads and of the moving clamps (at rest mass) since the start.
    external_work: f64,
    /// Work of the damping since the start.
    damping: f64,
    /// The moving clamps' work booked for the half step after the last check.
    clamp_ahead: f64,
    /// The total energy at the first check.
    initial_total: Option<f64>,
    /// The largest energy put in so far (the guard's measure).
    energy_in_max: f64,
    /// What the guard counts as stored (kinetic, elastic and contact) at the first check.
    initial_stored: Option<f64>,
    /// Largest `|total − total(0)|` so far.
    max_drift: f64,
}

/// Everything a run needs to go on from a recorded step, bit for bit: the state after that
/// step's check (`U^n`, `v^{n+½}`, `v^n`), the energy bookkeeping and the contact state
/// (see [`CentralDifference::state`]). Written as a checkpoint.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct State {
    dt: f64,
    step: u64,
    u: Vec<f64>,
    v: Vec<f64>,
    velocity: Vec<f64>,
    contact: Option<Contact>,
    failure: Option<FailureState>,
    #[serde(default)]
    elements: Option<ElementState>,
    ledger: EnergyLedger,
    peaks: Vec<[f64; 2]>,
}

impl State {
    /// The step of the state.
    pub fn step(&self) -> u64 {
        self.step
    }
}

impl<'a> CentralDifference<'a> {
    /// Starts at `t = 0` in the reference configuration with the model's initial velocities;
    /// `contact` is the model's contact in its initial state (`Contact::new`), `None` for a
    /// scene without contact.
    pub fn new(
        model: &'a Model,
        evaluator: &'a dyn Evaluator,
        mass: &'a Mass,
        loads: &'a Loads,
        contact: Option<Contact>,
        dt: f64,
    ) -> Self {
        Self::from_state(
            model,
            evaluator,
            mass,
            loads,
            contact,
            dt,
            vec![0.0; model.n_dofs()],
            model.initial_velocity.clone(),
        )
    }

    /// Starts at `t = 0` from displacements `u0` and velocities `v0` (fixed DOFs are zeroed):
    /// `v^{−½} = v^0 − ½ Δt a^0`.
    #[allow(clippy::too_many_arguments)]
    pub fn from_state(
        model: &'a Model,
        evaluator: &'a dyn Evaluator,
        mass: &'a Mass,
        loads: &'a Loads,
        contact: Option<Contact>,
        dt: f64,
        mut u0: Vec<f64>,
        mut v0: Vec<f64>,
    ) -> Self {
        let n = model.n_dofs();
        for &d in &model.fixed {
            u0[d] = 0.0;
            v0[d] = 0.0;
        }
        let mut s = CentralDifference {
            evaluator,
            mass,
            loads,
            damping: model.damping,
            local: LocalDamping::new(model.local_damping, n, &model.fixed),
            balance: Balance::new(model.stop_ratio, model.formulation.ndof(), n, &model.fixed),
            settled: None,
            dt,
            t: 0.0,
            step: 0,
            u: u0,
            v: v0,
            force: vec![0.0; n],
            force_clear: false,
            scratch: vec![0.0; n],
            contact,
            law: &*model.law,
            loaded: None,
            ledger: EnergyLedger::default(),
            good: Good {
                step: 0,
                t: 0.0,
                u: vec![0.0; n],
                velocity: vec![0.0; n],
                ledger: EnergyLedger::default(),
            },
            good_failure: FailureState::default(),
            fraction: None,
            pending: false,
            interrupt: None,
            failure: None,
            elements: None,
            good_elements: ElementState::default(),
            prescribed: &[],
            clamp_mass: Vec::new(),
            reactions: Vec::new(),
            peaks: Vec::new(),
            groups: None,
        };
        if s.contact.is_none() {
            s.loaded = loads.loaded_elements();
        }
        let undamped = s.damping == 0.0 && s.local.is_none();
        s.groups = Groups::new(evaluator, mass, n, undamped, s.loaded.is_some());
        s.net_force(false);
        mass.advance(&s.force, &mut s.v, &mut [], -0.5 * dt, (1.0, 1.0));
        s
    }

    /// Lets the interfaces of `plastic` fail, from a state where all are elastic. The start
    /// `v^{−½}` was taken with elastic springs, which is exact when `U^0` is within the
    /// strengths (as the reference configuration `U^0 = 0` is).
    pub fn with_failure(mut self, plastic: &'a dyn PlasticForces) -> Self {
        self.good_failure = plastic.initial();
        self.failure = Some((plastic, plastic.initial()));
        self.groups = None;
        self
    }

    /// Lets the elements of `elements` yield, from a state where all are elastic (as
    /// [`CentralDifference::with_failure`] lets interfaces fail). Such a step goes through the
    /// net force, where the return mapping corrects the elements' interior forces.
    pub fn with_plastic_elements(mut self, elements: &'a PlasticElements) -> Self {
        self.good_elements = elements.initial();
        self.elements = Some((elements, elements.initial()));
        self.groups = None;
        self
    }

    /// Moves the clamps of `model.prescribed` (displacement control). Their DOFs must be fixed
    /// DOFs of the model, as `Model::build` makes them.
    pub fn with_prescribed(mut self, model: &'a Model) -> Self {
        let nd = model.formulation.ndof();
        self.prescribed = &model.prescribed;
        if !self.prescribed.is_empty() {
            self.groups = None;
        }
        self.clamp_mass = model
            .prescribed
            .iter()
            .map(|p| {
                p.dofs
                    .iter()
                    .map(|&(d, _)| {
                        let e = &model.elements[d / nd];
                        e.rho * model.thickness * e.props.area
                    })
                    .collect()
            })
            .collect();
        self.reactions = vec![0.0; model.prescribed.len()];
        self.peaks = vec![[f64::NEG_INFINITY, 0.0]; model.prescribed.len()];
        self.place_clamps();
        self
    }

    /// The velocity of each moving clamp over the step from `t_n` to `t_{n+1}` (m/s per unit
    /// speed), `(d(t_{n+1}) − d(t_n)) / Δt`.
    fn clamp_rate(p: &Prescribed, step: u64, dt: f64) -> f64 {
        let at = |n: u64| p.travel(n as f64 * dt);
        (at(step + 1) - at(step)) / dt
    }

    /// Puts the moving clamps' DOFs at `d(t_n)`.
    fn place_clamps(&mut self) {
        for p in self.prescribed {
            for &(d, c) in &p.dofs {
                self.u[d] = p.displacement(c, self.t);
            }
        }
    }

    /// With `force` holding the net force at `t_n` and `v` the velocities `v^{n+½}`: books the
    /// moving clamps' work by the trapezoidal rule, `R_n · (Δd_{n−1} + Δd_n) / 2` with the
    /// reaction `R_n` the net force on their DOFs and `Δd_n = d(t_{n+1}) − d(t_n)` (the half
    /// ahead, `R_n · Δd_n / 2`, is left out of the energies at `t_n`), keeps their reactions, and
    /// sets their velocities (the update left them still).
    fn book_clamps(&mut self, dt: f64) {
        let (mut behind, mut ahead) = (0.0, 0.0);
        for (k, p) in self.prescribed.iter().enumerate() {
            let rate = Self::clamp_rate(p, self.step, dt);
            let before = match self.step {
                0 => 0.0,
                n => Self::clamp_rate(p, n - 1, dt),
            };
            let speed = p.velocity.norm();
            let mut along = 0.0;
            for &(d, c) in &p.dofs {
                let r = self.force[d] * p.velocity[c] * dt;
                behind += 0.5 * r * before;
                ahead += 0.5 * r * rate;
                if speed > 0.0 {
                    along += self.force[d] * p.velocity[c] / speed;
                }
                self.v[d] = p.velocity[c] * rate;
            }
            self.reactions[k] = along;
            if along > self.peaks[k][0] {
                self.peaks[k] = [along, self.t];
            }
        }
        self.ledger.external_work += behind + ahead;
        self.ledger.clamp_ahead = ahead;
    }

    /// The clamps' kinetic energy as the total counts it, `½ m v^{n+½} v^{n−½}` (J): the work
    /// that moved their mass, which `book_clamps` leaves out.
    fn clamp_kinetic(&self) -> f64 {
        self.prescribed
            .iter()
            .zip(&self.clamp_mass)
            .map(|(p, m)| {
                let ahead = Self::clamp_rate(p, self.step, self.dt);
                // `v^{−½}` of a clamped DOF is zero (`from_state`).
                let behind = match self.step {
                    0 => 0.0,
                    n => Self::clamp_rate(p, n - 1, self.dt),
                };
                let v2 = p.velocity.norm_squared() * ahead * behind;
                p.dofs
                    .iter()
                    .zip(m)
                    .map(|(&(_, c), m)| {
                        let share = if v2 > 0.0 {
                            p.velocity[c] * p.velocity[c] / p.velocity.norm_squared()
                        } else {
                            0.0
                        };
                        0.5 * m * v2 * share
                    })
                    .sum::<f64>()
            })
            .sum()
    }

    /// The damping's work over the step once `v` holds `v^{n+½}` and `scratch` `v^{n−½}`:
    /// `α Δt (v^n)ᵀ M v^n` with `v^n` their mean, which central difference dissipates exactly;
    /// leaves `v^n` in `scratch`. The moving clamps do not count (the update does not damp
    /// them).
    fn book_damping(&mut self, dt: f64) -> f64 {
        for (s, v) in self.scratch.iter_mut().zip(&self.v) {
            *s = 0.5 * (*s + v);
        }
        let kinetic = self.mass.kinetic_energy(&self.scratch);
        let mut work = 2.0 * self.damping * dt * kinetic;
        for (p, m) in self.prescribed.iter().zip(&self.clamp_mass) {
            for (&(d, _), m) in p.dofs.iter().zip(m) {
                work -= self.damping * dt * m * self.scratch[d] * self.scratch[d];
            }
        }
        self.ledger.damping += work;
        kinetic
    }

    /// Whether a step must go through the net force vector: the fused step has no place for
    /// the clamps' reactions, the local damping or the hand-over of broken interfaces to
    /// contact (it books the damping's work itself, and return-maps failing interfaces), nor
    /// for the return mapping of elements that yield.
    fn needs_net_force(&self) -> bool {
        self.failure.as_ref().is_some_and(|(p, _)| p.releases())
            || self.elements.is_some()
            || !self.prescribed.is_empty()
            || self.local.is_some()
    }

    /// Damps `force` locally against `v = v^{n−½}`, when the run has local damping.
    fn damp_locally(&mut self) {
        if let Some(l) = self.local.as_mut() {
            l.apply(&mut self.force, &self.v);
        }
    }

    /// Books the local damping's work over the step once `v` holds `v^{n+½}` and `scratch`
    /// `v^{n−½}`.
    fn book_local(&mut self, dt: f64) {
        if let Some(l) = &self.local {
            self.ledger.damping += l.work(&self.scratch, &self.v, dt);
        }
    }

    /// `force ← f_int(U^n) − f_c^n − P(t_n)`, so that `a^n = −M⁻¹ force`; returns the elastic
    /// energy `½ Uᵀ f_int` (less the plastic part of the failing interfaces) when `energy` is
    /// asked for (a pass over the vectors), else 0.
    fn net_force(&mut self, energy: bool) -> f64 {
        match self.failure.as_mut() {
            Some((plastic, state)) => {
                self.evaluator
                    .internal_force_failing(&self.u, &mut self.force, (*plastic, state));
                if plastic.releases() {
                    plastic.release(&self.u, state, &mut self.force);
                    if let (true, Some(c)) = (state.changed, self.contact.as_mut()) {
                        c.release(*plastic, state);
                    }
                }
            }
            None => self.evaluator.internal_force(&self.u, &mut self.force),
        }
        if let Some((elements, state)) = self.elements.as_mut() {
            elements.correct(&self.u, state, &mut self.force);
        }
        self.force_clear = false;
        let elastic = if energy {
            let offset = self.failure.as_ref().map_or(0.0, |(p, s)| {
                p.energy_offset(&self.u, s) + self.evaluator.energy_offset(&self.u, (*p, s))
            }) + self
                .elements
                .as_ref()
                .map_or(0.0, |(p, s)| p.energy_offset(&self.u, s));
            0.5 * dot(&self.u, &self.force) - offset
        } else {
            0.0
        };
        // At a check, the unbalanced-force ratio of the net force.
        self.subtract_external();
        if let Some(b) = self.balance.as_mut().filter(|_| energy) {
            b.measure(&self.force, self.loads, self.t);
        }
        elastic
    }

    /// `force −= f_c^n + P(t_n)`.
    fn subtract_external(&mut self) {
        if let Some(c) = self.contact.as_mut() {
            self.ledger.contact_energy = c.apply(
                self.law,
                self.step,
                &self.u,
                &self.v,
                self.dt,
                &mut self.force,
            );
        }
        self.loads.subtract(self.t, &mut self.force);
    }

    /// Steps without the model's damping, mass-proportional and local (the stability analysis
    /// measures the undamped scheme).
    pub fn undamped(mut self) -> Self {
        self.damping = 0.0;
        self.local = None;
        self
    }

    /// Tells the guard the stability limit `Δt_crit` of the model, or a lower bound of it (see
    /// [`GROWTH_LIMIT`]: the guard is then more lenient below the bound, and as strict as without
    /// one above it).
    pub fn set_stability_limit(&mut self, dt_crit: f64) {
        self.fraction = (dt_crit > 0.0 && dt_crit.is_finite()).then(|| self.dt / dt_crit);
    }

    /// Stops the run at the next step once `flag` is raised: that step is checked and recorded,
    /// and `run` returns [`Status::Interrupted`].
    pub fn stop_on(&mut self, flag: Arc<AtomicBool>) {
        self.interrupt = Some(flag);
    }

    /// The step and time at which the run stopped, settled below its unbalanced-force ratio
    /// (`time.stop_ratio`), if it has.
    pub fn settled(&self) -> Option<(u64, f64)> {
        self.settled
    }

    /// The unbalanced-force ratio at the last check, when the run has a stop on it.
    pub fn unbalanced_ratio(&self) -> Option<f64> {
        self.balance.as_ref().map(Balance::ratio)
    }

    fn interrupted(&self) -> bool {
        self.interrupt
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed))
    }

    /// The state at the end of the last `run` that ended `Ok` (after its last record), from
    /// which [`CentralDifference::restore`] goes on bit for bit.
    ///
    /// # Panics
    /// The integrator is not at the end of a run: it is new, its last `run` diverged, or it has
    /// stepped on since ([`CentralDifference::step_only`]).
    pub fn state(&self) -> State {
        assert!(
            self.pending,
            "a state is taken at the end of a run, after its last record"
        );
        State {
            dt: self.dt,
            step: self.step,
            u: self.u.clone(),
            v: self.v.clone(),
            velocity: self.scratch.clone(),
            contact: self.contact.clone(),
            failure: self.failure.as_ref().map(|(_, s)| s.clone()),
            elements: self.elements.as_ref().map(|(_, s)| s.clone()),
            ledger: self.ledger,
            peaks: self.peaks.clone(),
        }
    }

    /// Goes on from `state`, taken by [`CentralDifference::state`] from a run of the same model
    /// at the same time step; `Err` names what differs.
    ///
    /// # Errors
    /// `state` has another time step, number of DOFs, contact (one of the two has none, or
    /// [`Contact::check_saved`] refuses it), moving clamps or failing interfaces; the integrator is
    /// then left as it was.
    pub fn restore(&mut self, state: State) -> std::result::Result<(), String> {
        if state.dt.to_bits() != self.dt.to_bits() {
            return Err(format!(
                "the time step differs: {:e} s saved, {:e} s now",
                state.dt, self.dt
            ));
        }
        if state.u.len() != self.u.len()
            || state.v.len() != self.v.len()
            || state.velocity.len() != self.u.len()
        {
            return Err(format!(
                "the model differs: {} DOFs saved, {} now",
                state.u.len(),
                self.u.len()
            ));
        }
        match (&self.contact, &state.contact) {
            (Some(fresh), Some(saved)) => fresh.check_saved(saved)?,
            (None, None) => {}
            _ => return Err("one of the two has contact and the other not".into()),
        }
        if state.peaks.len() != self.peaks.len() {
            return Err("the moving clamps differ".into());
        }
        let sizes = |s: &FailureState| (s.points.len(), s.released.len());
        if state.failure.as_ref().map(sizes) != self.failure.as_ref().map(|(_, s)| sizes(s)) {
            return Err("the failing interfaces differ".into());
        }
        let yielding = |s: &ElementState| s.strain.len();
        if state.elements.as_ref().map(yielding) != self.elements.as_ref().map(|(_, s)| yielding(s))
        {
            return Err("the elements that yield differ".into());
        }
        self.step = state.step;
        self.t = state.step as f64 * self.dt;
        self.good = Good {
            step: state.step,
            t: self.t,
            u: state.u.clone(),
            velocity: state.velocity.clone(),
            ledger: state.ledger,
        };
        (self.u, self.v, self.scratch) = (state.u, state.v, state.velocity);
        if let (Some(c), Some(saved)) = (self.contact.as_mut(), state.contact) {
            *c = saved;
            // A wall time, as the summary's `step_time_s`: of this process's steps alone.
            c.stats.time_s = 0.0;
        }
        if let (Some((_, s)), Some(mut saved)) = (self.failure.as_mut(), state.failure) {
            // Not saved: which interfaces have left the initial state, which the steps read.
            saved.retouch();
            self.good_failure.copy_from(&saved);
            *s = saved;
        }
        if let (Some((_, s)), Some(saved)) = (self.elements.as_mut(), state.elements) {
            self.good_elements.clone_from(&saved);
            *s = saved;
        }
        self.ledger = state.ledger;
        self.peaks = state.peaks;
        self.force_clear = false;
        self.pending = true;
        Ok(())
    }

    /// The state of the failing interfaces, when the model has any: that of the current `U`
    /// (after a divergence, of the state the guard restored).
    pub fn failure(&self) -> Option<&FailureState> {
        self.failure.as_ref().map(|(_, s)| s)
    }

    /// The plastic state of the elements that may yield, when the model has any: that of the
    /// current `U` (after a divergence, of the state the guard restored).
    pub fn plastic_elements(&self) -> Option<&ElementState> {
        self.elements.as_ref().map(|(_, s)| s)
    }

    /// Whole-step velocities `v^n` of the last state handed to the observer (or restored by
    /// the guard).
    pub fn velocity(&self) -> &[f64] {
        &self.scratch
    }

    /// Largest `|total − total(0)|` so far divided by the energy put in (the guard's measure:
    /// the initial kinetic, elastic and contact energy plus the largest work of the loads,
    /// clamps and gravity so far); 0 while nothing has been put in.
    pub fn max_relative_drift(&self) -> f64 {
        if self.ledger.energy_in_max > 0.0 {
            self.ledger.max_drift / self.ledger.energy_in_max
        } else {
            0.0
        }
    }

    /// Runs `steps` steps; calls `observer` with the state and energies at every `every`-th step
    /// and at the last one, and `progress` with the step number at every guard check. Stops
    /// early, with the reason, when the guard finds a NaN or runaway energy; the state is then
    /// rolled back to the last one that passed the guard.
    ///
    /// # Errors
    /// `observer` returns an error: the run stops at that step and passes it on. A run that
    /// diverges or is interrupted is no error but a [`Status`].
    pub fn run(
        &mut self,
        steps: u64,
        every: u64,
        observer: impl FnMut(&Snapshot, &Energy) -> Result<()> + Send,
        progress: impl FnMut(u64) + Send,
    ) -> Result<Status> {
        in_pool(|| self.time_loop(steps, every, observer, progress))
    }

    fn time_loop(
        &mut self,
        steps: u64,
        every: u64,
        mut observer: impl FnMut(&Snapshot, &Energy) -> Result<()>,
        mut progress: impl FnMut(u64),
    ) -> Result<Status> {
        let check_every = every.min(CHECK_EVERY);
        let dt = self.dt;
        let damping = self.damping_factors();
        let end = self.step + steps;
        if self.pending && steps > 0 {
            self.finish_step(dt);
        }
        loop {
            let last = self.step == end;
            let interrupted = self.interrupted();
            let record = last || interrupted || self.step.is_multiple_of(every);
            let check = record || self.step.is_multiple_of(check_every);
            if !check {
                self.step_unchecked(dt, damping, check_every);
                continue;
            }
            self.ungroup();
            let elastic = self.net_force(true);
            // A run that has settled below its unbalanced-force ratio ends here, recorded.
            let settled = self.balance.as_ref().is_some_and(Balance::reached);
            let record = record || settled;
            self.scratch.copy_from_slice(&self.v);
            self.damp_locally();
            self.mass
                .advance(&self.force, &mut self.v, &mut [], dt, damping);
            self.book_clamps(dt);
            self.book_local(dt);
            let shadow = self.mass.kinetic_product(&self.scratch, &self.v);
            // v^n = (v^{n−½} + v^{n+½}) / 2 for the energies and the outputs.
            let kinetic = self.book_damping(dt);
            let energy = self.energy(elastic, shadow, kinetic);
            self.book_energy_in(&energy, dt);
            if let Some(reason) = self.guard(&energy) {
                let (step, t) = (self.step, self.t);
                let good = std::mem::take(&mut self.good);
                (self.step, self.t, self.u, self.scratch, self.ledger) =
                    (good.step, good.t, good.u, good.velocity, good.ledger);
                if let Some((_, s)) = self.failure.as_mut() {
                    std::mem::swap(s, &mut self.good_failure);
                }
                if let Some((_, s)) = self.elements.as_mut() {
                    std::mem::swap(s, &mut self.good_elements);
                }
                self.pending = false;
                return Ok(Status::Diverged { step, t, reason });
            }
            progress(self.step);
            if record {
                observer(
                    &Snapshot {
                        step: self.step,
                        t: self.t,
                        u: &self.u,
                        v: &self.scratch,
                        reactions: &self.reactions,
                        peaks: &self.peaks,
                        failure: self.failure.as_ref().map(|(_, s)| s),
                        elements: self.elements.as_ref().map(|(_, s)| s),
                    },
                    &energy,
                )?;
            }
            self.good.step = self.step;
            self.good.t = self.t;
            self.good.u.copy_from_slice(&self.u);
            self.good.velocity.copy_from_slice(&self.scratch);
            self.good.ledger = self.ledger;
            if let Some((_, s)) = &self.failure {
                self.good_failure.copy_from(s);
            }
            if let Some((_, s)) = &self.elements {
                self.good_elements.clone_from(s);
            }
            if settled {
                self.settled = Some((self.step, self.t));
            }
            if last || interrupted || settled {
                self.pending = true;
                return Ok(if last || settled {
                    Status::Ok
                } else {
                    Status::Interrupted {
                        step: self.step,
                        t: self.t,
                    }
                });
            }
            self.finish_step(dt);
        }
    }

    /// `U^{n+1} = U^n + Δt v^{n+½}` once `v` holds `v^{n+½}`; the loads' work of the step.
    fn finish_step(&mut self, dt: f64) {
        self.pending = false;
        self.ledger.external_work += self.loads.work_increment(self.t, dt, |d| self.v[d]);
        for_each_chunk(&mut self.u, STREAM_CHUNK, |first, u| {
            let v = &self.v[first..first + u.len()];
            for (u, v) in u.iter_mut().zip(v) {
                *u += dt * v;
            }
        });
        self.step += 1;
        self.t = self.step as f64 * dt;
        self.place_clamps();
    }

    /// `(1 − αΔt/2, 1/(1 + αΔt/2))` of the damped velocity update.
    fn damping_factors(&self) -> (f64, f64) {
        let half = 0.5 * self.damping * self.dt;
        (1.0 - half, 1.0 / (1.0 + half))
    }

    /// One step without energies, guard or outputs (the time loop between its checks):
    /// `v^{n+½}` and `U^{n+1}`, fused with the evaluation when the evaluator can do that, else
    /// in one element-local pass after it.
    /// `stretch`: the steps between the checks around it (or of a `step_only`), which decide
    /// whether the state goes into groups ([`MIN_STRETCH`]).
    fn step_unchecked(&mut self, dt: f64, damping: (f64, f64), stretch: u64) {
        let fused = self.evaluator.fused().filter(|_| !self.needs_net_force());
        let grouped = fused.and_then(|f| f.grouped());
        if let Some(grouped) = grouped.filter(|_| self.damping == 0.0 && stretch >= MIN_STRETCH) {
            if self.step_grouped(grouped, dt) {
                return;
            }
        }
        self.ungroup();
        match fused {
            Some(fused) => {
                if !self.force_clear {
                    self.force.fill(0.0);
                }
                self.subtract_external();
                let update = Update {
                    mass: self.mass,
                    dt,
                    damping,
                };
                let (u, v, force) = (&mut self.u, &mut self.v, &mut self.force);
                let loaded = self.loaded.as_deref();
                let power = match self.failure.as_mut() {
                    Some((plastic, state)) => {
                        fused.advance_failing(u, v, force, loaded, &update, (*plastic, state))
                    }
                    None => fused.advance(u, v, force, loaded, &update),
                };
                self.force_clear = true;
                self.ledger.damping += self.damping * dt * power;
            }
            None => {
                self.net_force(false);
                if self.damping > 0.0 || self.local.is_some() {
                    self.scratch.copy_from_slice(&self.v);
                }
                self.damp_locally();
                self.mass
                    .advance(&self.force, &mut self.v, &mut self.u, dt, damping);
                self.book_clamps(dt);
                self.book_local(dt);
                if self.damping > 0.0 {
                    self.book_damping(dt);
                }
            }
        }
        self.ledger.external_work += self.loads.work_increment(self.t, dt, |d| self.v[d]);
        self.step += 1;
        self.t = self.step as f64 * dt;
        self.place_clamps();
    }

    /// [`CentralDifference::step_unchecked`] on the state in groups of four elements, undamped
    /// (into them first, if the last step was not), when it has them; else `false`.
    fn step_grouped(&mut self, grouped: &dyn GroupedStep, dt: f64) -> bool {
        let (Some(g), Some(loaded)) = (self.groups.as_mut(), self.loaded.as_deref()) else {
            return false;
        };
        if !self.force_clear {
            self.force.fill(0.0);
        }
        self.loads.subtract(self.t, &mut self.force);
        g.advance(grouped, &self.u, &self.v, &mut self.force, loaded, dt);
        self.force_clear = true;
        self.ledger.external_work += self.loads.work_increment(self.t, dt, |d| g.velocity(d));
        self.step += 1;
        self.t = self.step as f64 * dt;
        true
    }

    /// Brings `U` and `v` back from their groups, if the last step left them there.
    fn ungroup(&mut self) {
        if let Some(g) = self.groups.as_mut() {
            g.leave(&mut self.u, &mut self.v);
        }
    }

    /// Runs `steps` steps in chunks of `every`, calling `each` with the integrator (its contact
    /// state included) and the energies at the end of every chunk; returns at the first chunk
    /// that does not end `Ok`.
    ///
    /// # Errors
    /// Never: its observer cannot fail; the `Result` is that of [`CentralDifference::run`].
    pub fn run_chunks(
        &mut self,
        steps: u64,
        every: u64,
        mut each: impl FnMut(&Self, &Energy),
    ) -> Result<Status> {
        let mut left = steps;
        while left > 0 {
            let n = every.clamp(1, left);
            let mut last = None;
            let status = self.run(
                n,
                n,
                |_, e| {
                    last = Some(*e);
                    Ok(())
                },
                |_| {},
            )?;
            left -= n;
            if status != Status::Ok {
                return Ok(status);
            }
            if let Some(e) = last {
                each(self, &e);
            }
        }
        Ok(Status::Ok)
    }

    /// The total energy of `e` with the contact term taken as what the contact springs store
    /// now instead of minus the work of the contact forces: it is conserved where contact is
    /// (frictionless edge-to-edge contact derives from a potential), and what it loses is what
    /// contact dissipated. Equal to `e.total` without contact.
    pub fn total_with_stored_contact(&self, e: &Energy) -> f64 {
        self.contact
            .as_ref()
            .map_or(e.total, |c| e.total - e.contact + c.stored())
    }

    /// Runs `steps` steps with no energies, guard or outputs: the bare cost of the explicit
    /// step, for benchmarks. `run` does the same between its checks.
    pub fn step_only(&mut self, steps: u64) {
        let dt = self.dt;
        let damping = self.damping_factors();
        in_pool(|| {
            let mut steps = steps;
            if self.pending && steps > 0 {
                self.finish_step(dt);
                steps -= 1;
            }
            for _ in 0..steps {
                self.step_unchecked(dt, damping, steps);
            }
            self.ungroup();
        })
    }

    /// The energies at `t_n`, with `scratch = v^n`. The total uses the kinetic energy that
    /// central difference conserves exactly with linear springs, `½ (v^{n+½})ᵀ M v^{n−½}`
    /// (`shadow`): then `total` changes only by contact, damping and round-off, while
    /// `½ (v^n)ᵀ M v^n`, reported as `kinetic`, oscillates by `O((ω Δt)²)` about it.
    fn energy(&mut self, elastic: f64, shadow: f64, kinetic: f64) -> Energy {
        let potential = self.loads.gravity_potential(&self.u);
        let external_work =
            self.ledger.external_work - self.ledger.clamp_ahead + self.clamp_kinetic();
        // The energy the released interfaces handed over is contact energy from then on.
        let contact =
            self.ledger.contact_energy + self.failure.as_ref().map_or(0.0, |(_, s)| s.handover);
        let [fracture, friction] = self
            .failure
            .as_ref()
            .map_or([0.0; 2], |(p, s)| p.dissipated(s));
        let plastic = self.elements.as_ref().map_or(0.0, |(_, s)| s.dissipated);
        let damping = self.ledger.damping;
        let total =
            shadow + elastic + contact + potential + fracture + friction + plastic + damping
                - external_work;
        let initial = *self.ledger.initial_total.get_or_insert(total);
        self.ledger.max_drift = self.ledger.max_drift.max((total - initial).abs());
        Energy {
            t: self.t,
            kinetic,
            elastic,
            contact,
            potential,
            external_work,
            fracture,
            friction,
            plastic,
            damping,
            total,
        }
    }

    /// Raises the largest energy put in so far (the guard's measure) to what has been put in by
    /// the end of the step under way, once `v` holds `v^{n+½}`: the initial kinetic, elastic and
    /// contact energy and the work of the loads and of gravity up to `t_{n+1}` (not what contact
    /// gives to
    /// the motion: contact stepped beyond its limit is what pumps energy in). The
    /// step ahead counts because `v^n` already carries half of the impulse `Δt M⁻¹ P(t_n)`: a
    /// load that rises from zero would otherwise show kinetic energy before any work is booked.
    fn book_energy_in(&mut self, e: &Energy, dt: f64) {
        let ahead = self.loads.work_increment(self.t, dt, |d| self.v[d])
            - dt * self.loads.gravity_potential(&self.v);
        let initial = *self
            .ledger
            .initial_stored
            .get_or_insert(e.kinetic + e.elastic + e.contact.max(0.0));
        let put_in = initial + e.external_work - e.potential + ahead.max(0.0);
        self.ledger.energy_in_max = self.ledger.energy_in_max.max(put_in);
    }

    /// Why the run must stop, if it must.
    fn guard(&self, e: &Energy) -> Option<String> {
        if !(e.total.is_finite()
            && e.kinetic.is_finite()
            && e.elastic.is_finite()
            && e.contact.is_finite())
        {
            return Some("NaN or infinite energy: the solution blew up".into());
        }
        // The contact energy counts only when positive: energy that contact gives to the motion
        // shows up in the kinetic energy. A stable mode stepped at `f Δt_crit` can hold up to
        // 1/(1 − f²) times its conserved energy as strain, so the limit widens near Δt_crit.
        let stored = e.kinetic + e.elastic + e.contact.max(0.0);
        let widen = match self.fraction {
            Some(f) if f < 1.0 => 1.0 / (1.0 - f * f),
            _ => 1.0,
        };
        let limit = GROWTH_LIMIT * widen;
        // Before any energy is put in (the first steps of a run loaded from zero, a damped start
        // whose `v^{−½}` leaves 1e-40 J of round-off), growth has no measure: only a NaN stops it.
        if self.ledger.energy_in_max > 0.0 && stored > limit * self.ledger.energy_in_max {
            return Some(format!(
                "energy growth: kinetic + elastic + contact = {stored:.6e} J exceeds {limit:.4} × the energy put in ({:.6e} J); \
                 the time step is likely above the stability limit",
                self.ledger.energy_in_max
            ));
        }
        // The largest movement so far, which `energy` has just raised to this step's: the first
        // check it exceeds the bound at is the first whose own movement does.
        let drift = self.ledger.max_drift;
        if self.max_relative_drift() > BALANCE_LIMIT {
            return Some(format!(
                "energy balance: the total energy moved by {drift:.6e} J, more than \
                 {BALANCE_LIMIT} × the energy put in ({:.6e} J); the time step is likely above \
                 the stability limit",
                self.ledger.energy_in_max
            ));
        }
        None
    }
}

/// Runs `f` on a worker of rayon's pool. Parallel loops started from outside the pool go
/// through its global queue, which allocates a block every 63 jobs; from a worker they use its
/// own queue, which keeps its size: the time loop then allocates nothing.
fn in_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

/// `xᵀ y`, summed in a fixed order.
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    x.iter().zip(y).map(|(a, b)| a * b).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::force::evaluator;
    use crate::input::scene::{EvaluatorKind, Scene};

    /// A step on the state in groups of four elements gives the bits of the fused step on the
    /// plain state, through checks and outputs (`run`) and without (`step_only`), on 1 and 2
    /// threads, for a grid of three blocks whose rows are a multiple of four elements long, with
    /// and without a second body that leaves the last group short of elements; rows of other
    /// lengths, damped or gravity-loaded runs and outputs every few steps step on the plain
    /// state.
    #[test]
    fn the_grouped_step_gives_the_bits_of_the_plain_one() {
        let second = r#", {"name": "c", "material": "m", "mesh": {"kind": "grid", "origin": [0, 5], "size": [1, 1], "cells": [3, 3]}}"#;
        let cases = [
            ("[100, 90]", "\"rect\"", "[0, 0]", 0, "", true),
            ("[100, 90]", "\"rect\"", "[0, 0]", 0, second, true),
            ("[100, 90]", "\"rect\"", "[0, -9.81]", 0, "", false),
            ("[100, 90]", "\"rect\"", "[0, 0]", 50, "", true),
            ("[101, 90]", "\"rect\"", "[0, 0]", 0, "", false),
            ("[60, 40]", "\"tri\"", "[0, 0]", 0, "", false),
        ];
        for (cells, cell, gravity, damping, second, grouped) in cases {
            let json = format!(
                r#"{{"name": "a", "thickness": 1.0, "formulation": {{"kind": "rigid"}}, "gravity": {gravity}, "damping": {damping},
                    "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
                    "bodies": [{{"name": "b", "material": "m", "mesh": {{"kind": "grid", "origin": [0, 0], "size": [2, 1], "cells": {cells}, "cell": {cell}}},
                        "supports": [{{"edge": "left", "kind": "ground-spring"}}],
                        "loads": [{{"kind": "traction", "edge": "right", "value": [1e5, -1e6], "amplitude": [[0, 0], [1e-5, 1]]}}]}}{second}],
                    "time": {{"dt": 1e-7, "steps": 10}}}}"#
            );
            let model = Model::build(&Scene::from_json(&json).unwrap()).unwrap();
            let (mass, loads) = (Mass::new(&model), Loads::new(&model));
            let ev = evaluator::build(&model, EvaluatorKind::ElementWise);
            let run = |groups: bool, threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut cd = CentralDifference::new(&model, ev.as_ref(), &mass, &loads, None, 1e-7);
                // Grouped steps only where the model and the run allow them.
                assert_eq!(
                    cd.groups.is_some(),
                    grouped && damping == 0,
                    "{cells} {cell}"
                );
                if !groups {
                    cd.groups = None;
                }
                let mut energies = Vec::new();
                pool.install(|| {
                    cd.run(
                        250,
                        100,
                        |s, e| {
                            energies.push((s.u.to_vec(), e.total, e.external_work));
                            Ok(())
                        },
                        |_| {},
                    )
                })
                .unwrap();
                cd.step_only(37);
                (cd.u, cd.v, energies)
            };
            // A stretch of a check's steps goes into the groups, one of a few steps does not.
            let mut probe = CentralDifference::new(&model, ev.as_ref(), &mass, &loads, None, 1e-7);
            let active = |cd: &CentralDifference| cd.groups.as_ref().is_some_and(Groups::active);
            probe.step_unchecked(1e-7, (1.0, 1.0), MIN_STRETCH - 1);
            assert!(!active(&probe));
            probe.step_unchecked(1e-7, (1.0, 1.0), CHECK_EVERY);
            assert_eq!(active(&probe), grouped && damping == 0, "{cells} {cell}");
            let plain = run(false, 1);
            let scale = plain.0.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(scale > 1e-9, "{cells} {cell}: the model moved ({scale:e})");
            for threads in [1, 2] {
                assert!(
                    run(true, threads) == plain,
                    "{cells} {cell}, gravity {gravity}, damping {damping}, {threads} threads"
                );
            }
        }
    }
}

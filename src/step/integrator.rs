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
use crate::force::evaluator::Evaluator;
use crate::model::loads::Loads;
use crate::model::mass::{Mass, Update};
use crate::model::Model;
use crate::parallel::for_each_chunk;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The energies at one time (J); `total = kinetic + elastic + contact + potential − external_work`
/// is constant for an undamped run, up to the integrator's error.
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
    /// Work done by the applied loads since the start.
    pub external_work: f64,
    /// `kinetic + elastic + contact + potential − external_work` (J).
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
}

/// The kinetic plus elastic energy may not exceed this multiple of the energy put in (the
/// initial energy plus the work of loads and gravity to the end of the step under way) before
/// a run counts as diverged. A mode
/// stepped at `f Δt_crit` holds up to `1/(1 − f²)` times its conserved energy as strain at its
/// turning points; when the integrator knows `Δt_crit` ([`CentralDifference::set_stability_limit`])
/// the limit is widened by that factor, so that a stable run at 0.999 `Δt_crit` is not stopped.
/// An unstable run grows geometrically and crosses it within a few hundred steps.
pub const GROWTH_LIMIT: f64 = 4.0;

/// Steps between two divergence checks when no output is due sooner.
pub const CHECK_EVERY: u64 = 100;

/// Central-difference time stepping of one model with one evaluator.
pub struct CentralDifference<'a> {
    evaluator: &'a dyn Evaluator,
    mass: &'a Mass,
    loads: &'a Loads,
    /// Mass-proportional damping `α` (1/s).
    pub damping: f64,
    /// Time step `Δt` (s).
    pub dt: f64,
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
    /// The elements where `−P − f_c` can be non-zero, when the loads name them (no gravity, no
    /// contact): a fused step reads `force` only there.
    loaded: Option<Vec<u32>>,
    /// The energy bookkeeping: what was put in and taken out so far.
    ledger: EnergyLedger,
    good: (u64, f64, Vec<f64>, Vec<f64>),
    /// Whether `v` already holds `v^{n+½}` of the current step `n`: a run ended there after its
    /// last record, and the next step only has `U` left to move.
    pending: bool,
    /// `Δt / Δt_crit` when the caller knows `Δt_crit`: the guard then allows for the energy
    /// that the averaged velocity misses in stable modes near the limit.
    fraction: Option<f64>,
    /// Raised from outside (a signal handler) to stop the run at the next step.
    interrupt: Option<Arc<AtomicBool>>,
}

impl Status {
    /// `ok`, `interrupted at step N (t = T s)` or `diverged at step N (t = T s): reason`.
    pub fn describe(&self) -> String {
        match self {
            Status::Ok => "ok".to_string(),
            Status::Interrupted { step, t } => {
                format!("interrupted at step {step} (t = {t:.6e} s)")
            }
            Status::Diverged { step, t, reason } => {
                format!("diverged at step {step} (t = {t:.6e} s): {reason}")
            }
        }
    }
}

/// The energy bookkeeping of a run (J): the contact energy and the loads' work so far, and
/// what the guard and the drift measure keep.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
struct EnergyLedger {
    /// Contact energy at `t_n`: minus the work of the contact forces (`Contact::apply`).
    contact_energy: f64,
    /// Work of the applied loads since the start.
    external_work: f64,
    /// The total energy at the first check.
    initial_total: Option<f64>,
    /// The largest energy put in so far (the guard's measure).
    energy_in_max: f64,
    /// What the guard counts as stored (kinetic, elastic and contact) at the first check.
    initial_stored: Option<f64>,
    /// Largest `|total − total(0)|` so far.
    max_drift: f64,
    /// Largest energy seen, the scale of the drift.
    energy_scale: f64,
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
    ledger: EnergyLedger,
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
        model: &Model,
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
        model: &Model,
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
            dt,
            t: 0.0,
            step: 0,
            u: u0,
            v: v0,
            force: vec![0.0; n],
            force_clear: false,
            scratch: vec![0.0; n],
            contact,
            loaded: None,
            ledger: EnergyLedger::default(),
            good: (0, 0.0, vec![0.0; n], vec![0.0; n]),
            fraction: None,
            pending: false,
            interrupt: None,
        };
        if s.contact.is_none() {
            s.loaded = loads.loaded_elements();
        }
        s.net_force(false);
        mass.advance(&s.force, &mut s.v, &mut [], -0.5 * dt, (1.0, 1.0));
        s
    }

    /// `force ← f_int(U^n) − f_c^n − P(t_n)`, so that `a^n = −M⁻¹ force`; returns the elastic
    /// energy `½ Uᵀ f_int` when `energy` is asked for (a pass over the vectors), else 0.
    fn net_force(&mut self, energy: bool) -> f64 {
        self.evaluator.internal_force(&self.u, &mut self.force);
        self.force_clear = false;
        let elastic = if energy {
            0.5 * dot(&self.u, &self.force)
        } else {
            0.0
        };
        self.subtract_external();
        elastic
    }

    /// `force −= f_c^n + P(t_n)`.
    fn subtract_external(&mut self) {
        if let Some(c) = self.contact.as_mut() {
            self.ledger.contact_energy =
                c.apply(self.step, &self.u, &self.v, self.dt, &mut self.force);
        }
        self.loads.subtract(self.t, &mut self.force);
    }

    /// Tells the guard the stability limit `Δt_crit` of the model (see [`GROWTH_LIMIT`]).
    pub fn set_stability_limit(&mut self, dt_crit: f64) {
        self.fraction = (dt_crit > 0.0 && dt_crit.is_finite()).then(|| self.dt / dt_crit);
    }

    /// Stops the run at the next step once `flag` is raised: that step is checked and recorded,
    /// and `run` returns [`Status::Interrupted`].
    pub fn stop_on(&mut self, flag: Arc<AtomicBool>) {
        self.interrupt = Some(flag);
    }

    fn interrupted(&self) -> bool {
        self.interrupt
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed))
    }

    /// The state at the end of the last `run` that ended `Ok` (after its last record), from
    /// which [`CentralDifference::restore`] goes on bit for bit.
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
            ledger: self.ledger,
        }
    }

    /// Goes on from `state`, taken by [`CentralDifference::state`] from a run of the same model
    /// at the same time step; `Err` names what differs.
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
        if state.contact.is_some() != self.contact.is_some() {
            return Err("one of the two has contact and the other not".into());
        }
        self.step = state.step;
        self.t = state.step as f64 * self.dt;
        self.good = (state.step, self.t, state.u.clone(), state.velocity.clone());
        (self.u, self.v, self.scratch) = (state.u, state.v, state.velocity);
        if let (Some(c), Some(saved)) = (self.contact.as_mut(), state.contact) {
            c.resume(saved);
        }
        self.ledger = state.ledger;
        self.force_clear = false;
        self.pending = true;
        Ok(())
    }

    /// Whole-step velocities `v^n` of the last state handed to the observer (or restored by
    /// the guard).
    pub fn velocity(&self) -> &[f64] {
        &self.scratch
    }

    /// Largest `|total − total(0)|` so far divided by the largest energy seen in the run
    /// (`kinetic + elastic + |potential| + |external_work|`); 0 while nothing has moved.
    pub fn max_relative_drift(&self) -> f64 {
        if self.ledger.energy_scale > 0.0 {
            self.ledger.max_drift / self.ledger.energy_scale
        } else {
            0.0
        }
    }

    /// Runs `steps` steps; calls `observer` with the state and energies at every `every`-th step
    /// and at the last one, and `progress` with the step number at every guard check. Stops
    /// early, with the reason, when the guard finds a NaN or runaway energy; the state is then
    /// rolled back to the last one that passed the guard.
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
                self.step_unchecked(dt, damping);
                continue;
            }
            let elastic = self.net_force(true);
            self.scratch.copy_from_slice(&self.v);
            self.mass
                .advance(&self.force, &mut self.v, &mut [], dt, damping);
            let shadow = self.mass.kinetic_product(&self.scratch, &self.v);
            // v^n = (v^{n−½} + v^{n+½}) / 2 for the energies and the outputs.
            for (s, v) in self.scratch.iter_mut().zip(&self.v) {
                *s = 0.5 * (*s + v);
            }
            let energy = self.energy(elastic, shadow);
            self.book_energy_in(&energy, dt);
            if let Some(reason) = self.guard(&energy) {
                let (step, t) = (self.step, self.t);
                let (gs, gt, gu, gv) = std::mem::take(&mut self.good);
                (self.step, self.t, self.u, self.scratch) = (gs, gt, gu, gv);
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
                    },
                    &energy,
                )?;
            }
            self.good.0 = self.step;
            self.good.1 = self.t;
            self.good.2.copy_from_slice(&self.u);
            self.good.3.copy_from_slice(&self.scratch);
            if last || interrupted {
                self.pending = true;
                return Ok(if last {
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
        self.ledger.external_work += self.loads.work_increment(self.t, dt, &self.v);
        for_each_chunk(&mut self.u, |first, u| {
            let v = &self.v[first..first + u.len()];
            for (u, v) in u.iter_mut().zip(v) {
                *u += dt * v;
            }
        });
        self.step += 1;
        self.t = self.step as f64 * dt;
    }

    /// `(1 − αΔt/2, 1/(1 + αΔt/2))` of the damped velocity update.
    fn damping_factors(&self) -> (f64, f64) {
        let half = 0.5 * self.damping * self.dt;
        (1.0 - half, 1.0 / (1.0 + half))
    }

    /// One step without energies, guard or outputs (the time loop between its checks):
    /// `v^{n+½}` and `U^{n+1}`, fused with the evaluation when the evaluator can do that, else
    /// in one element-local pass after it.
    fn step_unchecked(&mut self, dt: f64, damping: (f64, f64)) {
        if let Some(fused) = self.evaluator.fused() {
            if !self.force_clear {
                self.force.fill(0.0);
            }
            self.subtract_external();
            let update = Update {
                mass: self.mass,
                dt,
                damping,
            };
            fused.advance(
                &mut self.u,
                &mut self.v,
                &mut self.force,
                self.loaded.as_deref(),
                &update,
            );
            self.force_clear = true;
        } else {
            self.net_force(false);
            self.mass
                .advance(&self.force, &mut self.v, &mut self.u, dt, damping);
        }
        self.ledger.external_work += self.loads.work_increment(self.t, dt, &self.v);
        self.step += 1;
        self.t = self.step as f64 * dt;
    }

    /// Runs `steps` steps in chunks of `every`, calling `each` with the integrator (its contact
    /// state included) and the energies at the end of every chunk; returns at the first chunk
    /// that does not end `Ok`.
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
                self.step_unchecked(dt, damping);
            }
        })
    }

    /// The energies at `t_n`, with `scratch = v^n`. The total uses the kinetic energy that
    /// central difference conserves exactly with linear springs, `½ (v^{n+½})ᵀ M v^{n−½}`
    /// (`shadow`): then `total` changes only by contact, damping and round-off, while
    /// `½ (v^n)ᵀ M v^n`, reported as `kinetic`, oscillates by `O((ω Δt)²)` about it.
    fn energy(&mut self, elastic: f64, shadow: f64) -> Energy {
        let kinetic = self.mass.kinetic_energy(&self.scratch);
        let potential = self.loads.gravity_potential(&self.u);
        let external_work = self.ledger.external_work;
        let contact = self.ledger.contact_energy;
        let total = shadow + elastic + contact + potential - external_work;
        let initial = *self.ledger.initial_total.get_or_insert(total);
        self.ledger.energy_scale = self
            .ledger
            .energy_scale
            .max(kinetic + elastic + contact + potential.abs() + external_work.abs());
        self.ledger.max_drift = self.ledger.max_drift.max((total - initial).abs());
        Energy {
            t: self.t,
            kinetic,
            elastic,
            contact,
            potential,
            external_work,
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
        let ahead = self.loads.work_increment(self.t, dt, &self.v)
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

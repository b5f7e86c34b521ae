//! The setup of a scene: everything an analysis computes with, built once per command. Every
//! command, test and bench starts from [`Setup::new`]; the analyses take it with their own
//! parameters.

use crate::analysis::limit::{self, Limit};
use crate::error::{Error, Result};
use crate::force::contact::{self, Contact, WithBlocks};
use crate::force::evaluator::{self, Evaluator};
use crate::force::failure::{self, PlasticForces};
use crate::force::yielding::PlasticElements;
use crate::input::scene::{EvaluatorKind, Scene};
use crate::model::loads::Loads;
use crate::model::mass::Mass;
use crate::model::{dof_index, Model};
use crate::output::Probe;
use crate::step::integrator::CentralDifference;
use std::sync::OnceLock;

/// Command-line overrides of the scene.
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    /// Evaluator, replacing the scene's.
    pub evaluator: Option<EvaluatorKind>,
    /// Time step (s), replacing the scene's `dt` or `dt_factor`.
    pub dt: Option<f64>,
    /// Time step as a fraction of `Δt_crit`, replacing the scene's `dt` or `dt_factor`.
    pub dt_factor: Option<f64>,
    /// Number of steps, replacing the scene's `end` or `steps`.
    pub steps: Option<u64>,
    /// Compute `ω_max` to full precision ([`limit::EXACT`]) at setup, whatever the time step
    /// needs: `check`, `stability`, `eigen`, `tradeoff` and `run --exact-dt-crit` ask for it.
    /// Otherwise a given `dt` computes no `ω_max` at all (the proven bracket decides the
    /// warning) and a `dt_factor` computes it to [`limit::FOR_STEP`].
    pub exact_dt_crit: bool,
    /// The analysis takes no time step (`static`, `effective`, `limit`): no `ω_max` is computed
    /// for one, and a `dt_factor` is taken of the proven-safe step (the bracket's).
    pub no_step: bool,
}

impl Overrides {
    /// None of the scene's settings overridden, and `ω_max` to full precision: the setup of the
    /// analyses that need it (`eigen`, `stability`).
    pub fn exact() -> Overrides {
        Overrides {
            exact_dt_crit: true,
            ..Default::default()
        }
    }

    /// None of the scene's settings overridden, for an analysis that takes no time step: no
    /// Lanczos iteration at setup ([`Overrides::no_step`]).
    pub fn no_step() -> Overrides {
        Overrides {
            no_step: true,
            ..Default::default()
        }
    }
}

/// A scene ready to analyse: its model, evaluator, mass, loads, contact and time step.
pub struct Setup {
    /// The scene, as read.
    pub scene: Scene,
    /// The overrides it was set up with.
    pub overrides: Overrides,
    /// The model of the scene.
    pub model: Model,
    /// The evaluator of `f_int`.
    pub evaluator: Box<dyn Evaluator>,
    /// The plastic forces of the failing interfaces, in the evaluator's manner; `None` when no
    /// material's interfaces fail (then no interface has a state).
    pub plastic: Option<Box<dyn PlasticForces>>,
    /// The hybrid elements that may yield and their return mapping; `None` when none may.
    pub yielding: Option<PlasticElements>,
    /// `M` and its inverse.
    pub mass: Mass,
    /// Point loads and gravity.
    pub loads: Loads,
    /// The contact of the scene in its initial state; `None` when the scene declares none
    /// (then no contact search is done). Each integrator starts from a copy.
    pub contact: Option<Contact>,
    /// What is known of the largest circular frequency `ω_max` (rad/s): with contact, of `K`
    /// plus every contact closed against rigid ground (`contact::stiffness_estimate`), the one
    /// definition every command uses. Its proven bracket always; its Lanczos value
    /// (`limit::omega_max`) when the time step or [`Overrides::exact_dt_crit`] asks for it.
    pub limit: Limit,
    /// `ω_max` to full precision, computed on the first call of [`Setup::omega_max`] unless the
    /// setup already had it.
    exact: OnceLock<f64>,
    /// The time step of a run (s).
    pub dt: f64,
    /// Steps of a run.
    pub steps: u64,
    /// Wall time of [`Setup::new`] (s).
    pub seconds: f64,
}

/// `scene` with the evaluator `overrides` asks for.
fn evaluated_by<'s>(scene: &'s Scene, overrides: &Overrides) -> std::borrow::Cow<'s, Scene> {
    match overrides.evaluator {
        Some(kind) if kind != scene.evaluator => std::borrow::Cow::Owned(Scene {
            evaluator: kind,
            ..scene.clone()
        }),
        _ => std::borrow::Cow::Borrowed(scene),
    }
}

impl Setup {
    /// Builds everything an analysis of `scene` needs.
    ///
    /// # Errors
    /// The scene's model cannot be built (`Model::build`), its `ω_max` is not finite, or its
    /// time step or step count is out of range.
    pub fn new(scene: &Scene, overrides: &Overrides) -> Result<Setup> {
        let start = std::time::Instant::now();
        // The model's memory estimate depends on the evaluator: the one that will be built.
        let scene = evaluated_by(scene, overrides);
        let model = Model::build(&scene)?;
        Self::assemble(&scene, overrides, model, start)
    }

    /// [`Setup::new`] with the model given: one built from `scene` (`Model::build`) and then
    /// changed from code, such as a law the scene cannot name ([`Model::set_law`]).
    ///
    /// # Errors
    /// As [`Setup::new`], the model's build excepted.
    pub fn with_model(scene: &Scene, overrides: &Overrides, model: Model) -> Result<Setup> {
        let start = std::time::Instant::now();
        Self::assemble(&evaluated_by(scene, overrides), overrides, model, start)
    }

    fn assemble(
        scene: &Scene,
        overrides: &Overrides,
        model: Model,
        start: std::time::Instant,
    ) -> Result<Setup> {
        crate::output::refuse_own_columns(&model, &scene.output.probes)?;
        let kind = scene.evaluator;
        let evaluator = evaluator::build(&model, kind);
        let plastic = failure::build(&model);
        let yielding = PlasticElements::build(&model);
        let mass = Mass::new(&model);
        let loads = Loads::new(&model);
        let contact = Contact::new(&model);
        let blocks = contact
            .as_ref()
            .map(|c| contact::stiffness_estimate(&model, c));
        let mut limit = Limit::bracket(&model, blocks.as_deref());
        check_finite(scene, limit.bound)?;
        let given_dt =
            overrides.dt.is_some() || (overrides.dt_factor.is_none() && scene.time.dt.is_some());
        let tolerance = match (overrides.exact_dt_crit, given_dt || overrides.no_step) {
            (true, _) => Some(limit::EXACT),
            (false, false) => Some(limit::FOR_STEP),
            (false, true) => None,
        };
        let exact = OnceLock::new();
        if let Some(tolerance) = tolerance {
            let omega = lanczos(&model, evaluator.as_ref(), &mass, blocks, tolerance);
            check_finite(scene, omega)?;
            limit.omega_max = Some(omega);
            limit.tolerance = Some(tolerance);
            if tolerance == limit::EXACT {
                exact.set(omega).expect("set once");
            }
        }
        let dt_crit = match overrides.no_step {
            true => limit.dt_crit_at_least(),
            false => limit.dt_crit().unwrap_or(f64::INFINITY),
        };
        let dt = time_step(scene, overrides, dt_crit)?;
        let steps = match (overrides.steps, scene.time.steps, scene.time.end) {
            (Some(0), _, _) => {
                return Err(Error::scene("--steps", "must be ≥ 1, like `time.steps`"))
            }
            (Some(n), _, _) => n,
            (None, Some(n), _) => n,
            (None, None, Some(end)) => (end / dt - 1e-9).ceil().max(1.0) as u64,
            (None, None, None) => unreachable!("validated: the scene has `end` or `steps`"),
        };
        Ok(Setup {
            scene: scene.clone(),
            overrides: overrides.clone(),
            model,
            evaluator,
            plastic,
            yielding,
            mass,
            loads,
            contact,
            limit,
            exact,
            dt,
            steps,
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// A central-difference integrator of the model at time step `dt`, from the initial state
    /// (the contact's and the failing interfaces' included), with the guard told `Δt_crit`
    /// (the elastic one: softening only lowers the stiffness).
    pub fn integrator(&self, dt: f64) -> CentralDifference<'_> {
        let mut cd = CentralDifference::new(
            &self.model,
            self.evaluator.as_ref(),
            &self.mass,
            &self.loads,
            self.contact.as_ref().map(Contact::copy),
            dt,
        );
        if let Some(plastic) = &self.plastic {
            cd = cd.with_failure(plastic.as_ref());
        }
        if let Some(yielding) = &self.yielding {
            cd = cd.with_plastic_elements(yielding);
        }
        if !self.model.prescribed.is_empty() {
            cd = cd.with_prescribed(&self.model);
        }
        cd.set_stability_limit(self.limit.dt_crit_at_least());
        cd
    }

    /// `ω_max` (rad/s) to full precision ([`limit::EXACT`]): the setup's if it computed it so,
    /// else by Lanczos now (once; later calls return it).
    pub fn omega_max(&self) -> f64 {
        *self.exact.get_or_init(|| {
            let blocks = self
                .contact
                .as_ref()
                .map(|c| contact::stiffness_estimate(&self.model, c));
            lanczos(
                &self.model,
                self.evaluator.as_ref(),
                &self.mass,
                blocks,
                limit::EXACT,
            )
        })
    }

    /// `Δt_crit = 2/ω_max` (s) to full precision (see [`Setup::omega_max`]), over `√(1 + α)`
    /// with local damping `α` ([`Limit::stiffening`]).
    pub fn dt_crit(&self) -> f64 {
        self.limit.step_limit(self.omega_max())
    }

    /// What the checks found: extreme inputs (`model::checks::warnings`) and a time step
    /// above, or not proven below, `Δt_crit` ([`Limit::warning`]).
    pub fn warnings(&self) -> Vec<String> {
        let mut out = crate::model::checks::warnings(&self.model);
        out.extend(self.limit.warning(self.dt));
        out
    }

    /// The history columns the scene asks for, each checked against the model's DOFs.
    ///
    /// # Errors
    /// A probe names an element outside the model (`output.probes[k].element`), a point in no
    /// element (`output.probes[k].at`) or a DOF the formulation does not have
    /// (`output.probes[k].dof`).
    pub fn probes(&self) -> Result<Vec<Probe>> {
        probes(&self.scene, &self.model)
    }
}

/// `ω_max` of `K` (by `evaluator`) plus the contact estimate's `blocks`, by Lanczos to
/// `tolerance`.
fn lanczos(
    model: &Model,
    evaluator: &dyn Evaluator,
    mass: &Mass,
    blocks: Option<Vec<f64>>,
    tolerance: f64,
) -> f64 {
    match blocks {
        None => limit::omega_max(model, evaluator, mass, tolerance),
        Some(blocks) => limit::omega_max(
            model,
            &WithBlocks {
                inner: evaluator,
                nd: model.formulation.ndof(),
                blocks,
            },
            mass,
            tolerance,
        ),
    }
}

/// An error naming the scene's most extreme value when `omega` (rad/s) overflows, or its
/// fourth power does: Lanczos forms `|K x|²` of unit vectors, so a model whose `ω⁴` overflows
/// cannot be analysed (`check` refuses it), and a run is refused alike whether or not its step
/// needs Lanczos.
fn check_finite(scene: &Scene, omega: f64) -> Result<()> {
    if omega.powi(4).is_finite() {
        return Ok(());
    }
    Err(Error::scene(
        scene.most_extreme(0, &["E", "rho", "thickness", "penalty"]),
        format!(
            "the stiffness or mass of the model overflows (ω_max = {omega}); check E, rho, \
             thickness, the penalty and the mesh size"
        ),
    ))
}

/// The history columns `scene` asks for in `model` (the scene's), each checked against the
/// model's DOFs: what [`Setup::probes`] gives, without the rest of the setup.
///
/// # Errors
/// As [`Setup::probes`].
pub fn probes(scene: &Scene, model: &Model) -> Result<Vec<Probe>> {
    let nd = model.formulation.ndof();
    let elements = model.probe_elements(&scene.output.probes)?;
    scene
        .output
        .probes
        .iter()
        .zip(elements)
        .enumerate()
        .map(|(k, (pr, element))| {
            let d = dof_index(
                &pr.dof,
                model.formulation,
                &format!("output.probes[{k}].dof"),
            )?;
            let offset = pr.at.map(|[x, y]| {
                crate::mesh::geometry::Vec2::new(x, y) - model.elements[element].props.centroid
            });
            Ok(Probe {
                name: pr.column(),
                element,
                dof: d,
                nd,
                offset,
                formulation: model.formulation,
            })
        })
        .collect()
}

/// The time step of a run: the override, else the scene's `dt`, else its `dt_factor` of
/// `Δt_crit`.
fn time_step(scene: &Scene, o: &Overrides, dt_crit: f64) -> Result<f64> {
    Ok(match (o.dt, scene.time.dt, scene.time.dt_factor) {
        (Some(_), ..) if o.dt_factor.is_some() => {
            return Err(Error::scene(
                "--dt-factor",
                "give --dt or --dt-factor, not both",
            ))
        }
        (Some(dt), _, _) if dt > 0.0 && dt.is_finite() => dt,
        (Some(dt), _, _) => {
            return Err(Error::scene(
                "--dt",
                format!("must be a finite number > 0, got {dt}"),
            ))
        }
        (None, ..) if o.dt_factor.is_some() => match o.dt_factor {
            Some(f) if !(f > 0.0 && f.is_finite()) => {
                return Err(Error::scene(
                    "--dt-factor",
                    format!("must be a finite number > 0, got {f}"),
                ))
            }
            Some(f) if dt_crit.is_finite() => f * dt_crit,
            _ => {
                return Err(Error::scene(
                    "--dt-factor",
                    "Δt_crit is infinite (no spring is loaded): give --dt instead",
                ))
            }
        },
        (None, Some(dt), _) => dt,
        (None, None, Some(f)) if dt_crit.is_finite() => f * dt_crit,
        (None, None, _) => {
            return Err(Error::scene(
                "time.dt_factor",
                "Δt_crit is infinite (no spring is loaded): give `time.dt` instead",
            ))
        }
    })
}

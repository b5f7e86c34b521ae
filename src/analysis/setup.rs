//! The setup of a scene: everything an analysis computes with, built once per command. Every
//! command, test and bench starts from [`Setup::new`]; the analyses take it with their own
//! parameters.

use crate::analysis::{eigen, stability};
use crate::error::{Error, Result};
use crate::force::contact::{self, Contact, WithBlocks};
use crate::force::evaluator::{self, Evaluator};
use crate::force::failure::{self, PlasticForces};
use crate::input::scene::{EvaluatorKind, Scene};
use crate::model::loads::Loads;
use crate::model::mass::Mass;
use crate::model::{dof_index, Model};
use crate::output::Probe;
use crate::step::integrator::CentralDifference;

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
    /// `M` and its inverse.
    pub mass: Mass,
    /// Point loads and gravity.
    pub loads: Loads,
    /// The contact of the scene in its initial state; `None` when the scene declares none
    /// (then no contact search is done). Each integrator starts from a copy.
    pub contact: Option<Contact>,
    /// Largest circular frequency (rad/s), by Lanczos (`eigen::omega_max`); with contact, of
    /// `K` plus every contact closed against rigid ground (`contact::stiffness_estimate`). The
    /// one definition every command uses.
    pub omega_max: f64,
    /// Critical time step `2/ω_max` (s).
    pub dt_crit: f64,
    /// The time step of a run (s).
    pub dt: f64,
    /// Steps of a run.
    pub steps: u64,
}

impl Setup {
    /// Builds everything an analysis of `scene` needs.
    pub fn new(scene: &Scene, overrides: &Overrides) -> Result<Setup> {
        let model = Model::build(scene)?;
        let kind = overrides.evaluator.unwrap_or(scene.evaluator);
        let evaluator = evaluator::build(&model, kind);
        let plastic = failure::build(&model, kind);
        let mass = Mass::new(&model);
        let loads = Loads::new(&model);
        let contact = Contact::new(&model);
        let omega_max = match &contact {
            None => eigen::omega_max(&model, evaluator.as_ref(), &mass),
            Some(c) => {
                let blocks = contact::stiffness_estimate(&model, c);
                eigen::omega_max(
                    &model,
                    &WithBlocks {
                        inner: evaluator.as_ref(),
                        nd: model.formulation.ndof(),
                        blocks,
                    },
                    &mass,
                )
            }
        };
        if !omega_max.is_finite() {
            return Err(Error::scene(
                scene.most_extreme(0, &["E", "rho", "thickness", "penalty"]),
                format!(
                    "the stiffness or mass of the model overflows (ω_max = {omega_max}); check E, \
                     rho, thickness, the penalty and the mesh size"
                ),
            ));
        }
        let dt_crit = stability::critical_time_step(omega_max);
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
            mass,
            loads,
            contact,
            omega_max,
            dt_crit,
            dt,
            steps,
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
        if !self.model.prescribed.is_empty() {
            cd = cd.with_prescribed(&self.model);
        }
        cd.set_stability_limit(self.dt_crit);
        cd
    }

    /// The history columns the scene asks for, each checked against the model's DOFs.
    pub fn probes(&self) -> Result<Vec<Probe>> {
        probes(&self.scene, &self.model)
    }
}

/// The history columns `scene` asks for in `model` (the scene's), each checked against the
/// model's DOFs: what [`Setup::probes`] gives, without the rest of the setup.
pub fn probes(scene: &Scene, model: &Model) -> Result<Vec<Probe>> {
    let nd = model.formulation.ndof();
    scene
        .output
        .probes
        .iter()
        .enumerate()
        .map(|(k, pr)| {
            let d = dof_index(
                &pr.dof,
                model.formulation,
                &format!("output.probes[{k}].dof"),
            )?;
            let element = model.probe_element(k, pr)?;
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

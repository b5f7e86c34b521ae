//! Evaluators: `U ↦ f_int(U)`, the internal forces of the model (eqs. 7–16;
//! the crate documentation's *Assembled form* and *Element-wise form*).
//!
//! Two implementations of one contract, which the integrator cannot tell apart:
//! [`Assembled`] multiplies by the global stiffness `K` of eq. 7; [`ElementWise`] sums, per
//! element, the tractions on its own boundary (eq. 15) with no global matrix.

mod assembled;
mod element_wise;
mod failing;
mod poisson;
mod sweep;

pub use assembled::{assemble, interface_stiffness, Assembled, BlockCsr};
pub use element_wise::ElementWise;
pub use poisson::{
    cells, AssembledPoisson, ElementWisePoisson, FacetPressures, PressureOperator, WithPoisson,
    WAVE_FROM,
};

use crate::force::failure::{FailureState, PlasticForces};
use crate::input::scene::EvaluatorKind;
use crate::model::formulation::{Formulation, Hybrid, Rigid};
use crate::model::mass::Update;
use crate::model::Model;

/// Internal forces of a model in a given state.
pub trait Evaluator: Send + Sync {
    /// Which evaluator this is.
    fn kind(&self) -> EvaluatorKind;
    /// `f = f_int(u)`; both slices hold `ndof` entries per element, element after element.
    /// Allocation-free; parallel over elements; the result does not depend on the thread count.
    fn internal_force(&self, u: &[f64], f: &mut [f64]);
    /// [`Evaluator::internal_force`] of a model whose interfaces fail: `f = f_el(u) − f_p`, the
    /// Gauss points of the failing interfaces `plastic` return-mapped at `u` in `state` in the
    /// same pass (`force::failure`).
    ///
    /// The default adds the failing interfaces in a second pass
    /// ([`PlasticForces::add_plastic`]); the evaluators of the crate do it in their sweep.
    ///
    /// # Panics
    /// If the evaluator was built for a model whose interfaces do not fail, or `plastic` for
    /// another formulation.
    fn internal_force_failing(&self, u: &[f64], f: &mut [f64], (plastic, state): Failure<'_>) {
        self.internal_force(u, f);
        plastic.add_plastic(u, state, f);
    }
    /// What its last [`Evaluator::internal_force_failing`], at `u`, adds to `½ Uᵀ f_int`
    /// beyond the elastic energy and [`PlasticForces::energy_offset`], with the failing
    /// interfaces in `state` as it left them (J): zero but for the Poisson correction's share
    /// ([`WithPoisson`]).
    fn energy_offset(&self, _u: &[f64], _failure: (&dyn PlasticForces, &FailureState)) -> f64 {
        0.0
    }
    /// The bytes of data it holds, all of which one evaluation reads.
    fn bytes(&self) -> usize;
    /// The evaluator's fused step, when it has one; the integrator then steps through it
    /// instead of evaluating and updating in two passes.
    fn fused(&self) -> Option<&dyn FusedStep> {
        None
    }
}

/// An evaluator that fuses the evaluation with the explicit update (central difference,
/// [`crate::step::integrator`]): each element is advanced as soon as its force is complete.
pub trait FusedStep {
    /// One explicit step: with `force` holding the rest of the net force, `−P − f_c`, each
    /// element gets `f_int(U^n) + force` and is advanced by `update`; `force` is left zero.
    /// `loaded` lists, in order, the only elements where `force` may be non-zero (`None`: any
    /// element), so that a step need not read the rest. Returns `Σ v̄ᵀ M v̄` (`v̄` the mean of
    /// the old and new velocities) when the update is damped, else 0: the damping's work of
    /// the step is `α Δt` times it.
    fn advance(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        force: &mut [f64],
        loaded: Option<&[u32]>,
        update: &Update,
    ) -> f64;

    /// [`FusedStep::advance`] of a model whose interfaces fail: the Gauss points of `failure`
    /// return-mapped at `U^n` and their plastic forces added in the same pass
    /// ([`Evaluator::internal_force_failing`], whose panics it shares).
    fn advance_failing(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        force: &mut [f64],
        loaded: Option<&[u32]>,
        update: &Update,
        failure: Failure<'_>,
    ) -> f64;

    /// The same step on the state stored in groups of four elements, where that is faster:
    /// the sweep goes four elements at a time in lanes.
    fn grouped(&self) -> Option<&dyn GroupedStep> {
        None
    }
}

/// [`FusedStep::advance`] undamped with a lumped `M⁻¹`, on `U`, `v` and the diagonal `inv` of
/// `M⁻¹` stored in groups of four elements ([`crate::lanes::grouped`]).
pub trait GroupedStep {
    /// One step, `force` as in [`FusedStep::advance`] and `loaded` named: the same bits.
    #[allow(clippy::too_many_arguments)]
    fn advance_grouped(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        inv: &[f64],
        force: &mut [f64],
        loaded: &[u32],
        dt: f64,
    );
}

/// The failing interfaces of a model and their state, for an evaluation that updates it.
pub type Failure<'a> = (&'a dyn PlasticForces, &'a mut FailureState);

/// The global stiffness `K` of eq. 7 as scalar triplets `(row, col, value)` over all DOFs
/// (with the Poisson correction's part for `rigid-poisson`, which is not symmetric).
pub fn stiffness_triplets(model: &Model) -> Vec<(usize, usize, f64)> {
    match model.formulation {
        Formulation::Rigid => assemble::<Rigid, 3>(model).triplets(),
        Formulation::RigidPoisson => {
            let mut k = assemble::<Rigid, 3>(model).triplets();
            k.extend(PressureOperator::new(model).triplets());
            k
        }
        Formulation::Hybrid { .. } => assemble::<Hybrid, 6>(model).triplets(),
    }
}

/// The evaluator `kind` for the model's formulation.
pub fn build(model: &Model, kind: EvaluatorKind) -> Box<dyn Evaluator> {
    match (model.formulation, kind) {
        (Formulation::Rigid, EvaluatorKind::Assembled) => {
            Box::new(Assembled::<Rigid, 3>::new(model))
        }
        (Formulation::Rigid, EvaluatorKind::ElementWise) => {
            Box::new(ElementWise::<Rigid, 3>::new(model))
        }
        (Formulation::RigidPoisson, EvaluatorKind::Assembled) => {
            Box::new(WithPoisson::new(model, AssembledPoisson::new(model)))
        }
        (Formulation::RigidPoisson, EvaluatorKind::ElementWise) => {
            Box::new(WithPoisson::new(model, ElementWisePoisson::new(model)))
        }
        (Formulation::Hybrid { .. }, EvaluatorKind::Assembled) => {
            Box::new(Assembled::<Hybrid, 6>::new(model))
        }
        (Formulation::Hybrid { .. }, EvaluatorKind::ElementWise) => {
            Box::new(ElementWise::<Hybrid, 6>::new(model))
        }
    }
}

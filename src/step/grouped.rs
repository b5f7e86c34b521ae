//! The step's state in groups of four elements: `U`, `v` and the lumped `M⁻¹` laid out so that
//! the lanes of a fused step (`force::evaluator::GroupedStep`, [`crate::lanes::grouped`]) load
//! four elements' DOFs with no transpose.
//!
//! Where the sweep goes in lanes (a rigid grid whose rows are a multiple of four elements long)
//! and a step is undamped with a lumped `M⁻¹` and no gravity or contact, the integrator moves
//! `U` and `v` into the groups at the first such step of a stretch between two checks and back
//! before any check, output or return, with the same bits. It saves about a sixth of a step
//! on undamped rigid grids (`benches/summary.md`, the grouped grid); moving in and out costs
//! about one and a half steps, hence [`MIN_STRETCH`].

use crate::force::evaluator::{Evaluator, GroupedStep};
use crate::lanes::grouped;
use crate::model::mass::Mass;

/// The fewest steps between two checks that go on the state in groups. Moving `U` and `v` into
/// the groups and back reads and writes each twice, about the bytes of one and a half steps,
/// and a grouped step of a rigid grid saves about a sixth of a step: shorter stretches
/// (outputs every few steps) stay on the plain state.
pub const MIN_STRETCH: u64 = 16;

/// `U`, `v` and the lumped `M⁻¹` in groups of four elements ([`grouped`]).
#[derive(Debug)]
pub struct Groups {
    u: Vec<f64>,
    v: Vec<f64>,
    inv: Vec<f64>,
    /// DOFs per element.
    nd: usize,
    /// Whether `u` and `v` hold the state, and the integrator's own are behind.
    active: bool,
}

impl Groups {
    /// The groups of a run of `dofs` DOFs, when its steps can go on them: the evaluator's
    /// fused step goes in lanes, the run is undamped, the loaded elements are known (no
    /// gravity, no contact) and `M⁻¹` is lumped. Else `None`.
    pub fn new(
        evaluator: &dyn Evaluator,
        mass: &Mass,
        dofs: usize,
        undamped: bool,
        loaded: bool,
    ) -> Option<Groups> {
        evaluator.fused().and_then(|f| f.grouped())?;
        let inv = mass.lumped_inverse().filter(|_| undamped && loaded)?;
        let (nd, len) = (mass.nd(), grouped::len(mass.nd(), dofs));
        let mut g = vec![0.0; len];
        grouped::group(nd, inv, &mut g);
        Some(Groups {
            u: vec![0.0; len],
            v: vec![0.0; len],
            inv: g,
            nd,
            active: false,
        })
    }

    /// Whether the state is in the groups (the plain `U` and `v` are behind).
    pub fn active(&self) -> bool {
        self.active
    }

    /// One undamped step through `step` on the groups, `u` and `v` moved into them first if the
    /// last step was not grouped: `v ← v − Δt M⁻¹ f`, `U ← U + Δt v`, with `force` holding
    /// `−P` on the `loaded` elements and zero elsewhere (left zero).
    pub fn advance(
        &mut self,
        step: &dyn GroupedStep,
        u: &[f64],
        v: &[f64],
        force: &mut [f64],
        loaded: &[u32],
        dt: f64,
    ) {
        if !self.active {
            grouped::group(self.nd, u, &mut self.u);
            grouped::group(self.nd, v, &mut self.v);
            self.active = true;
        }
        step.advance_grouped(&mut self.u, &mut self.v, &self.inv, force, loaded, dt);
    }

    /// The velocity of DOF `d` (plain index) in the groups.
    #[inline]
    pub fn velocity(&self, d: usize) -> f64 {
        self.v[grouped::index(self.nd, d)]
    }

    /// Brings `U` and `v` back from the groups into `u` and `v`, if the last step left them
    /// there.
    pub fn leave(&mut self, u: &mut [f64], v: &mut [f64]) {
        if self.active {
            grouped::ungroup(self.nd, &self.u, u);
            grouped::ungroup(self.nd, &self.v, v);
            self.active = false;
        }
    }
}

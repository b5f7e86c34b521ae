//! Hybrid elements that yield (issue 43): the plastic part of the interior term of eq. 15.
//!
//! The evaluators add each hybrid element's interior force `t A D ε` on its strain DOFs (the
//! `+D` of eq. 8). An element with a strength ([`ElementStrength`]) carries the stress
//! `σ = D (ε − ε_p)`; once per step, at `U^n`, its trial stress `D (ε − ε_p)` is return-mapped
//! and the interior force becomes `t A σ`: `f −= t A (D ε − σ)`. What the flow dissipates,
//! `t A σ · Δε_p`, is booked as the `plastic` energy. The correction reads only the element's
//! own strains, so both evaluators give the same forces as without it, less the same
//! correction: their trajectories stay as close as without yielding.

use crate::model::plasticity::{compliance_times, ElementStrength};
use crate::model::Model;
use nalgebra::{Matrix3, Vector3};

/// An element that may yield.
#[derive(Debug, Clone, Copy)]
struct Yielding {
    /// Its index in `Model::elements`.
    element: u32,
    /// Its elasticity `D` (Pa).
    d: Matrix3<f64>,
    /// `t A` (m³).
    volume: f64,
    strength: ElementStrength,
}

/// The elements that may yield, in the order of `Model::elements`.
#[derive(Debug, Clone)]
pub struct PlasticElements {
    elements: Vec<Yielding>,
    /// DOFs per element (6: hybrid).
    ndof: usize,
}

/// The plastic state of the elements that may yield, in the order of
/// [`PlasticElements::elements`].
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ElementState {
    /// Each element's plastic strain `ε_p = (ε_x, ε_y, γ_xy)`.
    pub strain: Vec<[f64; 3]>,
    /// Whether it flowed at the last return mapping.
    pub yielding: Vec<bool>,
    /// The work dissipated by their flow so far (J).
    pub dissipated: f64,
}

impl PlasticElements {
    /// The model's elements that have a strength; `None` when none has.
    pub fn build(model: &Model) -> Option<Self> {
        let elements: Vec<Yielding> = model
            .elements
            .iter()
            .enumerate()
            .filter_map(|(k, e)| {
                e.strength.map(|strength| Yielding {
                    element: k as u32,
                    d: e.d,
                    volume: model.thickness * e.props.area,
                    strength,
                })
            })
            .collect();
        (!elements.is_empty()).then(|| PlasticElements {
            elements,
            ndof: model.formulation.ndof(),
        })
    }

    /// The indices (in `Model::elements`) of the elements that may yield.
    pub fn elements(&self) -> impl Iterator<Item = u32> + '_ {
        self.elements.iter().map(|y| y.element)
    }

    /// Every element elastic.
    pub fn initial(&self) -> ElementState {
        let n = self.elements.len();
        ElementState {
            strain: vec![[0.0; 3]; n],
            yielding: vec![false; n],
            dissipated: 0.0,
        }
    }

    fn strain(&self, y: &Yielding, u: &[f64]) -> Vector3<f64> {
        let k = y.element as usize * self.ndof;
        Vector3::new(u[k + 3], u[k + 4], u[k + 5])
    }

    /// Return-maps every element at `u` (`f` holding the internal forces with elastic
    /// interiors) and makes its interior force `t A σ`: `f −= t A (D ε − σ)`; books the work of
    /// the flow.
    pub fn correct(&self, u: &[f64], state: &mut ElementState, f: &mut [f64]) {
        for (j, y) in self.elements.iter().enumerate() {
            let eps = self.strain(y, u);
            let elastic = y.d * eps;
            let plastic = Vector3::from(state.strain[j]);
            let trial = elastic - y.d * plastic;
            let sigma = y.strength.return_map(&y.d, &trial);
            let flowed = sigma != trial;
            state.yielding[j] = flowed;
            if flowed {
                let step = compliance_times(&y.d, &(trial - sigma));
                state.strain[j] = (plastic + step).into();
                state.dissipated += y.volume * sigma.dot(&step);
            }
            if flowed || plastic != Vector3::zeros() {
                let k = y.element as usize * self.ndof + 3;
                let c = y.volume * (elastic - sigma);
                for i in 0..3 {
                    f[k + i] -= c[i];
                }
            }
        }
    }

    /// `½ Uᵀ f_int` minus the elastic energy of the elements that yield: `½ Σ t A ε_pᵀ σ` (J).
    pub fn energy_offset(&self, u: &[f64], state: &ElementState) -> f64 {
        self.elements
            .iter()
            .zip(&state.strain)
            .map(|(y, p)| {
                let p = Vector3::from(*p);
                let sigma = y.d * (self.strain(y, u) - p);
                0.5 * y.volume * p.dot(&sigma)
            })
            .sum()
    }

    /// Per element of a model of `n` elements: its plastic strain and whether it flowed at the
    /// last return mapping (zeros and `false` for the elements without a strength).
    pub fn per_element(&self, state: &ElementState, n: usize) -> Vec<([f64; 3], bool)> {
        let mut out = vec![([0.0; 3], false); n];
        for (e, s, f) in self.report(state) {
            out[e as usize] = (s, f);
        }
        out
    }

    /// Each element's plastic strain and whether it flowed, with its index in
    /// `Model::elements`.
    pub fn report<'s>(
        &'s self,
        state: &'s ElementState,
    ) -> impl Iterator<Item = (u32, [f64; 3], bool)> + 's {
        self.elements
            .iter()
            .zip(state.strain.iter().zip(&state.yielding))
            .map(|(y, (s, f))| (y.element, *s, *f))
    }
}

//! The interface law (eq. 11): what an interface's springs do with its relative displacement.
//!
//! On an interface with unit normal `n` and tangent `s`, the relative displacement
//! `δ = u_b − u_a` has the components `(δ_n, δ_s) = (n·δ, s·δ)`, and the traction on `a` from
//! `b` is `λ = λ_n n + λ_s s` (Pa). An [`InterfaceLaw`] maps `(δ_n, δ_s)` to `(λ_n, λ_s)` and
//! gives the tangent `dλ/dδ`, given the interface's elastic moduli `k = (k_n, k_s)` of eq. 12
//! (Pa/m, the hybrid penalty included). The evaluators, the statics and the contact springs
//! all reach eq. 11 through the model's law ([`crate::model::Model::law`]); [`Elastic`] is the
//! default.
//!
//! A law that is linear and stateless ([`InterfaceLaw::is_linear`]) is a constant
//! `λ = diag(k_n', k_s') δ`: the evaluators then take its springs once, when they are built
//! (`<dyn InterfaceLaw>::springs`), assemble a constant `K`, and split the Gauss rule of an
//! edge into `δ₀ ± δ₁` (`force::evaluator::ElementWise`). A law with a state per Gauss point
//! (plasticity, softening) will need neither.

use std::fmt::Debug;

/// A traction–separation law of the interfaces (eq. 11), on each interface's `(n, s)` axes.
pub trait InterfaceLaw: Send + Sync + Debug {
    /// The traction `(λ_n, λ_s)` (Pa) at the relative displacement `δ = (δ_n, δ_s)` (m) of an
    /// interface with elastic moduli `k = (k_n, k_s)` (Pa/m, eq. 12).
    fn traction(&self, k: [f64; 2], delta: [f64; 2]) -> [f64; 2];
    /// The tangent `dλ/dδ` (Pa/m) at `δ`, row by row: `[[dλ_n/dδ_n, dλ_n/dδ_s],
    /// [dλ_s/dδ_n, dλ_s/dδ_s]]`.
    fn tangent(&self, k: [f64; 2], delta: [f64; 2]) -> [[f64; 2]; 2];
    /// Whether `λ = tangent · δ` with the same tangent at every `δ` and no state: only then
    /// may the evaluators use a constant `K` and the Gauss split `δ₀ ± δ₁`.
    fn is_linear(&self) -> bool;
}

impl dyn InterfaceLaw + '_ {
    /// The springs `(k_n', k_s')` (Pa/m) of a linear law on an interface with moduli `k`: its
    /// tangent, `λ = diag(k_n', k_s') δ`. The evaluators and the contact take them when they
    /// are built; panics for a law that is not linear, or whose tangent couples `δ_n` and
    /// `δ_s` (neither is supported yet).
    pub fn springs(&self, k: [f64; 2]) -> [f64; 2] {
        assert!(
            self.is_linear(),
            "the interface law {self:?} is not linear: the evaluators need a linear law"
        );
        let [[k_n, ns], [sn, k_s]] = self.tangent(k, [0.0; 2]);
        assert!(
            ns == 0.0 && sn == 0.0,
            "the interface law {self:?} couples the normal and shear springs"
        );
        [k_n, k_s]
    }
}

/// Linear elastic springs (eqs. 11, 12): `λ = diag(k_n, k_s) δ`, the default law.
#[derive(Debug, Clone, Copy, Default)]
pub struct Elastic;

impl InterfaceLaw for Elastic {
    fn traction(&self, k: [f64; 2], delta: [f64; 2]) -> [f64; 2] {
        [k[0] * delta[0], k[1] * delta[1]]
    }
    fn tangent(&self, k: [f64; 2], _: [f64; 2]) -> [[f64; 2]; 2] {
        [[k[0], 0.0], [0.0, k[1]]]
    }
    fn is_linear(&self) -> bool {
        true
    }
}

//! The mass matrix `M`: block-diagonal, one block per element (eqs. 7–9), inverted once.
//!
//! Fixed DOFs get a zero row in `M⁻¹`, so they never move; the explicit step stays
//! element-local.

use crate::model::Model;

/// `M` and `M⁻¹` of a model. Diagonal blocks are stored as diagonals.
#[derive(Debug, Clone)]
pub enum Mass {
    /// Lumped: `m[i]` per DOF, `inv[i] = 1/m[i]` (0 for a fixed DOF).
    Diagonal { m: Vec<f64>, inv: Vec<f64>, inv_sqrt: Vec<f64> },
}

impl Mass {
    /// The mass of every element from the formulation (eq. 9 for rigid).
    pub fn new(model: &Model) -> Mass {
        let nd = model.formulation.ndof();
        let mut m = Vec::with_capacity(model.n_dofs());
        for el in &model.elements {
            let block = model.formulation.mass(&el.props, el.rho * model.thickness);
            debug_assert!((0..nd).all(|i| (0..nd).all(|j| i == j || block[i * nd + j] == 0.0)));
            m.extend((0..nd).map(|i| block[i * nd + i]));
        }
        let mut inv: Vec<f64> = m.iter().map(|x| 1.0 / x).collect();
        for &d in &model.fixed {
            inv[d] = 0.0;
        }
        let inv_sqrt = inv.iter().map(|x| x.sqrt()).collect();
        Mass::Diagonal { m, inv, inv_sqrt }
    }

    /// The diagonal of `M` (lumped, so the whole matrix).
    pub fn diagonal(&self) -> &[f64] {
        match self {
            Mass::Diagonal { m, .. } => m,
        }
    }

    /// `a = −M⁻¹ f` in place (the acceleration of a net internal-minus-external force `f`).
    pub fn accelerate(&self, f: &mut [f64]) {
        match self {
            Mass::Diagonal { inv, .. } => {
                for (x, w) in f.iter_mut().zip(inv) {
                    *x = -*x * w;
                }
            }
        }
    }

    /// Kinetic energy `½ vᵀ M v`.
    pub fn kinetic_energy(&self, v: &[f64]) -> f64 {
        match self {
            Mass::Diagonal { m, .. } => 0.5 * v.iter().zip(m).map(|(v, m)| m * v * v).sum::<f64>(),
        }
    }

    /// `y = M^{−½} x` restricted to the free DOFs (0 on fixed DOFs): with it, `M^{−½} K M^{−½}`
    /// has the squared frequencies `ω²` of `K φ = ω² M φ` as eigenvalues.
    pub fn inv_sqrt(&self, x: &[f64], y: &mut [f64]) {
        match self {
            Mass::Diagonal { inv_sqrt, .. } => {
                for ((y, x), s) in y.iter_mut().zip(x).zip(inv_sqrt) {
                    *y = x * s;
                }
            }
        }
    }
}

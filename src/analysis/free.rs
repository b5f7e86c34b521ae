//! The linear system of the free DOFs: `K_ff` as a faer sparse matrix and the diagonal of
//! `M_ff`, for the static, eigen and stability analyses (the README's *Commands*). Built from the
//! same
//! assembled `K` as the assembled evaluator: one copy of the physics.

use crate::force::evaluator::stiffness_triplets;
use crate::model::mass::Mass;
use crate::model::Model;
use faer::sparse::{SparseColMat, Triplet};

/// `K_ff`, `M_ff` and the map between free and global DOFs.
pub struct FreeSystem {
    /// Global index of each free DOF.
    pub free: Vec<usize>,
    /// Free index of each global DOF (`usize::MAX` for a fixed one).
    pub index: Vec<usize>,
    /// `K_ff`, both triangles.
    pub k: SparseColMat<usize, f64>,
    /// `M_ff`, both triangles (diagonal for a lumped mass, element blocks for hybrid).
    pub m: SparseColMat<usize, f64>,
    /// Diagonal of `M_ff`.
    pub mass: Vec<f64>,
}

impl FreeSystem {
    /// Assembles `K_ff` and `M_ff` of a model.
    ///
    /// # Panics
    /// Only when memory runs out while `K_ff` or `M_ff` is built (faer reports it where a `Vec`
    /// would abort): their entries are filtered to the free DOFs, so none is out of range.
    pub fn new(model: &Model, mass: &Mass) -> FreeSystem {
        let n = model.n_dofs();
        let mut index = vec![0usize; n];
        for &d in &model.fixed {
            index[d] = usize::MAX;
        }
        let mut free = Vec::with_capacity(n - model.fixed.len());
        for (d, i) in index.iter_mut().enumerate() {
            if *i == 0 {
                *i = free.len();
                free.push(d);
            }
        }
        let triplets: Vec<Triplet<usize, usize, f64>> = stiffness_triplets(model)
            .into_iter()
            .filter(|&(r, c, v)| v != 0.0 && index[r] != usize::MAX && index[c] != usize::MAX)
            .map(|(r, c, v)| Triplet::new(index[r], index[c], v))
            .collect();
        let k = SparseColMat::try_new_from_triplets(free.len(), free.len(), &triplets)
            .expect("indices lie within the free DOFs");
        let m_triplets: Vec<Triplet<usize, usize, f64>> = mass
            .triplets()
            .into_iter()
            .filter(|&(r, c, v)| v != 0.0 && index[r] != usize::MAX && index[c] != usize::MAX)
            .map(|(r, c, v)| Triplet::new(index[r], index[c], v))
            .collect();
        let m = SparseColMat::try_new_from_triplets(free.len(), free.len(), &m_triplets)
            .expect("indices lie within the free DOFs");
        let diag = mass.diagonal();
        let mass = free.iter().map(|&d| diag[d]).collect();
        FreeSystem {
            free,
            index,
            k,
            m,
            mass,
        }
    }

    /// `K_ff − σ M_ff`.
    ///
    /// # Panics
    /// Only when memory runs out, as [`FreeSystem::new`]: the entries are those of `K_ff` and
    /// `M_ff`, all in range.
    pub fn shifted(&self, sigma: f64) -> SparseColMat<usize, f64> {
        let mut t = Vec::with_capacity(self.k.compute_nnz() + self.m.compute_nnz());
        for (mat, scale) in [(&self.k, 1.0), (&self.m, -sigma)] {
            for j in 0..self.n() {
                for (&i, &v) in mat
                    .symbolic()
                    .row_idx_of_col_raw(j)
                    .iter()
                    .zip(mat.val_of_col(j))
                {
                    t.push(Triplet::new(i, j, scale * v));
                }
            }
        }
        SparseColMat::try_new_from_triplets(self.n(), self.n(), &t)
            .expect("indices lie within the free DOFs")
    }

    /// Applies an operator on vectors over all DOFs to a vector over the free DOFs.
    pub fn apply_free(&self, x: &[f64], y: &mut [f64], op: impl Fn(&[f64], &mut [f64])) {
        let full = self.scatter(x);
        let mut out = vec![0.0; full.len()];
        op(&full, &mut out);
        for (i, &d) in self.free.iter().enumerate() {
            y[i] = out[d];
        }
    }

    /// Number of free DOFs.
    pub fn n(&self) -> usize {
        self.free.len()
    }

    /// A vector over all DOFs from one over the free DOFs (zeros on the fixed ones).
    pub fn scatter(&self, x: &[f64]) -> Vec<f64> {
        let mut full = vec![0.0; self.index.len()];
        for (i, &d) in self.free.iter().enumerate() {
            full[d] = x[i];
        }
        full
    }
}

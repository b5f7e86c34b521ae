//! The assembled evaluator (eqs. 7–13): `K = Σ_s K_<s>` from the interfaces, stored as a
//! block-sparse matrix with one `N × N` block per element pair, and `f_int = K U`.

use super::Evaluator;
use crate::input::scene::EvaluatorKind;
use crate::model::formulation::Kinematics;
use crate::model::law::InterfaceLaw;
use crate::model::{Interface, Model, GROUND};
use crate::parallel::for_each_chunk;
use nalgebra::{Matrix2, SMatrix};
use std::marker::PhantomData;

/// The stiffness of one interface, `K_ab = t ∫ Bᵀ diag(k_n', k_s') B dℓ` with
/// `B = [n s]ᵀ [−N_a(x), N_b(x)]` and `(k_n', k_s')` the springs of the linear `law` on the
/// interface's moduli (eq. 11; `(k_n, k_s)` for [`crate::model::law::Elastic`]), integrated
/// exactly by 2-point Gauss ([`Interface::gauss_points`]).
/// Returns the blocks `(aa, ab, ba, bb)`; for a ground interface only `aa` is non-zero.
pub fn interface_stiffness<K: Kinematics<N>, const N: usize>(
    i: &Interface,
    law: &dyn InterfaceLaw,
    xa: crate::mesh::geometry::Vec2,
    xb: crate::mesh::geometry::Vec2,
    t: f64,
) -> [SMatrix<f64, N, N>; 4] {
    let r = Matrix2::new(i.normal.x, i.normal.y, i.tangent.x, i.tangent.y);
    let [k_n, k_s] = law.springs([i.k_n, i.k_s]);
    let k = Matrix2::new(k_n, 0.0, 0.0, k_s);
    let (g, w) = i.gauss_points();
    let mut out = [SMatrix::<f64, N, N>::zeros(); 4];
    for x in g {
        let ba = -(r * K::shape(x - xa));
        let bb = r * K::shape(x - xb);
        let c = t * w;
        out[0] += c * ba.transpose() * k * ba;
        if i.b != GROUND {
            out[1] += c * ba.transpose() * k * bb;
            out[2] += c * bb.transpose() * k * ba;
            out[3] += c * bb.transpose() * k * bb;
        }
    }
    out
}

/// A square block-sparse matrix in compressed-row form with `N × N` blocks.
#[derive(Debug, Clone)]
pub struct BlockCsr<const N: usize> {
    /// Blocks of row `r` are `row_start[r] .. row_start[r + 1]`.
    pub row_start: Vec<u32>,
    /// Block column of each block, ascending within a row.
    pub cols: Vec<u32>,
    /// The blocks, row-major.
    pub blocks: Vec<[[f64; N]; N]>,
}

impl<const N: usize> BlockCsr<N> {
    /// Sums block triplets `(row, col, block)` into compressed rows (duplicates added).
    pub fn from_triplets(n_rows: usize, mut triplets: Vec<(u32, u32, SMatrix<f64, N, N>)>) -> Self {
        triplets.sort_by_key(|&(r, c, _)| (r, c));
        let mut row_start = vec![0u32; n_rows + 1];
        let mut cols: Vec<u32> = Vec::with_capacity(triplets.len());
        let mut blocks: Vec<[[f64; N]; N]> = Vec::with_capacity(triplets.len());
        let mut last = None;
        for (r, c, b) in triplets {
            if last == Some((r, c)) {
                let top = blocks.last_mut().expect("a block was pushed for this key");
                for i in 0..N {
                    for j in 0..N {
                        top[i][j] += b[(i, j)];
                    }
                }
            } else {
                cols.push(c);
                blocks.push(std::array::from_fn(|i| std::array::from_fn(|j| b[(i, j)])));
                row_start[r as usize + 1] += 1;
                last = Some((r, c));
            }
        }
        for r in 0..n_rows {
            row_start[r + 1] += row_start[r];
        }
        BlockCsr {
            row_start,
            cols,
            blocks,
        }
    }

    /// Number of block rows.
    pub fn n_rows(&self) -> usize {
        self.row_start.len() - 1
    }

    /// `y = A x`, parallel over block rows; each row sums in a fixed order.
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        let (x, _) = x.as_chunks::<N>();
        let (y, _) = y.as_chunks_mut::<N>();
        for_each_chunk(y, |first, rows| {
            for (i, yr) in rows.iter_mut().enumerate() {
                let r = first + i;
                let mut acc = [0.0; N];
                for k in self.row_start[r] as usize..self.row_start[r + 1] as usize {
                    let (b, xc) = (&self.blocks[k], &x[self.cols[k] as usize]);
                    for p in 0..N {
                        for q in 0..N {
                            acc[p] += b[p][q] * xc[q];
                        }
                    }
                }
                *yr = acc;
            }
        });
    }

    /// The matrix as scalar triplets `(row, col, value)`, for sparse and dense analyses.
    pub fn triplets(&self) -> Vec<(usize, usize, f64)> {
        let mut out = Vec::with_capacity(self.blocks.len() * N * N);
        for r in 0..self.n_rows() {
            for k in self.row_start[r] as usize..self.row_start[r + 1] as usize {
                let c = self.cols[k] as usize;
                for p in 0..N {
                    for q in 0..N {
                        out.push((r * N + p, c * N + q, self.blocks[k][p][q]));
                    }
                }
            }
        }
        out
    }

    /// The matrix as a dense faer matrix (small models only: tests, dense eigen).
    pub fn to_dense(&self) -> faer::Mat<f64> {
        let n = self.n_rows() * N;
        let mut m = faer::Mat::<f64>::zeros(n, n);
        for (r, c, v) in self.triplets() {
            m[(r, c)] += v;
        }
        m
    }
}

/// The assembled evaluator: `f_int = K U`.
pub struct Assembled<K: Kinematics<N>, const N: usize> {
    /// The global stiffness `K` of eq. 7.
    pub stiffness: BlockCsr<N>,
    kinematics: PhantomData<K>,
}

impl<K: Kinematics<N>, const N: usize> Assembled<K, N> {
    /// Assembles `K` from the interface blocks (eq. 7; eq. 13 shows its pattern) with the
    /// model's law, which must be linear.
    pub fn new(model: &Model) -> Self {
        let mut triplets = Vec::with_capacity(4 * model.interfaces.len());
        let centroid = |e: u32| model.elements[e as usize].props.centroid;
        for i in &model.interfaces {
            let xb = if i.b == GROUND {
                i.midpoint()
            } else {
                centroid(i.b)
            };
            let [kaa, kab, kba, kbb] =
                interface_stiffness::<K, N>(i, &*model.law, centroid(i.a), xb, model.thickness);
            triplets.push((i.a, i.a, kaa));
            if i.b != GROUND {
                triplets.push((i.a, i.b, kab));
                triplets.push((i.b, i.a, kba));
                triplets.push((i.b, i.b, kbb));
            }
        }
        // Every element gets a diagonal block (its interior stiffness, the `+D` of eq. 8, or
        // zero), so that an unconnected element is still a row.
        triplets.extend(model.elements.iter().enumerate().map(|(e, el)| {
            let k = if K::HAS_INTERIOR {
                K::interior_stiffness(&el.props, &el.d, model.thickness)
            } else {
                SMatrix::zeros()
            };
            (e as u32, e as u32, k)
        }));
        Assembled {
            stiffness: BlockCsr::from_triplets(model.elements.len(), triplets),
            kinematics: PhantomData,
        }
    }
}

impl<K: Kinematics<N>, const N: usize> Evaluator for Assembled<K, N> {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::Assembled
    }

    fn bytes(&self) -> usize {
        let k = &self.stiffness;
        std::mem::size_of_val(&k.row_start[..])
            + std::mem::size_of_val(&k.cols[..])
            + std::mem::size_of_val(&k.blocks[..])
    }

    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        self.stiffness.mul(u, f);
    }
}

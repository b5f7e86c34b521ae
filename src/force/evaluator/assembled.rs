//! The assembled evaluator (eqs. 7–13): `K = Σ_s K_<s>` from the interfaces, summed into one
//! `N × N` block per element pair, and `f_int = K U`.
//!
//! `K` is symmetric, so the evaluator keeps the upper triangle of each element's diagonal
//! block `K_ee` and, of each pair `a < b`, the block `K_ab` alone (`K_ba = K_abᵀ`): on a grid,
//! 5 blocks per element become 2 and a triangle. The product runs in the sweep both evaluators
//! share ([`super::sweep`]): the pair gives `K_ab U_b` to `a` and `K_abᵀ U_a` to `b`, each
//! element adds `K_ee U_e` last, and a time step advances each element as soon as its row of
//! `K U` is complete, so that `K` and the vectors are read once per step and no force vector is
//! written.

use super::failing::{Carried, Screened, WithFailure};
use super::sweep::{Couplings, Face, Sweep};
use super::{Evaluator, Failure, FusedStep};
use crate::input::scene::EvaluatorKind;
use crate::lanes::Lanes;
use crate::model::formulation::Kinematics;
use crate::model::law::InterfaceLaw;
use crate::model::mass::Update;
use crate::model::{Interface, Model, GROUND};
use nalgebra::{Matrix2, SMatrix};
use std::marker::PhantomData;

/// The stiffness of one interface, `K_ab = t ∫ Bᵀ diag(k_n', k_s') B dℓ` with
/// `B = [n s]ᵀ [−N_a(x), N_b(x)]` and `(k_n', k_s')` the springs of the interface's `law` on its
/// moduli (eq. 11; `(k_n, k_s)` for [`crate::model::law::Elastic`]), integrated
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
    ///
    /// # Panics
    /// A triplet's row is `n_rows` or more.
    pub fn from_triplets(n_rows: usize, mut triplets: Vec<(u32, u32, SMatrix<f64, N, N>)>) -> Self {
        triplets.sort_by_key(|&(r, c, _)| (r, c));
        let mut row_start = vec![0u32; n_rows + 1];
        let mut cols: Vec<u32> = Vec::with_capacity(triplets.len());
        let mut blocks: Vec<[[f64; N]; N]> = Vec::with_capacity(triplets.len());
        let mut last = None;
        for (r, c, b) in triplets {
            // The key of the last block pushed: add to that block.
            if let (true, Some(top)) = (last == Some((r, c)), blocks.last_mut()) {
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

/// The global stiffness `K` of eq. 7, summed from the interface blocks (eq. 13 shows its
/// pattern) with the model's law, which must be linear.
pub fn assemble<K: Kinematics<N>, const N: usize>(model: &Model) -> BlockCsr<N> {
    let mut triplets = Vec::with_capacity(4 * model.interfaces.len());
    let centroid = |e: u32| model.elements[e as usize].props.centroid;
    for i in &model.interfaces {
        let xb = if i.b == GROUND {
            i.midpoint()
        } else {
            centroid(i.b)
        };
        let [kaa, kab, kba, kbb] =
            interface_stiffness::<K, N>(i, model.law_of(i), centroid(i.a), xb, model.thickness);
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
    BlockCsr::from_triplets(model.elements.len(), triplets)
}

/// An `N × N` block, row-major.
pub(super) type Block<const N: usize> = [[f64; N]; N];

/// The assembled evaluator: `f_int = K U`, with `K` in symmetric block storage.
pub struct Assembled<K: Screened<N>, const N: usize> {
    /// `K_ab` of each pair `a < b` of coupled elements, in the order of the sweep.
    pairs: Vec<Face<Block<N>>>,
    /// `K_ee` of each element, its upper triangle row after row ([`Assembled::PACKED`] numbers).
    diagonal: Vec<f64>,
    sweep: Sweep<N>,
    /// Where interfaces fail: the failing interfaces of each pair ([`Carried`]).
    carried: Option<Carried<K::Screen>>,
    kinematics: PhantomData<K>,
}

impl<K: Screened<N>, const N: usize> Assembled<K, N> {
    /// The numbers of a symmetric `N × N` block's upper triangle.
    const PACKED: usize = N * (N + 1) / 2;

    /// Where entry `(p, q)`, `p ≤ q`, of a block's upper triangle is kept.
    #[inline(always)]
    const fn packed(p: usize, q: usize) -> usize {
        p * N - p * (p + 1) / 2 + q
    }

    /// Assembles `K` ([`assemble`]) and keeps its diagonal and upper blocks.
    pub fn new(model: &Model) -> Self {
        let k = assemble::<K, N>(model);
        let n = k.n_rows();
        let mut diagonal = vec![0.0; n * Self::PACKED];
        let mut pairs = Vec::with_capacity(k.blocks.len().saturating_sub(n) / 2);
        for (a, row) in k.row_start.windows(2).enumerate() {
            for j in row[0] as usize..row[1] as usize {
                let (b, block) = (k.cols[j], k.blocks[j]);
                match (b as usize).cmp(&a) {
                    std::cmp::Ordering::Equal => {
                        let packed = &mut diagonal[a * Self::PACKED..][..Self::PACKED];
                        for p in 0..N {
                            for q in p..N {
                                packed[Self::packed(p, q)] = block[p][q];
                            }
                        }
                    }
                    std::cmp::Ordering::Greater => pairs.push(Face {
                        a: a as u32,
                        b,
                        record: block,
                    }),
                    std::cmp::Ordering::Less => {}
                }
            }
        }
        let sweep = Sweep::new(n, &mut pairs, false);
        let carried = model
            .any_fails()
            .then(|| Carried::new::<K, N, _>(model, &pairs));
        Assembled {
            pairs,
            diagonal,
            sweep,
            carried,
            kinematics: PhantomData,
        }
    }
}

impl<K: Screened<N>, const N: usize> Assembled<K, N> {
    /// The sweep over its pairs.
    pub(super) fn sweep(&self) -> &Sweep<N> {
        &self.sweep
    }

    /// Its couplings with the failing interfaces `failure` they carry ([`WithFailure::new`],
    /// whose panics it shares).
    pub(super) fn with_failure<'a>(
        &'a self,
        (plastic, state): Failure<'a>,
    ) -> WithFailure<'a, K, N> {
        WithFailure::new(self, self.carried.as_ref(), plastic, state)
    }

    /// A pair's forces, `K_ab U_b` on `a` and `K_abᵀ U_a` on `b`.
    #[inline(always)]
    pub(super) fn products(k: &Block<N>, ua: &[f64; N], ub: &[f64; N]) -> [[f64; N]; 2] {
        let mut out = [[0.0; N]; 2];
        for p in 0..N {
            let mut s = k[p][0] * ub[0];
            for q in 1..N {
                s += k[p][q] * ub[q];
            }
            out[0][p] = s;
        }
        for q in 0..N {
            let mut s = k[0][q] * ua[0];
            for p in 1..N {
                s += k[p][q] * ua[p];
            }
            out[1][q] = s;
        }
        out
    }
}

impl<K: Screened<N>, const N: usize> Couplings<N> for Assembled<K, N> {
    type Ref = Block<N>;
    /// A rigid pair is 80 bytes (`K_ab` and its two elements), more than an element-wise inline
    /// record (10⁶-element rigid grid, one thread: 15.9 and 15.7 ns per element-step with,
    /// 20.8 without; `cargo bench --bench step -- 'grid/rigid/assembled/1thr/1000000$'` on
    /// both builds, criterion's estimate).
    const PREFETCH: bool = true;
    /// Each pair has its own block.
    const RUNS: bool = false;
    const WIDE: bool = false;
    #[inline(always)]
    fn faces(&self) -> &[Face<Block<N>>] {
        &self.pairs
    }
    type Coupling<'a> = &'a Block<N>;
    #[inline(always)]
    fn coupling<'a>(&'a self, face: &'a Face<Block<N>>) -> &'a Block<N> {
        &face.record
    }
    /// `f_a += K_ab U_b`, `f_b += K_abᵀ U_a`.
    #[inline(always)]
    fn add_pair(
        &self,
        _: impl Lanes,
        k: &Block<N>,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        let [on_a, on_b] = Self::products(k, ua, ub);
        for p in 0..N {
            fa[p] += on_a[p];
            fb[p] += on_b[p];
        }
    }
    /// `K` holds the ground springs in its diagonal blocks: no pair is to the ground.
    fn add_ground(&self, _: &Face<Block<N>>, _: &[f64; N], _: &mut [f64; N]) {
        unreachable!("an assembled pair to the ground");
    }
    /// `f_e += K_ee U_e`.
    #[inline(always)]
    fn add_own(&self, e: usize, ue: &[f64; N], f: &mut [f64; N]) {
        let k = &self.diagonal[e * Self::PACKED..][..Self::PACKED];
        let at = |p: usize, q: usize| k[Self::packed(p.min(q), p.max(q))];
        for p in 0..N {
            let mut s = at(p, 0) * ue[0];
            for q in 1..N {
                s += at(p, q) * ue[q];
            }
            f[p] += s;
        }
    }
}

impl<K: Screened<N>, const N: usize> Evaluator for Assembled<K, N> {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::Assembled
    }

    fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.pairs[..])
            + std::mem::size_of_val(&self.diagonal[..])
            + self.sweep.bytes()
    }

    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        self.sweep.evaluate(self, u, f);
    }

    fn internal_force_failing(&self, u: &[f64], f: &mut [f64], (plastic, state): Failure<'_>) {
        self.sweep
            .evaluate(&self.with_failure((plastic, state)), u, f);
    }

    fn fused(&self) -> Option<&dyn FusedStep> {
        Some(self)
    }
}

impl<K: Screened<N>, const N: usize> FusedStep for Assembled<K, N> {
    fn advance(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        force: &mut [f64],
        loaded: Option<&[u32]>,
        update: &Update,
    ) -> f64 {
        self.sweep.advance(self, u, v, force, loaded, update)
    }

    fn advance_failing(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        force: &mut [f64],
        loaded: Option<&[u32]>,
        update: &Update,
        (plastic, state): Failure<'_>,
    ) -> f64 {
        let pairs = self.with_failure((plastic, state));
        self.sweep.advance(&pairs, u, v, force, loaded, update)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::scene::Scene;
    use crate::model::formulation::{Hybrid, Rigid};

    /// The diagonal and upper blocks, swept in three blocks of elements, give `K U` of the whole
    /// compressed rows to round-off, rigid and hybrid, and leave the rings zero; they hold half
    /// of the pair blocks; and the AVX2 sweep gives the plain bits.
    #[test]
    fn the_upper_blocks_give_k_u() {
        fn check<K: Screened<N>, const N: usize>(model: &Model) {
            let (k, ev) = (assemble::<K, N>(model), Assembled::<K, N>::new(model));
            let n = model.elements.len();
            assert!(ev.sweep.blocks.len() >= 3 && !ev.sweep.crossing.is_empty());
            assert_eq!(2 * ev.pairs.len() + n, k.blocks.len());
            let u: Vec<f64> = (0..n * N)
                .map(|i| ((i * 7919) % 1000) as f64 * 1e-6 - 5e-4)
                .collect();
            let mut full = vec![0.0; u.len()];
            for (r, (row, out)) in k.row_start.windows(2).zip(full.chunks_mut(N)).enumerate() {
                assert!(k.cols[row[0] as usize..row[1] as usize].contains(&(r as u32)));
                for j in row[0] as usize..row[1] as usize {
                    let c = k.cols[j] as usize;
                    for p in 0..N {
                        for q in 0..N {
                            out[p] += k.blocks[j][p][q] * u[c * N + q];
                        }
                    }
                }
            }
            let mut f = vec![0.0; u.len()];
            ev.internal_force(&u, &mut f);
            let scale = full.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let diff = f
                .iter()
                .zip(&full)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(diff <= 1e-12 * scale, "|Δf| = {diff:e} of {scale:e}");
            let scratch = ev.sweep.scratch.lock().unwrap();
            assert!(
                scratch
                    .rings
                    .iter()
                    .flat_map(|r| &r.forces)
                    .all(|s| *s == [0.0; N]),
                "a ring was left with a pending force"
            );
            drop(scratch);
            let plain = ev.sweep.evaluate_plain(&ev, &u);
            assert!(
                f.iter()
                    .zip(&plain)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "the two builds differ"
            );
        }
        for formulation in [
            r#"{"kind": "rigid"}"#,
            r#"{"kind": "hybrid", "penalty": 10}"#,
        ] {
            let json = format!(
                r#"{{"name": "v", "thickness": 0.2, "formulation": {formulation},
                "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
                "bodies": [{{"name": "b", "material": "m",
                    "mesh": {{"kind": "grid", "origin": [0.3, -7], "size": [4, 1], "cells": [120, 100]}},
                    "supports": [{{"edge": "left", "kind": "ground-spring"}}]}}],
                "time": {{"dt": 1e-9, "steps": 1}}}}"#
            );
            let model = Model::build(&Scene::from_json(&json).unwrap()).unwrap();
            match model.formulation {
                crate::model::formulation::Formulation::Rigid => check::<Rigid, 3>(&model),
                _ => check::<Hybrid, 6>(&model),
            }
        }
    }
}

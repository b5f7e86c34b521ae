//! The Poisson correction's forces (formulation `rigid-poisson`, [`crate::model::poisson`]) in
//! the two evaluators' manners, on top of the rigid springs' evaluator:
//!
//! - **element-wise** ([`FacetPressures`]): each element sums the first moment of its facets'
//!   spring tractions (from its own and its neighbours' `U`, through each facet's coefficients
//!   integrated in closed form once) into its `q_I`; then each element takes the correction's
//!   forces of its facets from its own and its neighbours' `q`. Two passes over the elements,
//!   records kept per element, no global matrix.
//! - **assembled** ([`PressureOperator`]): the same two maps as sparse matrices, `q = Λ G U`
//!   (cells × DOFs) and `f += t Gᵀ q` (DOFs × cells); `t Gᵀ Λ G` is the correction's part of `K`
//!   ([`PressureOperator::triplets`]).
//!
//! Both keep the cells' `q` in a buffer of their own (locked for an evaluation, no allocation),
//! and go over the elements in fixed chunks, so the result does not depend on the thread count.
//! Neither offers a fused step: a cell's `q` needs its neighbours' displacements, and an
//! element's force its neighbours' `q`.

use crate::force::evaluator::{Evaluator, FusedStep};
use crate::input::scene::EvaluatorKind;
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Kinematics, Rigid};
use crate::model::poisson::{load_moment, springs, Poisson};
use crate::model::{Model, GROUND};
use crate::parallel::{for_each_chunk, for_each_chunk_pair, CHUNK};
use std::sync::Mutex;

/// The correction's forces, `f += K_P U`.
pub trait Correction: Send + Sync {
    /// `f += K_P u`, with `q` (one per element) as the buffer of the cells' `q_I`.
    fn add(&self, u: &[f64], f: &mut [f64], q: &mut [f64]);
    /// Bytes it reads in an evaluation.
    fn bytes(&self) -> usize;
}

/// The rigid springs' evaluator with the Poisson correction added.
pub struct WithPoisson<C: Correction> {
    springs: Box<dyn Evaluator>,
    correction: C,
    q: Mutex<Vec<f64>>,
}

impl<C: Correction> WithPoisson<C> {
    /// `springs` (a rigid evaluator of the model) with `correction`.
    pub fn new(model: &Model, springs: Box<dyn Evaluator>, correction: C) -> Self {
        WithPoisson {
            springs,
            correction,
            q: Mutex::new(vec![0.0; model.elements.len()]),
        }
    }
}

impl<C: Correction> Evaluator for WithPoisson<C> {
    fn kind(&self) -> EvaluatorKind {
        self.springs.kind()
    }
    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        self.springs.internal_force(u, f);
        // A poisoned lock only means another evaluation panicked; the buffer is scratch.
        let mut q = self.q.lock().unwrap_or_else(|e| e.into_inner());
        self.correction.add(u, f, &mut q);
    }
    fn bytes(&self) -> usize {
        self.springs.bytes() + self.correction.bytes()
    }
    fn fused(&self) -> Option<&dyn FusedStep> {
        None
    }
}

/// The element-wise correction, element by element. Element `I`'s facets to other elements are
/// `start[I] .. start[I + 1]` in `other` (the element `J` across), `reads` (the coefficients of
/// `U_J` in `s_I`: `∫ S (x − x_I) ds` on `(u, v)`, `∫ (x − x_I)·S (ẑ × (x − x_J)) ds` on `θ`)
/// and `read_by` (those of `U_I` in `s_J`), kept apart so that each pass reads only its own;
/// `own` holds the coefficients of `U_I` in `s_I`, ground springs included.
pub struct FacetPressures {
    other: Vec<u32>,
    reads: Vec<[f64; 3]>,
    read_by: Vec<[f64; 3]>,
    start: Vec<u32>,
    own: Vec<[f64; 3]>,
    scale: Vec<f64>,
    thickness: f64,
}

/// `(∫ S (x − x_i) ds, ∫ (x − x_i)·S (ẑ × (x − x_j)) ds)` over an interface (two Gauss points,
/// exact): the coefficients of `(u_j, v_j, θ_j)` in `∫ (x − x_i)·S u_j(x) ds`.
fn reading(model: &Model, i: &crate::model::Interface, xi: Vec2, xj: Vec2) -> [f64; 3] {
    let s = springs(model, i);
    let (points, w) = i.gauss_points();
    let mut c = [0.0; 3];
    for x in points {
        let t = s.apply(x - xi) * w;
        let turn = x - xj;
        c[0] += t.x;
        c[1] += t.y;
        c[2] += t.dot(&Vec2::new(-turn.y, turn.x));
    }
    c
}

impl FacetPressures {
    /// The facets and own coefficients of a `rigid-poisson` model.
    pub fn new(model: &Model) -> Self {
        let poisson = Poisson::new(model);
        let n = model.elements.len();
        let centroid = |e: u32| model.elements[e as usize].props.centroid;
        let mut own = vec![[0.0; 3]; n];
        let (mut other, mut reads, mut read_by) = (Vec::new(), Vec::new(), Vec::new());
        let mut start = vec![0u32; n + 1];
        for e in 0..n {
            let me = e as u32;
            for &k in poisson.facets_of(e) {
                let i = &model.interfaces[k as usize];
                let across = if i.a == me { i.b } else { i.a };
                // `δ = u_b − u_a` and the traction on `I` is `±S δ`: in `s_I` the other's
                // displacement enters with `+`, its own with `−`.
                let self_read = reading(model, i, centroid(me), centroid(me));
                own[e].iter_mut().zip(self_read).for_each(|(o, c)| *o -= c);
                if across != GROUND {
                    other.push(across);
                    reads.push(reading(model, i, centroid(me), centroid(across)));
                    read_by.push(reading(model, i, centroid(across), centroid(me)));
                }
            }
            start[e + 1] = other.len() as u32;
        }
        FacetPressures {
            other,
            reads,
            read_by,
            start,
            own,
            scale: poisson.scale,
            thickness: model.thickness,
        }
    }

    fn sides(&self, e: usize) -> std::ops::Range<usize> {
        self.start[e] as usize..self.start[e + 1] as usize
    }

    /// `s_e`: the first moment `∫ (x − x_e)·S δ ds` of the spring tractions on element `e`'s
    /// facets (per unit thickness), from its own and its neighbours' DOFs.
    #[inline]
    fn moment(&self, e: usize, u: &[f64]) -> f64 {
        let dot =
            |c: &[f64; 3], k: usize| c[0] * u[3 * k] + c[1] * u[3 * k + 1] + c[2] * u[3 * k + 2];
        let r = self.sides(e);
        self.other[r.clone()]
            .iter()
            .zip(&self.reads[r])
            .fold(dot(&self.own[e], e), |s, (&j, c)| s + dot(c, j as usize))
    }

    /// The correction's diagonal blocks `K^P_ee` (row-major, nine per element), and the most
    /// elements a cell's `q` reads (`K_P`'s terms couple that many): what the stability limit's
    /// bracket needs ([`crate::analysis::limit::Limit`]). `K^P_ee = t Σ_c Λ_c g_ce g_ceᵀ` over
    /// the cells `c` whose `s` reads element `e`: itself (`own`) and its neighbours (`read_by`).
    pub fn diagonal_blocks(&self) -> (Vec<f64>, usize) {
        let n = self.own.len();
        let mut blocks = vec![0.0; 9 * n];
        for (e, block) in blocks.chunks_exact_mut(9).enumerate() {
            let r = self.sides(e);
            let cells = std::iter::once((e, &self.own[e])).chain(
                self.other[r.clone()]
                    .iter()
                    .map(|&j| j as usize)
                    .zip(&self.read_by[r]),
            );
            for (c, g) in cells {
                let w = self.thickness * self.scale[c];
                for (k, b) in block.iter_mut().enumerate() {
                    *b += w * g[k / 3] * g[k % 3];
                }
            }
        }
        let most = (0..n).map(|e| 1 + self.sides(e).len()).max().unwrap_or(0);
        (blocks, most)
    }

    /// The cells' `q_e = Λ_e s_e` at `u`, from the springs alone (the loads' share is in `P`).
    pub fn cells(&self, u: &[f64], q: &mut [f64]) {
        for_each_chunk(q, |first, chunk| {
            for (k, q) in chunk.iter_mut().enumerate() {
                let e = first + k;
                *q = self.scale[e] * self.moment(e, u);
            }
        });
    }
}

/// The cells' `q_e = λ' tr ε_e / 2μ` of a `rigid-poisson` model at `u` under its loads at
/// their full value: what the correction's tractions on its facets are made of
/// ([`crate::model::poisson::correction`]; the static analysis reports them).
pub fn cells(model: &Model, u: &[f64]) -> Vec<f64> {
    let facets = FacetPressures::new(model);
    let mut q = vec![0.0; model.elements.len()];
    facets.cells(u, &mut q);
    for l in &model.loads {
        let e = l.element as usize;
        q[e] += facets.scale[e] * load_moment(model, e, l.point, l.force);
    }
    q
}

impl Correction for FacetPressures {
    fn add(&self, u: &[f64], f: &mut [f64], q: &mut [f64]) {
        self.cells(u, q);
        let q = &*q;
        // `f_I += t (q_I ∂s_I/∂U_I + Σ_J q_J ∂s_J/∂U_I)`: the energy's gradient.
        for_each_chunk_pair(f, &mut [], 3 * CHUNK, |first, chunk, _| {
            for (k, fe) in chunk.chunks_exact_mut(3).enumerate() {
                let e = first / 3 + k;
                let mut g = self.own[e].map(|c| c * q[e]);
                let r = self.sides(e);
                for (&j, c) in self.other[r.clone()].iter().zip(&self.read_by[r]) {
                    let qj = q[j as usize];
                    g.iter_mut().zip(c).for_each(|(g, c)| *g += qj * c);
                }
                fe.iter_mut()
                    .zip(g)
                    .for_each(|(f, g)| *f += self.thickness * g);
            }
        });
    }
    fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.other[..])
            + std::mem::size_of_val(&self.reads[..])
            + std::mem::size_of_val(&self.read_by[..])
            + std::mem::size_of_val(&self.start[..])
            + std::mem::size_of_val(&self.own[..])
            + std::mem::size_of_val(&self.scale[..])
    }
}

/// A sparse matrix in compressed rows.
#[derive(Debug, Clone, Default)]
struct Rows {
    start: Vec<u32>,
    col: Vec<u32>,
    val: Vec<f64>,
}

impl Rows {
    /// From `(row, col, value)` triplets over `n` rows, duplicates summed.
    fn new(n: usize, mut t: Vec<(usize, usize, f64)>) -> Rows {
        t.sort_unstable_by_key(|&(r, c, _)| (r, c));
        let mut rows = Rows {
            start: vec![0; n + 1],
            ..Rows::default()
        };
        let mut last = None;
        for (r, c, v) in t {
            if last == Some((r, c)) {
                *rows.val.last_mut().expect("a previous entry") += v;
            } else {
                rows.col.push(c as u32);
                rows.val.push(v);
                last = Some((r, c));
            }
            rows.start[r + 1] = rows.col.len() as u32;
        }
        for r in 0..n {
            rows.start[r + 1] = rows.start[r + 1].max(rows.start[r]);
        }
        rows
    }
    fn range(&self, r: usize) -> std::ops::Range<usize> {
        self.start[r] as usize..self.start[r + 1] as usize
    }
    #[inline]
    fn dot(&self, r: usize, x: &[f64]) -> f64 {
        let r = self.range(r);
        self.col[r.clone()]
            .iter()
            .zip(&self.val[r])
            .map(|(&c, v)| v * x[c as usize])
            .sum()
    }
    fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.start[..])
            + std::mem::size_of_val(&self.col[..])
            + std::mem::size_of_val(&self.val[..])
    }
    /// The transpose, with `n` rows, each row scaled by `scale[r]` first.
    fn transpose(&self, n: usize, scale: &[f64]) -> Rows {
        let t = (0..self.start.len() - 1)
            .flat_map(|r| self.range(r).map(move |j| (r, j)))
            .map(|(r, j)| (self.col[j] as usize, r, scale[r] * self.val[j]))
            .collect();
        Rows::new(n, t)
    }
}

/// The assembled correction: `q = Λ G U`, `f += t Gᵀ q`.
pub struct PressureOperator {
    /// `G`: per cell, the first moment `s` of its tractions from the DOFs.
    g: Rows,
    /// `t Gᵀ`: per DOF, its internal force from the cells' `q`.
    gt: Rows,
    /// `Λ` per cell.
    scale: Vec<f64>,
}

impl PressureOperator {
    /// `G`, `t Gᵀ` and `Λ` of a `rigid-poisson` model.
    pub fn new(model: &Model) -> Self {
        let poisson = Poisson::new(model);
        let centroid = |e: u32| model.elements[e as usize].props.centroid;
        let mut g = Vec::new();
        for i in &model.interfaces {
            let s = springs(model, i);
            let (x, w) = i.gauss_points();
            // The first moment of the traction on side `e`, `±w (x − x_e)ᵀ S (u_b(x) − u_a(x))`.
            for (e, sign) in [(i.a, 1.0), (i.b, -1.0)] {
                if e == GROUND {
                    continue;
                }
                for &xg in &x {
                    let r = s.apply(xg - centroid(e)) * (sign * w);
                    for (side, dir) in [(i.a, -1.0), (i.b, 1.0)] {
                        if side == GROUND {
                            continue;
                        }
                        let shape = Rigid::shape(xg - centroid(side));
                        for d in 0..3 {
                            let v = dir * (r.x * shape[(0, d)] + r.y * shape[(1, d)]);
                            g.push((e as usize, 3 * side as usize + d, v));
                        }
                    }
                }
            }
        }
        let n = model.elements.len();
        let g = Rows::new(n, g);
        let gt = g.transpose(3 * n, &vec![model.thickness; n]);
        PressureOperator {
            g,
            gt,
            scale: poisson.scale,
        }
    }

    /// The correction's part of `K`, `t Gᵀ Λ G`, as triplets over all DOFs, duplicates summed.
    pub fn triplets(&self) -> Vec<(usize, usize, f64)> {
        let n = self.gt.start.len() - 1;
        let mut products = Vec::new();
        for r in 0..n {
            for j in self.gt.range(r) {
                let cell = self.gt.col[j] as usize;
                let tv = self.scale[cell] * self.gt.val[j];
                products.extend(
                    self.g
                        .range(cell)
                        .map(|k| (r, self.g.col[k] as usize, tv * self.g.val[k])),
                );
            }
        }
        let k = Rows::new(n, products);
        (0..n)
            .flat_map(|r| k.range(r).map(move |j| (r, j)))
            .map(|(r, j)| (r, k.col[j] as usize, k.val[j]))
            .collect()
    }
}

impl Correction for PressureOperator {
    fn add(&self, u: &[f64], f: &mut [f64], q: &mut [f64]) {
        for_each_chunk(q, |first, chunk| {
            for (k, q) in chunk.iter_mut().enumerate() {
                *q = self.scale[first + k] * self.g.dot(first + k, u);
            }
        });
        let q = &*q;
        for_each_chunk_pair(f, &mut [], 3 * CHUNK, |first, chunk, _| {
            for (k, fd) in chunk.iter_mut().enumerate() {
                *fd += self.gt.dot(first + k, q);
            }
        });
    }
    fn bytes(&self) -> usize {
        self.g.bytes() + self.gt.bytes() + std::mem::size_of_val(&self.scale[..])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::scene::Scene;

    fn voronoi(nu: f64) -> Model {
        Model::build(
            &Scene::from_json(&format!(
                r#"{{"name": "p", "thickness": 0.5, "plane": "stress", "formulation": {{"kind": "rigid-poisson"}},
                "materials": {{"m": {{"E": 1e10, "nu": {nu}, "rho": 2000}}}},
                "bodies": [{{"name": "b", "material": "m",
                    "mesh": {{"kind": "voronoi", "origin": [0, 0], "size": [1, 1], "sites": 300, "seed": 3, "lloyd": 30}}}}],
                "time": {{"dt": 1e-6, "steps": 1}}}}"#
            ))
            .unwrap(),
        )
        .unwrap()
    }

    /// Under a uniform strain (each cell at the affine field), an interior cell's
    /// `q = λ' tr ε / 2μ` to the lattice's uniformity.
    #[test]
    fn interior_pressures_under_a_uniform_strain() {
        let m = voronoi(0.25);
        let lambda = m.elements[0].d[(0, 1)];
        // Interior: no edge without springs (`B = 0`).
        let poisson = Poisson::new(&m);
        let interior: Vec<bool> = (0..m.elements.len())
            .map(|e| {
                let el = &m.elements[e];
                let two_mu = el.d[(0, 0)] - lambda;
                (poisson.scale[e] * two_mu * two_mu * el.props.area / lambda - 1.0).abs() < 1e-9
            })
            .collect();
        for (ex, ey, g) in [
            (1e-3, 0.0, 0.0),
            (0.0, 1e-3, 0.0),
            (0.0, 0.0, 1e-3),
            (1e-3, -4e-4, 6e-4),
        ] {
            let u: Vec<f64> = m
                .elements
                .iter()
                .flat_map(|el| {
                    let c = el.props.centroid;
                    [ex * c.x + 0.5 * g * c.y, ey * c.y + 0.5 * g * c.x, 0.0]
                })
                .collect();
            let p = cells(&m, &u);
            // `q = λ' tr ε / 2μ`.
            let exact = lambda * (ex + ey) / (m.elements[0].d[(0, 0)] - lambda);
            let worst = (0..m.elements.len())
                .filter(|&e| interior[e])
                .map(|e| (p[e] - exact).abs())
                .fold(0.0, f64::max);
            assert!(
                worst
                    <= 0.03
                        * exact
                            .abs()
                            .max(lambda * 1e-3 / (m.elements[0].d[(0, 0)] - lambda)),
                "ε = ({ex}, {ey}, {g}): worst interior |p − λ' tr ε| = {worst:e}"
            );
        }
    }

    /// The two evaluators' corrections, and `K`'s triplets, give the same force on any `U`; `K`
    /// is symmetric.
    #[test]
    fn the_evaluators_agree_on_any_displacement() {
        use crate::force::evaluator::{build, stiffness_triplets};
        use crate::input::scene::EvaluatorKind;
        let m = voronoi(0.3);
        let n = m.n_dofs();
        let u: Vec<f64> = (0..n)
            .map(|k| 1e-4 * ((k as f64 * 0.7).sin() + 0.3 * (k as f64 * 1.9).cos()))
            .collect();
        let force = |kind| {
            let mut f = vec![0.0; n];
            build(&m, kind).internal_force(&u, &mut f);
            f
        };
        let (fa, fe) = (
            force(EvaluatorKind::Assembled),
            force(EvaluatorKind::ElementWise),
        );
        let mut fk = vec![0.0; n];
        let k = stiffness_triplets(&m);
        for &(r, c, v) in &k {
            fk[r] += v * u[c];
        }
        let mut entries = std::collections::BTreeMap::new();
        for &(r, c, v) in &k {
            *entries.entry((r, c)).or_insert(0.0) += v;
        }
        let big = entries.values().fold(0.0f64, |s, v| s.max(v.abs()));
        for (&(r, c), v) in &entries {
            let vt = entries.get(&(c, r)).copied().unwrap_or(0.0);
            assert!(
                (v - vt).abs() <= 1e-12 * big,
                "K[{r}][{c}] = {v:e}, K[{c}][{r}] = {vt:e}"
            );
        }
        let scale = fa.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        for (name, g) in [("element-wise", &fe), ("triplets", &fk)] {
            let worst = fa
                .iter()
                .zip(g)
                .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
            assert!(
                worst <= 1e-12 * scale,
                "assembled against {name}: {worst:e} of {scale:e}"
            );
        }
    }

    /// The bracket's diagonal blocks, from each element's own records, are those of `K_P`'s
    /// triplets.
    #[test]
    fn the_diagonal_blocks_are_those_of_k() {
        let m = voronoi(0.3);
        let (blocks, most) = FacetPressures::new(&m).diagonal_blocks();
        let mut from_k = vec![0.0; blocks.len()];
        for (r, c, v) in PressureOperator::new(&m).triplets() {
            if r / 3 == c / 3 {
                from_k[9 * (r / 3) + 3 * (r % 3) + c % 3] += v;
            }
        }
        let big = from_k.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        let worst = blocks
            .iter()
            .zip(&from_k)
            .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
        assert!(worst <= 1e-12 * big, "{worst:e} of {big:e}");
        assert!(
            (4..=12).contains(&most),
            "a Voronoi cell reads {most} elements"
        );
    }
}

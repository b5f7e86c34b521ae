//! The element-wise evaluator (eqs. 15–16): each element's force is the resultant of the
//! tractions `λ = diag(k_n, k_s) δ` on its own edges, integrated by the edge's 2-point Gauss rule.
//! No global matrix.
//!
//! The two Gauss points of an edge sit at `m ± g` about its midpoint `m`, with
//! `g = L/(2√3) s` along the edge. The displacement jump is affine along the edge,
//! `δ(m ± g) = δ₀ ± δ₁`, so the rule's sum `Σ± N_e(m ± g)ᵀ λ(m ± g) t L/2` splits exactly into
//! `t L [N_e(m)ᵀ λ(δ₀) + (N_e(g) − N_e(0))ᵀ λ(δ₁)]`: the same quadrature in half the work.
//!
//! The traction on a shared edge is one physical quantity, `+λ` on one side and `−λ` on the
//! other. So an evaluation has two passes, both parallel and free of locks: each interface
//! computes its traction once and the generalised forces it puts on its two elements (from one
//! 64-byte record); then each element sums those of its own edges (eq. 15) and adds its interior
//! term. Every sum runs in a fixed order, so the result does not depend on the thread count.

use super::Evaluator;
use crate::formulation::Kinematics;
use crate::geometry::Vec2;
use crate::model::{Model, GROUND};
use crate::parallel::for_each_chunk;
use crate::scene::EvaluatorKind;
use std::marker::PhantomData;
use std::sync::Mutex;

/// What one interface needs at evaluation time (64 bytes).
#[derive(Debug, Clone, Copy)]
struct Face {
    a: u32,
    b: u32,
    /// Midpoint of the edge (m).
    mid: Vec2,
    normal: Vec2,
    /// `t L k_s` and `t L (k_n − k_s)` (N/m): the springs times thickness and the rule's total
    /// weight, so that `λ = k_s δ + (k_n − k_s)(n·δ) n`.
    ks_tl: f64,
    dk_tl: f64,
    /// `L/(2√3)`: distance of the Gauss points from the midpoint (m).
    half: f64,
}

/// Element-wise evaluation of eq. 15 for the kinematics `K` with `N` DOFs per element.
pub struct ElementWise<K: Kinematics<N>, const N: usize> {
    centroids: Vec<Vec2>,
    faces: Vec<Face>,
    /// `sides[side_start[e] .. side_start[e + 1]]` are the edges of element `e`, as `2k` (it is
    /// side `a` of face `k`) or `2k + 1` (side `b`): indices into the per-side forces.
    side_start: Vec<u32>,
    sides: Vec<u32>,
    /// `t A D` per element, acting on the strains `U_e[3..6]` (hybrid only; empty for rigid).
    interior: Vec<nalgebra::Matrix3<f64>>,
    /// The generalised forces of each face on its sides `a` and `b`, from the first pass.
    side_forces: Mutex<Vec<[[f64; N]; 2]>>,
    kinematics: PhantomData<K>,
}

impl<K: Kinematics<N>, const N: usize> ElementWise<K, N> {
    /// Face records and per-element side lists from the model's interfaces.
    pub fn new(model: &Model) -> Self {
        let t = model.thickness;
        let mut faces: Vec<Face> = model
            .interfaces
            .iter()
            .map(|i| {
                let (g, _) = i.gauss_points();
                let half = 0.5 * (g[1] - g[0]).norm();
                Face { a: i.a, b: i.b, mid: i.midpoint(), normal: i.normal, ks_tl: i.k_s * t * i.length, dk_tl: (i.k_n - i.k_s) * t * i.length, half }
            })
            .collect();
        // In the order of their lower element, so that both passes walk memory forwards.
        faces.sort_by_key(|f| (f.a.min(f.b), f.a.max(f.b)));
        let n = model.elements.len();
        let mut count = vec![0u32; n + 1];
        for f in &faces {
            for e in [f.a, f.b] {
                if e != GROUND {
                    count[e as usize + 1] += 1;
                }
            }
        }
        for e in 0..n {
            count[e + 1] += count[e];
        }
        let side_start = count.clone();
        let mut sides = vec![0u32; side_start[n] as usize];
        let mut next = count;
        for (k, f) in faces.iter().enumerate() {
            for (side, e) in [f.a, f.b].into_iter().enumerate() {
                if e != GROUND {
                    sides[next[e as usize] as usize] = (2 * k + side) as u32;
                    next[e as usize] += 1;
                }
            }
        }
        let centroids = model.elements.iter().map(|e| e.props.centroid).collect();
        let interior = if K::HAS_INTERIOR {
            model.elements.iter().map(|e| e.d * (model.thickness * e.props.area)).collect()
        } else {
            Vec::new()
        };
        let side_forces = Mutex::new(vec![[[0.0; N]; 2]; faces.len()]);
        ElementWise { centroids, faces, side_start, sides, interior, side_forces, kinematics: PhantomData }
    }

    /// The generalised forces that face `f` puts on its sides `a` and `b`:
    /// `± t L [N(m)ᵀ λ(δ₀) + (N(g) − N(0))ᵀ λ(δ₁)]` with `δ = u_b − u_a` (module doc).
    #[inline]
    fn face_forces(&self, f: &Face, u: &[[f64; N]]) -> [[f64; N]; 2] {
        let n = f.normal;
        let g = f.half * Vec2::new(n.y, -n.x);
        let (ua, da) = (&u[f.a as usize], f.mid - self.centroids[f.a as usize]);
        let mut delta = -K::displacement(ua, da);
        let mut out = [[0.0; N]; 2];
        if f.b == GROUND {
            K::add_force(&mut out[0], da, f.ks_tl * delta + (f.dk_tl * n.dot(&delta)) * n);
            K::add_edge_odd(&mut out[0], ua, None, g, n, f.ks_tl, f.dk_tl);
            return out;
        }
        let (ub, db) = (&u[f.b as usize], f.mid - self.centroids[f.b as usize]);
        delta += K::displacement(ub, db);
        let traction = f.ks_tl * delta + (f.dk_tl * n.dot(&delta)) * n;
        K::add_force(&mut out[0], da, traction);
        K::add_edge_odd(&mut out[0], ua, Some(ub), g, n, f.ks_tl, f.dk_tl);
        K::add_force(&mut out[1], db, -traction);
        K::add_edge_odd(&mut out[1], ub, Some(ua), g, n, f.ks_tl, f.dk_tl);
        out
    }
}

impl<K: Kinematics<N>, const N: usize> Evaluator for ElementWise<K, N> {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::ElementWise
    }

    fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        let side_forces = self.faces.len() * std::mem::size_of::<[[f64; N]; 2]>();
        size_of_val(&self.centroids[..]) + size_of_val(&self.faces[..]) + size_of_val(&self.side_start[..])
            + size_of_val(&self.sides[..]) + size_of_val(&self.interior[..]) + side_forces
    }

    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        let (u, _) = u.as_chunks::<N>();
        let (f, _) = f.as_chunks_mut::<N>();
        let mut side_forces = self.side_forces.lock().unwrap_or_else(|e| e.into_inner());
        // Pass 1: the traction of each interface, once, and its forces on both sides.
        for_each_chunk(&mut side_forces, |first, chunk| {
            for (k, out) in chunk.iter_mut().enumerate() {
                *out = self.face_forces(&self.faces[first + k], u);
            }
        });
        let side_forces = &*side_forces;
        // Pass 2 (eq. 15): each element sums the forces of its own edges; f_int is minus the
        // springs' force, plus the interior term `t A D ε` (eq. 8) for hybrid elements.
        for_each_chunk(f, |first, block| {
            for (i, fe) in block.iter_mut().enumerate() {
                let e = first + i;
                let mut acc = [0.0; N];
                for &h in &self.sides[self.side_start[e] as usize..self.side_start[e + 1] as usize] {
                    let s = &side_forces[(h / 2) as usize][(h % 2) as usize];
                    for j in 0..N {
                        acc[j] -= s[j];
                    }
                }
                if K::HAS_INTERIOR {
                    let ue = &u[e];
                    let stress = self.interior[e] * nalgebra::Vector3::new(ue[3], ue[4], ue[5]);
                    for j in 0..3 {
                        acc[3 + j] += stress[j];
                    }
                }
                *fe = acc;
            }
        });
    }
}

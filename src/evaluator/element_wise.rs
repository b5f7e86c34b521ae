//! The element-wise evaluator (eqs. 15–16): each element's force is the resultant of the
//! tractions `λ = diag(k_n, k_s) δ` on its own edges, integrated by the edge's 2-point Gauss rule.
//! No global matrix; each element writes only its own force, so the loop runs in parallel
//! without locks and gives the same bits on any number of threads.
//!
//! The two Gauss points of an edge sit at `m ± e` about its midpoint `m`, with
//! `e = L/(2√3) s` along the edge. The displacement jump is affine along the edge,
//! `δ(m ± e) = δ₀ ± δ₁`, so the rule's sum `Σ± N_e(m ± e)ᵀ λ(m ± e) t L/2` splits exactly into
//! `t L [N_e(m)ᵀ λ(δ₀) + (N_e(e) − N_e(0))ᵀ λ(δ₁)]`: the same quadrature in half the work,
//! from one 64-byte record per interface shared by its two elements.

use super::Evaluator;
use crate::formulation::Kinematics;
use crate::geometry::Vec2;
use crate::model::{Model, GROUND};
use crate::parallel::for_each_chunk;
use crate::scene::EvaluatorKind;
use std::marker::PhantomData;

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
    /// `faces_of[face_start[e] .. face_start[e + 1]]` are the faces of element `e`.
    face_start: Vec<u32>,
    faces_of: Vec<u32>,
    /// `t A D` per element, acting on the strains `U_e[3..6]` (hybrid only; empty for rigid).
    interior: Vec<nalgebra::Matrix3<f64>>,
    kinematics: PhantomData<K>,
}

impl<K: Kinematics<N>, const N: usize> ElementWise<K, N> {
    /// Per-element face lists from the model's interfaces.
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
        // In the order of their lower element, so that the loop over elements walks them forwards.
        faces.sort_by_key(|f| (f.a.min(f.b), f.a.max(f.b)));
        let n = model.elements.len();
        let mut count = vec![0u32; n + 1];
        for f in &faces {
            count[f.a as usize + 1] += 1;
            if f.b != GROUND {
                count[f.b as usize + 1] += 1;
            }
        }
        for e in 0..n {
            count[e + 1] += count[e];
        }
        let face_start = count.clone();
        let mut faces_of = vec![0u32; face_start[n] as usize];
        let mut next = count;
        for (k, f) in faces.iter().enumerate() {
            for e in [f.a, f.b] {
                if e != GROUND {
                    faces_of[next[e as usize] as usize] = k as u32;
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
        ElementWise { centroids, faces, face_start, faces_of, interior, kinematics: PhantomData }
    }

    /// The force that the springs exert on element `e`: `Σ_faces t L [N_e(m)ᵀ λ₀ + (N_e(e) −
    /// N_e(0))ᵀ λ₁]` (eq. 15 by the split 2-point rule of the module doc), and for hybrid
    /// elements the interior term `−t A D ε`.
    #[inline]
    fn element_force(&self, e: usize, u: &[[f64; N]]) -> [f64; N] {
        // Accumulated in registers, stored once.
        let mut fe = [0.0; N];
        let (xe, ue) = (self.centroids[e], &u[e]);
        for &k in &self.faces_of[self.face_start[e] as usize..self.face_start[e + 1] as usize] {
            let f = &self.faces[k as usize];
            let other = if f.a as usize == e { f.b } else { f.a };
            let n = f.normal;
            let d = f.mid - xe;
            // δ = u_other − u_e: the spring pulls `e` towards the other side, whichever side it is.
            let mut delta = -K::displacement(ue, d);
            let uo = (other != GROUND).then(|| &u[other as usize]);
            if let Some(uo) = uo {
                delta += K::displacement(uo, f.mid - self.centroids[other as usize]);
            }
            K::add_force(&mut fe, d, f.ks_tl * delta + (f.dk_tl * n.dot(&delta)) * n);
            K::add_edge_odd(&mut fe, ue, uo, f.half * Vec2::new(n.y, -n.x), n, f.ks_tl, f.dk_tl);
        }
        if K::HAS_INTERIOR {
            // The element's own strain energy ½ t A εᵀ D ε pulls back on its strains (eq. 8).
            let ue = &u[e];
            let stress = self.interior[e] * nalgebra::Vector3::new(ue[3], ue[4], ue[5]);
            for i in 0..3 {
                fe[3 + i] -= stress[i];
            }
        }
        fe
    }
}

impl<K: Kinematics<N>, const N: usize> Evaluator for ElementWise<K, N> {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::ElementWise
    }

    fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(&self.centroids[..]) + size_of_val(&self.faces[..]) + size_of_val(&self.face_start[..])
            + size_of_val(&self.faces_of[..]) + size_of_val(&self.interior[..])
    }

    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        let (u, _) = u.as_chunks::<N>();
        let (f, _) = f.as_chunks_mut::<N>();
        // Eq. 15 gives the force that the springs exert on the element; f_int is its negative.
        for_each_chunk(f, |first, block| {
            for (i, fe) in block.iter_mut().enumerate() {
                *fe = self.element_force(first + i, u).map(|x| -x);
            }
        });
    }
}

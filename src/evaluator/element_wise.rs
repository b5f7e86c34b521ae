//! The element-wise evaluator (eqs. 15–16): each element's force is the resultant of the
//! tractions `λ = diag(k_n, k_s) δ` on its own edges, integrated at the edge's two Gauss points.
//! No global matrix; each element writes only its own force, so the loop runs in parallel
//! without locks and gives the same bits on any number of threads.

use super::Evaluator;
use crate::parallel::for_each_chunk;
use crate::formulation::Kinematics;
use crate::geometry::Vec2;
use crate::model::{Model, GROUND};
use crate::scene::EvaluatorKind;
use std::marker::PhantomData;

/// What one interface needs at evaluation time.
#[derive(Debug, Clone, Copy)]
struct Face {
    a: u32,
    b: u32,
    /// Gauss points (absolute coordinates, m).
    g: [Vec2; 2],
    normal: Vec2,
    /// `t · w · k_n` and `t · w · k_s`: spring constants times thickness and Gauss weight.
    kn_tw: f64,
    ks_tw: f64,
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
        let faces: Vec<Face> = model
            .interfaces
            .iter()
            .map(|i| {
                let (g, w) = i.gauss_points();
                Face { a: i.a, b: i.b, g, normal: i.normal, kn_tw: i.k_n * t * w, ks_tw: i.k_s * t * w }
            })
            .collect();
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

    /// The force on element `e`: `Σ_faces Σ_gauss N_e(x)ᵀ (±λ) t w` (eq. 15), and for hybrid
    /// elements the interior term `−t A D ε`.
    #[inline]
    fn element_force(&self, e: usize, u: &[[f64; N]], fe: &mut [f64; N]) {
        *fe = [0.0; N];
        let xe = self.centroids[e];
        let zero = [0.0; N];
        for &k in &self.faces_of[self.face_start[e] as usize..self.face_start[e + 1] as usize] {
            let f = &self.faces[k as usize];
            let (ua, xa) = (&u[f.a as usize], self.centroids[f.a as usize]);
            let (ub, xb) = if f.b == GROUND { (&zero, Vec2::zeros()) } else { (&u[f.b as usize], self.centroids[f.b as usize]) };
            // The traction acts on `a` along +δ and on `b` along −δ (δ = u_b − u_a).
            let sign = if f.a as usize == e { 1.0 } else { -1.0 };
            let tangent = Vec2::new(f.normal.y, -f.normal.x);
            for g in f.g {
                let ga = if f.b == GROUND { Vec2::zeros() } else { K::displacement(ub, g - xb) };
                let delta = ga - K::displacement(ua, g - xa);
                let traction = f.normal * (f.kn_tw * f.normal.dot(&delta)) + tangent * (f.ks_tw * tangent.dot(&delta));
                K::add_force(fe, g - xe, sign * traction);
            }
        }
        if K::HAS_INTERIOR {
            // The element's own strain energy ½ t A εᵀ D ε pulls back on its strains (eq. 8).
            let ue = &u[e];
            let stress = self.interior[e] * nalgebra::Vector3::new(ue[3], ue[4], ue[5]);
            for i in 0..3 {
                fe[3 + i] -= stress[i];
            }
        }
    }
}

impl<K: Kinematics<N>, const N: usize> Evaluator for ElementWise<K, N> {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::ElementWise
    }

    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        let (u, _) = u.as_chunks::<N>();
        let (f, _) = f.as_chunks_mut::<N>();
        // Eq. 15 gives the force that the springs exert on the element; f_int is its negative.
        for_each_chunk(f, |first, block| {
            for (i, fe) in block.iter_mut().enumerate() {
                self.element_force(first + i, u, fe);
                for x in fe.iter_mut() {
                    *x = -*x;
                }
            }
        });
    }
}

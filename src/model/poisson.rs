//! The Poisson correction of rigid cells: the formulation `rigid-poisson` (README
//! *Formulations*, `paper_notes.md` item 30).
//!
//! Springs `k_n = k_s = 2μ/h` ([`crate::model::spring_moduli`]) make a lattice of rigid cells a
//! material of `ν = 0`: under a uniform strain `ε` a facet whose centroids face each other across
//! it carries `σ₀ n`, `σ₀ = 2μ ε` (on centroidal Voronoi cells to a few per mille, which
//! `rbsm effective` measures). The material's stress is `σ = σ₀ + λ' tr ε I`, with `λ' = λ` in
//! plane strain and `2λμ/(λ + 2μ)` in plane stress. So each cell `I` reads its `tr ε_I` from the
//! tractions on its boundary, and its facets carry what that pressure `λ' tr ε_I` adds.
//!
//! **The estimate.** Over a cell, `∮ (x − x_I)·σ n ds = A_I tr σ` for a constant `σ`. Its
//! facets' springs measure `σ₀ n`; on its edges with no springs the traction is the whole `σ n`
//! (zero on a free edge, the load on a loaded one), `λ' tr ε n` more than `σ₀ n`. So the first
//! moment of its tractions
//!
//! `s_I = Σ_facets ∫ (x − x_I)·S δ ds + Σ_loads (x − x_I)·F / t = (2μ A_I + λ' B_I) tr ε_I`,
//!
//! `B_I = Σ h L` over the cell's edges without a normal spring (`h` the distance from the
//! centroid to the edge line), is exact under a uniform strain for every cell, inside or on the
//! outline. Clamps and contact forces are not in it (a clamped cell does not move; a cell in
//! contact reads its pressure from its facets alone).
//!
//! **The correction.** With `s = G U` (one row per cell; the loads' share is in `P`) and
//! `q_I = Λ_I s_I`, `Λ_I = λ'_I / (2μ_I (2μ_I A_I + λ'_I B_I))` (so `q_I = λ' tr ε_I / 2μ`), the
//! correction is the energy `½ t Σ_I Λ_I s_I²`: `f_P = t Gᵀ q`, `K_P = t Gᵀ Λ G`, symmetric and
//! positive semi-definite. On a facet it is the traction
//!
//! `c(x) = S (q_a (x − x_a) − q_b (x − x_b))`   (`q_b = 0` on ground),
//!
//! which under a uniform strain is `S q d = λ' tr ε n` (`d = x_b − x_a = h n`, `S = 2μ/h`): the
//! lattice's `σ₀ n` plus `λ' tr ε n` is the material's `σ n` on every facet. `K_P` couples the
//! neighbours of each cell with each other (second neighbours).

use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Kinematics, Rigid, Springs};
use crate::model::{Interface, Model, GROUND};

/// What the correction needs of a model: per element its `Λ` and its interfaces.
#[derive(Debug, Clone)]
pub struct Poisson {
    /// Per element, `Λ_I = λ' / (2μ (2μ A + λ' B))` (1/(Pa·m²)): `q_I = Λ_I s_I`.
    pub scale: Vec<f64>,
    /// The interfaces of element `e` are `facets[start[e] .. start[e + 1]]`, in model order.
    pub start: Vec<u32>,
    /// Interface indices.
    pub facets: Vec<u32>,
}

/// `λ'` and `2μ` of an element's elasticity matrix `D` (isotropic, plane stress or strain:
/// `D₁₂ = λ'`, `D₁₁ − D₁₂ = 2μ`).
fn lame(d: &nalgebra::Matrix3<f64>) -> (f64, f64) {
    (d[(0, 1)], d[(0, 0)] - d[(0, 1)])
}

impl Poisson {
    /// The correction's data of a `rigid-poisson` model.
    pub fn new(model: &Model) -> Poisson {
        let n = model.elements.len();
        let mut count = vec![0u32; n + 1];
        for i in &model.interfaces {
            count[i.a as usize + 1] += 1;
            if i.b != GROUND {
                count[i.b as usize + 1] += 1;
            }
        }
        for e in 0..n {
            count[e + 1] += count[e];
        }
        let start = count.clone();
        let mut facets = vec![0u32; start[n] as usize];
        let mut next = count;
        for (k, i) in model.interfaces.iter().enumerate() {
            for e in [i.a, i.b].into_iter().filter(|&e| e != GROUND) {
                facets[next[e as usize] as usize] = k as u32;
                next[e as usize] += 1;
            }
        }
        // B_I: the cell's edges that no normal spring holds. Its whole boundary is Σ h L = 2A
        // (the centroid inside), less the facets with a normal spring.
        let scale = (0..n)
            .map(|e| {
                let el = &model.elements[e];
                let held: f64 = facets[start[e] as usize..start[e + 1] as usize]
                    .iter()
                    .map(|&k| &model.interfaces[k as usize])
                    .filter(|i| model.law_of(i).springs([i.k_n, i.k_s])[0] > 0.0)
                    .map(|i| i.length * if i.a as usize == e { i.h_a } else { i.h_b })
                    .sum();
                let b = (2.0 * el.props.area - held).max(0.0);
                let (lambda, two_mu) = lame(&el.d);
                lambda / (two_mu * (two_mu * el.props.area + lambda * b))
            })
            .collect();
        Poisson {
            scale,
            start,
            facets,
        }
    }

    /// The interfaces of element `e`.
    pub fn facets_of(&self, e: usize) -> &[u32] {
        &self.facets[self.start[e] as usize..self.start[e + 1] as usize]
    }

    /// The loads' share: for a force `force` at `point` on element `e`, the generalised forces
    /// `(dof, value)` that the correction's traction of `q_e = Λ_e (x − x_e)·F / t` puts on the
    /// element and its neighbours, to add to `P` with the load's amplitude.
    pub fn load_share(
        &self,
        model: &Model,
        e: usize,
        point: Vec2,
        force: Vec2,
    ) -> Vec<(usize, f64)> {
        let q = self.scale[e] * load_moment(model, e, point, force);
        let mut out = Vec::new();
        if q == 0.0 {
            return out;
        }
        for &k in self.facets_of(e) {
            let i = &model.interfaces[k as usize];
            let (qa, qb) = if i.a as usize == e {
                (q, 0.0)
            } else {
                (0.0, q)
            };
            let (points, w) = i.gauss_points();
            for (side, sign) in [(i.a, 1.0), (i.b, -1.0)] {
                if side == GROUND {
                    continue;
                }
                let mut f = [0.0; 3];
                let c = model.elements[side as usize].props.centroid;
                for x in points {
                    let force = correction(model, i, qa, qb, x) * (sign * w * model.thickness);
                    Rigid::add_force(&mut f, x - c, force);
                }
                out.extend(
                    f.iter()
                        .enumerate()
                        .map(|(d, &v)| (side as usize * 3 + d, v)),
                );
            }
        }
        out
    }
}

/// A force's share of the first moment `s_e` of element `e`'s boundary tractions, per unit
/// thickness: `(x − x_e)·F / t`.
pub fn load_moment(model: &Model, e: usize, point: Vec2, force: Vec2) -> f64 {
    (point - model.elements[e].props.centroid).dot(&force) / model.thickness
}

/// The springs `S` of an interface's law.
pub fn springs(model: &Model, i: &Interface) -> Springs {
    let [k_n, k_s] = model.law_of(i).springs([i.k_n, i.k_s]);
    Springs::new(i.normal, k_n, k_s)
}

/// The correction's traction (Pa) on side `a` of interface `i` at its point `x`, from its cells'
/// `q_a`, `q_b`: `S (q_a (x − x_a) − q_b (x − x_b))` (`q_b` ignored on ground).
pub fn correction(model: &Model, i: &Interface, qa: f64, qb: f64, x: Vec2) -> Vec2 {
    let arm = |e: u32| x - model.elements[e as usize].props.centroid;
    let v = if i.b == GROUND {
        qa * arm(i.a)
    } else {
        qa * arm(i.a) - qb * arm(i.b)
    };
    springs(model, i).apply(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::scene::Scene;

    fn model(mesh: &str, nu: f64, plane: &str) -> Model {
        Model::build(
            &Scene::from_json(&format!(
                r#"{{"name": "p", "thickness": 0.5, "plane": "{plane}", "formulation": {{"kind": "rigid-poisson"}},
                "materials": {{"m": {{"E": 1e10, "nu": {nu}, "rho": 2000}}}},
                "bodies": [{{"name": "b", "material": "m", "mesh": {mesh},
                    "supports": [{{"edge": "left", "kind": "ground-spring", "components": ["n"]}}]}}],
                "time": {{"dt": 1e-6, "steps": 1}}}}"#
            ))
            .unwrap(),
        )
        .unwrap()
    }

    /// Springs of `ν = 0` in both planes, `λ'` of each plane, and `B` on a grid: an interior
    /// cell has none, a corner cell the free halves of its outer edges.
    #[test]
    fn springs_and_scale_on_a_grid() {
        let grid = r#"{"kind": "grid", "origin": [0, 0], "size": [3, 3], "cells": [3, 3]}"#;
        for plane in ["stress", "strain"] {
            let m = model(grid, 0.25, plane);
            let mu2 = 1e10 / 1.25;
            for i in m.interfaces.iter().filter(|i| i.b != GROUND) {
                assert!((i.k_n * (i.h_a + i.h_b) / mu2 - 1.0).abs() < 1e-12);
                assert!((i.k_s - i.k_n).abs() <= 1e-12 * i.k_n);
            }
            let p = Poisson::new(&m);
            let (l, mu2_d) = lame(&m.elements[0].d);
            assert!((mu2_d / mu2 - 1.0).abs() < 1e-12);
            let expect = match plane {
                "stress" => 1e10 * 0.25 / (1.0 - 0.0625),
                _ => 1e10 * 0.25 / (1.25 * 0.5),
            };
            assert!(
                (l / expect - 1.0).abs() < 1e-12,
                "{plane}: λ' {l} against {expect}"
            );
            // Element 4 is the centre (no free edge); element 8 the top-right corner: two free
            // edges of length 1 at h = 0.5.
            let close = |x: f64, y: f64| (x / y - 1.0).abs() < 1e-12;
            assert!(close(p.scale[4], l / (mu2 * mu2)));
            assert!(close(p.scale[8], l / (mu2 * (mu2 + l * 1.0))));
            // Element 0, bottom-left: the left edge is a roller (a normal spring), the bottom free.
            assert!(close(p.scale[0], l / (mu2 * (mu2 + l * 0.5))));
        }
    }
}

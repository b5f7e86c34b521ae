//! Effective elastic constants of a mesh (`rbsm effective`, the README's *Commands*): the number
//! a user needs before trusting a mesh with a formulation. The body is loaded in uniform strain,
//! three cases `ε̄ = (1, 0, 0)`, `(0, 1, 0)`, `(0, 0, 1)` in `(ε_x, ε_y, γ_xy)`: the elements that
//! touch its outline follow the affine field `u = ε̄ x` (at their centroid, no rotation; a
//! hybrid element's strain is `ε̄`), the others find their equilibrium (`K_ff U_f = −K_fb U_b`, the
//! static solver's sparse Cholesky). Each element's own stress is the average of the tractions on
//! its facets, `σ_e = (1/A_e) Σ ∫ sym(t ⊗ (x − x_e)) ds` (two-point Gauss, exact for the linear
//! traction of an edge); the area-weighted mean `σ̄` over the interior elements (those of the
//! outline are rigid on the affine field and miss the free surface's tractions: a boundary
//! layer) gives the effective stiffness column by column, `σ̄ = C ε̄` in Voigt form (engineering
//! shear). An isotropic fit reads `E` and `ν` from `C₁₁`, `C₁₂` as the scene's
//! `plane` says; `C₂₂` and `C₃₃` against `C₁₁` and `(C₁₁ − C₁₂)/2` say how far the mesh is
//! from isotropic. The interior elements' stresses scatter about `σ̄`: their area-weighted RMS
//! over `|σ̄|` is reported per case. A boundary element is one with a free edge: its bonded facets
//! do not cover its perimeter.

use crate::analysis::setup::Setup;
use crate::analysis::Report;
use crate::error::{Error, Result};
use crate::force::evaluator::{stiffness_triplets, FacetPressures};
use crate::input::scene::Plane;
use crate::mesh::geometry::Vec2;
use crate::model::formulation::Formulation;
use crate::model::poisson::correction;
use crate::model::{Model, GROUND};
use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use serde::Serialize;
use std::time::Instant;

/// The effective elastic constants of a scene's mesh and formulation.
#[derive(Debug, Clone, Serialize)]
pub struct EffectiveReport {
    /// The scene's name.
    pub scene: String,
    /// Elements, and how many of them follow the affine field (the boundary).
    pub elements: usize,
    /// Elements on the outline.
    pub boundary_elements: usize,
    /// The effective stiffness `C` (Pa), Voigt `(σ_x, σ_y, τ_xy) = C (ε_x, ε_y, γ_xy)`.
    pub stiffness: [[f64; 3]; 3],
    /// `E` (Pa) of the isotropic fit to `C₁₁`, `C₁₂` in the scene's `plane`.
    pub young: f64,
    /// `ν` of that fit.
    pub poisson: f64,
    /// The material's `E` and `ν`, for comparison.
    pub material: [f64; 2],
    /// `C₂₂ / C₁₁ − 1` and `C₃₃ / ((C₁₁ − C₁₂)/2) − 1`: zero for an isotropic mesh.
    pub anisotropy: [f64; 2],
    /// Per load case, the area-weighted RMS of `|σ_e − σ̄|` over `|σ̄|` on interior elements.
    pub scatter: [f64; 3],
    /// Wall time (s).
    pub seconds: f64,
}

impl Report for EffectiveReport {
    fn text(&self) -> String {
        let c = &self.stiffness;
        format!(
            "{}: {} elements ({} on the outline follow the uniform strain)\n  C (Pa) = \
             [[{:.6e}, {:.6e}, {:.6e}], [{:.6e}, {:.6e}, {:.6e}], [{:.6e}, {:.6e}, {:.6e}]]\n  \
             isotropic fit: E = {:.6e} Pa ({:+.3} % of the material's), ν = {:.4} (material \
             {:.4})\n  anisotropy: C22/C11 − 1 = {:+.3e}, C33/((C11 − C12)/2) − 1 = {:+.3e}\n  \
             element stresses about the uniform one (RMS/|σ̄|): ε_x {:.3e}, ε_y {:.3e}, γ_xy \
             {:.3e}; {:.3} s",
            self.scene,
            self.elements,
            self.boundary_elements,
            c[0][0],
            c[0][1],
            c[0][2],
            c[1][0],
            c[1][1],
            c[1][2],
            c[2][0],
            c[2][1],
            c[2][2],
            self.young,
            100.0 * (self.young / self.material[0] - 1.0),
            self.poisson,
            self.material[1],
            self.anisotropy[0],
            self.anisotropy[1],
            self.scatter[0],
            self.scatter[1],
            self.scatter[2],
            self.seconds
        )
    }
}

/// The affine field of the unit strain case `k` at `x`: `ε̄ x` with `γ` shared by both
/// components, `(u, v)`.
fn affine(k: usize, x: Vec2) -> Vec2 {
    match k {
        0 => Vec2::new(x.x, 0.0),
        1 => Vec2::new(0.0, x.y),
        _ => Vec2::new(0.5 * x.y, 0.5 * x.x),
    }
}

/// The effective elastic constants of the setup's model (its supports and loads are ignored).
///
/// # Errors
/// A scene of more than one body (the constants are one material's on one mesh), one
/// whose elements all touch the outline (nothing to find), or a stiffness that is not positive
/// definite on the interior DOFs.
pub fn analyse(setup: &Setup) -> Result<EffectiveReport> {
    let started = Instant::now();
    let scene = &setup.scene;
    if scene.bodies.len() != 1 {
        return Err(Error::scene(
            "bodies",
            format!(
                "rbsm effective measures one body; the scene has {}",
                scene.bodies.len()
            ),
        ));
    }
    // Without its supports and loads: the `rigid-poisson` pressures would read the ground
    // springs' tractions (the other formulations' forces on the interior do not see them).
    let mut bare = setup.model.clone();
    bare.interfaces.retain(|i| i.b != GROUND);
    bare.loads.clear();
    let model = &bare;
    let nd = model.formulation.ndof();
    let n = model.n_dofs();
    // The outline: elements whose bonded facets do not cover their perimeter (a free edge).
    let mut bonded = vec![0.0; model.elements.len()];
    for i in model.interfaces.iter().filter(|i| i.b != GROUND) {
        bonded[i.a as usize] += i.length;
        bonded[i.b as usize] += i.length;
    }
    let perimeter = |e: usize| {
        let body = &model.bodies[model.elements[e].body as usize];
        let p = body.mesh.cell_points(e - body.first_element);
        (0..p.len())
            .map(|k| (p[(k + 1) % p.len()] - p[k]).norm())
            .sum::<f64>()
    };
    let boundary: Vec<bool> = (0..model.elements.len())
        .map(|e| bonded[e] < (1.0 - 1e-9) * perimeter(e))
        .collect();
    let mut index = vec![usize::MAX; n];
    let mut free = Vec::new();
    for (e, &b) in boundary.iter().enumerate() {
        if !b {
            for k in 0..nd {
                index[e * nd + k] = free.len();
                free.push(e * nd + k);
            }
        }
    }
    if free.is_empty() {
        return Err(Error::scene(
            "bodies[0].mesh",
            "every element has a free edge (it is on the outline), so none is left to find its \
             equilibrium: use a mesh at least three elements across each way",
        ));
    }
    let k = stiffness_triplets(model);
    let kff: Vec<Triplet<usize, usize, f64>> = k
        .iter()
        .filter(|&&(r, c, v)| v != 0.0 && index[r] != usize::MAX && index[c] != usize::MAX)
        .map(|&(r, c, v)| Triplet::new(index[r], index[c], v))
        .collect();
    let kff = SparseColMat::try_new_from_triplets(free.len(), free.len(), &kff)
        .map_err(|e| Error::scene("bodies[0].mesh", format!("K_ff: {e:?}")))?;
    let llt = kff.sp_cholesky(faer::Side::Lower).map_err(|_| {
        Error::scene(
            "bodies[0].mesh",
            "the stiffness of the interior elements is not positive definite: some of them are \
             not held by their interfaces (a mechanism inside the mesh)",
        )
    })?;
    let times = |u: &[f64]| {
        let mut f = vec![0.0; n];
        for &(r, c, v) in &k {
            f[r] += v * u[c];
        }
        f
    };
    // The three cases: the outline on the affine field, the interior in equilibrium.
    let cases: Vec<Vec<f64>> = (0..3)
        .map(|case| {
            let mut u = vec![0.0; n];
            for (e, el) in model.elements.iter().enumerate() {
                if boundary[e] {
                    let d = affine(case, el.props.centroid);
                    u[e * nd] = d.x;
                    u[e * nd + 1] = d.y;
                    if nd == 6 {
                        u[e * nd + 3 + case] = 1.0;
                    }
                }
            }
            let f = times(&u);
            let mut rhs = faer::Mat::<f64>::from_fn(free.len(), 1, |i, _| -f[free[i]]);
            llt.solve_in_place(rhs.as_mut());
            for (i, &d) in free.iter().enumerate() {
                u[d] = rhs[(i, 0)];
            }
            u
        })
        .collect();
    // `σ̄` of each case: the area-weighted mean of the interior elements' stresses (the outline's
    // elements, rigid on the affine field, carry no strain of their own and miss the tractions
    // of the free surface).
    let stresses: Vec<Vec<[f64; 3]>> = cases.iter().map(|u| element_stresses(model, u)).collect();
    let interior = || (0..model.elements.len()).filter(|&e| !boundary[e]);
    let area: f64 = interior().map(|e| model.elements[e].props.area).sum();
    let mut c = [[0.0; 3]; 3];
    for (case, s) in stresses.iter().enumerate() {
        for e in interior() {
            for (row, x) in s[e].iter().enumerate() {
                c[row][case] += model.elements[e].props.area * x / area;
            }
        }
    }
    let (c11, c12) = (c[0][0], 0.5 * (c[0][1] + c[1][0]));
    let (young, poisson) = match scene.plane {
        Plane::Stress => {
            let nu = c12 / c11;
            (c11 * (1.0 - nu * nu), nu)
        }
        Plane::Strain => {
            let nu = c12 / (c11 + c12);
            ((c11 - c12) * (1.0 + nu), nu)
        }
    };
    let material = scene.materials[&scene.bodies[0].material];
    let scatter = [0, 1, 2].map(|case| {
        let mean = [c[0][case], c[1][case], c[2][case]];
        let sum: f64 = interior()
            .map(|e| {
                let d = [0, 1, 2].map(|k| stresses[case][e][k] - mean[k]);
                model.elements[e].props.area * (d[0] * d[0] + d[1] * d[1] + 2.0 * d[2] * d[2])
            })
            .sum();
        let norm = mean[0] * mean[0] + mean[1] * mean[1] + 2.0 * mean[2] * mean[2];
        (sum / area / norm).sqrt()
    });
    Ok(EffectiveReport {
        scene: model.name.clone(),
        elements: model.elements.len(),
        boundary_elements: boundary.iter().filter(|&&b| b).count(),
        stiffness: c,
        young,
        poisson,
        material: [material.e, material.nu],
        anisotropy: [c[1][1] / c11 - 1.0, c[2][2] / (0.5 * (c11 - c12)) - 1.0],
        scatter,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Each element's stress `(σ_x, σ_y, τ_xy)` (Pa), the average of the tractions its bonded facets
/// carry at displacements `u`: `σ_e = (1/A_e) Σ_f Σ_g w_g sym(t_g ⊗ (x_g − x_e))`, the traction
/// `t = k_n δ_n n + k_s δ_s s` on `a` (and its opposite on `b`) at the facet's Gauss points,
/// with `rigid-poisson`'s correction added ([`crate::model::poisson::correction`]).
fn element_stresses(model: &Model, u: &[f64]) -> Vec<[f64; 3]> {
    let nd = model.formulation.ndof();
    let mut s = vec![[0.0; 3]; model.elements.len()];
    // `rigid-poisson`: the cells' `q` add the correction's traction to every facet.
    let q = match model.formulation {
        Formulation::RigidPoisson => FacetPressures::new(model).cells(u),
        _ => vec![0.0; model.elements.len()],
    };
    for i in model.interfaces.iter().filter(|i| i.b != GROUND) {
        let (points, w) = i.gauss_points();
        let [k_n, k_s] = model.law_of(i).springs([i.k_n, i.k_s]);
        for x in points {
            let disp = |e: u32| {
                let e = e as usize;
                let d = x - model.elements[e].props.centroid;
                model.formulation.displacement(&u[e * nd..(e + 1) * nd], d)
            };
            let delta = disp(i.b) - disp(i.a);
            let t = k_n * i.normal.dot(&delta) * i.normal
                + k_s * i.tangent.dot(&delta) * i.tangent
                + correction(model, i, q[i.a as usize], q[i.b as usize], x);
            for (e, sign) in [(i.a, 1.0), (i.b, -1.0)] {
                let r = x - model.elements[e as usize].props.centroid;
                let f = sign * w * t;
                let st = &mut s[e as usize];
                st[0] += f.x * r.x;
                st[1] += f.y * r.y;
                st[2] += 0.5 * (f.x * r.y + f.y * r.x);
            }
        }
    }
    for (st, el) in s.iter_mut().zip(&model.elements) {
        st.iter_mut().for_each(|x| *x /= el.props.area);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::setup::Overrides;
    use crate::input::scene::Scene;

    fn setup(mesh: &str, formulation: &str, plane: &str) -> Setup {
        let scene = Scene::from_json(&format!(
            r#"{{"name": "e", "thickness": 0.5, "plane": "{plane}", "formulation": {formulation},
            "materials": {{"m": {{"E": 2.0e10, "nu": 0.25, "rho": 2000}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {mesh}}}],
            "time": {{"dt_factor": 0.5, "steps": 1}}}}"#
        ))
        .unwrap();
        Setup::new(&scene, &Overrides::default()).unwrap()
    }

    /// The rigid square grid in closed form: eq. 12's springs carry `E/(1 − ν²)` along each
    /// axis and `E/(2(1 + ν))` in shear (plane stress), and nothing across: `C₁₂ = 0`, `ν = 0`,
    /// every element at the uniform stress.
    #[test]
    fn the_square_grid_has_the_closed_form_constants() {
        let s = setup(
            r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [12, 12]}"#,
            r#"{"kind": "rigid"}"#,
            "stress",
        );
        let r = analyse(&s).unwrap();
        let (e, nu) = (2.0e10, 0.25);
        let c = r.stiffness;
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * e;
        assert!(close(c[0][0], e / (1.0 - nu * nu)), "{c:?}");
        assert!(close(c[1][1], e / (1.0 - nu * nu)), "{c:?}");
        assert!(close(c[2][2], e / (2.0 * (1.0 + nu))), "{c:?}");
        for (a, b) in [(0, 1), (1, 0), (0, 2), (2, 0), (1, 2), (2, 1)] {
            assert!(close(c[a][b], 0.0), "C{a}{b} = {}", c[a][b]);
        }
        assert!(r.poisson.abs() < 1e-12);
        assert!(r.scatter.iter().all(|&x| x < 1e-9), "{:?}", r.scatter);
        assert_eq!(r.boundary_elements, 44);
        assert_eq!(r.elements, 144);
    }

    /// The hybrid formulation passes the patch test as `1/p`: on triangles its effective
    /// constants tend to the material's (plane strain here) with an error that falls tenfold
    /// when the penalty grows tenfold (the interface springs, `p` times eq. 12, in series with
    /// the elements).
    #[test]
    fn hybrid_triangles_tend_to_the_materials_constants_as_one_over_p() {
        let errors = [100.0, 1000.0].map(|p| {
            let s = setup(
                r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [8, 8], "cell": "tri"}"#,
                &format!(r#"{{"kind": "hybrid", "penalty": {p}}}"#),
                "strain",
            );
            let r = analyse(&s).unwrap();
            ((r.young / 2.0e10 - 1.0).abs(), (r.poisson - 0.25).abs())
        });
        assert!(errors[0].0 < 0.02 && errors[0].1 < 0.02, "{errors:?}");
        for (a, b) in [(errors[0].0, errors[1].0), (errors[0].1, errors[1].1)] {
            assert!((5.0..20.0).contains(&(a / b)), "{errors:?}");
        }
    }
}

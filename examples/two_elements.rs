//! # Two elements, assembled by hand
//!
//! **Purpose.** Build the stiffness matrix of the smallest RBSM model, two rigid squares
//! sharing one edge, with pencil-and-paper formulas, and compare it with the `K` the library
//! assembles.
//!
//! **Equations.**
//! - The rigid kinematics `N_e(x) = [[1, 0, −Δy], [0, 1, Δx]]` (eqs. 5, 10).
//! - The relative displacement on the shared edge, `δ(x) = N_b(x) U_b − N_a(x) U_a`, in normal
//!   and tangential components (eq. 6).
//! - The penalty springs `k_n = E / ((1 − ν²)(h_a + h_b))`, `k_s = E / ((1 + ν)(h_a + h_b))`
//!   (eq. 12).
//! - The interface stiffness `K = t ∫ Bᵀ diag(k_n, k_s) B dℓ` (eqs. 7, 11, 13). For rigid
//!   elements it is exactly `t L B_mᵀ k B_m + t k_n (L³/12) e eᵀ`, with `B_m` at the edge
//!   midpoint and `e` picking `θ_b − θ_a`.
//!
//! **Run.** `cargo run --release --example two_elements`
//!
//! **Key number.** The largest difference between the hand-built `K` and the library's,
//! relative to the largest entry: round-off, about 1e-16. The example also checks that the
//! three rigid-body motions of the pair strain no spring (`K U = 0`).

use nalgebra::{SMatrix, SVector};
use rbsm::input::scene::Scene;
use rbsm::model::Model;

/// Young's modulus (Pa), Poisson's ratio, thickness (m).
const E: f64 = 3.0e10;
const NU: f64 = 0.2;
const T: f64 = 0.1;

/// Two unit squares side by side: `a` = [0, 1]², `b` = [1, 2] × [0, 1], no supports.
fn scene() -> Scene {
    Scene::from_json(&format!(
        r#"{{"name": "two_elements", "plane": "stress", "thickness": {T}, "formulation": {{"kind": "rigid"}},
        "materials": {{"m": {{"E": {E}, "nu": {NU}, "rho": 2400.0}}}},
        "bodies": [{{"name": "pair", "material": "m",
            "mesh": {{"kind": "polygons", "vertices": [[0,0],[1,0],[2,0],[2,1],[1,1],[0,1]], "cells": [[0,1,4,5],[1,2,3,4]]}}}}],
        "time": {{"dt": 1e-6, "steps": 1}}}}"#
    ))
    .expect("a valid scene")
}

/// `K` (6 × 6, DOFs `u_a, v_a, θ_a, u_b, v_b, θ_b`) by the formulas above.
fn stiffness_by_hand() -> SMatrix<f64, 6, 6> {
    // The shared edge x = 1, 0 ≤ y ≤ 1: length 1, normal from a to b (1, 0), tangent (0, 1),
    // each centroid 0.5 from it.
    let (length, h_a, h_b) = (1.0, 0.5, 0.5);
    let k_n = E / ((1.0 - NU * NU) * (h_a + h_b));
    let k_s = E / ((1.0 + NU) * (h_a + h_b));
    // At the midpoint (1, 0.5): Δ = (0.5, 0) from a's centroid, (−0.5, 0) from b's.
    let n_a = SMatrix::<f64, 2, 3>::new(1.0, 0.0, -0.0, 0.0, 1.0, 0.5);
    let n_b = SMatrix::<f64, 2, 3>::new(1.0, 0.0, -0.0, 0.0, 1.0, -0.5);
    // B_m = [n s]ᵀ [−N_a, N_b]; with n = x̂ and s = ŷ the rotation [n s]ᵀ is the identity.
    let mut b_m = SMatrix::<f64, 2, 6>::zeros();
    b_m.fixed_view_mut::<2, 3>(0, 0).copy_from(&(-n_a));
    b_m.fixed_view_mut::<2, 3>(0, 3).copy_from(&n_b);
    let k = SMatrix::<f64, 2, 2>::new(k_n, 0.0, 0.0, k_s);
    let e = SVector::<f64, 6>::new(0.0, 0.0, -1.0, 0.0, 0.0, 1.0);
    T * length * b_m.transpose() * k * b_m + T * k_n * length.powi(3) / 12.0 * e * e.transpose()
}

/// What the example prints and the test checks.
struct Outcome {
    by_hand: SMatrix<f64, 6, 6>,
    library: SMatrix<f64, 6, 6>,
    /// `max |K_hand − K_lib| / max |K_lib|`.
    difference: f64,
    /// `max |K U| / (max |K| · max |U|)` over the three rigid-body motions.
    rigid_residual: f64,
}

fn compute() -> Outcome {
    let model = Model::build(&scene()).expect("the model builds");
    let mut library = SMatrix::<f64, 6, 6>::zeros();
    for (i, j, v) in rbsm::force::evaluator::stiffness_triplets(&model) {
        library[(i, j)] += v;
    }
    let by_hand = stiffness_by_hand();
    let scale = library.abs().max();
    let difference = (by_hand - library).abs().max() / scale;
    // Rigid motions of the pair about the origin: U_e = (u − θ y_e, v + θ x_e, θ).
    let centroids = [(0.5, 0.5), (1.5, 0.5)];
    let rigid = |u: f64, v: f64, th: f64| {
        SVector::<f64, 6>::from_iterator(
            centroids
                .iter()
                .flat_map(|&(x, y)| [u - th * y, v + th * x, th]),
        )
    };
    let rigid_residual = [
        rigid(1.0, 0.0, 0.0),
        rigid(0.0, 1.0, 0.0),
        rigid(0.0, 0.0, 1.0),
    ]
    .iter()
    .map(|u| (library * u).abs().max() / (scale * u.abs().max()))
    .fold(0.0, f64::max);
    Outcome {
        by_hand,
        library,
        difference,
        rigid_residual,
    }
}

fn main() {
    let o = compute();
    println!(
        "K by hand (N/m, N, N·m; DOFs u_a v_a θ_a u_b v_b θ_b):{:.6e}",
        o.by_hand
    );
    println!(
        "K from rbsm::force::evaluator::stiffness_triplets:{:.6e}",
        o.library
    );
    println!(
        "largest |K_hand - K_lib| / largest |K| = {:.3e}",
        o.difference
    );
    println!(
        "largest |K U| over the rigid motions, relative = {:.3e}",
        o.rigid_residual
    );
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_hand_built_stiffness_is_the_library_one() {
        let o = super::compute();
        assert!(o.difference < 1e-14, "difference {:e}", o.difference);
        assert!(
            o.rigid_residual < 1e-14,
            "rigid residual {:e}",
            o.rigid_residual
        );
    }
}

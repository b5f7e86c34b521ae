//! The hybrid formulation (rigid motion plus constant strain, eqs. 5 and 8): the same parity
//! guarantees as rigid, and penalty springs whose error falls like 1/p.

mod common;
use common::*;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::analysis::statics;
use rbsm::force::evaluator;
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::mesh::geometry::Vec2;
use rbsm::model::Model;
use rbsm::step::integrator::Status;

fn hybrid_json(mesh: &str, supports: &str, loads: &str, penalty: f64, nu: f64) -> String {
    format!(
        r#"{{"name": "hybrid", "thickness": 0.1, "formulation": {{"kind": "hybrid", "penalty": {penalty}}},
            "materials": {{"m": {{"E": 2.0e10, "nu": {nu}, "rho": 2400.0}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {mesh}, "supports": {supports}, "loads": {loads}}}],
            "time": {{"dt_factor": 0.9, "steps": 10}}}}"#
    )
}

fn hybrid(mesh: &str, supports: &str, penalty: f64) -> Model {
    Model::build(&Scene::from_json(&hybrid_json(mesh, supports, "[]", penalty, 0.2)).unwrap())
        .unwrap()
}

/// `K U` and the element-wise resultant (tractions plus the interior term) agree to round-off.
#[test]
fn hybrid_operators_agree_on_every_mesh_kind() {
    for (name, mesh) in [("rect", RECT), ("tri", TRI), ("voronoi", VORONOI)] {
        let model = hybrid(mesh, SUPPORTS, 100.0);
        assert_eq!(model.n_dofs(), 6 * model.elements.len());
        let u: Vec<f64> = random_vector(model.n_dofs(), 4)
            .iter()
            .enumerate()
            .map(|(i, x)| if i % 6 >= 3 { x * 1e-3 } else { *x })
            .collect();
        let (fa, fe) = forces(&model, &u);
        let rel = norm(&fa.iter().zip(&fe).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm(&fa);
        assert!(rel <= 1e-12, "{name}: {rel:e}");
    }
}

/// A rigid motion with zero strain loads nothing; a uniform strain `ε` carried by every
/// element with the displacement field `u = ε·x` loads only the interior term (`t A D ε`) and
/// no interface (the fields match on every edge).
#[test]
fn hybrid_rigid_motion_and_uniform_strain() {
    let model = hybrid(VORONOI, "[]", 1e4);
    let pivot = Vec2::new(0.3, 0.2);
    let (th, ex, ey, g) = (1e-3, 2e-4, -1e-4, 3e-4);
    let (mut rigid, mut strained) = (Vec::new(), Vec::new());
    for e in &model.elements {
        let r = e.props.centroid - pivot;
        rigid.extend([1e-3 - th * r.y, 2e-3 + th * r.x, th, 0.0, 0.0, 0.0]);
        let c = e.props.centroid;
        strained.extend([
            ex * c.x + 0.5 * g * c.y,
            ey * c.y + 0.5 * g * c.x,
            0.0,
            ex,
            ey,
            g,
        ]);
    }
    let scale = norm(
        &forces(
            &model,
            &random_vector(model.n_dofs(), 2)
                .iter()
                .map(|x| x * 1e-3)
                .collect::<Vec<_>>(),
        )
        .0,
    );
    let (fa, fe) = forces(&model, &rigid);
    assert!(norm(&fa) <= 1e-13 * scale && norm(&fe) <= 1e-13 * scale);
    let (fa, fe) = forces(&model, &strained);
    for (k, el) in model.elements.iter().enumerate() {
        let interior = el.d * nalgebra::Vector3::new(ex, ey, g) * (model.thickness * el.props.area);
        for f in [&fa, &fe] {
            // Interface forces cancel up to the round-off of springs of stiffness p × eq. 12.
            assert!(
                f[6 * k..6 * k + 3].iter().all(|x| x.abs() <= 1e-13 * scale),
                "element {k}: {:?}",
                &f[6 * k..6 * k + 6]
            );
            for i in 0..3 {
                assert!(
                    (f[6 * k + 3 + i] - interior[i]).abs() <= 1e-9 * interior.norm(),
                    "element {k}"
                );
            }
        }
    }
}

/// A free hybrid assembly has exactly three zero eigenvalues of `K` (the interior term and the
/// penalties together leave only the rigid motions).
#[test]
fn hybrid_free_assembly_has_three_zero_modes() {
    for mesh in [RECT, TRI, VORONOI] {
        let k = rbsm::force::evaluator::assemble::<rbsm::model::formulation::Hybrid, 6>(&hybrid(
            mesh, "[]", 100.0,
        ))
        .to_dense();
        let eig = k.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
        let top = eig.iter().cloned().fold(0.0, f64::max);
        assert!(eig.iter().all(|&l| l >= -1e-10 * top));
        assert_eq!(
            eig.iter().filter(|&&l| l.abs() <= 1e-11 * top).count(),
            3,
            "{:?}",
            &eig[..5]
        );
    }
}

/// Over 10⁴ steps with the consistent block mass, both evaluators stay within 1e-9 (the
/// round-off argument of tests/dynamics.rs), and the energy drift stays below 1e-4, on every
/// mesh kind.
#[test]
fn hybrid_trajectories_agree_and_keep_energy() {
    for mesh in [RECT, TRI, VORONOI] {
        let json = hybrid_json(
            mesh,
            r#"[{"edge": "left", "kind": "ground-spring"}]"#,
            r#"[{"kind": "traction", "edge": "right", "value": [0, -1e6]}]"#,
            100.0,
            0.2,
        );
        let scene = Scene::from_json(&json).unwrap();
        let run = |kind| {
            let p = Setup::new(
                &scene,
                &Overrides {
                    evaluator: Some(kind),
                    ..Default::default()
                },
            )
            .unwrap();
            let mut cd = p.integrator(p.dt);
            assert_eq!(
                cd.run(10_000, 100, |_, _| Ok(()), |_| {}).unwrap(),
                Status::Ok
            );
            (cd.u.clone(), cd.max_relative_drift())
        };
        let ((a, drift), (e, _)) = (
            run(EvaluatorKind::Assembled),
            run(EvaluatorKind::ElementWise),
        );
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = max_abs_diff(&a, &e) / scale;
        eprintln!("hybrid: trajectory difference {diff:.2e}, energy drift {drift:.2e}");
        assert!(diff <= 1e-9, "{diff:e}");
        assert!(drift <= 1e-4, "{drift:e}");
    }
}

/// The uniform-tension patch on triangles: the error against the continuum falls like `1/p`
/// (a decade per decade of `p`) until it reaches round-off.
#[test]
fn hybrid_patch_error_falls_like_one_over_p() {
    let (e, nu, sigma) = (2.0e10, 0.2, 3.0e6);
    let mut errors = Vec::new();
    for p in [1e1, 1e2, 1e3, 1e4] {
        let json = hybrid_json(
            r#"{"kind": "grid", "origin": [0, 0], "size": [1.2, 0.8], "cells": [6, 4], "cell": "tri"}"#,
            r#"[{"edge": "left", "kind": "ground-spring", "components": ["n"]}, {"edge": "bottom", "kind": "ground-spring", "components": ["n"]}]"#,
            &format!(r#"[{{"kind": "traction", "edge": "right", "value": [{sigma}, 0]}}]"#),
            p,
            nu,
        );
        let model = Model::build(&Scene::from_json(&json).unwrap()).unwrap();
        let u = statics::solve(&model).unwrap().u;
        let (ex, ey) = (sigma / e, -nu * sigma / e);
        let err = model
            .elements
            .iter()
            .enumerate()
            .map(|(k, el)| {
                let c = el.props.centroid;
                [
                    (u[6 * k] - ex * c.x).abs() / (ex * 1.2),
                    (u[6 * k + 1] - ey * c.y).abs() / (ex * 1.2),
                    (u[6 * k + 3] - ex).abs() / ex,
                    (u[6 * k + 4] - ey).abs() / ex,
                ]
                .into_iter()
                .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        errors.push(err);
    }
    eprintln!("hybrid triangle patch errors for p = 1e1..1e4: {errors:?}");
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (7.0..=13.0).contains(&ratio),
            "error ratio per decade of p: {ratio} ({errors:?})"
        );
    }
}

/// With the consistent block mass, the dense path (`L⁻¹ K L⁻ᵀ`) and the sparse one
/// (Lanczos for `ω_max`, shift-invert `Lᵀ (K − σM)⁻¹ L` for the lowest modes) agree, and the
/// shapes are `M`-orthonormal. Tolerances as in tests/analyses.rs (dense backward error).
#[test]
fn hybrid_eigen_dense_and_sparse_agree() {
    use rbsm::{analysis::eigen, analysis::free::FreeSystem, model::mass::Mass};
    let model = hybrid(TRI, r#"[{"edge": "left", "kind": "ground-spring"}]"#, 100.0);
    let mass = Mass::new(&model);
    assert!(!mass.is_diagonal());
    let sys = FreeSystem::new(&model, &mass);
    let ev = evaluator::build(&model, EvaluatorKind::ElementWise);
    let dense = eigen::modes(&sys, ev.as_ref(), &mass, 6, eigen::Method::Dense).unwrap();
    let sparse = eigen::modes(&sys, ev.as_ref(), &mass, 6, eigen::Method::Sparse).unwrap();
    assert!(
        (dense.omega_max - sparse.omega_max).abs() <= 1e-10 * dense.omega_max,
        "{} {}",
        dense.omega_max,
        sparse.omega_max
    );
    for j in 0..6 {
        let tol = sys.n() as f64 * f64::EPSILON * (dense.omega_max / dense.omega[j]).powi(2);
        let rel = (dense.omega[j] - sparse.omega[j]).abs() / dense.omega[j];
        assert!(rel <= tol, "mode {}: {rel:e} > {tol:e}", j + 1);
    }
    let m: Vec<(usize, usize, f64)> = mass.triplets();
    let m_dot = |a: &[f64], b: &[f64]| m.iter().map(|&(r, c, v)| a[r] * v * b[c]).sum::<f64>();
    for (i, j) in [(0, 0), (1, 1), (0, 1), (2, 4)] {
        let expect = if i == j { 1.0 } else { 0.0 };
        assert!(
            (m_dot(&sparse.shapes[i], &sparse.shapes[j]) - expect).abs() < 1e-8,
            "φ{i}ᵀ M φ{j}"
        );
    }
}

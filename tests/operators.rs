//! The two evaluators against each other and against closed forms (the crate
//! documentation's *Interfaces*, *Assembled form* and *Element-wise form*).

mod common;
use common::*;
use rbsm::force::evaluator::{self, assemble, interface_stiffness};
use rbsm::input::scene::EvaluatorKind;
use rbsm::mesh::geometry::Vec2;
use rbsm::model::formulation::Rigid;
use rbsm::model::law::Elastic;
use rbsm::model::{Interface, Model, GROUND};

/// `K U` and the element-wise resultant of eq. 15 agree to round-off on every mesh kind: both
/// integrate the same tractions at the same Gauss points and differ only in summation order.
#[test]
fn assembled_and_element_wise_forces_agree_to_round_off() {
    for (name, mesh) in [("rect", RECT), ("tri", TRI), ("voronoi", VORONOI)] {
        let model = model(mesh, SUPPORTS);
        for seed in 0..3 {
            let u = random_vector(model.n_dofs(), seed);
            let (fa, fe) = forces(&model, &u);
            let rel = norm(&fa.iter().zip(&fe).map(|(a, b)| a - b).collect::<Vec<_>>()) / norm(&fa);
            assert!(
                rel <= 1e-12,
                "{name}, seed {seed}: relative difference {rel:e}"
            );
        }
    }
}

/// A rigid motion of a free assembly (translation plus small rotation about any point)
/// stretches no spring: every element's `(u, v, θ)` follows from one `(u0, v0, θ0)`.
#[test]
fn rigid_motion_of_a_free_assembly_gives_zero_force() {
    for mesh in [RECT, TRI, VORONOI] {
        let model = model(mesh, "[]");
        let (u0, v0, th) = (1e-3, -2e-3, 5e-4);
        let pivot = Vec2::new(0.3, -0.7);
        let mut u = Vec::new();
        for e in &model.elements {
            let r = e.props.centroid - pivot;
            u.extend([u0 - th * r.y, v0 + th * r.x, th]);
        }
        let (fa, fe) = forces(&model, &u);
        // Compare with the force the same amplitude produces when it is not a rigid motion.
        let scale = norm(
            &forces(
                &model,
                &random_vector(u.len(), 5)
                    .iter()
                    .map(|x| x * 2e-3)
                    .collect::<Vec<_>>(),
            )
            .0,
        );
        assert!(
            norm(&fa) <= 1e-13 * scale,
            "assembled: {:e} vs {scale:e}",
            norm(&fa)
        );
        assert!(
            norm(&fe) <= 1e-13 * scale,
            "element-wise: {:e} vs {scale:e}",
            norm(&fe)
        );
    }
}

fn stiffness(model: &Model) -> faer::Mat<f64> {
    assemble::<Rigid, 3>(model).to_dense()
}

/// `K` is symmetric positive semi-definite, and a free assembly has exactly three zero
/// eigenvalues (two translations and one rotation), on every mesh kind.
#[test]
fn stiffness_is_symmetric_psd_with_three_rigid_modes_when_free() {
    for (name, mesh) in [("rect", RECT), ("tri", TRI), ("voronoi", VORONOI)] {
        let k = stiffness(&model(mesh, "[]"));
        let n = k.nrows();
        let kmax = (0..n).map(|i| k[(i, i)].abs()).fold(0.0, f64::max);
        for i in 0..n {
            for j in 0..n {
                assert!(
                    (k[(i, j)] - k[(j, i)]).abs() <= 1e-14 * kmax,
                    "{name}: K[{i},{j}] not symmetric"
                );
            }
        }
        let eig = k
            .self_adjoint_eigenvalues(faer::Side::Lower)
            .expect("eigenvalues converge");
        let top = eig.iter().cloned().fold(0.0, f64::max);
        let zero = eig.iter().filter(|&&l| l.abs() <= 1e-10 * top).count();
        assert!(
            eig.iter().all(|&l| l >= -1e-10 * top),
            "{name}: K has a negative eigenvalue"
        );
        assert_eq!(
            zero,
            3,
            "{name}: {zero} zero eigenvalues; smallest: {:?}",
            &eig[..5.min(eig.len())]
        );
    }
}

/// With supports the assembly has no zero eigenvalue left.
#[test]
fn supported_assembly_is_positive_definite() {
    let k = stiffness(&model(
        RECT,
        r#"[{"edge": "left", "kind": "ground-spring"}]"#,
    ));
    let eig = k.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
    let top = eig.iter().cloned().fold(0.0, f64::max);
    assert!(
        eig.iter().all(|&l| l > 1e-12 * top),
        "smallest {:e}, largest {top:e}",
        eig[0]
    );
}

/// For a skewed edge, 2-point Gauss gives exactly `t L B_mᵀ k B_m + t k_n (L³/12) e eᵀ`.
#[test]
fn interface_stiffness_matches_the_closed_form() {
    let (p1, p2) = (Vec2::new(0.3, -0.2), Vec2::new(0.9, 0.7));
    let length = (p2 - p1).norm();
    let dir = (p2 - p1) / length;
    let normal = Vec2::new(dir.y, -dir.x);
    let tangent = Vec2::new(normal.y, -normal.x);
    let (xa, xb) = (Vec2::new(0.2, 0.6), Vec2::new(1.1, -0.4));
    let (k_n, k_s, t) = (3.0e9, 1.7e9, 0.25);
    let iface = Interface {
        a: 0,
        b: 1,
        p1,
        p2,
        normal,
        tangent,
        length,
        h_a: 0.5,
        h_b: 0.5,
        k_n,
        k_s,
        law: rbsm::model::DEFAULT_LAW,
    };
    let [kaa, kab, kba, kbb] = interface_stiffness::<Rigid, 3>(&iface, &Elastic, xa, xb, t);
    // Closed form: B at the midpoint, 2 × 6, rows (n, s).
    let m = iface.midpoint();
    let row = |d: Vec2| {
        let (da, db) = (m - xa, m - xb);
        [
            -d.x,
            -d.y,
            -(-da.y * d.x + da.x * d.y),
            d.x,
            d.y,
            -db.y * d.x + db.x * d.y,
        ]
    };
    let bm = [row(normal), row(tangent)];
    let mut k = [[0.0; 6]; 6];
    for i in 0..6 {
        for j in 0..6 {
            k[i][j] = t * length * (k_n * bm[0][i] * bm[0][j] + k_s * bm[1][i] * bm[1][j]);
        }
    }
    let e = [0.0, 0.0, -1.0, 0.0, 0.0, 1.0];
    for i in 0..6 {
        for j in 0..6 {
            k[i][j] += t * k_n * length.powi(3) / 12.0 * e[i] * e[j];
        }
    }
    let scale = k.iter().flatten().map(|x| x.abs()).fold(0.0, f64::max);
    for i in 0..6 {
        for j in 0..6 {
            let got = match (i < 3, j < 3) {
                (true, true) => kaa[(i, j)],
                (true, false) => kab[(i, j - 3)],
                (false, true) => kba[(i - 3, j)],
                (false, false) => kbb[(i - 3, j - 3)],
            };
            assert!(
                (got - k[i][j]).abs() <= 1e-13 * scale,
                "K[{i},{j}] = {got:e}, closed form {:e}",
                k[i][j]
            );
        }
    }
    // The rotational term is the whole coupling of θ_a and θ_b beyond the midpoint rule.
    assert!(kab[(2, 2)].abs() > 0.0);
    let ground = Interface { b: GROUND, ..iface };
    let [gaa, gab, ..] = interface_stiffness::<Rigid, 3>(&ground, &Elastic, xa, xb, t);
    assert_eq!(gaa, kaa);
    assert_eq!(gab, nalgebra::SMatrix::<f64, 3, 3>::zeros());
}

/// Each element's force is summed in the same order whatever the thread count: bit-identical.
#[test]
fn forces_do_not_depend_on_the_thread_count() {
    let model = model(
        r#"{"kind": "grid", "origin": [0.0, 0.0], "size": [1.0, 1.0], "cells": [100, 50], "cell": "tri"}"#,
        SUPPORTS,
    );
    let u = random_vector(model.n_dofs(), 9);
    common::same_forces_on_one_and_two_threads(&model, &u);
}

/// Both evaluators advance each element inside their sweep (eq. 15, or the rows of `K U` of
/// eq. 7, fused with the update of `rbsm::step::integrator`). On a mesh of several blocks, with
/// loads, gravity and damping, that gives the same steps as evaluating first and updating after,
/// and as the other evaluator, up to round-off; and the same on 1 and 2 threads, bit for bit. Without gravity the fused
/// step reads the external force only at the loaded elements, and without damping it leaves
/// out the damping factors: the same holds. A damped fused step books the damping's work in
/// its sweep: the same work as the two passes book, and the energy balance closes.
#[test]
fn the_fused_step_matches_evaluation_then_update() {
    use rbsm::force::evaluator::Evaluator;
    use rbsm::model::loads::Loads;
    use rbsm::model::mass::Mass;
    use rbsm::step::integrator::CentralDifference;
    let cases = [
        r#"{"kind": "rigid"}"#,
        r#"{"kind": "hybrid", "penalty": 10}"#,
    ]
    .into_iter()
    .flat_map(|f| [(f, "[0, -9.81]", 50), (f, "[0, 0]", 50), (f, "[0, 0]", 0)]);
    for (formulation, gravity, damping) in cases {
        let json = format!(
            r#"{{"name": "a", "thickness": 1.0, "formulation": {formulation}, "gravity": {gravity}, "damping": {damping},
                "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
                "bodies": [{{"name": "b", "material": "m", "mesh": {{"kind": "grid", "origin": [0, 0], "size": [2, 1], "cells": [100, 90]}},
                    "supports": [{{"edge": "left", "kind": "ground-spring"}}],
                    "loads": [{{"kind": "traction", "edge": "right", "value": [1e5, -1e6], "amplitude": [[0, 0], [1e-5, 1]]}}]}}],
                "time": {{"dt": 1e-7, "steps": 10}}}}"#
        );
        let model = Model::build(&rbsm::input::scene::Scene::from_json(&json).unwrap()).unwrap();
        let (mass, loads) = (Mass::new(&model), Loads::new(&model));
        let run = |ev: &dyn evaluator::Evaluator, threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut cd = CentralDifference::new(&model, ev, &mass, &loads, None, 1e-7);
            // Checked every 100 steps, unchecked between: the fused step where it can be.
            let mut last = None;
            pool.install(|| {
                cd.run(
                    300,
                    300,
                    |_, e| {
                        last = Some(*e);
                        Ok(())
                    },
                    |_| {},
                )
            })
            .unwrap();
            let e = last.unwrap();
            (cd.u, cd.v, e.damping, e.total, e.external_work)
        };
        for (kind, other) in [
            (EvaluatorKind::ElementWise, EvaluatorKind::Assembled),
            (EvaluatorKind::Assembled, EvaluatorKind::ElementWise),
        ] {
            let fused = evaluator::build(&model, kind);
            let two_pass = TwoPass(fused.as_ref());
            let other = evaluator::build(&model, other);
            assert!(fused.fused().is_some() && two_pass.fused().is_none());
            let (u, v, work, ..) = run(fused.as_ref(), 1);
            let two = run(fused.as_ref(), 2);
            assert_eq!(
                (&u, &v, work),
                (&two.0, &two.1, two.2),
                "{kind:?}, {formulation}, gravity {gravity}, damping {damping}: thread count"
            );
            for (name, ev) in [
                ("two passes", &two_pass as &dyn evaluator::Evaluator),
                ("the other evaluator", other.as_ref()),
            ] {
                let (u2, v2, work2, total2, _) = run(ev, 2);
                if damping > 0 {
                    // The damping did work, the same in both ways of booking it, and the balance
                    // `total` (which includes it) is the same.
                    assert!(
                        work > 0.0 && (work - work2).abs() <= 1e-12 * work,
                        "{kind:?}, {name}: {work} {work2}"
                    );
                    assert!(
                        (two.3 - total2).abs() <= 1e-12 * two.4,
                        "{kind:?}, {name}: {} {total2} of {}",
                        two.3,
                        two.4
                    );
                }
                let scale = u.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                assert!(
                scale > 1e-9,
                "{kind:?}, {formulation}, gravity {gravity}, damping {damping}: the model moved ({scale:e})"
            );
                assert!(
                    max_abs_diff(&u, &u2) <= 1e-12 * scale,
                    "{kind:?}, {formulation}, gravity {gravity}, \
                damping {damping}, {name}: |ΔU| = {:e} of {scale:e}",
                    max_abs_diff(&u, &u2)
                );
                let vscale = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                assert!(
                    max_abs_diff(&v, &v2) <= 1e-12 * vscale,
                    "{kind:?}, {formulation}, gravity {gravity}, \
                damping {damping}, {name}: |Δv| = {:e} of {vscale:e}",
                    max_abs_diff(&v, &v2)
                );
            }
        }
    }
}

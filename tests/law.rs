//! The interface-law seam (eq. 11, `rbsm::model::law`): a law defined here, springs twice as
//! stiff, set on a model reaches both evaluators, the statics, the midpoint tractions and the
//! contact springs, with no change to any of them.

mod common;
use common::*;
use rbsm::analysis::statics;
use rbsm::force::contact::{self, Contact};
use rbsm::force::evaluator;
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::model::law::InterfaceLaw;
use rbsm::model::loads::Loads;
use rbsm::model::mass::Mass;
use rbsm::model::Model;
use rbsm::step::integrator::{CentralDifference, Status};
use std::sync::Arc;

/// `λ = 2 diag(k_n, k_s) δ`: linear, so the evaluators may precompute it.
#[derive(Debug)]
struct Twice;

impl InterfaceLaw for Twice {
    fn traction(&self, k: [f64; 2], delta: [f64; 2]) -> [f64; 2] {
        [2.0 * k[0] * delta[0], 2.0 * k[1] * delta[1]]
    }
    fn tangent(&self, k: [f64; 2], _: [f64; 2]) -> [[f64; 2]; 2] {
        [[2.0 * k[0], 0.0], [0.0, 2.0 * k[1]]]
    }
    fn is_linear(&self) -> bool {
        true
    }
}

fn with_twice(mut model: Model) -> Model {
    model.law = Arc::new(Twice);
    model
}

/// The same model with its springs `k_n`, `k_s` doubled, under the default law.
fn doubled_springs(model: &Model) -> Model {
    let mut m = model.clone();
    for i in &mut m.interfaces {
        i.k_n *= 2.0;
        i.k_s *= 2.0;
    }
    m
}

const PULL: &str = r#"[{"kind": "traction", "edge": "right", "value": [2e5, -1e6]}]"#;

/// A cantilever of `mesh` under an end traction, rigid or hybrid (penalty 100).
fn cantilever(mesh: &str, formulation: &str) -> Model {
    let json = format!(
        r#"{{"name": "law", "plane": "stress", "thickness": 0.1, "formulation": {formulation},
        "materials": {{"m": {{"E": 2.0e10, "nu": 0.2, "rho": 2400.0}}}},
        "bodies": [{{"name": "b", "material": "m", "mesh": {mesh}, "supports": {SUPPORTS},
            "loads": {PULL}}}],
        "time": {{"dt": 1e-6, "steps": 10}}}}"#
    );
    Model::build(&Scene::from_json(&json).unwrap()).unwrap()
}

const FORMULATIONS: [&str; 2] = [
    r#"{"kind": "rigid"}"#,
    r#"{"kind": "hybrid", "penalty": 100}"#,
];

/// A displacement with small strains on the hybrid strain DOFs.
fn displacement(model: &Model, seed: u64) -> Vec<f64> {
    let nd = model.formulation.ndof();
    random_vector(model.n_dofs(), seed)
        .iter()
        .enumerate()
        .map(|(i, x)| if i % nd >= 3 { x * 1e-3 } else { *x })
        .collect()
}

/// With the law, `K U` and the element-wise resultant agree to round-off and equal the
/// default law's forces on doubled springs; they differ from the default law's forces.
#[test]
fn both_evaluators_use_the_law() {
    for formulation in FORMULATIONS {
        for mesh in [RECT, TRI, VORONOI] {
            let model = cantilever(mesh, formulation);
            let u = displacement(&model, 7);
            let (fa, fe) = forces(&with_twice(model.clone()), &u);
            let (da, de) = forces(&doubled_springs(&model), &u);
            let (ea, _) = forces(&model, &u);
            let scale = norm(&fa);
            let rel = |a: &[f64], b: &[f64]| max_abs_diff(a, b) / scale;
            assert!(
                rel(&fa, &fe) <= 1e-12,
                "{formulation} {mesh}: {:e}",
                rel(&fa, &fe)
            );
            assert!(
                rel(&fa, &da) <= 1e-13,
                "{formulation} {mesh}: {:e}",
                rel(&fa, &da)
            );
            assert!(
                rel(&fe, &de) <= 1e-13,
                "{formulation} {mesh}: {:e}",
                rel(&fe, &de)
            );
            assert!(
                rel(&fa, &ea) >= 1e-3,
                "{formulation} {mesh}: the law changed nothing"
            );
        }
    }
}

/// `U` after `steps` steps of `model` with the evaluator `kind`, at the stable step of its
/// own `K` (the law reaches the eigenvalue estimate too).
fn trajectory(model: &Model, kind: EvaluatorKind, steps: u64) -> (Vec<f64>, f64) {
    let ev = evaluator::build(model, kind);
    let mass = Mass::new(model);
    let loads = Loads::new(model);
    let omega =
        rbsm::analysis::limit::omega_max(model, ev.as_ref(), &mass, rbsm::analysis::limit::EXACT);
    let dt = 0.9 * 2.0 / omega;
    let mut cd = CentralDifference::new(model, ev.as_ref(), &mass, &loads, None, dt);
    assert_eq!(
        cd.run(steps, steps, |_, _| Ok(()), |_| {}).unwrap(),
        Status::Ok
    );
    (cd.u, dt)
}

/// 500 steps of the cantilever scenes, rigid and hybrid, with the law: the two evaluators stay
/// within the 1e-9 of tests/dynamics.rs and tests/hybrid.rs, and the stable step is that of
/// springs twice as stiff (`Δt_crit / √2` for rigid elements).
#[test]
fn trajectories_agree_with_the_law() {
    for name in ["cantilever", "cantilever_hybrid"] {
        let path = format!("{}/examples/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
        let model = Model::build(&Scene::from_file(path).unwrap()).unwrap();
        let twice = with_twice(model.clone());
        let (a, dt) = trajectory(&twice, EvaluatorKind::Assembled, 500);
        let (e, _) = trajectory(&twice, EvaluatorKind::ElementWise, 500);
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = max_abs_diff(&a, &e) / scale;
        eprintln!("{name} with the law: trajectory difference {diff:.2e}");
        assert!(scale > 0.0 && diff <= 1e-9, "{name}: {diff:e}");
        let (_, dt_default) = trajectory(&model, EvaluatorKind::Assembled, 1);
        let ratio = dt_default / dt;
        if name == "cantilever" {
            assert!(
                (ratio - 2f64.sqrt()).abs() <= 1e-6,
                "{name}: Δt ratio {ratio}"
            );
        } else {
            assert!(ratio > 1.1, "{name}: Δt ratio {ratio}");
        }
    }
}

/// Statics with the law: rigid elements move half as far as with the default law; hybrid
/// ones as far as with the default law at twice the penalty (their interior term stays).
#[test]
fn statics_uses_the_law() {
    for formulation in FORMULATIONS {
        let model = cantilever(RECT, formulation);
        let u = statics::solve(&with_twice(model.clone())).unwrap().u;
        let expected: Vec<f64> = if formulation.contains("rigid") {
            statics::solve(&model)
                .unwrap()
                .u
                .iter()
                .map(|x| 0.5 * x)
                .collect()
        } else {
            statics::solve(&doubled_springs(&model)).unwrap().u
        };
        let scale = expected.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let rel = max_abs_diff(&u, &expected) / scale;
        assert!(scale > 0.0 && rel <= 1e-9, "{formulation}: {rel:e}");
    }
}

/// The midpoint traction is the law's: twice the default law's at the same `U`, exactly.
#[test]
fn midpoint_traction_uses_the_law() {
    for formulation in FORMULATIONS {
        let model = cantilever(VORONOI, formulation);
        let twice = with_twice(model.clone());
        let u = displacement(&model, 3);
        for i in &model.interfaces {
            let [n, s] = statics::midpoint_traction(&model, i, &u);
            let [n2, s2] = statics::midpoint_traction(&twice, i, &u);
            assert!(
                n2 == 2.0 * n && s2 == 2.0 * s,
                "{formulation}: {n2} {s2} vs {n} {s}"
            );
            assert!(n != 0.0 || s != 0.0);
        }
    }
}

/// The contact springs are the law's: the stiffness of every contact closed at once doubles.
#[test]
fn contact_springs_use_the_law() {
    let path = format!(
        "{}/examples/scenes/toppling_stack.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let model = Model::build(&Scene::from_file(path).unwrap()).unwrap();
    let twice = with_twice(model.clone());
    let k = contact::stiffness_estimate(&model, &Contact::new(&model).unwrap());
    let k2 = contact::stiffness_estimate(&twice, &Contact::new(&twice).unwrap());
    assert!(k.iter().any(|&x| x != 0.0));
    assert!(k.iter().zip(&k2).all(|(a, b)| *b == 2.0 * a));
}

//! The interface-law seam (eq. 11, `rbsm::model::law`): laws defined here reach the crate with
//! no change to it. A linear one, springs twice as stiff, set as a model's law reaches both
//! evaluators, the statics, the midpoint tractions and the contact springs; one with a state
//! (brittle in tension) reaches the plastic forces, the run and its reports.

mod common;
use common::*;
use rbsm::analysis::run::{self as run, RunParams, Silent};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::analysis::statics;
use rbsm::force::contact::{self, Contact};
use rbsm::force::evaluator;
use rbsm::force::failure::{self, InterfaceStatus};
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::model::law::{InterfaceLaw, LawPoint};
use rbsm::model::loads::Loads;
use rbsm::model::mass::Mass;
use rbsm::model::Model;
use rbsm::step::integrator::{CentralDifference, Status};
use std::sync::Arc;

/// `λ = 2 diag(k_n, k_s) δ`: linear, so the evaluators may precompute it.
#[derive(Debug)]
struct Twice;

impl InterfaceLaw for Twice {
    fn springs(&self, k: [f64; 2]) -> [f64; 2] {
        [2.0 * k[0], 2.0 * k[1]]
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

/// A law with a state, defined here and given to a model through the seam alone
/// (`Model::set_law`): brittle in tension. A Gauss point is elastic until its normal traction
/// passes `f_t`; then it breaks, the elastic energy it held, `½ k_n δ_n²` per unit area, is
/// booked as the work of fracture, and it carries no tension from then on (its opening
/// `δ_p,n` follows `δ_n`); shear stays elastic.
#[derive(Debug)]
struct Brittle {
    f_t: f64,
}

impl InterfaceLaw for Brittle {
    fn springs(&self, k: [f64; 2]) -> [f64; 2] {
        k
    }
    fn is_linear(&self) -> bool {
        false
    }
    fn update(&self, k: [f64; 2], delta: [f64; 2], point: &mut LawPoint) -> ([f64; 2], bool) {
        let mut sigma = k[0] * (delta[0] - point.p[0]);
        let mut flowed = false;
        if point.kappa[0] == 0.0 && sigma > self.f_t {
            point.kappa[0] = 1.0;
            point.fracture += 0.5 * sigma * sigma / k[0];
        }
        if point.kappa[0] > 0.0 && sigma > 0.0 {
            point.p[0] = delta[0];
            sigma = 0.0;
            flowed = true;
        }
        ([sigma, k[1] * (delta[1] - point.p[1])], flowed)
    }
    fn is_broken(&self, point: &LawPoint) -> bool {
        point.kappa[0] > 0.0
    }
}

const F_T: f64 = 1.0e6;

/// A scene of rigid squares in a row, `cells` long, held by a clamp on the left and pulled by
/// one on the right at 0.02 m/s.
fn row(cells: usize) -> Scene {
    let json = format!(
        r#"{{"name": "brittle", "thickness": 0.1, "formulation": {{"kind": "rigid"}},
        "materials": {{"m": {{"E": 2.0e10, "nu": 0.2, "rho": 2400.0}}}},
        "damping": 500,
        "bodies": [{{"name": "b", "material": "m",
            "mesh": {{"kind": "grid", "origin": [0, 0], "size": [{}, 0.05], "cells": [{cells}, 1]}},
            "supports": [{{"kind": "clamp", "edge": "left"}},
                {{"kind": "clamp", "edge": "right", "velocity": [0.02, 0], "ramp": 1e-4}}]}}],
        "time": {{"dt_factor": 0.5, "end": 1e-3}}}}"#,
        0.05 * cells as f64
    );
    Scene::from_json(&json).unwrap()
}

fn brittle(scene: &Scene) -> Model {
    let mut model = Model::build(scene).unwrap();
    model.set_law(Arc::new(Brittle { f_t: F_T }), |_| true);
    model
}

/// On one interface, against the law in closed form: two squares pulled apart by `δ_n` keep
/// the elastic force below `f_t / k_n`; beyond it the interface breaks, carries nothing, and
/// has dissipated `t L ½ k_n δ_n²`. Both evaluators give the same forces.
#[test]
fn a_law_with_state_through_the_seam_alone() {
    let scene = row(2);
    let model = brittle(&scene);
    let i = model
        .interfaces
        .iter()
        .position(|i| i.b != rbsm::model::GROUND)
        .unwrap();
    let (k_n, length) = (model.interfaces[i].k_n, model.interfaces[i].length);
    for kind in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
        let ev = evaluator::build(&model, kind);
        let plastic = failure::build(&model).expect("the law is not linear: points");
        assert_eq!(plastic.interfaces(), &[i as u32]);
        for (ratio, breaks) in [(0.5, false), (2.0, true)] {
            let d = ratio * F_T / k_n;
            let mut u = vec![0.0; model.n_dofs()];
            u[3] = d;
            let mut state = plastic.initial();
            let mut f = vec![0.0; u.len()];
            ev.internal_force_failing(&u, &mut f, (plastic.as_ref(), &mut state));
            let elastic = model.thickness * length * k_n * d;
            let expected = if breaks { 0.0 } else { elastic };
            assert!(
                (f[3] - expected).abs() <= 1e-12 * elastic
                    && (f[0] + expected).abs() <= 1e-12 * elastic,
                "{kind:?} δ_n = {ratio} f_t/k_n: f = {:?}, expected ±{expected}",
                &f[..6]
            );
            let report = plastic.report(&state);
            let dissipated = if breaks {
                0.5 * model.thickness * length * k_n * d * d
            } else {
                0.0
            };
            assert!(
                (report[0].dissipated - dissipated).abs() <= 1e-12 * dissipated.max(1.0),
                "{kind:?}: {} dissipated, {dissipated} expected",
                report[0].dissipated
            );
            let status = if breaks {
                InterfaceStatus::Broken
            } else {
                InterfaceStatus::Elastic
            };
            assert_eq!(report[0].status, status, "{kind:?}");
        }
    }
}

/// Through a whole run (`Setup::with_model`, `run::simulate`): a row of squares pulled apart
/// breaks at the law's strength. The work of fracture is that of the interfaces that broke,
/// `t h f_t² / (2 k_n)` each, plus the overshoot of the step at which each broke, which is
/// first order in `Δt`: at `Δt/2` the excess is about half; so is the energy books' drift. The
/// scene with its elastic law does none of it.
#[test]
fn a_run_with_a_law_of_its_own() {
    let scene = row(4);
    let (k_n, h) = (Model::build(&scene).unwrap().interfaces[0].k_n, 0.05);
    let each = 0.1 * h * F_T * F_T / (2.0 * k_n);
    let params = RunParams::default();
    let excess = [0.5, 0.25].map(|dt_factor| {
        let overrides = Overrides {
            dt_factor: Some(dt_factor),
            ..Overrides::default()
        };
        let setup = Setup::with_model(&scene, &overrides, brittle(&scene)).unwrap();
        let outcome = run::simulate(&setup, &params, None, &mut Silent).unwrap();
        let failure = outcome
            .summary
            .failure
            .expect("a law that is not linear reports failure");
        assert_eq!(failure.interfaces, 3);
        assert!(failure.broken >= 1, "{failure:?}");
        let drift = outcome.summary.energy.max_relative_drift;
        let ratio = failure.fracture / (failure.broken as f64 * each);
        eprintln!(
            "Δt_crit × {dt_factor}: {} broken, fracture / closed form = {ratio}, energy drift {drift}",
            failure.broken
        );
        [ratio - 1.0, drift]
    });
    // The excess of the work over the closed form, and the energy books' drift (the work of
    // a traction that drops within one step is booked to first order, as for `Strength`).
    for (c, what) in ["fracture excess", "energy drift"].iter().enumerate() {
        let [coarse, fine] = [excess[0][c], excess[1][c]];
        assert!(
            coarse > 0.0 && fine > 0.0 && fine <= 0.7 * coarse,
            "{what} {coarse:e} at Δt, {fine:e} at Δt/2: not first order"
        );
    }
    let elastic = Setup::new(&scene, &Overrides::default()).unwrap();
    let plain = run::simulate(&elastic, &params, None, &mut Silent).unwrap();
    assert!(plain.summary.failure.is_none() && elastic.plastic.is_none());
}

/// `Strength` with its `initial_region` or without it (the steps then return-map every point),
/// counting the calls of `update`.
#[derive(Debug)]
struct Counted {
    strength: rbsm::model::law::Strength,
    region: bool,
    calls: std::sync::atomic::AtomicUsize,
}

impl InterfaceLaw for Counted {
    fn springs(&self, k: [f64; 2]) -> [f64; 2] {
        self.strength.springs(k)
    }
    fn is_linear(&self) -> bool {
        false
    }
    fn update(&self, k: [f64; 2], delta: [f64; 2], point: &mut LawPoint) -> ([f64; 2], bool) {
        self.calls
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.strength.update(k, delta, point)
    }
    fn is_broken(&self, point: &LawPoint) -> bool {
        self.strength.is_broken(point)
    }
    fn initial_region(&self) -> Option<[f64; 3]> {
        self.region
            .then(|| self.strength.initial_region())
            .flatten()
    }
}

/// The quick test of a law's initial region is exact: a bar that cracks under a traction (the
/// bundled tension bar's softening law, its clamp on the right replaced by the load), rigid
/// and hybrid, follows the same trajectory whether the steps test `Strength::initial_region`
/// first or return-map every point (to the bit in the assembled evaluator, whose screen only
/// decides whether to return-map; to round-off in the element-wise one, whose screen computes
/// an elastic traction another way), with fewer calls of `update`; and more than a few of its
/// interfaces break. Under a tenth of the strength it calls `update` not once (at a third, the
/// hybrid bar's transient takes some interfaces out of the initial region).
#[test]
fn the_initial_region_spares_update_calls_and_changes_no_bit() {
    let path = format!(
        "{}/examples/scenes/tension_bar.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    json["bodies"][0]["supports"] = serde_json::json!([{"kind": "clamp", "edge": "left"}]);
    json["time"]["end"] = serde_json::json!(3e-4);
    let mut pulled = |traction: f64, formulation: &serde_json::Value| {
        json["bodies"][0]["loads"] =
            serde_json::json!([{"kind": "traction", "edge": "right", "value": [traction, 0]}]);
        json["formulation"] = formulation.clone();
        Scene::from_json(&json.to_string()).unwrap()
    };
    // The scene's law, as `Strength::from_spec` forms it.
    let strength = rbsm::model::law::Strength {
        f_t: 3e6,
        c: 6e6,
        tan_phi: 30f64.to_radians().tan(),
        per_w_n: 3e6 / (2.0 * 100.0),
        per_w_s: 6e6 / (2.0 * 1000.0),
    };
    let formulations = [
        serde_json::json!({"kind": "rigid"}),
        serde_json::json!({"kind": "hybrid", "penalty": 10}),
    ];
    for (formulation, kind) in formulations
        .iter()
        .flat_map(|f| [EvaluatorKind::Assembled, EvaluatorKind::ElementWise].map(|k| (f, k)))
    {
        let (cracks, holds) = (pulled(4e6, formulation), pulled(0.3e6, formulation));
        let overrides = Overrides {
            evaluator: Some(kind),
            ..Overrides::default()
        };
        let run = |scene: &Scene, region: bool| {
            let law = Arc::new(Counted {
                strength,
                region,
                calls: Default::default(),
            });
            let mut model = Model::build(scene).unwrap();
            model.set_law(law.clone(), |_| true);
            let s = Setup::with_model(scene, &overrides, model).unwrap();
            let mut cd = s.integrator(s.dt);
            cd.step_only(s.steps);
            let broken = s
                .plastic
                .as_ref()
                .unwrap()
                .report(cd.failure().unwrap())
                .iter()
                .filter(|i| i.status == InterfaceStatus::Broken)
                .count();
            (
                cd.u,
                broken,
                law.calls.load(std::sync::atomic::Ordering::Relaxed),
            )
        };
        let (quick, broken, spared) = run(&cracks, true);
        let (every, _, calls) = run(&cracks, false);
        assert!(broken >= 5, "{formulation} {kind:?}: only {broken} broken");
        // The element-wise sweep of a rigid model first screens a fresh interface on its
        // elastic record (`Kernel::screened`): a disc inside the initial region, where the
        // traction is the elastic one computed another way, so the two agree to round-off;
        // the assembled sweep's screen decides only whether to return-map, to the bit.
        let scale = every.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let apart = quick
            .iter()
            .zip(&every)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let bound = match kind {
            EvaluatorKind::Assembled => 0.0,
            _ => 1e-12 * scale,
        };
        assert!(
            apart <= bound,
            "{formulation} {kind:?}: the quick test changed the trajectory by {apart:e} of {scale:e}"
        );
        assert!(
            spared < calls,
            "{formulation} {kind:?}: {spared} calls of update with the quick test, {calls} without"
        );
        let ((_, broken, spared), (_, _, calls)) = (run(&holds, true), run(&holds, false));
        assert_eq!(
            (broken, spared),
            (0, 0),
            "{formulation} {kind:?}: a bar within its strength"
        );
        assert!(calls > 0);
    }
}

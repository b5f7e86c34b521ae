//! Scenes built in code for the tests.
#![allow(dead_code)]

use rbsm::analysis::run;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use rbsm::model::Model;
use rbsm::output::Summary;

/// A one-body scene around `mesh` (a JSON object) with `supports` (a JSON array).
pub fn scene_json(mesh: &str, supports: &str) -> String {
    format!(
        r#"{{
        "name": "test", "plane": "stress", "thickness": 0.1,
        "formulation": {{"kind": "rigid"}},
        "materials": {{"m": {{"E": 2.0e10, "nu": 0.2, "rho": 2400.0}}}},
        "bodies": [{{"name": "b", "material": "m", "mesh": {mesh}, "supports": {supports}}}],
        "time": {{"dt": 1e-6, "steps": 10}}
    }}"#
    )
}

pub fn model(mesh: &str, supports: &str) -> Model {
    let scene = Scene::from_json(&scene_json(mesh, supports)).expect("valid test scene");
    Model::build(&scene).expect("model builds")
}

pub const RECT: &str = r#"{"kind": "grid", "origin": [0.0, 0.0], "size": [1.0, 0.4], "cells": [10, 4], "cell": "rect"}"#;
pub const TRI: &str = r#"{"kind": "grid", "origin": [0.2, -0.1], "size": [1.0, 0.4], "cells": [6, 3], "cell": "tri"}"#;
pub const VORONOI: &str = r#"{"kind": "voronoi", "origin": [0.0, 0.0], "size": [1.0, 0.5], "sites": 80, "seed": 11, "lloyd": 10}"#;
pub const SUPPORTS: &str = r#"[{"edge": "left", "kind": "ground-spring"}, {"edge": "bottom", "kind": "ground-spring", "components": ["n"]}]"#;

/// Seeded pseudo-random numbers in (-1, 1) (a small LCG, enough for test vectors).
pub fn random_vector(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

/// `(K U, element-wise f(U))`: the internal forces of both evaluators.
pub fn forces(model: &Model, u: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = model.n_dofs();
    let (mut fa, mut fe) = (vec![0.0; n], vec![0.0; n]);
    rbsm::force::evaluator::build(model, rbsm::input::scene::EvaluatorKind::Assembled)
        .internal_force(u, &mut fa);
    rbsm::force::evaluator::build(model, rbsm::input::scene::EvaluatorKind::ElementWise)
        .internal_force(u, &mut fe);
    (fa, fe)
}

/// Asserts that both evaluators' forces at `u` are the same bits on 1 and 2 threads.
pub fn same_forces_on_one_and_two_threads(model: &Model, u: &[f64]) {
    for kind in [
        rbsm::input::scene::EvaluatorKind::Assembled,
        rbsm::input::scene::EvaluatorKind::ElementWise,
    ] {
        let ev = rbsm::force::evaluator::build(model, kind);
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut f = vec![0.0; u.len()];
            pool.install(|| ev.internal_force(u, &mut f));
            f
        };
        let (one, two) = (run(1), run(2));
        assert!(
            one.iter()
                .zip(&two)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{kind:?}"
        );
    }
}

pub fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The largest `|total − total(0)|` over the energies of a run's records (J).
pub fn energy_drift(rows: &[rbsm::step::integrator::Energy]) -> f64 {
    rows.iter()
        .map(|e| (e.total - rows[0].total).abs())
        .fold(0.0, f64::max)
}

/// Runs `scene` silently into `dir`, for `steps` steps when given (else the scene's).
pub fn run_into(scene: &Scene, steps: Option<u64>, dir: &std::path::Path) -> Summary {
    let overrides = Overrides {
        steps,
        ..Default::default()
    };
    let setup = Setup::new(scene, &overrides).expect("the scene sets up");
    run::run(&setup, &Default::default(), dir, &mut run::Silent).expect("the run writes")
}

/// An evaluator seen through its evaluation only: a time step then evaluates and updates in
/// two passes, and failing interfaces are added after the evaluation
/// (`PlasticForces::add_plastic`), not in its sweep.
pub struct TwoPass<'a>(pub &'a dyn rbsm::force::evaluator::Evaluator);

impl rbsm::force::evaluator::Evaluator for TwoPass<'_> {
    fn kind(&self) -> rbsm::input::scene::EvaluatorKind {
        self.0.kind()
    }
    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        self.0.internal_force(u, f)
    }
    fn bytes(&self) -> usize {
        self.0.bytes()
    }
}

/// An evaluator stepped in two passes through its own failing evaluation (`TwoPass` takes the
/// default one, `PlasticForces::add_plastic`, which knows no Poisson correction).
pub struct Unfused<'a>(pub &'a dyn rbsm::force::evaluator::Evaluator);

impl rbsm::force::evaluator::Evaluator for Unfused<'_> {
    fn kind(&self) -> rbsm::input::scene::EvaluatorKind {
        self.0.kind()
    }
    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        self.0.internal_force(u, f)
    }
    fn internal_force_failing(
        &self,
        u: &[f64],
        f: &mut [f64],
        failure: rbsm::force::evaluator::Failure<'_>,
    ) {
        self.0.internal_force_failing(u, f, failure)
    }
    fn bytes(&self) -> usize {
        self.0.bytes()
    }
}

/// A run's monitor that raises `flag` (the run's interrupt) once the run reaches step `at`: a
/// Ctrl-C at a known step.
pub struct StopAt {
    pub at: u64,
    pub flag: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl run::Monitor for StopAt {
    fn info(&mut self, _: &str) {}
    fn progress(&mut self, step: u64, _: u64) {
        if step >= self.at {
            self.flag.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }
}

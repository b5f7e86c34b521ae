//! Quasi-static solution control (`rbsm::step::local`, the scene's `local_damping`): Cundall's
//! local non-viscous damping brings a suddenly loaded body to its static solution, the energy books close with the work it
//! takes, and the run does not depend on the thread count.

mod common;
use common::*;
use rbsm::analysis::run::{self as run, Outcome, RunParams, Silent};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::analysis::statics;
use rbsm::input::scene::Scene;
use rbsm::model::Model;

/// The scene of [`cantilever`].
fn rbsm_scene(mesh: &str, alpha: f64, steps: u64, dt_factor: f64) -> String {
    format!(
        r#"{{"name": "settle", "thickness": 0.1, "formulation": {{"kind": "rigid"}},
        "local_damping": {alpha},
        "materials": {{"m": {{"E": 2.0e10, "nu": 0.2, "rho": 2400.0}}}},
        "bodies": [{{"name": "b", "material": "m", "mesh": {mesh},
            "supports": [{{"kind": "ground-spring", "edge": "left"}}],
            "loads": [{{"kind": "traction", "edge": "right", "value": [1e5, -1e6]}}]}}],
        "time": {{"dt_factor": {dt_factor}, "steps": {steps}}}, "output": {{"every": {steps}}}}}"#
    )
}

/// A cantilever of `mesh`, held on its left edge by ground springs, under an end traction
/// applied at `t = 0`, with local damping `alpha`, run for `steps` steps at `dt_factor Δt_crit`.
fn cantilever(mesh: &str, alpha: f64, steps: u64, dt_factor: f64) -> (Model, Outcome) {
    let json = rbsm_scene(mesh, alpha, steps, dt_factor);
    let scene = Scene::from_json(&json).unwrap();
    let setup = Setup::new(&scene, &Overrides::default()).unwrap();
    assert_eq!(setup.model.local_damping, alpha);
    let outcome = run::simulate(&setup, &RunParams::default(), None, &mut Silent).unwrap();
    (setup.model.clone(), outcome)
}

/// Relative distance of `u` from the static solution of `model`.
fn from_static(model: &Model, u: &[f64]) -> f64 {
    let exact = statics::solve(model).unwrap().u;
    max_abs_diff(u, &exact) / exact.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// With `α = 0.8` the cantilever settles on the static solution; undamped, it still swings
/// about it by as much as its static deflection.
#[test]
fn local_damping_settles_on_the_static_solution() {
    for mesh in [RECT, VORONOI] {
        let (model, damped) = cantilever(mesh, 0.8, 8000, 0.5);
        let (_, free) = cantilever(mesh, 0.0, 8000, 0.5);
        let (settled, swinging) = (from_static(&model, &damped.u), from_static(&model, &free.u));
        eprintln!("{mesh}: {settled:.2e} from the static solution damped, {swinging:.2e} undamped");
        assert!(settled < 1e-6, "{mesh}: {settled:e}");
        assert!(swinging > 0.05, "{mesh}: {swinging:e}");
    }
}

/// The books close: what the loads put in is the elastic energy left plus the work the local
/// damping took (counted in `damping`: half of it, for a linear body settling under a load
/// applied at once), to first order in `Δt` (the damping force turns with the sign of the
/// velocity, inside a step).
#[test]
fn the_books_close_with_local_damping() {
    let drift = [(0.5, 2000), (0.25, 4000)].map(|(f, steps)| {
        let (_, o) = cantilever(VORONOI, 0.8, steps, f);
        let (damping, work) = (o.last("damping").unwrap(), o.last("external_work").unwrap());
        let drift = o.summary.energy.max_relative_drift;
        eprintln!("Δt_crit × {f}: damping took {damping:e} J of {work:e} J; drift {drift:e}");
        assert!(
            (damping / work - 0.5).abs() < 0.01,
            "{damping:e} of {work:e}"
        );
        drift
    });
    assert!(
        drift[0] < 1e-3 && drift[1] <= 0.7 * drift[0],
        "drift {drift:?} at Δt, Δt/2: not first order"
    );
}

/// The same bits on one thread and on two, on a model whose damping and `U` update go in
/// several parallel chunks (18,000 DOFs).
#[test]
fn local_damping_does_not_depend_on_the_threads() {
    const BIG: &str = r#"{"kind": "grid", "origin": [0, 0], "size": [3, 1], "cells": [120, 50]}"#;
    let runs: Vec<Vec<f64>> = [1, 2]
        .iter()
        .map(|&threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| cantilever(BIG, 0.7, 500, 0.5).1.u)
        })
        .collect();
    assert!(runs[0].len() > rbsm::parallel::STREAM_CHUNK);
    assert_eq!(runs[0], runs[1]);
}

/// Local damping stiffens the highest mode by `1 + α` (its force has the sign of the elastic
/// one there), so the setup's `Δt_crit` is the undamped one over `√(1 + α)`, and a run at
/// 0.9 of it stays stable; the undamped scheme's limit would diverge.
#[test]
fn local_damping_lowers_the_stable_step() {
    let (model, run) = cantilever(RECT, 0.8, 2000, 0.9);
    let undamped = Setup::new(
        &Scene::from_json(&rbsm_scene(RECT, 0.0, 10, 0.9)).unwrap(),
        &Overrides::default(),
    )
    .unwrap();
    let damped = Setup::new(
        &Scene::from_json(&rbsm_scene(RECT, 0.8, 10, 0.9)).unwrap(),
        &Overrides::default(),
    )
    .unwrap();
    let ratio = undamped.dt_crit() / damped.dt_crit();
    assert!((ratio - 1.8f64.sqrt()).abs() < 1e-12, "{ratio}");
    assert_eq!(run.summary.status, rbsm::step::integrator::RunStatus::Ok);
    assert!(from_static(&model, &run.u) < 1e-3);
    // At 0.9 of the undamped limit the damped scheme is unstable: the guard stops it.
    let over = Overrides {
        dt: Some(0.9 * undamped.dt_crit()),
        ..Overrides::default()
    };
    let setup = Setup::new(
        &Scene::from_json(&rbsm_scene(RECT, 0.8, 2000, 0.9)).unwrap(),
        &over,
    )
    .unwrap();
    let o = run::simulate(&setup, &RunParams::default(), None, &mut Silent).unwrap();
    assert_eq!(
        o.summary.status,
        rbsm::step::integrator::RunStatus::Diverged
    );
}

/// With `time.stop_ratio` a run stops at the first check whose unbalanced-force ratio is below
/// it: the locally damped cantilever settles long before its planned steps, on the static
/// solution to the ratio's order; undamped, it never settles and goes to its end.
#[test]
fn a_run_stops_once_balanced() {
    let stop = |alpha: f64| {
        let mut json: serde_json::Value =
            serde_json::from_str(&rbsm_scene(RECT, alpha, 20_000, 0.5)).unwrap();
        json["time"]["stop_ratio"] = serde_json::json!(1e-6);
        let scene = Scene::from_json(&json.to_string()).unwrap();
        let setup = Setup::new(&scene, &Overrides::default()).unwrap();
        let o = run::simulate(&setup, &RunParams::default(), None, &mut Silent).unwrap();
        (setup.model.clone(), o)
    };
    let (model, damped) = stop(0.8);
    let balance = damped.summary.balance.clone().unwrap();
    let at = balance.settled_at_step.expect("settles");
    let error = from_static(&model, &damped.u);
    eprintln!(
        "settled at step {at} (ratio {:.2e}), {error:.2e} from the static solution",
        balance.ratio
    );
    assert!(balance.ratio < 1e-6 && at < 20_000 && damped.summary.steps == at);
    assert_eq!(damped.summary.status, rbsm::step::integrator::RunStatus::Ok);
    assert!(error < 1e-5, "{error:e}");
    let (_, free) = stop(0.0);
    let balance = free.summary.balance.unwrap();
    assert!(
        balance.settled_at_step.is_none() && balance.ratio > 1e-2,
        "{balance:?}"
    );
    assert_eq!(free.summary.steps, 20_000);
}

/// The bundled squeeze (`examples/scenes/squeeze.json`: a cohesive block between smooth
/// platens, local damping, the clamp ten times as fast as the validation report's run under
/// mass-proportional damping) levels off at the closed-form collapse stress `2c` within 1 %,
/// where its largest reaction, a dynamic overshoot at the start of the mechanism, is more than
/// 5 % above it: a collapse load is read on the plateau (validation report §11.6).
#[test]
fn the_bundled_squeeze_levels_off_at_its_collapse_load() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/scenes/squeeze.json");
    let setup = Setup::new(&Scene::from_file(path).unwrap(), &Overrides::default()).unwrap();
    let params = RunParams {
        keep_history: true,
        ..RunParams::default()
    };
    let outcome = run::simulate(&setup, &params, None, &mut Silent).unwrap();
    let force = outcome
        .columns
        .iter()
        .position(|c| c == "block_s1_force")
        .unwrap();
    let q: Vec<f64> = outcome
        .history
        .chunks(outcome.columns.len())
        .map(|row| row[force] / (0.5 * 1.0e5))
        .collect();
    let (end, peak) = (*q.last().unwrap(), q.iter().fold(0.0f64, |m, &x| m.max(x)));
    eprintln!(
        "q / c: {end:.4} at the end, {peak:.4} at most, {} steps",
        outcome.summary.steps
    );
    assert!((end / 2.0 - 1.0).abs() < 0.01, "{end}");
    assert!(peak / 2.0 - 1.0 > 0.05, "{peak}");
}

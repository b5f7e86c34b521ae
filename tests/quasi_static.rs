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

/// A cantilever of `mesh`, held on its left edge by ground springs, under an end traction
/// applied at `t = 0`, with local damping `alpha`, run for `steps` steps at `dt_factor Δt_crit`.
fn cantilever(mesh: &str, alpha: f64, steps: u64, dt_factor: f64) -> (Model, Outcome) {
    let json = format!(
        r#"{{"name": "settle", "thickness": 0.1, "formulation": {{"kind": "rigid"}},
        "local_damping": {alpha},
        "materials": {{"m": {{"E": 2.0e10, "nu": 0.2, "rho": 2400.0}}}},
        "bodies": [{{"name": "b", "material": "m", "mesh": {mesh},
            "supports": [{{"kind": "ground-spring", "edge": "left"}}],
            "loads": [{{"kind": "traction", "edge": "right", "value": [1e5, -1e6]}}]}}],
        "time": {{"dt_factor": {dt_factor}, "steps": {steps}}}, "output": {{"every": {steps}}}}}"#
    );
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
        let (model, damped) = cantilever(mesh, 0.8, 4000, 0.5);
        let (_, free) = cantilever(mesh, 0.0, 4000, 0.5);
        let (settled, swinging) = (from_static(&model, &damped.u), from_static(&model, &free.u));
        eprintln!("{mesh}: {settled:.2e} from the static solution damped, {swinging:.2e} undamped");
        assert!(settled < 1e-4, "{mesh}: {settled:e}");
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
        let col = |name: &str| o.columns.iter().position(|c| c == name).unwrap();
        let row = &o.history[o.history.len() - o.columns.len()..];
        let (damping, work) = (row[col("damping")], row[col("external_work")]);
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

/// The same bits on one thread and on two.
#[test]
fn local_damping_does_not_depend_on_the_threads() {
    let runs: Vec<Vec<f64>> = [1, 2]
        .iter()
        .map(|&threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| cantilever(VORONOI, 0.7, 500, 0.5).1.u)
        })
        .collect();
    assert_eq!(runs[0], runs[1]);
}

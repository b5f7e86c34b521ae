//! A run models only what its scene asks for, at setup too (paper_notes.md 24): with a given `dt`
//! it computes no `ω_max` (Lanczos iterations are counted process-wide, so this file holds one
//! test, alone in its process), with a `dt_factor` only a few digits, and to full precision when
//! asked; an analysis that takes no step (`static`, `effective`, `limit`) computes none.

use rbsm::analysis::limit;
use rbsm::analysis::run::{self, RunParams, Silent};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use rbsm::output::Summary;
use rbsm::step::integrator::RunStatus;

/// The bundled cantilever, refined to 4000 elements so that Lanczos takes many iterations.
fn cantilever(time: &str) -> Scene {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/cantilever.json"
    );
    let text = std::fs::read_to_string(path)
        .unwrap()
        .replace("\"cells\": [80, 8]", "\"cells\": [200, 20]")
        .replace("\"dt_factor\": 0.9, \"end\": 0.1", time);
    assert!(
        text.contains("[200, 20]") && text.contains(time),
        "the scene changed"
    );
    Scene::from_json(&text).unwrap()
}

/// Sets up and runs `scene` for 50 steps; the Lanczos iterations that took, and the setup.
fn run_counted(scene: &Scene, overrides: &Overrides) -> (u64, Setup, Summary) {
    let before = limit::lanczos_iterations();
    let setup = Setup::new(scene, overrides).unwrap();
    let out = tempfile::tempdir().unwrap();
    let params = RunParams {
        resume: false,
        interrupt: None,
        keep_history: false,
    };
    let summary = run::run(&setup, &params, out.path(), &mut Silent).unwrap();
    assert_eq!(summary.status, RunStatus::Ok);
    (limit::lanczos_iterations() - before, setup, summary)
}

#[test]
fn a_run_with_a_given_dt_does_no_lanczos_iteration() {
    let steps = Overrides {
        steps: Some(50),
        ..Default::default()
    };
    // A given time step: no iteration, and summary.json says Δt_crit was not computed.
    let (given, setup, summary) = run_counted(&cantilever("\"dt\": 1e-6, \"steps\": 50"), &steps);
    assert_eq!(given, 0, "Lanczos ran {given} iterations for a given dt");
    assert_eq!(summary.dt_crit, None);
    // The same through `--dt`, on a scene that has a `dt_factor`.
    let cli_dt = Overrides {
        dt: Some(1e-6),
        ..steps.clone()
    };
    let (overridden, ..) = run_counted(&cantilever("\"dt_factor\": 0.9, \"steps\": 50"), &cli_dt);
    assert_eq!(
        overridden, 0,
        "Lanczos ran {overridden} iterations for --dt"
    );
    // The counter counts: a `dt_factor` needs ω_max, to a few digits.
    let factor_scene = cantilever("\"dt_factor\": 0.9, \"steps\": 50");
    let (few, approximate, _) = run_counted(&factor_scene, &steps);
    assert!(few > 0);
    // `--exact-dt-crit` settles it to full precision, which takes more iterations.
    let exact = Overrides {
        exact_dt_crit: true,
        ..steps.clone()
    };
    let (full, exact_setup, exact_summary) = run_counted(&factor_scene, &exact);
    assert!(
        full > few,
        "full precision {full} iterations, a few digits {few}"
    );
    let (a, b) = (
        approximate.limit.omega_max.unwrap(),
        exact_setup.limit.omega_max.unwrap(),
    );
    assert!(
        a <= b * (1.0 + 1e-12) && (b - a) <= limit::FOR_STEP * b,
        "a few digits: {a}, exact {b}"
    );
    assert_eq!(exact_summary.dt_crit, Some(2.0 / b));
    // The given step was checked against a bound proven below Δt_crit (one more Lanczos).
    let before = limit::lanczos_iterations();
    assert!(summary.dt_safe <= setup.dt_crit());
    assert!(limit::lanczos_iterations() > before);
    // The analyses that take no step: none on the scene's `dt_factor` either.
    let before = limit::lanczos_iterations();
    let setup = Setup::new(&factor_scene, &Overrides::no_step()).unwrap();
    rbsm::analysis::statics::analyse(&setup).unwrap();
    rbsm::analysis::effective::analyse(&setup).unwrap();
    assert_eq!(
        limit::lanczos_iterations(),
        before,
        "an analysis without steps ran Lanczos"
    );
    assert!(setup.dt > 0.0 && setup.dt <= setup.limit.dt_safe() * 0.9 * (1.0 + 1e-12));
}

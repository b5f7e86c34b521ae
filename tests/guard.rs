//! The divergence guard (README, *Outputs*; paper_notes.md 18): it never stops a stable run,
//! whatever the run starts from (zero energy, loads ramped from zero, damping, gravity on touching
//! bodies), and it still stops runs above `Δt_crit` within the steps it took before.

use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use rbsm::step::integrator::Status;
use serde_json::Value;

fn bundled(name: &str) -> Value {
    let path = format!("{}/examples/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Runs `steps` steps of `scene` with a history row every `every` steps; the status.
fn status(scene: &Value, dt_factor: Option<f64>, steps: u64, every: u64) -> Status {
    let scene = Scene::from_json(&scene.to_string()).unwrap();
    let p = Setup::new(&scene, &Overrides::default()).unwrap();
    let dt = dt_factor.map_or(p.dt, |f| f * p.dt_crit());
    let mut cd = p.integrator(dt);
    cd.run(steps, every, |_, _| Ok(()), |_| {}).unwrap()
}

#[test]
fn stable_runs_that_start_from_nothing_are_not_stopped() {
    // Loads ramped from zero: the first step's kinetic energy comes before any booked work.
    for name in ["voronoi_panel", "bar_pulse"] {
        let s = bundled(name);
        for steps in [1, 2, 3] {
            assert_eq!(
                status(&s, None, steps, 1),
                Status::Ok,
                "{name}, {steps} steps"
            );
        }
        assert_eq!(
            status(&s, None, 3000, 1),
            Status::Ok,
            "{name}, every step checked"
        );
    }
    // Damped starts, at and near the scene's time step.
    for name in ["cantilever", "column_step", "hopping_block", "wall"] {
        let mut s = bundled(name);
        s["damping"] = 1.0.into();
        for steps in [1, 5, 300] {
            assert_eq!(
                status(&s, None, steps, 1),
                Status::Ok,
                "{name} damped, {steps} steps"
            );
        }
        assert_eq!(
            status(&s, Some(0.999), 300, 1),
            Status::Ok,
            "{name} damped at 0.999 Δt_crit"
        );
    }
    // Bricks that touch at t = 0, under gravity, with contact.
    let mut wall = bundled("wall");
    wall["damping"] = 0.0.into();
    assert_eq!(status(&wall, None, 200, 1), Status::Ok, "touching wall");
}

#[test]
fn runs_above_the_critical_step_are_stopped_as_early_as_before() {
    // (scene, Δt / Δt_crit, the step at which the guard of 7500eec stopped the run, with the
    // scene's own `output.every`: `rbsm run SCENE --dt F×Δt_crit` then reported that step).
    let cases = [
        ("cantilever", 1.01, 300),
        ("cantilever", 1.5, 200),
        ("cantilever", 10.0, 100),
        ("bar_pulse", 1.01, 380),
        ("bar_pulse", 1.5, 10),
        ("column_step", 1.01, 30),
        ("column_step", 1.5, 190),
        ("column_step", 10.0, 60),
        ("hopping_block", 10.0, 1500),
    ];
    for (name, f, before) in cases {
        let s = bundled(name);
        let every = s["output"]["every"].as_u64().unwrap_or(1);
        match status(&s, Some(f), 30_000, every) {
            Status::Diverged { step, reason, .. } => {
                assert!(
                    step <= before,
                    "{name} at {f} Δt_crit: stopped at step {step}, before at {before}"
                );
                assert!(
                    reason.contains("energy growth") || reason.contains("NaN"),
                    "{reason}"
                );
            }
            other => panic!("{name} at {f} Δt_crit: {other:?}"),
        }
    }
}

/// A dropped beam stepped at 1.5 `Δt_crit` (the contact springs' limit): each impact pumps
/// energy in and takes it out, so the energy stays bounded (2.3 × the energy put in) and the
/// growth test never fires, but the books break: the total energy moved by 29 J of the 60 J
/// put in by 23.8 ms, where the run used to end `ok` at 80 ms with a drift of 0.44. The
/// balance test stops it; at the scene's 0.25 `Δt_crit` the run ends `ok`.
#[test]
fn a_run_whose_energy_balance_breaks_is_stopped() {
    let s = bundled("beam_drop");
    let every = s["output"]["every"].as_u64().unwrap_or(1);
    match status(&s, Some(1.5), 20_000, every) {
        Status::Diverged { reason, .. } => {
            assert!(reason.contains("energy balance"), "{reason}")
        }
        other => panic!("beam_drop at 1.5 Δt_crit: {other:?}"),
    }
    assert_eq!(status(&s, None, 4_000, every), Status::Ok);
}

//! The extremes of validation §10, on shorter runs: each test asserts the behaviour that the
//! report states (stable, warned, stopped or refused).

#[path = "../validation/fixtures/extremes.rs"]
mod extremes;

use rbsm::step::integrator::Status;

const RIGID: &str = r#"{"kind": "rigid"}"#;

#[test]
fn penalty_up_to_1e8_runs_stably_and_is_warned_about() {
    let low = extremes::penalty(1e4).unwrap();
    let high = extremes::penalty(1e8).unwrap();
    for x in [&low, &high] {
        assert_eq!(x.run.status, Status::Ok, "p = {}", x.p);
        assert!(x.run.drift < 1e-2, "p = {}: drift {}", x.p, x.run.drift);
    }
    // Δt_crit ∝ 1/√p between 1e4 and 1e8.
    assert!(
        (high.dt_ratio_sqrt_p / low.dt_ratio_sqrt_p - 1.0).abs() < 0.05,
        "{} {}",
        low.dt_ratio_sqrt_p,
        high.dt_ratio_sqrt_p
    );
    assert!(low.patch_error < 1e-3, "{}", low.patch_error);
    assert!(!low.warnings.iter().any(|w| w.contains("penalty")));
    assert!(
        high.warnings.iter().any(|w| w.contains("penalty p = 1e8")),
        "{:?}",
        high.warnings
    );
}

#[test]
fn aspect_ratio_1000_is_stable_below_and_stopped_above_the_limit() {
    let x = extremes::aspect(1000.0, RIGID).unwrap();
    assert!(x.lanczos_error < 1e-8, "{}", x.lanczos_error);
    assert_eq!(x.stable.status, Status::Ok);
    assert!(x.stable.drift < 1e-2);
    assert!(
        matches!(x.above.status, Status::Diverged { .. }) && x.above.finite,
        "{:?}",
        x.above.status
    );
    assert!(
        x.warnings
            .iter()
            .any(|w| w.contains("aspect ratio of 1000")),
        "{:?}",
        x.warnings
    );
    assert!(extremes::aspect(10.0, RIGID).unwrap().warnings.is_empty());
}

#[test]
fn sizes_spanning_1000_are_stable_and_warned_about() {
    let x = extremes::size_ratio(1000.0).unwrap();
    assert!(x.lanczos_error < 1e-8, "{}", x.lanczos_error);
    assert_eq!(x.stable.status, Status::Ok);
    assert!(matches!(x.above.status, Status::Diverged { .. }) && x.above.finite);
    assert!(
        x.sizes > 500.0 && x.warnings.iter().any(|w| w.contains("sizes span 1:")),
        "{} {:?}",
        x.sizes,
        x.warnings
    );
    // The limit is the smallest cells': 100 times larger cells leave it where it was.
    let y = extremes::size_ratio(10.0).unwrap();
    assert!(
        (x.dt_crit / y.dt_crit - 1.0).abs() < 0.2,
        "{} {}",
        x.dt_crit,
        y.dt_crit
    );
}

#[test]
fn extreme_poisson_ratios_run_and_the_hybrid_carries_them() {
    for nu in [0.49, -0.9] {
        let h = extremes::poisson(nu, true, "stress").unwrap();
        assert!(
            (h.nu_effective - nu).abs() < 0.01,
            "ν = {nu}: fitted {}",
            h.nu_effective
        );
        assert!(
            (h.e_ratio - 1.0).abs() < 0.01,
            "ν = {nu}: E ratio {}",
            h.e_ratio
        );
        assert_eq!(h.run.status, Status::Ok);
        assert!(
            h.warnings.iter().any(|w| w.contains("ν =")),
            "{:?}",
            h.warnings
        );
        let r = extremes::poisson(nu, false, "stress").unwrap();
        assert_eq!(r.run.status, Status::Ok);
        assert!(r.run.drift < 1e-2);
    }
    assert!(extremes::poisson(0.2, true, "stress")
        .unwrap()
        .warnings
        .is_empty());
}

#[test]
fn a_million_undamped_steps_drift_by_round_off_only() {
    let d = extremes::long_run(&[100_000, 1_000_000]).unwrap();
    assert_eq!(d.len(), 2);
    // The conserved discrete energy moves by round-off alone, at most linearly in the steps.
    assert!(d[1].1 < 1e-11 && d[1].1 < 15.0 * d[0].1, "{d:?}");
}

#[test]
fn large_rotations_in_contact_keep_the_balance_and_meshed_bodies_are_warned_about() {
    let one = extremes::tumble(1, 20.0, 0.5).unwrap();
    assert_eq!(one.run.status, Status::Ok);
    assert!(one.max_rotation > 1.5, "{}", one.max_rotation);
    assert!(one.run.drift < 1e-2, "{}", one.run.drift);
    assert!(one.warnings.is_empty(), "{:?}", one.warnings);
    let meshed = extremes::tumble(4, 20.0, 0.5).unwrap();
    assert!(
        meshed
            .warnings
            .iter()
            .any(|w| w.contains("meshed body turned")),
        "{:?}",
        meshed.warnings
    );
    assert!(meshed.spurious > 0.0);
}

#[test]
fn just_above_the_critical_step_the_guard_stops_the_run() {
    let scene = rbsm::input::scene::Scene::from_json(&extremes::stack_scene(1.0, RIGID)).unwrap();
    let p = rbsm::analysis::setup::Setup::new(&scene, &Default::default()).unwrap();
    assert_eq!(
        extremes::run_at(&p, 0.999, 20_000).unwrap().status,
        Status::Ok
    );
    for f in [1.001, 1.01] {
        let x = extremes::run_at(&p, f, 20_000).unwrap();
        assert!(
            matches!(&x.status, Status::Diverged { reason, .. } if reason.contains("energy growth")),
            "{f}: {:?}",
            x.status
        );
        assert!(x.finite && x.steps < 20_000);
    }
}

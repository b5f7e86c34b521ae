//! Explicit runs: the two evaluators give the same trajectory, energy is kept, the guard stops
//! an unstable run, and the outputs follow the README's *Outputs*.

mod common;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::step::integrator::{RunStatus, Status};

fn scene(name: &str) -> Scene {
    Scene::from_file(format!(
        "{}/examples/scenes/{name}.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

/// `U` after `steps` steps of `scene` with the given evaluator, and `max |U|`.
fn trajectory(scene: &Scene, kind: EvaluatorKind, steps: u64) -> Vec<f64> {
    let p = Setup::new(
        scene,
        &Overrides {
            evaluator: Some(kind),
            ..Default::default()
        },
    )
    .unwrap();
    let mut cd = p.integrator(p.dt);
    assert_eq!(
        cd.run(steps, steps, |_, _| Ok(()), |_| {}).unwrap(),
        Status::Ok
    );
    cd.u
}

/// Over 10⁴ steps the two evaluators stay within 1e-9 of each other, relative to `max |U|`.
///
/// Why round-off alone explains what remains: the two forces differ only in summation order,
/// by about `ε ‖K‖ ‖U‖` (ε ≈ 1e-16; tests/operators.rs shows 1e-12 or better). Below Δt_crit
/// central difference neither damps nor amplifies, and a force error that repeats from step to
/// step acts like a small static load: its displacement response is bounded by
/// `2 κ ε ‖U‖`, `κ = (ω_max / ω_1)²`. For the cantilever `κ ≈ 7e6` (ω_max = 4.6e5 rad/s,
/// first bending mode 28 Hz), so the bound is about 1.5e-9; measured: 1e-15 after 10 steps,
/// 9e-13 after 10³, 1.4e-10 after 10⁴ (growing as steps² within the first bending period of
/// ~9000 steps, then bounded). The Voronoi panel is stiffer (smaller κ): 2e-13, and as much
/// with the `rigid-poisson` correction, computed by each evaluator its own way. A physics
/// difference (a missing term, another quadrature) would show at 1e-3 or more in a few steps.
#[test]
fn evaluators_give_the_same_trajectory_over_ten_thousand_steps() {
    for name in ["cantilever", "voronoi_panel", "voronoi_panel_poisson"] {
        let s = scene(name);
        let a = trajectory(&s, EvaluatorKind::Assembled, 10_000);
        let e = trajectory(&s, EvaluatorKind::ElementWise, 10_000);
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = common::max_abs_diff(&a, &e) / scale;
        eprintln!(
            "{name}: max |U_assembled − U_element-wise| / max |U| = {diff:.3e} after 10⁴ steps"
        );
        assert!(
            scale > 0.0 && diff <= 1e-9,
            "{name}: relative difference {diff:e}"
        );
    }
}

fn drift(scene: &Scene, factor: f64, steps: u64) -> f64 {
    let mut s = scene.clone();
    s.time.dt = None;
    s.time.dt_factor = Some(factor);
    let dir = tempfile::tempdir().unwrap();
    let summary = common::run_into(&s, Some(steps), dir.path());
    assert_eq!(summary.status, RunStatus::Ok);
    summary.energy.max_relative_drift
}

/// An undamped run keeps its energy: the total uses the kinetic energy that central difference
/// conserves exactly on a linear system, `½ (v^{n+½})ᵀ M v^{n−½}`, and the cantilever's step
/// load is constant, so the drift is round-off at any stable Δt (measured 1.2e-11 at 0.9 and at
/// 0.45 Δt_crit). The averaged-velocity energy it replaced drifted by O(Δt²) (4.8e-7 at 0.9).
#[test]
fn energy_is_conserved_to_round_off() {
    let s = scene("cantilever");
    let coarse = drift(&s, 0.9, 10_000);
    let fine = drift(&s, 0.45, 20_000);
    eprintln!("cantilever energy drift: {coarse:.3e} at 0.9 Δt_crit, {fine:.3e} at 0.45 Δt_crit");
    assert!(
        coarse <= 1e-10 && fine <= 1e-10,
        "drift {coarse:e} at 0.9 Δt_crit, {fine:e} at 0.45"
    );
}

/// Above Δt_crit the run stops with the step, the time and the reason, and what it wrote stays
/// valid: the history parses, the summary says `diverged`, the final state is finite.
#[test]
fn unstable_run_stops_with_reason_and_keeps_its_outputs() {
    let mut s = scene("cantilever");
    s.time.dt_factor = Some(1.05);
    s.output.every = 50;
    let dir = tempfile::tempdir().unwrap();
    let summary = common::run_into(&s, None, dir.path());
    assert_eq!(summary.status, RunStatus::Diverged);
    let reason = summary.reason.unwrap();
    assert!(
        reason.starts_with("step ") && reason.contains("t = ") && reason.contains("energy growth"),
        "{reason}"
    );
    assert!(summary.steps < 25_000, "stopped at step {}", summary.steps);
    // It was warned about before it started, and the summary keeps the warning.
    assert!(
        summary
            .warnings
            .iter()
            .any(|w| w.contains("1.0500 × Δt_crit")),
        "{:?}",
        summary.warnings
    );
    let history = std::fs::read_to_string(dir.path().join("history.csv")).unwrap();
    for line in history.lines().skip(1) {
        assert!(
            line.split(',')
                .all(|x| x.parse::<f64>().is_ok_and(f64::is_finite)),
            "bad row {line}"
        );
    }
    let state: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("final_state.json")).unwrap(),
    )
    .unwrap();
    let u = &state["elements"][79]["U"];
    assert!(u
        .as_array()
        .unwrap()
        .iter()
        .all(|x| x.as_f64().is_some_and(f64::is_finite)));
}

/// A run into a folder that holds an earlier run's outputs removes them first: a shorter run
/// leaves none of the earlier frames, and had it stopped early, no earlier summary.
#[test]
fn a_run_clears_an_earlier_runs_outputs() {
    let mut s = scene("cantilever");
    s.output.every = 100;
    s.output.vtk = true;
    let dir = tempfile::tempdir().unwrap();
    let frames = |dir: &std::path::Path| std::fs::read_dir(dir.join("vtk")).unwrap().count();
    common::run_into(&s, Some(1000), dir.path());
    assert_eq!(frames(dir.path()), 11);
    std::fs::write(dir.path().join("notes.txt"), "mine").unwrap();
    std::fs::write(dir.path().join("vtk").join("mine.vtk"), "mine").unwrap();
    let summary = common::run_into(&s, Some(300), dir.path());
    assert_eq!(summary.steps, 300);
    // Frames of steps 0 … 300 and the user's own file; the earlier run's 400 … 1000 are gone.
    assert_eq!(frames(dir.path()), 5);
    assert!(
        dir.path().join("notes.txt").exists() && dir.path().join("vtk").join("mine.vtk").exists()
    );
    // The pictures `rbsm plot` drew of the earlier run go, and so does a frames folder that
    // only held its frames, when the next run writes no frames.
    rbsm::output::plot::histories(dir.path()).unwrap();
    assert!(dir.path().join("energies.svg").exists());
    std::fs::remove_file(dir.path().join("vtk").join("mine.vtk")).unwrap();
    s.output.vtk = false;
    common::run_into(&s, Some(100), dir.path());
    assert!(!dir.path().join("energies.svg").exists() && !dir.path().join("vtk").exists());
    assert!(dir.path().join("notes.txt").exists());
}

/// The files of the README's *Outputs* with their exact keys, header and element order.
#[test]
fn outputs_follow_the_contract() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = scene("voronoi_panel");
    s.time.end = None;
    s.time.steps = Some(200);
    let summary = common::run_into(&s, None, dir.path());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    for key in [
        "scene",
        "formulation",
        "evaluator",
        "elements",
        "interfaces",
        "dofs",
        "dt",
        "dt_crit",
        "dt_safe",
        "steps",
        "t_end",
        "status",
        "reason",
        "wall_time_s",
        "setup_time_s",
        "step_time_s",
        "threads",
        "energy",
    ] {
        assert!(json.get(key).is_some(), "summary.json lacks `{key}`");
    }
    for key in ["initial", "final", "max_relative_drift"] {
        assert!(
            json["energy"].get(key).is_some(),
            "summary.json energy lacks `{key}`"
        );
    }
    assert_eq!(json["steps"], 200);
    assert_eq!(summary.elements, 400);
    let history = std::fs::read_to_string(dir.path().join("history.csv")).unwrap();
    assert!(history.starts_with("t,kinetic,elastic,contact,potential,external_work,total\n"));
    assert_eq!(
        history.lines().count(),
        1 + 3,
        "rows at steps 0, 100 and 200"
    );
    // No `-0e0`: the hopping block's potential at the start was written so.
    let hop = tempfile::tempdir().unwrap();
    common::run_into(&scene("hopping_block"), Some(10), hop.path());
    let history = std::fs::read_to_string(hop.path().join("history.csv")).unwrap();
    assert!(history.split([',', '\n']).all(|x| x != "-0e0"), "{history}");
    let state: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("final_state.json")).unwrap(),
    )
    .unwrap();
    let elements = state["elements"].as_array().unwrap();
    assert_eq!(elements.len(), 400);
    assert_eq!(elements[0]["U"].as_array().unwrap().len(), 3);
    assert!((state["t"].as_f64().unwrap() - summary.t_end).abs() <= 1e-15);
    // The scene asks for VTK: a frame per row and a collection that lists them.
    let pvd = std::fs::read_to_string(dir.path().join("series.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 3);
    let frame = std::fs::read_to_string(dir.path().join("vtk/step_000000200.vtu")).unwrap();
    assert!(frame.starts_with("<VTKFile type=\"UnstructuredGrid\""));
}

/// Without `output.vtk` no VTK is written: an output nobody asked for is not computed.
#[test]
fn no_vtk_unless_asked() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = scene("bar_pulse");
    s.time.end = None;
    s.time.steps = Some(20);
    common::run_into(&s, None, dir.path());
    assert!(!dir.path().join("vtk").exists() && !dir.path().join("series.pvd").exists());
    let history = std::fs::read_to_string(dir.path().join("history.csv")).unwrap();
    assert!(history.lines().next().unwrap().ends_with(",u_tip,u_mid"));
}

/// Probes placed by point (`"at": [x, y]`, docs/scene.md *`probes`*): at an element's centroid the
/// same column as the element's own DOF; at a corner of the plate `N_e(x) U_e` of the element
/// holding it; a point outside every element is an error naming the probe.
#[test]
fn probes_by_point_read_the_displacement_there() {
    let path = format!(
        "{}/examples/scenes/cantilever.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let model = rbsm::model::Model::build(&Scene::from_json(&v.to_string()).unwrap()).unwrap();
    let c = model.elements[79].props.centroid;
    v["output"]["probes"] = serde_json::json!([
        {"element": 79, "dof": "v"},
        {"at": [c.x, c.y], "dof": "v"},
        {"name": "corner_v", "at": [2.0, 0.0], "dof": "v"},
        {"at": [2.0, 0.0], "dof": "theta"}
    ]);
    let dir = tempfile::tempdir().unwrap();
    let s = Scene::from_json(&v.to_string()).unwrap();
    common::run_into(&s, Some(2000), dir.path());
    let history = std::fs::read_to_string(dir.path().join("history.csv")).unwrap();
    let header: Vec<&str> = history.lines().next().unwrap().split(',').collect();
    assert_eq!(
        header[7..],
        [
            "e79_v",
            &format!("v_at_{}_{}", c.x, c.y),
            "corner_v",
            "theta_at_2_0"
        ]
    );
    let last: Vec<f64> = history
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(last[7], last[8], "at the centroid, the element's own v");
    let corner = model
        .element_at(rbsm::mesh::geometry::Vec2::new(2.0, 0.0))
        .unwrap();
    let state: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("final_state.json")).unwrap(),
    )
    .unwrap();
    let u: Vec<f64> = state["elements"][corner]["U"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let d = rbsm::mesh::geometry::Vec2::new(2.0, 0.0) - model.elements[corner].props.centroid;
    let expected = model.formulation.displacement(&u, d).y;
    assert!(
        (last[9] - expected).abs() <= 1e-12 * expected.abs() && expected != last[8],
        "{} against {expected}",
        last[9]
    );
    assert_eq!(last[10], u[2], "θ is the element's own");
    v["output"]["probes"] = serde_json::json!([{"at": [5.0, 0.0], "dof": "u"}]);
    let e = Scene::from_json(&v.to_string())
        .and_then(|s| rbsm::model::Model::build(&s))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("output.probes[0].at") && e.contains("lies in no element"),
        "{e}"
    );
}

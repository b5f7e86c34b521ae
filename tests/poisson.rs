//! The `rigid-poisson` formulation (`rbsm::model::poisson`): rigid cells that keep Poisson's
//! effect. Its patch test at ν = 0.2 and 0.4 on Voronoi cells, where plain rigid cells miss the
//! lateral contraction; the square grid's effective constants in closed form; a bad pairing
//! refused by name.

mod common;
use rbsm::analysis::effective;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::analysis::statics;
use rbsm::input::scene::Scene;
use rbsm::model::{Model, GROUND};
use rbsm::step::integrator::RunStatus;

const E: f64 = 1.0e10;
const SIGMA: f64 = 3.0e6;

fn patch(formulation: &str, mesh: &str, nu: f64) -> Scene {
    Scene::from_json(&format!(
        r#"{{"name": "patch", "thickness": 0.2, "formulation": {{"kind": "{formulation}"}},
        "materials": {{"m": {{"E": {E}, "nu": {nu}, "rho": 2000}}}},
        "bodies": [{{"name": "b", "material": "m", "mesh": {mesh},
            "supports": [{{"edge": "left", "kind": "ground-spring", "components": ["n"]}},
                         {{"edge": "bottom", "kind": "ground-spring", "components": ["n"]}}],
            "loads": [{{"kind": "traction", "edge": "right", "value": [{SIGMA}, 0]}}]}}],
        "time": {{"dt": 1e-6, "steps": 1}}}}"#
    ))
    .unwrap()
}

const VORONOI: &str = r#"{"kind": "voronoi", "origin": [0, 0], "size": [1.2, 0.8], "sites": 60, "seed": 5, "lloyd": 30}"#;

/// The uniform-tension patch's errors against plane stress (`u = σ/E x`, `v = −ν σ/E y`): the
/// largest centroid displacement error over the largest displacement, and the largest midpoint
/// traction error over `σ`, as validation §3 measures them.
fn patch_errors(model: &Model, nu: f64) -> (f64, f64) {
    let sol = statics::solve(model).unwrap();
    let exact = |x: rbsm::mesh::geometry::Vec2| (SIGMA / E * x.x, -nu * SIGMA / E * x.y);
    let mut scale = 0.0f64;
    let mut du = 0.0f64;
    for (k, el) in model.elements.iter().enumerate() {
        let (a, b) = exact(el.props.centroid);
        scale = scale.max(a.hypot(b));
        du = du.max((sol.u[3 * k] - a).hypot(sol.u[3 * k + 1] - b));
    }
    let dt = model
        .interfaces
        .iter()
        .filter(|i| i.b != GROUND)
        .map(|i| {
            let [t_n, t_s] = sol.traction(model, i);
            let (n, s) = (i.normal, i.tangent);
            (t_n - SIGMA * n.x * n.x).hypot(t_s - SIGMA * n.x * s.x)
        })
        .fold(0.0, f64::max);
    (du / scale, dt / SIGMA)
}

/// With the correction, the Voronoi patch follows the continuum at ν = 0.2 and 0.4 (tractions
/// within 1 %), where plain rigid cells miss it by about ten percent.
#[test]
fn the_voronoi_patch_keeps_poissons_effect() {
    for nu in [0.2, 0.4] {
        let rigid = Model::build(&patch("rigid", VORONOI, nu)).unwrap();
        let corrected = Model::build(&patch("rigid-poisson", VORONOI, nu)).unwrap();
        let (ru, rt) = patch_errors(&rigid, nu);
        let (pu, pt) = patch_errors(&corrected, nu);
        eprintln!("ν = {nu}: rigid {ru:.3e} / {rt:.3e}, rigid-poisson {pu:.3e} / {pt:.3e}");
        assert!(
            rt > 0.05,
            "ν = {nu}: plain rigid cells should miss the patch, {rt:.3e}"
        );
        assert!(pt < 0.01, "ν = {nu}: traction error {pt:.3e}");
        assert!(pu < 0.01, "ν = {nu}: displacement error {pu:.3e}");
    }
}

fn bundled() -> Scene {
    Scene::from_file(format!(
        "{}/examples/scenes/voronoi_panel_poisson.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

/// On the bundled panel of 400 Voronoi cells, `rbsm effective` reads the material's `E` and `ν`
/// within 2 % at ν = 0.25 and 0.4, where plain rigid cells read `ν` ≈ 0.08; the same in plane
/// stress.
#[test]
fn effective_constants_of_voronoi_cells_are_the_materials() {
    for (plane, nu) in [("strain", 0.25), ("strain", 0.4), ("stress", 0.25)] {
        let json = std::fs::read_to_string(format!(
            "{}/examples/scenes/voronoi_panel_poisson.json",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap()
        .replace("\"nu\": 0.25", &format!("\"nu\": {nu}"))
        .replace("\"strain\"", &format!("\"{plane}\""));
        let scene = Scene::from_json(&json).unwrap();
        let r = effective::analyse(&Setup::new(&scene, &Overrides::default()).unwrap()).unwrap();
        eprintln!(
            "{plane}, ν = {nu}: E {:+.3} %, ν {:.4}",
            100.0 * (r.young / r.material[0] - 1.0),
            r.poisson
        );
        assert!(
            (r.young / r.material[0] - 1.0).abs() < 0.02,
            "{plane} ν = {nu}: E {:e}",
            r.young
        );
        assert!(
            (r.poisson / nu - 1.0).abs() < 0.02,
            "{plane} ν = {nu}: ν {}",
            r.poisson
        );
    }
}

/// An element with a free edge is on the outline, whatever its neighbours: the outline of a
/// grid 80 × 8 is its 172 elements with a free edge, and a mesh one element thick (the
/// column's row of blocks, the cantilever as 80 × 1) or of one element (the hopping block) has
/// nothing inside and is refused. Such meshes used to count two elements on the outline (the
/// free edges of a row come in opposite pairs, whose normals cancel) and print `E` = 5e-18 Pa,
/// or leak the factorisation's debug output.
#[test]
fn the_outline_is_every_element_with_a_free_edge() {
    let text = |name: &str| {
        std::fs::read_to_string(format!(
            "{}/examples/scenes/{name}.json",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap()
    };
    let bundled = |name: &str| Scene::from_json(&text(name)).unwrap();
    let of = |scene: &Scene| effective::analyse(&Setup::new(scene, &Overrides::default()).unwrap());
    assert_eq!(of(&bundled("cantilever")).unwrap().boundary_elements, 172);
    let mut json: serde_json::Value = serde_json::from_str(&text("cantilever")).unwrap();
    json["bodies"][0]["mesh"]["cells"] = serde_json::json!([80, 1]);
    let one_row = Scene::from_json(&json.to_string()).unwrap();
    for scene in [one_row, bundled("column_step"), bundled("hopping_block")] {
        let e = of(&scene).expect_err("nothing inside").to_string();
        assert!(
            e.contains("bodies[0].mesh") && e.contains("free edge") && !e.contains("Numeric"),
            "{}: {e}",
            scene.name
        );
    }
}

/// An undamped run with the correction keeps its energy to round-off (`K` is symmetric).
#[test]
fn an_undamped_run_keeps_its_energy() {
    let mut s = bundled();
    s.gravity = None;
    let dir = tempfile::tempdir().unwrap();
    let summary = common::run_into(&s, Some(3000), dir.path());
    assert_eq!(summary.status, RunStatus::Ok);
    let drift = summary.energy.max_relative_drift;
    assert!(drift < 1e-9, "drift {drift:e}");
}

/// Failing interfaces handed over to edge-to-edge contact and `ν < 0` are refused with the
/// key and why.
#[test]
fn what_the_correction_cannot_model_is_refused() {
    let base = std::fs::read_to_string(format!(
        "{}/examples/scenes/voronoi_panel_poisson.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let softening = base.replace(
        "\"rho\": 2600.0}",
        "\"rho\": 2600.0, \"interface\": {\"kind\": \"mohr-coulomb\", \"tensile_strength\": 1e6, \"cohesion\": 1e6, \"friction_angle\": 30}}",
    );
    Scene::from_json(&softening).expect("failing interfaces without contact");
    let fragments = softening.replacen(
        "\"bodies\"",
        "\"contact\": {\"model\": \"edge-to-edge\"}, \"bodies\"",
        1,
    );
    let negative = base.replace("\"nu\": 0.25", "\"nu\": -0.1");
    for (json, key, says) in [
        (
            fragments,
            "materials.rock.interface",
            "does not hand broken interfaces over",
        ),
        (negative, "materials.rock.nu", "must be ≥ 0"),
    ] {
        let err = format!("{:?}", Scene::from_json(&json).expect_err("refused"));
        assert!(err.contains(key) && err.contains(says), "{err}");
    }
}

/// The explicit scheme's empirical limit is the `Δt_crit` the setup reports (Lanczos on the
/// symmetric `K`, without the inertia probes), and inside the proven bracket.
#[test]
fn the_empirical_stability_limit_is_the_reported_one() {
    let mut s = bundled();
    s.gravity = None;
    let setup = Setup::new(
        &s,
        &Overrides {
            exact_dt_crit: true,
            ..Default::default()
        },
    )
    .unwrap();
    let (_, ratio) = rbsm::analysis::stability::empirical_limit(&setup, 2000, 1e-3).unwrap();
    assert!(
        (ratio - 1.0).abs() < 2e-3,
        "empirical limit / Δt_crit = {ratio}"
    );
    let limit = &setup.limit;
    let omega = setup.omega_max();
    assert!(
        limit.floor <= omega && omega <= limit.bound,
        "{limit:?} against {omega:e}"
    );
}

/// Both evaluators' forces are the same bits on 1 and 2 threads (the correction's passes go
/// over fixed chunks of elements; 6,000 cells make three of them).
#[test]
fn the_correction_does_not_depend_on_the_thread_count() {
    let json = std::fs::read_to_string(format!(
        "{}/examples/scenes/voronoi_panel_poisson.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
    .replace("\"sites\": 400", "\"sites\": 6000")
    .replace("\"lloyd\": 20", "\"lloyd\": 2");
    let model = Model::build(&Scene::from_json(&json).unwrap()).unwrap();
    let u = common::random_vector(model.n_dofs(), 7);
    common::same_forces_on_one_and_two_threads(&model, &u);
}

/// A bar of squares pulled along its length (clamps that hold `u` alone, so that it contracts
/// freely) cracks when its facets' traction reaches `f_t`: the law bounds the material's
/// traction, the springs' plus the correction's. Its springs alone carry `σ / (1 + ν)` in
/// uniaxial stress, so a law on them would peak at `(1 + ν) f_t` = 1.2 `f_t`. The cells at the
/// clamps read their pressure without the clamps' forces (`paper_notes.md` item 30), which
/// lowers the peak by a few parts in a thousand. The energy balance closes to first order in
/// `Δt`, as for the other formulations.
#[test]
fn a_bar_of_squares_cracks_at_the_materials_strength() {
    let mut scene: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(format!(
            "{}/examples/scenes/tension_bar.json",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap(),
    )
    .unwrap();
    scene["formulation"] = serde_json::json!({"kind": "rigid-poisson"});
    let body = &mut scene["bodies"][0];
    body["mesh"] = serde_json::json!({"kind": "grid", "origin": [0, 0], "size": [0.2, 0.05], "cells": [20, 5]});
    for clamp in body["supports"].as_array_mut().unwrap() {
        clamp["dofs"] = serde_json::json!(["u"]);
    }
    let dir = tempfile::tempdir().unwrap();
    let s = Scene::from_json(&scene.to_string()).unwrap();
    let summary = common::run_into(&s, None, dir.path());
    assert_eq!(summary.status, RunStatus::Ok);
    let peak = summary.clamps[0].peak_force / (0.05 * 3.0e6);
    assert!((peak - 1.0).abs() < 5e-3, "peak / f_t = {peak}");
    let failure = summary.failure.as_ref().expect("failing interfaces");
    assert!(failure.broken >= 5, "{} broken", failure.broken);
    // One crack across the bar spends `G_f` per unit section (5 J); yielding beside it a little more.
    let work = failure.fracture / 5.0;
    assert!(
        (1.0..1.3).contains(&work),
        "fracture work / (G_f A) = {work}"
    );
}

//! Contact (eqs. 17–20): the hopping block against its theory, tilted landings, friction on an
//! incline, a block at rest, a falling stack, and no contact work without contact.

use rbsm::analysis::hopping::{centre_velocity, lowest_point, Tracker};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::force::contact::Contact;
use rbsm::input::scene::Scene;
use rbsm::step::integrator::Status;

#[path = "../validation/fixtures/brick.rs"]
mod brick;
use brick::G;

struct Outcome {
    tracker: Tracker,
    drift: f64,
    status: Status,
    /// Largest |θ| of element 0 and its final value.
    max_rotation: f64,
    final_u: Vec<f64>,
    final_v: Vec<f64>,
    max_pairs: usize,
    tests_per_step: f64,
}

/// Runs `scene` for `steps` steps of `dt`, sampling every step.
fn run(scene: &str, dt: f64, steps: u64) -> Outcome {
    let scene = Scene::from_json(scene).expect("valid scene");
    let p = Setup::new(
        &scene,
        &Overrides {
            dt: Some(dt),
            steps: Some(steps),
            ..Default::default()
        },
    )
    .expect("model");
    let mut cd = p.integrator(dt);
    let mut tracker = Tracker::default();
    let mut max_rotation: f64 = 0.0;
    let nd = p.model.formulation.ndof();
    let status = cd
        .run(
            steps,
            1,
            |s, _| {
                tracker.push(
                    s.t,
                    lowest_point(&p.model, s.u),
                    centre_velocity(&p.model, s.v).y,
                );
                max_rotation = max_rotation.max(
                    (0..p.model.elements.len())
                        .map(|e| s.u[e * nd + 2].abs())
                        .fold(0.0, f64::max),
                );
                Ok(())
            },
            |_| {},
        )
        .unwrap();
    let c = cd.contact.as_ref().expect("contact scene");
    Outcome {
        tracker,
        drift: cd.max_relative_drift(),
        status,
        max_rotation,
        final_u: cd.u.clone(),
        final_v: cd.velocity().to_vec(),
        max_pairs: c.stats.max_pairs,
        tests_per_step: c.stats.tests as f64 / c.stats.steps as f64,
    }
}

/// One bounce of the flat single brick from 0.2 m, both contact models, against the theory.
#[test]
fn hopping_block_matches_the_theory_of_a_flat_landing() {
    let h = 0.2;
    let th = brick::theory(h);
    let steps = (1.15 * th.period() / 1e-6) as u64;
    for model in ["edge-to-edge", "point"] {
        let o = run(&brick::scene([1, 1], model, None, 0.0, h, 0.0), 1e-6, steps);
        assert_eq!(o.status, Status::Ok);
        let b = o.tracker.bounces[0];
        let rel = |a: f64, b: f64| (a - b).abs() / b;
        eprintln!(
            "{model}: {b:?}; theory impact {} contact {} speed {}",
            th.impact_time(),
            th.contact_time(),
            th.impact_speed()
        );
        // Impact time and speed: free fall, exact up to the step (1e-6 s in 0.2 s).
        assert!(
            rel(b.impact, th.impact_time()) < 1e-5,
            "impact at {} s",
            b.impact
        );
        assert!(
            rel(b.impact_speed, th.impact_speed()) < 1e-5,
            "impact speed {}",
            b.impact_speed
        );
        // Contact time against (π + 2 arcsin(δ_s/A))/ω: ~25 steps per contact, 1 % (measured 0.4
        // %).
        assert!(
            rel(b.release - b.impact, th.contact_time()) < 0.01,
            "contact time {} s",
            b.release - b.impact
        );
        // Rebound speed and apex: no energy loss, up to the penalty's O(Δt) onset error.
        assert!(
            rel(b.rebound_speed, b.impact_speed) < 1e-3,
            "rebound speed {}",
            b.rebound_speed
        );
        assert!(rel(b.apex, h) < 2e-3, "apex {} m", b.apex);
        assert!(
            o.max_rotation < 1e-9,
            "a flat landing does not turn the block: θ = {}",
            o.max_rotation
        );
        assert!(o.drift < 5e-3, "energy drift {}", o.drift);
    }
}

/// The apex error shrinks with the step (the penalty contact's onset error).
#[test]
fn apex_error_converges_with_the_time_step() {
    let h = 0.05;
    let th = brick::theory(h);
    let errors: Vec<f64> = [4e-6, 1e-6]
        .iter()
        .map(|&dt| {
            let o = run(
                &brick::scene([1, 1], "edge-to-edge", None, 0.0, h, 0.0),
                dt,
                (1.3 * th.period() / dt) as u64,
            );
            (o.tracker.bounces[0].apex - h).abs() / h
        })
        .collect();
    eprintln!("apex errors at dt = 4e-6, 1e-6: {errors:?}");
    assert!(
        errors[1] < errors[0] / 3.0,
        "apex error {errors:?} does not fall with dt"
    );
}

/// A 5° tilt: frictionless contact keeps the energy in both models, and the two models differ.
#[test]
fn tilted_landing_conserves_energy_without_friction() {
    let h = 0.1;
    let steps = (1.2 * brick::theory(h).period() / 1e-6) as u64;
    let mut rotations = Vec::new();
    for model in ["edge-to-edge", "point"] {
        let o = run(
            &brick::scene([1, 1], model, Some(0.0), 5.0, h, 0.0),
            1e-6,
            steps,
        );
        assert_eq!(o.status, Status::Ok);
        eprintln!(
            "{model}: drift {:e}, final θ {:e}, rate {:e}",
            o.drift, o.final_u[2], o.final_v[2]
        );
        assert!(o.drift < 2e-3, "{model}: energy drift {}", o.drift);
        rotations.push(o.final_v[2]);
    }
    assert!(
        (rotations[0] - rotations[1]).abs() > 1e-3 * rotations[0].abs(),
        "the two models spin the block alike: {rotations:?}"
    );
}

/// A brick that lands on a corner while it slides, with no slip limit, sticks there and rolls
/// onto its face: the piece of its lower edge in the ground grows from the corner to the whole
/// face at the slip the corner took. The tangential springs then give the motion no energy
/// they did not take: the contact work never goes below zero (a piece's springs scaled their
/// slip with the piece, and gave back 1.4 J where the brick fell with 1.2 J).
#[test]
fn a_sticking_corner_that_rolls_onto_its_face_creates_no_energy() {
    let mut scene: serde_json::Value =
        serde_json::from_str(&brick::scene([1, 1], "edge-to-edge", None, 3.0, 0.01, 0.0)).unwrap();
    scene["bodies"][0]["initial"]["velocity"] = serde_json::json!([-1.0, 0.0]);
    let scene = Scene::from_json(&scene.to_string()).expect("valid scene");
    let dt = 1e-6;
    let p = Setup::new(
        &scene,
        &Overrides {
            dt: Some(dt),
            ..Default::default()
        },
    )
    .expect("model");
    let mut cd = p.integrator(dt);
    let (mut lowest, mut first, mut largest) = (f64::INFINITY, None, 0.0f64);
    let status = cd
        .run(
            100_000,
            10,
            |_, e| {
                let start = *first.get_or_insert(e.kinetic + e.potential);
                largest = largest.max(e.kinetic + e.potential - start);
                lowest = lowest.min(e.contact);
                Ok(())
            },
            |_| {},
        )
        .unwrap();
    assert_eq!(status, Status::Ok);
    let energy = first.unwrap().abs().max(1.0);
    assert!(
        lowest > -1e-9 * energy && largest < 1e-9 * energy,
        "contact gave the motion energy: contact work down to {lowest:e} J, kinetic + \
         potential up by {largest:e} J"
    );
}

/// A brick at rest on flat ground, placed at its static penetration, stays there for 10⁵ steps.
#[test]
fn resting_block_stays_at_rest() {
    let th = brick::theory(0.0);
    let static_depth = th.mass * G / th.stiffness;
    for model in ["edge-to-edge", "point"] {
        let o = run(
            &brick::scene([1, 1], model, None, 0.0, -static_depth, 0.0),
            1e-6,
            100_000,
        );
        assert_eq!(o.status, Status::Ok);
        let speed = o.final_v[..3].iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let moved = o.final_u[..3].iter().fold(0.0f64, |a, v| a.max(v.abs()));
        eprintln!(
            "{model}: static depth {static_depth:e} m, |v| {speed:e}, |u| {moved:e}, bounces {}",
            o.tracker.bounces.len()
        );
        assert!(
            speed < 1e-9 && moved < 1e-6 * static_depth,
            "{model}: drifted: |v| {speed:e} m/s, |u| {moved:e} m"
        );
    }
}

/// A brick on a 20° incline with μ = 0.2 slides at `g (sin α − μ cos α)`; with μ = 0.5 it holds.
#[test]
fn incline_with_friction_slides_at_the_coulomb_rate() {
    let alpha = 20f64.to_radians();
    let th = brick::theory(0.0);
    let depth = th.mass * G * alpha.cos() / th.stiffness;
    for model in ["edge-to-edge", "point"] {
        for mu in [0.2, 0.5] {
            let (t1, t2) = (0.05, 0.1);
            let o_speed = |steps: u64| {
                let o = run(
                    &brick::scene([1, 1], model, Some(mu), 0.0, -depth, 20.0),
                    1e-6,
                    steps,
                );
                assert_eq!(o.status, Status::Ok);
                // Down the slope.
                -(o.final_v[0] * alpha.cos() + o.final_v[1] * alpha.sin())
            };
            let (v1, v2) = (o_speed((t1 / 1e-6) as u64), o_speed((t2 / 1e-6) as u64));
            let a = (v2 - v1) / (t2 - t1);
            let expected = (G * (alpha.sin() - mu * alpha.cos())).max(0.0);
            eprintln!("{model}, μ = {mu}: a = {a:.5} m/s², Coulomb {expected:.5}");
            if expected > 0.0 {
                assert!(
                    (a - expected).abs() < 0.01 * expected,
                    "{model}: a = {a}, expected {expected}"
                );
            } else {
                assert!(
                    a.abs() < 1e-3 && v2.abs() < 1e-3,
                    "{model}: a block that should stick moves: v = {v2}, a = {a}"
                );
            }
        }
    }
}

/// Three bricks stacked with offsets topple onto the ground: multi-body contact works, the
/// broad phase tests only nearby pairs, nothing sinks in and the energy balance holds.
#[test]
fn a_toppling_stack_of_bricks() {
    let scene = include_str!("../examples/scenes/toppling_stack.json");
    let parsed = Scene::from_json(scene).unwrap();
    let p = Setup::new(&parsed, &Overrides::default()).unwrap();
    let o = run(scene, p.dt, 150_000);
    assert_eq!(o.status, Status::Ok);
    let model = &p.model;
    // Boundary vertices (one per boundary edge of a closed boundary) against boundary edges
    // of the other bodies and the ground.
    let edges: usize = model.bodies.iter().map(|b| b.mesh.boundary.len()).sum();
    let all_pairs = edges * (edges - edges / model.bodies.len() + model.ground.len());
    eprintln!(
        "stack: max pairs {}, tests/step {:.1} (all pairs {all_pairs}), drift {:e}",
        o.max_pairs, o.tests_per_step, o.drift
    );
    assert!(
        o.max_pairs >= 3,
        "the bricks touch each other and the ground: {} pairs",
        o.max_pairs
    );
    assert!(
        o.tests_per_step < 0.6 * all_pairs as f64,
        "broad phase: {} tests per step",
        o.tests_per_step
    );
    assert!(o.drift < 0.01, "energy drift {}", o.drift);
    assert!(
        lowest_point(model, &o.final_u) > -1e-3,
        "a brick sank into the ground"
    );
}

/// A scene without `contact` builds no contact and so does no contact work.
#[test]
fn no_contact_without_contact() {
    let scene = Scene::from_json(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/examples/scenes/cantilever.json"
        ))
        .unwrap(),
    )
    .unwrap();
    let p = Setup::new(&scene, &Overrides::default()).unwrap();
    assert!(Contact::new(&p.model).is_none());
    let cd = p.integrator(p.dt);
    assert!(cd.contact.is_none());
}

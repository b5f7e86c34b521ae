//! No allocation inside a step: a counting global allocator watches the time loop once it is
//! warm, for both evaluators and formulations, on a model large enough to run in parallel, on
//! the contact scene, and on a bar whose interfaces crack under a moving, damped clamp or a
//! traction (then in the fused step).

use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::{EvaluatorKind, Scene};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by `steps` steps of the time loop (energies, guard and observer included)
/// after `warm` steps to let lazily grown buffers reach their size.
///
/// Measured on a worker of rayon's pool: each call of `run` or `step_only` from outside it
/// enters the pool through its global queue, which allocates a block every 63 entries, so
/// whether two calls cross a block depends on how many entries the process made before
/// (what the other scenes did), not on the step.
fn allocations(p: &Setup, warm: u64, steps: u64) -> usize {
    let mut cd = p.integrator(p.dt);
    cd.run(warm, 10, |_, _| Ok(()), |_| ()).unwrap();
    rayon::scope(|_| {
        let before = ALLOCATIONS.load(Ordering::Relaxed);
        cd.run(steps, 10, |_, _| Ok(()), |_| ()).unwrap();
        cd.step_only(steps);
        ALLOCATIONS.load(Ordering::Relaxed) - before
    })
}

fn setup(scene: &Scene, evaluator: EvaluatorKind) -> Setup {
    let overrides = Overrides {
        evaluator: Some(evaluator),
        ..Default::default()
    };
    Setup::new(scene, &overrides).unwrap()
}

/// One test: the counter is global, and tests running side by side would count each other.
#[test]
fn the_time_loop_does_not_allocate() {
    plain_steps();
    contact_steps();
    failure_steps();
}

fn failure_steps() {
    let scene = Scene::from_file(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/tension_bar.json"
    )))
    .unwrap();
    for evaluator in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
        let p = setup(&scene, evaluator);
        // The bar yields from about step 800 and cracks through by step 2500.
        assert_eq!(allocations(&p, 1000, 1500), 0, "{}", evaluator.name());
    }
    // The same bar under local damping instead of mass-proportional, its unbalanced-force
    // ratio measured at every check (a threshold it does not reach).
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/tension_bar.json"
    ))
    .unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["damping"] = serde_json::json!(0);
    json["local_damping"] = serde_json::json!(0.8);
    json["time"]["stop_ratio"] = serde_json::json!(1e-12);
    let p = setup(
        &Scene::from_json_in(
            &json.to_string(),
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
        )
        .unwrap(),
        EvaluatorKind::ElementWise,
    );
    assert_eq!(allocations(&p, 1000, 1500), 0, "local damping");
    // The same bar pulled by a traction, no clamp moving: its steps are fused, the failing
    // interfaces return-mapped in the sweep while it cracks.
    json["damping"] = serde_json::json!(2000);
    json["local_damping"] = serde_json::Value::Null;
    json["time"]["stop_ratio"] = serde_json::Value::Null;
    json["bodies"][0]["supports"] = serde_json::json!([{"kind": "clamp", "edge": "left"}]);
    json["bodies"][0]["loads"] =
        serde_json::json!([{"kind": "traction", "edge": "right", "value": [4e6, 0]}]);
    for evaluator in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
        let p = setup(
            &Scene::from_json_in(
                &json.to_string(),
                std::path::Path::new(env!("CARGO_MANIFEST_DIR")),
            )
            .unwrap(),
            evaluator,
        );
        assert!(p.evaluator.fused().is_some() && p.model.prescribed.is_empty());
        assert_eq!(
            allocations(&p, 1000, 1500),
            0,
            "fused, {}",
            evaluator.name()
        );
    }
}

fn plain_steps() {
    // 4800 elements: more than one parallel chunk, so rayon's loops are exercised too.
    for (formulation, evaluator) in [
        ("rigid", EvaluatorKind::Assembled),
        ("rigid", EvaluatorKind::ElementWise),
        ("hybrid", EvaluatorKind::ElementWise),
        ("rigid-poisson", EvaluatorKind::Assembled),
        ("rigid-poisson", EvaluatorKind::ElementWise),
    ] {
        let f = match formulation {
            "hybrid" => r#"{"kind": "hybrid", "penalty": 10}"#.to_string(),
            kind => format!(r#"{{"kind": "{kind}"}}"#),
        };
        let json = format!(
            r#"{{"name": "a", "thickness": 1.0, "formulation": {f}, "gravity": [0, -9.81],
                "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
                "bodies": [{{"name": "b", "material": "m", "mesh": {{"kind": "grid", "origin": [0, 0], "size": [2, 1], "cells": [80, 60]}},
                    "supports": [{{"edge": "left", "kind": "ground-spring"}}],
                    "loads": [{{"kind": "traction", "edge": "right", "value": [0, -1e5], "amplitude": [[0, 0], [1e-4, 1]]}}]}}],
                "time": {{"dt_factor": 0.5, "steps": 10}}}}"#
        );
        let scene = Scene::from_json(&json).unwrap_or_else(|e| panic!("{e}"));
        let mut p = setup(&scene, evaluator);
        assert_eq!(
            allocations(&p, 20, 200),
            0,
            "{formulation} / {}",
            evaluator.name()
        );
        // The element-wise sweep that the cells' wave leads, which a mesh this small does not
        // take by itself (`WAVE_FROM`): two blocks, cells on their border.
        if formulation == "rigid-poisson" && evaluator == EvaluatorKind::ElementWise {
            use rbsm::force::evaluator::{ElementWisePoisson, WithPoisson};
            p.evaluator = Box::new(WithPoisson::new(
                &p.model,
                ElementWisePoisson::with_wave(&p.model, true),
            ));
            assert_eq!(allocations(&p, 20, 200), 0, "rigid-poisson led by its wave");
        }
    }
}

fn contact_steps() {
    let scene = Scene::from_file(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/toppling_stack.json"
    )))
    .unwrap();
    let p = Setup::new(&scene, &Overrides::default()).unwrap();
    // The stack is in contact from the start; after the warm-up its buffers have their size.
    assert_eq!(allocations(&p, 2000, 2000), 0);
}

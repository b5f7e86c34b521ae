//! Setup grows linearly with the probes: 10⁵ probes placed by `at` took
//! 11.3 s, each looked for in every element (and each name compared with every other).

use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use rbsm::mesh::geometry::Vec2;
use std::time::Instant;

/// A 100 × 100 grid (10⁴ elements) with 10⁵ probes at seeded random points of it, a tenth of
/// them on the grid lines (shared edges and corners).
#[test]
fn setup_of_many_probes_is_linear() {
    const PROBES: usize = 100_000;
    let mut s: u64 = 7;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let points: Vec<[f64; 2]> = (0..PROBES)
        .map(|k| {
            let (x, y) = (next(), next());
            if k % 10 == 0 {
                [(x * 100.0).round() / 100.0, (y * 100.0).round() / 100.0]
            } else {
                [x, y]
            }
        })
        .collect();
    let probes: Vec<serde_json::Value> = points
        .iter()
        .enumerate()
        .map(|(k, at)| serde_json::json!({"name": format!("p{k}"), "at": at, "dof": "u"}))
        .collect();
    let scene = serde_json::json!({
        "name": "many", "thickness": 0.1, "formulation": {"kind": "rigid"},
        "materials": {"m": {"E": 1e9, "nu": 0.2, "rho": 1000}},
        "bodies": [{"name": "b", "material": "m",
            "mesh": {"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [100, 100]},
            "supports": [{"edge": "left", "kind": "ground-spring"}]}],
        "time": {"dt": 1e-6, "steps": 1},
        "output": {"probes": probes}});
    let scene = Scene::from_json(&scene.to_string()).unwrap();
    let start = Instant::now();
    let setup = Setup::new(&scene, &Overrides::default()).unwrap();
    let placed = setup.probes().unwrap();
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(placed.len(), PROBES);
    // The count of point-in-polygon tests, which no load on the machine changes: about one per
    // probe (a probe on a shared edge or corner is tested by the two or four cells there),
    // where the search per probe made up to 10⁴ each.
    let at: Vec<Vec2> = points.iter().map(|&[x, y]| Vec2::new(x, y)).collect();
    let located = setup.model.elements_at(&at);
    assert!(
        located.tests <= 2 * PROBES as u64,
        "{} tests for {PROBES} probes",
        located.tests
    );
    // Each probe in the first element that holds it, as the one-point search finds it.
    for k in (0..PROBES).step_by(97) {
        assert_eq!(
            located.elements[k],
            setup.model.element_at(at[k]),
            "probe {k}"
        );
        assert_eq!(Some(placed[k].element), located.elements[k]);
    }
    eprintln!(
        "setup with {PROBES} probes: {seconds:.3} s, {} tests",
        located.tests
    );
}

/// Setup grows linearly with the ground segments: 3·10⁵ segments, a zigzag polyline, under a
/// block with edge-to-edge contact. Each segment's joints with its neighbours were looked for
/// among all segments (10⁵: 5.2 s; 3·10⁵ would take about 45 s); found by end point, the
/// whole setup takes under a second here. The bound, 15 s, is far from both.
#[test]
fn setup_of_many_ground_segments_is_linear() {
    const SEGMENTS: usize = 300_000;
    let point = |k: usize| {
        [
            k as f64 * 1e-3 - 150.0,
            if k.is_multiple_of(2) { 0.0 } else { 1e-4 },
        ]
    };
    let ground: Vec<serde_json::Value> = (0..SEGMENTS)
        .map(|k| serde_json::json!({"from": point(k), "to": point(k + 1)}))
        .collect();
    let scene = serde_json::json!({
        "name": "long", "thickness": 0.1, "formulation": {"kind": "rigid"},
        "gravity": [0, -9.81],
        "materials": {"m": {"E": 1e9, "nu": 0.2, "rho": 1000}},
        "bodies": [{"name": "b", "material": "m",
            "mesh": {"kind": "grid", "origin": [0, 0.01], "size": [0.1, 0.1], "cells": [2, 2]}}],
        "ground": ground,
        "contact": {"model": "edge-to-edge"},
        "time": {"dt": 1e-6, "steps": 1}});
    let scene = Scene::from_json(&scene.to_string()).unwrap();
    let start = Instant::now();
    let setup = Setup::new(&scene, &Overrides::default()).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(setup.model.ground.len(), SEGMENTS);
    assert!(seconds < 15.0, "setup took {seconds} s");
    eprintln!("setup with {SEGMENTS} ground segments: {seconds:.3} s");
}

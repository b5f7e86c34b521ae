//! The notched beam of `examples/scenes/notched_beam.json` in three-point bending, as the
//! validation runs it (`calibrated`, `size_effect`): a run of its scene (the moving clamp's
//! reaction against the crack mouth's opening) and the same beam as a cohesive continuum
//! (`cohesive.rs`).
#![allow(dead_code)] // each example takes its part

use crate::cohesive;
use rbsm::analysis::calibrate::CalibrationSpec;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use serde_json::{json, Value};

/// One beam run: its load–CMOD curve (mm, N), peak load, CMOD there, broken interfaces, steps
/// and wall time.
pub struct Bent {
    pub curve: Vec<(f64, f64)>,
    pub peak: f64,
    pub cmod_at_peak: f64,
    pub broken: usize,
    pub steps: u64,
    pub wall: f64,
}

/// Runs a notched-beam scene (its moving clamp's reaction and its two `cmod_*` probes).
pub fn bend(scene: &Value) -> Bent {
    use rbsm::analysis::run::{simulate, RunParams, Silent};
    let parsed = Scene::from_json(&scene.to_string()).unwrap();
    let setup = Setup::new(&parsed, &Overrides::default()).unwrap();
    let out = simulate(&setup, &RunParams::default(), None, &mut Silent).unwrap();
    let column = |name: &str| out.series(name).expect("the beam's columns");
    let curve: Vec<(f64, f64)> = column("cmod_right")
        .zip(column("cmod_left"))
        .zip(column("_force"))
        .map(|((right, left), force)| (1e3 * (right - left), force))
        .collect();
    let at_peak = peak_of(&curve);
    Bent {
        peak: out.summary.clamps[0].peak_force,
        cmod_at_peak: at_peak.0,
        broken: out.summary.failure.as_ref().map_or(0, |f| f.broken),
        steps: out.summary.steps,
        wall: out.summary.wall_time_s,
        curve,
    }
}

/// The notched beam's length, depth and notch depth, from its mesh's box and outline.
pub fn dimensions(base: &Value) -> (f64, f64, f64) {
    let mesh = &base["bodies"][0]["mesh"];
    let vertices: Vec<[f64; 2]> =
        serde_json::from_value(mesh["domain"]["vertices"].clone()).unwrap();
    let [length, depth] = [0, 1].map(|k| mesh["size"][k].as_f64().unwrap());
    let notch = vertices
        .iter()
        .map(|v| v[1])
        .filter(|&y| y < depth)
        .fold(0.0, f64::max);
    (length, depth, notch)
}

/// The notched beam of `base` as a continuum with a cohesive crack up its ligament
/// (`cohesive.rs`): its outline, thickness, supports (the ground-spring strips, or strips
/// `support_width` wide at the same places), load, CMOD gauge, and the targets' `E`, `ν`, `f_t`
/// and `g` × `G_F`. Its load–CMOD curve (mm, N) in 400 steps of CMOD `step` (m), on elements
/// `h` square.
pub fn continuum(
    base: &Value,
    spec: &CalibrationSpec,
    g: f64,
    support_width: Option<f64>,
    h: f64,
    step: f64,
) -> Vec<(f64, f64)> {
    let (length, depth, notch) = dimensions(base);
    let body = &base["bodies"][0];
    let span = |k: usize| [0, 1].map(|i| body["supports"][k]["span"][i].as_f64().unwrap());
    let [s0, s1, load] = [span(0), span(1), span(2)];
    let x = |k: usize| base["output"]["probes"][k]["at"][0].as_f64().unwrap();
    let t = spec.targets;
    let beam = cohesive::Beam {
        length,
        span: 0.5 * (s1[0] + s1[1] - s0[0] - s0[1]),
        depth,
        notch,
        thickness: base["thickness"].as_f64().unwrap(),
        e: t.e,
        nu: t.nu,
        f_t: t.tensile_strength,
        g_f: g * t.fracture_energy,
        support_width: support_width.unwrap_or(s0[1] - s0[0]),
        load_width: load[1] - load[0],
        gauge: 0.5 * (x(1) - x(0)),
    };
    let cmods: Vec<f64> = (0..=400).map(|i| step * i as f64).collect();
    let loads = cohesive::load_cmod(&beam, h, &cmods);
    cmods.iter().zip(loads).map(|(c, p)| (1e3 * c, p)).collect()
}

/// The highest load of a load–CMOD curve and the CMOD there.
pub fn peak_of(curve: &[(f64, f64)]) -> (f64, f64) {
    curve.iter().fold(
        (0.0, f64::MIN),
        |a, &(c, p)| if p > a.1 { (c, p) } else { a },
    )
}

/// The area of the notched beam's outline (m²).
pub fn outline_area(scene: &Value) -> f64 {
    let outline: Vec<[f64; 2]> =
        serde_json::from_value(scene["bodies"][0]["mesh"]["domain"]["vertices"].clone()).unwrap();
    0.5 * outline
        .iter()
        .zip(outline.iter().cycle().skip(1))
        .map(|(a, b)| a[0] * b[1] - b[0] * a[1])
        .sum::<f64>()
        .abs()
}

/// The notch's slot width (m): between the outline's two vertices at its tip.
pub fn notch_slot(scene: &Value) -> f64 {
    let (_, _, notch) = dimensions(scene);
    let vertices: Vec<[f64; 2]> =
        serde_json::from_value(scene["bodies"][0]["mesh"]["domain"]["vertices"].clone()).unwrap();
    let tip: Vec<f64> = vertices
        .iter()
        .filter(|v| v[1] == notch)
        .map(|v| v[0])
        .collect();
    (tip[1] - tip[0]).abs()
}

/// The notched-beam scene with its clamp at half the speed, its ramp and its duration doubled:
/// the check a quasi-static speed needs (`docs/scene.md`, *Quasi-static runs*).
pub fn at_half_speed(scene: &Value) -> Value {
    let mut slow = scene.clone();
    let clamp = &mut slow["bodies"][0]["supports"][2];
    clamp["velocity"][1] = json!(0.5 * clamp["velocity"][1].as_f64().unwrap());
    clamp["ramp"] = json!(2.0 * clamp["ramp"].as_f64().unwrap());
    slow["time"]["end"] = json!(2.0 * slow["time"]["end"].as_f64().unwrap());
    slow
}

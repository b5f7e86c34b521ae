//! # One interface pulled apart: the softening law, step by step
//!
//! **Purpose.** Show what a failing interface does, on the smallest model that has one: two
//! rigid squares side by side, the left one clamped, the right one clamped to a support that
//! moves to the right at a constant speed (displacement control, `supports[].velocity`). The
//! one interface between them opens by exactly the support's displacement `d`, and the
//! support's reaction divided by the edge's area is the interface's normal traction `σ`. The
//! example runs the model with the library (`Setup`, the central-difference integrator) and
//! prints the traction–opening curve beside the law in closed form.
//!
//! **Equations** (`paper_notes.md`, item 22; the law is `model::law::Strength`).
//! - Elastic (eq. 11): `σ = k_n δ`, `k_n = E / ((1 − ν²)(h_a + h_b))` (eq. 12).
//! - Tension cut-off `σ ≤ f_t (1 − ξ)`, softening linearly with the plastic opening:
//!   `ξ = δ_p / w_n`, `w_n = 2 G_f / f_t`. With `σ = k_n (δ − δ_p)` on the surface,
//!   `δ_p = (k_n δ − f_t) / (k_n − f_t / w_n)` and `σ = f_t (1 − δ_p / w_n)`.
//! - Broken once `δ_p = w_n`: `σ = 0` in tension. The work of the traction, the area under the
//!   curve, is `G_f` per unit area: `G_f L t` on this edge of length `L`, thickness `t`.
//!
//! **Run.** `cargo run --release --example interface_failure`
//!
//! **Key numbers.** The largest difference between the run's `σ` and the closed form over all
//! 400 steps, relative to `f_t`: round-off (below 1e-9). The fracture work booked when the
//! interface has broken, relative to `G_f L t`: 1 to round-off.

use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::force::failure::InterfaceStatus;
use rbsm::input::scene::Scene;

const F_T: f64 = 3.0e6;
const G_F: f64 = 100.0;

/// Two 0.1 m rigid squares; the right one moves at 1 m/s (a crack of 0.1 mm in 100 µs).
fn scene() -> Scene {
    Scene::from_json(&format!(
        r#"{{"name": "interface_failure", "thickness": 1.0, "formulation": {{"kind": "rigid"}},
        "materials": {{"m": {{"E": 3.0e10, "nu": 0.2, "rho": 2400,
            "interface": {{"kind": "softening", "tensile_strength": {F_T}, "cohesion": 6.0e6,
                "friction_angle": 30, "fracture_energy": {G_F}, "fracture_energy_shear": 1000}}}}}},
        "bodies": [{{"name": "pair", "material": "m",
            "mesh": {{"kind": "grid", "origin": [0, 0], "size": [0.2, 0.1], "cells": [2, 1]}},
            "supports": [{{"kind": "clamp", "edge": "left"}},
                         {{"kind": "clamp", "edge": "right", "velocity": [1.0, 0]}}]}}],
        "time": {{"dt": 2.5e-7, "end": 1e-4}}}}"#
    ))
    .expect("the example's scene is valid")
}

/// The traction of the law in closed form at opening `d`, for normal spring `k`.
fn closed_form(k: f64, d: f64) -> f64 {
    let w_n = 2.0 * G_F / F_T;
    if k * d <= F_T {
        return k * d;
    }
    let plastic = (k * d - F_T) / (k - F_T / w_n);
    (F_T * (1.0 - plastic / w_n)).max(0.0)
}

/// What the run shows.
pub struct Outcome {
    /// `(d, σ run, σ closed form)` at every step (m, Pa, Pa).
    pub curve: Vec<(f64, f64, f64)>,
    /// Largest `|σ run − σ closed form| / f_t`.
    pub error: f64,
    /// Fracture work at the end over `G_f L t`.
    pub energy_ratio: f64,
    /// The interface's status at the end.
    pub status: InterfaceStatus,
}

/// Runs the pair for every step of the scene and compares each step's traction with the
/// closed form.
///
/// # Panics
/// Never: the scene is the example's own, valid, with one interface that can fail, and the
/// run's observer cannot fail.
pub fn compute() -> Outcome {
    let setup = Setup::new(&scene(), &Overrides::default()).expect("the setup builds");
    let face = setup.model.interfaces[0];
    let area = face.length * setup.model.thickness;
    let clamp = &setup.model.prescribed[0];
    let mut cd = setup.integrator(setup.dt);
    let mut curve = Vec::new();
    cd.run(
        setup.steps,
        1,
        |s, _| {
            let d = clamp.displacement(0, s.t);
            curve.push((d, s.reactions[0] / area, closed_form(face.k_n, d)));
            Ok(())
        },
        |_| {},
    )
    .expect("the run has no outputs to fail");
    let plastic = setup.plastic.as_ref().expect("the interface can fail");
    let state = cd.failure().expect("the run has a failure state");
    let [fracture, _] = plastic.dissipated(state);
    Outcome {
        error: curve
            .iter()
            .map(|&(_, run, law)| (run - law).abs() / F_T)
            .fold(0.0, f64::max),
        energy_ratio: fracture / (G_F * area),
        status: plastic.report(state)[0].status,
        curve,
    }
}

fn main() {
    let o = compute();
    println!("opening d (µm)   σ run (MPa)   σ closed form (MPa)");
    for &(d, run, law) in o.curve.iter().step_by(20) {
        println!(
            "{:14.3}   {:11.6}   {:19.6}",
            d * 1e6,
            run * 1e-6,
            law * 1e-6
        );
    }
    println!("largest |σ run − σ closed form| / f_t = {:.3e}", o.error);
    println!(
        "fracture work / (G_f L t) = {:.12}; the interface is {}",
        o.energy_ratio, o.status
    );
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_interface_follows_the_law_and_spends_g_f() {
        let o = super::compute();
        assert!(
            o.error < 1e-9,
            "σ differs from the closed form by {:e} f_t",
            o.error
        );
        assert!(
            (o.energy_ratio - 1.0).abs() < 1e-9,
            "fracture work {} G_f L t",
            o.energy_ratio
        );
        assert_eq!(o.status, super::InterfaceStatus::Broken);
        // The curve rises to f_t and falls to zero: the test covers all three branches.
        let peak = o.curve.iter().map(|c| c.1).fold(0.0, f64::max);
        assert!(peak > 0.99 * super::F_T && o.curve.last().unwrap().1 == 0.0);
    }
}

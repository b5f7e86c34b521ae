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
//! **The facet law** (`model::facet::Facet`, `"kind": "facet"`) on the same pair, the right
//! square moved along three straight paths: pure opening, pure slip and both at once. Along a
//! straight path the effective traction `σ_eff = √(σ² + τ²/α)` (`α = k_s/k_n`) keeps its
//! direction `ω` and follows, in closed form, `σ_eff = σ₀ e^{−σ₀ w / G}` past its peak
//! `σ₀(ω)`, with `w = |δ|_eff − σ_eff / k_n` the effective inelastic opening
//! (`|δ|_eff = √(δ_n² + α δ_s²)`) and `G(ω) = G_t sin² ω + G_s cos² ω`; the work it spends
//! to the end of the path is `G (1 − e^{−σ₀ w_end / G})` per unit area. The example solves the
//! closed form by bisection on `w` at each step's opening and compares the clamp's reaction.
//!
//! **Run.** `cargo run --release --example interface_failure`
//!
//! **Key numbers.** The largest difference between the run's `σ` and the closed form over all
//! 400 steps, relative to `f_t`: round-off (below 1e-9). The fracture work booked when the
//! interface has broken, relative to `G_f L t`: 1 to round-off. For the facet law, on each of
//! the three paths: the largest difference is round-off (below 1e-9 of `σ₀`), and so is the
//! difference of the work from the closed form's (the law books the exact area under its
//! softening curve).

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

/// Runs the pair of `setup` for every step, handing `observe` each step's time and the moving
/// clamp's reaction over the edge's area (Pa); returns the fracture work per unit area of the
/// edge at the end and the interface's status.
fn run_pair(setup: &Setup, mut observe: impl FnMut(f64, f64) + Send) -> (f64, InterfaceStatus) {
    let area = setup.model.interfaces[0].length * setup.model.thickness;
    let mut cd = setup.integrator(setup.dt);
    cd.run(
        setup.steps,
        1,
        |s, _| {
            observe(s.t, s.reactions[0] / area);
            Ok(())
        },
        |_| {},
    )
    .expect("the run has no outputs to fail");
    let plastic = setup.plastic.as_ref().expect("the interface can fail");
    let state = cd.failure().expect("the run has a failure state");
    let [fracture, _] = plastic.dissipated(state);
    (fracture / area, plastic.report(state)[0].status)
}

/// Runs the pair for every step of the scene and compares each step's traction with the
/// closed form.
///
/// # Panics
/// Never: the scene is the example's own, valid, with one interface that can fail, and the
/// run's observer cannot fail.
pub fn compute() -> Outcome {
    let setup = Setup::new(&scene(), &Overrides::default()).expect("the setup builds");
    let k_n = setup.model.interfaces[0].k_n;
    let clamp = &setup.model.prescribed[0];
    let mut curve = Vec::new();
    let (fracture, status) = run_pair(&setup, |t, sigma| {
        let d = clamp.displacement(0, t);
        curve.push((d, sigma, closed_form(k_n, d)));
    });
    Outcome {
        error: curve
            .iter()
            .map(|&(_, run, law)| (run - law).abs() / F_T)
            .fold(0.0, f64::max),
        energy_ratio: fracture / G_F,
        status,
        curve,
    }
}

/// The facet law's parameters: `f_t`, `s`, `G_t`, `G_s` (Pa, Pa, J/m², J/m²).
const FACET: [f64; 4] = [3.0e6, 8.1e6, 100.0, 1000.0];

/// The pair with the facet law, the right square moving at `velocity` (m/s) for 1 ms.
fn facet_scene(velocity: [f64; 2]) -> Scene {
    let [f_t, s, g_t, g_s] = FACET;
    Scene::from_json(&format!(
        r#"{{"name": "facet_path", "thickness": 1.0, "formulation": {{"kind": "rigid"}},
        "materials": {{"m": {{"E": 3.0e10, "nu": 0.2, "rho": 2400,
            "interface": {{"kind": "facet", "tensile_strength": {f_t}, "shear_strength": {s},
                "fracture_energy": {g_t}, "fracture_energy_shear": {g_s},
                "compressive_strength": 3.0e7, "friction": 0.6}}}}}},
        "bodies": [{{"name": "pair", "material": "m",
            "mesh": {{"kind": "grid", "origin": [0, 0], "size": [0.2, 0.1], "cells": [2, 1]}},
            "supports": [{{"kind": "clamp", "edge": "left"}},
                         {{"kind": "clamp", "edge": "right", "velocity": [{}, {}]}}]}}],
        "time": {{"dt": 2.5e-7, "end": 1e-3}}}}"#,
        velocity[0], velocity[1]
    ))
    .expect("the example's scene is valid")
}

/// One straight path of the facet law against its closed form.
pub struct FacetPath {
    /// `ω` of the path (rad).
    pub omega: f64,
    /// `σ₀(ω)` (Pa).
    pub peak: f64,
    /// `G(ω)` (J/m²).
    pub energy: f64,
    /// Largest `|R·v̂/A − closed form| / σ₀` over the steps (`R·v̂` the clamp's reaction along
    /// its velocity, `A` the edge's area).
    pub error: f64,
    /// The fracture work at the end over the closed form's.
    pub energy_ratio: f64,
    /// The interface's status at the end.
    pub status: InterfaceStatus,
}

/// Runs the pair with the facet law along `direction` (a unit vector in `(x, y)`: `x` opens the
/// interface, `y` slides it).
///
/// # Panics
/// Never: the scene is the example's own and valid.
pub fn facet_path(direction: [f64; 2]) -> FacetPath {
    let [_, _, g_t, g_s] = FACET;
    let setup =
        Setup::new(&facet_scene(direction), &Overrides::default()).expect("the setup builds");
    let face = setup.model.interfaces[0];
    let (k_n, alpha) = (face.k_n, face.k_s / face.k_n);
    let law = rbsm::model::facet::Facet {
        f_t: FACET[0],
        s: FACET[1],
        g_t,
        g_s,
        f_c: 3.0e7,
        cap_hardening: 0.0,
        mu_0: 0.6,
        mu_inf: 0.6,
        sigma_n0: 3.0e7,
    };
    // The path's effective length per metre of travel, and the traction's direction.
    let per_m = (direction[0].powi(2) + alpha * direction[1].powi(2)).sqrt();
    let (sin, cos) = (
        direction[0] / per_m,
        alpha.sqrt() * direction[1].abs() / per_m,
    );
    let (s0, g) = (law.sigma_0(sin, cos, alpha), law.energy(sin, cos));
    // `R·v̂ / A = σ_eff (sin ω v̂_n + √α cos ω |v̂_s|)`.
    let along = sin * direction[0] + alpha.sqrt() * cos * direction[1].abs();
    // `σ_eff` at effective opening `r`: elastic to `σ₀`, then the root in `w` of
    // `w + σ₀ e^{−σ₀ w / G} / k_n = r`, by bisection (the left side grows with `w` where the
    // spring is stiffer than the softening, as here).
    let closed = |r: f64| -> (f64, f64) {
        if k_n * r <= s0 {
            return (k_n * r, 0.0);
        }
        let (mut lo, mut hi) = (0.0, r);
        for _ in 0..200 {
            let w = 0.5 * (lo + hi);
            if w + s0 * (-s0 * w / g).exp() / k_n < r {
                lo = w;
            } else {
                hi = w;
            }
        }
        (s0 * (-s0 * lo / g).exp(), lo)
    };
    let clamp = &setup.model.prescribed[0];
    let (mut error, mut w_end) = (0.0f64, 0.0);
    let (fracture, status) = run_pair(&setup, |t, sigma_run| {
        // The direction is a unit vector: the travel is the path's length.
        let (sigma, w) = closed(clamp.travel(t) * per_m);
        error = error.max((sigma_run - sigma * along).abs() / s0);
        w_end = w;
    });
    FacetPath {
        omega: sin.atan2(cos),
        peak: s0,
        energy: g,
        error,
        energy_ratio: fracture / (g * -(-s0 * w_end / g).exp_m1()),
        status,
    }
}

/// The three paths of the facet law: opening, slip, both.
pub const PATHS: [[f64; 2]; 3] = [[1.0, 0.0], [0.0, 1.0], [0.6, 0.8]];

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
    println!("\nThe facet law along straight paths (x opens, y slides):");
    println!("path         ω (°)   σ₀ (MPa)   G (J/m²)   largest |error| / σ₀   work / closed form   status");
    for d in PATHS {
        let p = facet_path(d);
        println!(
            "({:.1}, {:.1})   {:6.2}   {:8.3}   {:8.1}   {:20.3e}   {:18.9}   {}",
            d[0],
            d[1],
            p.omega.to_degrees(),
            p.peak * 1e-6,
            p.energy,
            p.error,
            p.energy_ratio,
            p.status
        );
    }
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

    #[test]
    fn the_facet_law_follows_its_closed_form_on_three_paths() {
        for d in super::PATHS {
            let p = super::facet_path(d);
            assert!(
                p.error < 1e-6,
                "{d:?}: the reaction differs by {:e} σ₀",
                p.error
            );
            assert!(
                (p.energy_ratio - 1.0).abs() < 1e-9,
                "{d:?}: fracture work {} of the closed form",
                p.energy_ratio
            );
            assert_eq!(p.status, super::InterfaceStatus::Broken, "{d:?}");
        }
    }
}

//! # The stability limit of central difference, seen by running
//!
//! **Purpose.** Show the critical time step `Δt_crit = 2/ω_max` by experiment. The cantilever of
//! `examples/scenes/cantilever.json` starts at rest from a random displacement, which excites
//! every mode including the highest. It is stepped undamped and unloaded at 0.9, 0.99 and 1.01
//! `Δt_crit`, by central difference written out in two lines on top of the library's evaluator
//! and mass. Below the limit the elastic energy stays bounded. Above it, the highest mode grows
//! by the same factor at every step. The library's own integrator, run at 1.01 `Δt_crit`, stops
//! at the step where its guard sees the energy grow.
//!
//! **Equations.**
//! - Central difference (`src/step/integrator.rs`) on the free motion of eq. 7, `M Ü + K U = 0`:
//!   `v^{n+½} = v^{n−½} − Δt M⁻¹ K U^n`, then `U^{n+1} = U^n + Δt v^{n+½}`.
//!   For one mode of frequency `ω` this is `U^{n+1} = (2 − ω²Δt²) U^n − U^{n−1}`.
//! - The amplification factors `z` solve `z² − (2 − ω²Δt²) z + 1 = 0`. They stay on the unit
//!   circle while `ωΔt ≤ 2`. Beyond that one of them is real with `|z| > 1`, and the energy of
//!   the mode grows by `z²` per step.
//! - `ω_max` comes from Lanczos on `M^{−½} K M^{−½}`.
//!
//! **Run.** `cargo run --release --example stability_limit`
//!
//! **Key number.** At 1.01 `Δt_crit` the elastic energy grows by `z² = 1.760` per step, as the
//! closed form predicts. The runs at 0.9 and 0.99 stay bounded.

use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::analysis::stability::run_at_fraction;
use rbsm::input::scene::Scene;
use rbsm::step::integrator::RunStatus;

/// What the example prints and the test checks.
struct Outcome {
    omega_max: f64,
    dt_crit: f64,
    /// `(fraction, steps, largest elastic energy / initial)` of each run.
    runs: Vec<(f64, usize, f64)>,
    /// Elastic energy `½ Uᵀ K U` of the run at 1.01 `Δt_crit`, every tenth step (J).
    unstable: Vec<f64>,
    /// Its growth per step over the last 20 steps, where the highest mode dominates.
    measured_growth: f64,
    /// `z²` of the closed form at `ω_max Δt = 2.02`.
    predicted_growth: f64,
    /// The library's integrator at 1.01 `Δt_crit`: the steps it took before its guard stopped it.
    guarded_steps: u64,
}

/// The larger amplification factor of central difference for `ω Δt = w`, squared.
fn energy_growth_per_step(w: f64) -> f64 {
    let a = 2.0 - w * w;
    let z = 0.5 * (a.abs() + (a * a - 4.0).max(0.0).sqrt());
    z * z
}

/// Central difference from rest at `u0`, `steps` steps of `dt`: the elastic energy
/// `½ Uᵀ f_int(U)` at every step.
fn elastic_history(p: &Setup, u0: &[f64], dt: f64, steps: usize) -> Vec<f64> {
    let (mut u, mut v, mut f) = (u0.to_vec(), vec![0.0; u0.len()], vec![0.0; u0.len()]);
    let mut energy = Vec::with_capacity(steps + 1);
    for _ in 0..=steps {
        p.evaluator.internal_force(&u, &mut f);
        energy.push(0.5 * u.iter().zip(&f).map(|(a, b)| a * b).sum::<f64>());
        // No loads and no damping: the net force is f_int, and (c₁, c₂) = (1, 1).
        p.mass.advance(&f, &mut v, &mut u, dt, (1.0, 1.0));
    }
    energy
}

fn compute() -> Outcome {
    let path = format!(
        "{}/examples/scenes/cantilever.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let p = Setup::new(
        &Scene::from_file(path).expect("the bundled scene"),
        &Overrides::default(),
    )
    .expect("it builds");
    assert!(
        p.model.fixed.is_empty(),
        "the loop above does not hold fixed DOFs"
    );
    // A reproducible random start of about 1 µm.
    let u0: Vec<f64> = (0..p.model.n_dofs())
        .map(|k| 1e-6 * (((k as f64 + 1.0) * 12.9898).sin() * 43758.5453).fract())
        .collect();
    let mut runs = Vec::new();
    let mut unstable = Vec::new();
    for (fraction, steps) in [(0.9, 4000), (0.99, 4000), (1.01, 100)] {
        let e = elastic_history(&p, &u0, fraction * p.dt_crit(), steps);
        runs.push((
            fraction,
            steps,
            e.iter().fold(0.0, |m: f64, x| m.max(*x)) / e[0],
        ));
        if fraction > 1.0 {
            unstable = e;
        }
    }
    let n = unstable.len() - 1;
    let measured_growth = (unstable[n] / unstable[n - 20]).powf(1.0 / 20.0);
    let guarded = run_at_fraction(&p, 1.01, 2000);
    Outcome {
        omega_max: p.omega_max(),
        dt_crit: p.dt_crit(),
        runs,
        unstable: unstable.into_iter().step_by(10).collect(),
        measured_growth,
        predicted_growth: energy_growth_per_step(2.02),
        guarded_steps: if guarded.status == RunStatus::Diverged {
            guarded.steps
        } else {
            0
        },
    }
}

fn main() {
    let o = compute();
    println!(
        "cantilever: omega_max = {:.6e} rad/s, dt_crit = 2/omega_max = {:.6e} s",
        o.omega_max, o.dt_crit
    );
    for (fraction, steps, largest) in &o.runs {
        println!(
            "  dt = {fraction:.2} dt_crit, {steps} steps: largest elastic energy = \
            {largest:.3e} x the initial"
        );
    }
    println!("elastic energy of the run at 1.01 dt_crit, every tenth step (J):");
    for (k, e) in o.unstable.iter().enumerate() {
        println!("  step {:>3}: {e:.6e}", 10 * k);
    }
    println!(
        "energy growth per step at 1.01 dt_crit: measured {:.4}, closed form z^2 = {:.4} \
        (z: the larger root of z^2 - (2 - w^2 dt^2) z + 1 = 0, at w_max dt = 2.02)",
        o.measured_growth, o.predicted_growth
    );
    println!(
        "the library's integrator at 1.01 dt_crit stops after {} steps: its guard saw the \
        energy grow",
        o.guarded_steps
    );
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_limit_is_where_the_closed_form_puts_it() {
        let o = super::compute();
        // Stable runs from rest keep their elastic energy below the bound of a mode stepped at
        // f Δt_crit, 1/(1 − f²) times its energy; the unstable one has grown by orders of
        // magnitude.
        assert!(
            o.runs[0].2 < 1.0 / (1.0 - 0.81) && o.runs[1].2 < 1.0 / (1.0 - 0.98),
            "{:?}",
            o.runs
        );
        assert!(o.runs[2].2 > 1e10, "{:?}", o.runs);
        assert!((o.predicted_growth - 1.7600).abs() < 1e-3);
        assert!(
            (o.measured_growth / o.predicted_growth - 1.0).abs() < 1e-3,
            "measured {} predicted {}",
            o.measured_growth,
            o.predicted_growth
        );
        assert!(o.guarded_steps > 0 && o.guarded_steps < 2000);
    }
}

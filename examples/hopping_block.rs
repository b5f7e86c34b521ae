//! # The hopping block: one bounce against its closed form (paper §4)
//!
//! **Purpose.** Follow the paper's brick, 210 mm × 60 mm and one rigid element, dropped flat from
//! 1 m onto rigid ground with edge-to-edge contact. Measure its first bounce (when it lands, how
//! long the contact lasts, how fast it leaves, how high it climbs) and compare each figure with
//! the theory of a mass on a spring.
//!
//! **Equations.**
//! - Free fall: impact at `√(2H/g)` with speed `√(2gH)`.
//! - The contact is the interface spring of eq. 12 against the ground, where `h_b = 0`:
//!   `K_c = k_n B t` with `k_n = E / ((1 − ν²) D/2)`. This is the edge-to-edge contact of
//!   eqs. 17–20 once the face is closed.
//! - On the spring the block oscillates about the static penetration `δ_s = mg/K_c` at
//!   `ω = √(K_c/m)`. The contact lasts `(π + 2 arcsin(δ_s/A))/ω`, with
//!   `A = √(δ_s² + (v₀/ω)²)`.
//! - No energy is lost, so the block leaves at its impact speed and climbs back to `H`.
//!
//! **Run.** `cargo run --release --example hopping_block` (about 1 s).
//!
//! **Key number.** The contact time over the theory's: 1.000, to better than 1 %. The rebound
//! speed and the apex match the theory to the same order. `examples/scenes/hopping_block.json`
//! runs ten bounces, and validation §8.1 shows how the flat landing turns into rocking.

#[path = "../validation/fixtures/brick.rs"]
mod brick;
use rbsm::analysis::hopping::{centre_velocity, lowest_point, Bounce, Tracker};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;

/// Drop height (m) and time step (s): 1 µs resolves the contact, about 80 µs, in 80 steps.
const HEIGHT: f64 = 1.0;
const DT: f64 = 1e-6;

/// What the example prints and the test checks.
struct Outcome {
    theory: rbsm::analysis::hopping::Theory,
    bounce: Bounce,
    steps: u64,
}

fn compute() -> Outcome {
    let scene = Scene::from_json(&brick::scene(
        [1, 1],
        "edge-to-edge",
        None,
        0.0,
        HEIGHT,
        0.0,
    ))
    .expect("the brick scene");
    let p = Setup::new(
        &scene,
        &Overrides {
            dt: Some(DT),
            ..Default::default()
        },
    )
    .expect("it builds");
    let theory = brick::theory(HEIGHT);
    // Fall, contact and climb back: the apex comes one period (impact to impact) after the
    // start; run a little beyond it.
    let steps = ((theory.period() + 0.05) / DT).ceil() as u64;
    let mut cd = p.integrator(DT);
    let mut tracker = Tracker::default();
    cd.run(
        steps,
        1,
        |s, _| {
            tracker.push(
                s.t,
                lowest_point(&p.model, s.u),
                centre_velocity(&p.model, s.v).y,
            );
            Ok(())
        },
        |_| {},
    )
    .expect("the observer cannot fail");
    Outcome {
        theory,
        bounce: tracker.bounces[0],
        steps: cd.step,
    }
}

fn main() {
    let o = compute();
    let (th, b) = (&o.theory, &o.bounce);
    println!(
        "brick of {:.3} kg on K_c = {:.4e} N/m, dropped from {HEIGHT} m; {} steps of {DT:e} s",
        th.mass, th.stiffness, o.steps
    );
    println!("                     measured        theory          ratio");
    println!(
        "impact time (s)      {:<15.8} {:<15.8} {:.6}",
        b.impact,
        th.impact_time(),
        b.impact / th.impact_time()
    );
    println!(
        "impact speed (m/s)   {:<15.8} {:<15.8} {:.6}",
        b.impact_speed,
        th.impact_speed(),
        b.impact_speed / th.impact_speed()
    );
    println!(
        "contact time (us)    {:<15.4} {:<15.4} {:.4}",
        1e6 * (b.release - b.impact),
        1e6 * th.contact_time(),
        (b.release - b.impact) / th.contact_time()
    );
    println!(
        "rebound speed (m/s)  {:<15.8} {:<15.8} {:.6}",
        b.rebound_speed,
        th.impact_speed(),
        b.rebound_speed / th.impact_speed()
    );
    println!(
        "apex (m)             {:<15.8} {:<15.8} {:.6}",
        b.apex,
        HEIGHT,
        b.apex / HEIGHT
    );
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_first_bounce_follows_the_spring_theory() {
        let o = super::compute();
        let (th, b) = (&o.theory, &o.bounce);
        assert!(
            (b.impact / th.impact_time() - 1.0).abs() < 1e-5,
            "impact at {}",
            b.impact
        );
        assert!(
            ((b.release - b.impact) / th.contact_time() - 1.0).abs() < 0.01,
            "contact {} s",
            b.release - b.impact
        );
        assert!(
            (b.rebound_speed / th.impact_speed() - 1.0).abs() < 0.01,
            "rebound {}",
            b.rebound_speed
        );
        assert!(
            (b.apex / super::HEIGHT - 1.0).abs() < 0.01,
            "apex {}",
            b.apex
        );
    }
}

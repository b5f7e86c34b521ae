//! Section 8 of the validation report: contact (eqs. 17–20), the hopping block of the paper §4.

use super::{plot, Report};
use plotters::prelude::*;
use rbsm::analysis::hopping::{centre_velocity, lowest_point, Theory, Tracker};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use rbsm::step::integrator::Status;
use std::path::Path;

use crate::fixtures::brick::{self, DEPTH as D, E, G, NU, RHO};

fn brick_scene(
    cells: [usize; 2],
    model: &str,
    friction: Option<f64>,
    tilt: f64,
    height: f64,
    slope: f64,
) -> Scene {
    Scene::from_json(&brick::scene(cells, model, friction, tilt, height, slope)).unwrap()
}

/// What one run gives.
struct Run {
    tracker: Tracker,
    /// `(t, lowest point, θ of element 0)` every `sample` seconds.
    trace: Vec<(f64, f64, f64)>,
    drift: f64,
    /// Energy taken from the motion by contact at the end (J), and the largest stored.
    contact_final: f64,
    step_time: f64,
    steps: u64,
    dt: f64,
    final_u: Vec<f64>,
    final_v: Vec<f64>,
    pairs: (f64, usize, f64, f64),
}

fn run(scene: &Scene, dt: Option<f64>, end: f64, sample: f64) -> Run {
    let probe = Setup::new(
        scene,
        &Overrides {
            dt,
            ..Default::default()
        },
    )
    .unwrap();
    let dt = probe.dt;
    let steps = (end / dt).ceil() as u64;
    let p = probe;
    let mut cd = p.integrator(dt);
    let mut tracker = Tracker::default();
    let mut trace = Vec::new();
    let every = ((sample / dt).round() as u64).max(1);
    let mut contact_final = 0.0;
    let clock = std::time::Instant::now();
    let status = cd
        .run(
            steps,
            1,
            |s, e| {
                let low = lowest_point(&p.model, s.u);
                tracker.push(s.t, low, centre_velocity(&p.model, s.v).y);
                if s.step % every == 0 {
                    trace.push((s.t, low, s.u[2]));
                }
                contact_final = e.contact;
                Ok(())
            },
            |_| {},
        )
        .unwrap();
    assert_eq!(status, Status::Ok, "contact run diverged");
    let step_time = clock.elapsed().as_secs_f64();
    let c = cd.contact.as_ref().unwrap();
    let st = c.stats;
    Run {
        tracker,
        trace,
        drift: cd.max_relative_drift(),
        contact_final,
        step_time,
        steps,
        dt,
        final_u: cd.u.clone(),
        final_v: cd.velocity().to_vec(),
        pairs: (
            st.pairs as f64 / st.steps as f64,
            st.max_pairs,
            st.tests as f64 / st.steps as f64,
            st.time_s,
        ),
    }
}

/// A linear plot of several series, with an optional dashed reference.
fn plot_lines(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(&str, Vec<(f64, f64)>)],
) {
    let root = SVGBackend::new(path, (760, 440)).into_drawing_area();
    root.fill(&WHITE).unwrap();
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.1.iter().copied()).collect();
    let (x0, x1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (y0, y1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    let pad = 0.05 * (y1 - y0).max(1e-12);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0 - pad..y1 + pad)
        .unwrap();
    chart
        .configure_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .draw()
        .unwrap();
    for (i, (name, pts)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(
                pts.clone(),
                color.stroke_width(if i == 0 { 3 } else { 1 }),
            ))
            .unwrap()
            .label(*name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .unwrap();
    root.present().unwrap();
}

/// The theory's height of the lower face over time: free flight between contacts of the
/// theoretical duration (the face below 0 during contact is drawn at 0).
fn theory_curve(th: &Theory, end: f64, n: usize) -> Vec<(f64, f64)> {
    (0..=n)
        .map(|i| {
            let t = end * i as f64 / n as f64;
            let ti = th.impact_time();
            let y = if t < ti {
                th.height - 0.5 * G * t * t
            } else {
                let tau = (t - ti) % th.period();
                let flight = tau - th.contact_time();
                if flight < 0.0 {
                    0.0
                } else {
                    th.impact_speed() * flight - 0.5 * G * flight * flight
                }
            };
            (t, y)
        })
        .collect()
}

pub fn contact(r: &mut Report) {
    r.line("## 8. Contact: the hopping block (paper §4) and multi-body contact\n");
    r.line("The paper's brick (210 mm × 60 mm, t = 0.1 m, E = 5127 N/mm², ν = 0.112, ρ = 1850 kg/m³, g = 9.80665 m/s²) \
            dropped flat with its lower face H above rigid ground, no energy loss (no friction limit; the landing is \
            flat so no tangential force arises). A single rigid element lands on a contact spring \
            `K_c = k_n B t`, `k_n = E'/(D/2)` (eq. 12 with `h_b = 0`). Figures are measured from each step: the lowest \
            point's crossings of the ground (interpolated), the centre-of-mass velocity, the highest point of each flight. \
            Reproduce: `cargo run --release --example validate`.\n");

    // 8.1 Ten bounces from 1 m, single rigid element.
    let h = 1.0;
    let th = brick::theory(h);
    let end = 10.0 * th.period() + 0.2;
    r.line(&format!(
        "### 8.1 Ten bounces from H = {h} m, one rigid element, Δt = 1 µs\n\nTheory: impact at √(2H/g) = {:.6} s with \
         {:.6} m/s; ω = √(K_c/m) = {:.1} rad/s; contact π/ω = {:.3} µs without gravity, {:.3} µs with it; apex back at H.\n",
        th.impact_time(),
        th.impact_speed(),
        th.omega(),
        1e6 * th.contact_time_without_gravity(),
        1e6 * th.contact_time()
    ));
    r.line("The flat landing is an unstable state of the bouncing block: a tilt θ makes one corner land first, the \
            contact turns the block at a rate of order θ ω, and the flight of about 0.9 s turns that into a tilt \
            thousands of times larger. The tilt seeded by round-off (about 1e-15 rad after the first contact, where the \
            moments of the two corners cancel only to round-off) grows by the factor measured below each bounce, until \
            the block lands on a corner and tumbles. The theory of a flat landing therefore holds for the first bounces \
            only; they are checked, and the growth is shown as measured (with μ = 0 it is the same, so it is not \
            the tangential springs). The ground is 4 m long: the point-contact brick tumbles off its end at about \
            7 s (its centroid at x = −3.7 m as it falls), hence its height's drop in the figure.\n");
    r.line(
        "| model | bounce | impact time err. | contact time / theory | rebound / impact speed \
        | apex err. | max |θ| before the next impact (rad) |",
    );
    r.line("|---|---|---|---|---|---|---|");
    let mut traces = vec![("theory", theory_curve(&th, end, 4000))];
    for model in ["edge-to-edge", "point"] {
        let o = run(
            &brick_scene([1, 1], model, None, 0.0, h, 0.0),
            Some(1e-6),
            end,
            1e-3,
        );
        let b = &o.tracker.bounces;
        let key = model.replace('-', "_");
        let tilt = |i: usize| {
            let (t0, t1) = (b[i].impact, b.get(i + 1).map_or(f64::MAX, |n| n.impact));
            o.trace
                .iter()
                .filter(|p| p.0 >= t0 && p.0 < t1)
                .map(|p| p.2.abs())
                .fold(0.0, f64::max)
        };
        for i in 0..b.len().min(10) {
            let expected_impact = th.impact_time() + i as f64 * th.period();
            r.line(&format!(
                "| {model} | {} | {:.2e} | {:.5} | {:.6} | {:+.2e} | {:.1e} |",
                i + 1,
                (b[i].impact - expected_impact).abs() / expected_impact,
                (b[i].release - b[i].impact) / th.contact_time(),
                b[i].rebound_speed / b[i].impact_speed,
                (b[i].apex - h) / h,
                tilt(i)
            ));
        }
        let first = 3;
        let worst = |f: &dyn Fn(usize) -> f64| (0..first).map(f).fold(0.0, f64::max);
        r.bound(
            &format!("8.1 {key} impact time rel. error"),
            (b[0].impact - th.impact_time()).abs() / th.impact_time(),
            1e-5,
        );
        r.bound(
            &format!("8.1 {key} contact time / theory - 1, bounces 1-3"),
            worst(&|i| ((b[i].release - b[i].impact) / th.contact_time() - 1.0).abs()),
            0.01,
        );
        r.bound(
            &format!("8.1 {key} rebound / impact speed - 1, bounces 1-3"),
            worst(&|i| (b[i].rebound_speed / b[i].impact_speed - 1.0).abs()),
            1e-3,
        );
        r.bound(
            &format!("8.1 {key} apex rel. error, bounces 1-3"),
            worst(&|i| ((b[i].apex - h) / h).abs()),
            5e-3,
        );
        r.bound(&format!("8.1 {key} tilt after bounce 1"), tilt(0), 1e-9);
        r.figure(
            &format!("8.1 {key} tilt growth per bounce (2 to 3)"),
            tilt(2) / tilt(1),
            0.5,
        );
        r.bound(&format!("8.1 {key} energy drift"), o.drift, 5e-3);
        r.csv(
            &format!("hopping_{key}.csv"),
            "t,lowest_point,theta",
            &o.trace
                .iter()
                .map(|p| vec![p.0, p.1, p.2])
                .collect::<Vec<_>>(),
        );
        traces.push((
            if model == "point" {
                "point"
            } else {
                "edge-to-edge"
            },
            o.trace.iter().map(|p| (p.0, p.1)).collect(),
        ));
    }
    plot_lines(
        &r.dir.join("hopping_block.svg"),
        "Hopping block: height of the lower face, H = 1 m",
        "t (s)",
        "height (m)",
        &traces,
    );
    r.line("\n![hopping block](hopping_block.svg)\n");

    // 8.2 Convergence of the apex error with Δt.
    r.line("### 8.2 Apex error against Δt (one bounce from 0.2 m, one rigid element)\n");
    r.line("| Δt (s) | edge-to-edge apex err. | point apex err. | steps per contact |");
    r.line("|---|---|---|---|");
    let h2 = 0.2;
    let th2 = brick::theory(h2);
    let mut series: Vec<(&str, Vec<(f64, f64)>)> =
        vec![("edge-to-edge", vec![]), ("point", vec![])];
    for dt in [8e-6, 4e-6, 2e-6, 1e-6, 5e-7] {
        let mut row = format!("| {dt:.0e} |");
        for (k, model) in ["edge-to-edge", "point"].iter().enumerate() {
            let o = run(
                &brick_scene([1, 1], model, None, 0.0, h2, 0.0),
                Some(dt),
                1.3 * th2.period(),
                1.0,
            );
            let err = ((o.tracker.bounces[0].apex - h2) / h2).abs();
            series[k].1.push((dt, err));
            row.push_str(&format!(" {err:.3e} |"));
        }
        row.push_str(&format!(" {:.0} |", th2.contact_time() / dt));
        r.line(&row);
    }
    let order =
        |s: &Vec<(f64, f64)>| (s[0].1 / s[s.len() - 1].1).ln() / (s[0].0 / s[s.len() - 1].0).ln();
    r.line(&format!(
        "\nObserved order between 8 µs and 0.5 µs: edge-to-edge {:.2}, point {:.2} (both models give the same flat-landing \
         spring, so the same figures).\n",
        order(&series[0].1),
        order(&series[1].1)
    ));
    r.bound(
        "8.2 apex error order (edge-to-edge) >= 1",
        1.0 / order(&series[0].1),
        1.0,
    );
    plot(
        &r.dir.join("hopping_apex_dt.svg"),
        "Apex error against Δt",
        "Δt (s)",
        "|apex − H| / H",
        &series,
    );
    r.line("![apex error](hopping_apex_dt.svg)\n");

    // 8.3 Meshed block.
    r.line(
        "### 8.3 The block as 21 × 6 rigid elements (two bounces from 0.2 m, Δt = 0.5 Δt_crit)\n",
    );
    r.line("The meshed block is an elastic body: the impact excites its internal vibration, so part of the energy stays in \
            the body and the apex is lower than H; the contact time is governed by the elastic wave in the block \
            (2D/c' = 2 · 0.06 m / √(E'/ρ) for a bar) rather than the spring of one rigid element.\n");
    r.line(
        "| model | contact time (µs) | 2D/c' (µs) | rebound / impact speed | apex err. bounce \
        1, 2 | energy drift | contact pairs (mean, max) |",
    );
    r.line("|---|---|---|---|---|---|---|");
    r.timing(
        "\n## 8.3 The block as 21 × 6 rigid elements\n\n| model | contact share of the step \
        time | wall (s) |\n|---|---|---|",
    );
    let c_bar = (E / (1.0 - NU * NU) / RHO).sqrt();
    for model in ["edge-to-edge", "point"] {
        let o = run(
            &brick_scene([21, 6], model, None, 0.0, h2, 0.0),
            None,
            2.0 * th2.period() + 0.05,
            1e-3,
        );
        let b = &o.tracker.bounces;
        let apex = |i: usize| b.get(i).map_or(f64::NAN, |x| (x.apex - h2) / h2);
        r.line(&format!(
            "| {model} | {:.2} | {:.2} | {:.4} | {:+.2e}, {:+.2e} | {:.2e} | {:.2}, {} |",
            1e6 * (b[0].release - b[0].impact),
            1e6 * 2.0 * D / c_bar,
            b[0].rebound_speed / b[0].impact_speed,
            apex(0),
            apex(1),
            o.drift,
            o.pairs.0,
            o.pairs.1,
        ));
        r.timing(&format!(
            "| {model} | {:.0} % | {:.1} |",
            100.0 * o.pairs.3 / o.step_time,
            o.step_time
        ));
        let key = model.replace('-', "_");
        r.bound(&format!("8.3 {key} meshed energy drift"), o.drift, 0.01);
        r.figure(&format!("8.3 {key} meshed apex rel. error"), apex(0), 0.05);
    }

    // 8.4 Tilted landing.
    r.line("\n### 8.4 The brick tilted by 5° (one rigid element, from 0.2 m, Δt = 1 µs, 0.6 s)\n");
    r.line("The lower corner lands first. Edge-to-edge contact spreads the traction over the penetrating part of the two \
            edges at that corner, point contact puts one spring `k_n ℓ_trib` on the corner; ℓ_trib counts the edges that \
            face the ground. Frictionless (μ = 0) contact keeps the energy; without a slip limit the tangential springs \
            still hold energy when the normal gap opens, and that energy leaves the motion (it is booked as contact \
            energy, so the energy balance still closes).\n");
    r.line(
        "| model | friction | apex 1 of the centroid over its start (m) | θ at 0.6 s (rad) | \
        spin at 0.6 s (rad/s) | energy taken by contact (J) | energy drift |",
    );
    r.line("|---|---|---|---|---|---|---|");
    let mut tilt_traces = Vec::new();
    for friction in [Some(0.0), None] {
        for model in ["edge-to-edge", "point"] {
            let o = run(
                &brick_scene([1, 1], model, friction, 5.0, h2, 0.0),
                Some(1e-6),
                0.6,
                1e-3,
            );
            let apex = o.tracker.bounces.first().map_or(f64::NAN, |b| b.apex);
            r.line(&format!(
                "| {model} | {} | {apex:.5} | {:.4} | {:.4} | {:.4} | {:.1e} |",
                if friction.is_some() {
                    "μ = 0"
                } else {
                    "none (stick)"
                },
                o.final_u[2],
                o.final_v[2],
                o.contact_final,
                o.drift
            ));
            let key = format!(
                "{}_{}",
                model.replace('-', "_"),
                if friction.is_some() { "mu0" } else { "stick" }
            );
            r.bound(&format!("8.4 {key} energy drift"), o.drift, 2e-3);
            r.figure(&format!("8.4 {key} spin at 0.6 s"), o.final_v[2], 0.05);
            if friction.is_some() {
                tilt_traces.push((
                    if model == "point" {
                        "point, θ"
                    } else {
                        "edge-to-edge, θ"
                    },
                    o.trace.iter().map(|p| (p.0, p.2)).collect(),
                ));
            }
        }
    }
    r.line("");
    plot_lines(
        &r.dir.join("tilted_block_rotation.svg"),
        "Tilted brick (5°, μ = 0): rotation of the brick",
        "t (s)",
        "θ (rad)",
        &tilt_traces,
    );
    r.line("![tilted block](tilted_block_rotation.svg)\n");

    // 8.5 Incline and rest.
    r.line(
        "### 8.5 Friction on a 20° incline, and a block at rest (one rigid element, Δt = 1 µs)\n",
    );
    r.line("The brick is placed on the ground line at its static penetration `m g cos α / K_c` (contacts that start \
            inside are caught at the first step). Acceleration measured down the slope from the velocities at 0.05 s \
            and 0.1 s, against `a = g (sin α − μ cos α)` (and 0 when μ ≥ tan α).\n");
    r.line("| model | μ | a measured (m/s²) | a Coulomb (m/s²) | rel. error |");
    r.line("|---|---|---|---|---|");
    let alpha = 20f64.to_radians();
    let depth = |cos: f64| brick::theory(0.0).mass * G * cos / brick::theory(0.0).stiffness;
    for model in ["edge-to-edge", "point"] {
        for mu in [0.2, 0.5] {
            let scene = brick_scene([1, 1], model, Some(mu), 0.0, -depth(alpha.cos()), 20.0);
            let speed = |end: f64| {
                let o = run(&scene, Some(1e-6), end, 1.0);
                -(o.final_v[0] * alpha.cos() + o.final_v[1] * alpha.sin())
            };
            let a = (speed(0.1) - speed(0.05)) / 0.05;
            let expected = (G * (alpha.sin() - mu * alpha.cos())).max(0.0);
            let err = if expected > 0.0 {
                (a - expected).abs() / expected
            } else {
                a.abs()
            };
            r.line(&format!(
                "| {model} | {mu} | {a:.5} | {expected:.5} | {err:.1e}{} |",
                if expected > 0.0 { "" } else { " (abs.)" }
            ));
            r.bound(
                &format!("8.5 {} incline mu {mu} error", model.replace('-', "_")),
                err,
                if expected > 0.0 { 0.01 } else { 1e-3 },
            );
        }
    }
    r.line(
        "\n| model | steps at rest | static penetration (m) | max |v| at the end (m/s) | max \
        |u| at the end (m) |",
    );
    r.line("|---|---|---|---|---|");
    for model in ["edge-to-edge", "point"] {
        let o = run(
            &brick_scene([1, 1], model, None, 0.0, -depth(1.0), 0.0),
            Some(1e-6),
            0.1,
            1.0,
        );
        let v = o.final_v[..3].iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let u = o.final_u[..3].iter().fold(0.0f64, |a, x| a.max(x.abs()));
        r.line(&format!(
            "| {model} | {} | {:.3e} | {v:.1e} | {u:.1e} |",
            o.steps,
            depth(1.0)
        ));
        r.bound(
            &format!("8.5 {} resting block max |v|", model.replace('-', "_")),
            v,
            1e-9,
        );
    }

    // 8.6 Toppling stack.
    r.line("\n### 8.6 A toppling stack of four bricks (`examples/scenes/toppling_stack.json`)\n");
    let scene = Scene::from_json(include_str!("../examples/scenes/toppling_stack.json")).unwrap();
    r.line(
        "| model | steps | Δt (s) | contact pairs per step (mean, max) | narrow-phase tests \
        per step | all vertex–edge pairs | energy drift |",
    );
    r.line("|---|---|---|---|---|---|---|");
    r.timing(
        "\n## 8.6 A toppling stack of four bricks\n\n| model | contact share of step time | \
        µs per step |\n|---|---|---|",
    );
    let mut stack_traces = Vec::new();
    for model in ["edge-to-edge", "point"] {
        let json = include_str!("../examples/scenes/toppling_stack.json")
            .replace("\"edge-to-edge\"", &format!("\"{model}\""));
        let sc = Scene::from_json(&json).unwrap();
        let o = run(&sc, None, 1.5, 2e-3);
        let p = Setup::new(&scene, &Overrides::default()).unwrap();
        let edges: usize = p.model.bodies.iter().map(|b| b.mesh.boundary.len()).sum();
        let all = edges * (edges - edges / p.model.bodies.len() + p.model.ground.len());
        r.line(&format!(
            "| {model} | {} | {:.2e} | {:.2}, {} | {:.1} | {all} | {:.1e} |",
            o.steps, o.dt, o.pairs.0, o.pairs.1, o.pairs.2, o.drift
        ));
        r.timing(&format!(
            "| {model} | {:.0} % | {:.2} |",
            100.0 * o.pairs.3 / o.step_time,
            1e6 * o.step_time / o.steps as f64
        ));
        r.bound(
            &format!("8.6 {} stack energy drift", model.replace('-', "_")),
            o.drift,
            0.01,
        );
        stack_traces.push((
            model,
            o.trace.iter().map(|p| (p.0, p.2)).collect::<Vec<_>>(),
        ));
    }
    plot_lines(
        &r.dir.join("toppling_stack.svg"),
        "Toppling stack: rotation of the bottom brick",
        "t (s)",
        "θ (rad)",
        &stack_traces,
    );
    r.line("\n![toppling stack](toppling_stack.svg)\n");

    walls(r);
}

/// A wall's run: histories every `every` steps and the final state.
struct WallRun {
    /// `(t, kinetic, stored contact, contact energy (−W), potential, ground reaction / weight)`.
    history: Vec<[f64; 6]>,
    /// Largest `|E − E₀|` of `total − contact + stored` over the largest energy.
    drift: f64,
    u: Vec<f64>,
    tests_per_body_step: f64,
    model: rbsm::model::Model,
}

fn wall_run(json: &str, every: u64) -> WallRun {
    let scene = Scene::from_json(json).unwrap();
    let p = Setup::new(&scene, &Overrides::default()).unwrap();
    let weight: f64 = p
        .model
        .elements
        .iter()
        .map(|e| e.rho * e.props.area * p.model.thickness)
        .sum::<f64>()
        * G;
    let mut cd = p.integrator(p.dt);
    let (mut history, mut first, mut worst, mut scale) = (Vec::new(), None, 0.0f64, 0.0f64);
    let status = cd
        .run_chunks(p.steps, every, |cd, e| {
            let c = cd.contact.as_ref().unwrap();
            let total = cd.total_with_stored_contact(e);
            let e0 = *first.get_or_insert(total);
            worst = worst.max((total - e0).abs());
            scale = scale.max(e.kinetic + c.stored() + e.potential.abs());
            history.push([
                e.t,
                e.kinetic,
                c.stored(),
                e.contact,
                e.potential,
                c.ground_reaction().y / weight,
            ]);
        })
        .unwrap();
    assert_eq!(status, Status::Ok, "wall run diverged");
    let c = cd.contact.as_ref().unwrap();
    let tests_per_body_step =
        c.stats.tests as f64 / c.stats.steps as f64 / p.model.bodies.len() as f64;
    WallRun {
        history,
        drift: worst / scale,
        u: cd.u.clone(),
        tests_per_body_step,
        model: p.model,
    }
}

/// The bricks at their final places (finite rotation), shaded by how far each settled.
fn draw_wall(path: &Path, title: &str, w: &WallRun) {
    let m = &w.model;
    let polygons: Vec<(Vec<(f64, f64)>, f64)> = m
        .bodies
        .iter()
        .map(|b| {
            let e = b.first_element;
            let c = m.elements[e].props.centroid;
            let ue = &w.u[3 * e..3 * e + 3];
            let pts = b.mesh.cell_points(0).into_iter().map(|x| {
                let p = m.formulation.current_position(c, ue, x - c);
                (p.x, p.y)
            });
            (pts.collect(), ue[1])
        })
        .collect();
    let deepest = polygons.iter().map(|p| p.1).fold(0.0f64, f64::min);
    let (x1, y1) = polygons
        .iter()
        .flat_map(|p| p.0.iter())
        .fold((0.0f64, 0.0f64), |a, p| (a.0.max(p.0), a.1.max(p.1)));
    let root = SVGBackend::new(path, (760, 420)).into_drawing_area();
    root.fill(&WHITE).unwrap();
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 16))
        .margin(15)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(-0.1..x1 + 0.1, -0.05..y1 + 0.05)
        .unwrap();
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .disable_mesh()
        .draw()
        .unwrap();
    for (pts, uy) in &polygons {
        let shade = if deepest < 0.0 { uy / deepest } else { 0.0 };
        let color = RGBColor(
            (255.0 * (1.0 - 0.8 * shade)) as u8,
            (200.0 * (1.0 - 0.5 * shade)) as u8,
            (120.0 + 100.0 * shade) as u8,
        );
        chart
            .draw_series(std::iter::once(Polygon::new(pts.clone(), color.filled())))
            .unwrap();
        let mut closed = pts.clone();
        closed.push(pts[0]);
        chart
            .draw_series(std::iter::once(PathElement::new(
                closed,
                BLACK.stroke_width(1),
            )))
            .unwrap();
    }
    chart
        .draw_series(std::iter::once(PathElement::new(
            vec![(-0.1, 0.0), (x1 + 0.1, 0.0)],
            BLACK.stroke_width(3),
        )))
        .unwrap();
    root.present().unwrap();
}

/// 8.7 Walls: the bundled 10 × 10 wall settling with friction in both contact models, and the
/// same wall in half-brick bond without friction or damping for the energy balance.
fn walls(r: &mut Report) {
    let scene = include_str!("../examples/scenes/wall.json");
    r.line("\n### 8.7 A wall of 10 × 10 bricks (`examples/scenes/wall.json`)\n");
    r.line("The paper's bricks (0.2 × 0.1 m, t = 0.1 m), rows shifted by a quarter brick, 1e-5 m apart, fall onto the \
            ground and onto each other under gravity: friction 0.5, mass-proportional damping 1000 1/s, Δt = 0.2 Δt_crit, \
            50 ms. The ground's reaction is the force of the ground segments on the bricks at the last step; at rest it \
            carries the weight (check: within 1e-3). Then the same wall in half-brick bond (the scene that diverged \
            before, paper_notes C10) without friction or damping: `total − contact + stored` (the energy with the \
            contact springs' stored energy in place of the contact work) is kept up to the step's error, which falls \
            as Δt² (checks for edge-to-edge: a fall by at least 8 from 0.2 to 0.05 Δt_crit, and 1e-4 at 0.035 Δt_crit). \
            Point contact is not built on a potential.\n");
    r.line(
        "| model | ground reaction / weight at 50 ms | kinetic energy at 50 ms (J) | contact \
        work taken (J) | narrow-phase tests per body-step | no friction: drift at 0.2 Δt_crit | \
        at 0.05 Δt_crit | at 0.035 Δt_crit |",
    );
    r.line("|---|---|---|---|---|---|---|---|");
    let mut kinetic = Vec::new();
    let mut reaction = Vec::new();
    for model in ["edge-to-edge", "point"] {
        let json = scene.replace(
            "\"model\": \"edge-to-edge\"",
            &format!("\"model\": \"{model}\""),
        );
        let w = wall_run(&json, 50);
        let last = *w.history.last().unwrap();
        let free = |f: f64| {
            let j = json
                .replace("\"friction\": 0.5", "\"friction\": 0.0")
                .replace("\"damping\": 1000.0", "\"damping\": 0.0")
                .replace("\"row_offset\": 0.05", "\"row_offset\": 0.1")
                .replace("\"dt_factor\": 0.2", &format!("\"dt_factor\": {f}"));
            wall_run(&j, 100).drift
        };
        let (coarse, fine, finer) = (free(0.2), free(0.05), free(0.035));
        r.line(&format!(
            "| {model} | {:.6} | {:.2e} | {:.3e} | {:.2} | {coarse:.1e} | {fine:.1e} | \
                {finer:.1e} |",
            last[5], last[1], last[3], w.tests_per_body_step
        ));
        let tag = model.replace('-', "_");
        r.bound(
            &format!("8.7 {tag} wall ground reaction / weight - 1"),
            (last[5] - 1.0).abs(),
            1e-3,
        );
        if model == "edge-to-edge" {
            // Second order would give 16 between 0.2 and 0.05 Δt_crit.
            r.bound(
                "8.7 edge_to_edge frictionless wall: drift(0.05) / drift(0.2) (1/16 at second \
                order)",
                fine / coarse,
                1.0 / 8.0,
            );
            r.bound(
                "8.7 edge_to_edge frictionless wall drift at 0.035 dt_crit",
                finer,
                1e-4,
            );
        }
        r.figure(
            &format!("8.7 {tag} frictionless wall drift at 0.2 dt_crit"),
            coarse,
            0.5,
        );
        kinetic.push((
            model,
            w.history
                .iter()
                .map(|h| (1e3 * h[0], h[1].max(1e-12).log10()))
                .collect::<Vec<_>>(),
        ));
        reaction.push((
            model,
            w.history
                .iter()
                .map(|h| (1e3 * h[0], h[5]))
                .collect::<Vec<_>>(),
        ));
        if model == "edge-to-edge" {
            draw_wall(
                &r.dir.join("wall.svg"),
                "10 × 10 wall after 50 ms (edge-to-edge; darker = settled more)",
                &w,
            );
        }
        let rows: Vec<Vec<f64>> = w.history.iter().map(|h| h.to_vec()).collect();
        r.csv(
            &format!("wall_{tag}.csv"),
            "t,kinetic,stored_contact,contact,potential,reaction_over_weight",
            &rows,
        );
    }
    plot_lines(
        &r.dir.join("wall_kinetic.svg"),
        "10 × 10 wall settling: kinetic energy",
        "t (ms)",
        "log10 kinetic energy (J)",
        &kinetic,
    );
    plot_lines(
        &r.dir.join("wall_reaction.svg"),
        "10 × 10 wall settling: ground reaction / weight",
        "t (ms)",
        "reaction / weight",
        &reaction,
    );
    r.line(
        "\n![wall](wall.svg)\n\n![kinetic \
        energy](wall_kinetic.svg)\n\n![reaction](wall_reaction.svg)\n",
    );
    r.line(
        "Histories: `validation/wall_edge_to_edge.csv`, `validation/wall_point.csv` (t, \
        kinetic, stored contact, contact work, potential, reaction / weight).\n",
    );
}

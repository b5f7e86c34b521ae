//! Hybrid elements that yield (`model::plasticity`, `force::yielding`): the return mapping
//! against its closed forms on one element and against a brute-force closest point, the two
//! evaluators against each other while elements and interfaces yield, the energy balance, the
//! checkpoint, the outputs, the rigid formulation's refusal, and the explicit plateau of a
//! footing against the collapse load of the same model by conic programming.

mod common;

use nalgebra::{Matrix3, Vector3};
use rbsm::analysis::collapse::{self, Points};
use rbsm::analysis::run::{self as run, RunParams, Silent};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::force::yielding::PlasticElements;
use rbsm::input::scene::{EvaluatorKind, Plane, Scene};
use rbsm::model::formulation::elasticity;
use rbsm::model::plasticity::{mohr, ElementStrength};
use serde_json::{json, Value};

/// Cohesion of every test (Pa).
const C: f64 = 1e5;

fn setup(scene: &Value, evaluator: EvaluatorKind) -> Setup {
    let scene = Scene::from_json(&scene.to_string()).expect("valid scene");
    let overrides = Overrides {
        evaluator: Some(evaluator),
        ..Overrides::default()
    };
    Setup::new(&scene, &overrides).expect("setup")
}

/// One hybrid unit square whose elements have `element` as strength, in `plane`.
fn one_element(element: Value, plane: &str) -> Setup {
    let scene = json!({
        "name": "one", "thickness": 0.5, "plane": plane,
        "formulation": {"kind": "hybrid", "penalty": 100},
        "materials": {"m": {"E": 1e8, "nu": 0.3, "rho": 2000, "element": element}},
        "bodies": [{"name": "b", "material": "m",
            "mesh": {"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [1, 1]},
            "supports": [{"kind": "clamp", "edge": "bottom", "dofs": ["u", "v", "theta"]}]}],
        "time": {"dt": 1e-6, "steps": 1}
    });
    setup(&scene, EvaluatorKind::Assembled)
}

/// Drives the one element of `s` through pure shear `γ` in `steps` equal steps; returns, per
/// step, the interior force on its strains divided by `t A` (its stress) and the work
/// dissipated so far.
fn shear(s: &Setup, gamma: f64, steps: usize) -> Vec<(Vector3<f64>, f64)> {
    let el = &s.model.elements[0];
    let volume = s.model.thickness * el.props.area;
    let yielding = PlasticElements::build(&s.model).expect("the element has a strength");
    let mut state = yielding.initial();
    (1..=steps)
        .map(|k| {
            let g = gamma * k as f64 / steps as f64;
            let u = [0.0, 0.0, 0.0, 0.0, 0.0, g];
            // The elastic interior force t A D ε, as the evaluators add it.
            let elastic = el.d * Vector3::new(0.0, 0.0, g) * volume;
            let mut f = [0.0, 0.0, 0.0, elastic[0], elastic[1], elastic[2]];
            yielding.correct(&u, &mut state, &mut f);
            (Vector3::new(f[3], f[4], f[5]) / volume, state.dissipated)
        })
        .collect()
}

/// Pure shear of one element with Tresca's strength (plane strain and plane stress alike): `τ`
/// rises as `μ γ` to `c` and stays there; the flow dissipates `c t A (γ − c/μ)`.
#[test]
fn tresca_in_pure_shear_holds_tau_at_c_and_dissipates_c_times_the_plastic_shear() {
    for plane in ["strain", "stress"] {
        let s = one_element(json!({"kind": "tresca", "cohesion": C}), plane);
        let mu = s.model.elements[0].d[(2, 2)];
        let volume = s.model.thickness * s.model.elements[0].props.area;
        let gamma = 5.0 * C / mu;
        let path = shear(&s, gamma, 10);
        for (k, (sigma, work)) in path.iter().enumerate() {
            let g = gamma * (k + 1) as f64 / 10.0;
            let tau = (mu * g).min(C);
            assert!(
                (sigma[2] - tau).abs() < 1e-9 * C && sigma[0].abs() < 1e-6 && sigma[1].abs() < 1e-6,
                "{plane}, γ = {g:e}: σ = {sigma:?}, τ = {tau:e}"
            );
            let closed = C * volume * (g - C / mu).max(0.0);
            assert!(
                (work - closed).abs() < 1e-9 * C * volume * gamma,
                "{work} vs {closed}"
            );
        }
    }
}

/// Pure shear of one element with Mohr–Coulomb in plane strain: once `τ = c cos φ`, the
/// associated flow dilates and, the strain held, the element is confined:
/// `p = −K sin φ λ`, `τ = c cos φ − p sin φ`, `λ = μ (γ − γ_y)/(μ + K sin² φ)`; the work is
/// `c cos φ t A λ`. The path is linear, so backward Euler is exact at any step.
#[test]
fn mohr_coulomb_in_pure_shear_dilates_and_confines_itself_as_the_closed_form_says() {
    let phi = 30f64.to_radians();
    let s = one_element(
        json!({"kind": "mohr-coulomb", "cohesion": C, "friction_angle": 30}),
        "strain",
    );
    let d = s.model.elements[0].d;
    let (mu, bulk) = (d[(2, 2)], 0.5 * (d[(0, 0)] + d[(0, 1)]));
    let volume = s.model.thickness * s.model.elements[0].props.area;
    let gamma_y = C * phi.cos() / mu;
    let gamma = 6.0 * gamma_y;
    for steps in [1, 7] {
        let (sigma, work) = *shear(&s, gamma, steps).last().unwrap();
        let lambda = mu * (gamma - gamma_y) / (mu + bulk * phi.sin().powi(2));
        let p = -bulk * phi.sin() * lambda;
        let tau = C * phi.cos() - p * phi.sin();
        let (p_num, r_num) = mohr(&sigma);
        assert!(
            (p_num - p).abs() < 1e-9 * C,
            "{steps} steps: p {p_num:e} vs {p:e}"
        );
        assert!(
            (r_num - tau).abs() < 1e-9 * C,
            "{steps} steps: τ {r_num:e} vs {tau:e}"
        );
        let closed = C * phi.cos() * volume * lambda;
        assert!((work - closed).abs() < 1e-9 * closed, "{work} vs {closed}");
    }
}

/// The energy norm `Δσᵀ D⁻¹ Δσ`.
fn energy_distance(d: &Matrix3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let x = a - b;
    x.dot(&(d.try_inverse().unwrap() * x))
}

/// The return mapping is the closest admissible stress in the energy norm: for trial stresses
/// all around, in both planes, with and without friction, no admissible stress of a fine
/// search (over the whole `(σ_x, σ_y, τ)` space near the result) is closer.
#[test]
fn the_return_is_the_closest_admissible_stress_in_the_energy_norm() {
    let mut seed = 12345u64;
    let mut next = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    for plane in [Plane::Strain, Plane::Stress] {
        let d = elasticity(1e8, 0.3, plane);
        for phi in [0.0, 30.0] {
            let st = ElementStrength::new(C, phi, plane);
            for _ in 0..60 {
                let trial = Vector3::new(6.0 * C * next(), 6.0 * C * next(), 3.0 * C * next());
                let sigma = st.return_map(&d, &trial);
                assert!(st.excess(&sigma) <= 1e-9 * C, "{sigma:?} is outside");
                let best = energy_distance(&d, &trial, &sigma);
                // A grid about the result, 0.4c wide, step c/50.
                for i in -10..=10 {
                    for j in -10..=10 {
                        for k in -10..=10 {
                            let h = C / 50.0;
                            let s = sigma + Vector3::new(i as f64 * h, j as f64 * h, k as f64 * h);
                            if st.excess(&s) <= 0.0 {
                                assert!(
                                    energy_distance(&d, &trial, &s) >= best * (1.0 - 1e-9),
                                    "{plane:?} φ = {phi}: {s:?} is closer to {trial:?} than {sigma:?}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }
}

/// A rough footing on hybrid crossed triangles, `n × n/2` cells on a 2 × 1 m layer, elements
/// and interfaces of cohesion `c` (Tresca and Mohr–Coulomb with no tension, `φ = 0`), the
/// clamp pressed at 0.1 m/s for `end` seconds.
fn footing(n: u32, end: f64) -> Value {
    json!({
        "name": "footing", "thickness": 1.0, "plane": "strain",
        "formulation": {"kind": "hybrid", "penalty": 100},
        "local_damping": 0.8,
        "materials": {"clay": {"E": 1.0e8, "nu": 0.3, "rho": 2000,
            "interface": {"kind": "mohr-coulomb", "tensile_strength": 0, "cohesion": C,
                "friction_angle": 0},
            "element": {"kind": "tresca", "cohesion": C}}},
        "bodies": [{"name": "soil", "material": "clay", "mesh": {"kind": "grid", "origin": [0, 0],
            "size": [2.0, 1.0], "cells": [n, n / 2], "cell": "crossed"},
            "supports": [{"kind": "clamp", "edge": "bottom"},
                {"kind": "clamp", "edge": "left", "dofs": ["u"]},
                {"kind": "clamp", "edge": "right", "dofs": ["u"]},
                {"kind": "clamp", "edge": "top", "span": [0.8, 1.2], "velocity": [0, -0.1],
                    "ramp": 0.005}]}],
        "time": {"dt_factor": 0.5, "end": end},
        "output": {"every": 100}
    })
}

/// Runs `s` to its end: the final `U`, the energies of every 100th step, the plastic state.
fn run_through(
    s: &Setup,
) -> (
    Vec<f64>,
    Vec<rbsm::step::integrator::Energy>,
    rbsm::force::yielding::ElementState,
) {
    let mut cd = s.integrator(s.dt);
    let mut rows = Vec::new();
    cd.run(
        s.steps,
        100,
        |_, e| {
            rows.push(*e);
            Ok(())
        },
        |_| {},
    )
    .unwrap();
    (cd.u.clone(), rows, cd.plastic_elements().unwrap().clone())
}

/// While elements and interfaces yield under the footing, the assembled and the element-wise
/// evaluators follow one trajectory to round-off (the return mapping reads only each element's
/// own strains, after either evaluator), and the energy balance closes with the elements'
/// plastic work booked. The damping is mass-proportional here: the local damping's sign of the
/// velocity turns round-off into differences of its own (1e-3 of `U` with elastic elements
/// alike).
#[test]
fn both_evaluators_agree_while_elements_and_interfaces_yield_and_the_energy_balance_closes() {
    let mut scene = footing(10, 0.04);
    scene.as_object_mut().unwrap().remove("local_damping");
    scene["damping"] = json!(300);
    let (ua, rows_a, state_a) = run_through(&setup(&scene, EvaluatorKind::Assembled));
    let (ue, rows_e, state_e) = run_through(&setup(&scene, EvaluatorKind::ElementWise));
    let scale = ua.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = common::max_abs_diff(&ua, &ue);
    assert!(diff <= 1e-9 * scale, "|ΔU| = {diff:e} of {scale:e}");
    let flowed = state_a.strain.iter().filter(|e| **e != [0.0; 3]).count();
    assert!(flowed > 0, "no element yielded");
    assert_eq!(
        flowed,
        state_e.strain.iter().filter(|e| **e != [0.0; 3]).count()
    );
    for rows in [&rows_a, &rows_e] {
        let last = rows.last().unwrap();
        assert!(last.plastic > 0.0 && last.fracture > 0.0, "{last:?}");
        let drift = common::energy_drift(rows);
        assert!(
            drift < 1e-4 * last.external_work,
            "energy balance off by {drift:e} J of {:e} J put in",
            last.external_work
        );
    }
    let (pa, pe) = (
        rows_a.last().unwrap().plastic,
        rows_e.last().unwrap().plastic,
    );
    assert!((pa - pe).abs() <= 1e-9 * pa, "{pa} vs {pe}");
}

/// The footing's explicit quasi-static reaction levels off at the collapse load of the same
/// discrete model that `rbsm limit` finds by conic programming (Tresca cones in the elements,
/// the interfaces' strengths at their Gauss points): the flow is associated (`φ = 0`, the
/// cut-off), so the two are one load. Both lie above Prandtl's `(2 + π) c`.
#[test]
fn the_hybrid_footing_levels_off_at_its_conic_collapse_load() {
    let scene = footing(10, 0.1);
    let s = setup(&scene, EvaluatorKind::Assembled);
    let lp = collapse::analyse(&s, None, Points::Gauss).unwrap();
    assert!(lp.yielding_elements == s.model.elements.len());
    let q_lp = lp.collapse / (0.4 * C);
    let params = RunParams {
        keep_history: true,
        ..RunParams::default()
    };
    let out = run::simulate(&s, &params, None, &mut Silent).unwrap();
    let q_explicit = out.last("_force").expect("the clamp's force column") / (0.4 * C);
    eprintln!("hybrid footing: LP {q_lp:.5} c, explicit {q_explicit:.5} c");
    assert!(
        (q_explicit - q_lp).abs() < 1e-2 * q_lp,
        "LP {q_lp} c, explicit {q_explicit} c"
    );
    assert!(
        q_lp > 2.0 + std::f64::consts::PI,
        "{q_lp} c is below Prandtl's"
    );
}

/// The conic program's mechanism flows normal to the strengths, and its stresses are the ones
/// that dissipate it (Mohr–Coulomb, φ = 30°, plane strain; the footing of the tests above):
/// every element's stress lies within `R + p sin φ ≤ c cos φ`; its plastic strain rate dilates
/// as associated flow says, `ε̇_x + ε̇_y = sin φ |ε̇|` with `|ε̇| = √((ε̇_x − ε̇_y)² + γ̇²)`; where
/// it flows its stress does the dissipation `c cos φ |ε̇|` (complementary slackness); and the
/// interfaces' jumps, which `tractions.csv` computes from the elements' velocities and strain
/// rates through the formulation's own displacement field, open as associated flow says,
/// `opening ≥ tan φ |slip|`. The stresses come from each element's equilibrium and the rates
/// from the cones' multipliers: a sign lost in either fails the power, a scale lost in the rates
/// (against the velocities) the jumps, a wrong pressure coefficient the dilatancy.
#[test]
fn the_conic_mechanism_flows_normal_to_the_strengths() {
    let mut scene = footing(10, 0.1);
    let phi = 30f64.to_radians();
    scene["materials"]["clay"]["interface"]["friction_angle"] = json!(30);
    scene["materials"]["clay"]["element"] =
        json!({"kind": "mohr-coulomb", "cohesion": C, "friction_angle": 30});
    let s = setup(&scene, EvaluatorKind::Assembled);
    let lp = collapse::analyse(&s, None, Points::Gauss).unwrap();
    let (sin, cos) = phi.sin_cos();
    let rate = |e: &[f64; 3]| (e[0] - e[1]).hypot(e[2]);
    let largest = lp.strain_rates.iter().map(rate).fold(0.0, f64::max);
    assert!(largest > 0.0, "the elements do not flow");
    let mut flowing = 0;
    for (sigma, e) in lp.stresses.iter().zip(&lp.strain_rates) {
        let (p, radius) = (
            0.5 * (sigma[0] + sigma[1]),
            (0.5 * (sigma[0] - sigma[1])).hypot(sigma[2]),
        );
        assert!(
            radius + p * sin <= C * cos + 1e-6 * C,
            "σ = {sigma:?} Pa outside the criterion"
        );
        let m = rate(e);
        assert!(
            (e[0] + e[1] - sin * m).abs() <= 1e-5 * largest,
            "ε̇ = {e:?}: not the associated dilatancy"
        );
        if m > 1e-3 * largest {
            flowing += 1;
            let power = sigma[0] * e[0] + sigma[1] * e[1] + sigma[2] * e[2];
            assert!(
                (power - C * cos * m).abs() <= 1e-4 * C * m,
                "σ:ε̇ = {power}, c cos φ |ε̇| = {}",
                C * cos * m
            );
        }
    }
    assert!(flowing > 0, "no element flows");
    let dir = tempfile::tempdir().unwrap();
    collapse::write(dir.path(), &s, &lp).unwrap();
    let csv = std::fs::read_to_string(dir.path().join("tractions.csv")).unwrap();
    let jumps: Vec<[f64; 2]> = csv
        .lines()
        .skip(1)
        .map(|row| {
            let f: Vec<&str> = row.split(',').collect();
            [f[8].parse().unwrap(), f[9].parse().unwrap()]
        })
        .collect();
    let largest_jump = jumps.iter().map(|j| j[0].hypot(j[1])).fold(0.0, f64::max);
    assert!(largest_jump > 0.0, "no interface moves");
    for [opening, slip] in jumps {
        assert!(
            opening >= phi.tan() * slip.abs() - 1e-5 * largest_jump,
            "an interface opens by {opening} while it slips by {slip}"
        );
    }
}

/// A run stopped at its end and resumed from its state (as a checkpoint does) ends with the
/// same bits as one run straight through: the elements' plastic strains are part of the state.
#[test]
fn a_resumed_run_keeps_the_elements_plastic_state() {
    let scene = footing(10, 0.03);
    let s = setup(&scene, EvaluatorKind::Assembled);
    let (straight, _, state) = run_through(&s);
    let half = s.steps / 2;
    let mut first = s.integrator(s.dt);
    first.run(half, half, |_, _| Ok(()), |_| {}).unwrap();
    let saved = first.state();
    let mut second = s.integrator(s.dt);
    second.restore(saved).unwrap();
    second
        .run(s.steps - half, 100, |_, _| Ok(()), |_| {})
        .unwrap();
    assert_eq!(second.u, straight);
    assert_eq!(second.plastic_elements().unwrap(), &state);
}

/// A rigid element has no stress of its own: a strength for it is refused, naming the key.
#[test]
fn a_rigid_formulation_refuses_an_element_strength_by_name() {
    let mut scene = footing(10, 0.01);
    scene["formulation"] = json!({"kind": "rigid"});
    let err = Scene::from_json(&scene.to_string())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("materials.clay.element") && err.contains("hybrid"),
        "{err}"
    );
    let mut scene = footing(10, 0.01);
    scene["materials"]["clay"]["element"] = json!({"kind": "tresca", "cohesion": 0});
    let err = Scene::from_json(&scene.to_string())
        .unwrap_err()
        .to_string();
    assert!(err.contains("materials.clay.element.cohesion"), "{err}");
}

/// A run's outputs carry the plasticity: the history's `plastic` column, and per element in
/// the frames and the final state its plastic strain (and in the frames whether it flows).
#[test]
fn the_outputs_show_the_elements_plastic_strain() {
    let mut scene = footing(10, 0.02);
    scene["output"]["vtk"] = json!(true);
    let s = setup(&scene, EvaluatorKind::Assembled);
    let dir = tempfile::tempdir().unwrap();
    run::run(&s, &RunParams::default(), dir.path(), &mut Silent).unwrap();
    let history = std::fs::read_to_string(dir.path().join("history.csv")).unwrap();
    assert!(history
        .lines()
        .next()
        .unwrap()
        .split(',')
        .any(|c| c == "plastic"));
    let state: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("final_state.json")).unwrap(),
    )
    .unwrap();
    let strains: Vec<&Value> = state["elements"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| &e["plastic_strain"])
        .collect();
    assert!(strains
        .iter()
        .all(|p| p.as_array().is_some_and(|a| a.len() == 3)));
    assert!(strains.iter().any(|p| p[1].as_f64().unwrap() != 0.0));
    let frame = std::fs::read_dir(dir.path().join("vtk"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .max()
        .unwrap();
    let text = std::fs::read_to_string(frame).unwrap();
    assert!(text.contains("Name=\"plastic_strain\"") && text.contains("Name=\"yielding\""));
}

/// A live load acts on a hybrid element's strains too. One unit square (`t` = 0.5 m, plane
/// strain) whose rigid DOFs are held, with a Tresca strength `c` and no interface, pressed by a
/// traction `q₀` on its top edge: the traction's work on `ε_y` is `−q₀ t ∫(y − y_c) dx = −q₀ t/2`
/// and on `ε_x` and `γ_xy` nothing, so the element's stress is `σ_y = −α q₀ / 2`,
/// `σ_x = τ_xy = 0`, and it yields at `α q₀ = 4 c`, flowing by normality with
/// `ε̇_x = −ε̇_y > 0`. Without the load's part on the strains it could not collapse. A
/// mechanism without a translation is scaled by its strain rates.
#[test]
fn a_live_traction_loads_the_strains_of_a_hybrid_element() {
    let (c, q0) = (1e5, 1e4);
    // The collapse of the square under `q₀` on `edge`, pressing it.
    let collapse_under = |edge: &str, value: [f64; 2]| {
        let scene = json!({
            "name": "one", "thickness": 0.5, "plane": "strain",
            "formulation": {"kind": "hybrid", "penalty": 100},
            "materials": {"m": {"E": 1e8, "nu": 0.3, "rho": 2000,
                "element": {"kind": "tresca", "cohesion": c}}},
            "bodies": [{"name": "b", "material": "m",
                "mesh": {"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [1, 1]},
                "supports": [{"kind": "clamp", "edge": "bottom", "dofs": ["u", "v", "theta"]}],
                "loads": [{"kind": "traction", "edge": edge, "value": value}]}],
            "time": {"dt": 1e-6, "steps": 1}
        });
        let s = setup(&scene, EvaluatorKind::Assembled);
        let r = collapse::analyse(&s, None, Points::Gauss).unwrap();
        assert!(
            (r.collapse - 4.0 * c / q0).abs() < 1e-6 * r.collapse,
            "α = {} pressed on its {edge} edge",
            r.collapse
        );
        r
    };
    let r = collapse_under("top", [0.0, -q0]);
    let [sx, sy, txy] = r.stresses[0];
    assert!(
        sx.abs() < 1e-6 * c && txy.abs() < 1e-6 * c && (sy + 2.0 * c).abs() < 1e-6 * c,
        "σ = {:?}",
        r.stresses[0]
    );
    let [ex, ey, gxy] = r.strain_rates[0];
    assert!(ex > 0.0 && ey < 0.0, "ε̇ = {:?}", r.strain_rates[0]);
    assert!(
        (ex + ey).abs() < 1e-6 * ex && gxy.abs() < 1e-6 * ex,
        "ε̇ = {:?}",
        r.strain_rates[0]
    );
    assert_eq!(r.velocities[0], [0.0; 3]);
    // The mechanism is reported so that its fastest vertex moves at 1: the corners, half a
    // metre from the centroid each way, at `ε̇_x √(½² + ½²)`.
    assert!(
        (ex - 2f64.sqrt()).abs() < 1e-6,
        "ε̇ = {:?}",
        r.strain_rates[0]
    );
    // The same traction on the element's side: `σ_x = −α q₀/2`, the same load.
    collapse_under("right", [-q0, 0.0]);
}

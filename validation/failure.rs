//! Section 11 of the validation report: interfaces that fail (`materials.*.interface`). One
//! interface against its law in closed form, uniaxial tension of a bar (strength and fracture
//! energy, on a grid and on three Voronoi meshes), plastic collapse in compression against
//! `2c cos φ / (1 − sin φ)`, and Prandtl's strip footing against `(2 + π) c`, each with its
//! cost in steps and element-steps (wall times in `timings.md`).

use super::Report;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::force::failure::{InterfaceFailure, InterfaceStatus};
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::step::integrator::Energy;
use serde_json::{json, Value};
use std::f64::consts::PI;

/// What one displacement-controlled run gives.
pub(super) struct Run {
    /// `(clamp displacement, reaction)` at every recorded step (m, N) of the scene's last
    /// moving clamp.
    pub(super) curve: Vec<(f64, f64)>,
    pub(super) last: Energy,
    /// Largest `|total − total(0)|` (J).
    pub(super) drift: f64,
    pub(super) interfaces: Vec<InterfaceFailure>,
    pub(super) u: Vec<f64>,
    pub(super) elements: usize,
    pub(super) steps: u64,
    /// The last clamp's largest reaction, checked at every step, and when (N, s).
    pub(super) peak: [f64; 2],
    /// The step at which it was reached.
    pub(super) peak_step: u64,
    pub(super) wall_s: f64,
}

pub(super) fn run(scene: &Value, evaluator: EvaluatorKind, every: u64) -> Run {
    let scene = Scene::from_json(&scene.to_string()).unwrap_or_else(|e| panic!("{e}\n{scene}"));
    let overrides = Overrides {
        evaluator: Some(evaluator),
        ..Overrides::default()
    };
    let start = std::time::Instant::now();
    let setup = Setup::new(&scene, &overrides).unwrap();
    let clamp = setup.model.prescribed.last().unwrap().clone();
    let mut cd = setup.integrator(setup.dt);
    let (mut curve, mut rows, mut peak) = (Vec::new(), Vec::new(), [0.0; 2]);
    let status = cd
        .run(
            setup.steps,
            every,
            |s, e| {
                let d = clamp.velocity.norm() * clamp.travel(s.t);
                curve.push((d, *s.reactions.last().unwrap()));
                peak = *s.peaks.last().unwrap();
                rows.push(*e);
                Ok(())
            },
            |_| {},
        )
        .unwrap();
    assert_eq!(status, rbsm::step::integrator::Status::Ok, "{}", scene.name);
    let plastic = setup.plastic.as_ref().unwrap();
    let drift = rows
        .iter()
        .map(|e| (e.total - rows[0].total).abs())
        .fold(0.0, f64::max);
    Run {
        curve,
        last: *rows.last().unwrap(),
        drift,
        interfaces: plastic.report(cd.failure().unwrap()),
        u: cd.u.clone(),
        elements: setup.model.elements.len(),
        steps: cd.step,
        peak,
        peak_step: (peak[1] / setup.dt).round() as u64,
        wall_s: start.elapsed().as_secs_f64(),
    }
}

impl Run {
    /// The last clamp's largest reaction over every step (N).
    pub(super) fn peak(&self) -> f64 {
        self.peak[0]
    }
    /// The tension bar's peak stress, its largest reaction over its section, over `f_t`.
    pub(super) fn bar_peak(&self) -> f64 {
        self.peak() / SECTION / F_T
    }
    /// The tension bar's fracture work at the end over `G_F` × its section.
    pub(super) fn bar_fracture(&self) -> f64 {
        self.last.fracture / (G_F * SECTION)
    }
    /// The largest `|total − total(0)|` over the work put in.
    pub(super) fn balance(&self) -> f64 {
        self.drift / self.last.external_work
    }
    pub(super) fn count(&self, status: InterfaceStatus) -> usize {
        self.interfaces
            .iter()
            .filter(|i| i.status == status)
            .count()
    }
    pub(super) fn cost(&self) -> String {
        format!(
            "{} | {:.2e}",
            self.steps,
            self.steps as f64 * self.elements as f64
        )
    }
}

pub(super) const F_T: f64 = 3.0e6;
pub(super) const G_F: f64 = 100.0;
/// The tension bar's section (m², per metre of thickness).
const SECTION: f64 = 0.05;

/// The tension bar of `examples/scenes/tension_bar.json` on `mesh`.
pub(super) fn bar(mesh: Value) -> Value {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes/tension_bar.json");
    let mut scene: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    scene["bodies"][0]["mesh"] = mesh;
    scene
}

/// A block squeezed between smooth platens, perfectly plastic with cohesion `c`.
fn squeeze(mesh: Value, phi: f64, f_t: f64) -> Value {
    json!({
        "name": "squeeze", "thickness": 1.0, "formulation": {"kind": "rigid"},
        "evaluator": "element-wise",
        "materials": {"soil": {"E": 1.0e8, "nu": 0.2, "rho": 2000,
            "interface": {"kind": "mohr-coulomb", "tensile_strength": f_t, "cohesion": 1.0e5,
                "friction_angle": phi}}},
        "damping": 300,
        "bodies": [{"name": "block", "material": "soil", "mesh": mesh,
            "supports": [{"kind": "clamp", "edge": "bottom", "dofs": ["v"]},
                {"kind": "clamp", "edge": "top", "dofs": ["v"], "velocity": [0, -0.01], "ramp": 0.01}]}],
        "time": {"dt_factor": 0.5, "end": 2.0},
    })
}

/// A rigid rough footing of width 0.4 m pushed into a weightless clay (φ = 0, `c` = 100 kPa,
/// no tension) 2 m wide and 1 m deep, on smooth side walls and a fixed base.
fn footing(mesh: Value) -> Value {
    json!({
        "name": "prandtl", "thickness": 1.0, "formulation": {"kind": "rigid"},
        "evaluator": "element-wise",
        "materials": {"clay": {"E": 1.0e8, "nu": 0.3, "rho": 2000,
            "interface": {"kind": "mohr-coulomb", "tensile_strength": 0, "cohesion": 1.0e5,
                "friction_angle": 0}}},
        "damping": 200,
        "bodies": [{"name": "soil", "material": "clay", "mesh": mesh,
            "supports": [{"kind": "clamp", "edge": "bottom"},
                {"kind": "clamp", "edge": "left", "dofs": ["u"]},
                {"kind": "clamp", "edge": "right", "dofs": ["u"]},
                {"kind": "clamp", "edge": "top", "span": [0.8, 1.2], "velocity": [0, -0.01], "ramp": 0.05}]}],
        "time": {"dt_factor": 0.5, "end": 1.5},
    })
}

pub(super) fn voronoi(size: [f64; 2], sites: usize) -> Value {
    json!({"kind": "voronoi", "origin": [0, 0], "size": size, "sites": sites, "seed": 1, "lloyd": 10})
}

fn grid(size: [f64; 2], cells: [usize; 2], cell: &str) -> Value {
    json!({"kind": "grid", "origin": [0, 0], "size": size, "cells": cells, "cell": cell})
}

/// `scene` run under the new controls: local damping 0.8 in place of its mass-proportional
/// damping, and its moving clamp (the last support of its first body) `speed` times as fast,
/// reaching that speed over `ramp` seconds and stopping at the same travel.
fn with_local_damping(scene: &Value, speed: f64, ramp: f64) -> Value {
    let mut scene = scene.clone();
    scene["damping"] = json!(0);
    scene["local_damping"] = json!(0.8);
    let travel_time = scene["time"]["end"].as_f64().unwrap() - 0.5 * clamp_ramp(&scene);
    scene["time"]["end"] = json!(travel_time / speed + 0.5 * ramp);
    let clamp = scene["bodies"][0]["supports"]
        .as_array_mut()
        .unwrap()
        .last_mut()
        .unwrap();
    let velocity: Vec<f64> = clamp["velocity"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() * speed)
        .collect();
    clamp["velocity"] = json!(velocity);
    clamp["ramp"] = json!(ramp);
    scene
}

/// The ramp (s) of `scene`'s moving clamp, the last support of its first body.
fn clamp_ramp(scene: &Value) -> f64 {
    scene["bodies"][0]["supports"]
        .as_array()
        .unwrap()
        .last()
        .unwrap()["ramp"]
        .as_f64()
        .unwrap()
}

/// A quasi-static test of 11.1–11.3 as the report runs it today, kept to be rerun under the
/// new controls in 11.6.
struct Today {
    test: String,
    mesh: String,
    scene: Value,
    /// Steps between the recorded points of the clamp's curve.
    every: u64,
    /// The reaction that makes `q` one: the section times the strength (N).
    scale: f64,
    /// Whether the test reads its largest reaction (softening) rather than the reaction at the
    /// end of the travel (a plateau).
    at_peak: bool,
    /// The closed form of `q` or the collapse load of the mesh's mechanism, where known.
    exact: Option<f64>,
    run: Run,
}

impl Today {
    /// The test's result `q` from `run`.
    fn read(&self, run: &Run) -> f64 {
        let reaction = if self.at_peak {
            run.peak()
        } else {
            run.curve.last().unwrap().1
        };
        reaction / self.scale
    }
}

pub fn failure(r: &mut Report) {
    r.line("## 11. Interfaces that fail\n");
    r.line(
        "Materials with `\"interface\": {\"kind\": \"mohr-coulomb\"}` (elastic–perfectly plastic, \
        tension cut-off) or `\"softening\"` (the same surface softening linearly with the plastic \
        opening and slip until `G_f`, `G_f,II` are spent; `docs/scene.md`, paper_notes item 22). \
        Every run here is displacement-controlled (a clamp with `velocity`), damped, and \
        explicit at 0.5 Δt_crit; the cost column is steps and element-steps (wall times in \
        `timings.md`).\n",
    );
    let mut today = Vec::new();
    tension(r, &mut today);
    compression(r, &mut today);
    prandtl(r, &mut today);
    fragments(r);
    quasi_static(r);
    controls(r, &today);
}

/// Local non-viscous damping on the tension bar (800 Voronoi sites): today's run (mass-
/// proportional damping, the clamp at 0.05 m/s) against local damping at the same speed and
/// at three and five times it, in proportionally fewer steps, and at five times it reached
/// over a longer ramp.
fn quasi_static(r: &mut Report) {
    r.line("### 11.5 Quasi-static control: local damping\n");
    r.line(
        "`\"local_damping\": α` (`docs/scene.md`, *Quasi-static runs*) reduces each free DOF's \
        unbalanced force by `α |F|` against its velocity's sign. On the 800-site tension bar of \
        11.1, with no mass-proportional damping, against today's run (α = 2000 1/s mass-\
        proportional, 0.05 m/s); a faster clamp stops at the same travel, after a ramp of 0.2 ms \
        unless the table says otherwise. *Steps to the peak* counts \
        the steps to the largest reaction, checked at every step. \
        Every run is at 0.5 Δt_crit, which local damping lowers by √(1 + α).\n",
    );
    r.line(
        "| damping | clamp speed | steps | steps to the peak | peak / f_t | peak / today's − 1 |",
    );
    r.line("|---|---|---|---|---|---|");
    let today = run(
        &bar(voronoi([0.2, 0.05], 800)),
        EvaluatorKind::ElementWise,
        100,
    );
    let reference = today.peak();
    r.line(&format!(
        "| mass-proportional 2000 1/s | 0.05 m/s | {} | {} | {:.4} | |",
        today.steps,
        today.peak_step,
        today.bar_peak()
    ));
    // (speed, ramp): a faster clamp, then a five times faster one that reaches its speed over
    // 1 ms, about 18 times the bar's wave transit time, instead of 0.2 ms.
    for (speed, ramp) in [(1.0, 2e-4), (3.0, 2e-4), (5.0, 2e-4), (5.0, 1e-3)] {
        let scene = with_local_damping(&bar(voronoi([0.2, 0.05], 800)), speed, ramp);
        let run = run(&scene, EvaluatorKind::ElementWise, 100);
        let change = run.peak() / reference - 1.0;
        r.line(&format!(
            "| local α = 0.8 | {:.2} m/s, ramp {:.1} ms | {} | {} | {:.4} | {change:+.2e} |",
            0.05 * speed,
            ramp * 1e3,
            run.steps,
            run.peak_step,
            run.bar_peak()
        ));
        r.timing(&format!(
            "- local damping, clamp × {speed}, ramp {ramp:e} s: {:.2} s",
            run.wall_s
        ));
        if speed == 1.0 && ramp == 2e-4 {
            r.bound(
                "quasi-static: local damping at today's speed, |peak / today's - 1|",
                change.abs(),
                0.01,
            );
        }
    }
    r.line(
        "\nAt today's speed local damping finds today's peak within 1 %; loaded faster, the peak \
        rises with the speed (the reaction carries the bar's inertia and the cracks run \
        dynamically), so fewer steps at the same accuracy are not reached by the damping alone: \
        the clamp's speed is bounded by the stress wave it sends, `ρ c v` (0.42 MPa at 0.05 m/s, \
        14 % of `f_t`), not by how the damping takes the energy out. A ramp five times as long \
        does not bring the peak down: the excess is the rate of the cracking, not the start. \
        Near the peak a crack takes several transit times to form while the clamp keeps \
        stretching the bar, so the peak is within 1 % only where the clamp is as slow as \
        today's while the bar cracks; what a quasi-static test can gain is a faster approach to \
        the first cracks. Local damping pays where the \
        load is applied at once and the state must settle (`tests/quasi_static.rs`: a cantilever \
        under a sudden load reaches its static solution to 2e-12 on a grid and 2e-10 on Voronoi cells in 8,000 steps, where \
        mass-proportional damping must be tuned to its lowest mode).\n",
    );
}

/// The bundled fragmentation scene, by both evaluators: the energy balance while the beam
/// breaks and its pieces collide, and the two evaluators side by side.
fn fragments(r: &mut Report) {
    r.line("### 11.4 Fragments: RBSM and DEM as one algorithm\n");
    r.line(
        "`examples/scenes/beam_drop.json`: a 1 m × 0.1 m concrete beam (150 Voronoi cells, `f_t` = \
        3 MPa, `G_f` = 50 J/m²) dropped at 2 m/s under gravity onto a ridge of rigid ground, \
        edge-to-edge contact with μ = 0.5, undamped, 0.25 Δt_crit, 80 ms. Broken interfaces \
        whose elements separate by 1 % of their length are released to contact (paper_notes \
        22). Energy put in: the initial kinetic energy plus the largest fall of the potential.\n",
    );
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes/beam_drop.json");
    let scene: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    r.line("| evaluator | released | broken | yielding | fracture (J) | friction (J) | |total drift| / put in | steps | element-steps |");
    r.line("|---|---|---|---|---|---|---|---|---|");
    let mut runs = Vec::new();
    for kind in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
        let scene = Scene::from_json(&scene.to_string()).unwrap();
        let overrides = Overrides {
            evaluator: Some(kind),
            ..Overrides::default()
        };
        let start = std::time::Instant::now();
        let setup = Setup::new(&scene, &overrides).unwrap();
        let mut cd = setup.integrator(setup.dt);
        let (mut rows, mut states) = (Vec::new(), Vec::new());
        cd.run(
            setup.steps,
            1000,
            |s, e| {
                rows.push(*e);
                states.push((s.t, s.u.to_vec()));
                Ok(())
            },
            |_| {},
        )
        .unwrap();
        let report = setup
            .plastic
            .as_ref()
            .unwrap()
            .report(cd.failure().unwrap());
        let count = |s| report.iter().filter(|i| i.status == s).count();
        let put_in = rows[0].kinetic - rows.iter().map(|e| e.potential).fold(0.0, f64::min);
        let drift = rows
            .iter()
            .map(|e| (e.total - rows[0].total).abs())
            .fold(0.0, f64::max)
            / put_in;
        let last = rows.last().unwrap();
        r.line(&format!(
            "| {} | {} | {} | {} | {:.4} | {:.4} | {drift:.2e} | {} | {:.2e} |",
            kind.name(),
            count(InterfaceStatus::Released),
            count(InterfaceStatus::Broken),
            count(InterfaceStatus::Yielding),
            last.fracture,
            last.friction,
            cd.step,
            cd.step as f64 * setup.model.elements.len() as f64
        ));
        r.timing(&format!(
            "- beam drop, {}: {:.2} s",
            kind.name(),
            start.elapsed().as_secs_f64()
        ));
        // The imbalance is the return mapping's first-order error (`tests/failure.rs`), which
        // each break adds to: it is bounded against the work of fracture.
        r.bound(
            &format!("fragments {}: |total drift| / fracture work", kind.name()),
            drift * put_in / last.fracture,
            5e-3,
        );
        r.figure(
            &format!("fragments {}: released", kind.name()),
            count(InterfaceStatus::Released) as f64,
            0.0,
        );
        runs.push(states);
    }
    // The two evaluators side by side in time: |ΔU| over the largest |U| at that time.
    let parity: Vec<(f64, f64)> = runs[0]
        .iter()
        .zip(&runs[1])
        .map(|((t, a), (_, e))| {
            let scale = a
                .iter()
                .fold(0.0f64, |m, x| m.max(x.abs()))
                .max(f64::MIN_POSITIVE);
            let diff = a
                .iter()
                .zip(e)
                .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            (*t, diff / scale)
        })
        .collect();
    r.line("\n|U_assembled − U_element-wise| / |U| in time (the beam lands at about 25 ms):\n");
    r.line("| t (ms) | 20 | 25 | 30 | 35 | 40 | 50 | 60 | 80 |");
    r.line("|---|---|---|---|---|---|---|---|---|");
    let at = |ms: f64| {
        parity
            .iter()
            .min_by(|a, b| (a.0 - ms * 1e-3).abs().total_cmp(&(b.0 - ms * 1e-3).abs()))
            .map_or(f64::NAN, |p| p.1)
    };
    let times = [20.0, 25.0, 30.0, 35.0, 40.0, 50.0, 60.0, 80.0];
    r.line(&format!(
        "| difference | {} |",
        times.map(|ms| format!("{:.1e}", at(ms))).join(" | ")
    ));
    r.bound("fragments: parity before landing (20 ms)", at(20.0), 1e-9);
    r.bound(
        "fragments: parity through the first cracks (40 ms)",
        at(40.0),
        1e-6,
    );
    r.line(
        "\nIn free fall the two differ by 1e-10: the assembled `K U` of a 4 cm translation cancels \
        only to the round-off of `K`'s entries, where the element-wise form takes `δ` as a \
        difference directly. Through the landing and the first cracks (25–40 ms) they stay within \
        1e-8. Each break and each contact decision is a threshold, so once the pieces fly and \
        collide the difference grows by orders of magnitude per few milliseconds, as a round-off \
        perturbation of a chaotic motion does, until the pieces' paths are unrelated; the counts \
        and the works above stay close. The energy balance closes to about 0.5 % of the fracture \
        work (1.6e-3 of the energy put in, 64.7 J, 0.503 % of the fracture work against the \
        check's 0.5 %; at 0.1 Δt_crit on the same scene 6.1e-4 of it, 0.18 % of the fracture \
        work, with 154 interfaces released: `rbsm run examples/scenes/beam_drop.json \
        --dt-factor 0.1`). The contact's tangential springs used to give energy back when a \
        piece grew at a given slip; once they stopped, the fragments took another path (140 \
        interfaces released by each evaluator where 147 and 157 were, the balance 1.1e-3 of the \
        energy put in, 0.17 % at 0.1 Δt_crit with 137 released). On a shorter run halving the step \
        halves the imbalance, the first-order error of the return mapping, which each break adds \
        to (`tests/failure.rs`). A broken interface is a crack that presses its faces only once \
        they touch: before that was so, a crack that began to close pushed them apart again at \
        once, and the beam broke less (107 interfaces released, 17.6 J of fracture work). \
        Contact never acts between two cells still bonded: before, every cell also pressed on \
        its bonded neighbours through contact, and the stiffer beam broke less still (83 \
        interfaces released, 15.3 J of fracture work) in six times the time.\n",
    );
}

/// Uniaxial tension: one interface, the grid bar, the Voronoi bar at three sizes; parity and
/// energy balance.
fn tension(r: &mut Report, today: &mut Vec<Today>) {
    r.line("### 11.1 Uniaxial tension\n");
    r.line(
        "`examples/scenes/tension_bar.json`: a 0.2 × 0.05 m bar, `f_t` = 3 MPa, `G_f` = 100 J/m², \
        `c` = 6 MPa, φ = 30°, `G_f,II` = 1000 J/m², pulled at 0.05 m/s (after a 0.2 ms ramp) to \
        0.15 mm, damping α = 2000 1/s. Peak: the largest reaction over the section, `F / (0.05 m × \
        1 m)`, checked at every step. Fracture work: the `fracture` column at the end, against \
        `G_f` × the section (5 J). The one-interface case is `cargo run --release --example \
        interface_failure` (two clamped squares, every step against the law in closed form).\n",
    );
    let one = super::interface_failure::compute();
    r.line(&format!(
        "- one interface, {} steps: largest |σ − closed form| / f_t = {:.1e}; fracture work / \
        (G_f L t) = {:.12}; status `{}`.\n",
        one.curve.len() - 1,
        one.error,
        one.energy_ratio,
        one.status
    ));
    r.bound(
        "one interface: |sigma - closed form| / f_t",
        one.error,
        1e-9,
    );
    r.bound(
        "one interface: |fracture work / (G_f L t) - 1|",
        (one.energy_ratio - 1.0).abs(),
        1e-9,
    );
    r.line("| mesh | elements | peak / f_t | fracture work / (G_f A) | yielding | broken | |total drift| / work in | steps | element-steps |");
    r.line("|---|---|---|---|---|---|---|---|---|");
    let cases: Vec<(String, Value)> = std::iter::once((
        "grid 20 × 5".to_string(),
        grid([0.2, 0.05], [20, 5], "rect"),
    ))
    .chain([200usize, 800, 3200].map(|n| (format!("Voronoi {n} sites"), voronoi([0.2, 0.05], n))))
    .chain(std::iter::once((
        "Voronoi 800 sites, G_f,II = G_f".to_string(),
        voronoi([0.2, 0.05], 800),
    )))
    .collect();
    for (name, mesh) in cases {
        let mut scene = bar(mesh);
        if name.ends_with("G_f,II = G_f") {
            scene["materials"]["concrete"]["interface"]["fracture_energy_shear"] = json!(G_F);
        }
        let run = run(&scene, EvaluatorKind::ElementWise, 100);
        let (peak, energy, balance) = (run.bar_peak(), run.bar_fracture(), run.balance());
        r.line(&format!(
            "| {name} | {} | {peak:.4} | {energy:.4} | {} | {} | {balance:.2e} | {} |",
            run.elements,
            run.count(InterfaceStatus::Yielding),
            run.count(InterfaceStatus::Broken),
            run.cost()
        ));
        r.timing(&format!("- tension bar, {name}: {:.2} s", run.wall_s));
        let key = name.replace(' ', "_");
        // The G_f,II = G_f row is there for the split of the fracture work; its balance
        // (1.1e-4, from its steeper shear softening) is reported against the reference.
        let balance_check = format!("tension {key}: energy balance |drift| / work in");
        if name.ends_with("G_f,II = G_f") {
            r.figure(&balance_check, balance, 1e-6);
        } else {
            r.bound(&balance_check, balance, 1e-4);
        }
        if name.starts_with("grid") {
            r.bound(
                &format!("tension {key}: |peak / f_t − 1|"),
                (peak - 1.0).abs(),
                0.02,
            );
        } else {
            r.figure(&format!("tension {key}: peak / f_t"), peak, 1e-6);
        }
        r.figure(
            &format!("tension {key}: fracture work / (G_f A)"),
            energy,
            1e-6,
        );
        if name == "grid 20 × 5" || name == "Voronoi 3200 sites" {
            today.push(Today {
                test: "tension".into(),
                exact: name.starts_with("grid").then_some(1.0),
                mesh: name,
                scene,
                every: 100,
                scale: 0.05 * F_T,
                at_peak: true,
                run,
            });
        }
    }
    r.line("");
    // Parity while the bar cracks.
    let scene = bar(voronoi([0.2, 0.05], 200));
    let (a, e) = (
        run(&scene, EvaluatorKind::Assembled, 100),
        run(&scene, EvaluatorKind::ElementWise, 100),
    );
    let scale = a.u.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff =
        a.u.iter()
            .zip(&e.u)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    r.line(&format!(
        "Both evaluators on the 200-site bar, {} steps, while {} interfaces break: final \
        displacements differ by {:.2e} of the largest; fracture works {:.10e} J (assembled, \
        the blocks `K_ab` and the plastic forces of each pair's interfaces) and {:.10e} J \
        (element-wise, each interface's tractions).\n",
        a.steps,
        a.count(InterfaceStatus::Broken),
        diff / scale,
        a.last.fracture,
        e.last.fracture
    ));
    r.bound(
        "tension parity: |U_assembled − U_element-wise| / |U|",
        diff / scale,
        1e-9,
    );
    r.line(
        "The grid bar reaches `f_t` (the bound of 2 % holds), but its fracture work exceeds \
        `G_f A` by 15 %: every section of a uniform bar reaches `f_t` at once and softens a little \
        before one localises. On the Voronoi bars the interfaces are inclined to the load, the \
        crack is tortuous and damage spreads before it localises (half the interfaces yield): the \
        peak is 20–37 % above `f_t` and the fracture work about three times `G_f A`. It is the \
        same on 800 and 3200 sites (to 0.1 %): the work per unit section does not depend on the \
        element size, but it is not `G_f`. A third of it is the cohesion's work on the inclined \
        facets that slide as the crack opens (with `G_f,II = G_f` it falls from 3.3 to 2.0 \
        `G_f A`); the rest is the spread damage. Each interface spends exactly its `G_f` (the \
        one-interface case); plain Voronoi RBSM would need a calibration of its interface \
        strengths to give the bar's `f_t` and `G_f`, which this code does not make. Reported as measured.\n",
    );
}

/// Plastic collapse of a block squeezed between smooth platens.
fn compression(r: &mut Report, today: &mut Vec<Today>) {
    r.line("### 11.2 Collapse in compression\n");
    r.line(
        "A 0.5 × 1 m block, `c` = 100 kPa, `f_t` = 1 MPa, squeezed between smooth platens at \
        0.01 m/s to 2 cm. The collapse stress of a Mohr–Coulomb continuum is \
        `q = 2c cos φ / (1 − sin φ)`, on planes at 45° + φ/2 to the platens. Meshes of right \
        triangles whose diagonals lie on those planes (10 × 20 cells for φ = 0°, 20 × 23 for \
        30°: diagonals at 45.0° and 60.1°) can form that mechanism; Voronoi cells cannot (below). \
        `q`: the largest platen reaction over the width.\n",
    );
    r.line("| mesh | φ | q / c | closed form | error | steps | element-steps |");
    r.line("|---|---|---|---|---|---|---|");
    for (cells, phi) in [([10, 20], 0.0), ([20, 23], 30.0)] {
        let scene = squeeze(grid([0.5, 1.0], cells, "tri"), phi, 1.0e6);
        let run = run(&scene, EvaluatorKind::ElementWise, 200);
        let q = run.peak() / 0.5 / 1.0e5;
        let s = f64::to_radians(phi).sin();
        let exact = 2.0 * (1.0 - s * s).sqrt() / (1.0 - s);
        let error = q / exact - 1.0;
        r.line(&format!(
            "| triangles {} × {} | {phi}° | {q:.4} | {exact:.4} | {:+.2} % | {} |",
            cells[0],
            cells[1],
            100.0 * error,
            run.cost()
        ));
        r.timing(&format!(
            "- compression, triangles, φ = {phi}°: {:.2} s",
            run.wall_s
        ));
        r.bound(
            &format!("compression phi={phi}: |q / closed form − 1|"),
            error.abs(),
            0.03,
        );
        today.push(Today {
            test: format!("compression, φ = {phi}°"),
            mesh: format!("triangles {} × {}", cells[0], cells[1]),
            scene,
            every: 200,
            scale: 0.5 * 1.0e5,
            at_peak: false,
            exact: Some(exact),
            run,
        });
    }
    for sites in [100usize, 400, 1600] {
        let scene = squeeze(voronoi([0.5, 1.0], sites), 0.0, 0.0);
        let run = run(&scene, EvaluatorKind::ElementWise, 200);
        let at = |f: f64| run.curve[((run.curve.len() - 1) as f64 * f) as usize].1 / 0.5 / 1.0e5;
        r.line(&format!(
            "| Voronoi {sites} sites (`f_t` = 0) | 0° | {:.2} at 1 cm, {:.2} at 2 cm | 2 | {:+.0} % | {} |",
            at(0.5),
            at(1.0),
            100.0 * (at(1.0) / 2.0 - 1.0),
            run.cost()
        ));
        r.timing(&format!(
            "- compression, Voronoi {sites}: {:.2} s",
            run.wall_s
        ));
        r.figure(
            &format!("compression voronoi {sites}: q / c at 2 cm"),
            at(1.0),
            1e-6,
        );
        if sites == 400 {
            today.push(Today {
                test: "compression, φ = 0°, `f_t` = 0".into(),
                mesh: format!("Voronoi {sites} sites"),
                scene,
                every: 200,
                scale: 0.5 * 1.0e5,
                at_peak: false,
                exact: None,
                run,
            });
        }
    }
    r.line(
        "\nOn the aligned triangles the collapse stress is met within 2 %; the excess is the drag \
        of the mass-proportional damping, and the run without it meets the closed form to 2e-5 \
        (11.6). On Voronoi cells the \
        load does not level off: rigid cells with non-dilatant slip can only shear along a \
        zig-zag band by opening or squeezing the inclined interfaces, so even with no tensile \
        strength the lattice interlocks and hardens (the rigid-cell analogue of volumetric \
        locking). Limit loads from Voronoi RBSM with these laws are upper values far above the \
        continuum's.\n",
    );
}

/// Prandtl's strip footing.
fn prandtl(r: &mut Report, today: &mut Vec<Today>) {
    r.line("### 11.3 Prandtl's strip footing\n");
    r.line(
        "A rigid rough footing 0.4 m wide pushed at 0.01 m/s (after a 0.05 s ramp) into the middle \
        of a weightless clay layer 2 m wide and 1 m deep (φ = 0, `c` = 100 kPa, no tension: the \
        Prandtl field is compressive everywhere), smooth side walls, fixed base. Collapse pressure \
        `(2 + π) c` = 5.142 c. `q`: the footing's reaction over its width at 1.5 cm.\n",
    );
    r.line("| mesh | elements | q / c | error | steps | element-steps |");
    r.line("|---|---|---|---|---|---|");
    let exact = 2.0 + PI;
    let meshes: Vec<(String, Value)> = [(20usize, 10usize), (40, 20)]
        .map(|(nx, ny)| {
            (
                format!("crossed triangles {nx} × {ny}"),
                grid([2.0, 1.0], [nx, ny], "crossed"),
            )
        })
        .into_iter()
        .chain(
            [400usize, 800, 1600].map(|n| (format!("Voronoi {n} sites"), voronoi([2.0, 1.0], n))),
        )
        .collect();
    for (name, mesh) in meshes {
        let scene = footing(mesh);
        let run = run(&scene, EvaluatorKind::ElementWise, 500);
        let q = run.curve.last().unwrap().1 / 0.4 / 1.0e5;
        r.line(&format!(
            "| {name} | {} | {q:.3} | {:+.1} % | {} |",
            run.elements,
            100.0 * (q / exact - 1.0),
            run.cost()
        ));
        r.timing(&format!("- Prandtl, {name}: {:.2} s", run.wall_s));
        let key = name.replace(' ', "_");
        r.figure(&format!("prandtl {key}: q / c"), q, 1e-6);
        let crossed = name.starts_with("crossed");
        if crossed {
            // The three-wedge mechanism of 45° blocks: q = 6c, an upper bound.
            r.bound(
                &format!("prandtl {key}: |q / 6c − 1|"),
                (q / 6.0 - 1.0).abs(),
                0.01,
            );
        }
        if crossed || name == "Voronoi 400 sites" {
            today.push(Today {
                test: "Prandtl's footing".into(),
                mesh: name,
                scene,
                every: 500,
                scale: 0.4 * 1.0e5,
                at_peak: false,
                exact: crossed.then_some(6.0),
                run,
            });
        }
    }
    r.line(
        "\nThe crossed triangles level off at 6.01 c on both meshes: their interfaces run at 0°, \
        45° and 90° only, so the mechanism they can form is the classical upper bound of three \
        rigid 45° wedges, `q = 6c` (+16.7 % over Prandtl), not Prandtl's fan, and refining the \
        same pattern does not change it. The Voronoi meshes interlock as in 11.2: the pressure \
        at 1.5 cm is about four times Prandtl's and still rising; it falls only slowly with \
        refinement. RBSM limit analysis reaches a few per cent only on meshes laid out for the \
        mechanism; this code reports, it does not tune.\n",
    );
}

/// The quasi-static tests of 11.1–11.3 rerun under the new controls (local damping, the clamp
/// at one, five and ten times today's speed to the same travel), beside today's runs; and the
/// drag that mass-proportional damping adds to a plateau, measured at half today's `α`.
fn controls(r: &mut Report, today: &[Today]) {
    r.line("### 11.6 The tests of 11.1–11.3 under the new controls\n");
    r.line(
        "Each test of 11.1–11.3 on the meshes below, run as today (mass-proportional damping, \
        the clamp's speed of its section) and with local damping α = 0.8 in its place, the clamp \
        one, five and ten times as fast, its ramp as many times shorter, to the same travel. \
        `q` is what the test reads: the largest reaction for the softening bar (over `f_t` \
        and the section), the reaction at the end of the travel where the load levels off (over \
        `c` and the width: 2 cm of squeeze, 1.5 cm of footing). *Exact*: the closed form (`f_t`; \
        `2c cos φ / (1 − sin φ)`) or, for the crossed triangles, the collapse load of their \
        three-wedge mechanism, `6c`; the Voronoi meshes have none. Steps are the cost (wall \
        times in `timings.md`); local damping's steps are 1/√1.8 as long. The dropped beam of \
        11.4 is a dynamic test, undamped by design: no quasi-static control applies to it.\n",
    );
    r.line(
        "| test | mesh | control | steps | today's / steps | q | q / today's − 1 | q / exact − 1 |",
    );
    r.line("|---|---|---|---|---|---|---|---|");
    // A percentage with its sign, none where it rounds to zero.
    let signed = |x: Option<f64>| {
        x.map_or(String::new(), |x| match format!("{:+.2} %", 100.0 * x) {
            zero if zero[1..].starts_with("0.00 ") => zero[1..].to_string(),
            s => s,
        })
    };
    for t in today {
        let q_today = t.read(&t.run);
        let off = |q: f64| t.exact.map(|e| q / e - 1.0);
        r.line(&format!(
            "| {} | {} | today's: `damping` {} 1/s | {} | 1 | {q_today:.4} | | {} |",
            t.test,
            t.mesh,
            t.scene["damping"],
            t.run.steps,
            signed(off(q_today))
        ));
        for speed in [1.0, 5.0, 10.0] {
            let scene = with_local_damping(&t.scene, speed, clamp_ramp(&t.scene) / speed);
            let run = run(&scene, EvaluatorKind::ElementWise, t.every);
            let q = t.read(&run);
            r.line(&format!(
                "| | | local 0.8, clamp × {speed} | {} | {:.2} | {q:.4} | {} | {} |",
                run.steps,
                t.run.steps as f64 / run.steps as f64,
                signed(Some(q / q_today - 1.0)),
                signed(off(q))
            ));
            r.timing(&format!(
                "- {}, {}, local damping, clamp × {speed}: {:.2} s (today's {:.2} s)",
                t.test, t.mesh, run.wall_s, t.run.wall_s
            ));
            let key = format!("controls {} {} x{speed}", t.test, t.mesh)
                .chars()
                .map(|c| if c.is_alphanumeric() { c } else { ' ' })
                .collect::<String>()
                .split_whitespace()
                .collect::<Vec<_>>()
                .join("_");
            match (t.exact, speed == 1.0, t.test.starts_with("tension")) {
                // A plateau reached slowly without drag is the model's collapse load.
                (Some(e), true, false) => r.bound(
                    &format!("{key}: |q / exact − 1|"),
                    (q / e - 1.0).abs(),
                    1e-4,
                ),
                // Local damping turns with the sign of every velocity, which amplifies
                // round-off: changes of the tractions' arithmetic at round-off moved the Voronoi
                // bar's peak by 1.6e-4, the fast runs by up to 3e-4, the φ = 30° squeeze at ten
                // times the speed, which has not settled, by 9e-3, and the slow runs by 6e-6.
                _ => {
                    let tolerance = match (speed == 1.0, t.test.as_str()) {
                        (_, "tension") if t.exact.is_none() => 1e-3,
                        (true, _) => 1e-5,
                        (false, "compression, φ = 30°") if speed == 10.0 => 2e-2,
                        (false, _) => 1e-3,
                    };
                    r.figure(&format!("{key}: q"), q, tolerance)
                }
            }
        }
    }
    // The drag of mass-proportional damping on the plateau of the φ = 0° squeeze.
    let t = today
        .iter()
        .find(|t| t.test == "compression, φ = 0°")
        .unwrap();
    let mut half = t.scene.clone();
    half["damping"] = json!(t.scene["damping"].as_f64().unwrap() / 2.0);
    let half = run(&half, EvaluatorKind::ElementWise, t.every);
    let excess = |run: &Run| t.read(run) - t.exact.unwrap();
    let ratio = excess(&t.run) / excess(&half);
    r.line(&format!(
        "\nToday's plateau of the φ = 0° squeeze exceeds 2c by {:.4} c at α = {} 1/s and by \
        {:.4} c at half that, {ratio:.3} times less: the excess is the drag `α M v` of the \
        sliding wedge, which mass-proportional damping adds to the platen's reaction at any \
        speed. Local damping opposes the unbalanced force only, which vanishes in a steady \
        mechanism, so its slow run finds the closed form itself (to 2e-5 on both \
        squeezes and the crossed footings).\n",
        excess(&t.run),
        t.scene["damping"],
        excess(&half)
    ));
    r.bound(
        "controls: today's excess over 2c / excess at half the damping − 2",
        (ratio - 2.0).abs(),
        1e-6,
    );
    r.line(
        "Where the load levels off without friction in the mechanism (the φ = 0° squeeze, the \
        footings), the clamp ten times as fast reaches it in 7.45 times fewer steps, within \
        0.2 % of the exact collapse load on the aligned meshes and within 0.1 % of today's on \
        the Voronoi footing: the 5× goal of fewer steps at 1 % is met there. Against today's \
        reading of the squeezes the difference is that drag (−1.0 % on the triangles and on \
        the Voronoi cells, whose load has not levelled off). With friction (the φ = 30° squeeze) \
        five times the speed still finds the closed form within 0.2 %, in 3.7 times fewer \
        steps; at ten times the reaction has not settled by the end of the travel and reads \
        several per cent high. \
        The softening bar is read at its peak. The grid bar, whose sections all reach `f_t` at \
        once, peaks within 0.2 % of `f_t` at ten times the speed too. On the Voronoi bar, \
        whose cracks form one after another, the clamp's speed raises the peak (11.5): +0.9 % \
        at today's speed under local damping, +4.6 % at five times, +18 % at ten; its peak \
        needs today's speed, and gains nothing from the new controls. A user checks a setting the same way: the same test at half the speed, whose reading \
        must agree (`docs/scene.md`, *Quasi-static runs*).\n",
    );
}

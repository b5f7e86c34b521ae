//! The validation suite: regenerates `validation/report.md` with its tables, CSV files and SVG
//! plots, and checks every figure against its closed form or against the committed reference
//! summary `validation/reference.json`, each with the tolerance stated beside it.
//!
//! Run: `cargo run --release --example validate` (about a minute). Exit code 1 if a check fails.
//! `-- --bless` rewrites `reference.json` from this run (after a deliberate change).

#[path = "collapse.rs"]
mod collapse;
#[path = "contact.rs"]
mod contact;
mod extremes;
#[path = "failure.rs"]
mod failure;
#[path = "fem.rs"]
mod fem;
mod fixtures;
#[path = "formulations.rs"]
mod formulations;
#[path = "fracture.rs"]
mod fracture;
#[path = "../examples/interface_failure.rs"]
#[allow(dead_code)]
mod interface_failure;
#[path = "q8.rs"]
mod q8;
mod trade;

use rbsm::analysis::eigen::{self, Method};
use rbsm::analysis::free::FreeSystem;
use rbsm::analysis::limit;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::analysis::stability;
use rbsm::analysis::statics;
use rbsm::force::evaluator;
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::model::mass::Mass;
use rbsm::model::Model;
use rbsm::step::integrator::{RunStatus, Status};
use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// One checked figure: against a closed form (`bound`) or against the reference run.
struct Check {
    name: String,
    value: f64,
    /// `Some(b)`: the figure must be ≤ b. `None`: compared with the reference at `rel_tol`.
    bound: Option<f64>,
    rel_tol: f64,
}

struct Report {
    dir: PathBuf,
    md: String,
    /// Wall times, which change from run to run: `validation/timings.md`, not tracked by git.
    timings: String,
    checks: Vec<Check>,
}

impl Report {
    fn bound(&mut self, name: &str, value: f64, bound: f64) {
        self.checks.push(Check {
            name: name.into(),
            value,
            bound: Some(bound),
            rel_tol: 0.0,
        });
    }
    /// A figure that has no closed form: it must reproduce the reference within `rel_tol`.
    fn figure(&mut self, name: &str, value: f64, rel_tol: f64) {
        self.checks.push(Check {
            name: name.into(),
            value,
            bound: None,
            rel_tol,
        });
    }
    fn line(&mut self, s: &str) {
        self.md.push_str(s);
        self.md.push('\n');
    }
    /// A line of `timings.md`.
    fn timing(&mut self, s: &str) {
        self.timings.push_str(s);
        self.timings.push('\n');
    }
    fn csv(&self, name: &str, header: &str, rows: &[Vec<f64>]) {
        let mut text = format!("{header}\n");
        for r in rows {
            text.push_str(
                &r.iter()
                    .map(|x| format!("{x:e}"))
                    .collect::<Vec<_>>()
                    .join(","),
            );
            text.push('\n');
        }
        std::fs::write(self.dir.join(name), text).unwrap();
    }
}

fn scene(json: String) -> Scene {
    Scene::from_json(&json).unwrap_or_else(|e| panic!("{e}\n{json}"))
}

fn body_scene(mesh: &str, supports: &str, loads: &str, e: f64, nu: f64, rho: f64, t: f64) -> Scene {
    scene(format!(
        r#"{{"name": "validation", "thickness": {t}, "formulation": {{"kind": "rigid"}},
            "materials": {{"m": {{"E": {e}, "nu": {nu}, "rho": {rho}}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {mesh}, "supports": {supports}, "loads": {loads}}}],
            "time": {{"dt": 1e-6, "steps": 1}}}}"#
    ))
}

fn model(s: &Scene) -> Model {
    Model::build(s).unwrap()
}

/// A log-log plot of several series.
fn plot(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[(&str, Vec<(f64, f64)>)],
) {
    rbsm::output::plot::log_log(path, title, x_label, y_label, series)
        .expect("the plot is written");
}

/// 1. One-row column on a ground spring: axial frequencies against the discrete closed form and
///    their convergence to the bar.
fn column(r: &mut Report) {
    let (e, nu, rho, t, length): (f64, f64, f64, f64, f64) = (2.0e10, 0.2, 2400.0, 1.0, 1.0);
    let e1 = e / (1.0 - nu * nu);
    let c1 = (e1 / rho).sqrt();
    r.line("## 1. Axial column on a ground spring\n");
    r.line(&format!(
        "One row of `n` square blocks (`L = {length}` m, `E = {e:e}` Pa, `ν = {nu}`, `ρ = {rho}`), left edge on a ground spring, \
         right end free, `v` and `θ` clamped so that only the axial chain remains. Discrete closed form \
         `ω_j = 2 √(K/m) sin((2j − 1) π / (4n))`, `K = k_n h t = E' t`, `m = ρ h² t`; bar `ω_j = (2j − 1) π c' / (2L)`, \
         `c' = √(E'/ρ)`. Check: every mode of every `n` within 1e-10 of the closed form.\n"
    ));
    r.line(
        "| n | max rel. error vs closed form (all modes) | ω₁ rel. error vs bar | ω₂ vs bar | \
        ω₃ vs bar |",
    );
    r.line("|---|---|---|---|---|");
    let mut rows = Vec::new();
    let mut series: Vec<(&str, Vec<(f64, f64)>)> =
        vec![("mode 1", vec![]), ("mode 2", vec![]), ("mode 3", vec![])];
    let mut worst = 0.0f64;
    for n in [5usize, 10, 20, 40, 80, 160, 320] {
        let h = length / n as f64;
        let mesh = format!(
            r#"{{"kind": "grid", "origin": [0, 0], "size": [{length}, {h}], "cells": [{n}, 1]}}"#
        );
        let sup = r#"[{"edge": "top", "kind": "clamp", "dofs": ["v", "theta"]}, {"edge": "left", "kind": "ground-spring"}]"#;
        let m = model(&body_scene(&mesh, sup, "[]", e, nu, rho, t));
        let mass = Mass::new(&m);
        let modes = eigen::dense_modes(&FreeSystem::new(&m, &mass), &mass, n).unwrap();
        let (k, mm) = (e1 * t, rho * h * h * t);
        let err = (1..=n)
            .map(|j| {
                let exact =
                    2.0 * (k / mm).sqrt() * (((2 * j - 1) as f64) * PI / (4.0 * n as f64)).sin();
                (modes.omega[j - 1] - exact).abs() / exact
            })
            .fold(0.0, f64::max);
        worst = worst.max(err);
        let bar: Vec<f64> = (1..=3)
            .map(|j| (2 * j - 1) as f64 * PI * c1 / (2.0 * length))
            .collect();
        let eb: Vec<f64> = (0..3)
            .map(|j| {
                if j < n {
                    (modes.omega[j] - bar[j]).abs() / bar[j]
                } else {
                    f64::NAN
                }
            })
            .collect();
        for j in 0..3 {
            series[j].1.push((n as f64, eb[j]));
        }
        r.line(&format!(
            "| {n} | {err:.2e} | {:.3e} | {:.3e} | {:.3e} |",
            eb[0], eb[1], eb[2]
        ));
        rows.push(vec![n as f64, err, eb[0], eb[1], eb[2]]);
    }
    r.bound(
        "column: max rel. error vs discrete closed form",
        worst,
        1e-10,
    );
    let slope = (rows[6][2] / rows[5][2]).ln() / 2f64.ln();
    r.figure("column: convergence order of ω₁ to the bar", -slope, 1e-3);
    r.line(&format!(
        "\nω₁ converges to the bar at order {:.3} (last halving); 2 is expected from \
        `sin x ≈ x − x³/6`.\n",
        -slope
    ));
    r.csv(
        "column.csv",
        "n,max_err_closed_form,err_bar_1,err_bar_2,err_bar_3",
        &rows,
    );
    plot(
        &r.dir.join("column_convergence.svg"),
        "Axial column: error of ω_j against the bar",
        "n (blocks)",
        "relative error",
        &series,
    );
    r.line("![column convergence](column_convergence.svg)\n");
}

/// The bending modes of a model (translational kinetic energy mostly along y), lowest first.
fn bending(omega: &[f64], shapes: &[Vec<f64>], mass: &[f64], nd: usize) -> Vec<f64> {
    omega
        .iter()
        .zip(shapes)
        .filter(|(_, s)| {
            let (mut ku, mut kv) = (0.0, 0.0);
            for e in 0..s.len() / nd {
                ku += mass[e * nd] * s[e * nd].powi(2);
                kv += mass[e * nd + 1] * s[e * nd + 1].powi(2);
            }
            kv > ku
        })
        .map(|(w, _)| *w)
        .collect()
}

/// The first three bending frequencies (rad/s) of the Q8 continuum model of the cantilever
/// (40 × 4 elements): its modes less the first axial one, the nearest to the bar's `c/(4L)`.
fn q8_bending(length: f64, depth: f64, t: f64, e: f64, nu: f64, rho: f64) -> Vec<f64> {
    let w = fem::cantilever_frequencies(length, depth, t, e, nu, rho, 40, 4, 12);
    without_axial(&w, (e / rho).sqrt() * PI / (2.0 * length))
}

/// The first three of frequencies `w` less the one nearest `axial`, the first axial mode.
fn without_axial(w: &[f64], axial: f64) -> Vec<f64> {
    let ax = w
        .iter()
        .enumerate()
        .min_by(|a, b| (a.1 - axial).abs().total_cmp(&(b.1 - axial).abs()))
        .map_or(usize::MAX, |(k, _)| k);
    w.iter()
        .enumerate()
        .filter(|(i, _)| *i != ax)
        .map(|(_, x)| *x)
        .take(3)
        .collect()
}

/// 2. Cantilever plate: bending frequencies against Euler–Bernoulli and a Q8 continuum model.
fn cantilever(r: &mut Report) {
    let (length, depth, t, e, nu, rho): (f64, f64, f64, f64, f64, f64) =
        (2.0, 0.2, 0.1, 3.0e10, 0.2, 2400.0);
    let e1 = e / (1.0 - nu * nu);
    let beta = [1.87510407, 4.69409113, 7.85475744];
    let eb =
        |e: f64, j: usize| (beta[j] / length).powi(2) * (e * depth * depth / (12.0 * rho)).sqrt();
    let fem_fine = fem::cantilever_frequencies(length, depth, t, e, nu, rho, 40, 4, 12);
    let fem_coarse = fem::cantilever_frequencies(length, depth, t, e, nu, rho, 20, 2, 12);
    // The Q8 model's bending modes: drop the first axial mode (c/(4L) ≈ 442 Hz lies between
    // bending modes 3 and 4); its frequency is identified as the one nearest the bar value.
    let axial = (e / rho).sqrt() * PI / (2.0 * length);
    let (fine, coarse) = (
        without_axial(&fem_fine, axial),
        without_axial(&fem_coarse, axial),
    );
    r.line("## 2. Cantilever plate: bending frequencies\n");
    r.line(&format!(
        "`{length}` m × `{depth}` m, `t = {t}` m, `E = {e:e}` Pa, `ν = {nu}`, `ρ = {rho}`; RBSM: square elements, left edge on \
         ground springs. References: Euler–Bernoulli with `E' = E/(1 − ν²)` (the square lattice has an effective Poisson \
         ratio of 0, so its bending stiffness is `E' I`) and with `E`; a continuum model of 40 × 4 eight-node quadrilaterals \
         (plane stress, consistent mass, clamped left edge; 20 × 2 differs from it by at most {:.1e}).\n",
        (0..3).map(|j| (coarse[j] - fine[j]).abs() / fine[j]).fold(0.0, f64::max)
    ));
    r.line("| mesh | DOFs | f₁ (Hz) | f₂ (Hz) | f₃ (Hz) | vs EB(E') 1/2/3 | vs Q8 1/2/3 |");
    r.line("|---|---|---|---|---|---|---|");
    let hz = |w: f64| w / (2.0 * PI);
    let mut rows = Vec::new();
    let mut s_eb: Vec<(&str, Vec<(f64, f64)>)> = vec![
        ("mode 1 vs EB(E')", vec![]),
        ("mode 2 vs EB(E')", vec![]),
        ("mode 3 vs EB(E')", vec![]),
    ];
    let mut s_fem: Vec<(&str, Vec<(f64, f64)>)> = vec![
        ("mode 1 vs Q8", vec![]),
        ("mode 2 vs Q8", vec![]),
        ("mode 3 vs Q8", vec![]),
    ];
    for (nx, ny) in [(20usize, 2usize), (40, 4), (80, 8), (160, 16)] {
        let mesh = format!(
            r#"{{"kind": "grid", "origin": [0, 0], "size": [{length}, {depth}], "cells": [{nx}, {ny}]}}"#
        );
        let m = model(&body_scene(
            &mesh,
            r#"[{"edge": "left", "kind": "ground-spring"}]"#,
            "[]",
            e,
            nu,
            rho,
            t,
        ));
        let mass = Mass::new(&m);
        let sys = FreeSystem::new(&m, &mass);
        let ev = evaluator::build(&m, EvaluatorKind::Assembled);
        let modes = eigen::modes(&sys, ev.as_ref(), &mass, 10, Method::Sparse).unwrap();
        let w = bending(&modes.omega, &modes.shapes, &mass.diagonal(), 3);
        let d_eb: Vec<f64> = (0..3).map(|j| (w[j] - eb(e1, j)) / eb(e1, j)).collect();
        let d_fem: Vec<f64> = (0..3).map(|j| (w[j] - fine[j]) / fine[j]).collect();
        for j in 0..3 {
            s_eb[j].1.push((ny as f64, d_eb[j].abs()));
            s_fem[j].1.push((ny as f64, d_fem[j].abs()));
        }
        r.line(&format!(
            "| {nx} × {ny} | {} | {:.3} | {:.3} | {:.3} | {:+.2} % / {:+.2} % / {:+.2} % | {:+.2} \
                % / {:+.2} % / {:+.2} % |",
            sys.n(),
            hz(w[0]),
            hz(w[1]),
            hz(w[2]),
            100.0 * d_eb[0],
            100.0 * d_eb[1],
            100.0 * d_eb[2],
            100.0 * d_fem[0],
            100.0 * d_fem[1],
            100.0 * d_fem[2]
        ));
        rows.push(vec![
            nx as f64,
            ny as f64,
            hz(w[0]),
            hz(w[1]),
            hz(w[2]),
            d_eb[0],
            d_eb[1],
            d_eb[2],
            d_fem[0],
            d_fem[1],
            d_fem[2],
        ]);
        for j in 0..3 {
            r.figure(
                &format!("cantilever {nx}x{ny}: f{} (Hz)", j + 1),
                hz(w[j]),
                1e-8,
            );
        }
    }
    r.line(&format!(
        "\nReferences (Hz): EB(E') {:.3} / {:.3} / {:.3}; EB(E) {:.3} / {:.3} / {:.3}; Q8 {:.3} / \
            {:.3} / {:.3}.\n",
        hz(eb(e1, 0)),
        hz(eb(e1, 1)),
        hz(eb(e1, 2)),
        hz(eb(e, 0)),
        hz(eb(e, 1)),
        hz(eb(e, 2)),
        hz(fine[0]),
        hz(fine[1]),
        hz(fine[2])
    ));
    r.line(
        "What this shows: with refinement the RBSM bending frequencies settle on a value of their own, not on the continuum's: \
         the square lattice is stiffer than the plane-stress continuum by its `E' = E/(1 − ν²)` (about +2 % in frequency \
         for ν = 0.2) and carries its own shear flexibility, which lowers modes 2 and 3 as Timoshenko theory would. \
         The differences to EB(E') at the finest mesh are that shear effect; the differences to the Q8 model combine both.\n",
    );
    for j in 0..3 {
        r.figure(
            &format!("cantilever Q8 reference f{} (Hz)", j + 1),
            hz(fine[j]),
            1e-8,
        );
    }
    r.csv(
        "cantilever.csv",
        "nx,ny,f1,f2,f3,err_eb1,err_eb2,err_eb3,err_q8_1,err_q8_2,err_q8_3",
        &rows,
    );
    let mut series = s_eb;
    series.extend(s_fem);
    plot(
        &r.dir.join("cantilever_convergence.svg"),
        "Cantilever: |relative difference| of bending frequencies",
        "elements through the depth",
        "|relative difference|",
        &series,
    );
    r.line("![cantilever convergence](cantilever_convergence.svg)\n");
    // Pictures of the model and its lowest modes, as `rbsm draw` and `rbsm eigen --svg` make them.
    let mesh = format!(
        r#"{{"kind": "grid", "origin": [0, 0], "size": [{length}, {depth}], "cells": [40, 4]}}"#
    );
    let m = model(&body_scene(
        &mesh,
        r#"[{"edge": "left", "kind": "ground-spring"}]"#,
        "[]",
        e,
        nu,
        rho,
        t,
    ));
    std::fs::write(
        r.dir.join("cantilever_model.svg"),
        rbsm::output::drawing::model_svg(&m),
    )
    .unwrap();
    let mass = Mass::new(&m);
    let modes = eigen::modes(
        &FreeSystem::new(&m, &mass),
        evaluator::build(&m, EvaluatorKind::Assembled).as_ref(),
        &mass,
        4,
        Method::Sparse,
    )
    .unwrap();
    rbsm::output::drawing::write_mode_shapes(
        &r.dir.join("cantilever_modes"),
        &m,
        &modes.omega,
        &modes.shapes,
    )
    .unwrap();
    r.line("The 40 × 4 model (springs from each centroid to its edges' midpoints, ground springs hatched) and its four lowest \
            modes, each captioned with its frequency (one of them is the first axial mode).\n");
    r.line("![cantilever model](cantilever_model.svg)\n");
    for k in 1..=4 {
        r.line(&format!(
            "![cantilever mode {k}](cantilever_modes/mode_{k:03}.svg)\n"
        ));
    }
}

/// 3. Patch tests: uniform tension and simple shear on rectangles, triangles, Voronoi cells.
fn patch(r: &mut Report) {
    let (e, sigma, tau) = (1.0e10, 3.0e6, 1.0e6);
    r.line("## 3. Patch tests (uniform stress)\n");
    r.line(
        "A 1.2 m × 0.8 m patch. Tension: `σ` on the right edge, normal-only ground springs (rollers) on the left and bottom \
         edges. Simple shear: `τ` along the top edge, tangential-only ground springs on the bottom, left and right edges. \
         Errors against the plane-stress continuum (`u = σ/E x`, `v = −ν σ/E y`; `u = γ y`, `v = 0`, `γ = τ/G`): displacement \
         error = max over elements of `|U − u(x_e)|` over max `|u|`; traction error = max over interfaces of \
         `|t − σ·n|` over the applied stress. The square grid is exact for its own lattice law \
         (`ε_x = σ(1 − ν²)/E`, `ε_y = 0`; tests/analyses.rs checks this to 1e-12), which equals the continuum only at ν = 0.\n",
    );
    r.line(
        "| mesh | ν | tension: displacement | tension: traction | shear: displacement | shear: \
        traction | passes |",
    );
    r.line("|---|---|---|---|---|---|---|");
    let meshes = [
        (
            "rectangles 6 × 4",
            r#"{"kind": "grid", "origin": [0, 0], "size": [1.2, 0.8], "cells": [6, 4]}"#,
        ),
        (
            "triangles 6 × 4 × 2",
            r#"{"kind": "grid", "origin": [0, 0], "size": [1.2, 0.8], "cells": [6, 4], "cell": "tri"}"#,
        ),
        (
            "Voronoi 60 cells",
            r#"{"kind": "voronoi", "origin": [0, 0], "size": [1.2, 0.8], "sites": 60, "seed": 5, "lloyd": 30}"#,
        ),
    ];
    let mut rows = Vec::new();
    for (mi, (name, mesh)) in meshes.iter().enumerate() {
        for nu in [0.0, 0.2] {
            let g = e / (2.0 * (1.0 + nu));
            let gamma = tau / g;
            let cases = [
                (
                    format!(r#"[{{"kind": "traction", "edge": "right", "value": [{sigma}, 0]}}]"#),
                    r#"[{"edge": "left", "kind": "ground-spring", "components": ["n"]}, {"edge": "bottom", "kind": "ground-spring", "components": ["n"]}]"#,
                    sigma,
                ),
                (
                    format!(r#"[{{"kind": "traction", "edge": "top", "value": [{tau}, 0]}}]"#),
                    r#"[{"edge": "bottom", "kind": "ground-spring", "components": ["s"]}, {"edge": "left", "kind": "ground-spring", "components": ["s"]}, {"edge": "right", "kind": "ground-spring", "components": ["s"]}]"#,
                    tau,
                ),
            ];
            let mut errs = Vec::new();
            for (ci, (loads, sup, stress)) in cases.iter().enumerate() {
                let m = model(&body_scene(mesh, sup, loads, e, nu, 2000.0, 0.2));
                let u = statics::solve(&m).unwrap().u;
                let exact = |x: rbsm::mesh::geometry::Vec2| {
                    if ci == 0 {
                        (sigma / e * x.x, -nu * sigma / e * x.y)
                    } else {
                        (gamma * x.y, 0.0)
                    }
                };
                let du = fixtures::extremes::patch_error(&m, &u, exact);
                let dt = m
                    .interfaces
                    .iter()
                    .filter(|i| i.b != rbsm::model::GROUND)
                    .map(|i| {
                        let t = statics::midpoint_traction(&m, i, &u);
                        let (n, s) = (i.normal, i.tangent);
                        let (tn, ts) = if ci == 0 {
                            (sigma * n.x * n.x, sigma * n.x * s.x)
                        } else {
                            (2.0 * tau * n.x * n.y, tau * (n.x * s.y + n.y * s.x))
                        };
                        (t[0] - tn).hypot(t[1] - ts)
                    })
                    .fold(0.0, f64::max)
                    / stress;
                errs.push(du);
                errs.push(dt);
            }
            let passes = errs.iter().all(|&x| x <= 1e-9);
            r.line(&format!(
                "| {name} | {nu} | {:.2e} | {:.2e} | {:.2e} | {:.2e} | {} |",
                errs[0],
                errs[1],
                errs[2],
                errs[3],
                if passes { "yes" } else { "no" }
            ));
            for (k, label) in [
                "tension displacement",
                "tension traction",
                "shear displacement",
                "shear traction",
            ]
            .iter()
            .enumerate()
            {
                r.figure(
                    &format!("patch {name} ν={nu}: {label} error"),
                    errs[k],
                    1e-6,
                );
            }
            if mi == 0 && nu == 0.0 {
                r.bound(
                    "patch: square grid, ν = 0, worst error against the continuum",
                    errs.iter().cloned().fold(0.0, f64::max),
                    1e-9,
                );
            }
            rows.push(vec![mi as f64, nu, errs[0], errs[1], errs[2], errs[3]]);
        }
    }
    r.line(
        "\nWhat RBSM passes: the square grid at ν = 0 (to round-off); at ν = 0.2 it follows its lattice law exactly and so \
         misses the continuum's lateral contraction. Triangles and Voronoi cells with the DOFs at the centroids do not pass: \
         the errors above, of the order of tens of percent in the tractions, are the method, not a bug (§7.1: the hybrid formulation passes on every mesh).\n",
    );
    r.csv(
        "patch.csv",
        "mesh,nu,tension_u,tension_t,shear_u,shear_t",
        &rows,
    );
}

/// One small mesh of each kind, for the checks that must hold on every kind.
const MESH_KINDS: [(&str, &str); 3] = [
    (
        "rectangles 10 × 4",
        r#"{"kind": "grid", "origin": [0, 0], "size": [1, 0.4], "cells": [10, 4]}"#,
    ),
    (
        "triangles 6 × 3 × 2",
        r#"{"kind": "grid", "origin": [0, 0], "size": [1, 0.4], "cells": [6, 3], "cell": "tri"}"#,
    ),
    (
        "Voronoi 80 cells",
        r#"{"kind": "voronoi", "origin": [0, 0], "size": [1, 0.5], "sites": 80, "seed": 11, "lloyd": 10}"#,
    ),
];

/// 4. Free assemblies: exactly three zero frequencies.
fn free_assembly(r: &mut Report) {
    r.line("## 4. Free assemblies: three zero frequencies\n");
    r.line(
        "No supports; dense eigen solve. Check: exactly three `ω ≤ 1e-6 ω_max` on every mesh.\n",
    );
    r.line("| mesh | free DOFs | ω₁/ω_max | ω₂/ω_max | ω₃/ω_max | ω₄/ω_max | zero modes |");
    r.line("|---|---|---|---|---|---|---|");
    for (name, mesh) in MESH_KINDS {
        let m = model(&body_scene(mesh, "[]", "[]", 2e10, 0.2, 2400.0, 0.1));
        let mass = Mass::new(&m);
        let sys = FreeSystem::new(&m, &mass);
        let modes = eigen::dense_modes(&sys, &mass, 4).unwrap();
        let rel: Vec<f64> = modes.omega.iter().map(|w| w / modes.omega_max).collect();
        let zero = rel.iter().filter(|&&x| x <= 1e-6).count();
        r.line(&format!(
            "| {name} | {} | {:.1e} | {:.1e} | {:.1e} | {:.2e} | {zero} |",
            sys.n(),
            rel[0],
            rel[1],
            rel[2],
            rel[3]
        ));
        r.bound(
            &format!("free assembly {name}: |zero modes − 3|"),
            (zero as f64 - 3.0).abs(),
            0.0,
        );
    }
    r.line("");
}

/// 5. The critical time step against the square-grid closed form, the bounds, the empirical limit.
fn critical_time_step(r: &mut Report) {
    let (e, nu, rho): (f64, f64, f64) = (3.0e10, 0.2, 2400.0);
    let c = (e / rho).sqrt();
    r.line("## 5. Critical time step\n");
    r.line(&format!(
        "Square grids of `n × n` elements of size `h = 1/n` m (`E = {e:e}`, `ν = {nu}`, `ρ = {rho}`). Infinite-lattice limit: \
         the top mode is the uniform rotation, `Δt_crit = (h/c) √((1 + ν)/3)`, `c = √(E/ρ)`. Exact `Δt_crit = 2/ω_max` \
         (Lanczos through the element-wise evaluator, top Ritz value settled to 1e-11). Bounds: each as its ratio to the exact value; `safe` ones must be ≤ 1.\n"
    ));
    r.line(
        "| n | supports | exact Δt_crit (s) | exact / closed form | gershgorin | \
        irons-treharne | per-body | single-body |",
    );
    r.line("|---|---|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    let mut series: Vec<(&str, Vec<(f64, f64)>)> =
        vec![("free", vec![]), ("bottom on ground springs", vec![])];
    for n in [4usize, 8, 16, 32, 64] {
        for (si, sup) in ["[]", r#"[{"edge": "bottom", "kind": "ground-spring"}]"#]
            .iter()
            .enumerate()
        {
            let h = 1.0 / n as f64;
            let mesh = format!(
                r#"{{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [{n}, {n}]}}"#
            );
            let m = model(&body_scene(&mesh, sup, "[]", e, nu, rho, 1.0));
            let mass = Mass::new(&m);
            let sys = FreeSystem::new(&m, &mass);
            let ev = evaluator::build(&m, EvaluatorKind::ElementWise);
            let dt =
                limit::critical_time_step(limit::omega_max(&m, ev.as_ref(), &mass, limit::EXACT));
            let closed = h / c * ((1.0 + nu) / 3.0).sqrt();
            let b = stability::bounds(&m, &sys, &mass, dt);
            r.line(&format!(
                "| {n} | {} | {dt:.6e} | {:.5} | {:.4} | {:.4} | {:.4} | {:.4} |",
                if si == 0 { "none" } else { "bottom" },
                dt / closed,
                b[0].ratio,
                b[1].ratio,
                b[2].ratio,
                b[3].ratio
            ));
            series[si].1.push((n as f64, (dt / closed - 1.0).abs()));
            rows.push(vec![
                n as f64,
                si as f64,
                dt,
                dt / closed,
                b[0].ratio,
                b[1].ratio,
                b[2].ratio,
                b[3].ratio,
            ]);
            for bound in &b[..3] {
                r.bound(
                    &format!("Δt bound {} (n = {n}, supports {si}): ratio", bound.name),
                    bound.ratio,
                    1.0 + 1e-12,
                );
            }
            r.figure(
                &format!("Δt_crit n={n} supports={si}: exact/closed"),
                dt / closed,
                1e-8,
            );
            r.figure(
                &format!("Δt bound single-body n={n} supports={si}: ratio"),
                b[3].ratio,
                1e-8,
            );
        }
    }
    r.csv(
        "dt_crit.csv",
        "n,supported,dt_crit,ratio_closed_form,gershgorin,irons_treharne,per_body,single_body",
        &rows,
    );
    plot(
        &r.dir.join("dt_crit.svg"),
        "Square grid: |exact/closed-form Δt_crit − 1|",
        "n (elements per side)",
        "|ratio − 1|",
        &series,
    );
    r.line("\n![dt_crit](dt_crit.svg)\n");
    // Empirical limit and runs around it on the 16 × 16 grid with its base on ground springs.
    let mesh = r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [16, 16]}"#;
    let grid16 = Setup::new(
        &body_scene(
            mesh,
            r#"[{"edge": "bottom", "kind": "ground-spring"}]"#,
            "[]",
            e,
            nu,
            rho,
            1.0,
        ),
        &Overrides {
            evaluator: Some(EvaluatorKind::ElementWise),
            ..Default::default()
        },
    )
    .unwrap();
    let (_, ratio) = stability::empirical_limit(&grid16, 2000, 1e-4).expect("a limit");
    r.line(&format!(
        "Empirical limit (16 × 16, base on ground springs; bisection on undamped runs of 2000 steps from a random \
         displacement, energy-growth detector, to 1e-4): **{ratio:.5} × Δt_crit**. Check: within 1 % of 1.\n"
    ));
    r.bound("empirical limit: |ratio − 1|", (ratio - 1.0).abs(), 0.01);
    r.line("| fraction of Δt_crit | status after 2000 steps | energy drift |");
    r.line("|---|---|---|");
    let mut runs = Vec::new();
    for f in [0.9, 0.99, 1.01] {
        let run = stability::run_at_fraction(&grid16, f, 2000);
        r.line(&format!(
            "| {f} | {} (step {}) | {} |",
            run.status,
            run.steps,
            run.max_relative_drift
                .map_or("— (diverged)".into(), |d| format!("{d:.3e}"))
        ));
        r.bound(
            &format!("run at {f} Δt_crit: diverged (1) when > 1"),
            if (run.status == RunStatus::Ok) == (f < 1.0) {
                0.0
            } else {
                1.0
            },
            0.0,
        );
        runs.push(run);
    }
    // The same pictures `rbsm stability --out DIR` and `rbsm plot DIR` give.
    let histories = r.dir.join("stability_16x16");
    rbsm::analysis::stability::write_fraction_histories(&histories, &runs).unwrap();
    rbsm::output::plot::histories(&histories).unwrap();
    r.line(
        "\n![stored energy of the runs at fractions of Δt_crit](stability_16x16/stability.svg)\n",
    );
    r.line("The stored (kinetic + elastic) energy of each run over the first it stored: every tenth step below the limit, \
            bounded at 0.9 and 0.99; every step at 1.01, which grows until the guard stops it (table above; the lower panel \
            shows those first steps). `examples/stability_limit.rs` steps the same kind of run without the guard and measures \
            the growth per step against the closed form.\n");
    r.line("\nThe drift of the stable runs is large because a random start puts most of the energy into the highest modes, where \
            the averaged-velocity kinetic energy differs most from the energy central difference conserves (`⅛ Δt² aᵀ M a`).\n");
}

/// 6. Assembled against element-wise: forces and trajectories.
fn parity(r: &mut Report) {
    r.line("## 6. Assembled against element-wise\n");
    r.line("Forces: `‖K U − f_ew(U)‖ / ‖K U‖` for a seeded random `U` (check ≤ 1e-12). Trajectories: `max |ΔU| / max |U|` \
            after 10⁴ steps at 0.9 Δt_crit (check ≤ 1e-9; tests/dynamics.rs explains the round-off bound).\n");
    r.line("| case | relative difference |");
    r.line("|---|---|");
    for (mesh_name, mesh) in MESH_KINDS {
        let name = format!("forces, {mesh_name}");
        let m = model(&body_scene(
            mesh,
            r#"[{"edge": "left", "kind": "ground-spring"}]"#,
            "[]",
            2e10,
            0.2,
            2400.0,
            0.1,
        ));
        let mut s = 12345u64;
        let u: Vec<f64> = (0..m.n_dofs())
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect();
        let (mut fa, mut fe) = (vec![0.0; u.len()], vec![0.0; u.len()]);
        evaluator::build(&m, EvaluatorKind::Assembled).internal_force(&u, &mut fa);
        evaluator::build(&m, EvaluatorKind::ElementWise).internal_force(&u, &mut fe);
        let d = fa
            .iter()
            .zip(&fe)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt()
            / fa.iter().map(|a| a * a).sum::<f64>().sqrt();
        r.line(&format!("| {name} | {d:.2e} |"));
        r.bound(&format!("parity {name}"), d, 1e-12);
    }
    for name in ["cantilever", "voronoi_panel"] {
        let s = Scene::from_file(format!(
            "{}/examples/scenes/{name}.json",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap();
        let run = |k| {
            let p = Setup::new(
                &s,
                &Overrides {
                    evaluator: Some(k),
                    ..Default::default()
                },
            )
            .unwrap();
            let mut cd = p.integrator(p.dt);
            assert_eq!(
                cd.run(10_000, 10_000, |_, _| Ok(()), |_| {}).unwrap(),
                Status::Ok
            );
            cd.u
        };
        let (a, b) = (
            run(EvaluatorKind::Assembled),
            run(EvaluatorKind::ElementWise),
        );
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let d = a
            .iter()
            .zip(&b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
            / scale;
        r.line(&format!("| trajectory, {name}, 10⁴ steps | {d:.2e} |"));
        r.bound(&format!("parity trajectory {name}"), d, 1e-9);
    }
    r.line("");
}

#[allow(clippy::too_many_arguments)] // the keys of a JSON template
fn hybrid_scene(
    mesh: &str,
    supports: &str,
    loads: &str,
    penalty: f64,
    e: f64,
    nu: f64,
    rho: f64,
    t: f64,
) -> Scene {
    let formulation = if penalty == 0.0 {
        r#"{"kind": "rigid"}"#.to_string()
    } else {
        format!(r#"{{"kind": "hybrid", "penalty": {penalty}}}"#)
    };
    scene(format!(
        r#"{{"name": "validation", "thickness": {t}, "formulation": {formulation},
            "materials": {{"m": {{"E": {e}, "nu": {nu}, "rho": {rho}}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {mesh}, "supports": {supports}, "loads": {loads}}}],
            "time": {{"dt": 1e-6, "steps": 1}}}}"#
    ))
}

/// 7. The hybrid formulation: patch tests against `p`, the triangle solution against linear
///    triangles, the cantilever's frequencies and time step against `p`, locking on quads.
fn hybrid(r: &mut Report) {
    let (e, nu, sigma, tau) = (1.0e10, 0.2, 3.0e6, 1.0e6);
    let pens = [1e1, 1e2, 1e3, 1e4, 1e5, 1e6];
    r.line("## 7. Hybrid formulation: rigid motion plus constant strain (eqs. 5, 8)\n");
    r.line("Interface springs are `p` times eq. 12 and tie the elements' linear fields together; each element adds its own \
            strain energy `½ t A εᵀ D ε`.\n");
    r.line("### 7.1 Patch tests against p\n");
    r.line("The patches of section 3 (same supports and loads), error of the element centroid displacements against the \
            continuum, relative to its largest value. Expected: O(1/p) on every mesh kind, since a uniform strain is \
            represented exactly by every element and the springs only carry its tractions.\n");
    r.line(&format!(
        "| mesh | ν | case | {} |",
        pens.iter()
            .map(|p| format!("p = {p:.0e}"))
            .collect::<Vec<_>>()
            .join(" | ")
    ));
    r.line(&format!("|---|---|---|{}", "---|".repeat(pens.len())));
    let mut series: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    let meshes = [
        (
            "rectangles",
            r#"{"kind": "grid", "origin": [0, 0], "size": [1.2, 0.8], "cells": [6, 4]}"#,
        ),
        (
            "triangles",
            r#"{"kind": "grid", "origin": [0, 0], "size": [1.2, 0.8], "cells": [6, 4], "cell": "tri"}"#,
        ),
        (
            "Voronoi",
            r#"{"kind": "voronoi", "origin": [0, 0], "size": [1.2, 0.8], "sites": 60, "seed": 5, "lloyd": 30}"#,
        ),
    ];
    for (name, mesh) in meshes {
        for nu in [0.0, 0.2, 0.45] {
            for (case, loads, sup) in [
                (
                    "tension",
                    format!(r#"[{{"kind": "traction", "edge": "right", "value": [{sigma}, 0]}}]"#),
                    r#"[{"edge": "left", "kind": "ground-spring", "components": ["n"]}, {"edge": "bottom", "kind": "ground-spring", "components": ["n"]}]"#,
                ),
                (
                    "shear",
                    format!(r#"[{{"kind": "traction", "edge": "top", "value": [{tau}, 0]}}]"#),
                    r#"[{"edge": "bottom", "kind": "ground-spring", "components": ["s"]}, {"edge": "left", "kind": "ground-spring", "components": ["s"]}, {"edge": "right", "kind": "ground-spring", "components": ["s"]}]"#,
                ),
            ] {
                let mut errs = Vec::new();
                for &p in &pens {
                    let m = model(&hybrid_scene(mesh, sup, &loads, p, e, nu, 2000.0, 0.2));
                    let u = statics::solve(&m).unwrap().u;
                    let gamma = tau * 2.0 * (1.0 + nu) / e;
                    let exact = |x: rbsm::mesh::geometry::Vec2| {
                        if case == "tension" {
                            (sigma / e * x.x, -nu * sigma / e * x.y)
                        } else {
                            (gamma * x.y, 0.0)
                        }
                    };
                    let err = fixtures::extremes::patch_error(&m, &u, exact);
                    errs.push(err);
                    r.figure(
                        &format!("hybrid patch {name} ν={nu} {case} p={p:.0e}"),
                        err,
                        1e-5,
                    );
                }
                r.line(&format!(
                    "| {name} | {nu} | {case} | {} |",
                    errs.iter()
                        .map(|x| format!("{x:.2e}"))
                        .collect::<Vec<_>>()
                        .join(" | ")
                ));
                // The error falls by a decade per decade of p until round-off takes over.
                r.bound(
                    &format!(
                        "hybrid patch {name} ν={nu} {case}: error at p = 1e4 over error \
                    at p = 1e1 (1/p predicts 1e-3)"
                    ),
                    errs[3] / errs[0],
                    2e-3,
                );
                if nu == 0.2 {
                    series.push((
                        format!("{name}, {case}"),
                        pens.iter().cloned().zip(errs).collect(),
                    ));
                }
            }
        }
    }
    let series_ref: Vec<(&str, Vec<(f64, f64)>)> = series
        .iter()
        .map(|(n, v)| (n.as_str(), v.clone()))
        .collect();
    plot(
        &r.dir.join("hybrid_patch.svg"),
        "Hybrid patch tests: error against p (ν = 0.2)",
        "penalty p",
        "relative error",
        &series_ref,
    );
    r.line("\n![hybrid patch](hybrid_patch.svg)\n");

    r.line("### 7.2 Triangles against linear-triangle FEM\n");
    r.line("A 2 m × 0.4 m plate of 16 × 4 × 2 triangles, left edge on ground springs (FEM: clamped nodes), a vertical traction \
            on the right edge. As `p` grows the ground springs clamp the edge and the interface springs make the \
            displacement continuous, so the hybrid solution tends to the constant-strain-triangle (CST) FEM solution on the \
            same triangles. Difference of the centroid displacements (FEM: the mean of the three nodes), relative to the \
            largest FEM displacement:\n");
    let mesh = r#"{"kind": "grid", "origin": [0, 0], "size": [2.0, 0.4], "cells": [16, 4], "cell": "tri"}"#;
    let base = model(&hybrid_scene(mesh, "[]", "[]", 1.0, e, nu, 2000.0, 0.1));
    let verts: Vec<(f64, f64)> = base.bodies[0]
        .mesh
        .vertices
        .iter()
        .map(|v| (v.x, v.y))
        .collect();
    let tris: Vec<[usize; 3]> = (0..base.bodies[0].mesh.n_cells())
        .map(|c| {
            let v = base.bodies[0].mesh.cell(c);
            [v[0] as usize, v[1] as usize, v[2] as usize]
        })
        .collect();
    let fem_u = fem::cst_static(&verts, &tris, 0.1, e, nu, (0.0, -1e6));
    let fem_max = fem_u.iter().map(|u| u.0.hypot(u.1)).fold(0.0, f64::max);
    r.line("| p | max centroid difference / max FEM displacement |");
    r.line("|---|---|");
    let mut cst = Vec::new();
    for &p in &pens {
        let m = model(&hybrid_scene(
            mesh,
            r#"[{"edge": "left", "kind": "ground-spring"}]"#,
            r#"[{"kind": "traction", "edge": "right", "value": [0, -1e6]}]"#,
            p,
            e,
            nu,
            2000.0,
            0.1,
        ));
        let u = statics::solve(&m).unwrap().u;
        let diff = tris
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let (fx, fy) = t.iter().fold((0.0, 0.0), |a, &i| {
                    (a.0 + fem_u[i].0 / 3.0, a.1 + fem_u[i].1 / 3.0)
                });
                (u[6 * k] - fx).hypot(u[6 * k + 1] - fy)
            })
            .fold(0.0, f64::max)
            / fem_max;
        r.line(&format!("| {p:.0e} | {diff:.3e} |"));
        r.figure(&format!("hybrid vs CST p={p:.0e}"), diff, 1e-5);
        cst.push((p, diff));
    }
    r.bound(
        "hybrid vs CST: difference at p = 1e6 over difference at p = 1e3 (1/p predicts 1e-3)",
        cst[5].1 / cst[2].1,
        2e-3,
    );
    r.line("");

    r.line("### 7.3 Cantilever: what each p buys and what it costs\n");
    let (length, depth, t, e2, nu2, rho) = (2.0, 0.2, 0.1, 3.0e10, 0.2, 2400.0);
    let q8 = q8_bending(length, depth, t, e2, nu2, rho);
    r.line(&format!(
        "The cantilever of section 2 as 40 × 4 rectangles, 40 × 4 × 2 triangles and 160 centroidal Voronoi cells, rigid \
         and hybrid, against the Q8 continuum model ({:.3} / {:.3} / {:.3} Hz). `Δt_crit` is the exact value (Lanczos). On rectangles and Voronoi cells the \
         linear fields cannot be continuous on every edge of every element with only constant strains, so large `p` \
         locks: the frequencies rise far above the continuum's. On triangles they tend to the linear-triangle FEM's, which is itself \
         stiff in bending on so coarse a mesh.\n",
        q8[0] / (2.0 * PI), q8[1] / (2.0 * PI), q8[2] / (2.0 * PI)
    ));
    r.line("| mesh | formulation | f₁ vs Q8 | f₂ vs Q8 | f₃ vs Q8 | Δt_crit (s) |");
    r.line("|---|---|---|---|---|---|");
    let mut dts: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for (mname, mesh) in [
        (
            "rectangles",
            format!(
                r#"{{"kind": "grid", "origin": [0, 0], "size": [{length}, {depth}], "cells": [40, 4], "cell": "rect"}}"#
            ),
        ),
        (
            "triangles",
            format!(
                r#"{{"kind": "grid", "origin": [0, 0], "size": [{length}, {depth}], "cells": [40, 4], "cell": "tri"}}"#
            ),
        ),
        (
            "Voronoi",
            format!(
                r#"{{"kind": "voronoi", "origin": [0, 0], "size": [{length}, {depth}], "sites": 160, "seed": 3, "lloyd": 30}}"#
            ),
        ),
    ] {
        let mut pts = Vec::new();
        for p in [0.0, 1.0, 1e1, 1e2, 1e3, 1e4] {
            let m = model(&hybrid_scene(
                &mesh,
                r#"[{"edge": "left", "kind": "ground-spring"}]"#,
                "[]",
                p,
                e2,
                nu2,
                rho,
                t,
            ));
            let mass = Mass::new(&m);
            let sys = FreeSystem::new(&m, &mass);
            let ev = evaluator::build(&m, EvaluatorKind::ElementWise);
            let modes = eigen::modes(&sys, ev.as_ref(), &mass, 8, Method::Sparse).unwrap();
            let nd = m.formulation.ndof();
            let w = bending(&modes.omega, &modes.shapes, &mass.diagonal(), nd);
            let dt = limit::critical_time_step(modes.omega_max);
            let d: Vec<f64> = (0..3).map(|j| (w[j] - q8[j]) / q8[j]).collect();
            let label = if p == 0.0 {
                "rigid".to_string()
            } else {
                format!("hybrid p = {p:.0e}")
            };
            r.line(&format!(
                "| {mname} | {label} | {:+.2} % | {:+.2} % | {:+.2} % | {dt:.3e} |",
                100.0 * d[0],
                100.0 * d[1],
                100.0 * d[2]
            ));
            for j in 0..3 {
                r.figure(
                    &format!("cantilever {mname} {label}: f{} vs Q8", j + 1),
                    d[j],
                    1e-6,
                );
            }
            r.figure(&format!("cantilever {mname} {label}: dt_crit"), dt, 1e-8);
            if p > 0.0 {
                pts.push((p, dt));
            }
        }
        let slope = (pts[4].1 / pts[2].1).ln() / (pts[4].0 / pts[2].0).ln();
        r.line(&format!(
            "| {mname} | slope of log Δt_crit against log p (p = 1e2 … 1e4) | | | | {slope:.3} |"
        ));
        r.bound(
            &format!("cantilever {mname}: |slope of Δt_crit against p + 1/2|"),
            (slope + 0.5).abs(),
            0.05,
        );
        dts.push((mname.to_string(), pts));
    }
    let dts_ref: Vec<(&str, Vec<(f64, f64)>)> =
        dts.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
    plot(
        &r.dir.join("hybrid_dt_crit.svg"),
        "Hybrid cantilever: Δt_crit against p",
        "penalty p",
        "Δt_crit (s)",
        &dts_ref,
    );
    r.line("\n![hybrid dt_crit](hybrid_dt_crit.svg)\n");
}

fn main() {
    let bless = std::env::args().any(|a| a == "--bless");
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("validation");
    let mut r = Report {
        dir: dir.clone(),
        md: String::new(),
        timings: String::from(
            "# Validation \
        wall times\n\nWritten by `cargo run --release --example validate` beside `report.md`; \
        single runs on this machine, with its noise. Not tracked by git: the results are in \
        `report.md`.\n",
        ),
        checks: Vec::new(),
    };
    r.line("# rbsm validation report\n");
    r.line("Regenerated by `cargo run --release --example validate`; nothing here is edited by hand. Every figure is checked \
            either against a closed form (bound stated beside it) or against the committed reference run \
            `validation/reference.json` (relative tolerance stated in the check list at the end).\n");
    let start = std::time::Instant::now();
    column(&mut r);
    cantilever(&mut r);
    patch(&mut r);
    free_assembly(&mut r);
    critical_time_step(&mut r);
    parity(&mut r);
    hybrid(&mut r);
    contact::contact(&mut r);
    trade::trade_section(&mut r);
    extremes::extremes(&mut r);
    failure::failure(&mut r);
    collapse::collapse(&mut r);
    fracture::fracture(&mut r);
    formulations::formulations(&mut r);
    // Checks: bounds, and figures against the reference.
    let reference: BTreeMap<String, f64> = std::fs::read_to_string(dir.join("reference.json"))
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_default();
    let mut failed = 0;
    r.line("## Checks\n");
    r.line("| check | value | criterion | result |");
    r.line("|---|---|---|---|");
    let mut summary = BTreeMap::new();
    let checks = std::mem::take(&mut r.checks);
    for c in &checks {
        summary.insert(c.name.clone(), c.value);
        let (criterion, ok) = match c.bound {
            Some(b) => (format!("≤ {b:e}"), c.value <= b),
            None => match reference.get(&c.name) {
                Some(&v) => (
                    format!("reference {v:.6e} ± {:.0e} rel.", c.rel_tol),
                    (c.value - v).abs() <= c.rel_tol * v.abs().max(1e-300),
                ),
                None => ("no reference yet".to_string(), bless),
            },
        };
        if !ok {
            failed += 1;
        }
        r.line(&format!(
            "| {} | {:.6e} | {criterion} | {} |",
            c.name,
            c.value,
            if ok { "pass" } else { "FAIL" }
        ));
    }
    let _ = writeln!(
        r.md,
        "\n{} checks, {} failed. Wall times are in `validation/timings.md` (not tracked).",
        checks.len(),
        failed
    );
    let _ = writeln!(
        r.timings,
        "\nGenerated in {:.0} s on {} threads.",
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    std::fs::write(dir.join("report.md"), &r.md).unwrap();
    std::fs::write(dir.join("timings.md"), &r.timings).unwrap();
    std::fs::write(
        dir.join("summary.json"),
        serde_json::to_string_pretty(&summary).unwrap(),
    )
    .unwrap();
    if bless {
        let figures: BTreeMap<_, _> = checks
            .iter()
            .filter(|c| c.bound.is_none())
            .map(|c| (c.name.clone(), c.value))
            .collect();
        std::fs::write(
            dir.join("reference.json"),
            serde_json::to_string_pretty(&figures).unwrap(),
        )
        .unwrap();
        println!("reference.json rewritten from this run");
    }
    println!(
        "validation: {} checks, {failed} failed; report in {}",
        checks.len(),
        dir.join("report.md").display()
    );
    if failed > 0 {
        std::process::exit(1);
    }
}

//! Static, eigen and stability analyses against closed forms (`validation/report.md` §1–5).

mod common;
use rbsm::analysis::eigen::{self, Method};
use rbsm::analysis::free::FreeSystem;
use rbsm::analysis::limit;
use rbsm::analysis::statics;
use rbsm::force::evaluator;
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::model::mass::Mass;
use rbsm::model::Model;
use rbsm::step::integrator::RunStatus;
use std::f64::consts::PI;

/// One row of `n` square blocks of side `h` with `supports` (JSON), `E`, `ν = 0.2`, `ρ`.
fn column(n: usize, h: f64, supports: &str) -> Model {
    let json = format!(
        r#"{{"name": "column", "thickness": 0.5, "formulation": {{"kind": "rigid"}},
            "materials": {{"m": {{"E": 2.0e9, "nu": 0.2, "rho": 1500.0}}}},
            "bodies": [{{"name": "col", "material": "m",
                "mesh": {{"kind": "grid", "origin": [0, 0], "size": [{}, {h}], "cells": [{n}, 1]}},
                "supports": {supports}}}],
            "time": {{"dt": 1e-6, "steps": 1}}}}"#,
        n as f64 * h
    );
    Model::build(&Scene::from_json(&json).unwrap()).unwrap()
}

/// The axial chain: `v` and `θ` clamped on every block (all lie on the top side), springs of
/// eq. 12 with `h_a + h_b = h` inside and `h/2` at a ground spring.
#[test]
fn column_frequencies_match_the_discrete_closed_form() {
    let (n, h, t, e, nu, rho): (usize, f64, f64, f64, f64, f64) =
        (40, 0.05, 0.5, 2.0e9, 0.2, 1500.0);
    let stiff = e / (1.0 - nu * nu) / h * h * t; // K = k_n h t
    let m = rho * h * h * t;
    let clamp = r#"{"edge": "top", "kind": "clamp", "dofs": ["v", "theta"]}"#;
    for (supports, exact) in [
        (
            format!(r#"[{clamp}, {{"edge": "left", "kind": "ground-spring"}}]"#),
            Box::new(|j: usize| {
                2.0 * (stiff / m).sqrt() * (((2 * j - 1) as f64) * PI / (4.0 * n as f64)).sin()
            }) as Box<dyn Fn(usize) -> f64>,
        ),
        (
            format!(
                r#"[{clamp}, {{"edge": "left", "kind": "ground-spring"}}, {{"edge": "right", "kind": "ground-spring"}}]"#
            ),
            Box::new(|j: usize| {
                2.0 * (stiff / m).sqrt() * ((j as f64) * PI / (2.0 * n as f64)).sin()
            }),
        ),
    ] {
        let model = column(n, h, &supports);
        let mass = Mass::new(&model);
        let sys = FreeSystem::new(&model, &mass);
        assert_eq!(sys.n(), n);
        let modes = eigen::dense_modes(&sys, &mass, n).unwrap();
        for j in 1..=n {
            let rel = (modes.omega[j - 1] - exact(j)).abs() / exact(j);
            assert!(
                rel <= 1e-10,
                "{supports}: mode {j}: {} vs {}: {rel:e}",
                modes.omega[j - 1],
                exact(j)
            );
        }
    }
}

/// A free assembly has exactly three zero frequencies on every mesh kind.
#[test]
fn free_assembly_has_three_zero_frequencies() {
    for (name, mesh) in [
        ("rect", common::RECT),
        ("tri", common::TRI),
        ("voronoi", common::VORONOI),
    ] {
        let model = common::model(mesh, "[]");
        let mass = Mass::new(&model);
        let modes = eigen::dense_modes(&FreeSystem::new(&model, &mass), &mass, 5).unwrap();
        let zero = modes
            .omega
            .iter()
            .filter(|&&w| w <= 1e-6 * modes.omega_max)
            .count();
        assert_eq!(zero, 3, "{name}: {:?}", &modes.omega);
        assert!(
            modes.omega[3] > 1e-3 * modes.omega_max,
            "{name}: fourth mode {:e}",
            modes.omega[3]
        );
    }
}

/// The dense and the sparse paths agree. A dense symmetric eigensolver is backward stable:
/// its eigenvalues carry an absolute error of up to about `n ε ‖A‖`, here `n ε ω_max²`, so the
/// low modes of a stiff model are where it is weakest: mode `j` agrees to
/// `½ n ε (ω_max/ω_j)²` relative in `ω`; we allow twice that (measured on the cantilever,
/// n = 1920: 7.3e-7 on mode 1, whose bound is 1.4e-6; the sparse shift-invert solution has a
/// residual of 7e-10 there, so the gap is the dense solver's). `ω_max` agrees to 1e-10.
#[test]
fn dense_and_sparse_eigen_agree() {
    let scene = Scene::from_file(format!(
        "{}/examples/scenes/cantilever.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let model = Model::build(&scene).unwrap();
    let mass = Mass::new(&model);
    let sys = FreeSystem::new(&model, &mass);
    let ev = evaluator::build(&model, EvaluatorKind::ElementWise);
    let dense = eigen::modes(&sys, ev.as_ref(), &mass, 8, Method::Dense).unwrap();
    let sparse = eigen::modes(&sys, ev.as_ref(), &mass, 8, Method::Sparse).unwrap();
    assert_eq!((dense.method, sparse.method), ("dense", "sparse"));
    assert!((dense.omega_max - sparse.omega_max).abs() <= 1e-10 * dense.omega_max);
    for j in 0..8 {
        let tol = sys.n() as f64 * f64::EPSILON * (dense.omega_max / dense.omega[j]).powi(2);
        let rel = (dense.omega[j] - sparse.omega[j]).abs() / dense.omega[j];
        assert!(
            rel <= tol,
            "mode {}: dense {} sparse {}: {rel:e} > {tol:e}",
            j + 1,
            dense.omega[j],
            sparse.omega[j]
        );
    }
    // The shapes are the same up to sign (M-normalised).
    let m = mass.diagonal();
    let dot: f64 = (0..m.len())
        .map(|i| dense.shapes[0][i] * m[i] * sparse.shapes[0][i])
        .sum();
    assert!((dot.abs() - 1.0).abs() < 1e-6, "{dot}");
}

fn patch(mesh: &str, nu: f64, load: &str, supports: &str) -> (Model, Vec<f64>) {
    let json = format!(
        r#"{{"name": "patch", "thickness": 0.2, "formulation": {{"kind": "rigid"}},
            "materials": {{"m": {{"E": 1.0e10, "nu": {nu}, "rho": 2000.0}}}},
            "bodies": [{{"name": "p", "material": "m", "mesh": {mesh}, "supports": {supports}, "loads": {load}}}],
            "time": {{"dt": 1e-6, "steps": 1}}}}"#
    );
    let model = Model::build(&Scene::from_json(&json).unwrap()).unwrap();
    let sol = statics::solve(&model).unwrap();
    (model, sol.u)
}

/// The square grid passes the uniform-stress patch tests exactly: tension gives
/// `u = σ (1 − ν²)/E · x`, `v = 0`, `θ = 0` and `t_n = σ` on every interface across the load;
/// shear gives `γ = τ/G` with `t_s = τ` on every interface. The ground springs carry exactly
/// the reactions.
#[test]
fn square_grid_passes_the_patch_tests_to_round_off() {
    let mesh = r#"{"kind": "grid", "origin": [0, 0], "size": [1.2, 0.8], "cells": [6, 4]}"#;
    let (e, sigma) = (1.0e10, 3.0e6);
    for nu in [0.0, 0.2] {
        let (model, u) = patch(
            mesh,
            nu,
            &format!(r#"[{{"kind": "traction", "edge": "right", "value": [{sigma}, 0]}}]"#),
            r#"[{"edge": "left", "kind": "ground-spring", "components": ["n"]}, {"edge": "bottom", "kind": "ground-spring", "components": ["n"]}]"#,
        );
        let eps = sigma * (1.0 - nu * nu) / e;
        for (k, el) in model.elements.iter().enumerate() {
            let c = el.props.centroid;
            let err = [
                (u[3 * k] - eps * c.x).abs(),
                u[3 * k + 1].abs(),
                u[3 * k + 2].abs(),
            ];
            assert!(
                err.iter().all(|&x| x <= 1e-12 * eps),
                "tension, ν = {nu}, element {k}: {err:?}"
            );
        }
        for i in model.interfaces.iter().filter(|i| i.normal.x.abs() > 0.5) {
            let t = statics::midpoint_traction(&model, i, &u);
            assert!(
                (t[0] - sigma).abs() <= 1e-10 * sigma && t[1].abs() <= 1e-10 * sigma,
                "tension traction {t:?}"
            );
        }
        // Shear: tangential ground springs on the bottom, left and right edges, `(τ, 0)` on
        // top. The rigid elements take the simple-shear state `U_e = (γ y_e, 0, −γ/2)` (pure
        // shear plus the rigid rotation that keeps `v = 0`); every interface, the supports
        // included, carries `t_s = ±τ`, `t_n = 0`. (A normal spring on a support would resist
        // the rotation through its `L³/12` term, so the supports are tangential only; with two
        // of them through one corner, the rotation about that corner would be a mechanism.)
        let tau = 1.0e6;
        let (model, u) = patch(
            mesh,
            nu,
            &format!(r#"[{{"kind": "traction", "edge": "top", "value": [{tau}, 0]}}]"#),
            r#"[{"edge": "bottom", "kind": "ground-spring", "components": ["s"]},
                {"edge": "left", "kind": "ground-spring", "components": ["s"]},
                {"edge": "right", "kind": "ground-spring", "components": ["s"]}]"#,
        );
        let gamma = tau * 2.0 * (1.0 + nu) / e;
        for (k, el) in model.elements.iter().enumerate() {
            let c = el.props.centroid;
            let err = [
                (u[3 * k] - gamma * c.y).abs(),
                u[3 * k + 1].abs(),
                (u[3 * k + 2] + 0.5 * gamma).abs(),
            ];
            assert!(
                err.iter().all(|&x| x <= 1e-12 * gamma),
                "shear, ν = {nu}, element {k}: {err:?}"
            );
        }
        for i in &model.interfaces {
            let t = statics::midpoint_traction(&model, i, &u);
            assert!(
                t[0].abs() <= 1e-10 * tau && (t[1].abs() - tau).abs() <= 1e-10 * tau,
                "shear traction {t:?}"
            );
        }
    }
}

/// A mechanism is an error that names each free rigid mode.
#[test]
fn mechanism_names_the_free_modes() {
    let roller = r#"[{"edge": "bottom", "kind": "ground-spring", "components": ["n"]}]"#;
    let err = statics::solve(&common::model(common::RECT, roller))
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("`bodies[0].supports`")
            && err.contains("mechanism (1 free rigid mode)")
            && err.contains("body `b` can translate along (1.000, 0.000)"),
        "{err}"
    );
    let err = statics::solve(&common::model(common::VORONOI, "[]"))
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("3 free rigid modes"), "{err}");
    // A clamp of `u` and `v` only on the left side leaves no rotation free (several elements).
    let clamp = r#"[{"edge": "left", "kind": "clamp", "dofs": ["u", "v"]}]"#;
    assert!(statics::solve(&common::model(common::RECT, clamp)).is_ok());
}

/// On a supported square grid: the proven bounds are safe, the naive single-body estimate is
/// not, and the empirical limit found by running lies within 1 % of `2/ω_max` (the guard
/// tolerance of the bisection is 1e-3; runs of 2000 steps grow by e^{2000·√(8ε)} at
/// `(1 + ε) Δt_crit`, so the limit is resolved to well below 1 %).
#[test]
fn bounds_and_empirical_limit_on_a_square_grid() {
    let model = common::model(
        r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [12, 12]}"#,
        r#"[{"edge": "bottom", "kind": "ground-spring"}]"#,
    );
    let mass = Mass::new(&model);
    let sys = FreeSystem::new(&model, &mass);
    let omega_max = eigen::dense_modes(&sys, &mass, 0).unwrap().omega_max;
    let dt_crit = 2.0 / omega_max;
    let bounds = rbsm::analysis::stability::bounds(&model, &sys, &mass, dt_crit);
    for b in &bounds {
        let proven = b.name != "single-body";
        assert_eq!(
            b.ratio <= 1.0 + 1e-12,
            proven,
            "{}: ratio {}",
            b.name,
            b.ratio
        );
        assert!(
            b.ratio > 0.3,
            "{}: ratio {} is uselessly small",
            b.name,
            b.ratio
        );
    }
    // The empirical limit against the setup's `Δt_crit` (Lanczos), which every command uses.
    let setup = rbsm::analysis::setup::Setup::new(
        &rbsm::input::scene::Scene::from_json(&common::scene_json(
            r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [12, 12]}"#,
            r#"[{"edge": "bottom", "kind": "ground-spring"}]"#,
        ))
        .unwrap(),
        &rbsm::analysis::setup::Overrides {
            evaluator: Some(EvaluatorKind::ElementWise),
            ..Default::default()
        },
    )
    .unwrap();
    assert!((setup.dt_crit() / dt_crit - 1.0).abs() < 1e-10);
    let (_, ratio) = rbsm::analysis::stability::empirical_limit(&setup, 2000, 1e-3).unwrap();
    assert!(
        (ratio - 1.0).abs() <= 0.01,
        "empirical limit at {ratio} × Δt_crit"
    );
}

/// An evaluator that counts its evaluations of `f_int`: the cost of `ω_max` in operator
/// applications (each Lanczos iteration is one, probing `K` for an inertia a few), which no
/// load on the machine changes.
struct Counted {
    inner: Box<dyn evaluator::Evaluator>,
    calls: std::sync::atomic::AtomicU64,
}

impl evaluator::Evaluator for Counted {
    fn kind(&self) -> EvaluatorKind {
        self.inner.kind()
    }
    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        self.calls
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.inner.internal_force(u, f);
    }
    fn bytes(&self) -> usize {
        self.inner.bytes()
    }
}

/// `ω_max` of long thin models (`limit::omega_max`'s doc). A free chain's top eigenvalues are a
/// cluster of spacing `~ω²/N²` that the Lanczos Ritz value creeps into as `1/k²`: the old stop
/// (Ritz value settled to 1e-11 over 20 iterations) left the 300-block chain 6.6e-9 short of the
/// dense value and took 12 600 iterations (10 s) on 20 000 blocks, 2e-9 short. Now
/// [`eigen::omega_max`] brackets `ω_max²` by the inertia of `σM − K` on such models: dense
/// agreement to 1e-11, the `1/N²` approach of the top to the infinite chain's band edge is
/// resolved (`ω_∞ − ω_N ∝ 1/N²`, so successive differences over doublings have ratio 4), and
/// 20 000 blocks take no more evaluations of `f_int` than a square grid of the same DOFs (each
/// costs the chain less: two interfaces per block, about four per square). The bisection's
/// factorisations are admitted only when estimated to cost less than the iterations done
/// (`limit::omega_max`), so the evaluations bound the whole cost. (Measured: 209 evaluations
/// against 491.)
#[test]
fn omega_max_of_long_free_chains_is_accurate_and_cheap() {
    let omega = |m: &Model| {
        let mass = Mass::new(m);
        let ev = Counted {
            inner: evaluator::build(m, EvaluatorKind::Assembled),
            calls: Default::default(),
        };
        let w = limit::omega_max(m, &ev, &mass, limit::EXACT);
        (w, ev.calls.into_inner())
    };
    let small = column(300, 0.01, "[]");
    let mass = Mass::new(&small);
    let dense = eigen::dense_modes(&FreeSystem::new(&small, &mass), &mass, 0)
        .unwrap()
        .omega_max;
    let (lanczos, _) = omega(&small);
    assert!(
        (lanczos - dense).abs() <= 1e-11 * dense,
        "{lanczos} {dense}: {:e}",
        lanczos / dense - 1.0
    );
    let w: Vec<(f64, u64)> = [5_000, 10_000, 20_000]
        .iter()
        .map(|&n| omega(&column(n, 0.01, "[]")))
        .collect();
    let ratio = (w[1].0 - w[0].0) / (w[2].0 - w[1].0);
    assert!((ratio - 4.0).abs() < 0.04, "{ratio}: {w:?}");
    let square = omega(&model_of(
        r#"{"kind": "grid", "origin": [0, 0], "size": [1.42, 1.41], "cells": [142, 141]}"#,
    ))
    .1;
    assert!(
        w[2].1 <= square,
        "chain {} evaluations, square {square}",
        w[2].1
    );
}

fn model_of(mesh: &str) -> Model {
    common::model(mesh, r#"[{"edge": "left", "kind": "ground-spring"}]"#)
}

/// The bracket a setup knows without Lanczos (README, `rbsm run`; paper_notes.md 24): `dt_safe ≤
/// Δt_crit ≤ dt_ceiling` on every bundled scene (rigid and hybrid, with and without contact,
/// supported or free), each side proven, and the safe step no further than `1/√2` below the exact
/// one.
#[test]
fn the_proven_bracket_holds_the_exact_critical_step_on_every_bundled_scene() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/scenes");
    let mut seen = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        let setup = rbsm::analysis::setup::Setup::new(
            &Scene::from_file(&path).unwrap(),
            &rbsm::analysis::setup::Overrides {
                exact_dt_crit: true,
                ..Default::default()
            },
        )
        .unwrap();
        let (lim, exact) = (setup.limit, setup.dt_crit());
        let name = path.display();
        assert!(
            lim.dt_safe() <= exact * (1.0 + 1e-12),
            "{name}: {lim:?} {exact}"
        );
        assert!(
            exact <= lim.dt_ceiling() * (1.0 + 1e-12),
            "{name}: {lim:?} {exact}"
        );
        assert!(
            lim.dt_safe() >= exact / 2f64.sqrt() * (1.0 - 1e-12),
            "{name}"
        );
        // A step between the bracket's ends is warned about, below it not.
        assert_eq!(setup.limit.omega_max, Some(setup.omega_max()));
        let bare = limit::Limit {
            omega_max: None,
            tolerance: None,
            ..lim
        };
        assert!(bare.warning(0.99 * lim.dt_safe()).is_none(), "{name}");
        assert!(bare.warning(1.01 * lim.dt_safe()).is_some(), "{name}");
        assert!(bare
            .warning(1.01 * lim.dt_ceiling())
            .unwrap()
            .contains("upper bound of Δt_crit"));
        seen += 1;
    }
    assert!(seen >= 10, "{seen} scenes");
}

/// The free rigid modes are named as translations and a rotation (README, `rbsm static`): a free
/// body's are the translations along x and y and the rotation about its centroid, not three
/// mixtures of them (each "can rotate about" some point); a body held at one element rotates
/// about that element's centroid, and one held there in `v` only also translates along x.
#[test]
fn free_rigid_modes_are_two_translations_and_a_rotation() {
    use rbsm::analysis::rigid_modes::{free_modes, Motion};
    use rbsm::mesh::geometry::Vec2;
    let modes = |model: &Model| {
        let ev = evaluator::build(model, EvaluatorKind::Assembled);
        free_modes(model, ev.as_ref())
            .into_iter()
            .map(|m| m.motion)
            .collect::<Vec<_>>()
    };
    let near = |a: Vec2, b: Vec2| (a - b).norm() < 1e-9;
    let free = common::model(common::VORONOI, "[]");
    let area: f64 = free.elements.iter().map(|e| e.props.area).sum();
    let centroid = free
        .elements
        .iter()
        .map(|e| e.props.area * e.props.centroid)
        .sum::<Vec2>()
        / area;
    match &modes(&free)[..] {
        [Motion::Translation(x), Motion::Translation(y), Motion::Rotation(p)] => assert!(
            near(*x, Vec2::new(1.0, 0.0)) && near(*y, Vec2::new(0.0, 1.0)) && near(*p, centroid),
            "{x} {y} {p} (centroid {centroid})"
        ),
        other => panic!("{other:?}"),
    }
    let text = statics::solve(&free).err().unwrap().to_string();
    assert_eq!(text.matches("can rotate about").count(), 1, "{text}");
    assert_eq!(text.matches("can translate along").count(), 2, "{text}");
    // One row of three blocks held at the first: it turns about that block's centroid.
    let held = |dofs: &str| {
        column(
            3,
            0.1,
            &format!(r#"[{{"edge": "left", "kind": "clamp", "dofs": {dofs}}}]"#),
        )
    };
    let pinned = held(r#"["u", "v"]"#);
    let first = pinned.elements[0].props.centroid;
    match &modes(&pinned)[..] {
        [Motion::Rotation(p)] => assert!(near(*p, first), "{p} against {first}"),
        other => panic!("{other:?}"),
    }
    // Held in `v` only: it also slides along x, and the rotation orthogonal to that slide is
    // about the block's centroid still.
    match &modes(&held(r#"["v"]"#))[..] {
        [Motion::Translation(x), Motion::Rotation(p)] => {
            assert!(near(*x, Vec2::new(1.0, 0.0)) && near(*p, first), "{x} {p}")
        }
        other => panic!("{other:?}"),
    }
}

/// A run of `rbsm stability` that diverges gives the reason (what the guard saw, and the
/// step), and no energy drift, which says nothing of a diverged run.
#[test]
fn a_diverged_stability_run_gives_its_reason() {
    use rbsm::analysis::Report;
    let setup = rbsm::analysis::setup::Setup::new(
        &Scene::from_json(&common::scene_json(
            r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [6, 6]}"#,
            r#"[{"edge": "bottom", "kind": "ground-spring"}]"#,
        ))
        .unwrap(),
        &Default::default(),
    )
    .unwrap();
    let ok = rbsm::analysis::stability::run_at_fraction(&setup, 0.5, 500);
    assert_eq!((ok.status, ok.reason.as_deref()), (RunStatus::Ok, None));
    assert!(ok.max_relative_drift.unwrap() < 1e-6);
    let report = rbsm::analysis::stability::analyse(
        &setup,
        &rbsm::analysis::stability::StabilityParams {
            fractions: vec![0.5, 1.2],
            steps: 500,
        },
    )
    .unwrap();
    let bad = &report.fractions[1];
    assert_eq!(bad.status, RunStatus::Diverged);
    assert!(bad.steps < 500 && bad.max_relative_drift.is_none());
    let reason = bad.reason.as_deref().unwrap();
    assert!(
        reason.starts_with("at step")
            && (reason.contains("energy growth") || reason.contains("NaN")),
        "{reason}"
    );
    let text = report.text();
    let line = text.lines().find(|l| l.contains("run at 1.200")).unwrap();
    assert!(
        line.contains("diverged at step") && line.contains(reason) && !line.contains("drift"),
        "{line}"
    );
    let line = text.lines().find(|l| l.contains("run at 0.500")).unwrap();
    assert!(line.contains("ok, 500 steps, energy drift"), "{line}");
    // Runs of no step would bisect to nonsense (an empirical limit of 1e148 s).
    let e = rbsm::analysis::stability::analyse(
        &setup,
        &rbsm::analysis::stability::StabilityParams {
            fractions: vec![0.5],
            steps: 0,
        },
    )
    .err()
    .unwrap()
    .to_string();
    assert!(e.contains("--steps") && e.contains("≥ 1"), "{e}");
    let json = serde_json::to_value(&report).unwrap();
    assert!(json["fractions"][1]["max_relative_drift"].is_null());
    assert_eq!(json["fractions"][1]["reason"], reason);
    assert_eq!(
        (
            &json["fractions"][0]["status"],
            &json["fractions"][1]["status"]
        ),
        (&serde_json::json!("ok"), &serde_json::json!("diverged"))
    );
}

/// On a scene whose runs excite nothing (the hopping block in free flight for 100 steps), no
/// fraction diverges: the search for a limit stops at its bracket with a message keyed
/// `--steps`, where it doubled the step for ever.
#[test]
fn stability_refuses_runs_that_cannot_show_a_limit() {
    let scene = Scene::from_file(std::path::Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/hopping_block.json"
    )))
    .unwrap();
    let setup =
        rbsm::analysis::setup::Setup::new(&scene, &rbsm::analysis::setup::Overrides::exact())
            .unwrap();
    let e = rbsm::analysis::stability::analyse(
        &setup,
        &rbsm::analysis::stability::StabilityParams {
            fractions: vec![0.5],
            steps: 100,
        },
    )
    .err()
    .expect("no limit to find")
    .to_string();
    assert!(
        e.contains("--steps") && e.contains("free flight") && e.contains("64"),
        "{e}"
    );
}

//! Limit analysis (`rbsm::analysis::collapse`, `rbsm limit`): the collapse load of small models
//! against their hand-computed values, and against the explicit run of the same discrete model
//! where its load levels off; the errors of models that cannot be analysed so.

use rbsm::analysis::collapse::{self, Multiplier};
use rbsm::analysis::run::{self as run, RunParams, Silent};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use serde_json::{json, Value};

/// Cohesion of every test (Pa).
const C: f64 = 1e5;

/// A scene of one body of `mesh` with an interface of tensile strength `f_t`, cohesion `c` and
/// friction angle `phi` (degrees), its bottom clamped, under `loads`.
fn scene(mesh: Value, [f_t, c, phi]: [f64; 3], loads: Value) -> Value {
    json!({
        "name": "lp", "thickness": 1.0, "formulation": {"kind": "rigid"},
        "materials": {"m": {"E": 1e9, "nu": 0.2, "rho": 2000,
            "interface": {"kind": "mohr-coulomb", "tensile_strength": f_t, "cohesion": c,
                "friction_angle": phi}}},
        "bodies": [{"name": "b", "material": "m", "mesh": mesh,
            "supports": [{"kind": "clamp", "edge": "bottom"}], "loads": loads}],
        "time": {"dt": 1e-6, "steps": 1}
    })
}

fn collapse(
    scene: &Value,
    on: Option<Multiplier>,
) -> rbsm::error::Result<collapse::CollapseReport> {
    let scene = Scene::from_json(&scene.to_string()).unwrap();
    collapse::analyse(
        &Setup::new(&scene, &Overrides::default())?,
        on,
        Default::default(),
    )
}

/// `n` unit squares stacked in a column.
fn column(n: usize) -> Value {
    json!({"kind": "grid", "origin": [0, 0], "size": [1, n], "cells": [1, n]})
}

/// A block on a clamped one slides when the shear on their interface reaches `c L t`: a push
/// `P` at its centroid collapses it at `α P = c` (the moment it adds is carried by normal
/// tractions well inside the cut-off).
#[test]
fn a_block_slides_at_its_cohesion() {
    let push = json!([{"kind": "force", "element": 1, "value": [4e4, 0, 0]}]);
    let r = collapse(&scene(column(2), [1e7, C, 0.0], push), None).unwrap();
    assert_eq!(r.multiplier, Multiplier::Loads);
    assert!(
        (r.collapse - C / 4e4).abs() < 1e-6 * r.collapse,
        "α = {}",
        r.collapse
    );
    // The mechanism: the top block translates along the push, the bottom one is fixed.
    let [top, bottom] = [r.velocities[1], r.velocities[0]];
    assert!(
        (top[0] - 1.0).abs() < 1e-4 && top[1].abs() < 1e-4,
        "{top:?}"
    );
    assert_eq!(bottom, [0.0; 3]);
}

/// A column of three blocks pulled at its top opens at its tension cut-off: `α P = f_t L t`,
/// whatever the cohesion above it.
#[test]
fn a_column_in_tension_opens_at_its_cut_off() {
    let pull = json!([{"kind": "force", "element": 2, "value": [0, 1e5, 0]}]);
    let r = collapse(&scene(column(3), [2e5, 10.0 * C, 30.0], pull), None).unwrap();
    assert!((r.collapse - 2.0).abs() < 1e-6 * 2.0, "α = {}", r.collapse);
}

/// A unit square cut by its diagonal, the lower triangle clamped: a horizontal push `H` at the
/// upper triangle's centroid presses it on the diagonal (`H/√2` across it) and shears it
/// (`H/√2` along it); with no tension and `φ = 0` it slides at `H/√2 = c √2`, `H = 2 c`, its
/// normal traction compressive at both Gauss points (the push's line meets the diagonal at
/// `(2/3, 2/3)`, between them).
#[test]
fn a_wedge_slides_on_its_diagonal() {
    let mesh = json!({"kind": "polygons", "vertices": [[0, 0], [1, 0], [1, 1], [0, 1]],
        "cells": [[0, 1, 2], [0, 2, 3]]});
    let push = json!([{"kind": "force", "element": 1, "value": [1e5, 0, 0]}]);
    let r = collapse(&scene(mesh, [0.0, C, 0.0], push), None).unwrap();
    assert!((r.collapse - 2.0).abs() < 1e-6 * 2.0, "α = {}", r.collapse);
    let sigma = r.tractions.iter().flatten().map(|t| t[0]);
    assert!(
        sigma.clone().all(|s| s <= 1e-6 * C),
        "{:?}",
        sigma.collect::<Vec<_>>()
    );
}

/// What does not grow is held: a flat block (4 × 0.25 m on a clamped one, `φ = 30°`) under
/// its weight `W` and a push `P` slides at `α P = c L t + W tan φ`; under gravity tilted by 45°
/// alone, at the gravity factor `β` with `β W sin 45° = c L t + β W cos 45° tan φ`. (Flat, so
/// that the moments of the loads leave the Gauss points far inside the apex of the surface.)
#[test]
fn gravity_and_loads_each_grow_with_the_other_held() {
    let tan = 30f64.to_radians().tan();
    let flat = json!({"kind": "grid", "origin": [0, 0], "size": [4, 0.5], "cells": [1, 2]});
    let weight = 2000.0 * 9.81 * 4.0 * 0.25;
    let push = json!([{"kind": "force", "element": 1, "value": [1e5, 0, 0]}]);
    let mut pushed = scene(flat.clone(), [1e7, C, 30.0], push);
    pushed["gravity"] = json!([0, -9.81]);
    let alpha = collapse(&pushed, None).unwrap().collapse;
    let expected = (4.0 * C + weight * tan) / 1e5;
    assert!(
        (alpha - expected).abs() < 1e-6 * expected,
        "α = {alpha}, expected {expected}"
    );
    let mut tilted = scene(flat, [1e7, C, 30.0], json!([]));
    let g = 9.81 / 2f64.sqrt();
    tilted["gravity"] = json!([g, -g]);
    let r = collapse(&tilted, None).unwrap();
    assert_eq!(r.multiplier, Multiplier::Gravity);
    let expected = 4.0 * C / (weight / 2f64.sqrt() * (1.0 - tan));
    assert!(
        (r.collapse - expected).abs() < 1e-6 * expected,
        "β = {}, expected {expected}",
        r.collapse
    );
}

/// A model that cannot collapse, one that cannot carry its dead load, and one with contact are
/// refused with a message that says which.
#[test]
fn unbounded_infeasible_and_contact_are_refused() {
    let push = json!([{"kind": "force", "element": 1, "value": [1e5, 0, 0]}]);
    let mut elastic = scene(column(2), [1e7, C, 0.0], push.clone());
    elastic["materials"]["m"]["interface"] = json!({"kind": "elastic"});
    let e = collapse(&elastic, None).unwrap_err().to_string();
    assert!(e.contains("does not collapse"), "{e}");
    // The bundled cantilever, all its interfaces elastic: the solver, given equalities alone,
    // returned a load factor of 0 as solved.
    let bundled = |name: &str| {
        let path = format!("{}/examples/scenes/{name}", env!("CARGO_MANIFEST_DIR"));
        let scene = Scene::from_file(&path).unwrap();
        collapse::analyse(
            &Setup::new(&scene, &Overrides::default()).unwrap(),
            None,
            Default::default(),
        )
        .unwrap_err()
        .to_string()
    };
    let e = bundled("cantilever.json");
    assert!(e.contains("does not collapse"), "{e}");
    // A law the program does not know is named with its body.
    let e = bundled("brazilian_disk.json");
    assert!(
        e.contains("bodies[0].material") && e.contains("`facet`"),
        "{e}"
    );

    // Gravity held while the push grows: a weight beyond the cut-off pulls the block off.
    let mut hanging = scene(column(2), [1e3, C, 0.0], push.clone());
    hanging["gravity"] = json!([0, 9.81]);
    let e = collapse(&hanging, Some(Multiplier::Loads))
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot carry its dead load"), "{e}");

    let mut touching = scene(column(2), [1e7, C, 0.0], push);
    touching["contact"] = json!({"model": "edge-to-edge"});
    let e = collapse(&touching, None).unwrap_err().to_string();
    assert!(e.contains("contact"), "{e}");
}

/// The bundled squeeze (`examples/scenes/squeeze.json`: a 0.5 m wide block of aligned
/// triangles, `φ = 0`, between smooth platens) collapses at `q = 2 c`, the closed form
/// `2 c cos φ / (1 − sin φ)`.
#[test]
fn the_bundled_squeeze_collapses_at_twice_its_cohesion() {
    let path = format!(
        "{}/examples/scenes/squeeze.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let scene: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let scene = Scene::from_json(&scene.to_string()).unwrap();
    let setup = Setup::new(&scene, &Overrides::default()).unwrap();
    let r = collapse::analyse(&setup, None, Default::default()).unwrap();
    let q = r.collapse / (0.5 * C);
    assert!((q - 2.0).abs() < 1e-6, "q = {q} c");
    // `--out`: the report, the mechanism and the tractions, whose shear is nowhere above `c`.
    let dir = tempfile::tempdir().unwrap();
    collapse::write(dir.path(), &setup, &r).unwrap();
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["collapse"].as_f64(), Some(r.collapse));
    for file in ["mechanism.vtu", "mechanism.svg"] {
        assert!(
            dir.path().join(file).metadata().unwrap().len() > 0,
            "{file}"
        );
    }
    let csv = std::fs::read_to_string(dir.path().join("tractions.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 2 * setup.model.interfaces.len());
    let failing: Vec<bool> = setup
        .model
        .interfaces
        .iter()
        .map(|i| setup.model.fails(i))
        .collect();
    let mut dissipated = 0.0;
    for row in rows {
        let cells: Vec<&str> = row.split(',').collect();
        let tau: f64 = cells[7].parse().unwrap();
        if failing[cells[0].parse::<usize>().unwrap()] {
            assert!(tau.abs() <= C * (1.0 + 1e-6), "{row}");
        }
        // The power the tractions take from the mechanism's jumps, `t w (σ δ̇_n + τ δ̇_s)`.
        let i = &setup.model.interfaces[cells[0].parse::<usize>().unwrap()];
        let values: Vec<f64> = cells[6..10].iter().map(|c| c.parse().unwrap()).collect();
        dissipated += 0.5 * i.length * (values[0] * values[2] + values[1] * values[3]);
    }
    // Duality: the interfaces dissipate what the clamp puts in, its reaction times its speed
    // in the mechanism (the top elements' `v̇`).
    let clamp = setup.model.prescribed[0].dofs[0].0 / setup.model.formulation.ndof();
    let power = r.collapse * r.velocities[clamp][1].abs();
    assert!(
        (dissipated.abs() - power).abs() < 1e-6 * power,
        "dissipated {dissipated:e} W, put in {power:e} W"
    );
}

/// The rough strip footing of the report (§11.3: weightless clay, `φ = 0`, no tension, 0.4 m on
/// a 2 × 1 m layer) on crossed triangles 20 × 10: the program's collapse pressure and the
/// plateau of the explicit run of the same model (local damping, the clamp at ten times the
/// report's speed, 1.5 cm of travel) agree within 0.2 %; the flow is associated here
/// (`φ = 0`, the cut-off), so the two are one load.
#[test]
fn the_footing_collapses_where_the_explicit_run_levels_off() {
    let footing = json!({
        "name": "prandtl", "thickness": 1.0, "formulation": {"kind": "rigid"},
        "local_damping": 0.8,
        "materials": {"clay": {"E": 1.0e8, "nu": 0.3, "rho": 2000,
            "interface": {"kind": "mohr-coulomb", "tensile_strength": 0, "cohesion": C,
                "friction_angle": 0}}},
        "bodies": [{"name": "soil", "material": "clay", "mesh": {"kind": "grid", "origin": [0, 0],
            "size": [2.0, 1.0], "cells": [20, 10], "cell": "crossed"},
            "supports": [{"kind": "clamp", "edge": "bottom"},
                {"kind": "clamp", "edge": "left", "dofs": ["u"]},
                {"kind": "clamp", "edge": "right", "dofs": ["u"]},
                {"kind": "clamp", "edge": "top", "span": [0.8, 1.2], "velocity": [0, -0.1],
                    "ramp": 0.005}]}],
        "time": {"dt_factor": 0.5, "end": 0.1525},
        "output": {"every": 100}
    });
    let lp = collapse(&footing, None).unwrap();
    assert_eq!(lp.multiplier, Multiplier::Clamps);
    let q_lp = lp.collapse / (0.4 * C);

    let scene = Scene::from_json(&footing.to_string()).unwrap();
    let setup = Setup::new(&scene, &Overrides::default()).unwrap();
    let params = RunParams {
        keep_history: true,
        ..RunParams::default()
    };
    let out = run::simulate(&setup, &params, None, &mut Silent).unwrap();
    let q_explicit = out.last("_force").expect("the clamp's force column") / (0.4 * C);
    eprintln!("footing: LP {q_lp:.5} c, explicit {q_explicit:.5} c");
    assert!(
        (q_explicit - q_lp).abs() < 2e-3 * q_lp,
        "LP {q_lp} c, explicit {q_explicit} c"
    );
}

//! Bad input: every class of bad scene is an error that names the key (or the cell), never a
//! panic and never a silent NaN.

mod common;
use common::scene_json;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use rbsm::model::Model;
use serde_json::Value;

fn base() -> Value {
    serde_json::from_str(&scene_json(common::RECT, common::SUPPORTS)).unwrap()
}

/// The error of the whole pipeline (parse, validate, model, time step) for a scene.
fn error_of(v: &Value) -> String {
    let result = Scene::from_json(&v.to_string())
        .and_then(|s| Setup::new(&s, &Overrides::default()).map(|_| ()));
    match result {
        Ok(()) => panic!("scene was accepted: {v}"),
        Err(e) => e.to_string(),
    }
}

fn with(edit: impl FnOnce(&mut Value)) -> String {
    let mut v = base();
    edit(&mut v);
    error_of(&v)
}

fn expect(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error `{msg}` lacks `{p}`");
    }
}

#[test]
fn unknown_keys_are_named_with_their_path() {
    expect(&with(|v| v["colour"] = "red".into()), &["colour"]);
    expect(
        &with(|v| v["bodies"][0]["mesh"]["cels"] = 3.into()),
        &["bodies[0].mesh", "cels"],
    );
    expect(
        &with(|v| v["materials"]["m"]["youngs"] = 3.into()),
        &["materials.m", "youngs"],
    );
    expect(&with(|v| v["time"]["tend"] = 3.into()), &["time", "tend"]);
}

/// A key at fault in well-formed JSON (unknown, missing, of the wrong type, inside a kind's
/// variant) is a scene error whose key is its JSON path, and its message places it by that path
/// alone (`rbsm check --json` and Python's `SceneError.key` gave the file or `<json>`,
/// and a scene built from a Python dict was placed at "line 1 column 376" of text nobody saw).
/// Malformed JSON stays a parse error placed by line and column.
#[test]
fn keys_at_fault_are_named_by_their_json_path() {
    type Edit = fn(&mut Value);
    let cases: [(Edit, &str); 6] = [
        (
            |v| v["materials"]["m"]["youngs"] = 3.into(),
            "materials.m.youngs",
        ),
        (
            |v| v["bodies"][0]["mesh"]["cels"] = 3.into(),
            "bodies[0].mesh.cels",
        ),
        (
            |v| v["bodies"][0]["mesh"]["cells"] = "many".into(),
            "bodies[0].mesh.cells",
        ),
        (
            |v| {
                v.as_object_mut()
                    .unwrap()
                    .remove("time")
                    .map(|_| ())
                    .unwrap()
            },
            "time",
        ),
        (
            |v| v["formulation"] = serde_json::json!({"kind": "hybrid"}),
            "formulation.penalty",
        ),
        (
            |v| {
                v["materials"]["m"]["interface"] = serde_json::json!({"kind": "mohr-coulomb",
                "tensile_strength": 1e6, "cohesion": 2e6, "friction_angle": 30, "fracture_energy": 1})
            },
            "materials.m.interface.fracture_energy",
        ),
    ];
    let dir = tempfile::tempdir().unwrap();
    for (edit, key) in cases {
        let mut v = base();
        edit(&mut v);
        let file = dir.path().join("scene.json");
        std::fs::write(&file, serde_json::to_string_pretty(&v).unwrap()).unwrap();
        for result in [Scene::from_json(&v.to_string()), Scene::from_file(&file)] {
            match result {
                Err(e @ rbsm::error::Error::Scene { .. }) => {
                    let (kind, field, message) = e.parts();
                    assert_eq!((kind, field.as_str()), ("scene", key), "{message}");
                    assert!(!message.contains(" line "), "{key}: {message}");
                }
                other => panic!("{key}: {other:?}"),
            }
        }
    }
    let e = Scene::from_json("{\"name\": \"x\", \"thickness\": }").unwrap_err();
    assert_eq!(e.parts().0, "parse");
    assert!(e.to_string().contains("line 1 column 28"), "{e}");
}

/// A kind without keys of its own refuses any (serde's internally tagged unit variants would
/// drop them: `{"kind": "rigid", "penalty": 100}` ran rigid without a word).
#[test]
fn kinds_without_keys_refuse_keys() {
    expect(
        &with(|v| v["formulation"] = serde_json::json!({"kind": "rigid", "penalty": 100})),
        &["formulation", "penalty"],
    );
    expect(
        &with(|v| v["reference"] = serde_json::json!({"kind": "hopping-block", "height": 1})),
        &["reference", "height"],
    );
    expect(
        &with(|v| v["formulation"] = serde_json::json!({"kind": "hybrid", "penalty": 1, "p": 2})),
        &["formulation", "`p`"],
    );
    expect(
        &with(|v| v["formulation"] = serde_json::json!({"kind": "hybrid"})),
        &["formulation", "penalty"],
    );
    expect(
        &with(|v| v["formulation"] = serde_json::json!({"kind": "elastic"})),
        &["formulation", "elastic", "rigid, rigid-poisson, hybrid"],
    );
}

#[test]
fn material_values_out_of_range_name_field_and_range() {
    expect(
        &with(|v| v["materials"]["m"]["E"] = 0.0.into()),
        &["materials.m.E", "> 0"],
    );
    expect(
        &with(|v| v["materials"]["m"]["E"] = (-2e9).into()),
        &["materials.m.E", "> 0"],
    );
    expect(
        &with(|v| v["materials"]["m"]["nu"] = 0.5.into()),
        &["materials.m.nu", "(-1, 0.5)"],
    );
    expect(
        &with(|v| v["materials"]["m"]["nu"] = (-1.0).into()),
        &["materials.m.nu", "(-1, 0.5)"],
    );
    expect(
        &with(|v| v["materials"]["m"]["rho"] = 0.0.into()),
        &["materials.m.rho", "> 0"],
    );
}

#[test]
fn thickness_and_time_out_of_range() {
    expect(
        &with(|v| v["thickness"] = 0.0.into()),
        &["thickness", "> 0"],
    );
    expect(
        &with(|v| v["time"]["dt"] = (-1e-6).into()),
        &["time.dt", "> 0"],
    );
    expect(&with(|v| v["time"]["dt"] = 0.0.into()), &["time.dt", "> 0"]);
    expect(
        &with(|v| v["time"]["dt_factor"] = 0.5.into()),
        &["time.dt", "exactly one"],
    );
    expect(
        &with(|v| v["time"]["steps"] = 0.into()),
        &["time.steps", "≥ 1"],
    );
    expect(
        &with(|v| v["output"] = serde_json::json!({"every": 0})),
        &["output.every", "≥ 1"],
    );
}

#[test]
fn unknown_names_are_errors() {
    expect(
        &with(|v| v["bodies"][0]["material"] = "steel".into()),
        &["bodies[0].material", "unknown material `steel`", "m"],
    );
    expect(
        &with(|v| v["bodies"][0]["supports"][0]["edge"] = "middle".into()),
        &["bodies[0].supports[0].edge", "middle"],
    );
    expect(
        &with(|v| v["bodies"][0]["supports"][0]["kind"] = "glue".into()),
        &["bodies[0].supports[0]", "glue"],
    );
    expect(&with(|v| v["plane"] = "shell".into()), &["plane", "shell"]);
    expect(
        &with(|v| v["evaluator"] = "magic".into()),
        &["evaluator", "magic"],
    );
    expect(
        &with(|v| {
            v["bodies"][0]["supports"][0] =
                serde_json::json!({"edge": "left", "kind": "clamp", "dofs": ["w"]})
        }),
        &[
            "bodies[0].supports[0].dofs",
            "unknown DOF `w`",
            "u, v, theta",
        ],
    );
}

#[test]
fn wrong_types_and_malformed_json_are_named() {
    expect(
        &with(|v| v["thickness"] = "thick".into()),
        &["thickness", "invalid type"],
    );
    expect(
        &with(|v| v["bodies"][0]["mesh"]["cells"] = serde_json::json!([10])),
        &["bodies[0].mesh.cells"],
    );
    let err = Scene::from_json("{\"name\": \"x\",")
        .unwrap_err()
        .to_string();
    expect(&err, &["line 1"]);
    let err = Scene::from_file("/nonexistent/scene.json")
        .unwrap_err()
        .to_string();
    expect(&err, &["/nonexistent/scene.json"]);
}

#[test]
fn references_out_of_range() {
    expect(
        &with(|v| {
            v["bodies"][0]["loads"] =
                serde_json::json!([{"kind": "force", "element": 40, "value": [1, 0, 0]}])
        }),
        &["bodies[0].loads[0].element", "0..40"],
    );
    expect(
        &with(|v| v["output"] = serde_json::json!({"probes": [{"element": 999, "dof": "u"}]})),
        &["output.probes[0].element", "0..40"],
    );
    expect(
        &with(|v| v["bodies"][0]["mesh"]["cells"] = serde_json::json!([100000, 100000])),
        &["bodies[0].mesh.cells", "≤ 20000000"],
    );
}

#[test]
fn bad_meshes_name_the_cell() {
    let poly = |cells: Value| serde_json::json!({"kind": "polygons", "vertices": [[0, 0], [1, 0], [1, 1], [0, 1]], "cells": cells});
    expect(
        &with(|v| v["bodies"][0]["mesh"] = poly(serde_json::json!([[0, 3, 2, 1]]))),
        &["cell 0", "clockwise"],
    );
    expect(
        &with(|v| v["bodies"][0]["mesh"] = poly(serde_json::json!([[0, 1, 2, 3], [0, 1, 7]]))),
        &["cell 1", "out of range"],
    );
    // A triangle has no edge on the left side of its bounding box.
    expect(
        &with(|v| {
            v["bodies"][0]["mesh"] = poly(serde_json::json!([[0, 1, 2]]));
            v["bodies"][0]["supports"] =
                serde_json::json!([{"edge": "left", "kind": "ground-spring"}]);
        }),
        &["bodies[0].supports[0].edge", "no boundary edge"],
    );
}

#[test]
fn penalty_and_contact_settings_are_checked() {
    use serde_json::json;
    expect(
        &with(|v| v["formulation"] = json!({"kind": "hybrid", "penalty": 0.0})),
        &["formulation.penalty", "> 0"],
    );
    expect(
        &with(|v| v["ground"] = json!([{"from": [0.0, 0.0], "to": [1.0, 0.0]}])),
        &["contact", "ground segments act only through contact"],
    );
    let with_ground = |contact: serde_json::Value, ground: serde_json::Value| {
        with(move |v| {
            v["contact"] = contact;
            v["ground"] = ground;
        })
    };
    let ground = json!([{"from": [0.0, 0.0], "to": [1.0, 0.0]}]);
    expect(
        &with_ground(json!({"model": "dem"}), ground.clone()),
        &["contact.model", "edge-to-edge", "point"],
    );
    expect(
        &with_ground(json!({"model": "point", "friction": -0.1}), ground.clone()),
        &["contact.friction", "μ ≥ 0"],
    );
    expect(
        &with_ground(
            json!({"model": "point"}),
            json!([{"from": [1.0, 2.0], "to": [1.0, 2.0]}]),
        ),
        &["ground[0].to", "positive length"],
    );
}

/// Every number of every shipped scene pushed to an extreme, every key deleted, every string
/// replaced: the pipeline answers with `Ok` or an error, never a panic, and never a NaN time step.
#[test]
fn no_panic_on_mutated_scenes() {
    let dir = format!("{}/examples/scenes", env!("CARGO_MANIFEST_DIR"));
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let original: Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let mut mutants = Vec::new();
        mutate(&original, &mut Vec::new(), &original, &mut mutants);
        assert!(
            mutants.len() > 50,
            "{}: only {} mutants",
            path.display(),
            mutants.len()
        );
        for m in mutants {
            let text = m.to_string();
            let outcome = std::panic::catch_unwind(|| {
                let scene = Scene::from_json(&text)?;
                Model::build(&scene)?;
                let p = Setup::new(&scene, &Overrides::default())?;
                assert!(
                    p.dt.is_finite() && p.dt > 0.0,
                    "time step {} for {text}",
                    p.dt
                );
                Ok::<(), rbsm::error::Error>(())
            });
            assert!(outcome.is_ok(), "panic on {text}");
        }
    }
}

/// Collects the mutants of `root`: for the node at `path`, extremes for numbers, a bogus
/// string, deletion of each object key.
fn mutate(node: &Value, path: &mut Vec<Value>, root: &Value, out: &mut Vec<Value>) {
    let replace = |new: Value, out: &mut Vec<Value>| {
        let mut m = root.clone();
        *pointer(&mut m, path) = new;
        out.push(m);
    };
    match node {
        Value::Number(_) => {
            for x in [0.0, -1.0, 1e-300, 1e300, 0.49999, 3.0] {
                replace(x.into(), out);
            }
            for x in [0u64, 1, 7, 1_000_000_000] {
                replace(x.into(), out);
            }
        }
        Value::String(_) => replace("bogus".into(), out),
        Value::Array(items) => {
            replace(Value::Array(Vec::new()), out);
            for (i, item) in items.iter().enumerate() {
                path.push(i.into());
                mutate(item, path, root, out);
                path.pop();
            }
        }
        Value::Object(map) => {
            for (k, item) in map {
                let mut m = root.clone();
                pointer(&mut m, path).as_object_mut().unwrap().remove(k);
                out.push(m);
                path.push(k.clone().into());
                mutate(item, path, root, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn pointer<'v>(v: &'v mut Value, path: &[Value]) -> &'v mut Value {
    path.iter().fold(v, |v, k| match k {
        Value::String(s) => &mut v[s.as_str()],
        Value::Number(n) => &mut v[n.as_u64().unwrap() as usize],
        _ => unreachable!(),
    })
}

/// A file that never ends, a FIFO or a file past the largest scene size is refused by what its
/// metadata says, before anything is read (docs/scene.md, *Top level*, on the size): a FIFO without
/// a writer would block the reader, and a 1 GiB file was read whole before its refusal.
#[cfg(unix)]
#[test]
fn a_device_a_fifo_or_a_huge_file_is_not_a_scene() {
    let e = Scene::from_file("/dev/zero").unwrap_err().to_string();
    assert!(
        e.contains("/dev/zero") && e.contains("not a regular file (a device)"),
        "{e}"
    );
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("scene.json");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success());
    let e = Scene::from_file(&fifo).unwrap_err().to_string();
    assert!(e.contains("not a regular file (a FIFO)"), "{e}");
    // A sparse file: its size is known without reading it, and the message gives it.
    let big = dir.path().join("big.json");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(1 << 30)
        .unwrap();
    let e = Scene::from_file(&big).unwrap_err().to_string();
    assert!(e.contains("1073741824 bytes, larger than 256 MiB"), "{e}");
    // A gmsh mesh that is a FIFO or a device is named as such, not as a missing file.
    for path in [fifo.to_str().unwrap(), "/dev/zero"] {
        let e = with(|v| {
            v["bodies"][0]["mesh"] = serde_json::json!({"kind": "gmsh", "path": path});
        });
        expect(&e, &["bodies[0].mesh.path", "is not a regular file"]);
    }
}

/// A softening law whose slope `f_t²/(2 G_f)` overflows (or whose exhausting opening
/// `2 G_f/f_t` underflows) is refused naming its keys; it used to break every
/// interface at the first step with NaN energies.
#[test]
fn a_softening_slope_that_overflows_is_refused() {
    let softening = |f_t: f64, g_f: f64, c: f64, g_s: f64| {
        with(|v| {
            v["materials"]["m"]["interface"] = serde_json::json!({"kind": "softening",
                "tensile_strength": f_t, "cohesion": c, "friction_angle": 30,
                "fracture_energy": g_f, "fracture_energy_shear": g_s});
        })
    };
    for (f_t, g_f) in [(1e308, 2.3e-308), (1e300, 1e-300), (1e160, 1.0)] {
        let e = softening(f_t, g_f, 1e6, 100.0);
        expect(
            &e,
            &[
                "materials.m.interface.fracture_energy`",
                "`tensile_strength`",
                "softening slope",
            ],
        );
    }
    let e = softening(3e6, 100.0, 1e300, 1e-300);
    expect(
        &e,
        &["materials.m.interface.fracture_energy_shear`", "`cohesion`"],
    );
    // The least energy it names passes.
    let e = softening(1e160, 1.0, 1e6, 100.0);
    let least: f64 = e
        .split("must be ≥ ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    let mut v = base();
    v["materials"]["m"]["interface"] = serde_json::json!({"kind": "softening",
        "tensile_strength": 1e160, "cohesion": 1e6, "friction_angle": 30,
        "fracture_energy": least, "fracture_energy_shear": 100.0});
    Scene::from_json(&v.to_string()).unwrap();
    // An energy so large that the exhausting opening overflows is refused by an upper bound,
    // which passes; it used to name a lower bound the energy already met.
    let e = softening(3e6, 9e307, 1e6, 100.0);
    expect(
        &e,
        &["materials.m.interface.fracture_energy`", "must be ≤ "],
    );
    let most: f64 = e
        .split("must be ≤ ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    assert!(most < 9e307, "{e}");
    v["materials"]["m"]["interface"]["tensile_strength"] = 3e6.into();
    v["materials"]["m"]["interface"]["fracture_energy"] = most.into();
    Scene::from_json(&v.to_string()).unwrap();
}

/// Two bodies of one name, or a body named as a copy of an array, are refused naming the
/// second: `history.csv` had a clamp's columns twice.
#[test]
fn duplicate_body_names_are_refused() {
    let e = with(|v| {
        let body = v["bodies"][0].clone();
        v["bodies"].as_array_mut().unwrap().push(body);
        v["bodies"][1]["mesh"]["origin"] = serde_json::json!([5.0, 0.0]);
    });
    expect(
        &e,
        &["`bodies[1].name`", "`b` is the name of `bodies[0]` too"],
    );
    let e = with(|v| {
        let mut body = v["bodies"][0].clone();
        body["name"] = "b[1,0]".into();
        body["mesh"]["origin"] = serde_json::json!([5.0, 0.0]);
        v["bodies"][0]["array"] = serde_json::json!({"count": [2, 1], "pitch": [2.0, 0.0]});
        v["bodies"].as_array_mut().unwrap().push(body);
    });
    expect(&e, &["`bodies[1].name`", "a copy of `bodies[0]`"]);
    // Outside the array's counts the name is no copy's, but its comma is refused as any
    // body name's is (`body_names_follow_the_column_rule`).
    let e = with(|v| {
        let mut body = v["bodies"][0].clone();
        body["name"] = "b[2,0]".into();
        body["mesh"]["origin"] = serde_json::json!([9.0, 0.0]);
        v["bodies"][0]["array"] = serde_json::json!({"count": [2, 1], "pitch": [2.0, 0.0]});
        v["bodies"].as_array_mut().unwrap().push(body);
    });
    expect(&e, &["`bodies[1].name`", "without commas"]);
}

/// Names of the scene, its bodies and its probes are at most 256 characters (docs/scene.md):
/// a probe name of 10⁶ characters was accepted.
#[test]
fn names_are_bounded() {
    let at_most = format!("at most {} characters", rbsm::input::scene::MAX_NAME);
    let long = "x".repeat(1_000_000);
    let e = with(|v| v["name"] = long.clone().into());
    expect(&e, &["`name`", &at_most, "got 1000000"]);
    let e = with(|v| v["bodies"][0]["name"] = long.clone().into());
    expect(&e, &["`bodies[0].name`", &at_most]);
    let e = with(|v| {
        v["output"]["probes"] =
            serde_json::json!([{"name": long.clone(), "element": 0, "dof": "u"}])
    });
    expect(&e, &["`output.probes[0].name`", &at_most]);
    // 256 characters pass, also counted as characters, not bytes.
    let mut v = base();
    v["name"] = "é".repeat(rbsm::input::scene::MAX_NAME).into();
    v["bodies"][0]["name"] = "b".repeat(rbsm::input::scene::MAX_NAME).into();
    Scene::from_json(&v.to_string()).unwrap();
}

/// `array` copies a body on a pattern, each copy a body of its own; bad counts name the key.
#[test]
fn array_makes_named_shifted_copies() {
    let scene = |array: &str| {
        Scene::from_json(&format!(
            r#"{{"name": "a", "thickness": 1.0, "formulation": {{"kind": "rigid"}}, "materials": {{"m": {{"E": 1e9, "nu": 0.2, "rho": 1000}}}},
                "bodies": [{{"name": "b", "material": "m", "mesh": {{"kind": "grid", "origin": [1, 2], "size": [1, 1], "cells": [1, 1]}}, "array": {array}}}],
                "time": {{"dt": 1e-6, "steps": 1}}}}"#
        ))
    };
    let s = scene(r#"{"count": [3, 2], "pitch": [1.5, 1.0], "row_offset": 0.25}"#).unwrap();
    assert_eq!(s.bodies.len(), 6);
    assert_eq!(s.bodies[4].name, "b[1,1]");
    match &s.bodies[4].mesh {
        rbsm::input::scene::MeshSpec::Grid(g) => assert_eq!(g.origin, [1.0 + 1.5 + 0.25, 3.0]),
        other => panic!("{other:?}"),
    }
    let e = scene(r#"{"count": [0, 2], "pitch": [1, 1]}"#)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bodies[0].array.count") && e.contains("≥ 1"),
        "{e}"
    );
}

/// A key repeated inside one object is refused with its path (README, *Scenes*): JSON parsers
/// keep one of the two silently.
#[test]
fn repeated_keys_are_refused_everywhere() {
    let text = base().to_string();
    let cases = [
        (
            r#""materials":{"#,
            r#""materials":{"m":{"E":1.0,"nu":0.2,"rho":1.0},"#,
            "`materials.m`",
        ),
        (
            r#""mesh":{"#,
            r#""mesh":{"cells":[2,2],"#,
            "`bodies[0].mesh.cells`",
        ),
        (
            r#""supports":[{"#,
            r#""supports":[{"edge":"top","#,
            "`bodies[0].supports[0].edge`",
        ),
        (r#""name":"#, r#""name":"a","name":"#, "`bodies[0].name`"),
    ];
    for (at, with, field) in cases {
        assert!(text.contains(at), "{at} not in {text}");
        let e = Scene::from_json(&text.replacen(at, with, 1))
            .unwrap_err()
            .to_string();
        expect(&e, &[field, "appears twice"]);
    }
}

/// Probe names become `history.csv` headers: no commas, quotes or newlines, none of the
/// energy columns, no repeats (docs/scene.md, *`probes`*).
#[test]
fn probe_names_must_make_a_valid_header() {
    let probe = |name: Value| serde_json::json!({"name": name, "element": 0, "dof": "u"});
    for bad in ["a,b", "two\nlines", "", "t", "total", "say \"x\""] {
        let e = with(|v| v["output"]["probes"] = Value::Array(vec![probe(bad.into())]));
        expect(&e, &["output.probes[0].name"]);
    }
    let e =
        with(|v| v["output"]["probes"] = Value::Array(vec![probe("x".into()), probe("x".into())]));
    expect(&e, &["output.probes[1].name", "`x`", "output.probes[0]"]);
    // A default name (`e0_u`) counts too.
    let e = with(
        |v| v["output"]["probes"] = serde_json::json!([{"element": 0, "dof": "u"}, {"name": "e0_u", "element": 1, "dof": "u"}]),
    );
    expect(&e, &["output.probes[1].name", "e0_u"]);
}

/// `--steps 0` is refused like `time.steps: 0`.
#[test]
fn zero_steps_are_refused_from_the_command_line_too() {
    let scene = Scene::from_json(&base().to_string()).unwrap();
    let e = Setup::new(
        &scene,
        &Overrides {
            steps: Some(0),
            ..Default::default()
        },
    )
    .err()
    .unwrap()
    .to_string();
    expect(&e, &["--steps", "≥ 1"]);
}

/// Messages blame the input at fault: a subnormal density or thickness is
/// refused as such (it was blamed on the hybrid formulation's mass on a rigid grid), an
/// overflowing penalty names the penalty (it was blamed on `materials`).
#[test]
fn messages_blame_the_input_at_fault() {
    expect(
        &with(|v| v["materials"]["m"]["rho"] = 1e-320.into()),
        &["materials.m.rho", "smallest normal"],
    );
    expect(
        &with(|v| v["thickness"] = 1e-320.into()),
        &["`thickness`", "smallest normal"],
    );
    expect(
        &with(|v| v["formulation"] = serde_json::json!({"kind": "hybrid", "penalty": 1e300})),
        &["formulation.penalty", "overflow"],
    );
    expect(
        &with(|v| v["materials"]["m"]["E"] = 1e300.into()),
        &["materials.m.E", "overflow"],
    );
}

/// A polygon cell shaped like an 8 (two lobes meeting at a point) is refused.
#[test]
fn a_figure_eight_cell_is_refused() {
    let e = with(|v| {
        v["bodies"][0]["mesh"] = serde_json::json!({"kind": "polygons",
            "vertices": [[0, 0], [2, 0], [1, 1], [2, 2], [0, 2], [1, 1]], "cells": [[0, 1, 2, 3, 4, 5]]});
        v["bodies"][0]["supports"] = serde_json::json!([]);
    });
    expect(&e, &["cell 0", "touches itself"]);
}

/// Messages stay short: a long value is echoed cut, not whole.
#[test]
fn messages_are_cut_to_a_useful_length() {
    let long = "x".repeat(50_000);
    let e = with(|v| v["bodies"][0]["material"] = long.clone().into());
    assert!(
        e.len() < 2 * rbsm::error::MAX_MESSAGE + 200 && e.contains("more characters"),
        "{} bytes",
        e.len()
    );
    let e = with(|v| v["bodies"][0]["mesh"]["kind"] = long.clone().into());
    assert!(
        e.len() < 2 * rbsm::error::MAX_MESSAGE + 200,
        "{} bytes",
        e.len()
    );
}

/// A model too large for the memory the process may take is refused with the estimate and
/// what is available, where it used to abort when an allocation failed.
#[cfg(target_os = "linux")]
#[test]
fn a_model_too_large_for_memory_is_refused_before_it_is_built() {
    let dir = tempfile::tempdir().unwrap();
    for cells in [[2000, 2000], [1, 20_000_000]] {
        let mut v = base();
        v["bodies"][0]["mesh"]["cells"] = serde_json::json!(cells);
        let path = dir.path().join("big.json");
        std::fs::write(&path, v.to_string()).unwrap();
        // 4 GB of address space, as `ulimit -v 4000000` gives.
        let out = std::process::Command::new("sh")
            .arg("-c")
            .arg(format!(
                "ulimit -v 4000000 && exec '{}' check '{}'",
                env!("CARGO_BIN_EXE_rbsm"),
                path.display()
            ))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{cells:?}: {err}");
        expect(&err, &["`bodies`", "needs about", "GiB is available"]);
    }
}

/// A ground spring on part of a side (`span`): a beam of 20 × 2 cells on two pads 0.1 m long
/// at its ends rests on the two cells under each pad, and under a uniform load it deflects
/// symmetrically; a span that holds no edge, or is not `from < to`, is refused with its key.
#[test]
fn ground_springs_on_part_of_a_side() {
    let beam = |supports: Value| {
        serde_json::json!({
            "name": "pads", "thickness": 0.1, "formulation": {"kind": "rigid"},
            "materials": {"c": {"E": 3e10, "nu": 0.2, "rho": 2400}},
            "bodies": [{"name": "beam", "material": "c",
                "mesh": {"kind": "grid", "origin": [0, 0], "size": [1.0, 0.1], "cells": [20, 2]},
                "supports": supports,
                "loads": [{"kind": "traction", "edge": "top", "value": [0.0, -1.0e5]}]}],
            "time": {"dt_factor": 0.5, "steps": 10}
        })
    };
    let pads = serde_json::json!([
        {"kind": "ground-spring", "edge": "bottom", "span": [0.0, 0.1]},
        {"kind": "ground-spring", "edge": "bottom", "span": [0.9, 1.0]}]);
    let scene = Scene::from_json(&beam(pads).to_string()).unwrap();
    let setup = Setup::new(&scene, &Overrides::default()).unwrap();
    let grounded: Vec<f64> = setup
        .model
        .interfaces
        .iter()
        .filter(|i| i.b == rbsm::model::GROUND)
        .map(|i| 0.5 * (i.p1.x + i.p2.x))
        .collect();
    assert_eq!(grounded.len(), 4, "{grounded:?}");
    for (x, want) in grounded.iter().zip([0.025, 0.075, 0.925, 0.975]) {
        assert!((x - want).abs() < 1e-12, "{grounded:?}");
    }
    let report = rbsm::analysis::statics::analyse(&setup).unwrap();
    let v = |x: f64| {
        let e = report
            .elements
            .iter()
            .find(|e| (e.centroid[0] - x).abs() < 1e-9 && e.centroid[1] < 0.05)
            .unwrap();
        e.u[1]
    };
    assert!(v(0.475) < 0.0, "the beam sags");
    assert!((v(0.275) - v(0.725)).abs() <= 1e-9 * v(0.475).abs());
    // A strip narrower than a cell: part of one edge, on the same line.
    let strip = beam(serde_json::json!([
        {"kind": "ground-spring", "edge": "bottom", "span": [0.31, 0.32]},
        {"kind": "ground-spring", "edge": "bottom", "span": [0.74, 0.76], "components": ["n"]}]));
    let setup = Setup::new(
        &Scene::from_json(&strip.to_string()).unwrap(),
        &Overrides::default(),
    )
    .unwrap();
    let held: Vec<(f64, f64, f64)> = setup
        .model
        .interfaces
        .iter()
        .filter(|i| i.b == rbsm::model::GROUND)
        .map(|i| (i.p1.x.min(i.p2.x), i.p1.x.max(i.p2.x), i.length))
        .collect();
    let want = [(0.31, 0.32), (0.74, 0.75), (0.75, 0.76)];
    assert_eq!(held.len(), want.len(), "{held:?}");
    for (h, w) in held.iter().zip(want) {
        assert!(
            (h.0 - w.0).abs() < 1e-12 && (h.1 - w.1).abs() < 1e-12 && (h.2 - 0.01).abs() < 1e-12,
            "{held:?}"
        );
    }
    let none = beam(serde_json::json!([
        {"kind": "ground-spring", "edge": "bottom", "span": [1.5, 1.6]}]));
    expect(
        &error_of(&none),
        &["bodies[0].supports[0].span", "no edge of side", "overlaps"],
    );
    let reversed = beam(serde_json::json!([
        {"kind": "ground-spring", "edge": "bottom", "span": [0.5, 0.1]}]));
    expect(
        &error_of(&reversed),
        &["bodies[0].supports[0].span", "from < to"],
    );
}

/// `tension_bar.json` with `sites` Voronoi cells, failing interfaces, edge-to-edge contact and
/// a ground below: a body that fragments (every element a contact target, every edge a source).
fn fragmenting_bar(dir: &std::path::Path, sites: u64) -> std::path::PathBuf {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/tension_bar.json"
    ))
    .unwrap();
    let mut v: Value = serde_json::from_str(&text).unwrap();
    v["bodies"][0]["mesh"]["sites"] = sites.into();
    v["contact"] = serde_json::json!({"model": "edge-to-edge"});
    v["ground"] = serde_json::json!([{"from": [-1, -0.001], "to": [1, -0.001]}]);
    let path = dir.join(format!("bar{sites}.json"));
    std::fs::write(&path, v.to_string()).unwrap();
    path
}

/// `rbsm run SCENE --steps 2 --threads 2` under `ulimit -v limit_kb`: exit code and standard
/// error.
fn run_limited(
    scene: &std::path::Path,
    out: &std::path::Path,
    limit_kb: u64,
) -> (Option<i32>, String) {
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {limit_kb} && exec '{}' run '{}' --steps 2 --threads 2 --quiet --out '{}'",
            env!("CARGO_BIN_EXE_rbsm"),
            scene.display(),
            out.display()
        ))
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// Failing interfaces with edge-to-edge contact are in the estimate, which bounds the address
/// space a run takes: the 10⁵-cell bar that aborted under 0.8 GB ("memory
/// allocation of 9574704 bytes failed", exit 134; the estimate left the fragments out and
/// each thread reserved a malloc arena) is refused with both figures; a 2·10⁴-cell bar runs
/// under a limit of the estimate it is refused with, and is refused under less.
#[cfg(target_os = "linux")]
#[test]
fn a_body_that_fragments_is_refused_when_it_does_not_fit() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let (code, err) = run_limited(&fragmenting_bar(dir.path(), 100_000), &out, 800_000);
    assert_eq!(code, Some(1), "{err}");
    expect(
        &err,
        &[
            "`bodies`",
            "100000 elements",
            "needs about",
            "GiB is available",
        ],
    );
    // The small bar: the figure it is refused with under too little room...
    let small = fragmenting_bar(dir.path(), 20_000);
    let (code, err) = run_limited(&small, &out, 100_000);
    assert_eq!(code, Some(1), "{err}");
    let need: f64 = err
        .split("needs about ")
        .nth(1)
        .and_then(|rest| rest.split(" GiB").next())
        .and_then(|x| x.parse().ok())
        .unwrap_or_else(|| panic!("no figure in `{err}`"));
    // ...is enough to run it, with the room the process held before the estimate (its code
    // and libraries: 20 MB; the figure is rounded to 10 MB).
    let kb = (need * (1u64 << 20) as f64) as u64 + 40_000;
    let (code, err) = run_limited(&small, &out, kb);
    assert_eq!(code, Some(0), "refused or aborted under {kb} kB: {err}");
}

/// A body name heads its moving clamps' columns of `history.csv` (`<body>_s<k>_disp`), so it
/// follows the probes' rule (docs/scene.md, *Bodies*): a comma split the columns, a quote or a
/// control character broke the CSV. An array's copies are named `name[i,j]`, so a body with
/// an `array` can have no moving clamp.
#[test]
fn body_names_follow_the_column_rule() {
    for name in ["bar,1", "bar\"", "bar\n", "bar\u{7}", ""] {
        let e = with(|v| v["bodies"][0]["name"] = name.into());
        expect(
            &e,
            &["bodies[0].name", "commas, quotes or control characters"],
        );
    }
    // The same rule, word for word, as the probes'.
    let e = with(|v| {
        v["output"]["probes"] = serde_json::json!([{"name": "a,b", "element": 0, "dof": "u"}]);
    });
    expect(
        &e,
        &[
            "output.probes[0].name",
            "commas, quotes or control characters",
        ],
    );
    let clamps = serde_json::json!([
        {"kind": "clamp", "edge": "left"},
        {"kind": "clamp", "edge": "right", "velocity": [0.01, 0.0]}
    ]);
    let e = with(|v| {
        v["bodies"][0]["supports"] = clamps.clone();
        v["bodies"][0]["array"] = serde_json::json!({"count": [2, 1], "pitch": [5.0, 0.0]});
    });
    expect(
        &e,
        &["bodies[0].supports[1].velocity", "array", "name[i,j]"],
    );
    // Without the array the scene is a good one: what is refused is the pair.
    let mut v = base();
    v["bodies"][0]["supports"] = clamps;
    v["bodies"][0]["name"] = "bar [1] (left; x=0)".into();
    Scene::from_json(&v.to_string()).unwrap();
}

/// A Voronoi mesh's `domain` out of shape or out of its rectangle is named, with the reason.
#[test]
fn bad_voronoi_domains_are_named() {
    let voronoi = |domain: Value| {
        with(|v| {
            v["bodies"][0]["mesh"] = serde_json::json!({"kind": "voronoi", "origin": [0, 0],
                "size": [1, 1], "sites": 50, "domain": domain});
        })
    };
    expect(
        &voronoi(serde_json::json!({"kind": "disk", "centre": [0.5, 0.5], "radius": 0.6})),
        &["bodies[0].mesh.domain", "outside the rectangle"],
    );
    expect(
        &voronoi(
            serde_json::json!({"kind": "disk", "centre": [0.5, 0.5], "radius": 0.4, "segments": 30}),
        ),
        &["bodies[0].mesh.domain.segments", "multiple of 4"],
    );
    expect(
        &voronoi(
            serde_json::json!({"kind": "polygon", "vertices": [[0, 0], [1, 1], [1, 0], [0, 1]]}),
        ),
        &["bodies[0].mesh.domain", "crosses itself"],
    );
    expect(
        &voronoi(serde_json::json!({"kind": "polygon", "vertices": [[0, 0], [1, 0]]})),
        &["bodies[0].mesh.domain.vertices", "at least 3"],
    );
    expect(
        &voronoi(
            serde_json::json!({"kind": "polygon", "vertices": [[0, 0], [1, 0], [0.5, 1e-12]]}),
        ),
        &["bodies[0].mesh.domain", "covers less than 1/1000"],
    );
}

/// A list where the scene wants an object is refused by that key: the reader took a list for a
/// struct's fields in order, so a contact block in brackets was "unknown variant `model`" at
/// `contact[0]`, and a `time` of `[dt, dt_factor, steps]` passed. Lists of numbers and of
/// bodies stay lists.
#[test]
fn a_list_for_an_object_is_refused_by_its_key() {
    let e = with(|v| v["contact"] = serde_json::json!([{"model": "point"}]));
    expect(&e, &["`contact`", "must be an object", "not a list"]);
    let e = with(|v| v["time"] = serde_json::json!([1e-6, null, 10]));
    expect(&e, &["`time`", "not a list"]);
    let e = with(|v| v["bodies"][0]["mesh"] = serde_json::json!(["grid", [0, 0]]));
    expect(&e, &["`bodies[0].mesh`", "not a list"]);
    let e = with(|v| v["materials"]["m"] = serde_json::json!([2e10, 0.2, 2400]));
    expect(&e, &["`materials.m`", "not a list"]);
    Scene::from_json(&base().to_string()).unwrap();
}

//! The JSON Schema of scene files (`rbsm schema`, `rbsm::input::scene::schema`) against the parser:
//! the bundled scenes validate against it, it names exactly the keys and kinds the parser
//! accepts, object by object, and the command prints the library's schema.
//!
//! How "exactly the keys" is checked: every JSON object of the bundled scenes and of the
//! scenes below (which between them use every optional key and every `kind`) is located in the
//! schema by walking the schema along the object's path. A key that no scene type knows,
//! inserted into that object, makes the parser (serde's `deny_unknown_fields`) answer
//! "unknown field `…`, expected one of `a`, `b`, …": that list is the parser's key set for the
//! object, and it must equal the `properties` of the schema found there. Likewise an unknown
//! `kind` makes the parser list its kinds, which must equal the schema's `kind` constants. Then
//! every object schema and every property in the whole schema must have been reached by some
//! scene: a field, a struct or a kind added to the scene types shows up in the parser's lists
//! or in the schema, and the test fails until both agree and a scene here uses it.

use rbsm::input::scene::Scene;
use serde_json::{json, Value};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const BOGUS: &str = "zz_not_a_key";

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes")
}

fn bundled() -> Vec<(String, Value)> {
    let mut out: Vec<(String, Value)> = std::fs::read_dir(scenes_dir())
        .expect("examples/scenes")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .map(|p| {
            let text = std::fs::read_to_string(&p).unwrap();
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                serde_json::from_str(&text).unwrap(),
            )
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    assert!(out.len() >= 9, "bundled scenes missing: {}", out.len());
    out
}

fn load(name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(scenes_dir().join(name)).unwrap()).unwrap()
}

/// Scenes that, with the bundled ones, use every optional key and every kind of the format.
fn extras() -> Vec<(String, Value)> {
    let mut all = load("cantilever.json");
    all["$schema"] = json!("./scene.schema.json");
    all["plane"] = json!("strain");
    all["evaluator"] = json!("element-wise");
    all["gravity"] = json!([0.0, -9.80665]);
    all["damping"] = json!(0.5);
    all["local_damping"] = json!(0.7);
    all["time"] = json!({"dt": 1e-6, "steps": 10, "stop_ratio": 1e-6});
    all["output"] = json!({
        "every": 5, "vtk": true, "checkpoint_every": 5,
        "probes": [{"name": "tip_v", "element": 79, "dof": "v"}, {"at": [1.0, 0.1], "dof": "u"}]
    });
    let body = &mut all["bodies"][0];
    body["initial"] =
        json!({"velocity": [0.1, 0.0], "angular_velocity": 0.01, "rotation_deg": 1.0});
    body["supports"] = json!([
        {"kind": "ground-spring", "edge": "left", "components": ["n"]},
        {"kind": "clamp", "edge": "bottom", "dofs": ["v", "theta"]},
        {"kind": "clamp", "edge": "top"}
    ]);
    body["loads"] = json!([
        {"kind": "traction", "edge": "right", "value": [0.0, -1e6], "amplitude": [[0.0, 0.0], [1e-5, 1.0]]},
        {"kind": "force", "element": 3, "value": [1.0, 2.0, 0.5], "amplitude": [[0.0, 1.0]]},
        {"kind": "force", "element": 4, "value": [1.0, 2.0, 0.5]}
    ]);

    let mut voronoi = load("voronoi_panel.json");
    voronoi["bodies"][0]["mesh"] = json!({"kind": "voronoi", "origin": [0.0, 0.0], "size": [1.0, 0.5], "sites": 40, "seed": 3, "lloyd": 2});

    let mut disk = load("voronoi_panel.json");
    disk["bodies"][0]["mesh"] = json!({"kind": "voronoi", "origin": [0.0, 0.0], "size": [1.0, 1.0], "sites": 60, "seed": 3, "lloyd": 2,
        "domain": {"kind": "disk", "centre": [0.5, 0.5], "radius": 0.5, "segments": 64}});
    let mut notched = load("voronoi_panel.json");
    notched["bodies"][0]["mesh"] = json!({"kind": "voronoi", "origin": [0.0, 0.0], "size": [1.0, 0.5], "sites": 60, "seed": 3, "lloyd": 2,
        "domain": {"kind": "polygon", "vertices": [[0, 0], [0.45, 0], [0.45, 0.1], [0.55, 0.1], [0.55, 0], [1, 0], [1, 0.5], [0, 0.5]]}});

    let mut polygons = load("cantilever.json");
    polygons["bodies"][0]["mesh"] = json!({"kind": "polygons", "vertices": [[0, 0], [1, 0], [1, 1], [0, 1], [2, 0], [2, 1]], "cells": [[0, 1, 2, 3], [1, 4, 5, 2]]});
    polygons["bodies"][0]["array"] =
        json!({"count": [2, 3], "pitch": [2.5, 1.5], "row_offset": 0.5});
    polygons["output"] = json!({});

    let mut hybrid = load("cantilever.json");
    hybrid["formulation"] = json!({"kind": "hybrid", "penalty": 100.0});
    hybrid["materials"]["concrete"]["element"] =
        json!({"kind": "mohr-coulomb", "cohesion": 3e6, "friction_angle": 30});
    hybrid["bodies"][0]["mesh"]["cell"] = json!("tri");
    hybrid["output"]["probes"] =
        json!([{"name": "tip_v", "element": 79, "dof": "v"}, {"element": 3, "dof": "gxy"}]);
    hybrid["bodies"][0]["supports"] =
        json!([{"kind": "clamp", "edge": "left", "dofs": ["u", "v", "theta", "ex", "ey", "gxy"]}]);

    let mut contact = load("hopping_block.json");
    contact["contact"] = json!({"model": "point", "friction": 0.3});
    contact["reference"] = json!({"kind": "hopping-block"});

    let mut plastic = load("tension_bar.json");
    plastic["materials"]["concrete"]["interface"] = json!({"kind": "mohr-coulomb",
        "tensile_strength": 1e6, "cohesion": 2e6, "friction_angle": 35});
    plastic["bodies"][0]["supports"][1]["span"] = json!([0.0, 0.05]);
    let mut facet = load("tension_bar.json");
    facet["materials"]["concrete"]["interface"] = json!({"kind": "facet",
        "tensile_strength": 3e6, "shear_strength": 8.1e6, "fracture_energy": 100,
        "fracture_energy_shear": 1000, "compressive_strength": 3e7, "cap_hardening": 3e11,
        "friction": 0.6, "friction_residual": 0.1, "friction_pressure": 1e7});
    let mut elastic = load("tension_bar.json");
    elastic["materials"]["concrete"]["interface"] = json!({"kind": "elastic"});
    elastic["materials"]["concrete"]["element"] = json!({"kind": "elastic"});
    elastic["bodies"][0]["supports"][0] =
        json!({"kind": "ground-spring", "edge": "left", "span": [0.0, 0.05]});

    let mut minimal = load("cantilever.json");
    for key in ["plane", "evaluator", "output"] {
        minimal.as_object_mut().unwrap().remove(key);
    }
    minimal["bodies"][0] = json!({"name": "b", "material": "concrete", "mesh": {"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [2, 2]}});

    [
        ("all optional keys", all),
        ("voronoi", voronoi),
        ("voronoi disk", disk),
        ("voronoi notched", notched),
        ("polygons array", polygons),
        ("hybrid", hybrid),
        ("point contact", contact),
        ("mohr-coulomb", plastic),
        ("facet", facet),
        ("elastic law", elastic),
        ("minimal", minimal),
    ]
    .into_iter()
    .map(|(n, v)| (n.to_string(), v))
    .chain(std::iter::once((
        "docs/scene.md example".to_string(),
        docs_example(),
    )))
    .collect()
}

/// The complete minimal example of `docs/scene.md` (the first ```json block).
fn docs_example() -> Value {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/scene.md"))
        .expect("docs/scene.md");
    let start = text
        .find("```json\n")
        .expect("a ```json block in docs/scene.md")
        + 8;
    let end = start + text[start..].find("```").unwrap();
    serde_json::from_str(&text[start..end]).expect("the example of docs/scene.md is JSON")
}

fn all_scenes() -> Vec<(String, Value)> {
    bundled().into_iter().chain(extras()).collect()
}

fn parse(scene: &Value) -> rbsm::error::Result<Scene> {
    Scene::from_json_in(&scene.to_string(), &scenes_dir())
}

fn validator(schema: &Value) -> jsonschema::Validator {
    jsonschema::validator_for(schema).expect("the schema compiles")
}

fn schema_errors(v: &jsonschema::Validator, scene: &Value) -> Vec<String> {
    v.iter_errors(scene)
        .map(|e| format!("{}: {e}", e.instance_path()))
        .collect()
}

#[test]
fn the_schema_is_a_valid_draft_2020_12_schema() {
    let schema = rbsm::input::scene::schema();
    assert_eq!(
        schema["$schema"],
        "https://json-schema.org/draft/2020-12/schema"
    );
    if let Err(e) = jsonschema::meta::validate(&schema) {
        panic!("not a valid JSON Schema: {e}");
    }
}

#[test]
fn bundled_scenes_validate_against_the_schema() {
    let v = validator(&rbsm::input::scene::schema());
    for (name, scene) in bundled() {
        let errors = schema_errors(&v, &scene);
        assert!(errors.is_empty(), "{name} fails the schema: {errors:#?}");
        Scene::from_file(scenes_dir().join(&name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn scenes_with_every_optional_key_parse_and_validate_against_the_schema() {
    let v = validator(&rbsm::input::scene::schema());
    for (name, scene) in extras() {
        let errors = schema_errors(&v, &scene);
        assert!(errors.is_empty(), "{name} fails the schema: {errors:#?}");
        if let Err(e) = parse(&scene) {
            panic!("{name} is refused by the parser: {e}");
        }
    }
}

#[test]
fn the_schema_refuses_what_the_parser_refuses_by_shape_or_simple_range() {
    let v = validator(&rbsm::input::scene::schema());
    let base = load("cantilever.json");
    type Edit = Box<dyn Fn(&mut Value)>;
    let cases: Vec<(&str, Edit)> = vec![
        (
            "unknown top-level key",
            Box::new(|s| s["colour"] = json!("red")),
        ),
        (
            "unknown key in a mesh",
            Box::new(|s| s["bodies"][0]["mesh"]["cels"] = json!(3)),
        ),
        (
            "unknown mesh kind",
            Box::new(|s| s["bodies"][0]["mesh"]["kind"] = json!("hexagons")),
        ),
        (
            "a mesh without kind",
            Box::new(|s| {
                drop(
                    s["bodies"][0]["mesh"]
                        .as_object_mut()
                        .unwrap()
                        .remove("kind"),
                )
            }),
        ),
        (
            "a voronoi key in a grid",
            Box::new(|s| s["bodies"][0]["mesh"]["sites"] = json!(10)),
        ),
        (
            "nu = 0.5",
            Box::new(|s| s["materials"]["concrete"]["nu"] = json!(0.5)),
        ),
        (
            "E = 0",
            Box::new(|s| s["materials"]["concrete"]["E"] = json!(0)),
        ),
        ("thickness < 0", Box::new(|s| s["thickness"] = json!(-0.1))),
        ("no materials", Box::new(|s| s["materials"] = json!({}))),
        ("no bodies", Box::new(|s| s["bodies"] = json!([]))),
        (
            "zero cells",
            Box::new(|s| s["bodies"][0]["mesh"]["cells"] = json!([0, 8])),
        ),
        (
            "both dt and dt_factor",
            Box::new(|s| s["time"]["dt"] = json!(1e-6)),
        ),
        (
            "neither end nor steps",
            Box::new(|s| drop(s["time"].as_object_mut().unwrap().remove("end"))),
        ),
        (
            "steps = 0",
            Box::new(|s| s["time"] = json!({"dt": 1e-6, "steps": 0})),
        ),
        ("every = 0", Box::new(|s| s["output"]["every"] = json!(0))),
        (
            "probe with element and at",
            Box::new(|s| s["output"]["probes"][0]["at"] = json!([0.1, 0.1])),
        ),
        (
            "probe of an unknown DOF",
            Box::new(|s| s["output"]["probes"][0]["dof"] = json!("w")),
        ),
        (
            "unknown contact model",
            Box::new(|s| s["contact"] = json!({"model": "mortar"})),
        ),
        (
            "negative friction",
            Box::new(|s| s["contact"] = json!({"model": "point", "friction": -0.1})),
        ),
        (
            "hybrid without penalty",
            Box::new(|s| s["formulation"] = json!({"kind": "hybrid"})),
        ),
        (
            "rigid with a penalty",
            Box::new(|s| s["formulation"] = json!({"kind": "rigid", "penalty": 3})),
        ),
        (
            "$schema not a string",
            Box::new(|s| s["$schema"] = json!(3)),
        ),
    ];
    for (what, edit) in cases {
        let mut scene = base.clone();
        edit(&mut scene);
        assert!(
            !v.is_valid(&scene),
            "the schema accepts a scene with {what}"
        );
        let built = parse(&scene).and_then(|s| rbsm::model::Model::build(&s).map(|_| ()));
        assert!(built.is_err(), "rbsm accepts a scene with {what}");
    }
    // `null` for an optional key is "absent" to the parser, and so to the schema.
    let mut scene = base.clone();
    scene["time"] = json!({"dt": null, "dt_factor": 0.9, "end": 0.1, "steps": null});
    assert!(v.is_valid(&scene), "{:?}", schema_errors(&v, &scene));
    parse(&scene).unwrap();
}

/// One step of a path into a scene.
#[derive(Clone, Debug)]
enum Step {
    Key(String),
    Index(usize),
}

fn at_mut<'a>(value: &'a mut Value, path: &[Step]) -> &'a mut Value {
    path.iter().fold(value, |v, s| match s {
        Step::Key(k) => &mut v[k.as_str()],
        Step::Index(i) => &mut v[*i],
    })
}

fn path_text(path: &[Step]) -> String {
    path.iter()
        .map(|s| match s {
            Step::Key(k) => format!(".{k}"),
            Step::Index(i) => format!("[{i}]"),
        })
        .collect()
}

/// The schema with its location (a JSON pointer into the schema document).
struct Located<'a> {
    schema: &'a Value,
    pointer: String,
}

/// Follows `$ref`, picks the non-null branch of an optional value (`anyOf` with `null`) and
/// the branch of a `kind`-keyed `oneOf` whose `kind` constant is the instance's.
fn resolve<'a>(root: &'a Value, mut here: Located<'a>, instance: &Value) -> Located<'a> {
    loop {
        if let Some(r) = here.schema.get("$ref").and_then(Value::as_str) {
            let pointer = r.strip_prefix('#').expect("local $ref");
            here = Located {
                schema: root
                    .pointer(pointer)
                    .unwrap_or_else(|| panic!("dangling {r}")),
                pointer: pointer.to_string(),
            };
        } else if let Some(any) = here.schema.get("anyOf").and_then(Value::as_array) {
            let (i, branch) = any
                .iter()
                .enumerate()
                .find(|(_, b)| b.get("type") != Some(&json!("null")))
                .expect("a non-null branch");
            here = Located {
                schema: branch,
                pointer: format!("{}/anyOf/{i}", here.pointer),
            };
        } else if let (Some(one), Some(kind)) = (
            here.schema.get("oneOf").and_then(Value::as_array),
            instance.get("kind"),
        ) {
            let found = one
                .iter()
                .enumerate()
                .find(|(_, b)| b.pointer("/properties/kind/const") == Some(kind));
            let (i, branch) =
                found.unwrap_or_else(|| panic!("no branch of {} for kind {kind}", here.pointer));
            here = Located {
                schema: branch,
                pointer: format!("{}/oneOf/{i}", here.pointer),
            };
        } else {
            return here;
        }
    }
}

/// Every object of `instance` (with its path) and the schema that governs it.
fn walk<'a>(
    root: &'a Value,
    here: Located<'a>,
    instance: &Value,
    path: Vec<Step>,
    out: &mut Vec<(Vec<Step>, Located<'a>)>,
) {
    let here = resolve(root, here, instance);
    let child = |step: Step| {
        let mut p = path.clone();
        p.push(step);
        p
    };
    match instance {
        Value::Object(map) => {
            let props = here.schema.get("properties");
            for (key, value) in map {
                let sub = match props.and_then(|p| p.get(key)) {
                    Some(s) => Located {
                        schema: s,
                        pointer: format!("{}/properties/{key}", here.pointer),
                    },
                    None => {
                        let extra = here
                            .schema
                            .get("additionalProperties")
                            .filter(|a| a.is_object());
                        let extra = extra.unwrap_or_else(|| {
                            panic!(
                                "{}: key `{key}` not in the schema at {}",
                                path_text(&path),
                                here.pointer
                            )
                        });
                        Located {
                            schema: extra,
                            pointer: format!("{}/additionalProperties", here.pointer),
                        }
                    }
                };
                walk(root, sub, value, child(Step::Key(key.clone())), out);
            }
            out.push((path, here));
        }
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                let s = here.schema.get("items").unwrap_or_else(|| {
                    panic!("{}: no items in {}", path_text(&path), here.pointer)
                });
                walk(
                    root,
                    Located {
                        schema: s,
                        pointer: format!("{}/items", here.pointer),
                    },
                    item,
                    child(Step::Index(i)),
                    out,
                );
            }
        }
        _ => {}
    }
}

/// The names the parser lists after "expected" in `message` (serde: "expected `a`",
/// "expected `a` or `b`", "expected one of `a`, `b`"; the kind dispatch: "expected one of: a,
/// b"; no fields: "there are no fields").
fn expected_list(message: &str) -> BTreeSet<String> {
    assert!(!message.contains('…'), "message cut short: {message}");
    if message.contains("there are no fields") {
        return BTreeSet::new();
    }
    let rest = &message[message
        .find("expected")
        .unwrap_or_else(|| panic!("no list in: {message}"))
        + "expected".len()..];
    let rest = rest.split(" at line ").next().unwrap();
    let rest = rest
        .trim_start()
        .trim_start_matches("one of")
        .trim_start_matches(':');
    rest.split(", ")
        .flat_map(|p| p.split(" or "))
        .map(|p| p.trim().trim_matches('`').to_string())
        .filter(|p| !p.is_empty())
        .collect()
}

fn keys(schema: &Value) -> BTreeSet<String> {
    schema
        .get("properties")
        .and_then(Value::as_object)
        .map(|p| p.keys().cloned().collect())
        .unwrap_or_default()
}

/// Every object schema (with `properties`) in the schema document, by pointer.
fn object_schemas(value: &Value, pointer: String, out: &mut BTreeMap<String, BTreeSet<String>>) {
    match value {
        Value::Object(map) => {
            if map.get("type") == Some(&json!("object")) && map.contains_key("properties") {
                out.insert(pointer.clone(), keys(value));
            }
            for (k, v) in map {
                // The `properties` inside the exactly-one rules (`allOf`) and the `kind`
                // constants only restate keys listed beside them.
                if k != "allOf" {
                    object_schemas(v, format!("{pointer}/{k}"), out);
                }
            }
        }
        Value::Array(items) => items
            .iter()
            .enumerate()
            .for_each(|(i, v)| object_schemas(v, format!("{pointer}/{i}"), out)),
        _ => {}
    }
}

#[test]
fn the_schema_names_exactly_the_keys_and_kinds_the_parser_accepts() {
    let schema = rbsm::input::scene::schema();
    let mut reached: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut kinds_checked = BTreeSet::new();
    for (name, scene) in all_scenes() {
        let mut objects = Vec::new();
        walk(
            &schema,
            Located {
                schema: &schema,
                pointer: String::new(),
            },
            &scene,
            Vec::new(),
            &mut objects,
        );
        for (path, here) in objects {
            let where_ = format!("{name}: `{}` (schema {})", path_text(&path), here.pointer);
            let listed = keys(here.schema);
            if listed.is_empty() {
                // A map of names (`materials`): its entries are checked as objects.
                assert!(
                    here.schema
                        .get("additionalProperties")
                        .is_some_and(Value::is_object),
                    "{where_}: neither an object nor a map"
                );
                continue;
            }
            assert_eq!(
                here.schema.get("additionalProperties"),
                Some(&json!(false)),
                "{where_}: not closed"
            );
            let present: BTreeSet<String> = at_mut(&mut scene.clone(), &path)
                .as_object()
                .unwrap()
                .keys()
                .cloned()
                .collect();
            reached
                .entry(here.pointer.clone())
                .or_default()
                .extend(present);

            // The parser's keys for this object.
            let mut probe = scene.clone();
            at_mut(&mut probe, &path)[BOGUS] = json!(1);
            let message = parse(&probe)
                .err()
                .unwrap_or_else(|| panic!("{where_}: an unknown key is accepted"))
                .to_string();
            assert!(
                message.contains(&format!("unknown field `{BOGUS}`")),
                "{where_}: {message}"
            );
            let mut parser = expected_list(&message);
            // `kind` is read before the variant's own keys (by the kind dispatch or serde's tag).
            if at_mut(&mut scene.clone(), &path).get("kind").is_some() {
                parser.insert("kind".into());
            }
            assert_eq!(
                parser, listed,
                "{where_}: the parser's keys (left) differ from the \
                schema's (right); message: {message}"
            );

            // The parser's kinds for this object.
            if at_mut(&mut scene.clone(), &path).get("kind").is_some() {
                let mut probe = scene.clone();
                at_mut(&mut probe, &path)["kind"] = json!(BOGUS);
                let message = parse(&probe)
                    .err()
                    .unwrap_or_else(|| panic!("{where_}: an unknown kind is accepted"))
                    .to_string();
                let parser = expected_list(&message);
                let oneof = here
                    .pointer
                    .rsplit_once("/oneOf/")
                    .expect("a kind branch of a oneOf")
                    .0;
                let branches = schema
                    .pointer(&format!("{oneof}/oneOf"))
                    .and_then(Value::as_array)
                    .unwrap();
                let consts: BTreeSet<String> = branches
                    .iter()
                    .map(|b| {
                        b.pointer("/properties/kind/const")
                            .and_then(Value::as_str)
                            .unwrap()
                            .to_string()
                    })
                    .collect();
                assert_eq!(
                    parser, consts,
                    "{where_}: the parser's kinds (left) differ from the \
                    schema's (right); message: {message}"
                );
                kinds_checked.insert(oneof.to_string());
            }
        }
    }
    // Every object schema, and every key of each, was reached by some scene above.
    let mut all = BTreeMap::new();
    object_schemas(&schema, String::new(), &mut all);
    for (pointer, listed) in &all {
        let seen = reached.get(pointer).unwrap_or_else(|| {
            panic!("no scene here reaches the object schema {pointer}: add one to `extras`")
        });
        let unused: Vec<_> = listed.difference(seen).collect();
        assert!(
            unused.is_empty(),
            "keys of {pointer} that no scene here uses: {unused:?}: add them to `extras`"
        );
    }
    assert!(all.len() >= 20, "too few object schemas: {:?}", all.keys());
    for oneof in [
        "/$defs/MeshSpec",
        "/$defs/SupportSpec",
        "/$defs/LoadSpec",
        "/$defs/FormulationSpec",
        "/$defs/ReferenceSpec",
    ] {
        assert!(
            kinds_checked.contains(oneof),
            "kinds of {oneof} not checked: {kinds_checked:?}"
        );
    }
}

#[test]
fn a_top_level_schema_key_is_ignored_and_only_there() {
    let mut scene = load("cantilever.json");
    scene["$schema"] = json!("https://example.org/scene.schema.json");
    parse(&scene).unwrap();
    scene["bodies"][0]["$schema"] = json!("x");
    let message = parse(&scene).unwrap_err().to_string();
    assert!(
        message.contains("bodies[0]") && message.contains("$schema"),
        "{message}"
    );
}

#[test]
fn rbsm_schema_prints_the_library_schema() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rbsm"))
        .arg("schema")
        .output()
        .expect("rbsm runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let printed: Value = serde_json::from_slice(&out.stdout).expect("rbsm schema prints JSON");
    assert_eq!(printed, rbsm::input::scene::schema());
    assert_eq!(printed["title"], "rbsm scene");
}

#[test]
fn docs_scene_md_names_every_key_and_kind_of_the_schema() {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/scene.md"))
        .unwrap();
    let schema = rbsm::input::scene::schema();
    let mut all = BTreeMap::new();
    object_schemas(&schema, String::new(), &mut all);
    let mut names: BTreeSet<String> = all.values().flatten().cloned().collect();
    for (pointer, _) in all.iter().filter(|(p, _)| p.contains("/oneOf/")) {
        names.insert(
            schema
                .pointer(&format!("{pointer}/properties/kind/const"))
                .unwrap()
                .as_str()
                .unwrap()
                .to_string(),
        );
    }
    let missing: Vec<_> = names
        .iter()
        .filter(|n| !text.contains(&format!("`{n}`")) && !text.contains(&format!("`\"{n}\"`")))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/scene.md does not describe {missing:?}"
    );
    assert!(names.len() > 40, "{names:?}");
}

//! A seeded fuzz campaign: 20 000 scenes and mesh files mutated from the bundled
//! ones. Each goes through what `rbsm run` does (parse, validate, model, `Δt_crit`, a few
//! steps) and must end as `rbsm` would exit: 0 (ran), 1 (an error) or 3 (diverged), never a
//! panic; every error names a key, a cell or a file.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::error::Error;
use rbsm::input::scene::Scene;
use rbsm::step::integrator::Status;
use serde_json::Value;
use std::path::Path;

const CASES: usize = 20_000;

/// The exit code `rbsm run` would give for the scene text, after at most 20 steps.
fn outcome(text: &str, dir: &Path) -> Result<i32, Error> {
    let scene = Scene::from_json_in(text, dir)?;
    let p = Setup::new(&scene, &Overrides::default())?;
    let mut cd = p.integrator(p.dt);
    let status = cd.run(p.steps.min(20), 5, |_, _| Ok(()), |_| {})?;
    Ok(if status == Status::Ok { 0 } else { 3 })
}

/// Whether the error names what is at fault: a key path, a body's cell, or a file.
fn names_its_cause(e: &Error) -> bool {
    match e {
        Error::Scene { field, .. } => !field.is_empty(),
        Error::Mesh { body, .. } => !body.is_empty(),
        Error::Parse { path, message } => {
            !path.is_empty() && (message.contains("line") || message.contains('`'))
        }
        Error::Io { path, .. } => !path.is_empty(),
    }
}

/// Numbers that break things: signs, zero, extremes, fractions near limits, big integers.
fn wild_number(rng: &mut ChaCha8Rng) -> Value {
    const FLOATS: [f64; 12] = [
        0.0, -0.0, -1.0, 1e-320, 1e-300, 1e300, 0.5, 0.49999, -0.99, 3.0, 1e9, 2.5e-7,
    ];
    const INTS: [u64; 6] = [0, 1, 2, 7, 4_294_967_296, 1_000_000_000];
    if rng.random_bool(0.5) {
        FLOATS[rng.random_range(0..FLOATS.len())].into()
    } else {
        INTS[rng.random_range(0..INTS.len())].into()
    }
}

/// Every path to a node of `v`.
fn paths(v: &Value, at: &mut Vec<Value>, out: &mut Vec<Vec<Value>>) {
    out.push(at.clone());
    match v {
        Value::Object(m) => m.iter().for_each(|(k, x)| {
            at.push(k.clone().into());
            paths(x, at, out);
            at.pop();
        }),
        Value::Array(a) => a.iter().enumerate().for_each(|(i, x)| {
            at.push(i.into());
            paths(x, at, out);
            at.pop();
        }),
        _ => {}
    }
}

fn node<'v>(v: &'v mut Value, path: &[Value]) -> &'v mut Value {
    path.iter().fold(v, |v, k| match k {
        Value::String(s) => &mut v[s.as_str()],
        Value::Number(n) => &mut v[n.as_u64().unwrap() as usize],
        _ => unreachable!(),
    })
}

/// One to three structural mutations of `scene` (mostly one), then maybe one of its text.
fn mutant(scene: &Value, rng: &mut ChaCha8Rng) -> String {
    let mut v = scene.clone();
    for _ in 0..[1, 1, 1, 2, 3][rng.random_range(0..5)] {
        let mut all = Vec::new();
        paths(&v, &mut Vec::new(), &mut all);
        let path = all[rng.random_range(0..all.len())].clone();
        let (parent, last) = path.split_at(path.len().saturating_sub(1));
        match rng.random_range(0..8) {
            0 | 1 => *node(&mut v, &path) = wild_number(rng),
            2 => {
                *node(&mut v, &path) =
                    ["bogus", "", "rigid", "point", "left", "u"][rng.random_range(0..6)].into()
            }
            3 => {
                *node(&mut v, &path) = [
                    Value::Null,
                    Value::Bool(true),
                    serde_json::json!([]),
                    serde_json::json!({}),
                ][rng.random_range(0..4)]
                .clone()
            }
            4 => {
                if let (Some(Value::String(k)), Some(map)) =
                    (last.first(), node(&mut v, parent).as_object_mut())
                {
                    map.remove(k);
                }
            }
            5 => {
                if let Some(map) = node(&mut v, &path).as_object_mut() {
                    map.insert(
                        ["colour", "cells", "kind", "E", "x"][rng.random_range(0..5)].into(),
                        wild_number(rng),
                    );
                }
            }
            6 => {
                if let Some(a) = node(&mut v, &path).as_array_mut() {
                    if !a.is_empty() && rng.random_bool(0.5) {
                        a.pop();
                    } else if let Some(x) = a.first().cloned() {
                        a.push(x);
                    }
                }
            }
            _ => *node(&mut v, &path) = serde_json::json!([wild_number(rng), wild_number(rng)]),
        }
    }
    let mut text = v.to_string();
    match rng.random_range(0..20) {
        // Cut short.
        0 => text.truncate(rng.random_range(0..text.len())),
        // A key repeated.
        1 => {
            if let Some(at) = text.find("{\"") {
                text.insert_str(at + 1, "\"name\":\"twice\",");
            }
        }
        // A byte changed.
        2 => {
            let mut bytes = text.into_bytes();
            let i = rng.random_range(0..bytes.len());
            const BYTES: &[u8] = b"{}[],:\"0-e9x \\";
            bytes[i] = BYTES[rng.random_range(0..BYTES.len())];
            text = String::from_utf8_lossy(&bytes).into_owned();
        }
        _ => {}
    }
    text
}

/// A mutant of a MSH file: cut, a byte changed, or a number of its header replaced.
fn msh_mutant(msh: &[u8], rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut bytes = msh.to_vec();
    match rng.random_range(0..3) {
        0 => bytes.truncate(rng.random_range(0..bytes.len())),
        1 => {
            let i = rng.random_range(0..bytes.len());
            const BYTES: &[u8] = b"0123456789-.$ \n";
            bytes[i] = BYTES[rng.random_range(0..BYTES.len())];
        }
        _ => {
            let text = String::from_utf8_lossy(&bytes).into_owned();
            let numbers = ["4294967296", "0", "-1", "99999999999", "2.2"];
            bytes = text
                .replacen(
                    "\n1 ",
                    &format!("\n{} ", numbers[rng.random_range(0..numbers.len())]),
                    1,
                )
                .into_bytes();
        }
    }
    bytes
}

#[test]
fn twenty_thousand_mutated_scenes_and_meshes_exit_cleanly_and_errors_name_their_cause() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenes_dir = root.join("examples/scenes");
    let mut originals: Vec<(String, Value)> = std::fs::read_dir(&scenes_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap(),
            )
        })
        .collect();
    originals.sort_by(|a, b| a.0.cmp(&b.0));
    let msh = std::fs::read(root.join("examples/meshes/cantilever.msh")).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let t0 = std::time::Instant::now();
    // Per case: the exit code or the error, or the panic message.
    type Outcome = std::result::Result<Result<i32, Error>, String>;
    let results: Vec<(usize, Outcome)> = (0..CASES)
        .into_par_iter()
        .map(|case| {
            let mut rng = ChaCha8Rng::seed_from_u64(case as u64);
            let (name, original) = &originals[case % originals.len()];
            // A tenth of the gmsh scene's cases mutate its mesh file instead.
            let (text, dir) = if name == "cantilever_gmsh.json" && rng.random_bool(0.5) {
                let dir = tmp.path().join(format!("case{case}"));
                std::fs::create_dir_all(&dir).unwrap();
                std::fs::write(dir.join("mesh.msh"), msh_mutant(&msh, &mut rng)).unwrap();
                let mut v = original.clone();
                v["bodies"][0]["mesh"]["path"] = "mesh.msh".into();
                (v.to_string(), dir)
            } else {
                (mutant(original, &mut rng), scenes_dir.clone())
            };
            let result =
                std::panic::catch_unwind(|| outcome(&text, &dir)).map_err(|_| text.clone());
            (case, result)
        })
        .collect();
    let mut codes = [0usize; 4];
    for (case, r) in &results {
        match r {
            Err(text) => panic!("case {case} panicked on: {text}"),
            Ok(Ok(code)) => codes[*code as usize] += 1,
            Ok(Err(e)) => {
                assert!(
                    names_its_cause(e),
                    "case {case}: the error names no key, cell or file: {e}"
                );
                assert!(
                    e.to_string().len() < 3 * rbsm::error::MAX_MESSAGE,
                    "case {case}: a message of {} bytes",
                    e.to_string().len()
                );
                codes[1] += 1;
            }
        }
    }
    eprintln!(
        "{CASES} cases in {:.1} s: {} ran, {} refused, {} diverged",
        t0.elapsed().as_secs_f64(),
        codes[0],
        codes[1],
        codes[3]
    );
    assert_eq!(codes.iter().sum::<usize>(), CASES);
    assert!(
        codes[0] > CASES / 20 && codes[1] > CASES / 4,
        "the mutants should both run and fail: {codes:?}"
    );
}

/// The same mutants through the command line: `rbsm run` exits with 0, 1 or 3 only, and says
/// nothing of a panic.
#[test]
fn the_command_line_exits_with_0_1_or_3_on_mutated_scenes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenes_dir = root.join("examples/scenes");
    let mut names: Vec<_> = std::fs::read_dir(&scenes_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    let tmp = tempfile::tempdir().unwrap();
    let mut codes = std::collections::BTreeMap::new();
    for case in 0..300 {
        let mut rng = ChaCha8Rng::seed_from_u64(1_000_000 + case as u64);
        let mut original: Value =
            serde_json::from_str(&std::fs::read_to_string(&names[case % names.len()]).unwrap())
                .unwrap();
        // Mesh files found from anywhere.
        for body in original["bodies"].as_array_mut().unwrap() {
            if let Some(mesh) = body["mesh"]["path"].as_str() {
                body["mesh"]["path"] = scenes_dir.join(mesh).to_string_lossy().into_owned().into();
            }
        }
        let path = tmp.path().join(format!("case{case}.json"));
        std::fs::write(&path, mutant(&original, &mut rng)).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_rbsm"))
            .args([
                "run",
                path.to_str().unwrap(),
                "--quiet",
                "--steps",
                "5",
                "--out",
            ])
            .arg(tmp.path().join("out"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let code = out.status.code();
        assert!(
            matches!(code, Some(0 | 1 | 3)),
            "case {case}: exit {code:?}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "case {case}: {stderr}");
        *codes.entry(code.unwrap()).or_insert(0) += 1;
    }
    eprintln!("exit codes of 300 mutated runs: {codes:?}");
}

//! The command line as scripts use it (README, *Commands*): `--json` gives JSON on standard
//! output for every command, results and errors alike; a reader that closes the pipe early
//! ends the process cleanly, with no panic.

use serde_json::Value;
use std::process::{Command, Stdio};

const RBSM: &str = env!("CARGO_BIN_EXE_rbsm");

fn scene(name: &str) -> String {
    format!("{}/examples/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"))
}

/// Runs `rbsm ARGS --json`; its exit code and standard output parsed as JSON.
fn json(args: &[&str]) -> (Option<i32>, Value) {
    let out = Command::new(RBSM)
        .args(args)
        .args(["--json", "--quiet"])
        .output()
        .unwrap();
    let text = String::from_utf8(out.stdout).unwrap();
    let value = serde_json::from_str(&text)
        .unwrap_or_else(|e| panic!("{args:?}: not JSON ({e}): {text:?}"));
    (out.status.code(), value)
}

#[test]
fn every_command_answers_json_with_json() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_str().unwrap();
    let cantilever = scene("cantilever");
    let (code, v) = json(&["check", &cantilever]);
    assert_eq!(code, Some(0));
    assert!(v["dt_crit"].as_f64().unwrap() > 0.0);
    let (code, v) = json(&[
        "run",
        &cantilever,
        "--steps",
        "50",
        "--out",
        &format!("{dir}/run"),
    ]);
    assert_eq!((code, v["status"].as_str()), (Some(0), Some("ok")));
    let (code, v) = json(&["plot", &format!("{dir}/run")]);
    assert_eq!(code, Some(0));
    assert!(v["written"]
        .as_array()
        .unwrap()
        .iter()
        .any(|p| p.as_str().unwrap().ends_with("energies.svg")));
    let (code, v) = json(&["draw", &cantilever, "--out", &format!("{dir}/model.svg")]);
    assert_eq!(
        (
            code,
            v["written"][0].as_str().map(|p| p.ends_with("model.svg"))
        ),
        (Some(0), Some(true))
    );
    let (code, v) = json(&["effective", &cantilever]);
    assert_eq!(code, Some(0));
    assert!(v["young"].as_f64().unwrap() > 0.0 && v["stiffness"][2][2].as_f64().unwrap() > 0.0);
    let (code, v) = json(&["static", &cantilever]);
    assert_eq!(code, Some(0));
    assert!(v["energy"].as_f64().unwrap() > 0.0);
    let (code, v) = json(&["eigen", &cantilever, "--modes", "2"]);
    assert_eq!(code, Some(0));
    assert_eq!(v["frequencies_hz"].as_array().unwrap().len(), 2);
    assert_eq!(v["with_contact"], false);
    // A block on the ground: its ω_max is the contact's, which the report says.
    let (code, v) = json(&["eigen", &scene("hopping_block")]);
    assert_eq!((code, &v["with_contact"]), (Some(0), &Value::Bool(true)));
    // Errors too: the key at fault and the message, on standard output.
    let bad = tmp.path().join("bad.json");
    std::fs::write(&bad, r#"{"name": "x", "thickness": -1}"#).unwrap();
    let (code, v) = json(&["check", bad.to_str().unwrap()]);
    assert_eq!(code, Some(1));
    // A missing key is a scene error whose key is the path it should have.
    assert_eq!(v["error"]["kind"], "scene");
    let key = v["error"]["key"].as_str().unwrap();
    assert_eq!(
        v["error"]["message"].as_str().unwrap(),
        format!("missing field `{key}`")
    );
    let (code, v) = json(&["check", "/no/such/scene.json"]);
    assert_eq!(
        (
            code,
            v["error"]["kind"].as_str(),
            v["error"]["key"].as_str()
        ),
        (Some(1), Some("io"), Some("/no/such/scene.json"))
    );
}

#[test]
fn a_reader_that_closes_early_ends_the_process_cleanly() {
    let tmp = tempfile::tempdir().unwrap();
    // (arguments, exit code): a closed pipe does not change it (`check` of a step above the
    // limit exited 0 when its reader closed).
    for (args, code) in [
        (
            vec!["run", &scene("cantilever"), "--steps", "200", "--json"],
            0,
        ),
        (vec!["eigen", &scene("cantilever"), "--modes", "3"], 0),
        (vec!["check", &scene("cantilever"), "--dt", "1e-5"], 4),
    ] {
        let mut child = Command::new(RBSM)
            .args(&args)
            .args(
                ["--out", tmp.path().join("out").to_str().unwrap()]
                    .iter()
                    .filter(|_| args[0] == "run"),
            )
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take()); // `| head -c 0`
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

/// `static` and `eigen` write files like `run` (README, *Commands*): a summary, VTK a ParaView
/// series opens, and the scene's probes.
#[test]
fn static_and_eigen_write_their_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let (s, e) = (tmp.path().join("static"), tmp.path().join("eigen"));
    let cantilever = scene("cantilever");
    let (code, _) = json(&["static", &cantilever, "--out", s.to_str().unwrap()]);
    assert_eq!(code, Some(0));
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(s.join("summary.json")).unwrap()).unwrap();
    assert!(summary["energy"].as_f64().unwrap() > 0.0);
    assert!(std::fs::read_to_string(s.join("series.pvd"))
        .unwrap()
        .contains(r#"file="static.vtu""#));
    assert!(vtkio::Vtk::import(s.join("static.vtu")).is_ok());
    let probes = std::fs::read_to_string(s.join("probes.csv")).unwrap();
    assert_eq!(probes.lines().next(), Some("case,tip_v (m)"));
    let tip: f64 = probes
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    let state: Value =
        serde_json::from_str(&std::fs::read_to_string(s.join("final_state.json")).unwrap())
            .unwrap();
    assert_eq!(tip, state["elements"][79]["U"][1].as_f64().unwrap());
    let (code, _) = json(&[
        "eigen",
        &cantilever,
        "--modes",
        "3",
        "--out",
        e.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0));
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(e.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["frequencies_hz"].as_array().unwrap().len(), 3);
    assert_eq!(
        std::fs::read_to_string(e.join("modes.pvd"))
            .unwrap()
            .matches("<DataSet")
            .count(),
        3
    );
    let probes = std::fs::read_to_string(e.join("probes.csv")).unwrap();
    assert_eq!(probes.lines().count(), 4);
    assert!(probes.starts_with("mode,frequency_hz,tip_v (M-normalised)\n1,"));
}

/// An unknown key is reported by its JSON path, as the key at fault, not by the file;
/// malformed JSON is still the file's.
#[test]
fn an_unknown_key_is_the_key_of_its_error() {
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scene("tension_bar")).unwrap();
    let mut v: Value = serde_json::from_str(&text).unwrap();
    let interface = &mut v["materials"]["concrete"]["interface"];
    assert!(interface.is_object(), "the scene changed");
    interface["tensile_strenght"] = 3.0e6.into();
    let bad = tmp.path().join("bad.json");
    std::fs::write(&bad, v.to_string()).unwrap();
    let (code, v) = json(&["check", bad.to_str().unwrap()]);
    assert_eq!(code, Some(1));
    assert_eq!(
        v["error"]["key"], "materials.concrete.interface.tensile_strenght",
        "{v}"
    );
    assert_eq!(v["error"]["kind"], "scene");
    assert!(v["error"]["message"]
        .as_str()
        .unwrap()
        .contains("unknown field `tensile_strenght`"));
    // A value of the wrong type inside a body, likewise.
    let mut v: Value = serde_json::from_str(&text).unwrap();
    v["bodies"][0]["mesh"]["sites"] = "many".into();
    std::fs::write(&bad, v.to_string()).unwrap();
    let (code, v) = json(&["check", bad.to_str().unwrap()]);
    assert_eq!(
        (code, v["error"]["key"].as_str()),
        (Some(1), Some("bodies[0].mesh.sites"))
    );
    // Malformed JSON has no key path: the file is at fault.
    std::fs::write(&bad, r#"{"name": "#).unwrap();
    let (code, v) = json(&["check", bad.to_str().unwrap()]);
    assert_eq!(
        (
            code,
            v["error"]["kind"].as_str(),
            v["error"]["key"].as_str()
        ),
        (Some(1), Some("parse"), bad.to_str())
    );
    // A run told to write into a file is refused under `--out`.
    let (code, v) = json(&["run", &scene("cantilever"), "--out", bad.to_str().unwrap()]);
    assert_eq!(
        (code, v["error"]["key"].as_str()),
        (Some(1), Some("--out")),
        "{v}"
    );
    assert!(v["error"]["message"]
        .as_str()
        .unwrap()
        .contains("is a file"));
}

/// `plot`'s folder is described in its help, and `schema`, whose output is JSON already,
/// refuses `--json` as a usage error (exit 2) instead of ignoring it.
#[test]
fn plot_describes_its_folder_and_schema_refuses_json() {
    let help = Command::new(RBSM)
        .args(["plot", "--help"])
        .output()
        .unwrap();
    let text = String::from_utf8(help.stdout).unwrap();
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("<DIR>"))
        .unwrap_or_else(|| panic!("no <DIR> line: {text}"));
    assert!(line.contains("rbsm run --out"), "{line}");
    let out = Command::new(RBSM)
        .args(["schema", "--json"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty());
    assert!(String::from_utf8_lossy(&out.stderr).contains("`--json` does not apply to `schema`"));
    let out = Command::new(RBSM).arg("schema").output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    let schema: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(schema["properties"]["bodies"].is_object());
}

/// `rbsm ARGS --quiet`, killed after 60 s (a FIFO read whole would block for ever): exit code
/// and standard error.
fn within_a_minute(args: &[&str]) -> (Option<i32>, String) {
    let mut child = Command::new(RBSM)
        .args(args)
        .arg("--quiet")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed().as_secs() > 60 {
            child.kill().unwrap();
            panic!("{args:?} still running after 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `draw --state DIR` and `plot DIR` check the kind and size of the files they read before
/// reading them, as scene and mesh files are: a FIFO is refused at once
/// (it used to block), a file larger than a final state of the scene or than a CSV `plot`
/// reads is refused unread, with the file named.
#[cfg(unix)]
#[test]
fn draw_and_plot_refuse_files_too_large_or_not_regular() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    let cantilever = scene("cantilever");
    let (code, _) = json(&[
        "run",
        &cantilever,
        "--steps",
        "5",
        "--out",
        run.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0));
    let svg = tmp.path().join("state.svg");
    let draw = || {
        within_a_minute(&[
            "draw",
            &cantilever,
            "--state",
            run.to_str().unwrap(),
            "--out",
            svg.to_str().unwrap(),
        ])
    };
    let plot = || within_a_minute(&["plot", run.to_str().unwrap()]);
    // The run's own files are read.
    assert_eq!(draw().0, Some(0));
    assert_eq!(plot().0, Some(0));
    let fifo = |path: &std::path::Path| {
        std::fs::remove_file(path).unwrap();
        let made = Command::new("mkfifo").arg(path).status().unwrap();
        assert!(made.success());
    };
    let sparse = |path: &std::path::Path, len: u64| {
        std::fs::remove_file(path).unwrap();
        std::fs::File::create(path).unwrap().set_len(len).unwrap();
    };
    let state = run.join("final_state.json");
    let history = run.join("history.csv");
    let saved = (
        std::fs::read(&state).unwrap(),
        std::fs::read(&history).unwrap(),
    );
    fifo(&state);
    let (code, err) = draw();
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("final_state.json") && err.contains("not a regular file"),
        "{err}"
    );
    // A final state of the cantilever's 200 elements is under 1.5 MiB.
    sparse(&state, 64 << 20);
    let (code, err) = draw();
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("final_state.json") && err.contains("larger than"),
        "{err}"
    );
    std::fs::remove_file(&state).unwrap();
    std::fs::write(&state, &saved.0).unwrap();
    fifo(&history);
    let (code, err) = plot();
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("history.csv") && err.contains("not a regular file"),
        "{err}"
    );
    sparse(&history, rbsm::output::plot::MAX_CSV_BYTES + 1);
    let (code, err) = plot();
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("history.csv") && err.contains("larger than 1024 MiB"),
        "{err}"
    );
    std::fs::remove_file(&history).unwrap();
    std::fs::write(&history, &saved.1).unwrap();
    assert_eq!((draw().0, plot().0), (Some(0), Some(0)));
}

/// `--threads` beyond 8 per core is a usage error that says the bound, at once (100,000 used
/// to spend minutes starting threads before anything was said).
#[test]
fn too_many_threads_are_refused_at_once() {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    let too_many = (8 * cores + 1).to_string();
    let out = Command::new(RBSM)
        .args(["check", &scene("cantilever"), "--threads", &too_many])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--threads") && stderr.contains(&format!("at most {}", 8 * cores)),
        "{stderr}"
    );
}

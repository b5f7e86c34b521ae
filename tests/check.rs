//! `rbsm check SCENE` (README, *Commands*): a valid scene is described without running, exit code
//! 0; an invalid one is refused with the field at fault, exit code 1.

use std::process::Command;

fn check(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rbsm"))
        .arg("check")
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_good_scene_is_described() {
    let (code, stdout, stderr) = check(&["examples/scenes/cantilever_gmsh.json", "--json"]);
    assert_eq!(code, 0, "{stderr}");
    let r: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(r["elements"], 640);
    assert_eq!(r["ground_springs"], 8, "the clamp group of the gmsh file");
    assert_eq!(r["interfaces"], 79 * 8 + 80 * 7);
    assert_eq!(r["dofs"], 1920);
    assert_eq!(r["loads"], 8);
    assert!(r["contact"].is_null());
    let (dt, crit) = (r["dt"].as_f64().unwrap(), r["dt_crit"].as_f64().unwrap());
    // The step is the `dt_factor` of the `Δt_crit` a run settles to a few digits, the
    // `Δt_crit` reported is to full precision.
    assert!(
        (dt / crit - 0.9).abs() < 1e-4
            && r["steps"].as_u64().unwrap() == (0.1 / dt - 1e-9).ceil() as u64
    );
    // The time step is the run's, to the bit (on this hybrid footing the Lanczos `Δt_crit` a
    // run settles to and the full one differ in the fifth digit).
    let (code, stdout, stderr) = check(&["examples/scenes/footing_hybrid.json", "--json"]);
    assert_eq!(code, 0, "{stderr}");
    let r: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let (dt, crit) = (r["dt"].as_f64().unwrap(), r["dt_crit"].as_f64().unwrap());
    assert!(
        dt != 0.5 * crit && (dt / crit - 0.5).abs() < 1e-4,
        "{dt} {crit}"
    );
    let out = tempfile::tempdir().unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_rbsm"))
        .args([
            "run",
            "examples/scenes/footing_hybrid.json",
            "--quiet",
            "--steps",
            "1",
        ])
        .arg("--out")
        .arg(out.path())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(run.status.success());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["dt"].as_f64(), Some(dt));
    assert!(r["memory_bytes"].as_u64().unwrap() > 1920 * 8 * 6);
    // With contact: the pairs it would track.
    let (code, stdout, _) = check(&["examples/scenes/hopping_block.json", "--json"]);
    assert_eq!(code, 0);
    let r: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(r["contact"]["model"], "edge-to-edge");
    assert_eq!(r["contact"]["vertices"], 4);
    // Text for people.
    let (code, stdout, _) = check(&["examples/scenes/cantilever.json"]);
    assert_eq!(code, 0);
    assert!(
        stdout.contains("cantilever: valid")
            && stdout.contains("Δt_crit")
            && stdout.contains("memory"),
        "{stdout}"
    );
}

#[test]
fn a_bad_scene_is_refused_with_its_field() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().to_path_buf();
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/cantilever_gmsh.json"
    ))
    .unwrap();
    let msh = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/meshes/cantilever.msh"
    );
    let bad = dir.join("bad.json");
    std::fs::write(
        &bad,
        text.replace("\"clamp\"", "\"clmap\"")
            .replace("../meshes/cantilever.msh", msh),
    )
    .unwrap();
    let (code, stdout, stderr) = check(&[bad.to_str().unwrap()]);
    assert_eq!(code, 1, "{stdout}");
    assert!(
        stderr.contains("bodies[0].supports[0].edge") && stderr.contains("clmap"),
        "{stderr}"
    );
    let neg = dir.join("neg.json");
    std::fs::write(
        &neg,
        text.replace("3.0e10", "-3.0e10")
            .replace("../meshes/cantilever.msh", msh),
    )
    .unwrap();
    let (code, _, stderr) = check(&[neg.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(stderr.contains("materials.concrete.E"), "{stderr}");
    // A value of the wrong type is named with the type a scene's author knows, and a file cut
    // short is said so without a key path it has not reached.
    let cases = [
        (
            r#""thickness": 0.1"#,
            r#""thickness": "0.1""#,
            "expected a number",
        ),
        (
            r#""dt_factor": 0.9"#,
            r#""dt_factor": true"#,
            "expected a number",
        ),
    ];
    for (from, to, says) in cases {
        assert!(text.contains(from), "{from}");
        std::fs::write(
            &neg,
            text.replace(from, to)
                .replace("../meshes/cantilever.msh", msh),
        )
        .unwrap();
        let (code, _, stderr) = check(&[neg.to_str().unwrap()]);
        assert_eq!(code, 1);
        assert!(stderr.contains(says) && !stderr.contains("f64"), "{stderr}");
    }
    std::fs::write(&neg, &text[..text.len() / 2]).unwrap();
    let (code, _, stderr) = check(&[neg.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(
        stderr.contains("EOF") && !stderr.contains("`?`"),
        "{stderr}"
    );
}

/// A valid scene whose time step is above `Δt_crit` is described, and exits 4: a run of it would
/// diverge. Just below the limit it exits 0.
#[test]
fn a_time_step_above_the_limit_exits_with_its_own_code() {
    let (code, stdout, stderr) = check(&["examples/scenes/cantilever.json", "--json"]);
    assert_eq!(code, 0, "{stderr}");
    let r: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(r["unstable"], false);
    let crit = r["dt_crit"].as_f64().unwrap();
    for (factor, expected) in [(0.99, 0), (1.01, 4), (89.0, 4)] {
        let dt = format!("{:e}", factor * crit);
        let (code, stdout, stderr) =
            check(&["examples/scenes/cantilever.json", "--dt", &dt, "--json"]);
        assert_eq!(code, expected, "dt = {factor} Δt_crit: {stderr}");
        let r: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        assert_eq!(r["unstable"], expected != 0);
    }
    let dt = format!("{:e}", 89.0 * crit);
    let (code, stdout, _) = check(&["examples/scenes/cantilever.json", "--dt", &dt]);
    assert_eq!(code, 4);
    assert!(stdout.contains("would diverge"), "{stdout}");
    // Its warnings speak of the exact Δt_crit it computed: none between the proven-safe step and
    // the limit (it used to say the run "may be unstable" and to run `rbsm check`), and above
    // the limit by how much.
    for (factor, warned) in [(0.92, false), (1.01, true)] {
        let dt = format!("{:e}", factor * crit);
        let (_, stdout, _) = check(&["examples/scenes/cantilever.json", "--dt", &dt]);
        assert!(!stdout.contains("rbsm check"), "{stdout}");
        assert_eq!(stdout.contains("warning: dt is 1.01"), warned, "{stdout}");
    }
    // A `dt_factor` just below 1 lands above the exact limit, the run's Lanczos estimate being
    // 1.6e-5 above it: exit 4, and a warning that says why.
    let mut scene: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/examples/scenes/footing_hybrid.json"
        ))
        .unwrap(),
    )
    .unwrap();
    scene["time"]["dt_factor"] = 0.99999.into();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("footing.json");
    std::fs::write(&path, scene.to_string()).unwrap();
    let (code, stdout, _) = check(&[path.to_str().unwrap()]);
    assert_eq!(code, 4, "{stdout}");
    assert!(
        stdout.contains("Lanczos settles to 1e-4") && stdout.contains("--exact-dt-crit"),
        "{stdout}"
    );
}

/// Counts of one are singular in every line that counts things, and the run's
/// `summary.json` counts interfaces as `check` and the run's information line do: between
/// elements, with the ground springs apart.
#[test]
fn counts_agree_and_one_is_singular() {
    let dir = tempfile::tempdir().unwrap();
    let one = dir.path().join("one.json");
    std::fs::write(
        &one,
        r#"{"name": "one", "thickness": 0.1, "formulation": {"kind": "rigid"},
            "materials": {"m": {"E": 1e9, "nu": 0.2, "rho": 1000}},
            "bodies": [{"name": "b", "material": "m",
                "mesh": {"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [1, 1]},
                "supports": [{"edge": "left", "kind": "ground-spring"}],
                "loads": [{"kind": "force", "element": 0, "value": [1, 0, 0]}]}],
            "time": {"dt_factor": 0.5, "steps": 1}}"#,
    )
    .unwrap();
    let (code, stdout, stderr) = check(&[one.to_str().unwrap()]);
    assert_eq!(code, 0, "{stderr}");
    for part in [
        "1 body, 1 element (",
        "0 interfaces between elements, 1 ground spring; 3 DOFs",
        "1 point load;",
        ", 1 step\n",
    ] {
        assert!(stdout.contains(part), "`{part}` not in {stdout}");
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rbsm"))
        .args(["run", one.to_str().unwrap(), "--threads", "1", "--out"])
        .arg(dir.path().join("run"))
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(
        stderr.contains(
            "one: 1 element, 0 interfaces between elements and 1 ground spring, 3 free DOFs \
             (rigid formulation, assembled evaluator, 1 thread)"
        ) && stderr.contains(", 1 step\n"),
        "{stderr}"
    );
    assert!(stdout.contains("one: ok, 1 step "), "{stdout}");
    // The gmsh cantilever: 1192 interfaces between elements and 8 ground springs, in the
    // check, the run's line and summary.json alike.
    let scene = "examples/scenes/cantilever_gmsh.json";
    let (code, stdout, _) = check(&[scene, "--json"]);
    assert_eq!(code, 0);
    let r: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rbsm"))
        .args(["run", scene, "--steps", "1", "--out"])
        .arg(dir.path().join("gmsh"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("gmsh/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        (&summary["interfaces"], &summary["ground_springs"]),
        (&r["interfaces"], &r["ground_springs"])
    );
    let line = format!(
        "{} interfaces between elements and {} ground springs",
        r["interfaces"], r["ground_springs"]
    );
    assert!(
        String::from_utf8_lossy(&out.stderr).contains(&line),
        "{line}"
    );
}

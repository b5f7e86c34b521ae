//! `rbsm check SCENE` (issue 7): a valid scene is described without running, exit code 0; an
//! invalid one is refused with the field at fault, exit code 1.

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
    assert!(
        (dt / crit - 0.9).abs() < 1e-12
            && r["steps"].as_u64().unwrap() == (0.1 / dt - 1e-9).ceil() as u64
    );
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
    let dir = std::env::temp_dir().join(format!("rbsm-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
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
}

/// A valid scene whose time step is above `Δt_crit` is described, and exits 4 (issue 40 item
/// 3): a run of it would diverge. Just below the limit it exits 0.
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
}

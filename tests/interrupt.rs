//! Runs that stop early lose nothing (README, *Outputs*: interrupting and resuming): SIGINT
//! finishes the step and writes complete outputs; after SIGKILL the history and the frame list are
//! valid up to the last frame written, and `--resume` ends with the outputs of an uninterrupted
//! run, byte for byte; a write error leaves whole rows.
#![cfg(unix)]

use serde_json::Value;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const RBSM: &str = env!("CARGO_BIN_EXE_rbsm");

/// The bundled wall of bricks (contact, friction, gravity) with frames every 20 steps, a
/// checkpoint every 300 steps and `steps` steps.
fn wall(dir: &Path, steps: u64, checkpoint: bool) -> std::path::PathBuf {
    let path = format!("{}/examples/scenes/wall.json", env!("CARGO_MANIFEST_DIR"));
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["time"] = serde_json::json!({"dt_factor": 0.5, "steps": steps});
    v["output"] = serde_json::json!({"every": 20, "vtk": true});
    if checkpoint {
        v["output"]["checkpoint_every"] = 300.into();
    }
    let scene = dir.join("scene.json");
    std::fs::write(&scene, v.to_string()).unwrap();
    scene
}

fn start(args: &[&str]) -> Child {
    Command::new(RBSM)
        .args(args)
        .arg("--quiet")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

fn rows(dir: &Path) -> usize {
    std::fs::read_to_string(dir.join("history.csv")).map_or(0, |t| t.lines().count())
}

/// Waits until the history of `dir` has `n` rows, or the child has ended.
fn wait_for_rows(child: &mut Child, dir: &Path, n: usize) {
    let t0 = Instant::now();
    while rows(dir) < n
        && child.try_wait().unwrap().is_none()
        && t0.elapsed() < Duration::from_secs(120)
    {
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Every file under `a` equals the one under `b` and none is missing on either side; in
/// `summary.json` the wall times and the thread count are left out.
fn same_outputs(a: &Path, b: &Path) {
    let list = |d: &Path| -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        names
    };
    assert_eq!(list(a), list(b), "{} and {}", a.display(), b.display());
    for name in list(a) {
        let (pa, pb) = (a.join(&name), b.join(&name));
        if pa.is_dir() {
            same_outputs(&pa, &pb);
        } else if name == "summary.json" {
            let clean = |p: &Path| {
                let mut v: Value =
                    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
                for k in ["wall_time_s", "setup_time_s", "step_time_s", "threads"] {
                    v.as_object_mut().unwrap().remove(k);
                }
                if let Some(c) = v.get_mut("contact") {
                    c.as_object_mut().unwrap().remove("time_s");
                }
                v
            };
            assert_eq!(clean(&pa), clean(&pb));
        } else {
            assert!(
                std::fs::read(&pa).unwrap() == std::fs::read(&pb).unwrap(),
                "{name} differs"
            );
        }
    }
}

/// The history holds whole rows of equal width; the collection is whole and lists frames that
/// are on disk: all of them, or all but the last when `killed` (a kill can fall between a
/// frame's rename and its entry).
fn outputs_are_whole(dir: &Path, killed: bool) -> usize {
    let history = std::fs::read_to_string(dir.join("history.csv")).unwrap();
    assert!(history.ends_with('\n'));
    let widths: std::collections::BTreeSet<usize> =
        history.lines().map(|l| l.split(',').count()).collect();
    assert_eq!(widths.len(), 1, "rows of several widths: {widths:?}");
    let pvd = std::fs::read_to_string(dir.join("series.pvd")).unwrap();
    assert!(
        pvd.starts_with("<?xml") && pvd.ends_with("</Collection>\n</VTKFile>\n"),
        "{pvd}"
    );
    let listed: Vec<&str> = pvd
        .split("file=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap())
        .collect();
    let on_disk = std::fs::read_dir(dir.join("vtk")).unwrap().count();
    let unlisted = on_disk - listed.len();
    assert!(
        unlisted == 0 || (killed && unlisted == 1),
        "the collection lists {} frames, {on_disk} on disk",
        listed.len()
    );
    assert!(listed.iter().all(|f| dir.join(f).is_file()));
    listed.len()
}

#[test]
fn a_killed_run_resumes_to_the_outputs_of_an_uninterrupted_one_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = wall(tmp.path(), 3000, true);
    let scene = scene.to_str().unwrap();
    let reference = tmp.path().join("reference");
    let status = Command::new(RBSM)
        .args([
            "run",
            scene,
            "--quiet",
            "--out",
            reference.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    assert!(
        !reference.join("checkpoint.bin").exists(),
        "a finished run keeps no checkpoint"
    );
    let total = rows(&reference);
    // Kill at a row drawn from the clock, after the first checkpoint (step 300 = row 16).
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos() as usize;
    let at = 20 + nanos % (total - 40);
    let killed = tmp.path().join("killed");
    let mut child = start(&["run", scene, "--out", killed.to_str().unwrap()]);
    wait_for_rows(&mut child, &killed, at);
    child.kill().unwrap();
    child.wait().unwrap();
    eprintln!("killed at row {} of {total}", rows(&killed));
    assert!(rows(&killed) < total, "the run ended before it was killed");
    assert!(!killed.join("summary.json").exists());
    outputs_are_whole(&killed, true);
    let status = Command::new(RBSM)
        .args([
            "run",
            scene,
            "--quiet",
            "--resume",
            killed.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    same_outputs(&reference, &killed);
}

#[test]
fn sigint_finishes_the_step_and_writes_complete_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = wall(tmp.path(), 20_000, false);
    let out = tmp.path().join("out");
    let mut child = start(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    wait_for_rows(&mut child, &out, 30);
    assert!(Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    assert_eq!(child.wait().unwrap().code(), Some(130));
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["status"], "interrupted");
    assert!(summary["reason"]
        .as_str()
        .unwrap()
        .contains("interrupted by a signal"));
    let t_end = summary["t_end"].as_f64().unwrap();
    let state: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("final_state.json")).unwrap())
            .unwrap();
    assert_eq!(state["t"].as_f64().unwrap(), t_end);
    // The step where it stopped is the last row and the last frame.
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let last_t: f64 = history
        .lines()
        .last()
        .unwrap()
        .split(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(last_t, t_end);
    let frames = outputs_are_whole(&out, false);
    assert_eq!(frames, history.lines().count() - 1);
}

#[test]
fn resume_refuses_another_scene_and_a_folder_without_checkpoint() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = wall(tmp.path(), 700, true);
    let out = tmp.path().join("out");
    let mut child = start(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    wait_for_rows(&mut child, &out, 20);
    child.kill().unwrap();
    child.wait().unwrap();
    if !out.join("checkpoint.bin").exists() {
        return; // too fast a machine: the run ended before it was killed
    }
    let other = Command::new(RBSM)
        .args([
            "run",
            scene.to_str().unwrap(),
            "--dt",
            "1e-7",
            "--resume",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(other.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&other.stderr).contains("another scene or other options"));
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let none = Command::new(RBSM)
        .args([
            "run",
            scene.to_str().unwrap(),
            "--resume",
            empty.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(none.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&none.stderr).contains("no checkpoint here"));
}

/// A file-size limit (as a full disk) stops the run with an error naming the file; the history
/// keeps whole rows only.
#[test]
fn a_write_error_leaves_whole_rows() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = wall(tmp.path(), 3000, false);
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&scene).unwrap()).unwrap();
    v["output"] = serde_json::json!({"every": 1});
    std::fs::write(&scene, v.to_string()).unwrap();
    let out = tmp.path().join("out");
    let run = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -f 8 && exec '{RBSM}' run '{}' --quiet --out '{}'",
            scene.display(),
            out.display()
        ))
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&run.stderr).contains("history.csv"),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let history = std::fs::read_to_string(out.join("history.csv")).unwrap();
    let columns = history.lines().next().unwrap().split(',').count();
    assert!(
        history.ends_with('\n') && history.lines().all(|l| l.split(',').count() == columns),
        "a partial row"
    );
    assert!(history.lines().count() > 10);
}

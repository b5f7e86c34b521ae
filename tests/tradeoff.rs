//! `rbsm tradeoff`: sweeps, references, the Pareto front and the files it writes.

use rbsm::analysis::tradeoff::{sweep, Key, PointStatus, Sweep};
use rbsm::input::scene::Scene;

const COLUMN: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/examples/scenes/column_step.json"
);

fn column() -> Scene {
    Scene::from_file(COLUMN).unwrap()
}

fn sweeps(args: &[&str]) -> Vec<Sweep> {
    args.iter().map(|a| Sweep::parse(a).unwrap()).collect()
}

#[test]
fn bad_sweeps_are_refused_with_the_allowed_values() {
    let e = Sweep::parse("dtt=1e-6").unwrap_err().to_string();
    assert!(
        e.contains("--sweep") && e.contains("dt_factor") && e.contains("refine"),
        "{e}"
    );
    let e = Sweep::parse("refine=0,2").unwrap_err().to_string();
    assert!(e.contains("--sweep refine") && e.contains("1..=64"), "{e}");
    let e = Sweep::parse("evaluator=fast").unwrap_err().to_string();
    assert!(e.contains("assembled or element-wise"), "{e}");
    assert!(Sweep::parse("dt_factor=").is_err());
    assert_eq!(
        Sweep::parse("penalty=10, 100").unwrap(),
        Sweep {
            key: Key::Penalty,
            values: vec!["10".into(), "100".into()]
        }
    );
    // A contact sweep needs a scene with contact.
    let e = sweep(&column(), &sweeps(&["contact=point"]), |_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("declares no `contact`"), "{e}");
    // The closed form's probe must exist.
    let e = Scene::from_json(
        &std::fs::read_to_string(COLUMN)
            .unwrap()
            .replace(r#""probe": "tip_u"}"#, r#""probe": "tip"}"#),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("reference.probe") && e.contains("`tip`"), "{e}");
}

#[test]
fn the_column_converges_to_the_bar_and_the_front_is_marked() {
    let report = sweep(
        &column(),
        &sweeps(&["refine=1,2,4", "dt_factor=0.9,0.5"]),
        |_| (),
    )
    .unwrap();
    assert!(
        report.reference.contains("closed form of the bar"),
        "{}",
        report.reference
    );
    assert_eq!(report.points.len(), 6);
    let err = |r: &str, f: &str| {
        report
            .points
            .iter()
            .find(|p| p.settings[0].1 == r && p.settings[1].1 == f)
            .and_then(|p| p.error)
            .unwrap()
    };
    // Refinement lowers the error at either time step; the error is a few per cent at most.
    for f in ["0.9", "0.5"] {
        assert!(
            err("2", f) < err("1", f) && err("4", f) < err("2", f),
            "{f}: {} {} {}",
            err("1", f),
            err("2", f),
            err("4", f)
        );
        assert!(err("1", f) < 0.05);
    }
    // Every point is measured; the front holds the most accurate point, and the cheapest one
    // unless a more accurate point's runs overlap it in time.
    assert!(report
        .points
        .iter()
        .all(|p| p.status.is_ok() && p.steps > 0 && p.dt_crit > 0.0 && p.wall_s > 0.0));
    // Each time is a median of runs that add up to 0.2 s of stepping (or 25 runs; a median
    // times the runs is at least half their sum), within the range of those runs.
    for p in &report.points {
        assert!(
            (1..=25).contains(&p.runs)
                && (p.runs == 25 || p.runs as f64 * p.stepping_s >= 0.1)
                && p.wall_range_s[0] <= p.wall_s
                && p.wall_s <= p.wall_range_s[1],
            "{} runs, stepping {} s, wall {} in {:?}",
            p.runs,
            p.stepping_s,
            p.wall_s,
            p.wall_range_s
        );
    }
    let cheapest = report
        .points
        .iter()
        .min_by(|a, b| a.wall_s.total_cmp(&b.wall_s))
        .unwrap();
    let best = report
        .points
        .iter()
        .min_by(|a, b| a.error.unwrap().total_cmp(&b.error.unwrap()))
        .unwrap();
    let overlapped = report.points.iter().any(|q| {
        q.error.unwrap() < cheapest.error.unwrap() && q.wall_range_s[0] <= cheapest.wall_range_s[1]
    });
    assert!(best.pareto && (cheapest.pareto || overlapped));
    for p in report.points.iter().filter(|p| p.pareto) {
        let beaten = report
            .points
            .iter()
            .any(|q| q.wall_s < p.wall_s && q.error.unwrap() < p.error.unwrap());
        assert!(!beaten, "a front point is beaten: {:?}", p.settings);
    }
    let dir = tempfile::tempdir().unwrap();
    report.write(dir.path()).unwrap();
    let csv = std::fs::read_to_string(dir.path().join("tradeoff.csv")).unwrap();
    assert_eq!(csv.lines().count(), 7);
    assert!(csv.starts_with("refine,dt_factor,elements,"));
    let svg = std::fs::read_to_string(dir.path().join("tradeoff.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("Pareto front"));
    assert!(std::fs::read_to_string(dir.path().join("tradeoff.md"))
        .unwrap()
        .contains("| refine | dt_factor |"));
}

#[test]
fn without_a_closed_form_the_finest_run_is_the_reference_and_diverged_runs_are_kept_out() {
    // The column without its reference: the finest run (refine 2, smallest Δt) is the reference.
    let mut scene = column();
    scene.reference = None;
    let report = sweep(
        &scene,
        &sweeps(&["refine=1,2", "dt_factor=0.5,0.25,1.05"]),
        |_| (),
    )
    .unwrap();
    assert!(
        report.reference.contains("finest run")
            && report.reference.contains("refine=2, dt_factor=0.25"),
        "{}",
        report.reference
    );
    for p in &report.points {
        let f = &p.settings[1].1;
        if f == "1.05" {
            // Above Δt_crit: stopped by the guard, no error, not on the front.
            assert!(matches!(p.status, PointStatus::Diverged(_)), "{}", p.status);
            assert!(p.error.is_none() && !p.pareto);
        } else if p.settings[0].1 == "2" && f == "0.25" {
            assert!(p.error.is_none() && p.status.is_ok());
        } else {
            assert!(
                p.error.is_some_and(|e| e > 0.0 && e < 0.1),
                "{:?}: {:?}",
                p.settings,
                p.error
            );
        }
    }
}

#[test]
fn the_hopping_block_is_measured_against_its_theory() {
    let scene = Scene::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/hopping_block.json"
    ))
    .unwrap();
    let report = sweep(&scene, &sweeps(&["dt=8e-6,2e-6"]), |_| ()).unwrap();
    assert!(
        report.reference.contains("hopping block") && report.reference.contains("H = 1"),
        "{}",
        report.reference
    );
    let e: Vec<f64> = report.points.iter().map(|p| p.error.unwrap()).collect();
    // The apex error falls with the time step, near second order (validation §8.2).
    assert!(e[0] < 1e-2 && e[1] < e[0] / 4.0, "{e:?}");
}

#[test]
fn the_command_line_writes_the_trade_and_refuses_bad_sweeps() {
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/column_step.json"
    );
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rbsm"))
        .args(["tradeoff", scene, "--sweep", "refine=1,2", "--out"])
        .arg(dir.path())
        .args(["--json", "--quiet"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["points"].as_array().unwrap().len(), 2);
    assert!(report["reference"]
        .as_str()
        .unwrap()
        .contains("closed form"));
    for f in ["tradeoff.csv", "tradeoff.md", "tradeoff.svg"] {
        assert!(dir.path().join(f).exists(), "{f}");
    }
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_rbsm"))
        .args(["tradeoff", scene, "--sweep", "refine=x"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("--sweep refine") && err.contains("1..=64"),
        "{err}"
    );
}

#[test]
fn a_gmsh_scene_finds_its_mesh_from_its_own_folder_whatever_the_working_directory() {
    // The gmsh cantilever with a tip probe, in a folder of its own beside its mesh's
    // (`../meshes/cantilever.msh`, relative to the scene's folder), traded from a third folder.
    let root = tempfile::tempdir().unwrap();
    // (From `elsewhere/deeper`, `../meshes` is no folder: the mesh is found from the scene's.)
    let [scenes, meshes, elsewhere] = ["scenes", "meshes", "elsewhere/deeper"].map(|d| {
        let d = root.path().join(d);
        std::fs::create_dir_all(&d).unwrap();
        d
    });
    let examples = concat!(env!("CARGO_MANIFEST_DIR"), "/examples");
    std::fs::copy(
        format!("{examples}/meshes/cantilever.msh"),
        meshes.join("cantilever.msh"),
    )
    .unwrap();
    let mut scene: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(format!("{examples}/scenes/cantilever_gmsh.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        scene["bodies"][0]["mesh"]["path"],
        "../meshes/cantilever.msh"
    );
    scene["time"]["end"] = 2e-3.into();
    scene["output"]["probes"] =
        serde_json::json!([{"name": "tip_v", "at": [1.99, 0.11], "dof": "v"}]);
    let file = scenes.join("cantilever_gmsh.json");
    std::fs::write(&file, scene.to_string()).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rbsm"))
        .current_dir(&elsewhere)
        .arg("tradeoff")
        .arg(&file)
        .args(["--sweep", "dt_factor=0.9,0.5", "--out"])
        .arg(root.path().join("out"))
        .args(["--json", "--quiet"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let points = report["points"].as_array().unwrap();
    assert_eq!(points.len(), 2);
    assert!(points
        .iter()
        .all(|p| p["status"] == "ok" && p["elements"] == 640));
    assert!(
        report["reference"]
            .as_str()
            .unwrap()
            .contains("dt_factor=0.5")
            && report["error"].as_str().unwrap().contains("tip_v"),
        "{report}"
    );
    assert!(points[0]["error"]
        .as_f64()
        .is_some_and(|e| e > 0.0 && e < 0.1));
}

/// A study's points run alone, passed as JSON (as they come back from the workers of a
/// cluster) and scored together, give `sweep`'s report: the same reference and errors.
#[test]
fn points_run_alone_and_scored_together_give_the_sweeps_report() {
    use rbsm::analysis::tradeoff::{Measured, Study};
    let scene = column();
    let settings = |f: &str, r: &str| vec![(Key::DtFactor, f.to_string()), (Key::Refine, r.into())];
    let study = Study::new(&scene).unwrap();
    // Out of sweep order, as a cluster finishes them; reported in the order given.
    let runs: Vec<Measured> = [("0.5", "1"), ("0.9", "2"), ("0.9", "1"), ("0.5", "2")]
        .iter()
        .map(|(f, r)| {
            let json = serde_json::to_string(&study.point(settings(f, r)).unwrap()).unwrap();
            serde_json::from_str(&json).unwrap()
        })
        .collect();
    let alone = study.report(runs).unwrap();
    let together = sweep(
        &scene,
        &sweeps(&["dt_factor=0.5,0.9", "refine=1,2"]),
        |_| (),
    )
    .unwrap();
    assert_eq!(alone.reference, together.reference);
    let find = |settings: &Vec<(Key, String)>| {
        together
            .points
            .iter()
            .find(|p| &p.settings == settings)
            .unwrap()
    };
    for p in &alone.points {
        let q = find(&p.settings);
        // The front depends on the wall times too, which differ from run to run.
        assert_eq!(
            (p.error, p.dt, p.steps, p.elements),
            (q.error, q.dt, q.steps, q.elements),
            "{:?}",
            p.settings
        );
    }
    // A value a sweep refuses is refused here too, before the point runs.
    let e = study
        .point(vec![(Key::Refine, "0".into())])
        .unwrap_err()
        .to_string();
    assert!(e.contains("--sweep refine") && e.contains("1..=64"), "{e}");
}

/// `seed` redraws every Voronoi mesh: another mesh of the same density, another `Δt_crit`;
/// a scene without a Voronoi mesh refuses it.
#[test]
fn a_seed_sweep_redraws_the_voronoi_mesh() {
    let mut scene = Scene::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/voronoi_panel.json"
    ))
    .unwrap();
    scene.output.vtk = false;
    scene.output.probes =
        vec![serde_json::from_str(r#"{"name": "top_u", "at": [0.5, 0.49], "dof": "u"}"#).unwrap()];
    let report = sweep(&scene, &sweeps(&["seed=1,2", "dt_factor=0.5"]), |_| ()).unwrap();
    let [a, b] = &report.points[..] else {
        panic!("two points")
    };
    assert_eq!(a.elements, b.elements);
    assert_ne!(a.dt_crit, b.dt_crit, "the same mesh for two seeds");
    assert!(a.error.is_some_and(|e| e > 0.0) || b.error.is_some_and(|e| e > 0.0));
    let e = sweep(&column(), &sweeps(&["seed=1"]), |_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("--sweep seed") && e.contains("no Voronoi mesh"),
        "{e}"
    );
    let e = Sweep::parse("seed=-1").unwrap_err().to_string();
    assert!(e.contains("--sweep seed"), "{e}");
}

/// The default folder of a sweep is one folder directly in `out/` whatever the scene's name
/// holds: a `/` or `..` in the name moved the files elsewhere. The name is
/// sanitised (not refused: it is free text elsewhere), its safe characters kept.
#[test]
fn the_default_folder_stays_in_out_whatever_the_name() {
    let mut scene = column();
    for name in [
        "../../etc",
        "a/b",
        "..",
        ".",
        "/abs",
        "",
        "é\u{0}\\x",
        &"y".repeat(256),
    ] {
        scene.name = name.to_string();
        let dir = rbsm::analysis::tradeoff::default_folder(&scene);
        let parts: Vec<_> = dir.components().collect();
        assert_eq!(parts.len(), 2, "{name:?} gives {dir:?}");
        assert_eq!(parts[0].as_os_str(), "out");
        let folder = parts[1].as_os_str().to_str().unwrap();
        assert!(
            folder.starts_with("tradeoff-")
                && folder.len() <= 255
                && folder[9..]
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_'),
            "{name:?} gives {dir:?}"
        );
    }
    scene.name = "column_step-2".into();
    assert_eq!(
        rbsm::analysis::tradeoff::default_folder(&scene),
        std::path::Path::new("out/tradeoff-column_step-2")
    );
}

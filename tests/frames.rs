//! The frames ParaView opens (README, *Reading the outputs in ParaView*): a run's `series.pvd`
//! lists VTK XML unstructured grids (`.vtu`), read back here with vtkio's XML parser; cells carry
//! their own VTK type; rigid elements are drawn with their finite rotation.

mod common;
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use rbsm::step::integrator::RunStatus;
use serde_json::Value;
use std::path::Path;
use vtkio::model::{Attribute, CellType, DataSet, Piece, VertexNumbers};

/// The frames a collection lists, in order.
fn listed(dir: &Path) -> Vec<String> {
    let pvd = std::fs::read_to_string(dir.join("series.pvd")).unwrap();
    pvd.split("file=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap().to_string())
        .collect()
}

/// Points, cell connectivity (per cell), cell types and cell-data names of a `.vtu` file.
fn read(path: &Path) -> (Vec<f64>, Vec<Vec<u64>>, Vec<CellType>, Vec<String>) {
    let vtk = vtkio::Vtk::import(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid")
    };
    let Piece::Inline(piece) = pieces.into_iter().next().unwrap() else {
        panic!("not inline")
    };
    let points: Vec<f64> = piece.points.cast_into().unwrap();
    let cells = match piece.cells.cell_verts {
        VertexNumbers::XML {
            connectivity,
            offsets,
        } => {
            let mut start = 0;
            offsets
                .iter()
                .map(|&end| {
                    let c = connectivity[start as usize..end as usize].to_vec();
                    start = end;
                    c
                })
                .collect()
        }
        VertexNumbers::Legacy { .. } => panic!("legacy cells in an XML file"),
    };
    let names = piece
        .data
        .cell
        .iter()
        .map(|a| match a {
            Attribute::DataArray(d) => d.name.clone(),
            Attribute::Field { name, .. } => name.clone(),
        })
        .collect();
    (points, cells, piece.cells.types, names)
}

fn bundled(name: &str) -> Value {
    let path = format!("{}/examples/scenes/{name}.json", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn the_series_lists_xml_frames_with_every_cell_typed_and_every_array() {
    // Voronoi cells (polygons, some quadrilaterals), rigid; and a hybrid grid of triangles.
    let mut tri = bundled("cantilever_hybrid");
    tri["bodies"][0]["mesh"]["cell"] = "tri".into();
    for (scene, arrays) in [
        (
            bundled("voronoi_panel"),
            vec!["displacement", "velocity", "rotation", "body"],
        ),
        (
            tri,
            vec![
                "displacement",
                "velocity",
                "rotation",
                "body",
                "strain",
                "stress",
            ],
        ),
    ] {
        let mut scene = scene;
        scene["output"]["vtk"] = true.into();
        scene["output"]["every"] = 50.into();
        let s = Scene::from_json_in(
            &scene.to_string(),
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/examples/scenes")),
        )
        .unwrap();
        let model = rbsm::model::Model::build(&s).unwrap();
        let dir = tempfile::tempdir().unwrap();
        common::run_into(&s, Some(200), dir.path());
        let frames = listed(dir.path());
        assert_eq!(
            frames,
            (0..=4)
                .map(|k| format!("vtk/step_{:09}.vtu", 50 * k))
                .collect::<Vec<_>>()
        );
        for f in &frames {
            let (points, cells, types, names) = read(&dir.path().join(f));
            assert_eq!(cells.len(), model.elements.len());
            assert_eq!(points.len(), 3 * cells.iter().map(Vec::len).sum::<usize>());
            for (cell, ty) in cells.iter().zip(&types) {
                let expected = match cell.len() {
                    3 => CellType::Triangle,
                    4 => CellType::Quad,
                    _ => CellType::Polygon,
                };
                assert_eq!(*ty, expected);
            }
            assert_eq!(names, arrays);
        }
    }
}

#[test]
fn a_block_spun_by_two_radians_keeps_its_shape_in_the_frames() {
    let (w, h) = (0.2, 0.1);
    let scene = serde_json::json!({
        "name": "spin", "thickness": 0.1, "formulation": {"kind": "rigid"},
        "materials": {"m": {"E": 1e9, "nu": 0.2, "rho": 1000.0}},
        "bodies": [{"name": "block", "material": "m",
            "mesh": {"kind": "grid", "origin": [0.0, 0.0], "size": [w, h], "cells": [1, 1]},
            "initial": {"angular_velocity": 2.0}}],
        "time": {"dt": 1e-3, "steps": 1000},
        "output": {"every": 1000, "vtk": true}
    });
    let s = Scene::from_json(&scene.to_string()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    common::run_into(&s, None, dir.path());
    let (points, cells, _, _) = read(&dir.path().join("vtk/step_000001000.vtu"));
    let p = |k: u64| (points[3 * k as usize], points[3 * k as usize + 1]);
    let cell = &cells[0];
    let lengths: Vec<f64> = (0..4)
        .map(|i| {
            let (a, b) = (p(cell[i]), p(cell[(i + 1) % 4]));
            (a.0 - b.0).hypot(a.1 - b.1)
        })
        .collect();
    for (l, reference) in lengths.iter().zip([w, h, w, h]) {
        assert!(
            (l - reference).abs() <= 1e-9,
            "edge lengths {lengths:?} against {w} × {h}"
        );
    }
    // Turned by 2 rad about its centroid, which stays put.
    let (a, b) = (p(cell[0]), p(cell[1]));
    let angle = (b.1 - a.1).atan2(b.0 - a.0);
    assert!((angle - 2.0).abs() < 1e-9, "edge at {angle} rad");
    let centre = (0..4).fold((0.0, 0.0), |c, i| {
        (c.0 + p(cell[i]).0 / 4.0, c.1 + p(cell[i]).1 / 4.0)
    });
    assert!(
        (centre.0 - 0.5 * w).abs() < 1e-12 && (centre.1 - 0.5 * h).abs() < 1e-12,
        "{centre:?}"
    );
}

/// Mode shapes come as `.vtu` files and a `modes.pvd` collection, one time step per mode.
#[test]
fn mode_shapes_open_as_a_series() {
    let s = Scene::from_json(&bundled("cantilever").to_string()).unwrap();
    let setup = Setup::new(&s, &Overrides::default()).unwrap();
    let params = rbsm::analysis::eigen::EigenParams {
        modes: 3,
        method: rbsm::analysis::eigen::Method::Auto,
    };
    let r = rbsm::analysis::eigen::analyse(&setup, &params).unwrap();
    let dir = tempfile::tempdir().unwrap();
    rbsm::output::vtk::write_mode_shapes(dir.path(), &setup.model, &r.modes.shapes).unwrap();
    let pvd = std::fs::read_to_string(dir.path().join("modes.pvd")).unwrap();
    let files: Vec<&str> = pvd
        .split("file=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap())
        .collect();
    assert_eq!(files, ["mode_001.vtu", "mode_002.vtu", "mode_003.vtu"]);
    assert!(pvd.contains(r#"timestep="1e0""#) && pvd.contains(r#"timestep="3e0""#));
    for f in files {
        let (_, cells, types, _) = read(&dir.path().join(f));
        assert_eq!(cells.len(), setup.model.elements.len());
        assert!(types.iter().all(|t| *t == CellType::Quad));
    }
}

/// Scenes without failing interfaces write the frames they wrote before the cracks were added,
/// byte for byte: `tests/golden/frames/{rigid,hybrid}/` hold the collection and the frames of
/// `tests/golden/frames/{rigid,hybrid}.json` as commit a61c31b wrote them (a fixed `dt`, and
/// motions that are translations up to round-off, so that no eigen solve or trigonometry of
/// the platform enters); and they write nothing about cracks. The frames at steps 10 and 20
/// were written again when the assembled evaluator came to sum `K U` from symmetric storage:
/// the same bytes but for round-off in the data (rotations within 4e-19 rad, velocities within
/// 2.2e-16 m/s of 0.3 to 0.4 m/s).
#[test]
fn frames_without_failure_are_the_frames_written_before_cracks() {
    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/frames");
    for name in ["rigid", "hybrid"] {
        let s = Scene::from_file(golden.join(format!("{name}.json"))).unwrap();
        let dir = tempfile::tempdir().unwrap();
        common::run_into(&s, None, dir.path());
        let expected = golden.join(name);
        let mut files = vec!["series.pvd".to_string()];
        files.extend(listed(&expected));
        assert_eq!(
            files.len(),
            4,
            "{name}: three frames in the golden collection"
        );
        for f in &files {
            let (got, want) = (
                std::fs::read(dir.path().join(f)).unwrap(),
                std::fs::read(expected.join(f)).unwrap(),
            );
            assert!(got == want, "{name}: {f} differs from the golden file");
        }
        let mut written: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        written.sort();
        assert_eq!(
            written,
            [
                "final_state.json",
                "history.csv",
                "series.pvd",
                "summary.json",
                "vtk"
            ],
            "{name}"
        );
        assert_eq!(
            std::fs::read_dir(dir.path().join("vtk")).unwrap().count(),
            3
        );
    }
}

/// The cell arrays of a `.vtu` file by name, as numbers, and its points.
fn arrays(path: &Path) -> (Vec<f64>, Vec<(String, Vec<f64>)>) {
    let vtk = vtkio::Vtk::import(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid")
    };
    let Piece::Inline(piece) = pieces.into_iter().next().unwrap() else {
        panic!("not inline")
    };
    let named = piece
        .data
        .cell
        .into_iter()
        .map(|a| match a {
            Attribute::DataArray(d) => (d.name, d.data.cast_into::<f64>().unwrap()),
            Attribute::Field { name, .. } => panic!("field data {name}"),
        })
        .collect();
    (piece.points.cast_into().unwrap(), named)
}

/// The bundled tension bar, which cracks within its run, with frames every 500 steps.
fn tension_bar() -> Value {
    let mut v = bundled("tension_bar");
    v["output"] = serde_json::json!({"vtk": true, "every": 500});
    v
}

/// A run whose interfaces can fail writes beside each element frame a frame of its failing
/// interfaces, `cracks/step_N.vtu`, listed by `cracks.pvd` at the same times: one line per
/// interface that can fail (the same lines in every frame), on its edge (the reference edge
/// at the start), with the arrays of its state; at the end they are the states of
/// `final_state.json`, some broken. The element frames keep one cell per element and their
/// arrays.
#[test]
fn a_cracking_run_writes_the_state_of_each_failing_interface_beside_the_frames() {
    let s = Scene::from_json(&tension_bar().to_string()).unwrap();
    let model = rbsm::model::Model::build(&s).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let summary = common::run_into(&s, None, dir.path());
    let failing = summary
        .failure
        .expect("the bar's interfaces can fail")
        .interfaces;
    assert_eq!(
        failing,
        model.interfaces.iter().filter(|i| model.fails(i)).count()
    );
    let frames = listed(dir.path());
    assert_eq!(frames.len(), 12, "steps 0, 500, …, 5000 and the last, 5367");
    let pvd = std::fs::read_to_string(dir.path().join("cracks.pvd")).unwrap();
    let series = std::fs::read_to_string(dir.path().join("series.pvd")).unwrap();
    assert_eq!(pvd, series.replace("file=\"vtk/", "file=\"cracks/"));
    let names = [
        "interface_status",
        "crack_opening",
        "crack_slip",
        "dissipated",
        "interface",
    ];
    let mut statuses = Vec::new();
    for f in &frames {
        let (_, cells, _, elements) = read(&dir.path().join(f));
        assert_eq!(cells.len(), model.elements.len());
        assert_eq!(elements, ["displacement", "velocity", "rotation", "body"]);
        let crack = dir.path().join(f.replace("vtk/", "cracks/"));
        let (_, lines, types, _) = read(&crack);
        assert_eq!(lines.len(), failing, "{f}: one line per failing interface");
        assert!(lines.iter().all(|l| l.len() == 2) && types.iter().all(|t| *t == CellType::Line));
        let (points, data) = arrays(&crack);
        assert_eq!(points.len(), 3 * 2 * failing);
        assert_eq!(data.iter().map(|d| d.0.as_str()).collect::<Vec<_>>(), names);
        for (name, values) in &data {
            assert_eq!(values.len(), failing, "{f}: tuples of {name}");
        }
        statuses.push(data[0].1.clone());
        if f == &frames[0] {
            // Nothing has moved: each line is its interface's reference edge (up to the
            // round-off of `x_e + (x − x_e)`, 1e-17 m on the 0.2 m bar).
            for (k, &i) in data[4].1.iter().enumerate() {
                let i = &model.interfaces[i as usize];
                for (j, p) in [i.p1, i.p2].iter().enumerate() {
                    let at = 6 * k + 3 * j;
                    let d = (points[at] - p.x).hypot(points[at + 1] - p.y);
                    assert!(d < 1e-15, "line {k} end {j} is {d:e} m off its edge");
                }
            }
        }
    }
    assert!(
        statuses[0].iter().all(|s| *s == 0.0),
        "all elastic at t = 0"
    );
    // The last frame is the final state.
    let state: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("final_state.json")).unwrap(),
    )
    .unwrap();
    let (_, data) = arrays(
        &dir.path()
            .join(frames.last().unwrap().replace("vtk/", "cracks/")),
    );
    let listed = state["interfaces"].as_array().unwrap();
    assert_eq!(listed.len(), failing);
    for (k, i) in listed.iter().enumerate() {
        let code = match i["status"].as_str().unwrap() {
            "elastic" => 0.0,
            "yielding" => 1.0,
            "broken" => 2.0,
            s => panic!("status {s}"),
        };
        assert_eq!(data[0].1[k], code);
        assert_eq!(data[1].1[k], i["opening"].as_f64().unwrap());
        assert_eq!(data[2].1[k], i["slip"].as_f64().unwrap());
        assert_eq!(data[3].1[k], i["dissipated"].as_f64().unwrap());
        assert_eq!(data[4].1[k], i["interface"].as_f64().unwrap());
    }
    let broken = statuses
        .last()
        .unwrap()
        .iter()
        .filter(|s| **s == 2.0)
        .count();
    assert!(broken > 0, "the bar has cracked through some interfaces");
    // Cracks only grow: an interface once broken stays broken.
    for w in statuses.windows(2) {
        assert!(w[0].iter().zip(&w[1]).all(|(a, b)| *a < 2.0 || *b == 2.0));
    }
}

/// A run of the cracking bar stopped after a checkpoint and resumed ends with the crack frames
/// and collection of a run that was never stopped, byte for byte; and a later run of a scene
/// without failure in the same folder removes them.
#[test]
fn crack_frames_resume_byte_for_byte_and_go_with_the_next_run() {
    let mut v = tension_bar();
    v["output"]["checkpoint_every"] = 1000.into();
    let s = Scene::from_json(&v.to_string()).unwrap();
    let setup = Setup::new(&s, &Overrides::default()).unwrap();
    let (whole, stopped) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    common::run_into(&s, None, whole.path());
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let params = rbsm::analysis::run::RunParams {
        resume: false,
        interrupt: Some(flag.clone()),
        keep_history: false,
    };
    let summary = rbsm::analysis::run::run(
        &setup,
        &params,
        stopped.path(),
        &mut common::StopAt {
            at: 2600,
            flag: flag.clone(),
        },
    )
    .unwrap();
    assert_eq!(summary.status, RunStatus::Interrupted);
    assert!(summary.steps < 5367);
    let resume = rbsm::analysis::run::RunParams {
        resume: true,
        interrupt: None,
        keep_history: false,
    };
    rbsm::analysis::run::run(
        &setup,
        &resume,
        stopped.path(),
        &mut rbsm::analysis::run::Silent,
    )
    .unwrap();
    let files = |d: &Path| {
        let mut names: Vec<String> = std::fs::read_dir(d.join("cracks"))
            .unwrap()
            .map(|e| format!("cracks/{}", e.unwrap().file_name().to_string_lossy()))
            .collect();
        names.sort();
        names.push("cracks.pvd".into());
        names
    };
    assert_eq!(files(whole.path()), files(stopped.path()));
    assert_eq!(files(whole.path()).len(), 13);
    for f in files(whole.path()) {
        assert!(
            std::fs::read(whole.path().join(&f)).unwrap()
                == std::fs::read(stopped.path().join(&f)).unwrap(),
            "{f} differs"
        );
    }
    let golden = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/frames/rigid.json");
    common::run_into(&Scene::from_file(golden).unwrap(), None, whole.path());
    // Its frames and the folder they emptied are gone.
    assert!(!whole.path().join("cracks.pvd").exists());
    assert!(!whole.path().join("cracks").exists());
}

/// A run writes no file through a symbolic link: a link in the output folder
/// is replaced by the file, its target left untouched, for `history.csv` (written row by row),
/// the temporary names files are written under, the collection and the frames, and for the
/// history a resumed run cuts back and goes on with.
#[cfg(unix)]
#[test]
fn a_run_writes_through_no_link() {
    use rbsm::analysis::run::{self, RunParams};
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let mut v = bundled("cantilever");
    v["time"] = serde_json::json!({"dt_factor": 0.5, "steps": 600});
    v["output"]["every"] = 20.into();
    v["output"]["vtk"] = true.into();
    v["output"]["checkpoint_every"] = 100.into();
    let scene = Scene::from_json(&v.to_string()).unwrap();
    let setup = Setup::new(&scene, &Overrides::default()).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let (out, targets) = (tmp.path().join("out"), tmp.path().join("targets"));
    std::fs::create_dir_all(out.join("vtk")).unwrap();
    std::fs::create_dir_all(&targets).unwrap();
    let names = [
        "history.csv",
        ".part-history.csv",
        ".part-series.pvd",
        "vtk/.part-step_000000000.vtu",
        "vtk/step_000000000.vtu",
        ".part-summary.json",
    ];
    let plant = |name: &str| {
        let target = targets.join(name.replace('/', "_"));
        std::fs::write(&target, "precious").unwrap();
        let link = out.join(name);
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(&target, &link).unwrap();
        target
    };
    let planted: Vec<_> = names.iter().map(|n| plant(n)).collect();
    // Stopped by its interrupt flag after its checkpoint at step 300.
    let stop_at = |at, flag: &Arc<AtomicBool>| common::StopAt {
        at,
        flag: flag.clone(),
    };
    let flag = Arc::new(AtomicBool::new(false));
    let params = |resume| RunParams {
        resume,
        interrupt: Some(flag.clone()),
        keep_history: false,
    };
    let first = run::run(&setup, &params(false), &out, &mut stop_at(330, &flag)).unwrap();
    assert_eq!(first.status, RunStatus::Interrupted);
    for (name, target) in names.iter().zip(&planted) {
        assert_eq!(
            std::fs::read_to_string(target).unwrap(),
            "precious",
            "{name}"
        );
    }
    let history = out.join("history.csv");
    assert!(std::fs::symlink_metadata(&history).unwrap().is_file());
    // The history becomes a link to a copy of itself; the resumed run replaces the link.
    let copy = targets.join("history_copy.csv");
    std::fs::copy(&history, &copy).unwrap();
    let before = std::fs::read(&copy).unwrap();
    std::fs::remove_file(&history).unwrap();
    std::os::unix::fs::symlink(&copy, &history).unwrap();
    flag.store(false, Ordering::SeqCst);
    let end = run::run(&setup, &params(true), &out, &mut stop_at(u64::MAX, &flag)).unwrap();
    assert_eq!(end.status, RunStatus::Ok);
    assert_eq!(
        std::fs::read(&copy).unwrap(),
        before,
        "the link's target was written"
    );
    assert!(std::fs::symlink_metadata(&history).unwrap().is_file());
    // And the history is that of a run never stopped.
    let whole = tmp.path().join("whole");
    flag.store(false, Ordering::SeqCst);
    run::run(
        &setup,
        &params(false),
        &whole,
        &mut stop_at(u64::MAX, &flag),
    )
    .unwrap();
    assert_eq!(
        std::fs::read(&history).unwrap(),
        std::fs::read(whole.join("history.csv")).unwrap()
    );
}

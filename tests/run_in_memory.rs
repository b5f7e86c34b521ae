//! A run without a folder (the Python package's): the history and final state in memory are
//! those a run with a folder writes, to the bit.

mod common;

use rbsm::analysis::run::{simulate, RunParams, Silent};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;

fn setup(name: &str, steps: u64) -> Setup {
    let path = format!("{}/examples/scenes/{name}", env!("CARGO_MANIFEST_DIR"));
    let overrides = Overrides {
        steps: Some(steps),
        ..Default::default()
    };
    Setup::new(&Scene::from_file(path).unwrap(), &overrides).unwrap()
}

#[test]
fn a_run_in_memory_holds_what_a_run_in_a_folder_writes() {
    for (name, steps) in [("cantilever.json", 2000), ("tension_bar.json", 1500)] {
        let s = setup(name, steps);
        let dir = tempfile::tempdir().unwrap();
        let keep = RunParams {
            keep_history: true,
            ..Default::default()
        };
        let written = simulate(&s, &keep, Some(dir.path()), &mut Silent).unwrap();
        let memory = simulate(&s, &RunParams::default(), None, &mut Silent).unwrap();
        // The history file, read back, is the rows kept in memory by both runs.
        let text = std::fs::read_to_string(dir.path().join("history.csv")).unwrap();
        let mut lines = text.lines();
        let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let rows: Vec<f64> = lines
            .flat_map(|l| l.split(',').map(|x| x.parse::<f64>().unwrap()))
            .collect();
        assert_eq!(header, memory.columns, "{name}");
        assert_eq!(written.columns, memory.columns);
        assert!(!rows.is_empty());
        let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&rows), bits(&memory.history), "{name}: history");
        assert_eq!(bits(&rows), bits(&written.history), "{name}: kept history");
        assert_eq!(bits(&written.u), bits(&memory.u), "{name}: U");
        assert_eq!(bits(&written.v), bits(&memory.v), "{name}: V");
        assert_eq!(written.t, memory.t);
        assert_eq!(written.summary.steps, steps);
        assert_eq!(
            written.interfaces.as_ref().map(Vec::len),
            memory.interfaces.as_ref().map(Vec::len)
        );
        // The final state on disk is the one in memory.
        let state =
            rbsm::output::read_final_state(&dir.path().join("final_state.json"), &s.model).unwrap();
        assert_eq!(bits(&state.u), bits(&memory.u), "{name}: final_state.json");
        // Without `keep_history`, a run in a folder keeps no rows.
        let lean = simulate(&s, &RunParams::default(), Some(dir.path()), &mut Silent).unwrap();
        assert!(lean.history.is_empty());
    }
}

#[test]
fn a_run_without_a_folder_cannot_resume() {
    let s = setup("cantilever.json", 10);
    let params = RunParams {
        resume: true,
        ..Default::default()
    };
    let e = simulate(&s, &params, None, &mut Silent)
        .unwrap_err()
        .to_string();
    assert!(e.contains("resume") && e.contains("folder"), "{e}");
}

/// A run resumed with its history kept (the Python package's `resume=True`) holds the whole
/// history, the rows before the checkpoint read back from `history.csv`: the same bits as a run
/// that was never stopped.
#[test]
fn a_resumed_run_keeps_the_whole_history() {
    let path = format!(
        "{}/examples/scenes/cantilever.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["output"]["checkpoint_every"] = 500.into();
    v["output"]["every"] = 100.into();
    let scene = Scene::from_json(&v.to_string()).unwrap();
    let overrides = Overrides {
        steps: Some(3000),
        ..Default::default()
    };
    let s = Setup::new(&scene, &overrides).unwrap();
    let keep = RunParams {
        keep_history: true,
        ..Default::default()
    };
    let (whole, stopped) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let reference = simulate(&s, &keep, Some(whole.path()), &mut Silent).unwrap();
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let first = RunParams {
        interrupt: Some(flag.clone()),
        ..Default::default()
    };
    let mut stop = common::StopAt { at: 1700, flag };
    let cut = simulate(&s, &first, Some(stopped.path()), &mut stop).unwrap();
    assert!(cut.summary.steps < 3000);
    let resume = RunParams {
        resume: true,
        keep_history: true,
        ..Default::default()
    };
    let resumed = simulate(&s, &resume, Some(stopped.path()), &mut Silent).unwrap();
    let bits = |x: &[f64]| x.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(resumed.columns, reference.columns);
    assert_eq!(bits(&resumed.history), bits(&reference.history));
    assert_eq!(bits(&resumed.u), bits(&reference.u));
}

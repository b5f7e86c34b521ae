//! The documents say what is so: the figures README.md quotes about the
//! bundled scenes that are not timings, the `$schema` the scenes name, and the folders README's
//! commands write into. Timings are measured, not tested.

use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn readme() -> String {
    std::fs::read_to_string(root().join("README.md")).unwrap()
}

fn scene_file(name: &str) -> PathBuf {
    root().join("examples/scenes").join(name)
}

fn scene_json(name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(scene_file(name)).unwrap()).unwrap()
}

/// The row of README's table of bundled scenes for `name`.
fn row<'r>(readme: &'r str, name: &str) -> &'r str {
    let start = format!("| `{name}` |");
    readme
        .lines()
        .find(|l| l.starts_with(&start))
        .unwrap_or_else(|| panic!("README.md: no row for `{name}` in *Bundled scenes*"))
}

fn contains(text: &str, what: &str, place: &str) {
    // A table row is shown; the whole README is not.
    let shown = if text.len() < 2000 { text } else { "" };
    assert!(
        text.contains(what),
        "README.md, {place}, should say `{what}`\n{shown}"
    );
}

/// Each scene's size and duration as the table of bundled scenes states them, taken from the
/// scene file.
#[test]
fn the_bundled_scenes_table_quotes_the_scenes() {
    let readme = readme();
    for (name, phrase) in [
        ("voronoi_panel.json", "{} centroidal Voronoi cells"),
        ("tension_bar.json", "{} Voronoi cells"),
        ("beam_drop.json", "{} Voronoi cells"),
        ("brazilian_disk.json", "{} Voronoi cells"),
        ("notched_beam.json", "{} Voronoi cells"),
    ] {
        let sites = &scene_json(name)["bodies"][0]["mesh"]["sites"];
        contains(
            row(&readme, name),
            &phrase.replace("{}", &sites.to_string()),
            name,
        );
    }
    let cells = &scene_json("cantilever.json")["bodies"][0]["mesh"]["cells"];
    contains(
        row(&readme, "cantilever.json"),
        &format!("{} × {} square elements", cells[0], cells[1]),
        "cantilever.json",
    );
    let hop = scene_json("hopping_block.json");
    let (end, dt) = (
        hop["time"]["end"].as_f64().unwrap(),
        hop["time"]["dt"].as_f64().unwrap(),
    );
    let hop_row = row(&readme, "hopping_block.json");
    contains(hop_row, &format!("{end} s of motion"), "hopping_block.json");
    contains(
        hop_row,
        &format!("Δt = {} µs", dt * 1e6),
        "hopping_block.json",
    );
    contains(
        hop_row,
        &format!("{} × 10⁶ steps", (end / dt).round() / 1e6),
        "hopping_block.json",
    );
}

/// The quick start's cantilever: its elements and steps as the setup of a run counts them.
#[test]
fn the_quick_start_quotes_the_cantilevers_size_and_steps() {
    let scene = Scene::from_file(scene_file("cantilever.json")).unwrap();
    let setup = Setup::new(&scene, &Overrides::default()).unwrap();
    let steps = setup.steps.to_string();
    // Thousands apart, as README writes them: 25 685.
    let (high, low) = steps.split_at(steps.len() - 3);
    let quoted = format!(
        "{} elements, {high} {low} steps",
        setup.model.elements.len()
    );
    contains(&readme(), &quoted, "Quick start");
}

/// README's ParaView walk-through quotes a bundled scene's `output` (`"output": {...}` in the
/// scene (the bundled `X.json` does)): each key it quotes has that value in the scene.
#[test]
fn the_paraview_walk_through_quotes_the_scenes_output() {
    // Its lines joined: the sentence may be wrapped anywhere.
    let readme = readme().split_whitespace().collect::<Vec<_>>().join(" ");
    let marker = "` in the scene (the bundled `";
    let at = readme
        .find(marker)
        .expect("README.md: the ParaView walk-through names a bundled scene");
    let quoted = &readme[..at];
    let quoted: Value = serde_json::from_str(
        quoted[quoted.rfind('`').unwrap() + 1..]
            .trim_start_matches("\"output\":")
            .trim(),
    )
    .expect("README.md: the quoted `output` is JSON");
    let rest = &readme[at + marker.len()..];
    let name = &rest[..rest.find('`').unwrap()];
    let output = &scene_json(name)["output"];
    for (key, value) in quoted.as_object().unwrap() {
        assert_eq!(
            &output[key], value,
            "README.md quotes `output.{key}` of `{name}` as {value}, the scene has {}",
            output[key]
        );
    }
}

/// Every `$schema` a bundled scene names is a file (relative to the scene) that holds what
/// `rbsm schema` prints now.
#[test]
fn every_schema_the_scenes_name_is_there_and_current() {
    let printed = serde_json::to_string_pretty(&rbsm::input::scene::schema()).unwrap() + "\n";
    let dir = root().join("examples/scenes");
    let mut named = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("json") {
            continue;
        }
        let scene: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let Some(schema) = scene.get("$schema") else {
            continue;
        };
        let schema = schema.as_str().unwrap();
        let file = dir.join(schema);
        let text = std::fs::read_to_string(&file).unwrap_or_else(|e| {
            panic!("{}: `$schema` {schema}: {e}", path.display());
        });
        assert!(
            text == printed,
            "{} differs from what `rbsm schema` prints: run \
             `cargo run --release -- schema > docs/scene.schema.json`",
            file.display()
        );
        named += 1;
    }
    assert!(named > 0, "no bundled scene names a `$schema`");
}

/// The `rbsm` command lines of README's `sh` blocks, their arguments split on blanks.
fn commands(readme: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut in_sh = false;
    for line in readme.lines() {
        if line.starts_with("```") {
            in_sh = line == "```sh" && !in_sh;
            continue;
        }
        if let Some(args) = in_sh
            .then(|| line.split_once("cargo run --release -- "))
            .flatten()
        {
            let args = args.1.split('#').next().unwrap();
            out.push(args.split_whitespace().map(str::to_string).collect());
        }
    }
    out
}

fn option<'a>(args: &'a [String], name: &str) -> Option<&'a str> {
    args.iter()
        .position(|a| a == name)
        .map(|k| args[k + 1].as_str())
}

/// README's commands run one after the other leave each one's output: no two write into the
/// same `--out` (a run owns its folder and clears it), and `draw --state DIR` reads the folder
/// of a run before it.
#[test]
fn readmes_commands_write_into_distinct_folders() {
    let commands = commands(&readme());
    assert!(commands.len() >= 10, "README.md: {commands:?}");
    let mut outs: Vec<&str> = Vec::new();
    let mut runs: Vec<&str> = Vec::new();
    for args in &commands {
        if let Some(state) = option(args, "--state") {
            assert!(
                runs.contains(&state),
                "README.md: `{}` draws the state of `{state}`, which no run before it writes",
                args.join(" ")
            );
        }
        if let Some(out) = option(args, "--out") {
            assert!(
                !outs.contains(&out),
                "README.md: two commands write into `{out}`, the second: `{}`",
                args.join(" ")
            );
            outs.push(out);
            if args[0] == "run" {
                runs.push(out);
            }
        }
    }
}

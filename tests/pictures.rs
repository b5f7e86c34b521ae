//! Pictures (README, *Commands*: `draw`, `plot`): the dependency-free SVG of a model and of a mode
//! shape, the SVG histories of `rbsm plot`, and the commands that write them.

use rbsm::input::scene::Scene;
use rbsm::model::{Model, GROUND};
use rbsm::output::drawing::{displaced_svg, model_svg};
use std::process::Command;

fn model(name: &str) -> Model {
    Model::build(
        &Scene::from_file(format!(
            "{}/examples/scenes/{name}.json",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap(),
    )
    .unwrap()
}

/// Every tag `<tag ...>` with `marker` in it.
fn tags<'a>(svg: &'a str, tag: &str, marker: &str) -> Vec<&'a str> {
    svg.split('<')
        .filter(|t| t.starts_with(tag) && t.contains(marker))
        .collect()
}

fn points(tag: &str) -> Vec<(f64, f64)> {
    let p = tag
        .split("points=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap();
    p.split_whitespace()
        .map(|xy| {
            let (x, y) = xy.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

/// The trimmed contents of every `<text>` element.
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .map(|t| {
            t.split_once('>')
                .unwrap()
                .1
                .split("</text>")
                .next()
                .unwrap()
                .trim()
                .to_string()
        })
        .collect()
}

fn view_box(svg: &str) -> (f64, f64) {
    let v: Vec<f64> = svg
        .split("viewBox=\"")
        .nth(1)
        .unwrap()
        .split('"')
        .next()
        .unwrap()
        .split(' ')
        .map(|s| s.parse().unwrap())
        .collect();
    (v[2], v[3])
}

#[test]
fn the_model_drawing_shows_each_element_spring_support_and_load_inside_its_frame() {
    let m = model("cantilever");
    let svg = model_svg(&m);
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    let elements = tags(&svg, "polygon", "fill=\"#dbe7f3\"");
    assert_eq!(elements.len(), m.elements.len());
    let pairs = m.interfaces.iter().filter(|i| i.b != GROUND).count();
    assert_eq!(
        tags(&svg, "line", "#2a5db0").len(),
        2 * pairs,
        "two springs per interface"
    );
    let grounded = m.interfaces.iter().filter(|i| i.b == GROUND).count();
    assert!(
        grounded == 8
            && tags(&svg, "line", "stroke=\"#1b8a3a\" stroke-width=\"2.5\"").len() == grounded
    );
    assert_eq!(
        tags(&svg, "line", "#c0392b").len(),
        m.loads.len(),
        "one arrow per point load"
    );
    // Every vertex inside the frame, and the drawing keeps the model's proportions.
    let (w, h) = view_box(&svg);
    let all: Vec<(f64, f64)> = elements.iter().flat_map(|t| points(t)).collect();
    assert!(all
        .iter()
        .all(|&(x, y)| (0.0..=w).contains(&x) && (0.0..=h).contains(&y)));
    let (x0, x1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (y0, y1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    assert!(((x1 - x0) / (y1 - y0) - 10.0).abs() < 1e-2, "2 m × 0.2 m");
    // Contact ground and gravity on the hopping block; the key names only what is drawn.
    let svg = model_svg(&model("hopping_block"));
    assert!(
        svg.contains(">g</text>")
            && !tags(&svg, "line", "stroke=\"#000\" stroke-width=\"2.5\"").is_empty()
    );
    assert!(
        svg.contains("hatched black: contact ground")
            && !svg.contains("blue:")
            && !svg.contains("red:")
    );
    // A clamped edge: one black triangle per element with fixed DOFs.
    let path = format!(
        "{}/examples/scenes/cantilever.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    scene["bodies"][0]["supports"] = serde_json::json!([{"edge": "left", "kind": "clamp"}]);
    let m = Model::build(&Scene::from_json(&scene.to_string()).unwrap()).unwrap();
    let svg = model_svg(&m);
    let clamped: std::collections::BTreeSet<usize> = m.fixed.iter().map(|d| d / 3).collect();
    assert_eq!(clamped.len(), 8);
    assert_eq!(tags(&svg, "polygon", "fill=\"black\"").len(), clamped.len());
    assert!(svg.contains("black: clamped elements") && !svg.contains("green:"));
}

#[test]
fn a_mode_drawing_moves_the_largest_vertex_a_tenth_of_the_model_size() {
    let m = model("cantilever");
    let n = m.n_dofs();
    // Nothing moves: the displaced elements lie on the reference.
    let svg = displaced_svg(&m, &vec![0.0; n], "rest");
    let (reference, displaced) = (
        tags(&svg, "polygon", "fill=\"none\""),
        tags(&svg, "polygon", "fill-opacity"),
    );
    assert_eq!(reference.len(), m.elements.len());
    assert!(reference
        .iter()
        .zip(&displaced)
        .all(|(r, d)| points(r) == points(d)));
    // A rotation of the whole plate about the origin by 1e-3 rad: U = (−θ y_c, θ x_c, θ).
    let mut u = vec![0.0; n];
    for (e, el) in m.elements.iter().enumerate() {
        let c = el.props.centroid;
        u[3 * e..3 * e + 3].copy_from_slice(&[-1e-3 * c.y, 1e-3 * c.x, 1e-3]);
    }
    let svg = displaced_svg(&m, &u, "rotation");
    let (reference, displaced) = (
        tags(&svg, "polygon", "fill=\"none\""),
        tags(&svg, "polygon", "fill-opacity"),
    );
    let all: Vec<(f64, f64)> = reference.iter().flat_map(|t| points(t)).collect();
    let width_px = all.iter().map(|p| p.0).fold(f64::MIN, f64::max)
        - all.iter().map(|p| p.0).fold(f64::MAX, f64::min);
    let largest = reference
        .iter()
        .zip(&displaced)
        .flat_map(|(r, d)| points(r).into_iter().zip(points(d)))
        .map(|(a, b)| (a.0 - b.0).hypot(a.1 - b.1))
        .fold(0.0, f64::max);
    // The largest vertex displacement is a tenth of the 2 m length; the picture's reference
    // width is 2 m (up to the 0.01 px of the coordinates).
    assert!(
        (largest / width_px - 0.1).abs() < 1e-3,
        "largest {largest} px of {width_px} px"
    );
}

/// The bundled scene `name` run for `steps` steps into a new folder.
fn bundled_run(name: &str, steps: u64) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let scene = Scene::from_file(format!(
        "{}/examples/scenes/{name}.json",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let opts = rbsm::analysis::setup::Overrides {
        steps: Some(steps),
        ..Default::default()
    };
    rbsm::analysis::run::run(
        &rbsm::analysis::setup::Setup::new(&scene, &opts).unwrap(),
        &Default::default(),
        dir.path(),
        &mut rbsm::analysis::run::Silent,
    )
    .unwrap();
    dir
}

#[test]
fn plot_draws_energies_and_probes_of_a_run_and_refuses_an_empty_directory() {
    let dir = bundled_run("cantilever", 400);
    let written = rbsm::output::plot::histories(dir.path()).unwrap();
    assert_eq!(
        written,
        vec![
            dir.path().join("energies.svg"),
            dir.path().join("probes.svg")
        ]
    );
    let energies = texts(&std::fs::read_to_string(&written[0]).unwrap());
    for name in ["kinetic", "elastic", "external_work", "total"] {
        assert!(energies.iter().any(|t| t == name), "{name} in the legend");
    }
    assert!(
        !energies.iter().any(|t| t == "contact"),
        "no contact in the scene: its zero energy is not drawn"
    );
    assert!(texts(&std::fs::read_to_string(&written[1]).unwrap())
        .iter()
        .any(|t| t == "probe tip_v"));
    // Nothing to draw, and a broken history.
    let empty = tempfile::tempdir().unwrap();
    let e = rbsm::output::plot::histories(empty.path())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("history.csv") && e.contains("fraction_F.csv"),
        "{e}"
    );
    std::fs::write(empty.path().join("history.csv"), "t,kinetic\n0,1\n1e-3,x\n").unwrap();
    let e = rbsm::output::plot::histories(empty.path())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("line 3") && e.contains("`x`") && e.contains("kinetic"),
        "{e}"
    );
}

/// The works a failing, damped model adds to its history are energies, drawn with the others;
/// a moving clamp's displacement and reaction are panels of their own with their units; none of
/// them is a probe.
#[test]
fn plot_draws_the_works_as_energies_and_the_clamps_apart_from_the_probes() {
    let dir = bundled_run("squeeze", 3000);
    let history = std::fs::read_to_string(dir.path().join("history.csv")).unwrap();
    let header: Vec<&str> = history.lines().next().unwrap().split(',').collect();
    for column in [
        "fracture",
        "friction",
        "damping",
        "block_s1_disp",
        "block_s1_force",
    ] {
        assert!(header.contains(&column), "{column} in {header:?}");
    }
    let written = rbsm::output::plot::histories(dir.path()).unwrap();
    let energies = texts(&std::fs::read_to_string(&written[0]).unwrap());
    for name in ["external_work", "fracture", "damping"] {
        assert!(energies.iter().any(|t| t == name), "{name} in {energies:?}");
    }
    let panels = texts(&std::fs::read_to_string(&written[1]).unwrap());
    assert!(
        !panels.iter().any(|t| t.starts_with("probe")),
        "the squeeze has no probe: {panels:?}"
    );
    for text in [
        "clamp block_s1: its displacement along its velocity",
        "block_s1_disp (m)",
        "clamp block_s1: its reaction along its velocity",
        "block_s1_force (N)",
    ] {
        assert!(panels.iter().any(|t| t == text), "{text} in {panels:?}");
    }
}

#[test]
fn the_commands_write_the_pictures() {
    let dir = tempfile::tempdir().unwrap();
    let rbsm = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_rbsm"))
            .args(args)
            .arg("--quiet")
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let d = dir.path().to_str().unwrap();
    rbsm(&[
        "draw",
        "examples/scenes/voronoi_panel.json",
        "--out",
        &format!("{d}/panel.svg"),
    ]);
    rbsm(&[
        "eigen",
        "examples/scenes/cantilever.json",
        "--modes",
        "2",
        "--svg",
        &format!("{d}/modes"),
    ]);
    rbsm(&[
        "stability",
        "examples/scenes/cantilever.json",
        "--steps",
        "400",
        "--out",
        &format!("{d}/stability"),
    ]);
    rbsm(&["plot", &format!("{d}/stability")]);
    let panel = std::fs::read_to_string(dir.path().join("panel.svg")).unwrap();
    assert_eq!(tags(&panel, "polygon", "fill=\"#dbe7f3\"").len(), 400);
    let mode = std::fs::read_to_string(dir.path().join("modes/mode_002.svg")).unwrap();
    assert!(
        mode.contains("cantilever mode 2: f = 1.7364"),
        "the caption names the frequency"
    );
    assert!(!dir.path().join("modes/mode_003.svg").exists());
    let s = texts(&std::fs::read_to_string(dir.path().join("stability/stability.svg")).unwrap());
    assert!(
        ["0.9", "0.99", "1.01"]
            .iter()
            .all(|f| s.contains(&format!("dt = {f} Δt_crit"))),
        "{s:?}"
    );
}

/// `rbsm draw SCENE --state DIR` draws a run's final state: every element displaced, each
/// broken interface of `final_state.json` as a thick red line and each yielding one as an
/// orange line, counted in the legend; without `--state` the command draws the model as
/// before. A missing state, or the state of another scene (other elements, or as many
/// elements elsewhere), is an error that names the file, not a panic.
#[test]
fn draw_state_shows_the_cracks_of_a_run_and_refuses_another_scenes_state() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let bar = root.join("examples/scenes/tension_bar.json");
    let scene = Scene::from_file(&bar).unwrap();
    let setup = rbsm::analysis::setup::Setup::new(&scene, &Default::default()).unwrap();
    let run = d.join("run");
    rbsm::analysis::run::run(
        &setup,
        &Default::default(),
        &run,
        &mut rbsm::analysis::run::Silent,
    )
    .unwrap();
    let rbsm = |args: &[&std::ffi::OsStr]| {
        Command::new(env!("CARGO_BIN_EXE_rbsm"))
            .arg("draw")
            .args(args)
            .arg("--quiet")
            .output()
            .unwrap()
    };
    let (svg, plain) = (d.join("state.svg"), d.join("model.svg"));
    for (out, state) in [(&svg, Some(&run)), (&plain, None)] {
        let mut args = vec![bar.as_os_str(), "--out".as_ref(), out.as_os_str()];
        if let Some(s) = state {
            args.extend(["--state".as_ref(), s.as_os_str()]);
        }
        let o = rbsm(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let m = &setup.model;
    assert_eq!(std::fs::read_to_string(&plain).unwrap(), model_svg(m));
    let svg = std::fs::read_to_string(&svg).unwrap();
    let state: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("final_state.json")).unwrap())
            .unwrap();
    let count = |s: &str| {
        state["interfaces"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|i| i["status"] == s)
            .count()
    };
    let (broken, yielding) = (count("broken"), count("yielding"));
    assert!(broken > 0, "the bar cracks through");
    let red = tags(&svg, "line", "class=\"crack broken\"");
    let orange = tags(&svg, "line", "class=\"crack yielding\"");
    assert_eq!((red.len(), orange.len()), (broken, yielding));
    assert!(red
        .iter()
        .all(|t| t.contains("#d62728") && t.contains("stroke-width=\"3.5\"")));
    assert!(orange
        .iter()
        .all(|t| t.contains("#ff8c00") && t.contains("stroke-width=\"1.5\"")));
    assert_eq!(
        tags(&svg, "polygon", "fill-opacity").len(),
        m.elements.len(),
        "every element displaced"
    );
    let legend = format!(
        "{} broken (thick red, {} of them released to contact), {yielding} yielding (orange), \
         {} elastic",
        broken + count("released"),
        count("released"),
        count("elastic")
    );
    assert!(texts(&svg).contains(&legend), "{:?}", texts(&svg));
    // Every crack inside the picture.
    let (w, h) = view_box(&svg);
    let attr = |t: &str, a: &str| -> f64 {
        t.split(&format!("{a}=\""))
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    for t in red.iter().chain(&orange) {
        for (x, y) in [("x1", "y1"), ("x2", "y2")] {
            assert!((0.0..=w).contains(&attr(t, x)) && (0.0..=h).contains(&attr(t, y)));
        }
    }
    // Bad states: none, another scene's (640 elements), and 200 elements of another mesh.
    let other = d.join("other.json");
    std::fs::write(
        &other,
        std::fs::read_to_string(&bar)
            .unwrap()
            .replace("\"seed\": 1", "\"seed\": 2"),
    )
    .unwrap();
    let cantilever = root.join("examples/scenes/cantilever.json");
    for (scene, state, why) in [
        (&bar, d.join("nothing"), "No such file"),
        (&cantilever, run.clone(), "holds 200 elements"),
        (&other, run.clone(), "centroid"),
    ] {
        let o = rbsm(&[
            scene.as_os_str(),
            "--out".as_ref(),
            d.join("bad.svg").as_os_str(),
            "--state".as_ref(),
            state.as_os_str(),
        ]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{e}");
        let file = state.join("final_state.json");
        assert!(
            e.contains(&*file.to_string_lossy()) && e.contains(why),
            "{e}"
        );
        assert!(!d.join("bad.svg").exists());
    }
}

/// A long ground does not shrink the bodies: the drawing shows the ground near them (the
/// hopping block's brick, 0.21 m over 40 m of ground, used to be a dash of 4 px). A state whose
/// bodies moved by more than a tenth of their own size (the toppling stack's bricks, turned by
/// 0.5 rad and moved 0.1 m, which the 3 m ground used to hide) is drawn at true scale with
/// finite rotations, each brick keeping its sides' lengths, over the ground.
#[test]
fn drawings_fit_the_bodies_and_draw_large_motions_at_true_scale() {
    let m = model("hopping_block");
    let svg = model_svg(&m);
    let brick = points(tags(&svg, "polygon", "stroke=\"#555\"")[0]);
    let (x0, x1) = brick
        .iter()
        .fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    assert!(x1 - x0 > 100.0, "the brick is {} px wide", x1 - x0);
    let m = model("toppling_stack");
    let nd = m.formulation.ndof();
    let mut u = vec![0.0; m.elements.len() * nd];
    for e in u.chunks_mut(nd) {
        e[..3].copy_from_slice(&[0.1, -0.02, 0.5]);
    }
    let state = rbsm::output::FinalState {
        t: 1.0,
        u,
        interfaces: Vec::new(),
    };
    let svg = rbsm::output::drawing::state_svg(&m, &state);
    assert!(svg.contains("true scale"), "{}", texts(&svg)[0]);
    assert!(!tags(&svg, "line", "stroke=\"#000\" stroke-width=\"2.5\"").is_empty());
    let placed = tags(&svg, "polygon", "fill-opacity");
    let reference = tags(&svg, "polygon", "stroke=\"#bbb\"");
    assert_eq!(placed.len(), m.elements.len());
    let sides = |tag: &str| {
        let p = points(tag);
        (0..p.len())
            .map(|k| {
                let (a, b) = (p[k], p[(k + 1) % p.len()]);
                ((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt()
            })
            .collect::<Vec<_>>()
    };
    for (placed, reference) in placed.iter().zip(&reference) {
        for (a, b) in sides(placed).iter().zip(sides(reference)) {
            assert!((a - b).abs() < 0.05, "a side of {b:.2} px drawn {a:.2} px");
        }
    }
}

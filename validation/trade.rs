//! Section 9 of the validation report: speed against accuracy (`rbsm tradeoff`) on the column,
//! the cantilever and the hopping block.

use super::Report;
use rbsm::analysis::tradeoff::{sweep, Sweep, TradeoffReport as Trade};
use rbsm::input::scene::Scene;

fn trade(r: &mut Report, file: &str, args: &[&str]) -> Trade {
    let scene = Scene::from_file(r.dir.join("../examples/scenes").join(file)).unwrap();
    let sweeps: Vec<Sweep> = args.iter().map(|a| Sweep::parse(a).unwrap()).collect();
    let report = sweep(&scene, &sweeps, |_| ()).unwrap();
    let name = file.trim_end_matches(".json");
    // The full tables, with wall times and the Pareto front, go with the timings (not tracked).
    report
        .write(&r.dir.join(format!("timings/tradeoff_{name}")))
        .unwrap();
    let command = format!(
        "rbsm tradeoff examples/scenes/{file} {}",
        args.iter()
            .map(|a| format!("--sweep {a}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    r.line(&format!(
        "`{command}`; the errors (the wall times and the Pareto front are in \
        `validation/timings/tradeoff_{name}/`):\n"
    ));
    let names: Vec<&str> = report
        .points
        .first()
        .map(|p| p.settings.iter().map(|s| s.0.name()).collect())
        .unwrap_or_default();
    r.line(&format!(
        "| {} | elements | dt (s) | dt / dt_crit | steps | error |",
        names.join(" | ")
    ));
    r.line(&format!(
        "|{}---|---|---|---|---|",
        "---|".repeat(names.len() + 1)
    ));
    for p in &report.points {
        let values: Vec<&str> = p.settings.iter().map(|s| s.1.as_str()).collect();
        let error = p.error.map_or("—".to_string(), |e| format!("{e:.3e}"));
        r.line(&format!(
            "| {} | {} | {:.3e} | {:.3} | {} | {error} |",
            values.join(" | "),
            p.elements,
            p.dt,
            p.dt / p.dt_crit,
            p.steps
        ));
    }
    r.line("");
    r.timing(&format!(
        "\n## `{command}`\n\n![trade {name}](timings/tradeoff_{name}/tradeoff.svg)\n"
    ));
    r.timing(
        &std::fs::read_to_string(r.dir.join(format!("timings/tradeoff_{name}/tradeoff.md")))
            .unwrap(),
    );
    report
}

fn error(t: &Trade, settings: &[&str]) -> f64 {
    t.points
        .iter()
        .find(|p| {
            p.settings
                .iter()
                .map(|s| s.1.as_str())
                .eq(settings.iter().copied())
        })
        .and_then(|p| p.error)
        .unwrap_or(f64::NAN)
}

pub fn trade_section(r: &mut Report) {
    r.line("## 9. Speed against accuracy\n");
    r.line("Each point's error is measured against the scene's closed form, the theory of the hopping block, or else the \
            finest run of the sweep; the errors are deterministic. Wall time (the model, `Δt_crit` by Lanczos and the time \
            loop: the median of runs repeated until their stepping adds up to 0.2 s, at most 25, on the machine that ran the \
            validation, with their range) and the Pareto front it gives (where two points' ranges of runs overlap, the time \
            does not decide between them) are in `validation/timings.md` and `validation/timings/`, which git does not \
            track.\n");
    r.line("### 9.1 Column under a step end load, against the bar's modal series\n");
    let c = trade(
        r,
        "column_step.json",
        &["refine=1,2,4,8,16", "dt_factor=0.9,0.5,0.1"],
    );
    r.line("The error falls about as `h` with the mesh (the wave front is a jump, which a chain of blocks resolves over a few \
            blocks), and it is *smaller* near `Δt_crit`: a 1D chain stepped at the Courant limit is exact, so the time \
            discretisation cancels part of the mesh's dispersion. The cheapest accurate runs are therefore the fine meshes at \
            0.9 `Δt_crit`.\n");
    for (k, f) in [("1", "0.9"), ("16", "0.9"), ("16", "0.1")] {
        r.figure(
            &format!("trade column: error refine={k} dt_factor={f}"),
            error(&c, &[k, f]),
            1e-6,
        );
    }
    r.bound(
        "trade column: error at refine 16 over refine 1 (dt_factor 0.9)",
        error(&c, &["16", "0.9"]) / error(&c, &["1", "0.9"]),
        0.1,
    );
    r.line("### 9.2 Cantilever, against the finest run\n");
    let k = trade(r, "cantilever.json", &["refine=1,2,3", "dt_factor=0.9,0.3"]);
    r.line("The time step hardly matters here (the tip history is dominated by the lowest bending modes, far below `ω_max`); \
            the mesh does.\n");
    r.figure(
        "trade cantilever: error refine=1 dt_factor=0.9",
        error(&k, &["1", "0.9"]),
        1e-6,
    );
    r.bound(
        "trade cantilever: error at refine 2 over refine 1 (dt_factor 0.9)",
        error(&k, &["2", "0.9"]) / error(&k, &["1", "0.9"]),
        0.5,
    );
    r.line("### 9.3 Hopping block, against its theory\n");
    let h = trade(
        r,
        "hopping_block.json",
        &["dt=8e-6,4e-6,2e-6,1e-6", "contact=edge-to-edge,point"],
    );
    r.line("For the single rigid brick both contact models give nearly the same apex error: with a flat landing the point \
            springs at the two corners and the edge-to-edge interface carry the same force. From 8 µs to 1 µs the error falls by \
            about 180×, order 2.5 in `Δt`. Each point runs one step at a time through the first bounce, so its wall time is \
            dominated by the flight, not by the contact.\n");
    for m in ["edge-to-edge", "point"] {
        r.figure(
            &format!("trade hopping: apex error dt=1e-6 {m}"),
            error(&h, &["1e-6", m]),
            1e-6,
        );
        r.bound(
            &format!("trade hopping: apex error dt=1e-6 over dt=8e-6, {m} (second order: 1/64)"),
            error(&h, &["1e-6", m]) / error(&h, &["8e-6", m]),
            1.0 / 16.0,
        );
    }
}

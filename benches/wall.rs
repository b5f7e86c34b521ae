//! Contact at DEM scale: a running-bond wall of 100 × 100 of the paper's bricks settling on the
//! ground, as µs per body-step of both contact models on 1 and 2 threads, with the narrow-phase
//! tests and live contacts per body-step, beside the same wall in pymunk (Chipmunk2D, an
//! impulse solver) run by `benches/peer_pymunk.py` in the same harness, round after round; and
//! the share of the hopping block's step spent in contact.
//!
//! `cargo bench --bench wall` rewrites the section *Contact at DEM scale* of
//! `benches/summary.md` (about 2 minutes; `cargo bench --bench step` keeps it). The peer
//! needs `pip install pymunk`; without it the peer's column says so. `RBSM_WALL=30` runs a
//! 30 × 30 wall instead, for a quick look (the summary is then left as it was).

#[path = "common/section.rs"]
mod section;

use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::Scene;
use std::fmt::Write as _;
use std::process::Command;
use std::time::Instant;

/// Steps before the timing: the wall, placed touching, presses its contacts in.
const WARMUP: u64 = 300;
/// Steps of one timed round.
const STEPS: u64 = 50;
/// Rounds; each figure is their median.
const ROUNDS: usize = 3;

/// The bundled wall with `n × n` bricks placed touching, so that it carries itself from the
/// first steps.
fn wall(n: usize, model: &str) -> Scene {
    let json = include_str!("../examples/scenes/wall.json")
        .replace("\"count\": [10, 10]", &format!("\"count\": [{n}, {n}]"))
        .replace("\"origin\": [0.0, 1e-5]", "\"origin\": [0.0, 0.0]")
        .replace("\"pitch\": [0.20001, 0.10001]", "\"pitch\": [0.2, 0.1]")
        .replace(
            "\"to\": [3.0, 0.0]",
            &format!("\"to\": [{}, 0.0]", 0.2001 * n as f64 + 1.0),
        )
        .replace(
            "\"model\": \"edge-to-edge\"",
            &format!("\"model\": \"{model}\""),
        );
    Scene::from_json(&json).expect("the wall scene is valid")
}

/// One model's figures on one thread count.
struct Ours {
    us: f64,
    tests: f64,
    live: f64,
    contact_share: f64,
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
}

/// Median µs per body-step over the rounds, after the warm-up.
fn ours(p: &Setup, threads: usize) -> Ours {
    let bodies = p.model.bodies.len() as f64;
    pool(threads).install(|| {
        let mut cd = p.integrator(p.dt);
        cd.step_only(WARMUP);
        let mut times = Vec::new();
        let (mut tests, mut live, mut contact, mut total) = (0.0, 0.0, 0.0, 0.0);
        for _ in 0..ROUNDS {
            let before = cd.contact.as_ref().unwrap().stats;
            let clock = Instant::now();
            cd.step_only(STEPS);
            let elapsed = clock.elapsed().as_secs_f64();
            let after = cd.contact.as_ref().unwrap().stats;
            times.push(elapsed / (STEPS as f64 * bodies) * 1e6);
            tests += (after.tests - before.tests) as f64;
            live += cd.contact.as_ref().unwrap().live() as f64;
            contact += after.time_s - before.time_s;
            total += elapsed;
        }
        times.sort_by(f64::total_cmp);
        let per = (ROUNDS as u64 * STEPS) as f64 * bodies;
        Ours {
            us: times[ROUNDS / 2],
            tests: tests / per,
            live: live / (ROUNDS as f64 * bodies),
            contact_share: contact / total,
        }
    })
}

/// The peer's µs per body-step, or why there is none.
fn peer(n: usize, threads: usize, dt: f64) -> Result<f64, String> {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/benches/peer_pymunk.py");
    let args = [n, n, WARMUP as usize, STEPS as usize, threads].map(|a| a.to_string());
    let out = Command::new("python3")
        .arg(script)
        .args(&args)
        .arg(dt.to_string())
        .arg("0")
        .output()
        .map_err(|e| format!("python3: {e}"))?;
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr)
            .lines()
            .last()
            .unwrap_or("failed")
            .to_string());
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).map_err(|e| e.to_string())?;
    v["us_per_body_step"]
        .as_f64()
        .ok_or_else(|| "no figure".into())
}

/// The hopping block's share of its step spent in contact (in flight and bouncing): its step
/// time against that of the same block falling without ground or contact, 2 × 10⁶ steps each on
/// 1 thread, the median of seven such pairs.
fn hopping_share() -> f64 {
    let json = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/scenes/hopping_block.json"
    ))
    .unwrap();
    let mut bare: serde_json::Value = serde_json::from_str(&json).unwrap();
    let map = bare.as_object_mut().unwrap();
    map.remove("ground");
    map.remove("contact");
    let time = |json: &str| {
        let p = Setup::new(
            &Scene::from_json(json).unwrap(),
            &Overrides {
                dt: Some(1e-6),
                ..Default::default()
            },
        )
        .unwrap();
        pool(1).install(|| {
            let mut cd = p.integrator(p.dt);
            let clock = Instant::now();
            cd.step_only(2_000_000);
            clock.elapsed().as_secs_f64()
        })
    };
    let bare = bare.to_string();
    let mut shares: Vec<f64> = (0..7)
        .map(|_| {
            let with = time(&json);
            1.0 - time(&bare) / with
        })
        .collect();
    shares.sort_by(f64::total_cmp);
    shares[3]
}

fn main() {
    let quick = std::env::var("RBSM_WALL").ok().and_then(|s| s.parse().ok());
    let n = quick.unwrap_or(100);
    let mut table = String::new();
    for model in ["edge-to-edge", "point"] {
        let p = Setup::new(&wall(n, model), &Overrides::default()).expect("wall model");
        for threads in [1, 2] {
            let o = ours(&p, threads);
            let q = peer(n, threads, p.dt);
            let (q_text, ratio) = match &q {
                Ok(us) => (format!("{us:.3}"), format!("{:.2}", us / o.us)),
                Err(e) => (format!("not run: {e}"), "–".into()),
            };
            println!(
                "{model}, {threads} thread(s): {:.3} µs per body-step, {:.2} tests and {:.2} \
                    contacts per body-step, contact {:.0} % of the step; pymunk {q_text} (ratio \
                    {ratio})",
                o.us,
                o.tests,
                o.live,
                100.0 * o.contact_share
            );
            writeln!(
                table,
                "| {model} | {threads} | {:.3} | {:.2} | {:.2} | {:.0} % | {q_text} | {ratio} |",
                o.us,
                o.tests,
                o.live,
                100.0 * o.contact_share
            )
            .unwrap();
        }
    }
    let share = hopping_share();
    println!("hopping block: contact {:.0} % of the step", 100.0 * share);
    if quick.is_some() {
        return;
    }
    let mut md = String::new();
    writeln!(md, "# Contact at DEM scale (`cargo bench --bench wall`)\n").unwrap();
    writeln!(
        md,
        "A running-bond wall of {n} × {n} bricks (0.2 × 0.1 m, rows shifted by a quarter brick, placed touching on the \
         ground), friction 0.5, damping 1000 1/s, Δt = 0.2 Δt_crit: {WARMUP} steps for gravity to press the \
         contacts in, then the median of \
         {ROUNDS} rounds of {STEPS} steps. The peer is the same wall in pymunk (Chipmunk2D, impulses, 10 iterations \
         a step) at the same Δt on as many threads, run between our rounds by `benches/peer_pymunk.py`; \
         *peer / rbsm* above 1 means rbsm is faster. Chipmunk's impulses allow a far larger Δt than a penalty \
         spring: this compares the cost of one step, not of a simulated second.\n"
    )
    .unwrap();
    writeln!(
        md,
        "| contact | threads | rbsm µs per body-step | narrow-phase tests per body-step \
        | live contacts per body | contact share of the step | pymunk µs per body-step | peer / \
        rbsm |"
    )
    .unwrap();
    writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|").unwrap();
    md.push_str(&table);
    writeln!(
        md,
        "\nThe hopping block (`examples/scenes/hopping_block.json`, 2 × 10⁶ steps of 1 µs on 1 thread against the same \
         block without ground or contact, median of 7 pairs): contact is {:.0} % of the step.",
        100.0 * share
    )
    .unwrap();
    section::write("wall", &md);
}

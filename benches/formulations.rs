//! What each formulation costs a step: Voronoi panels of 10⁴, 10⁵ and 10⁶ elements, rigid,
//! `rigid-poisson` and hybrid (`p` = 10), stepped by both evaluators on 1 and 2 threads; as ns
//! per element-step (the median of criterion's samples, with the quartiles). Every sample steps
//! the three formulations' panels in turn, and the ratios to the rigid step are taken sample by
//! sample, their median reported: the figures to read.
//!
//! `cargo bench --bench formulations` measures and rewrites the section *What a formulation
//! costs* of `benches/summary.md` (between its markers; `cargo bench --bench step` keeps it);
//! `RBSM_BENCH_MAX=100000` stops at 10⁵ elements and leaves the summary as it was.

#[path = "common/paired.rs"]
mod paired;
#[path = "common/section.rs"]
mod section;

use criterion::Criterion;
use rbsm::force::evaluator;
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::model::loads::Loads;
use rbsm::model::mass::Mass;
use rbsm::model::Model;
use rbsm::step::integrator::CentralDifference;
use std::cell::RefCell;
use std::fmt::Write as _;
use std::time::{Duration, Instant};

const SIZES: [usize; 3] = [10_000, 100_000, 1_000_000];
const FORMULATIONS: [(&str, &str); 3] = [
    ("rigid", r#"{"kind": "rigid"}"#),
    ("rigid-poisson", r#"{"kind": "rigid-poisson"}"#),
    ("hybrid", r#"{"kind": "hybrid", "penalty": 10}"#),
];

fn scene(elements: usize, formulation: &str) -> Scene {
    let json = format!(
        r#"{{"name": "bench", "thickness": 1.0, "formulation": {formulation},
            "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m",
                "mesh": {{"kind": "voronoi", "origin": [0, 0], "size": [1, 1], "sites": {elements}, "seed": 1, "lloyd": 2}},
                "supports": [{{"edge": "left", "kind": "ground-spring"}}],
                "loads": [{{"kind": "traction", "edge": "right", "value": [1e6, 1e5]}}]}}],
            "time": {{"dt": 1e-9, "steps": 1}}}}"#
    );
    Scene::from_json(&json).expect("the bench scene is valid")
}

fn main() {
    let mut c = Criterion::default()
        .sample_size(10)
        .measurement_time(Duration::from_secs(6))
        .warm_up_time(Duration::from_millis(500))
        .configure_from_args();
    // (elements, evaluator, threads) → per formulation [q1, median, q3] ns per element-step,
    // and the medians of the ratios to rigid, sample by sample.
    type Row = (usize, &'static str, usize, [[f64; 3]; 3], [f64; 2]);
    let mut rows: Vec<Row> = Vec::new();
    // `RBSM_BENCH_MAX=100000` stops at 10⁵ elements (a partial run, as a filter makes one).
    let max = paired::max_elements();
    for n in SIZES.into_iter().filter(|&n| n <= max) {
        let cases: Vec<_> = FORMULATIONS
            .iter()
            .map(|(_, json)| {
                let model = Model::build(&scene(n, json)).expect("the model builds");
                let (mass, loads) = (Mass::new(&model), Loads::new(&model));
                (model, mass, loads)
            })
            .collect();
        for kind in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
            let evaluators: Vec<_> = cases.iter().map(|c| evaluator::build(&c.0, kind)).collect();
            for threads in [1, 2] {
                let pool = paired::pool(threads);
                let samples = RefCell::new([Vec::new(), Vec::new(), Vec::new()]);
                let name = format!("formulations/{n}/{}/{threads}thr", kind.name());
                c.bench_function(&name, |b| {
                    b.iter_custom(|iters| {
                        let mut total = Duration::ZERO;
                        for (k, ((model, mass, loads), ev)) in
                            cases.iter().zip(&evaluators).enumerate()
                        {
                            let e = pool.install(|| {
                                let mut cd = CentralDifference::new(
                                    model,
                                    ev.as_ref(),
                                    mass,
                                    loads,
                                    None,
                                    1e-9,
                                );
                                let t0 = Instant::now();
                                cd.step_only(iters);
                                t0.elapsed()
                            });
                            samples.borrow_mut()[k]
                                .push(e.as_secs_f64() / iters as f64 / n as f64 * 1e9);
                            total += e;
                        }
                        total
                    })
                });
                let s = samples.borrow().clone();
                if s[0].is_empty() {
                    continue; // filtered out on the command line
                }
                let ns = [0, 1, 2].map(|k| paired::quartiles(s[k].clone()));
                rows.push((
                    n,
                    kind.name(),
                    threads,
                    ns,
                    [paired::paired(&s, 1), paired::paired(&s, 2)],
                ));
            }
        }
    }
    for r in &rows {
        println!(
            "{} {} {}thr: rigid {:.1} ns, rigid-poisson {:.1} ns ({:.2}×), hybrid {:.1} ns ({:.2}×)",
            r.0, r.1, r.2, r.3[0][1], r.3[1][1], r.4[0], r.3[2][1], r.4[1]
        );
    }
    if rows.len() < SIZES.len() * 4 {
        println!("a partial run (RBSM_BENCH_MAX or a filter): benches/summary.md left as it was");
        return;
    }
    let mut section = String::from(
        "## What a formulation costs\n\nVoronoi panels (unit square, 2 Lloyd steps, left edge \
        on ground springs, a traction on the right), stepped by each evaluator: rigid, \
        `rigid-poisson` (the cells' pressures, then the rigid springs' fused sweep with the \
        correction's tractions: element-wise as a jump on each interface, assembled as `G`'s \
        entries pair by pair; the pressures gathered cell by cell before the sweep, but \
        element-wise from 50,000 elements on, where a wave that leads the sweep sums them \
        from the interfaces' records and only the cells on its blocks' borders are gathered) and hybrid with `p` = 10. ns per element-step, median of 10 samples with \
        the quartiles, all measured in one run of `cargo bench --bench formulations`; each \
        sample steps the three panels in turn, and the ratios to the rigid step are the medians \
        of the ratios sample by sample.\n\n\
        | elements | evaluator | threads | rigid ns | rigid-poisson ns | ratio | hybrid ns | \
        ratio |\n|---:|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for (n, kind, threads, [r, p, h], [rp, rh]) in &rows {
        let _ = writeln!(
            section,
            "| {n} | {kind} | {threads} | {:.1} ({:.1}–{:.1}) | {:.1} ({:.1}–{:.1}) | {rp:.2} | \
            {:.1} ({:.1}–{:.1}) | {rh:.2} |",
            r[1], r[0], r[2], p[1], p[0], p[2], h[1], h[0], h[2]
        );
    }
    section::write("formulations", &section);
    println!("{section}");
}

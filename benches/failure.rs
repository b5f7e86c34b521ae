//! What failing interfaces cost a step: a 10⁵-element Voronoi panel, rigid, stepped by both
//! evaluators with elastic interfaces and with a softening law (`materials.*.interface`), on 1
//! and 2 threads, as ns per element-step (the median of criterion's samples, with the quartiles),
//! measured in one run so that the ratios are the figures to read.
//!
//! `cargo bench --bench failure` measures and rewrites the section *Interfaces that fail* of
//! `benches/summary.md` (between its markers; `cargo bench --bench step` keeps it).
//!
//! The softening law is strong enough that the panel stays elastic under its load: the step
//! still does the state update at every Gauss point and steps through the net force, which is
//! what a scene with such a law pays before its interfaces yield (the plastic forces join once
//! a point has; this bench does not measure a panel that cracks).

#[path = "common/section.rs"]
mod section;

use criterion::Criterion;
use rbsm::force::{evaluator, failure};
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::model::loads::Loads;
use rbsm::model::mass::Mass;
use rbsm::model::Model;
use rbsm::step::integrator::CentralDifference;
use std::cell::RefCell;
use std::fmt::Write as _;
use std::time::{Duration, Instant};

const ELEMENTS: usize = 100_000;

fn scene(law: &str) -> Scene {
    let json = format!(
        r#"{{"name": "bench", "thickness": 1.0, "formulation": {{"kind": "rigid"}},
            "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400{law}}}}},
            "bodies": [{{"name": "b", "material": "m",
                "mesh": {{"kind": "voronoi", "origin": [0, 0], "size": [1, 1], "sites": {ELEMENTS}, "seed": 1, "lloyd": 2}},
                "supports": [{{"edge": "left", "kind": "ground-spring"}}],
                "loads": [{{"kind": "traction", "edge": "right", "value": [1e6, 1e5]}}]}}],
            "time": {{"dt": 1e-9, "steps": 1}}}}"#
    );
    Scene::from_json(&json).expect("the bench scene is valid")
}

const LAWS: [(&str, &str); 2] = [
    ("elastic", ""),
    (
        "softening",
        r#", "interface": {"kind": "softening", "tensile_strength": 1e9, "cohesion": 1e9,
            "friction_angle": 30, "fracture_energy": 100, "fracture_energy_shear": 1000}"#,
    ),
];

fn main() {
    let mut c = Criterion::default()
        .sample_size(10)
        .measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_secs(1))
        .configure_from_args();
    // (law, evaluator, threads) → [q1, median, q3] ns per element-step.
    let mut rows: Vec<(&str, &str, usize, [f64; 3])> = Vec::new();
    for (law, json) in LAWS {
        let model = Model::build(&scene(json)).expect("the bench model builds");
        let (mass, loads) = (Mass::new(&model), Loads::new(&model));
        for kind in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
            let ev = evaluator::build(&model, kind);
            let plastic = failure::build(&model, kind);
            assert_eq!(plastic.is_some(), law == "softening");
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("a thread pool");
                let samples = RefCell::new(Vec::new());
                let name = format!("failure/{law}/{}/{threads}thr", kind.name());
                c.bench_function(&name, |b| {
                    b.iter_custom(|iters| {
                        let e = pool.install(|| {
                            let mut cd = CentralDifference::new(
                                &model,
                                ev.as_ref(),
                                &mass,
                                &loads,
                                None,
                                1e-9,
                            );
                            if let Some(p) = &plastic {
                                cd = cd.with_failure(p.as_ref());
                            }
                            let t0 = Instant::now();
                            cd.step_only(iters);
                            t0.elapsed()
                        });
                        samples
                            .borrow_mut()
                            .push(e.as_secs_f64() / iters as f64 / ELEMENTS as f64 * 1e9);
                        e
                    })
                });
                let mut s = samples.borrow().clone();
                if s.is_empty() {
                    continue; // filtered out on the command line
                }
                s.sort_by(f64::total_cmp);
                let q = [1, 2, 3].map(|k| s[(k * s.len() / 4).min(s.len() - 1)]);
                rows.push((law, kind.name(), threads, q));
            }
        }
    }
    if rows.len() < 8 {
        println!("a filtered run: benches/summary.md left as it was");
        return;
    }
    let mut section = format!(
        "## Interfaces that fail\n\nA 10⁵-element Voronoi panel (rigid), elastic \
        interfaces against a softening law that stays elastic under the load (the failure work \
        an elastic state needs: the state update at every Gauss point, the step through the net \
        force; the plastic forces only once a point has yielded). ns per \
        element-step, median of {} samples with the quartiles, all measured in one run of \
        `cargo bench --bench failure`.\n\n| evaluator | threads | elastic ns | softening ns | \
        softening / elastic |\n|---|---:|---:|---:|---:|\n",
        10
    );
    for kind in ["assembled", "element-wise"] {
        for threads in [1, 2] {
            let get = |law: &str| {
                rows.iter()
                    .find(|r| r.0 == law && r.1 == kind && r.2 == threads)
                    .map(|r| r.3)
                    .expect("every case was measured")
            };
            let (e, s) = (get("elastic"), get("softening"));
            let _ = writeln!(
                section,
                "| {kind} | {threads} | {:.1} ({:.1}–{:.1}) | {:.1} ({:.1}–{:.1}) | {:.2} |",
                e[1],
                e[0],
                e[2],
                s[1],
                s[0],
                s[2],
                s[1] / e[1]
            );
        }
    }
    section::write("failure", &section);
    println!("{section}");
}

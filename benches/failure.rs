//! What failing interfaces cost a step: Voronoi panels of 10⁴, 10⁵ and 10⁶ elements, rigid,
//! rigid-poisson and hybrid, stepped by both evaluators on 1 and 2 threads with elastic interfaces, with a
//! softening law that stays elastic under the load, and with the same law on a panel that
//! cracks; as ns per element-step (the median of criterion's samples, with the quartiles).
//! Every sample steps the three panels of a mesh in turn, and the ratios to the elastic step
//! are taken sample by sample, their median reported: the figures to read.
//!
//! `cargo bench --bench failure` measures and rewrites the section *Interfaces that fail* of
//! `benches/summary.md` (between its markers; `cargo bench --bench step` keeps it);
//! `RBSM_BENCH_MAX=100000` stops at 10⁵ elements and leaves the summary as it was.
//!
//! The panel that stays elastic pays what a failing scene pays before it yields: the return
//! mapping of every Gauss point in the sweep. The panel that cracks starts stretched to twice
//! its cracking strain, so that every interface in tension yields in the first step and, with
//! a small fracture energy, breaks: then every step reads and writes the state of those points
//! and applies their plastic forces.

#[path = "common/paired.rs"]
mod paired;
#[path = "common/section.rs"]
mod section;

use criterion::Criterion;
use rbsm::force::{evaluator, failure};
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::model::law::{InterfaceLaw, Strength};
use rbsm::model::loads::Loads;
use rbsm::model::mass::Mass;
use rbsm::model::Model;
use rbsm::step::integrator::CentralDifference;
use std::cell::RefCell;
use std::fmt::Write as _;
use std::sync::Arc;
use std::time::{Duration, Instant};

const SIZES: [usize; 3] = [10_000, 100_000, 1_000_000];
/// Rigid, rigid-poisson, and hybrid with the penalty `p = 10` of `benches/step.rs`.
const FORMULATIONS: [&str; 3] = ["rigid", "rigid-poisson", "hybrid"];
const E: f64 = 3e10;
const F_T: f64 = 3e6;

fn scene(elements: usize, formulation: &str) -> Scene {
    let formulation = match formulation {
        "rigid" => r#"{"kind": "rigid"}"#,
        "rigid-poisson" => r#"{"kind": "rigid-poisson"}"#,
        _ => r#"{"kind": "hybrid", "penalty": 10}"#,
    };
    let json = format!(
        r#"{{"name": "bench", "thickness": 1.0, "formulation": {formulation},
            "materials": {{"m": {{"E": {E}, "nu": 0.2, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m",
                "mesh": {{"kind": "voronoi", "origin": [0, 0], "size": [1, 1], "sites": {elements}, "seed": 1, "lloyd": 2}},
                "supports": [{{"edge": "left", "kind": "ground-spring"}}],
                "loads": [{{"kind": "traction", "edge": "right", "value": [1e6, 1e5]}}]}}],
            "time": {{"dt": 1e-9, "steps": 1}}}}"#
    );
    Scene::from_json(&json).expect("the bench scene is valid")
}

/// A softening law (Mohr–Coulomb with cut-off, `φ` = 30°) of tensile strength `f_t`,
/// cohesion `2 f_t` and fracture energies `G_f`, `10 G_f`, given to the model through the
/// interface-law seam.
fn softening(f_t: f64, g_f: f64) -> Arc<dyn InterfaceLaw> {
    Arc::new(Strength {
        f_t,
        c: 2.0 * f_t,
        tan_phi: 30f64.to_radians().tan(),
        per_w_n: f_t / (2.0 * g_f),
        per_w_s: 2.0 * f_t / (2.0 * 10.0 * g_f),
    })
}

/// A case: its name, the interfaces' law (none: elastic), the stretch `ε` of the start
/// `u = ε x`.
type Case = (&'static str, Option<Arc<dyn InterfaceLaw>>, f64);

/// The cases measured on each mesh.
fn laws() -> [Case; 3] {
    [
        ("elastic", None, 0.0),
        ("stays elastic", Some(softening(1e9, 100.0)), 0.0),
        ("cracks", Some(softening(F_T, 0.1)), 2.0 * F_T / E),
    ]
}

fn main() {
    let mut c = Criterion::default()
        .sample_size(10)
        .measurement_time(Duration::from_secs(6))
        .warm_up_time(Duration::from_millis(500))
        .configure_from_args();
    // (elements, formulation, evaluator, threads) → per case of `laws()`, [q1, median, q3] ns
    // per element-step, and the median of the ratios to the elastic case, sample by sample.
    type Row = (
        usize,
        &'static str,
        &'static str,
        usize,
        [[f64; 3]; 3],
        [f64; 2],
    );
    let mut rows: Vec<Row> = Vec::new();
    let mut cracked = Vec::new();
    // `RBSM_BENCH_MAX=100000` stops at 10⁵ elements (a partial run, as a filter makes one).
    let max = paired::max_elements();
    for n in SIZES.into_iter().filter(|&n| n <= max) {
        for formulation in FORMULATIONS {
            let elastic = Model::build(&scene(n, formulation)).expect("the model builds");
            // Per case: its model, mass, loads, starting `U` and failing interfaces.
            let cases: Vec<_> = laws()
                .into_iter()
                .map(|(law, strength, stretch)| {
                    let mut model = elastic.clone();
                    if let Some(strength) = strength {
                        model.set_law(strength, |_| true);
                    }
                    let (mass, loads) = (Mass::new(&model), Loads::new(&model));
                    let nd = model.formulation.ndof();
                    let mut u0 = vec![0.0; model.n_dofs()];
                    for (e, el) in model.elements.iter().enumerate() {
                        u0[e * nd] = stretch * el.props.centroid.x;
                    }
                    let plastic = failure::build(&model);
                    assert_eq!(plastic.is_some(), law != "elastic");
                    (model, mass, loads, u0, plastic)
                })
                .collect();
            drop(elastic);
            for kind in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
                let evaluators: Vec<_> =
                    cases.iter().map(|c| evaluator::build(&c.0, kind)).collect();
                for threads in [1, 2] {
                    let pool = paired::pool(threads);
                    // The three cases in turn in every sample, so that their ratios are taken
                    // sample by sample (a shared machine drifts between samples).
                    let samples = RefCell::new([Vec::new(), Vec::new(), Vec::new()]);
                    let name = format!("failure/{n}/{formulation}/{}/{threads}thr", kind.name());
                    c.bench_function(&name, |b| {
                        b.iter_custom(|iters| {
                            let mut total = Duration::ZERO;
                            for (k, ((model, mass, loads, u0, plastic), ev)) in
                                cases.iter().zip(&evaluators).enumerate()
                            {
                                let (e, broken) = pool.install(|| {
                                    let mut cd = CentralDifference::from_state(
                                        model,
                                        ev.as_ref(),
                                        mass,
                                        loads,
                                        None,
                                        1e-9,
                                        u0.clone(),
                                        vec![0.0; u0.len()],
                                    );
                                    if let Some(p) = plastic {
                                        cd = cd.with_failure(p.as_ref());
                                    }
                                    let t0 = Instant::now();
                                    cd.step_only(iters);
                                    let e = t0.elapsed();
                                    let broken = plastic.as_ref().map_or(0, |p| {
                                        let state = cd.failure().expect("a failing model");
                                        p.report(state)
                                            .iter()
                                            .filter(|i| {
                                                i.status == failure::InterfaceStatus::Broken
                                            })
                                            .count()
                                    });
                                    (e, broken)
                                });
                                samples.borrow_mut()[k]
                                    .push(e.as_secs_f64() / iters as f64 / n as f64 * 1e9);
                                if k == 2 {
                                    cracked.push((n, formulation, broken));
                                }
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
                        formulation,
                        kind.name(),
                        threads,
                        ns,
                        [paired::paired(&s, 1), paired::paired(&s, 2)],
                    ));
                }
            }
        }
    }
    if rows.len() < SIZES.len() * FORMULATIONS.len() * 4 {
        println!("a partial run (RBSM_BENCH_MAX or a filter): benches/summary.md left as it was");
        return;
    }
    let broken = |n: usize, f: &str| {
        cracked
            .iter()
            .filter(|c| c.0 == n && c.1 == f)
            .map(|c| c.2)
            .min()
            .unwrap_or(0)
    };
    let mut section = String::from(
        "## Interfaces that fail\n\nVoronoi panels (unit square, left edge on ground springs, a \
        traction on the right; hybrid with `p` = 10), elastic interfaces against a softening law \
        (Mohr–Coulomb with cut-off, φ = 30°, `c` = 2 `f_t`, `G_f,II` = 10 `G_f`, given through \
        the interface-law seam): one strong enough that the panel stays elastic (what a failing \
        scene pays before it yields: the relative displacement at every Gauss point and the \
        law's quick test of its initial region, in the sweep), and one (`f_t` = 3 MPa, `G_f` = \
        0.1 J/m²) on a panel stretched at the start to twice its cracking strain, so that the \
        interfaces in tension yield in the first step and break (their state read and written, \
        their return mapping and plastic forces at every step). ns per element-step, median of \
        10 samples with the quartiles, all measured in one run of `cargo bench --bench \
        failure`; each sample steps the three panels in turn, and the ratios to the elastic \
        step of the same mesh are the medians of the ratios sample by sample (a shared machine \
        drifts between samples: a ratio of medians taken minutes apart moved by a third); \
        *broken* counts the interfaces broken at the end of the shortest sample. Rigid-poisson's \
        laws act on its correction's jump, which both evaluators' screens of a fresh interface \
        bound (the assembled blocks from the cells' `q` and a lever kept per block).\n\n\
        | elements | formulation | evaluator | threads | elastic ns | stays elastic ns | ratio | \
        cracks ns | ratio | broken interfaces |\n|---:|---|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for n in SIZES {
        for formulation in FORMULATIONS {
            for kind in ["assembled", "element-wise"] {
                for threads in [1, 2] {
                    let (_, _, _, _, [e, s, k], [rs, rk]) = rows
                        .iter()
                        .find(|r| (r.0, r.1, r.2, r.3) == (n, formulation, kind, threads))
                        .expect("every case was measured");
                    let _ = writeln!(
                        section,
                        "| {n} | {formulation} | {kind} | {threads} | {:.1} ({:.1}–{:.1}) | \
                        {:.1} ({:.1}–{:.1}) | {:.2} | {:.1} ({:.1}–{:.1}) | {:.2} | {} |",
                        e[1],
                        e[0],
                        e[2],
                        s[1],
                        s[0],
                        s[2],
                        rs,
                        k[1],
                        k[0],
                        k[2],
                        rk,
                        broken(n, formulation)
                    );
                }
            }
        }
    }
    section::write("failure", &section);
    println!("{section}");
}

//! Time per explicit step (evaluator plus the central-difference update) of both evaluators,
//! rigid and hybrid, on square grids and Voronoi meshes of 10³ … 10⁶ elements, on 1 and 2
//! threads, as ns per element-step; each figure beside its distance from its memory bound: the
//! bytes a step must move divided by the bandwidth of a triad kernel run on the same threads
//! just before and just after each case, so that the load from elsewhere on a shared machine,
//! which comes and goes within a run, is the same on both sides of the ratio. Also the
//! model build time of 10⁶ Voronoi elements, `ω_max` of 3 × 10⁶ DOFs and the bytes per element.
//! In the same run, the peer: the explicit loop a user of a sparse library writes (`f = K u`
//! by faer's CSR product on one thread, then `v += Δt M⁻¹ (P − f)`, `u += Δt v`) on the same
//! rigid models; what a user's `rbsm run` costs per step against the inner loop on the same
//! 10⁶-element model (checks, history rows, a probe and the final state included); and the
//! setup of that run with a given `dt` and with a `dt_factor`.
//!
//! `cargo bench --bench step` measures everything and rewrites `benches/summary.md`.
//! `RBSM_BENCH_MAX=100000 cargo bench --bench step` stops at 10⁵ elements, and a criterion filter
//! (`cargo bench --bench step -- grid/rigid`) runs only the matching cases: a quick look, after
//! which the summary is left as it was.

#[path = "common/section.rs"]
mod section;

use criterion::{Criterion, SamplingMode};
use rbsm::analysis::run::{self, RunParams, Silent};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::model::loads::Loads;
use rbsm::model::mass::Mass;
use rbsm::model::Model;
use rbsm::step::integrator::{CentralDifference, CHECK_EVERY};
use rbsm::{analysis::limit, force::evaluator};
use std::cell::RefCell;
use std::fmt::Write as _;
use std::time::{Duration, Instant};

const SIZES: [usize; 4] = [1_000, 10_000, 100_000, 1_000_000];
const THREADS: [usize; 2] = [1, 2];

fn mesh_json(kind: &str, n: usize) -> String {
    match kind {
        "grid" => {
            let k = (n as f64).sqrt().round() as usize;
            format!(r#"{{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [{k}, {k}]}}"#)
        }
        _ => format!(
            r#"{{"kind": "voronoi", "origin": [0, 0], "size": [1, 1], "sites": {n}, "seed": 1, "lloyd": 2}}"#
        ),
    }
}

fn scene(mesh: &str, formulation: &str) -> Scene {
    let json = format!(
        r#"{{"name": "bench", "thickness": 1.0, "formulation": {formulation},
            "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {mesh},
                         "supports": [{{"edge": "left", "kind": "ground-spring"}}],
                         "loads": [{{"kind": "traction", "edge": "right", "value": [1e6, 1e5]}}]}}],
            "time": {{"dt": 1e-9, "steps": 1}}}}"#
    );
    Scene::from_json(&json).expect("the bench scene is valid")
}

const FORMULATIONS: [(&str, &str); 2] = [
    ("rigid", r#"{"kind": "rigid"}"#),
    ("hybrid", r#"{"kind": "hybrid", "penalty": 10}"#),
];

/// First quartile, median and third quartile (NaN of no values: a case filtered out on the
/// command line).
fn quartiles(mut x: Vec<f64>) -> [f64; 3] {
    x.sort_by(f64::total_cmp);
    [1, 2, 3].map(|q| x.get(q * x.len() / 4).copied().unwrap_or(f64::NAN))
}

/// From this many elements a case is sampled longer ([`sampling`]).
const LARGE: usize = 500_000;

/// Samples per case, and the time criterion spreads them over: on this shared machine a burst
/// of load from elsewhere can last a second or two, so the 10⁶-element cases, at 10–150 ms per
/// step, take 30 samples of equal length over 8 s (or 30 steps, when longer) and not 10 over 2.
fn sampling(elements: usize) -> (usize, Duration) {
    if elements >= LARGE {
        (30, Duration::from_secs(8))
    } else {
        (10, Duration::from_secs(2))
    }
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool")
}

/// The triad `a = b + s c` over arrays far larger than the caches (3 × 128 MiB), which moves
/// three arrays of 8-byte values per pass, as STREAM counts them.
struct Triad {
    a: Vec<f64>,
    b: Vec<f64>,
    c: Vec<f64>,
}

impl Triad {
    fn new() -> Self {
        let n = 1 << 24;
        Triad {
            a: vec![0.0; n],
            b: vec![1.0; n],
            c: vec![2.0; n],
        }
    }

    /// `case` (its warm-up and samples) between three passes on `pool` just before and three
    /// just after it, and the bandwidth of the median pass (bytes/s): the bandwidth of the
    /// seconds in which the case ran.
    fn around(&mut self, pool: &rayon::ThreadPool, case: impl FnOnce()) -> f64 {
        let mut t: Vec<f64> = (0..3).map(|_| pool.install(|| self.pass())).collect();
        case();
        t.extend((0..3).map(|_| pool.install(|| self.pass())));
        (3 * 8 * self.a.len()) as f64 / quartiles(t)[1]
    }

    /// The seconds of one pass, on the threads of the calling pool.
    fn pass(&mut self) -> f64 {
        use rayon::prelude::*;
        let t0 = Instant::now();
        self.a
            .par_chunks_mut(1 << 16)
            .zip(self.b.par_chunks(1 << 16))
            .zip(self.c.par_chunks(1 << 16))
            .for_each(|((a, b), c)| {
                for ((a, b), c) in a.iter_mut().zip(b).zip(c) {
                    *a = b + 3.0 * c;
                }
            });
        let t = t0.elapsed().as_secs_f64();
        std::hint::black_box(&self.a);
        t
    }
}

/// Times one iteration of a case's samples: `iters` calls of `step` in `pool`, recorded in
/// `samples` as seconds per call.
fn timed(
    pool: &rayon::ThreadPool,
    samples: &RefCell<Vec<f64>>,
    iters: u64,
    step: impl FnOnce(u64) + Send,
) -> Duration {
    let e = pool.install(|| {
        let t0 = Instant::now();
        step(iters);
        t0.elapsed()
    });
    samples.borrow_mut().push(e.as_secs_f64() / iters as f64);
    e
}

/// What the last `keep` samples of a case say (its warm-up comes first), for `ne` elements and
/// `bytes` per element-step, with the `bandwidth` of the triad passes around it.
struct Measured {
    /// First quartile, median and third quartile of the time (ns per element-step).
    ns: [f64; 3],
    bandwidth: f64,
    /// The same quartiles over the memory bound, `bytes / bandwidth`.
    ratio: [f64; 3],
}

impl Measured {
    fn of(samples: &RefCell<Vec<f64>>, keep: usize, ne: usize, bytes: f64, bandwidth: f64) -> Self {
        let s = samples.borrow();
        let last = &s[s.len().saturating_sub(keep)..];
        let ns = quartiles(last.iter().map(|t| t / ne as f64 * 1e9).collect());
        let bound_ns = bytes / bandwidth * 1e9;
        Measured {
            ns,
            bandwidth,
            ratio: ns.map(|t| t / bound_ns),
        }
    }
}

struct Row {
    mesh: &'static str,
    formulation: &'static str,
    evaluator: &'static str,
    elements: usize,
    threads: usize,
    samples: usize,
    bytes: f64,
    m: Measured,
}

/// The peer on one model, on one thread.
struct Peer {
    mesh: &'static str,
    elements: usize,
    /// What one of its steps must move per element: `K`'s values and column indices (8 bytes
    /// each) and row starts, `u` read, `f` written, then `f`, `P`, `M⁻¹` read and `v`, `u`
    /// read and written.
    bytes: f64,
    m: Measured,
}

/// The explicit loop of a sparse-library user on `model`: `K` in compressed rows (faer),
/// `f = K u` on one thread, then one fused pass `v += Δt M⁻¹ (P − f)`, `u += Δt v`.
fn peer(
    c: &mut Criterion,
    triad: &mut Triad,
    mesh: &'static str,
    model: &Model,
    mass: &Mass,
) -> Peer {
    use faer::sparse::{SparseColMat, Triplet};
    let n = model.n_dofs();
    let triplets: Vec<Triplet<usize, usize, f64>> = evaluator::stiffness_triplets(model)
        .into_iter()
        .map(|(r, c, v)| Triplet::new(r, c, v))
        .collect();
    let k = SparseColMat::try_new_from_triplets(n, n, &triplets).expect("K assembles");
    drop(triplets);
    let ne = model.elements.len();
    let bytes = (16 * k.compute_nnz() + 8 * (n + 1) + 8 * 9 * n) as f64 / ne as f64;
    let minv: Vec<f64> = mass.diagonal().iter().map(|m| 1.0 / m).collect();
    let mut p = vec![0.0; n];
    Loads::new(model).subtract(0.0, &mut p);
    p.iter_mut().for_each(|x| *x = -*x);
    let (mut u, mut v, mut f) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let dt = 1e-9;
    let (sample_size, time) = sampling(ne);
    let samples = RefCell::new(Vec::new());
    let mut group = c.benchmark_group("peer");
    group.sample_size(sample_size).measurement_time(time);
    if ne >= LARGE {
        group.sampling_mode(SamplingMode::Flat);
    }
    let one = pool(1);
    let bandwidth = triad.around(&one, || {
        group.bench_function(format!("{mesh}/rigid/faer-csr/1thr/{ne}"), |b| {
            b.iter_custom(|iters| {
                timed(&one, &samples, iters, |iters| {
                    for _ in 0..iters {
                        // K is symmetric: its columns are its rows, and the transposed view is CSR.
                        faer::sparse::linalg::matmul::sparse_dense_matmul(
                            faer::ColMut::from_slice_mut(&mut f).as_mat_mut(),
                            faer::Accum::Replace,
                            k.as_ref().transpose(),
                            faer::ColRef::from_slice(&u).as_mat(),
                            1.0,
                            faer::Par::Seq,
                        );
                        for i in 0..n {
                            v[i] += dt * minv[i] * (p[i] - f[i]);
                            u[i] += dt * v[i];
                        }
                    }
                })
            })
        });
    });
    group.finish();
    std::hint::black_box(&u);
    Peer {
        mesh,
        elements: ne,
        bytes,
        m: Measured::of(&samples, sample_size, ne, bytes, bandwidth),
    }
}

/// What a user's run costs on the 10⁶-element rigid grid (element-wise, all threads).
struct RunPath {
    /// `run::run`'s stepping loop (checks, history rows, a probe) per step over the inner
    /// loop's on the same setup, each round; then the whole `run::run` (the final state
    /// written too) over the inner loop.
    loop_ratio: Vec<f64>,
    whole_ratio: Vec<f64>,
    inner_ns: Vec<f64>,
    steps: u64,
    /// `Setup::new` with a given `dt` and with a `dt_factor` (s), each round.
    setup_dt: Vec<f64>,
    setup_factor: Vec<f64>,
}

/// The 10⁶-element grid of the step bench as a user's scene: element-wise, `time` as given,
/// a probe, history rows every 100 steps (the default).
fn user_scene(time: &str) -> Scene {
    let json = format!(
        r#"{{"name": "user", "thickness": 1.0, "formulation": {{"kind": "rigid"}},
            "evaluator": "element-wise",
            "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {},
                         "supports": [{{"edge": "left", "kind": "ground-spring"}}],
                         "loads": [{{"kind": "traction", "edge": "right", "value": [1e6, 1e5]}}]}}],
            "time": {time},
            "output": {{"probes": [{{"name": "corner_u", "element": 999999, "dof": "u"}}]}}}}"#,
        mesh_json("grid", 1_000_000)
    );
    Scene::from_json(&json).expect("the user scene is valid")
}

/// Rounds of the run path and of the setup, interleaved so that the machine's load falls on
/// both alike.
fn run_path() -> RunPath {
    const ROUNDS: usize = 3;
    const STEPS: u64 = 300;
    let out = std::env::temp_dir().join(format!("rbsm-bench-run-{}", std::process::id()));
    let given = user_scene(&format!(r#"{{"dt": 1e-9, "steps": {STEPS}}}"#));
    let factor = user_scene(&format!(r#"{{"dt_factor": 0.5, "steps": {STEPS}}}"#));
    let mut r = RunPath {
        loop_ratio: Vec::new(),
        whole_ratio: Vec::new(),
        inner_ns: Vec::new(),
        steps: STEPS,
        setup_dt: Vec::new(),
        setup_factor: Vec::new(),
    };
    for _ in 0..ROUNDS {
        let setup = Setup::new(&given, &Overrides::default()).expect("sets up");
        r.setup_dt.push(setup.seconds);
        let per_step = 1e9 / (STEPS as f64 * setup.model.elements.len() as f64);
        let mut cd = setup.integrator(setup.dt);
        let t0 = Instant::now();
        cd.step_only(STEPS);
        let inner = t0.elapsed().as_secs_f64() * per_step;
        drop(cd);
        let params = RunParams {
            resume: false,
            interrupt: None,
            keep_history: false,
        };
        let t0 = Instant::now();
        let summary = run::run(&setup, &params, &out, &mut Silent).expect("the run runs");
        let whole = t0.elapsed().as_secs_f64() * per_step;
        r.inner_ns.push(inner);
        r.loop_ratio.push(summary.step_time_s * per_step / inner);
        r.whole_ratio.push(whole / inner);
        drop(setup);
        let setup = Setup::new(&factor, &Overrides::default()).expect("sets up");
        r.setup_factor.push(setup.seconds);
    }
    let _ = std::fs::remove_dir_all(&out);
    r
}

/// Median and range of a few rounds.
fn median_range(x: &[f64]) -> (f64, f64, f64) {
    let mut s = x.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    (0.5 * (s[(n - 1) / 2] + s[n / 2]), s[0], s[n - 1])
}

fn main() {
    let max: usize = std::env::var("RBSM_BENCH_MAX")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .map_or(usize::MAX, |x| x as usize);
    let mut c = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(2))
        .configure_from_args();
    // First, in a fresh process: what a ready-to-step 10⁶-element model occupies.
    let memory = if max >= 1_000_000 {
        Some(memory())
    } else {
        None
    };
    let mut triad = Triad::new();
    let mut bandwidths = Vec::new();
    let mut rows = Vec::new();
    let mut peers = Vec::new();
    let mut builds = Vec::new();
    for mesh in ["grid", "voronoi"] {
        for n in SIZES.into_iter().filter(|&n| n <= max) {
            let first_row = rows.len();
            for (fname, fjson) in FORMULATIONS {
                let t0 = Instant::now();
                let model = Model::build(&scene(&mesh_json(mesh, n), fjson))
                    .expect("the bench model builds");
                builds.push((
                    mesh,
                    fname,
                    model.elements.len(),
                    t0.elapsed().as_secs_f64(),
                ));
                let (mass, loads) = (Mass::new(&model), Loads::new(&model));
                if fname == "rigid" {
                    peers.push(peer(&mut c, &mut triad, mesh, &model, &mass));
                }
                let nd = model.formulation.ndof();
                let inv_bytes = if mass.is_diagonal() {
                    8 * nd
                } else {
                    8 * nd * nd
                };
                for kind in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
                    let ev = evaluator::build(&model, kind);
                    let ne = model.elements.len();
                    // Both evaluators step fused into one sweep: the evaluator's data and M⁻¹
                    // read, U and v each read and written once; the pending forces stay in the
                    // sweep's rings, and this scene (no gravity, no contact) reads −P only at
                    // its loaded elements. (Evaluated first and updated after: U read and f
                    // written, then f, M⁻¹ read and v, U updated, 7 vectors.)
                    let vectors = if ev.fused().is_some() { 4 } else { 7 };
                    let bytes =
                        ev.bytes() as f64 / ne as f64 + (8 * nd * vectors + inv_bytes) as f64;
                    let mut integrator =
                        CentralDifference::new(&model, ev.as_ref(), &mass, &loads, None, 1e-9);
                    let (sample_size, time) = sampling(ne);
                    let mut group = c.benchmark_group("step");
                    group.sample_size(sample_size).measurement_time(time);
                    if ne >= LARGE {
                        // The same steps in every sample: 30 need not take the 465 of a linear
                        // ramp.
                        group.sampling_mode(SamplingMode::Flat);
                    }
                    // A grouped step moves `U` and `v` into their groups at the first step of
                    // a stretch and back at its end: a run does it once per check, so a sample
                    // is at least a check's stretch (`CHECK_EVERY` steps), not the few steps
                    // the time allows the others.
                    let grouped = ne >= LARGE && ev.fused().and_then(|f| f.grouped()).is_some();
                    for threads in THREADS {
                        let samples = RefCell::new(Vec::new());
                        let pool = pool(threads);
                        if grouped {
                            let t0 = Instant::now();
                            pool.install(|| integrator.step_only(10));
                            let step = t0.elapsed() / 10;
                            let stretch = step * (sample_size as u32) * (CHECK_EVERY as u32 + 10);
                            group.measurement_time(time.max(stretch));
                        }
                        let bandwidth = triad.around(&pool, || {
                            group.bench_function(
                                format!("{mesh}/{fname}/{}/{threads}thr/{ne}", kind.name()),
                                |b| {
                                    b.iter_custom(|iters| {
                                        timed(&pool, &samples, iters, |iters| {
                                            integrator.step_only(iters)
                                        })
                                    })
                                },
                            );
                        });
                        rows.push(Row {
                            mesh,
                            formulation: fname,
                            evaluator: kind.name(),
                            elements: ne,
                            threads,
                            samples: sample_size,
                            bytes,
                            m: Measured::of(&samples, sample_size, ne, bytes, bandwidth),
                        });
                    }
                    group.finish();
                }
            }
            let beside = |t: usize| {
                let of_t = rows[first_row..].iter().filter(|r| r.threads == t);
                quartiles(of_t.map(|r| r.m.bandwidth).collect())[1]
            };
            bandwidths.push((mesh, n, THREADS.map(beside)));
        }
    }
    c.final_summary();
    // `cargo test --benches` runs each case once, in criterion's test mode, without `--bench`.
    let measured = std::env::args().any(|a| a == "--bench");
    let unmeasured = (rows.iter().map(|r| &r.m))
        .chain(peers.iter().map(|p| &p.m))
        .any(|m| m.ns[1].is_nan());
    if !measured || max < 1_000_000 || unmeasured {
        eprintln!(
            "a partial run (RBSM_BENCH_MAX, a filter or a test run): benches/summary.md is left \
            as it was"
        );
        return;
    }
    let Some((rss_per_element, working_set)) = memory else {
        return;
    };
    let extras = extras(rss_per_element, working_set);
    let path = run_path();
    let mut summary = render(&bandwidths, &rows, &builds, &extras);
    summary.push_str(&render_user(&rows, &peers, &path));
    // The sections that `cargo bench --bench failure` and `--bench wall` write stay.
    let summary = section::keep_owned(summary);
    let path = section::path();
    std::fs::write(&path, summary).expect("benches/summary.md is writable");
    eprintln!("wrote {}", path.display());
}

/// Figures measured once (they take seconds each): memory per element of a ready 10⁶ rigid
/// grid, `ω_max` of 3 × 10⁶ DOFs, and the cost of a declared contact with nothing touching.
struct Extras {
    rss_per_element: f64,
    working_set: f64,
    omega_max_s: f64,
    dofs: usize,
    contact_ns: [f64; 2],
}

fn rss_bytes() -> f64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    statm
        .split_whitespace()
        .nth(1)
        .and_then(|p| p.parse::<f64>().ok())
        .unwrap_or(f64::NAN)
        * 4096.0
}

/// The growth of the resident memory from nothing to a 10⁶-element rigid grid ready to step
/// with the element-wise evaluator, and the working set of its steps, both per element.
fn memory() -> (f64, f64) {
    let before = rss_bytes();
    let model = Model::build(&scene(&mesh_json("grid", 1_000_000), FORMULATIONS[0].1))
        .expect("the bench model builds");
    let (mass, loads) = (Mass::new(&model), Loads::new(&model));
    let ev = evaluator::build(&model, EvaluatorKind::ElementWise);
    let integrator = CentralDifference::new(&model, ev.as_ref(), &mass, &loads, None, 1e-9);
    let ne = model.elements.len() as f64;
    let rss_per_element = (rss_bytes() - before) / ne;
    drop(integrator);
    // u, v, force, scratch and the guard's last good u and v; M⁻¹ (lumped: 8 B per DOF); and
    // u, v and M⁻¹ in groups of four elements where the step goes in lanes.
    let groups = if ev.fused().and_then(|f| f.grouped()).is_some() {
        3
    } else {
        0
    };
    (
        rss_per_element,
        ev.bytes() as f64 / ne + (6 + 1 + groups) as f64 * 8.0 * 3.0,
    )
}

fn extras(rss_per_element: f64, working_set: f64) -> Extras {
    let model = Model::build(&scene(&mesh_json("grid", 1_000_000), FORMULATIONS[0].1))
        .expect("the bench model builds");
    let mass = Mass::new(&model);
    let ev = evaluator::build(&model, EvaluatorKind::ElementWise);
    let t0 = Instant::now();
    std::hint::black_box(limit::omega_max(&model, ev.as_ref(), &mass, limit::EXACT));
    let omega_max_s = t0.elapsed().as_secs_f64();
    let dofs = model.n_dofs();
    drop((ev, model));
    // A 10⁵-element rigid grid with and without a declared contact (a ground far below it).
    let mut contact_ns = [0.0; 2];
    for (k, extra) in ["", r#", "contact": {"model": "edge-to-edge"}, "ground": [{"from": [-1, -10], "to": [2, -10]}]"#].iter().enumerate() {
        let json = format!(
            r#"{{"name": "c", "thickness": 1.0, "formulation": {{"kind": "rigid"}}, "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
                "bodies": [{{"name": "b", "material": "m", "mesh": {}}}], "time": {{"dt": 1e-9, "steps": 1}}{extra}}}"#,
            mesh_json("grid", 100_000)
        );
        let model = Model::build(&Scene::from_json(&json).expect("valid")).expect("builds");
        let (mass, loads) = (Mass::new(&model), Loads::new(&model));
        let ev = evaluator::build(&model, EvaluatorKind::ElementWise);
        let mut integrator = CentralDifference::new(&model, ev.as_ref(), &mass, &loads, None, 1e-9);
        let mut times: Vec<f64> = (0..7)
            .map(|_| {
                let t0 = Instant::now();
                integrator.step_only(20);
                t0.elapsed().as_secs_f64() / 20.0 / model.elements.len() as f64 * 1e9
            })
            .collect();
        times.sort_by(f64::total_cmp);
        contact_ns[k] = times[3];
    }
    Extras {
        rss_per_element,
        working_set,
        omega_max_s,
        dofs,
        contact_ns,
    }
}

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let model = cpu
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .unwrap_or("unknown")
        .trim()
        .to_string();
    let mem = std::fs::read_to_string("/proc/meminfo").unwrap_or_default();
    let total = mem
        .lines()
        .next()
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|k| k.parse::<f64>().ok())
        .unwrap_or(0.0)
        / 1048576.0;
    format!(
        "{model}, {} cores, {total:.1} GiB; rustc release profile",
        std::thread::available_parallelism().map_or(0, |n| n.get())
    )
}

fn render(
    bandwidths: &[(&str, usize, [f64; 2])],
    rows: &[Row],
    builds: &[(&str, &str, usize, f64)],
    x: &Extras,
) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Step benchmark summary\n\nRegenerate with `cargo bench --bench step` \
        (about 10 minutes). Machine: {}.\n",
        machine()
    );
    let range = |t: usize| {
        let gb: Vec<f64> = bandwidths.iter().map(|b| b.2[t] / 1e9).collect();
        let (med, lo, hi) = median_range(&gb);
        format!("{} ({}–{})", fmt(med, 1), fmt(lo, 1), fmt(hi, 1))
    };
    let _ = writeln!(
        s,
        "Triad bandwidth `a = b + s c` (3 × 8 bytes per entry, over 3 × 128 MiB), the median of \
        three passes just before and three just after each case (its warm-up and samples), on \
        the case's threads: a step's memory bound comes from the bandwidth of the seconds in \
        which it ran, for the load from elsewhere on a shared machine comes and goes within a \
        run. The median of the bandwidths around each mesh and size's cases: overall median {} \
        GB/s on 1 thread, {} GB/s on 2, the lowest and highest of the {} in brackets.\n",
        range(0),
        range(1),
        bandwidths.len()
    );
    let _ = writeln!(
        s,
        "| mesh | elements asked | triad, 1 thr GB/s | 2 thr GB/s |\n|---|---:|---:|---:|"
    );
    for (mesh, n, b) in bandwidths {
        let _ = writeln!(
            s,
            "| {mesh} | {n} | {} | {} |",
            fmt(b[0] / 1e9, 1),
            fmt(b[1] / 1e9, 1)
        );
    }
    s.push('\n');
    let _ = writeln!(
        s,
        "Each time is the median of the criterion samples ({}), in ns per \
        element-step: one step of the central-difference",
        sampling_text()
    );
    let _ = writeln!(
        s,
        "loop between its checks. *Bytes* is what one step must move per element; both \
        evaluators advance each element as soon as its force is complete, in one sweep:"
    );
    let _ = writeln!(
        s,
        "the evaluator's data (assembled: the upper triangles of `K`'s diagonal blocks, its \
        upper blocks with their element pairs, 80 bytes a pair rigid; element-wise: its interfaces, of 12 bytes on a grid, \
        whose few records they share and of whose rows' runs it keeps the first element's, of 72 rigid and 80 hybrid on a Voronoi mesh; both with \
        their rings of pending forces) and `M⁻¹` read, `U` and `v` read and"
    );
    let _ = writeln!(
        s,
        "written (on a grid of rows a multiple of four elements long, in groups of four elements, which the timed steps \
        move into and back); the bench scene has no gravity and no contact, so `−P` is read only at its loaded elements. *Limit* is bytes /"
    );
    let _ = writeln!(
        s,
        "the bandwidth of the triad passes around its case, and *× limit* the time over its limit: how far the \
        step is from that memory bound.\n"
    );
    let _ = writeln!(
        s,
        "| mesh | formulation | evaluator | elements | bytes/elt | 1 thr ns | × \
        limit | 2 thr ns | × limit |\n|---|---|---|---:|---:|---:|---:|---:|---:|"
    );
    for pair in rows.chunks(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.0} | {} | {} | {} | {} |",
            a.mesh,
            a.formulation,
            a.evaluator,
            a.elements,
            a.bytes,
            fmt(a.m.ns[1], 1),
            fmt(a.m.ratio[1], 2),
            fmt(b.m.ns[1], 1),
            fmt(b.m.ratio[1], 2)
        );
    }
    let find = |ev: &str, thr: usize| {
        rows.iter().find(|r| {
            r.mesh == "grid"
                && r.formulation == "rigid"
                && r.evaluator == ev
                && r.elements == 1_000_000
                && r.threads == thr
        })
    };
    let voronoi_build = builds
        .iter()
        .filter(|b| b.0 == "voronoi" && b.1 == "rigid")
        .map(|b| (b.2, b.3))
        .next_back()
        .unwrap_or((0, f64::NAN));
    let _ = writeln!(s, "\n## Targets, 10⁶ rigid elements on a square grid\n");
    let _ = writeln!(
        s,
        "A step time is the median of its samples, and beside it the middle half \
        of them (first to third quartile).\n"
    );
    let _ = writeln!(s, "| target | measured | met |\n|---|---|---|");
    let mut target = |what: &str, measured: f64, limit: f64, unit: &str, spread: &str| {
        let met = if measured <= limit { "yes" } else { "**no**" };
        let _ = writeln!(
            s,
            "| {what} ≤ {limit} {unit} | {} {unit}{spread} | {met} |",
            fmt(measured, 1)
        );
    };
    for (ev, thr, limit) in [
        ("element-wise", 1, 15.0),
        ("element-wise", 2, 10.0),
        ("assembled", 1, 30.0),
        ("assembled", 2, 18.0),
    ] {
        let what = format!("{ev}, {thr} thread{}", if thr > 1 { "s" } else { "" });
        match find(ev, thr) {
            Some(r) => target(
                &what,
                r.m.ns[1],
                limit,
                "ns",
                &format!(
                    " ({}–{}, {} samples)",
                    fmt(r.m.ns[0], 1),
                    fmt(r.m.ns[2], 1),
                    r.samples
                ),
            ),
            None => target(&what, f64::NAN, limit, "ns", ""),
        }
    }
    target(
        "element-wise working set per element",
        x.working_set,
        500.0,
        "B",
        "",
    );
    target(
        &format!("Voronoi model build, {} elements", voronoi_build.0),
        voronoi_build.1,
        10.0,
        "s",
        "",
    );
    target(
        &format!("ω_max of {} DOFs (Lanczos, element-wise)", x.dofs),
        x.omega_max_s,
        60.0,
        "s",
        "",
    );
    let _ = writeln!(
        s,
        "\nThe working set is the evaluator's data, `M⁻¹` and the integrator's \
        six vectors (`U`, `v`, `f`, the averaged"
    );
    let _ = writeln!(
        s,
        "velocity and the guard's last good `U`, `v`), and `U`, `v`, `M⁻¹` once more in groups of four elements, which the \
        grid's steps between two checks go on. The whole process grows by {} bytes per element from nothing to",
        fmt(x.rss_per_element, 0)
    );
    let _ = writeln!(s, "ready to step (resident memory, measured first in the bench process; this adds the model itself: meshes, elements,
interfaces, and what the allocator keeps of the build).\n");
    let _ = writeln!(
        s,
        "No allocation inside a step: `tests/allocation.rs` counts them. Contact: \
        a 10⁵-element rigid grid steps in {} ns per",
        fmt(x.contact_ns[0], 1)
    );
    let _ = writeln!(
        s,
        "element without a `contact` section, which builds no contact engine; \
        declaring contact with a ground far away costs {} ns",
        fmt(x.contact_ns[1], 1)
    );
    let _ = writeln!(
        s,
        "(median of 7 × 20 steps, 2 threads).\n\nModel build times (s):\n\n| mesh \
        | formulation | elements | build s |\n|---|---|---:|---:|"
    );
    for b in builds {
        let _ = writeln!(s, "| {} | {} | {} | {} |", b.0, b.1, b.2, fmt(b.3, 2));
    }
    s
}

/// How many samples [`sampling`] takes, in words.
fn sampling_text() -> String {
    let ((few, short), (many, long)) = (sampling(1), sampling(usize::MAX));
    format!(
        "{few} over {} s; from {LARGE} elements, {many} over {} s, or longer for the \
        grouped steps of a rigid grid, whose samples are each at least the {CHECK_EVERY} steps \
        between two checks of a run",
        short.as_secs(),
        long.as_secs()
    )
}

fn fmt(x: f64, digits: usize) -> String {
    format!("{x:.digits$}")
}

/// The sections of `benches/summary.md` on what a user sees: the peer, the goals on 10⁶
/// elements, the run path and the setup.
fn render_user(rows: &[Row], peers: &[Peer], r: &RunPath) -> String {
    let mut s = String::new();
    let row = |mesh: &str, formulation: &str, ev: &str, n: usize, thr: usize| {
        rows.iter().find(|r| {
            r.mesh == mesh
                && r.formulation == formulation
                && r.evaluator == ev
                && r.elements == n
                && r.threads == thr
        })
    };
    let _ = writeln!(
        s,
        "\n## Against the peer, in the same run\n\nThe peer is the explicit loop a user of a \
        sparse library writes on the same rigid model: `K` in compressed rows (faer 0.24), \
        `f = K u` on one thread, then one fused pass `v += Δt M⁻¹ (P − f)`, `u += Δt v`. It is \
        measured like the steps above (median of its samples, quartiles in brackets). *× peer* \
        is the peer's time over ours (above 1: we are faster), for our step on 1 and on 2 \
        threads against the peer on one. *Bytes* is what a peer's step must move per element \
        (`K`'s values and column indices, 8 bytes each, its row starts, `u` read, `f` written, \
        then `f`, `P`, `M⁻¹` read and `v`, `u` read and written), and *× limit* its time over \
        bytes / the bandwidth of the one-thread triad passes around it: the peer's own distance from its memory \
        bound. The ratio of the two bytes columns bounds how much faster than the peer a \
        step at its own memory bound can be.\n"
    );
    let _ = writeln!(
        s,
        "| mesh | elements | peer bytes/elt | peer ns | × limit | element-wise × peer, 1 thr | \
        2 thr | assembled × peer, 1 thr | 2 thr |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    let times = |p: &Peer, ev: &str, thr: usize| {
        row(p.mesh, "rigid", ev, p.elements, thr)
            .map_or(String::from("–"), |r| fmt(p.m.ns[1] / r.m.ns[1], 2))
    };
    for p in peers {
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} | {} ({}–{}) | {} | {} | {} | {} | {} |",
            p.mesh,
            p.elements,
            p.bytes,
            fmt(p.m.ns[1], 1),
            fmt(p.m.ns[0], 1),
            fmt(p.m.ns[2], 1),
            fmt(p.m.ratio[1], 2),
            times(p, "element-wise", 1),
            times(p, "element-wise", 2),
            times(p, "assembled", 1),
            times(p, "assembled", 2)
        );
    }
    let (ratio_med, ratio_lo, ratio_hi) = median_range(&r.loop_ratio);
    let (whole_med, whole_lo, whole_hi) = median_range(&r.whole_ratio);
    let (inner_med, _, _) = median_range(&r.inner_ns);
    let (dt_med, dt_lo, dt_hi) = median_range(&r.setup_dt);
    let (f_med, f_lo, f_hi) = median_range(&r.setup_factor);
    // A 10⁴-step run of the same model at the inner loop's speed.
    let run_s = 1e4 * inner_med * 1e-9 * 1e6;
    let _ = writeln!(
        s,
        "\n## Goals, 10⁶ elements\n\n| goal | measured | met |\n|---|---|---|"
    );
    let mut goal = |what: String, measured: f64, text: String, ok: bool| {
        let met = if measured.is_nan() {
            "–"
        } else if ok {
            "yes"
        } else {
            "**no**"
        };
        let _ = writeln!(s, "| {what} | {text} | {met} |");
    };
    let grid_peer = peers
        .iter()
        .find(|p| p.mesh == "grid" && p.elements == 1_000_000);
    for (ev, thr, want) in [
        ("element-wise", 1, 4.0),
        ("element-wise", 2, 7.0),
        ("assembled", 1, 2.0),
        ("assembled", 2, 3.5),
    ] {
        let x = match (grid_peer, row("grid", "rigid", ev, 1_000_000, thr)) {
            (Some(p), Some(r)) => p.m.ns[1] / r.m.ns[1],
            _ => f64::NAN,
        };
        goal(
            format!("grid, rigid, {ev}, {thr} thr: ≥ {want}× faster than the peer"),
            x,
            format!("{}×", fmt(x, 2)),
            x >= want,
        );
    }
    for (mesh, formulation, want) in [
        ("grid", "rigid", 1.3),
        ("grid", "hybrid", 1.6),
        ("voronoi", "rigid", 1.5),
    ] {
        for thr in THREADS {
            let r = row(mesh, formulation, "element-wise", 1_000_000, thr);
            let [q1, x, q3] = r.map_or([f64::NAN; 3], |r| r.m.ratio);
            // Against the best bandwidth of the run's triad passes on as many threads.
            let best = rows
                .iter()
                .filter(|r| r.threads == thr)
                .fold(f64::NAN, |b, r| b.max(r.m.bandwidth));
            let strict = r.map_or(f64::NAN, |r| r.m.ns[1] * 1e-9 / (r.bytes / best));
            goal(
                format!("{mesh}, {formulation}, element-wise, {thr} thr: within {want}× the memory bound"),
                x,
                format!(
                    "{}× ({}–{}); {}× at the run's best triad ({} GB/s)",
                    fmt(x, 2),
                    fmt(q1, 2),
                    fmt(q3, 2),
                    fmt(strict, 2),
                    fmt(best / 1e9, 1)
                ),
                x <= want,
            );
        }
    }
    goal(
        "a user's run steps within 1.15× of the inner loop".into(),
        ratio_med,
        format!(
            "{}× ({}–{}); with the final state written, {}× ({}–{})",
            fmt(ratio_med, 2),
            fmt(ratio_lo, 2),
            fmt(ratio_hi, 2),
            fmt(whole_med, 2),
            fmt(whole_lo, 2),
            fmt(whole_hi, 2)
        ),
        ratio_med <= 1.15,
    );
    goal(
        "setup with a given `dt` ≤ 5 s".into(),
        dt_med,
        format!("{} s ({}–{})", fmt(dt_med, 2), fmt(dt_lo, 2), fmt(dt_hi, 2)),
        dt_med <= 5.0,
    );
    goal(
        "setup with a `dt_factor` ≤ 5 s".into(),
        f_med,
        format!("{} s ({}–{})", fmt(f_med, 2), fmt(f_lo, 2), fmt(f_hi, 2)),
        f_med <= 5.0,
    );
    let share = f_med / (f_med + run_s);
    goal(
        "setup ≤ 10 % of a 10⁴-step run".into(),
        share,
        format!(
            "{} % with a `dt_factor` (the run: {} s at the inner loop's speed)",
            fmt(100.0 * share, 1),
            fmt(run_s, 0)
        ),
        share <= 0.1,
    );
    let _ = writeln!(
        s,
        "\nA ratio to the memory bound is judged at the bandwidth of the seconds in which the step \
        ran: its median time over bytes / the bandwidth of the triad passes around its case, the \
        quartiles' in brackets. Beside it, the median time against the best bandwidth around any \
        case on as many threads in the run: nearer what the step would read on a machine of its \
        own. A step that is not held by the memory keeps its time when others' \
        traffic lowers the bandwidth, so the two figures part most for it.\n\
        \nThe run path: {} rounds, interleaved, each of {} steps of the 10⁶-element rigid grid \
        (element-wise, all threads): the inner loop (`step_only`, {} ns per element-step, median) \
        and a user's `run::run` of the same setup (a history row every 100 steps, one probe, the \
        guard's checks; then `final_state.json`), and the setup (`Setup::new`: the model, the \
        evaluator, the proven bracket of `Δt_crit`, and with a `dt_factor` the Lanczos `ω_max` \
        to four digits). Medians, with the range of the rounds.",
        r.loop_ratio.len(),
        r.steps,
        fmt(inner_med, 1)
    );
    s
}

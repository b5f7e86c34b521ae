//! Speed against accuracy: one scene run over a sweep of time steps, mesh resolutions,
//! formulations, evaluators and contact models. Each point reports its error against a
//! reference, its wall time, steps, peak memory and `Δt_crit`; the points that no other point
//! beats in both error and time form the Pareto front, where a time within another's spread
//! of runs is no better and no worse than it ([`Point::pareto`]).
//!
//! The reference is the scene's closed form or theory ([`ReferenceSpec`]) when it has one,
//! otherwise the finest run of the sweep (highest refinement, then smallest time step), named in
//! the report. Runs write no files; only the report does.

use crate::analysis::hopping::{lowest_point, Tracker};
use crate::analysis::setup::{self, Overrides, Setup};
use crate::error::{Error, Result};
use crate::input::names;
use crate::input::scene::{
    ContactModel, EvaluatorKind, FormulationSpec, MeshSpec, ReferenceSpec, Scene,
};
use crate::mesh::geometry::Vec2;
use crate::model::Model;
use crate::step::integrator::{RunStatus, Status};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

/// What a sweep varies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Key {
    /// Absolute time step (s).
    Dt,
    /// Time step as a fraction of `Δt_crit`.
    DtFactor,
    /// Mesh refinement: grid cells × r in each direction of more than one cell, Voronoi
    /// sites × r².
    Refine,
    /// `rigid` or `hybrid` (hybrid keeps the scene's penalty, or 10).
    Formulation,
    /// Hybrid penalty `p` (the formulation becomes hybrid).
    Penalty,
    /// `assembled` or `element-wise`.
    Evaluator,
    /// `edge-to-edge` or `point` (the scene must declare contact).
    Contact,
    /// The seed of every Voronoi mesh's sites (the scene must have one).
    Seed,
}

const KEYS: [(&str, Key); 8] = [
    ("dt", Key::Dt),
    ("dt_factor", Key::DtFactor),
    ("refine", Key::Refine),
    ("formulation", Key::Formulation),
    ("penalty", Key::Penalty),
    ("evaluator", Key::Evaluator),
    ("contact", Key::Contact),
    ("seed", Key::Seed),
];

impl Key {
    /// Refuses a value the key cannot take, naming the key and the allowed values (the names of
    /// formulations, evaluators and contact models as scenes write them).
    ///
    /// # Errors
    /// `v` is not a value of the key: a finite number > 0 (`dt`, `dt_factor`, `penalty`), an
    /// integer in 1..=64 (`refine`), a formulation, evaluator or contact model by its name, or
    /// an unsigned 64-bit integer (`seed`).
    pub fn check(self, v: &str) -> Result<()> {
        let within = |ok: bool, allowed: &str| match ok {
            true => Ok(()),
            false => Err(format!("must be {allowed}, got `{v}`")),
        };
        let checked = match self {
            Key::Dt | Key::DtFactor | Key::Penalty => within(
                v.parse::<f64>().is_ok_and(|x| x > 0.0 && x.is_finite()),
                "a finite number > 0",
            ),
            Key::Refine => within(
                v.parse::<u32>().is_ok_and(|r| (1..=64).contains(&r)),
                "an integer in 1..=64",
            ),
            Key::Formulation => within(
                FormulationSpec::KINDS.contains(&v),
                &names::or_list(FormulationSpec::KINDS),
            ),
            Key::Evaluator => v.parse::<EvaluatorKind>().map(|_| ()),
            Key::Contact => v.parse::<ContactModel>().map(|_| ()),
            Key::Seed => within(
                v.parse::<u64>().is_ok(),
                "an integer in 0..=18446744073709551615",
            ),
        };
        checked.map_err(|why| Error::scene(format!("--sweep {}", self.name()), why))
    }

    /// The key of `name` as written on the command line, if there is one.
    ///
    /// # Errors
    /// `name`, trimmed, is none of `dt`, `dt_factor`, `refine`, `formulation`, `penalty`,
    /// `evaluator`, `contact` and `seed`.
    pub fn named(name: &str) -> Result<Key> {
        KEYS.iter()
            .find(|k| k.0 == name.trim())
            .map(|k| k.1)
            .ok_or_else(|| {
                Error::scene(
                    "--sweep",
                    format!(
                        "unknown key `{name}`; allowed: {}",
                        KEYS.map(|k| k.0).join(", ")
                    ),
                )
            })
    }

    /// The key as written on the command line.
    pub fn name(self) -> &'static str {
        KEYS.iter().find(|k| k.1 == self).map_or("?", |k| k.0)
    }
}

/// One `--sweep KEY=V1,V2,...`.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// What is swept.
    pub key: Key,
    /// Its values, as given.
    pub values: Vec<String>,
}

impl Sweep {
    /// Parses `KEY=V1,V2,...`; the error names the key or value and what is allowed.
    ///
    /// # Errors
    /// `text` has no `=`, names an unknown key ([`Key::named`]), lists no value, or lists a value
    /// the key does not take ([`Key::check`]).
    pub fn parse(text: &str) -> Result<Sweep> {
        let field = "--sweep";
        let (key, values) = text
            .split_once('=')
            .ok_or_else(|| Error::scene(field, format!("expected KEY=V1,V2,..., got `{text}`")))?;
        let key = Key::named(key)?;
        let values: Vec<String> = values
            .split(',')
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .collect();
        if values.is_empty() {
            return Err(Error::scene(
                field,
                format!("`{}` has no values", key.name()),
            ));
        }
        for v in &values {
            key.check(v)?;
        }
        Ok(Sweep { key, values })
    }
}

/// One point of the sweep and what it measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Point {
    /// `(key, value)` of each sweep, in the order given.
    pub settings: Vec<(Key, String)>,
    /// Elements of the point's model.
    pub elements: usize,
    /// Its DOFs.
    pub dofs: usize,
    /// Time step (s).
    pub dt: f64,
    /// Critical time step (s).
    pub dt_crit: f64,
    /// Steps run.
    pub steps: u64,
    /// Model, evaluator and `Δt_crit` (s).
    pub setup_s: f64,
    /// The time loop (s).
    pub stepping_s: f64,
    /// `setup_s + stepping_s`: what the point cost. Each is the median of the point's runs.
    pub wall_s: f64,
    /// Runs of the point: repeated until their stepping adds up to 0.2 s (at most 25), so that
    /// its time is a median, not one noisy sample.
    pub runs: usize,
    /// The least and the largest wall time of those runs (s): the spread of `wall_s`.
    pub wall_range_s: [f64; 2],
    /// Peak resident memory of the process during the point (MiB), where the system tells it.
    pub peak_mib: Option<f64>,
    /// `ok`, or where and why the run stopped.
    pub status: PointStatus,
    /// Relative error against the reference; `None` when the run diverged.
    pub error: Option<f64>,
    /// Whether no other point beats it: an error as small and a wall time clearly smaller
    /// (its slowest run faster than this point's fastest), or a smaller error and a wall time
    /// not clearly larger (its fastest run no slower than this point's slowest).
    pub pareto: bool,
}

/// How a point's run ended, serialised (and written into `tradeoff.csv`) as one text: `ok`,
/// `diverged at step N (t = T s): reason` or `interrupted at step N (t = T s)`
/// ([`Status::describe`]); read back from it by its `FromStr`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum PointStatus {
    /// Every step was taken.
    Ok,
    /// Stopped by the guard: `at step N (t = T s): reason` ([`Status::detail`]).
    Diverged(String),
    /// Stopped by the interrupt flag: `at step N (t = T s)`.
    Interrupted(String),
}

impl From<&Status> for PointStatus {
    fn from(status: &Status) -> Self {
        let detail = status.detail().unwrap_or_default();
        match status.kind() {
            RunStatus::Ok => PointStatus::Ok,
            RunStatus::Diverged => PointStatus::Diverged(detail),
            RunStatus::Interrupted => PointStatus::Interrupted(detail),
        }
    }
}

impl PointStatus {
    /// Whether every step was taken.
    pub fn is_ok(&self) -> bool {
        *self == PointStatus::Ok
    }
}

impl std::fmt::Display for PointStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PointStatus::Ok => write!(f, "{}", RunStatus::Ok),
            PointStatus::Diverged(detail) => write!(f, "{} {detail}", RunStatus::Diverged),
            PointStatus::Interrupted(detail) => write!(f, "{} {detail}", RunStatus::Interrupted),
        }
    }
}

impl std::str::FromStr for PointStatus {
    type Err = String;

    /// The status that [`Display`](std::fmt::Display) wrote as `text`.
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        let after = |kind: RunStatus| {
            text.strip_prefix(kind.name())
                .and_then(|rest| rest.strip_prefix(' '))
                .map(str::to_string)
        };
        if text == RunStatus::Ok.name() {
            Ok(PointStatus::Ok)
        } else if let Some(detail) = after(RunStatus::Diverged) {
            Ok(PointStatus::Diverged(detail))
        } else if let Some(detail) = after(RunStatus::Interrupted) {
            Ok(PointStatus::Interrupted(detail))
        } else {
            Err(format!(
                "a point's status is `ok`, `diverged …` or `interrupted …`, not `{text}`"
            ))
        }
    }
}

impl From<PointStatus> for String {
    fn from(status: PointStatus) -> String {
        status.to_string()
    }
}

impl TryFrom<String> for PointStatus {
    type Error = String;

    fn try_from(text: String) -> std::result::Result<Self, String> {
        text.parse()
    }
}

/// The whole sweep.
#[derive(Debug, Clone, Serialize)]
pub struct TradeoffReport {
    /// The scene's name.
    pub scene: String,
    /// What the errors are measured against.
    pub reference: String,
    /// How the error is defined.
    pub error: String,
    /// Every point of the sweep, in sweep order.
    pub points: Vec<Point>,
}

/// The quantity a run is measured by.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Measure {
    /// The histories `(t, value)` of the scene's probes, with the centroid of the element that
    /// carried each.
    Histories(Vec<Vec<(f64, f64)>>, Vec<Vec2>),
    /// The first apex of the lowest point above the ground (m).
    Apex(f64),
}

/// The folder a sweep of `scene` writes to unless told another: `out/tradeoff-<name>`, the
/// scene's name with every character other than an ASCII letter, a digit, `-` and `_` made
/// `_`, and cut to 200 characters, so that it is one folder directly in `out/` whatever the
/// name holds (a `/` or `..` moved the files elsewhere).
pub fn default_folder(scene: &Scene) -> std::path::PathBuf {
    let name: String = scene
        .name
        .chars()
        .take(200)
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    std::path::Path::new("out").join(format!("tradeoff-{name}"))
}

/// Runs `scene` (read and validated, as [`Scene::from_file`] gives it) at every combination
/// of `sweeps`, calling `progress` with each finished point. The errors compare the histories
/// of the scene's probes, the columns `rbsm run` writes.
///
/// # Errors
/// As [`Study::new`] for `scene`, [`Study::point`] for each combination of `sweeps` (the first that
/// fails stops the sweep) and [`Study::report`] for the errors.
pub fn sweep(
    scene: &Scene,
    sweeps: &[Sweep],
    mut progress: impl FnMut(&Point),
) -> Result<TradeoffReport> {
    let study = Study::new(scene)?;
    let combos = combinations(sweeps);
    let mut runs = Vec::with_capacity(combos.len());
    for settings in combos {
        let measured = study.point(settings)?;
        progress(&measured.point);
        runs.push(measured);
    }
    study.report(runs)
}

/// A scene ready for a study: its probes placed by point on its own model. Its points are
/// independent ([`Study::point`]), so that they may run anywhere, in any order; the errors are
/// scored once all are in ([`Study::report`]).
pub struct Study {
    scene: Scene,
    model: Model,
}

/// One point of a study: its figures, and what its error is scored from.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Measured {
    /// The point's settings, costs and status; its error is scored by [`Study::report`].
    pub point: Point,
    /// The probes' histories, or the hopping block's apex.
    pub measure: Measure,
}

impl Study {
    /// The study of `scene` (read and validated): refuses a scene with neither a probe nor a
    /// closed-form reference, which leaves nothing to compare.
    ///
    /// # Errors
    /// The scene's model cannot be built ([`Model::build`]), a probe of the scene names an element
    /// outside the model, a point `at` in no element or a DOF the formulation does not have, or the
    /// scene has neither a probe nor a `reference` with a closed form.
    pub fn new(scene: &Scene) -> Result<Study> {
        let model = Model::build(scene)?;
        let scene = probes_by_point(scene, &model)?;
        if scene.reference.is_none() && scene.output.probes.is_empty() {
            return Err(Error::scene(
                "output.probes",
                "the tradeoff needs at least one probe to \
                compare runs (or a `reference` with a closed form)",
            ));
        }
        Ok(Study { scene, model })
    }

    /// Runs the point `settings` (each value checked by [`Key::check`]), again until its stepping
    /// adds up to 0.2 s (at most 25 runs); its times are the medians of those runs.
    ///
    /// # Errors
    /// A value is refused by [`Key::check`] or does not apply to the scene (`refine` of a polygons
    /// or gmsh mesh, `seed` without a Voronoi mesh, `contact` without a `contact`); or the point's
    /// scene is invalid, cannot be set up ([`Setup::new`]), or has a probe in no element of its
    /// model.
    pub fn point(&self, settings: Vec<(Key, String)>) -> Result<Measured> {
        let mut point_scene = self.scene.clone();
        for (key, value) in &settings {
            key.check(value)?;
            apply(&mut point_scene, *key, value)?;
        }
        point_scene.validate()?;
        let (mut point, measure) = run_point(&point_scene, settings.clone())?;
        let mut times = vec![(point.setup_s, point.stepping_s)];
        while point.status.is_ok()
            && times.len() < MAX_RUNS
            && times.iter().map(|t| t.1).sum::<f64>() < MIN_STEPPING_S
        {
            let (again, _) = run_point(&point_scene, settings.clone())?;
            times.push((again.setup_s, again.stepping_s));
        }
        point.timed(&times);
        Ok(Measured { point, measure })
    }

    /// The report of the points `runs`, in the order given: each error against the reference,
    /// and the Pareto front.
    ///
    /// # Errors
    /// Without a closed-form reference, every run diverged, leaving none to compare with; with
    /// `bar-step`, the first body is not on a grid mesh or has no traction on its right side.
    pub fn report(&self, runs: Vec<Measured>) -> Result<TradeoffReport> {
        let mut runs: Vec<(Point, Measure)> =
            runs.into_iter().map(|m| (m.point, m.measure)).collect();
        let (reference, error) = score(&self.scene, &self.model, &mut runs)?;
        let mut points: Vec<Point> = runs.into_iter().map(|r| r.0).collect();
        mark_pareto(&mut points);
        Ok(TradeoffReport {
            scene: self.scene.name.clone(),
            reference,
            error,
            points,
        })
    }
}

/// Every combination of the sweeps' values, the first sweep varying slowest.
fn combinations(sweeps: &[Sweep]) -> Vec<Vec<(Key, String)>> {
    let mut out = vec![Vec::new()];
    for s in sweeps {
        out = out
            .into_iter()
            .flat_map(|c: Vec<(Key, String)>| {
                s.values
                    .iter()
                    .map(move |v| [c.clone(), vec![(s.key, v.clone())]].concat())
            })
            .collect();
    }
    out
}

/// `scene` with each probe given by `element` placed instead by point, at the element's
/// reference centroid in `model` (the base scene's), under the same column name: a refined mesh
/// then measures the same material point. Every probe is first checked against `model`, as
/// `rbsm run` checks it.
fn probes_by_point(scene: &Scene, model: &Model) -> Result<Scene> {
    let placed = setup::probes(scene, model)?;
    let mut scene = scene.clone();
    for (spec, probe) in scene.output.probes.iter_mut().zip(&placed) {
        if spec.at.is_none() {
            let c = model.elements[probe.element].props.centroid;
            spec.name = Some(spec.column());
            spec.element = None;
            spec.at = Some([c.x, c.y]);
        }
    }
    Ok(scene)
}

/// Sets one sweep value in the scene; the caller validates the result.
fn apply(scene: &mut Scene, key: Key, value: &str) -> Result<()> {
    let number = || value.parse::<f64>().expect("checked by Key::check");
    match key {
        Key::Dt => {
            scene.time.dt = Some(number());
            scene.time.dt_factor = None;
        }
        Key::DtFactor => {
            scene.time.dt = None;
            scene.time.dt_factor = Some(number());
        }
        Key::Refine => {
            let r: usize = value.parse().expect("checked by Key::check");
            for (k, body) in scene.bodies.iter_mut().enumerate() {
                match &mut body.mesh {
                    MeshSpec::Grid(grid) => {
                        // A direction of one cell stays one cell: a one-row column stays a column.
                        for n in &mut grid.cells {
                            if *n > 1 {
                                *n *= r;
                            }
                        }
                    }
                    MeshSpec::Voronoi(voronoi) => voronoi.sites *= r * r,
                    MeshSpec::Polygons(_) | MeshSpec::Gmsh(_) => {
                        return Err(Error::scene(
                            format!("bodies[{k}].mesh"),
                            "`refine` needs a grid or Voronoi mesh",
                        ))
                    }
                }
            }
        }
        Key::Formulation => {
            scene.formulation = match (value, scene.formulation) {
                (rigid, _) if rigid == FormulationSpec::Rigid.kind() => FormulationSpec::Rigid,
                (poisson, _) if poisson == FormulationSpec::RigidPoisson.kind() => {
                    FormulationSpec::RigidPoisson
                }
                (_, FormulationSpec::Hybrid { penalty }) => FormulationSpec::Hybrid { penalty },
                (_, FormulationSpec::Rigid | FormulationSpec::RigidPoisson) => {
                    FormulationSpec::Hybrid { penalty: 10.0 }
                }
            }
        }
        Key::Penalty => scene.formulation = FormulationSpec::Hybrid { penalty: number() },
        Key::Evaluator => scene.evaluator = value.parse().expect("checked by Key::check"),
        Key::Seed => {
            let seed: u64 = value.parse().expect("checked by Key::check");
            let mut voronoi = 0;
            for body in &mut scene.bodies {
                if let MeshSpec::Voronoi(v) = &mut body.mesh {
                    v.seed = seed;
                    voronoi += 1;
                }
            }
            if voronoi == 0 {
                return Err(Error::scene(
                    "--sweep seed",
                    "the scene has no Voronoi mesh whose seed could vary",
                ));
            }
        }
        Key::Contact => {
            let contact = scene.contact.as_mut().ok_or_else(|| {
                Error::scene("--sweep contact", "the scene declares no `contact`")
            })?;
            contact.model = value.parse().expect("checked by Key::check");
        }
    }
    Ok(())
}

/// Linux: the peak resident set is reset before a point and read after it.
fn reset_peak_memory() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

fn peak_memory_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<f64>().ok()? / 1024.0)
}

/// A point is run again until its runs' stepping adds up to this much (s)...
const MIN_STEPPING_S: f64 = 0.2;
/// ... or it has run this many times.
const MAX_RUNS: usize = 25;

/// The median of `x` (not empty).
fn median(mut x: Vec<f64>) -> f64 {
    x.sort_by(f64::total_cmp);
    let n = x.len();
    if n % 2 == 1 {
        x[n / 2]
    } else {
        0.5 * (x[n / 2 - 1] + x[n / 2])
    }
}

impl Point {
    /// Sets the point's times from its runs' `(setup, stepping)` times (s): medians, and the
    /// range of the wall times.
    fn timed(&mut self, runs: &[(f64, f64)]) {
        let walls: Vec<f64> = runs.iter().map(|t| t.0 + t.1).collect();
        self.setup_s = median(runs.iter().map(|t| t.0).collect());
        self.stepping_s = median(runs.iter().map(|t| t.1).collect());
        self.wall_s = median(walls.clone());
        self.runs = runs.len();
        self.wall_range_s = [
            walls.iter().copied().fold(f64::INFINITY, f64::min),
            walls.iter().copied().fold(0.0, f64::max),
        ];
    }
}

/// Runs one point and measures it.
fn run_point(scene: &Scene, settings: Vec<(Key, String)>) -> Result<(Point, Measure)> {
    reset_peak_memory();
    let start = Instant::now();
    // The exact Δt_crit: each point's step is stated as a fraction of it.
    let exact = Overrides {
        exact_dt_crit: true,
        ..Default::default()
    };
    let p = Setup::new(scene, &exact)?;
    let setup_s = start.elapsed().as_secs_f64();
    let model = &p.model;
    let mut cd = p.integrator(p.dt);
    let clock = Instant::now();
    let (status, measure) = if matches!(scene.reference, Some(ReferenceSpec::HoppingBlock)) {
        // Every step, until the first apex: the contact lasts a few dozen steps.
        let ground = ground_height(model);
        let mut tracker = Tracker::default();
        let mut status = Status::Ok;
        // Until the body falls again after its first rebound: the apex is then behind it.
        let mut falling = false;
        while cd.step < p.steps
            && !(falling && tracker.bounces.first().is_some_and(|b| b.apex.is_finite()))
        {
            let n = (p.steps - cd.step).min(1000);
            status = cd.run(
                n,
                1,
                |s, _| {
                    let vy = crate::analysis::hopping::centre_velocity(model, s.v).y;
                    tracker.push(s.t, lowest_point(model, s.u) - ground, vy);
                    falling = vy < 0.0;
                    Ok(())
                },
                |_| (),
            )?;
            if status != Status::Ok {
                break;
            }
        }
        (
            status,
            Measure::Apex(tracker.bounces.first().map_or(f64::NAN, |b| b.apex)),
        )
    } else {
        let probes = p.probes()?;
        let mut histories = vec![Vec::new(); probes.len()];
        let every = (p.steps / 2000).max(1);
        let status = cd.run(
            p.steps,
            every,
            |s, _| {
                for (pr, h) in probes.iter().zip(&mut histories) {
                    h.push((s.t, pr.value(s.u)));
                }
                Ok(())
            },
            |_| (),
        )?;
        (
            status,
            Measure::Histories(
                histories,
                probes
                    .iter()
                    .map(|pr| model.elements[pr.element].props.centroid)
                    .collect(),
            ),
        )
    };
    let stepping_s = clock.elapsed().as_secs_f64();
    let status = PointStatus::from(&status);
    let point = Point {
        settings,
        elements: model.elements.len(),
        dofs: model.n_dofs(),
        dt: p.dt,
        dt_crit: p.dt_crit(),
        steps: cd.step,
        setup_s,
        stepping_s,
        wall_s: setup_s + stepping_s,
        peak_mib: peak_memory_mib(),
        status,
        error: None,
        pareto: false,
        runs: 1,
        wall_range_s: [setup_s + stepping_s; 2],
    };
    Ok((point, measure))
}

/// The height of the (horizontal) ground of a hopping-block scene: its first segment's.
fn ground_height(model: &Model) -> f64 {
    model.ground.first().map_or(0.0, |g| g[0].y)
}

/// Fills in every point's error; returns the reference's name and the error's definition.
fn score(scene: &Scene, model: &Model, runs: &mut [(Point, Measure)]) -> Result<(String, String)> {
    let names: Vec<String> = scene.output.probes.iter().map(|p| p.column()).collect();
    let ok = |p: &Point| p.status.is_ok();
    match &scene.reference {
        Some(ReferenceSpec::HoppingBlock) => {
            let ground = ground_height(model);
            let height = lowest_point(model, &vec![0.0; model.n_dofs()]) - ground;
            for (p, m) in runs.iter_mut() {
                if let (true, Measure::Apex(a)) = (ok(p), m) {
                    p.error = a.is_finite().then(|| (*a - height).abs() / height);
                }
            }
            Ok((
                format!(
                    "theory of the hopping block: the first apex returns to the drop height H \
                = {height} m"
                ),
                "|apex − H| / H".into(),
            ))
        }
        Some(ReferenceSpec::BarStep { probe }) => {
            let k = names
                .iter()
                .position(|name| name == probe)
                .expect("validated: the probe exists");
            let bar = Bar::of(scene, model)?;
            for (p, m) in runs.iter_mut() {
                if let (true, Measure::Histories(h, at)) = (ok(p), m) {
                    // At the centroid of the element that carried the probe (the rigid elements'
                    // displacement jumps at their edges, where a refined mesh may put the point).
                    let x = at[k].x - bar.origin;
                    let exact: Vec<(f64, f64)> = h[k]
                        .iter()
                        .map(|&(t, _)| (t, bar.displacement(x, t)))
                        .collect();
                    p.error = Some(rms_difference(&h[k], &exact));
                }
            }
            Ok((
                format!(
                    "closed form of the bar (L = {} m) under a step end load, modal series of \
                    4000 modes, at the centroid of the probe's element",
                    bar.length
                ),
                format!("RMS over time of (u − u_exact) / RMS of u_exact, probe `{probe}`"),
            ))
        }
        None => {
            let finest = runs
                .iter()
                .enumerate()
                .filter(|(_, r)| ok(&r.0))
                .max_by(|a, b| {
                    a.1 .0
                        .elements
                        .cmp(&b.1 .0.elements)
                        .then(b.1 .0.dt.total_cmp(&a.1 .0.dt))
                        .then(b.0.cmp(&a.0))
                })
                .map(|(i, _)| i)
                .ok_or_else(|| {
                    Error::scene(
                        "--sweep",
                        "every run of the sweep diverged: there is no reference",
                    )
                })?;
            let name = describe(&runs[finest].0.settings);
            let Measure::Histories(reference, _) = &runs[finest].1 else {
                unreachable!("no closed form: histories")
            };
            let reference = reference.clone();
            for (i, (p, m)) in runs.iter_mut().enumerate() {
                if let (true, Measure::Histories(h, _)) = (ok(p), m) {
                    p.error = (i != finest).then(|| {
                        h.iter()
                            .zip(&reference)
                            .map(|(h, r)| rms_difference(h, &resample(r, h)))
                            .fold(0.0, f64::max)
                    });
                }
            }
            Ok((
                format!("finest run of the sweep ({name})"),
                format!(
                    "largest over the probes ({}) of RMS(u − u_ref) / RMS(u_ref)",
                    names.join(", ")
                ),
            ))
        }
    }
}

/// `key=value, ...` of a point.
pub fn describe(settings: &[(Key, String)]) -> String {
    if settings.is_empty() {
        return "the scene as given".into();
    }
    settings
        .iter()
        .map(|(k, v)| format!("{}={v}", k.name()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `RMS(a − b) / RMS(b)` over matching samples.
fn rms_difference(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    let diff: f64 = a.iter().zip(b).map(|(x, y)| (x.1 - y.1).powi(2)).sum();
    let norm: f64 = b.iter().map(|y| y.1 * y.1).sum();
    (diff / norm).sqrt()
}

/// `reference` interpolated linearly at the times of `at`.
fn resample(reference: &[(f64, f64)], at: &[(f64, f64)]) -> Vec<(f64, f64)> {
    at.iter()
        .map(|&(t, _)| {
            let k = reference
                .partition_point(|r| r.0 < t)
                .clamp(1, reference.len().max(2) - 1);
            let (a, b) = (reference[k - 1], reference[k.min(reference.len() - 1)]);
            let w = if b.0 > a.0 {
                ((t - a.0) / (b.0 - a.0)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (t, a.1 + w * (b.1 - a.1))
        })
        .collect()
}

/// A bar fixed at `x = 0`, free at `x = L`, loaded at `t = 0` by the end traction `q`:
/// `u(x, t) = (q/E)[x − Σ_n 2(−1)ⁿ/(L k_n²) sin(k_n x) cos(c k_n t)]`, `k_n = (2n+1)π/(2L)`,
/// `c = √(E/ρ)`, with `E` the normal spring modulus `E/(1 − ν²)` of eq. 12.
struct Bar {
    origin: f64,
    length: f64,
    strain: f64,
    speed: f64,
}

impl Bar {
    fn of(scene: &Scene, model: &Model) -> Result<Bar> {
        let field = "reference";
        let body = scene
            .bodies
            .first()
            .ok_or_else(|| Error::scene(field, "bar-step needs a body"))?;
        let crate::input::scene::MeshSpec::Grid(grid) = &body.mesh else {
            return Err(Error::scene(
                field,
                "bar-step needs the first body on a grid mesh",
            ));
        };
        let q = body
            .loads
            .iter()
            .find_map(|l| match l {
                crate::input::scene::LoadSpec::Traction(t)
                    if t.edge
                        == crate::input::scene::EdgeSet::Side(crate::input::scene::Side::Right) =>
                {
                    Some(t.value[0])
                }
                _ => None,
            })
            .ok_or_else(|| {
                Error::scene(
                    field,
                    "bar-step needs a traction on the right edge of the first body",
                )
            })?;
        let e = model.bodies[0].moduli[0];
        let rho = scene.materials[&body.material].rho;
        Ok(Bar {
            origin: grid.origin[0],
            length: grid.size[0],
            strain: q / e,
            speed: (e / rho).sqrt(),
        })
    }

    /// `u(x, t)`, `x` from the held end.
    fn displacement(&self, x: f64, t: f64) -> f64 {
        let l = self.length;
        let series: f64 = (0..4000)
            .map(|n| {
                let k = (2 * n + 1) as f64 * std::f64::consts::PI / (2.0 * l);
                let sign = if n % 2 == 0 { 1.0 } else { -1.0 };
                2.0 * sign / (l * k * k) * (k * x).sin() * (self.speed * k * t).cos()
            })
            .sum();
        self.strain * (x - series)
    }
}

/// Marks the points on the Pareto front of (wall time, error) ([`Point::pareto`]). Times are
/// compared by the ranges of the points' runs, so that timing noise does not decide the front:
/// of two points whose runs overlap in time, the one with the smaller error beats the other;
/// a point of one run has a range of one time.
fn mark_pareto(points: &mut [Point]) {
    let snapshot: Vec<([f64; 2], Option<f64>)> =
        points.iter().map(|p| (p.wall_range_s, p.error)).collect();
    for (i, p) in points.iter_mut().enumerate() {
        let Some(e) = p.error else { continue };
        let [fastest, slowest] = p.wall_range_s;
        p.pareto = !snapshot
            .iter()
            .enumerate()
            .any(|(j, &([min, max], other))| {
                j != i
                    && other.is_some_and(|o| (o <= e && max < fastest) || (o < e && min <= slowest))
            });
    }
}

impl crate::analysis::Report for TradeoffReport {
    /// The table of `tradeoff.md`.
    fn text(&self) -> String {
        self.tables().1
    }
}

impl TradeoffReport {
    /// Writes `tradeoff.csv`, `tradeoff.md` and `tradeoff.svg` into `dir`.
    ///
    /// # Errors
    /// `dir` cannot be created, `tradeoff.csv` or `tradeoff.md` cannot be written in it, or
    /// `tradeoff.svg` cannot be drawn or written.
    pub fn write(&self, dir: &Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let (csv, md) = self.tables();
        let write =
            |name: &str, text: &str| crate::output::write_atomic(&dir.join(name), text.as_bytes());
        write("tradeoff.csv", &csv)?;
        write("tradeoff.md", &md)?;
        let pts: Vec<(f64, f64, bool, String)> = self
            .points
            .iter()
            .filter_map(|p| {
                p.error
                    .filter(|e| *e > 0.0)
                    .map(|e| (p.wall_s, e, p.pareto, describe(&p.settings)))
            })
            .collect();
        crate::output::plot::pareto(
            &dir.join("tradeoff.svg"),
            &format!("{}: error against wall time", self.scene),
            &pts,
        )
    }

    /// The contents of `tradeoff.csv` and `tradeoff.md`.
    fn tables(&self) -> (String, String) {
        let keys: Vec<&str> = self
            .points
            .first()
            .map(|p| p.settings.iter().map(|s| s.0.name()).collect())
            .unwrap_or_default();
        let mut csv = keys.iter().map(|k| format!("{k},")).collect::<String>();
        csv.push_str("elements,dofs,dt,dt_crit,steps,setup_s,stepping_s,wall_s,runs,wall_min_s,wall_max_s,peak_mib,\
            error,pareto,status\n",
        );
        let mut md = format!(
            "Scene `{}`. Reference: {}. Error: {}.\n\n",
            self.scene, self.reference, self.error
        );
        md.push_str(&format!(
            "| {} | elements | Δt (s) | Δt/Δt_crit | steps | wall (s), median (range) of \
            runs | peak (MiB) | error | Pareto |\n",
            keys.join(" | ")
        ));
        md.push_str(&format!(
            "|{}---|---|---|---|---|---|---|---|\n",
            "---|".repeat(keys.len())
        ));
        for p in &self.points {
            let values: Vec<&str> = p.settings.iter().map(|s| s.1.as_str()).collect();
            let err = p.error.map_or(String::new(), |e| format!("{e:.4e}"));
            let peak = p.peak_mib.map_or(String::new(), |m| format!("{m:.1}"));
            csv.push_str(&values.iter().map(|v| format!("{v},")).collect::<String>());
            csv.push_str(&format!(
                "{},{},{:e},{:e},{},{:.6},{:.6},{:.6},{},{:.6},{:.6},{peak},{err},{},\"{}\"\n",
                p.elements,
                p.dofs,
                p.dt,
                p.dt_crit,
                p.steps,
                p.setup_s,
                p.stepping_s,
                p.wall_s,
                p.runs,
                p.wall_range_s[0],
                p.wall_range_s[1],
                p.pareto,
                p.status.to_string().replace('"', "'")
            ));
            let err_md = match (&p.error, &p.status) {
                (Some(e), _) => format!("{e:.3e}"),
                (None, PointStatus::Ok) => "reference".into(),
                // Where it stopped, without the guard's reason.
                (None, status) => {
                    let text = status.to_string();
                    text.split(':').next().unwrap_or(&text).to_string()
                }
            };
            md.push_str(&format!(
                "| {} | {} | {:.3e} | {:.3} | {} | {:.3e} ({:.2e}–{:.2e}) of {} | {peak} | \
                {err_md} | {} |\n",
                values.join(" | "),
                p.elements,
                p.dt,
                p.dt / p.dt_crit,
                p.steps,
                p.wall_s,
                p.wall_range_s[0],
                p.wall_range_s[1],
                p.runs,
                if p.pareto { "◆" } else { "" }
            ));
        }
        (csv, md)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point with `error` whose runs took `[fastest, slowest]` s.
    fn point(error: Option<f64>, [fastest, slowest]: [f64; 2]) -> Point {
        Point {
            settings: Vec::new(),
            elements: 1,
            dofs: 3,
            dt: 1.0,
            dt_crit: 1.0,
            steps: 1,
            setup_s: 0.0,
            stepping_s: 0.5 * (fastest + slowest),
            wall_s: 0.5 * (fastest + slowest),
            runs: 3,
            wall_range_s: [fastest, slowest],
            peak_mib: None,
            status: PointStatus::Ok,
            error,
            pareto: false,
        }
    }

    fn front(points: &mut [Point]) -> Vec<bool> {
        mark_pareto(points);
        points.iter().map(|p| p.pareto).collect()
    }

    /// Of two points whose runs overlap in time, the one with the smaller error is on the front
    /// whichever median is smaller; apart in time, both are, the faster one with the larger
    /// error; a point beaten in both is off it, and so is a point with no error.
    #[test]
    fn timing_noise_does_not_decide_the_front() {
        // Overlapping runs: the accurate one wins, even with the larger median.
        let mut overlap = [point(Some(1e-3), [1.0, 1.4]), point(Some(1e-2), [0.9, 1.1])];
        assert_eq!(front(&mut overlap), [true, false]);
        // Apart: a trade, both on the front.
        let mut apart = [point(Some(1e-3), [1.2, 1.4]), point(Some(1e-2), [0.9, 1.1])];
        assert_eq!(front(&mut apart), [true, true]);
        // Beaten in both; equal errors, the clearly faster one alone; no error.
        let mut beaten = [
            point(Some(1e-3), [1.0, 1.1]),
            point(Some(1e-2), [2.0, 2.1]),
            point(Some(1e-3), [1.5, 1.6]),
            point(None, [0.1, 0.2]),
        ];
        assert_eq!(front(&mut beaten), [true, false, false, false]);
        // Equal errors, overlapping runs: neither beats the other.
        let mut tied = [point(Some(1e-3), [1.0, 1.2]), point(Some(1e-3), [1.1, 1.3])];
        assert_eq!(front(&mut tied), [true, true]);
    }
}

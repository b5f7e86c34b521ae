//! A whole explicit run, from a scene to its outputs: model, evaluator, `Δt_crit`, the time
//! loop and the files of DESIGN.md §9. The command line and the tests call this one function.

use crate::contact::{self, Contact, WithBlocks};
use crate::error::{Error, Result};
use crate::evaluator::{self, Evaluator};
use crate::integrator::{CentralDifference, Status};
use crate::loads::Loads;
use crate::mass::Mass;
use crate::model::{dof_index, Model};
use crate::output::{self, ContactSummary, EnergySummary, History, Probe, Summary};
use crate::scene::{EvaluatorKind, Scene};
use crate::{eigen, stability};
use crate::vtk::VtkSeries;
use std::path::Path;
use std::time::Instant;

/// Removes what an earlier run left in `out` of the files a run writes (`summary.json`,
/// `final_state.json`, `series.pvd` and the frames `vtk/step_*.vtk`), so that a run that stops
/// early never leaves an earlier run's results beside its own. Other files are left alone;
/// `history.csv` is rewritten from its first line anyway.
fn clear_previous(out: &Path) -> Result<()> {
    let remove = |path: &Path| match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::io(path, e)),
        _ => Ok(()),
    };
    for name in ["summary.json", "final_state.json", "series.pvd"] {
        remove(&out.join(name))?;
    }
    let frames = out.join("vtk");
    let Ok(entries) = std::fs::read_dir(&frames) else { return Ok(()) };
    for entry in entries {
        let path = entry.map_err(|e| Error::io(&frames, e))?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.starts_with("step_") && name.ends_with(".vtk") {
            remove(&path)?;
        }
    }
    Ok(())
}

/// Command-line overrides of the scene.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Evaluator, replacing the scene's.
    pub evaluator: Option<EvaluatorKind>,
    /// Time step (s), replacing the scene's `dt` or `dt_factor`.
    pub dt: Option<f64>,
    /// Number of steps, replacing the scene's `end` or `steps`.
    pub steps: Option<u64>,
}

/// A model ready to step: evaluator, mass, loads and the time step.
pub struct Prepared {
    /// The model of the scene.
    pub model: Model,
    /// The evaluator of `f_int`.
    pub evaluator: Box<dyn Evaluator>,
    /// `M` and its inverse.
    pub mass: Mass,
    /// Point loads and gravity.
    pub loads: Loads,
    /// Largest circular frequency (rad/s), by Lanczos (`eigen::omega_max`); with contact, of
    /// `K` plus every contact closed against rigid ground (`contact::stiffness_estimate`).
    pub omega_max: f64,
    /// Critical time step `2/ω_max` (s).
    pub dt_crit: f64,
    /// The time step of the run (s).
    pub dt: f64,
    /// Steps to run.
    pub steps: u64,
}

impl Prepared {
    /// Builds everything a run of `scene` needs.
    pub fn new(scene: &Scene, opts: &RunOptions) -> Result<Prepared> {
        let model = Model::build(scene)?;
        let evaluator = evaluator::build(&model, opts.evaluator.unwrap_or(scene.evaluator));
        let mass = Mass::new(&model);
        let loads = Loads::new(&model);
        let omega_max = match Contact::new(&model) {
            None => eigen::omega_max(&model, evaluator.as_ref(), &mass),
            Some(c) => {
                let blocks = contact::stiffness_estimate(&model, &c);
                eigen::omega_max(&model, &WithBlocks { inner: evaluator.as_ref(), nd: model.formulation.ndof(), blocks }, &mass)
            }
        };
        if !omega_max.is_finite() {
            return Err(Error::scene("materials", format!(
                "the stiffness or mass of the model overflows (ω_max = {omega_max}); check E, rho, thickness and the mesh size")));
        }
        let dt_crit = stability::critical_time_step(omega_max);
        let dt = match (opts.dt, scene.time.dt, scene.time.dt_factor) {
            (Some(dt), _, _) if dt > 0.0 && dt.is_finite() => dt,
            (Some(dt), _, _) => return Err(Error::scene("--dt", format!("must be a finite number > 0, got {dt}"))),
            (None, Some(dt), _) => dt,
            (None, None, Some(f)) if dt_crit.is_finite() => f * dt_crit,
            (None, None, _) => return Err(Error::scene("time.dt_factor", "Δt_crit is infinite (no spring is loaded): give `time.dt` instead")),
        };
        let steps = match (opts.steps, scene.time.steps, scene.time.end) {
            (Some(n), _, _) => n,
            (None, Some(n), _) => n,
            (None, None, Some(end)) => (end / dt - 1e-9).ceil().max(1.0) as u64,
            (None, None, None) => unreachable!("validated: the scene has `end` or `steps`"),
        };
        Ok(Prepared { model, evaluator, mass, loads, omega_max, dt_crit, dt, steps })
    }
}

impl Prepared {
    /// A central-difference integrator of the model at time step `dt`, with the guard told
    /// `Δt_crit`.
    pub fn integrator(&self, dt: f64) -> CentralDifference<'_> {
        let mut cd = CentralDifference::new(&self.model, self.evaluator.as_ref(), &self.mass, &self.loads, dt);
        cd.set_stability_limit(self.dt_crit);
        cd
    }
}

/// What the caller sees of a run while it goes: a line of text, and the step reached.
pub trait Monitor: Send {
    /// Information before the run starts (model size, time step, warnings).
    fn info(&mut self, line: &str);
    /// The step reached, called often; `total` steps in all.
    fn progress(&mut self, step: u64, total: u64);
}

/// A monitor that shows nothing.
pub struct Silent;

impl Monitor for Silent {
    fn info(&mut self, _: &str) {}
    fn progress(&mut self, _: u64, _: u64) {}
}

/// The history columns the scene asks for, each checked against the model's DOFs.
pub fn probes(scene: &Scene, model: &Model) -> Result<Vec<Probe>> {
    let nd = model.formulation.ndof();
    scene
        .output
        .probes
        .iter()
        .enumerate()
        .map(|(k, pr)| {
            let d = dof_index(&pr.dof, model.formulation, &format!("output.probes[{k}].dof"))?;
            let name = pr.name.clone().unwrap_or_else(|| format!("e{}_{}", pr.element, pr.dof));
            Ok(Probe { name, dof: pr.element * nd + d })
        })
        .collect()
}

/// Runs `scene` and writes its outputs into `out`; returns the summary (also written).
pub fn run(scene: &Scene, opts: &RunOptions, out: &Path, monitor: &mut dyn Monitor) -> Result<Summary> {
    let wall = Instant::now();
    let p = Prepared::new(scene, opts)?;
    let model = &p.model;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    clear_previous(out)?;
    monitor.info(&format!(
        "{}: {} elements, {} interfaces, {} free DOFs ({} formulation, {} evaluator, {} threads)",
        model.name,
        model.elements.len(),
        model.interfaces.len(),
        model.n_free_dofs(),
        model.formulation.name(),
        p.evaluator.kind().name(),
        rayon::current_num_threads()
    ));
    let ratio = p.dt / p.dt_crit;
    monitor.info(&format!("dt = {:.6e} s, Δt_crit = {:.6e} s, dt/Δt_crit = {ratio:.4}, {} steps", p.dt, p.dt_crit, p.steps));
    let warnings = crate::checks::warnings(model, p.dt, p.dt_crit);
    for w in &warnings {
        monitor.info(&format!("warning: {w}"));
    }
    let probes = probes(scene, model)?;
    let mut history = History::create(out, probes)?;
    let mut vtk = if scene.output.vtk { Some(VtkSeries::create(out)?) } else { None };
    let mut cd = p.integrator(p.dt);
    let (mut first, mut last, mut rotation) = (None, None, 0.0f64);
    let start = Instant::now();
    let status = cd.run(
        p.steps,
        scene.output.every,
        |s, e| {
            first.get_or_insert(*e);
            last = Some(*e);
            rotation = rotation.max(crate::checks::largest_rotation(model, s.u, true));
            history.write(s, e)?;
            if let Some(v) = vtk.as_mut() {
                v.write(model, s)?;
            }
            Ok(())
        },
        |step| monitor.progress(step, p.steps),
    )?;
    let step_time = start.elapsed().as_secs_f64();
    let mut warnings = warnings;
    if let Some(w) = crate::checks::rotation_warning(rotation) {
        monitor.info(&format!("warning: {w}"));
        warnings.push(w);
    }
    let reason = match &status {
        Status::Ok => None,
        Status::Diverged { step, t, reason } => Some(format!("step {step}, t = {t:e} s: {reason}")),
    };
    // After a divergence the integrator has rolled back to its last good state.
    output::write_final_state(out, model, cd.t, &cd.u, cd.velocity())?;
    let (first, last) = (first.unwrap_or_default(), last.unwrap_or_default());
    let summary = Summary {
        scene: scene.name.clone(),
        formulation: model.formulation.name().into(),
        evaluator: p.evaluator.kind().name().into(),
        elements: model.elements.len(),
        interfaces: model.interfaces.len(),
        dofs: model.n_free_dofs(),
        dt: p.dt,
        dt_crit: p.dt_crit,
        steps: cd.step,
        t_end: cd.t,
        status: if reason.is_none() { "ok".into() } else { "diverged".into() },
        reason,
        wall_time_s: wall.elapsed().as_secs_f64(),
        step_time_s: step_time,
        threads: rayon::current_num_threads(),
        warnings,
        energy: EnergySummary { initial: first.total, final_: last.total, max_relative_drift: cd.max_relative_drift() },
        contact: cd.contact.as_ref().map(|c| ContactSummary {
            model: c.settings.model.name().into(),
            friction: c.settings.friction,
            mean_pairs: c.stats.pairs as f64 / c.stats.steps.max(1) as f64,
            max_pairs: c.stats.max_pairs,
            tests_per_step: c.stats.tests as f64 / c.stats.steps.max(1) as f64,
            rebuilds: c.stats.rebuilds,
            time_s: c.stats.time_s,
        }),
    };
    output::write_json(&out.join("summary.json"), &summary)?;
    Ok(summary)
}

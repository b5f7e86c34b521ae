//! A whole explicit run, from a scene to its outputs: model, evaluator, `Δt_crit`, the time
//! loop and the files of [`crate::output`]. The command line and the tests call this one function.

pub mod checkpoint;

use crate::analysis::run::checkpoint::Checkpoint;
use crate::force::contact::{self, Contact, WithBlocks};
use crate::error::{Error, Result};
use crate::force::evaluator::{self, Evaluator};
use crate::step::integrator::{CentralDifference, Status};
use crate::model::loads::Loads;
use crate::model::mass::Mass;
use crate::model::{dof_index, Model};
use crate::output::{self, ContactSummary, EnergySummary, History, Probe, ProbeColumn, Summary};
use crate::input::scene::{EvaluatorKind, Scene};
use crate::output::vtk::VtkSeries;
use crate::analysis::{eigen, stability};
use std::path::Path;
use std::time::Instant;

/// The files a run writes into its folder, beside `history.csv` and the frames `vtk/step_*.vtk`.
const OUTPUTS: [&str; 4] = [
    "summary.json",
    "final_state.json",
    "series.pvd",
    crate::analysis::run::checkpoint::FILE,
];

/// Removes what an earlier run left in `out` of the files a run writes (`summary.json`,
/// `final_state.json`, `series.pvd`, `checkpoint.bin`, the frames `vtk/step_*.vtk` and files
/// half written), so that a run that stops early never leaves an earlier run's results beside
/// its own. Other files are left alone; `history.csv` is rewritten from its first line anyway.
fn clear_previous(out: &Path) -> Result<()> {
    for name in OUTPUTS {
        remove(&out.join(name))?;
        remove(&crate::output::temporary(&out.join(name)))?;
    }
    let frames = out.join("vtk");
    let Ok(entries) = std::fs::read_dir(&frames) else {
        return Ok(());
    };
    for entry in entries {
        let path = entry.map_err(|e| Error::io(&frames, e))?.path();
        if crate::output::vtk::is_frame(path.file_name().and_then(|n| n.to_str()).unwrap_or("")) {
            remove(&path)?;
        }
    }
    Ok(())
}

/// Removes `path` if it is there.
fn remove(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::io(path, e)),
        _ => Ok(()),
    }
}

/// Command-line overrides of the scene.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Evaluator, replacing the scene's.
    pub evaluator: Option<EvaluatorKind>,
    /// Time step (s), replacing the scene's `dt` or `dt_factor`.
    pub dt: Option<f64>,
    /// Time step as a fraction of `Δt_crit`, replacing the scene's `dt` or `dt_factor`.
    pub dt_factor: Option<f64>,
    /// Number of steps, replacing the scene's `end` or `steps`.
    pub steps: Option<u64>,
    /// Raised from outside (a signal handler) to stop the run at the next step with a complete
    /// set of outputs (status `interrupted`).
    pub interrupt: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
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
                eigen::omega_max(
                    &model,
                    &WithBlocks {
                        inner: evaluator.as_ref(),
                        nd: model.formulation.ndof(),
                        blocks,
                    },
                    &mass,
                )
            }
        };
        if !omega_max.is_finite() {
            return Err(Error::scene(scene.most_extreme(0, &["E", "rho", "thickness", "penalty"]), format!(
                "the stiffness or mass of the model overflows (ω_max = {omega_max}); check E, rho, thickness, the penalty and the mesh size")));
        }
        let dt_crit = stability::critical_time_step(omega_max);
        let dt = match (opts.dt, scene.time.dt, scene.time.dt_factor) {
            (Some(_), ..) if opts.dt_factor.is_some() => {
                return Err(Error::scene(
                    "--dt-factor",
                    "give --dt or --dt-factor, not both",
                ))
            }
            (Some(dt), _, _) if dt > 0.0 && dt.is_finite() => dt,
            (Some(dt), _, _) => {
                return Err(Error::scene(
                    "--dt",
                    format!("must be a finite number > 0, got {dt}"),
                ))
            }
            (None, ..) if opts.dt_factor.is_some() => match opts.dt_factor {
                Some(f) if !(f > 0.0 && f.is_finite()) => {
                    return Err(Error::scene(
                        "--dt-factor",
                        format!("must be a finite number > 0, got {f}"),
                    ))
                }
                Some(f) if dt_crit.is_finite() => f * dt_crit,
                _ => {
                    return Err(Error::scene(
                        "--dt-factor",
                        "Δt_crit is infinite (no spring is loaded): give --dt instead",
                    ))
                }
            },
            (None, Some(dt), _) => dt,
            (None, None, Some(f)) if dt_crit.is_finite() => f * dt_crit,
            (None, None, _) => {
                return Err(Error::scene(
                    "time.dt_factor",
                    "Δt_crit is infinite (no spring is loaded): give `time.dt` instead",
                ))
            }
        };
        let steps = match (opts.steps, scene.time.steps, scene.time.end) {
            (Some(0), _, _) => {
                return Err(Error::scene("--steps", "must be ≥ 1, like `time.steps`"))
            }
            (Some(n), _, _) => n,
            (None, Some(n), _) => n,
            (None, None, Some(end)) => (end / dt - 1e-9).ceil().max(1.0) as u64,
            (None, None, None) => unreachable!("validated: the scene has `end` or `steps`"),
        };
        Ok(Prepared {
            model,
            evaluator,
            mass,
            loads,
            omega_max,
            dt_crit,
            dt,
            steps,
        })
    }
}

impl Prepared {
    /// A central-difference integrator of the model at time step `dt`, with the guard told
    /// `Δt_crit`.
    pub fn integrator(&self, dt: f64) -> CentralDifference<'_> {
        let mut cd = CentralDifference::new(
            &self.model,
            self.evaluator.as_ref(),
            &self.mass,
            &self.loads,
            dt,
        );
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
            let d = dof_index(
                &pr.dof,
                model.formulation,
                &format!("output.probes[{k}].dof"),
            )?;
            let element = model.probe_element(k, pr)?;
            let offset = pr.at.map(|[x, y]| {
                crate::mesh::geometry::Vec2::new(x, y) - model.elements[element].props.centroid
            });
            Ok(Probe {
                name: pr.column(),
                element,
                dof: d,
                nd,
                offset,
                formulation: model.formulation,
            })
        })
        .collect()
}

/// Runs `scene` and writes its outputs into `out`; returns the summary (also written).
pub fn run(
    scene: &Scene,
    opts: &RunOptions,
    out: &Path,
    monitor: &mut dyn Monitor,
) -> Result<Summary> {
    execute(scene, opts, out, monitor, false)
}

/// Goes on with the run of `scene` that stopped in `out`, from its last checkpoint
/// (`output.checkpoint_every`); the outputs end as those of a run that never stopped.
pub fn resume(
    scene: &Scene,
    opts: &RunOptions,
    out: &Path,
    monitor: &mut dyn Monitor,
) -> Result<Summary> {
    execute(scene, opts, out, monitor, true)
}

fn execute(
    scene: &Scene,
    opts: &RunOptions,
    out: &Path,
    monitor: &mut dyn Monitor,
    resuming: bool,
) -> Result<Summary> {
    let wall = Instant::now();
    let p = Prepared::new(scene, opts)?;
    let model = &p.model;
    let checkpoint = if resuming {
        let c = Checkpoint::read(out, scene, opts)?;
        // The summary and final state of the stopped run end at another step; files it was
        // writing when killed are half written.
        for name in ["summary.json", "final_state.json"] {
            remove(&out.join(name))?;
        }
        for name in OUTPUTS {
            remove(&crate::output::temporary(&out.join(name)))?;
        }
        Some(c)
    } else {
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
        clear_previous(out)?;
        None
    };
    let ground_springs = model
        .interfaces
        .iter()
        .filter(|i| i.b == crate::model::GROUND)
        .count();
    monitor.info(&format!(
        "{}: {} elements, {} interfaces between elements and {} ground springs, {} free DOFs ({} formulation, {} evaluator, {} threads)",
        model.name,
        model.elements.len(),
        model.interfaces.len() - ground_springs,
        ground_springs,
        model.n_free_dofs(),
        model.formulation.name(),
        p.evaluator.kind().name(),
        rayon::current_num_threads()
    ));
    let ratio = p.dt / p.dt_crit;
    monitor.info(&format!(
        "dt = {:.6e} s, Δt_crit = {:.6e} s, dt/Δt_crit = {ratio:.4}, {} steps",
        p.dt, p.dt_crit, p.steps
    ));
    let mut warnings = crate::model::checks::warnings(model, p.dt, p.dt_crit);
    for w in &warnings {
        monitor.info(&format!("warning: {w}"));
    }
    let probes = probes(scene, model)?;
    let probe_columns: Vec<ProbeColumn> = probes
        .iter()
        .map(|p| ProbeColumn {
            name: p.name.clone(),
            unit: p.unit().into(),
        })
        .collect();
    let mut cd = p.integrator(p.dt);
    let (mut history, mut vtk, mut first, mut rotation) = match checkpoint {
        None => (
            History::create(out, probes)?,
            scene
                .output
                .vtk
                .then(|| VtkSeries::create(out))
                .transpose()?,
            None,
            0.0f64,
        ),
        Some(c) => {
            monitor.info(&format!(
                "resuming from the checkpoint at step {}",
                c.state.step()
            ));
            cd.restore(c.state).map_err(|why| {
                Error::io(
                    out.join(crate::analysis::run::checkpoint::FILE),
                    std::io::Error::other(why),
                )
            })?;
            let vtk = scene
                .output
                .vtk
                .then(|| VtkSeries::resume(out, c.frames))
                .transpose()?;
            (
                History::resume(out, probes, c.history_bytes)?,
                vtk,
                c.first,
                c.rotation,
            )
        }
    };
    if let Some(flag) = &opts.interrupt {
        cd.stop_on(flag.clone());
    }
    let (end, every) = (p.steps, scene.output.every);
    let interrupted = || {
        opts.interrupt
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
    };
    let mut last = None;
    let start = Instant::now();
    // In chunks that end at the checkpoints; a chunk's end is recorded only when it is a
    // history row's step, the last step or the step where the run was interrupted.
    let status = loop {
        let step = cd.step;
        let next = scene
            .output
            .checkpoint_every
            .map_or(end, |c| ((step / c + 1) * c).min(end));
        let status = cd.run(
            next - step,
            every,
            |s, e| {
                if !(s.step % every == 0 || s.step == end || interrupted()) {
                    return Ok(());
                }
                first.get_or_insert(*e);
                last = Some(*e);
                rotation = rotation.max(crate::model::checks::largest_rotation(model, s.u, true));
                history.write(s, e)?;
                if let Some(v) = vtk.as_mut() {
                    v.write(model, s)?;
                }
                Ok(())
            },
            |step| monitor.progress(step, p.steps),
        )?;
        if status != Status::Ok || next == end {
            break status;
        }
        let frames = vtk.as_ref().map_or_else(Vec::new, |v| v.frames().to_vec());
        Checkpoint::new(
            scene,
            opts,
            cd.state(),
            history.len(),
            frames,
            first,
            rotation,
        )
        .write(out)?;
    };
    let step_time = start.elapsed().as_secs_f64();
    if let Some(w) = crate::model::checks::rotation_warning(rotation) {
        monitor.info(&format!("warning: {w}"));
        warnings.push(w);
    }
    let (status_name, reason) = match &status {
        Status::Ok => ("ok", None),
        Status::Interrupted { step, t } => (
            "interrupted",
            Some(format!(
                "step {step}, t = {t:e} s: interrupted by a signal{}",
                if scene.output.checkpoint_every.is_some() {
                    "; `rbsm run SCENE --resume DIR` goes on from the last checkpoint"
                } else {
                    ""
                }
            )),
        ),
        Status::Diverged { step, t, reason } => (
            "diverged",
            Some(format!("step {step}, t = {t:e} s: {reason}")),
        ),
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
        status: status_name.into(),
        reason,
        wall_time_s: wall.elapsed().as_secs_f64(),
        step_time_s: step_time,
        threads: rayon::current_num_threads(),
        warnings,
        energy: EnergySummary {
            initial: first.total,
            final_: last.total,
            max_relative_drift: cd.max_relative_drift(),
        },
        contact: cd.contact.as_ref().map(|c| ContactSummary {
            model: c.settings.model.name().into(),
            friction: c.settings.friction,
            mean_pairs: c.stats.pairs as f64 / c.stats.steps.max(1) as f64,
            max_pairs: c.stats.max_pairs,
            tests_per_step: c.stats.tests as f64 / c.stats.steps.max(1) as f64,
            rebuilds: c.stats.rebuilds,
            time_s: c.stats.time_s,
        }),
        probes: probe_columns,
    };
    output::write_json(&out.join("summary.json"), &summary)?;
    if status == Status::Ok {
        // A finished run has nothing to resume.
        remove(&out.join(crate::analysis::run::checkpoint::FILE))?;
    }
    Ok(summary)
}

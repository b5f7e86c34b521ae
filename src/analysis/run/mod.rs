//! A whole explicit run of a [`Setup`], to its outputs: the time loop and the files of
//! [`crate::output`]. The command line and the tests call this one function.

pub mod checkpoint;

use crate::analysis::run::checkpoint::Checkpoint;
use crate::analysis::setup::Setup;
use crate::error::{Error, Result};
use crate::input::scene::Scene;
use crate::model::Model;
use crate::output::vtk::VtkSeries;
use crate::output::{
    self, count, BalanceSummary, ClampSummary, Columns, ContactSummary, EnergySummary,
    FailureSummary, History, ProbeColumn, Summary,
};
use crate::step::integrator::{CentralDifference, Energy, RunStatus, Snapshot, Status};
use std::path::Path;
use std::time::Instant;

/// The files a run writes into its folder, beside `history.csv`, the frames `vtk/step_*.vtu`
/// and the cracks `cracks/step_*.vtu`.
const OUTPUTS: [&str; 5] = [
    "summary.json",
    "final_state.json",
    "series.pvd",
    crate::output::vtk::CRACKS.1,
    crate::analysis::run::checkpoint::FILE,
];

/// Removes what an earlier run left in `out` of the files a run writes (`summary.json`,
/// `final_state.json`, `series.pvd`, `cracks.pvd`, `checkpoint.bin`, the frames
/// `vtk/step_*.vtu`, `cracks/step_*.vtu`, the folders they leave empty and files half
/// written) and of the pictures `rbsm plot` drew from its history, so that a run that stops
/// early never leaves an earlier run's results beside its own. Other files are left alone;
/// `history.csv` is rewritten from its first line anyway.
fn clear_previous(out: &Path) -> Result<()> {
    for name in OUTPUTS.iter().chain(&crate::output::plot::RUN_PLOTS) {
        remove(&out.join(name))?;
        remove(&crate::output::temporary(&out.join(name)))?;
    }
    for folder in ["vtk", crate::output::vtk::CRACKS.0] {
        let frames = out.join(folder);
        let Ok(entries) = std::fs::read_dir(&frames) else {
            continue;
        };
        for entry in entries {
            let path = entry.map_err(|e| Error::io(&frames, e))?.path();
            if crate::output::vtk::is_frame(path.file_name().and_then(|n| n.to_str()).unwrap_or(""))
            {
                remove(&path)?;
            }
        }
        // Only an empty folder goes; one that holds the user's files stays.
        let _ = std::fs::remove_dir(&frames);
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

/// What a run does besides stepping: where it writes, whether it goes on from a checkpoint,
/// and the flag that stops it.
#[derive(Debug, Clone, Default)]
pub struct RunParams {
    /// Go on from the last checkpoint (`output.checkpoint_every`) of the run that stopped in the
    /// output folder; the outputs end as those of a run that never stopped.
    pub resume: bool,
    /// Raised from outside (a signal handler) to stop the run at the next step with a complete
    /// set of outputs (status `interrupted`).
    pub interrupt: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// Keep the history's rows in memory ([`Outcome::history`]) when they are written to a
    /// folder too; a run without a folder always keeps them.
    pub keep_history: bool,
}

/// What a run ends with, in memory: its summary, its history and its final state.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The summary (`summary.json` when the run has a folder).
    pub summary: Summary,
    /// The history's column names (the header of `history.csv`).
    pub columns: Vec<String>,
    /// The history's rows, one after the other (`columns.len()` values each); empty when the
    /// run wrote them to a folder without [`RunParams::keep_history`].
    pub history: Vec<f64>,
    /// Time reached (s).
    pub t: f64,
    /// The final displacements `U`, `ndof` per element.
    pub u: Vec<f64>,
    /// The final velocities `V` (at `t`), `ndof` per element.
    pub v: Vec<f64>,
    /// The failing interfaces' state at the end; `None` when no interface can fail.
    pub interfaces: Option<Vec<crate::force::failure::InterfaceFailure>>,
}

impl Outcome {
    /// The last row's value in the first column whose name ends with `suffix` (`"_force"`: the
    /// first moving clamp's reaction); `None` without such a column or rows.
    pub fn last(&self, suffix: &str) -> Option<f64> {
        self.series(suffix)?.last()
    }

    /// The values, row by row, of the first column whose name ends with `suffix` (`"t"`: the
    /// time, the first column); `None` without such a column.
    pub fn series(&self, suffix: &str) -> Option<impl Iterator<Item = f64> + '_> {
        let k = self.columns.iter().position(|c| c.ends_with(suffix))?;
        Some(
            self.history
                .chunks_exact(self.columns.len())
                .map(move |row| row[k]),
        )
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

/// Runs the setup's scene and writes its outputs into `out`; returns the summary (also written).
///
/// # Errors
/// As [`simulate`] with a folder.
pub fn run(
    setup: &Setup,
    params: &RunParams,
    out: &Path,
    monitor: &mut dyn Monitor,
) -> Result<Summary> {
    simulate(setup, params, Some(out), monitor).map(|o| o.summary)
}

/// Runs the setup's scene; with a folder `out`, writes its outputs there as [`run`] does;
/// without, writes nothing and keeps the history in memory. Returns what the run ends with.
///
/// # Errors
/// A probe of the scene names an element outside the model, a point `at` in no element or a DOF the
/// formulation does not have; with `out`, the folder cannot be created, cleared of an earlier run's
/// outputs or written; with [`RunParams::resume`], there is no `out`, or its checkpoint is missing,
/// damaged or of another scene or options ([`Checkpoint::read`]), or its `history.csv` is shorter
/// than the checkpoint counts. A run that diverges or is interrupted is no error: its
/// [`Summary::status`] says so.
pub fn simulate(
    setup: &Setup,
    params: &RunParams,
    out: Option<&Path>,
    monitor: &mut dyn Monitor,
) -> Result<Outcome> {
    let wall = Instant::now();
    if params.resume && out.is_none() {
        return Err(Error::scene(
            "resume",
            "a run resumes from the checkpoint in its output folder: give the folder",
        ));
    }
    let (p, scene) = (setup, &setup.scene);
    let model = &p.model;
    let checkpoint = prepare_folder(setup, params, out)?;
    let mut warnings = announce(setup, monitor);
    let probes = p.probes()?;
    let probe_columns: Vec<ProbeColumn> = probes
        .iter()
        .map(|p| ProbeColumn {
            name: p.name.clone(),
            unit: p.unit().into(),
        })
        .collect();
    let mut cd = p.integrator(p.dt);
    let columns = Columns::of(model, probes);
    let mut rec = open_outputs(setup, params, out, checkpoint, columns, &mut cd, monitor)?;
    let start = Instant::now();
    let status = step_through(setup, params, out, &mut cd, &mut rec, monitor)?;
    let step_time = start.elapsed().as_secs_f64();
    if let Some(w) = crate::model::checks::rotation_warning(rec.rotation) {
        monitor.info(&format!("warning: {w}"));
        warnings.push(w);
    }
    let reason = reason(&status, scene, out);
    // After a divergence the integrator has rolled back to its last good state.
    let failure = p
        .plastic
        .as_ref()
        .zip(cd.failure())
        .map(|(plastic, state)| {
            let report = plastic.report(state);
            (
                FailureSummary::of(&report, plastic.dissipated(state)),
                report,
            )
        });
    let v = cd.velocity().to_vec();
    if let Some(out) = out {
        output::write_final_state(
            out,
            model,
            cd.t,
            &cd.u,
            &v,
            failure.as_ref().map(|(_, r)| &r[..]),
            &p.yielding
                .as_ref()
                .zip(cd.plastic_elements())
                .map(|(y, s)| y.per_element(s, model.elements.len()))
                .unwrap_or_default(),
        )?;
    }
    let (first, last) = (rec.first.unwrap_or_default(), rec.last.unwrap_or_default());
    let summary = Summary {
        scene: scene.name.clone(),
        formulation: model.formulation.name().into(),
        evaluator: p.evaluator.kind().name().into(),
        elements: model.elements.len(),
        interfaces: model.interfaces.len() - model.ground_springs(),
        ground_springs: model.ground_springs(),
        dofs: model.n_free_dofs(),
        dt: p.dt,
        dt_crit: p.limit.dt_crit(),
        dt_safe: p.limit.dt_safe(),
        steps: cd.step,
        t_end: cd.t,
        status: status.kind(),
        reason,
        wall_time_s: p.seconds + wall.elapsed().as_secs_f64(),
        setup_time_s: p.seconds,
        step_time_s: step_time,
        threads: rayon::current_num_threads(),
        warnings,
        energy: EnergySummary {
            initial: first.total,
            final_: last.total,
            max_relative_drift: cd.max_relative_drift(),
        },
        contact: cd.contact.as_ref().map(contact_summary),
        probes: probe_columns,
        failure: failure.as_ref().map(|(s, _)| s.clone()),
        clamps: model
            .prescribed
            .iter()
            .zip(&rec.peaks)
            .map(|(c, &(peak_force, displacement_at_peak))| ClampSummary {
                name: c.name.clone(),
                peak_force,
                displacement_at_peak,
            })
            .collect(),
        balance: cd.unbalanced_ratio().map(|ratio| BalanceSummary {
            ratio,
            settled_at_step: cd.settled().map(|(step, _)| step),
        }),
        dir: out.map(Path::to_path_buf).unwrap_or_default(),
    };
    if let Some(out) = out {
        output::write_json(&out.join("summary.json"), &summary)?;
        if status == Status::Ok {
            // A finished run has nothing to resume.
            remove(&out.join(crate::analysis::run::checkpoint::FILE))?;
        }
    }
    Ok(Outcome {
        summary,
        columns: rec.history.header(),
        history: rec.history.into_rows(),
        t: cd.t,
        u: std::mem::take(&mut cd.u),
        v,
        interfaces: failure.map(|(_, r)| r),
    })
}

impl crate::analysis::Report for Summary {
    fn text(&self) -> String {
        match &self.reason {
            Some(reason) => {
                let state = if self.status == RunStatus::Diverged {
                    "the last state that passed the guard"
                } else {
                    "the step reached"
                };
                format!(
                    "{}: {} at {reason}\n  the outputs in {} hold the run up to {state}: step {} \
                        (t = {:.6e} s)",
                    self.scene,
                    self.status,
                    self.dir.display(),
                    self.steps,
                    self.t_end
                )
            }
            None => format!(
                "{}: ok, {} (t = {:.6e} s) in {:.3} s; energy drift {:.3e} of the energy \
                    put in;{} outputs in {}",
                self.scene,
                count(self.steps as usize, "step", "steps"),
                self.t_end,
                self.wall_time_s,
                self.energy.max_relative_drift,
                match &self.balance {
                    Some(BalanceSummary {
                        ratio,
                        settled_at_step: Some(_),
                    }) => format!(" settled: unbalanced-force ratio {ratio:.3e};"),
                    Some(BalanceSummary { ratio, .. }) => {
                        format!(" unbalanced-force ratio {ratio:.3e}, not settled;")
                    }
                    None => String::new(),
                },
                self.dir.display()
            ),
        }
    }
}

/// Readies the output folder: with `params.resume`, reads its checkpoint and removes what the
/// stopped run left half done; else creates it and clears a previous run's outputs.
fn prepare_folder(
    setup: &Setup,
    params: &RunParams,
    out: Option<&Path>,
) -> Result<Option<Checkpoint>> {
    let Some(out) = out else {
        return Ok(None);
    };
    if out.exists() && !out.is_dir() {
        return Err(Error::scene(
            "--out",
            format!(
                "`{}` is a file: name a folder (new or a run's) for the outputs",
                out.display()
            ),
        ));
    }
    if !params.resume {
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
        clear_previous(out)?;
        return Ok(None);
    }
    let c = Checkpoint::read(out, &setup.scene, &setup.overrides)?;
    // The summary and final state of the stopped run end at another step; files it was
    // writing when killed are half written.
    for name in ["summary.json", "final_state.json"] {
        remove(&out.join(name))?;
    }
    for name in OUTPUTS {
        remove(&crate::output::temporary(&out.join(name)))?;
    }
    Ok(Some(c))
}

/// Tells the monitor what the run models and how it steps, with the setup's warnings; returns
/// the warnings.
fn announce(setup: &Setup, monitor: &mut dyn Monitor) -> Vec<String> {
    let (p, model) = (setup, &setup.model);
    let ground_springs = model.ground_springs();
    monitor.info(&format!(
        "{}: {}, {} between elements and {}, {} ({} formulation, {} evaluator, {})",
        model.name,
        count(model.elements.len(), "element", "elements"),
        count(
            model.interfaces.len() - ground_springs,
            "interface",
            "interfaces"
        ),
        count(ground_springs, "ground spring", "ground springs"),
        count(model.n_free_dofs(), "free DOF", "free DOFs"),
        model.formulation.name(),
        p.evaluator.kind().name(),
        count(rayon::current_num_threads(), "thread", "threads")
    ));
    monitor.info(&format!(
        "{}, {}",
        p.limit.describe(p.dt),
        count(p.steps as usize, "step", "steps")
    ));
    let warnings = p.warnings();
    for w in &warnings {
        monitor.info(&format!("warning: {w}"));
    }
    warnings
}

/// What a run records at its recorded steps: the history, the VTK series, the first and last
/// energies, the largest rotation, and each moving clamp's peak reaction over every step with
/// its displacement there.
struct Recorder<'s> {
    history: History,
    vtk: Option<VtkSeries<'s>>,
    first: Option<Energy>,
    last: Option<Energy>,
    rotation: f64,
    peaks: Vec<(f64, f64)>,
}

impl Recorder<'_> {
    /// Records the state `s` with its energies `e`.
    fn record(&mut self, model: &Model, s: &Snapshot, e: &Energy) -> Result<()> {
        self.first.get_or_insert(*e);
        self.last = Some(*e);
        self.rotation = self
            .rotation
            .max(crate::model::checks::largest_rotation(model, s.u, true));
        self.history.write(s, e)?;
        for ((peak, at), (c, &[r, t])) in self
            .peaks
            .iter_mut()
            .zip(model.prescribed.iter().zip(s.peaks))
        {
            (*peak, *at) = (r, c.velocity.norm() * c.travel(t));
        }
        if let Some(v) = self.vtk.as_mut() {
            v.write(model, s)?;
        }
        Ok(())
    }
}

/// The contact's part of the summary.
fn contact_summary(c: &crate::force::contact::Contact) -> ContactSummary {
    ContactSummary {
        model: c.settings.model.name().into(),
        friction: c.settings.friction,
        mean_pairs: c.stats.pairs as f64 / c.stats.steps.max(1) as f64,
        max_pairs: c.stats.max_pairs,
        tests_per_step: c.stats.tests as f64 / c.stats.steps.max(1) as f64,
        rebuilds: c.stats.rebuilds,
        time_s: c.stats.time_s,
    }
}

/// The recorder of a run: new outputs, or those of the checkpoint `checkpoint` with the
/// integrator restored to it.
fn open_outputs<'s>(
    setup: &'s Setup,
    params: &RunParams,
    out: Option<&Path>,
    checkpoint: Option<Checkpoint>,
    columns: Columns,
    cd: &mut CentralDifference<'_>,
    monitor: &mut dyn Monitor,
) -> Result<Recorder<'s>> {
    let (p, scene) = (setup, &setup.scene);
    let keep = params.keep_history;
    let peaks = vec![(f64::NEG_INFINITY, 0.0); setup.model.prescribed.len()];
    let (history, vtk, first, rotation) = match (checkpoint, out) {
        (None, None) => (History::memory(columns), None, None, 0.0f64),
        (None, Some(out)) => (
            History::create(out, columns, keep)?,
            scene
                .output
                .vtk
                .then(|| VtkSeries::create(out, p.plastic.as_deref(), p.yielding.as_ref()))
                .transpose()?,
            None,
            0.0f64,
        ),
        (Some(_), None) => unreachable!("refused above: a resumed run has a folder"),
        (Some(c), Some(out)) => {
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
                .then(|| {
                    VtkSeries::resume(out, c.frames, p.plastic.as_deref(), p.yielding.as_ref())
                })
                .transpose()?;
            (
                History::resume(out, columns, c.history_bytes, keep)?,
                vtk,
                c.first,
                c.rotation,
            )
        }
    };
    Ok(Recorder {
        history,
        vtk,
        first,
        last: None,
        rotation,
        peaks,
    })
}

/// Why the run stopped early, for the summary: `None` for a run that took every step.
fn reason(status: &Status, scene: &Scene, out: Option<&Path>) -> Option<String> {
    match status {
        Status::Ok => None,
        Status::Interrupted { step, t } => Some(format!(
            "step {step}, t = {t:e} s: interrupted by a signal{}",
            if scene.output.checkpoint_every.is_some() && out.is_some() {
                "; `rbsm run SCENE --resume DIR` goes on from the last checkpoint"
            } else {
                ""
            }
        )),
        Status::Diverged { step, t, reason } => Some(format!("step {step}, t = {t:e} s: {reason}")),
    }
}

/// Steps the run to its end (or its stop), recording at the steps the output asks for and
/// writing a checkpoint at the end of each chunk (`output.checkpoint_every`); returns how it
/// ended.
fn step_through(
    setup: &Setup,
    params: &RunParams,
    out: Option<&Path>,
    cd: &mut CentralDifference<'_>,
    rec: &mut Recorder<'_>,
    monitor: &mut dyn Monitor,
) -> Result<Status> {
    let (p, scene, opts, model) = (setup, &setup.scene, &setup.overrides, &setup.model);
    if let Some(flag) = &params.interrupt {
        cd.stop_on(flag.clone());
    }
    let (end, every) = (p.steps, scene.output.every);
    let interrupted = || {
        params
            .interrupt
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
    };
    // In chunks that end at the checkpoints; a chunk's end is recorded only when it is a
    // history row's step, the last step or the step where the run was interrupted.
    loop {
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
                rec.record(model, s, e)
            },
            |step| monitor.progress(step, p.steps),
        )?;
        if status != Status::Ok || next == end || cd.settled().is_some() {
            return Ok(status);
        }
        let Some(out) = out else {
            continue;
        };
        let frames = rec
            .vtk
            .as_ref()
            .map_or_else(Vec::new, |v| v.frames().to_vec());
        Checkpoint::new(
            scene,
            opts,
            cd.state(),
            rec.history.bytes(),
            frames,
            rec.first,
            rec.rotation,
        )
        .write(out)?;
    }
}

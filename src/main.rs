//! The `rbsm` command line: a thin layer over the library.

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rbsm::analysis::run::{self, Monitor};
use rbsm::analysis::setup::{Overrides, Setup};
use rbsm::analysis::{check, effective, eigen, stability, statics, tradeoff, Report};
use rbsm::input::names::Named;
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::step::integrator::RunStatus;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// A parser of the library's names of `T` (`--evaluator`, `--method`), each listed with its
/// help in `--help` and in the error that refuses another.
fn named<T: Named + Send + Sync>() -> impl clap::builder::TypedValueParser<Value = T> {
    use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
    let values = T::ALL.iter().map(|v| {
        // clap's style: help without its final full stop.
        PossibleValue::new(v.name()).help(v.help().trim_end_matches('.'))
    });
    PossibleValuesParser::new(values).try_map(|name| T::from_name(&name))
}

#[derive(Parser)]
#[command(
    name = "rbsm",
    version,
    about = "Rigid-Bodies-Spring Model in 2D with explicit dynamics"
)]
struct Cli {
    /// Worker threads (default, or 0: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    /// No progress bar and no information lines on standard error.
    #[arg(long, global = true)]
    quiet: bool,
    /// Print the result as JSON on standard output.
    #[arg(long, global = true)]
    json: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene with explicit central difference; writes summary.json, history.csv,
    /// final_state.json (and VTK frames when the scene asks) into DIR.
    Run(RunArgs),
    /// Validate a scene without running it and print what it would model: elements,
    /// interfaces, DOFs, supports, loads, contact, Δt_crit, the time step and the memory.
    /// Exit code 0 for a valid scene, 1 for an invalid one, 4 for a valid scene whose time
    /// step is above Δt_crit (a run would diverge).
    Check {
        /// The scene file (JSON; see docs/scene.md).
        scene: PathBuf,
        /// Override the scene's evaluator.
        #[arg(long, value_parser = named::<EvaluatorKind>())]
        evaluator: Option<EvaluatorKind>,
        /// Override the time step (s).
        #[arg(long)]
        dt: Option<f64>,
    },
    /// The collapse load of the scene's discrete model by conic programming (limit analysis; a
    /// linear program where no element has a strength).
    Limit {
        /// Scene file.
        scene: PathBuf,
        /// What grows until collapse: `loads` (gravity held), `gravity` (loads held) or
        /// `clamps` (the moving clamp's reaction); the scene's clamp, else its loads, else its
        /// gravity when absent.
        #[arg(long, value_parser = ["loads", "gravity", "clamps"])]
        on: Option<String>,
        /// Where the interface strengths are checked: `gauss` (the explicit law's two Gauss
        /// points, the model `rbsm run` steps) or `ends` (each interface's end points, where a
        /// linear traction is extreme, as finite-element limit analysis checks it).
        #[arg(long, default_value = "gauss", value_parser = ["gauss", "ends"])]
        points: String,
        /// Write `summary.json`, the mechanism (`mechanism.vtu`, `mechanism.svg`) and the
        /// tractions at collapse (`tractions.csv`) here.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Static solution K_ff U_f = P_f (sparse Cholesky); loads at their full value.
    Static {
        /// Write summary.json, final_state.json, probes.csv and static.vtu with series.pvd
        /// into this directory.
        #[arg(long)]
        out: Option<PathBuf>,
        /// The scene file (JSON; see docs/scene.md).
        scene: PathBuf,
    },
    /// Effective elastic constants of the scene's mesh and formulation: the body in three
    /// uniform strains (its outline on the affine field), C, the isotropic E and ν, and the
    /// scatter of the element stresses; its supports and loads are ignored.
    Effective {
        /// The scene file (JSON; see docs/scene.md).
        scene: PathBuf,
    },
    /// Calibrate the facet law of a Voronoi material: the facet parameters that give the
    /// targets' E, ν, f_t, G_F and f_c on tension bars and compression prisms of every cell
    /// size and seed (docs/calibrate.md). The specimen runs of a round share the cores.
    Calibrate {
        /// The calibration file (JSON; see docs/calibrate.md).
        spec: PathBuf,
        /// Write the calibrated material block, `{"<name>": {...}}`, to this file (JSON), for
        /// a scene's `materials`.
        #[arg(long)]
        material: Option<PathBuf>,
    },
    /// Lowest modes and ω_max of K φ = ω² M φ.
    Eigen {
        /// The scene file (JSON; see docs/scene.md).
        scene: PathBuf,
        /// Number of lowest modes (0: ω_max and Δt_crit alone).
        #[arg(long, default_value_t = 10)]
        modes: usize,
        /// Dense (all modes) or sparse (Krylov–Schur) solver.
        #[arg(long, value_parser = named::<eigen::Method>(), default_value_t = eigen::Method::Auto)]
        method: eigen::Method,
        /// Write the mode shapes as VTK into this directory.
        #[arg(long)]
        vtk: Option<PathBuf>,
        /// Draw the mode shapes as SVG (deformed mesh over the reference) into this directory.
        #[arg(long)]
        svg: Option<PathBuf>,
        /// Write summary.json, probes.csv and the shapes as mode_NNN.vtu with modes.pvd into
        /// this directory.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Draw a scene's model as SVG: elements, interface springs, supports, loads, ground; or,
    /// with --state, a run's final state with its cracks.
    Draw {
        /// The scene file (JSON; see docs/scene.md).
        scene: PathBuf,
        /// The SVG file to write.
        #[arg(long)]
        out: PathBuf,
        /// Draw the final state of the run in DIR (DIR/final_state.json, of this scene):
        /// the deformed elements, broken interfaces as thick red lines, yielding ones orange.
        #[arg(long, value_name = "DIR")]
        state: Option<PathBuf>,
    },
    /// Draw the histories a run left in DIR as SVG beside them: energies.svg and probes.svg
    /// from history.csv (rbsm run), stability.svg from fraction_F.csv (rbsm stability --out).
    Plot {
        /// The folder a run (`rbsm run --out`) or a stability analysis (`rbsm stability --out`)
        /// wrote into.
        dir: PathBuf,
    },
    /// Exact Δt_crit, cheap bounds, the empirical limit and runs at fractions of Δt_crit.
    Stability {
        /// The scene file (JSON; see docs/scene.md).
        scene: PathBuf,
        /// Fractions of Δt_crit to run at.
        #[arg(long, value_delimiter = ',', default_value = "0.9,0.99,1.01")]
        fractions: Vec<f64>,
        /// Steps of each run (bisection and fractions).
        #[arg(long, default_value_t = 2000)]
        steps: u64,
        /// Write the energy history of each fraction run as CSV into this directory.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Speed against accuracy: runs the scene at every combination of the sweeps and writes
    /// tradeoff.csv, tradeoff.md and tradeoff.svg (error against wall time, Pareto front).
    Tradeoff {
        /// The scene file (JSON; see docs/scene.md).
        scene: PathBuf,
        /// KEY=V1,V2,... with KEY one of dt, dt_factor, refine, formulation, penalty, evaluator,
        /// contact, seed; repeat for a product of sweeps.
        #[arg(long = "sweep", required = true)]
        sweeps: Vec<String>,
        /// Output directory (default: out/tradeoff-<scene name>, the name's characters other
        /// than ASCII letters, digits, `-` and `_` made `_`).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Print the JSON Schema of scene files on standard output (docs/scene.md describes every
    /// key); an editor given it checks and completes scenes. It is JSON already: `--json` is
    /// refused.
    Schema,
}

/// The options of `rbsm run`.
#[derive(clap::Args)]
struct RunArgs {
    /// The scene file (JSON).
    scene: PathBuf,
    /// Output directory (created if missing); its earlier run outputs are removed first.
    #[arg(long, required_unless_present = "resume", conflicts_with = "resume")]
    out: Option<PathBuf>,
    /// Go on with the run that stopped in DIR from its last checkpoint
    /// (`output.checkpoint_every`); give the scene and options it was started with.
    #[arg(long, value_name = "DIR")]
    resume: Option<PathBuf>,
    /// Override the scene's evaluator.
    #[arg(long, value_parser = named::<EvaluatorKind>())]
    evaluator: Option<EvaluatorKind>,
    /// Override the time step (s).
    #[arg(long, conflicts_with = "dt_factor")]
    dt: Option<f64>,
    /// Override the time step as a fraction of Δt_crit.
    #[arg(long)]
    dt_factor: Option<f64>,
    /// Override the number of steps.
    #[arg(long)]
    steps: Option<u64>,
    /// Compute Δt_crit to full precision (Lanczos) even when the time step does not need
    /// it: with --dt or a scene `dt` none is computed, and the step is checked against a
    /// proven-safe bound; with a `dt_factor` it is computed to about four digits.
    #[arg(long)]
    exact_dt_crit: bool,
}

/// Information lines and a progress bar on standard error; the bar appears only on a terminal,
/// and only once a run has lasted two seconds.
struct Terminal {
    quiet: bool,
    bar: Option<ProgressBar>,
    start: Instant,
}

impl Monitor for Terminal {
    fn info(&mut self, line: &str) {
        if !self.quiet {
            tell(line);
        }
    }
    fn progress(&mut self, step: u64, total: u64) {
        if self.quiet || !std::io::stderr().is_terminal() {
            return;
        }
        if self.bar.is_none() && self.start.elapsed() > Duration::from_secs(2) {
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr())
                .with_elapsed(self.start.elapsed());
            bar.set_style(
                ProgressStyle::with_template(
                    "{bar:40} {pos}/{len} steps, {elapsed} elapsed, eta {eta}",
                )
                .expect("valid template"),
            );
            // The bar appears late: its rate is measured from here, not from a jump of `step`
            // steps in no time (which showed an ETA of 0 s).
            bar.set_position(step);
            bar.reset_eta();
            self.bar = Some(bar);
        }
        if let Some(bar) = &self.bar {
            bar.set_position(step);
        }
    }
}

/// A flag raised by the first SIGINT, SIGTERM or SIGHUP: the run then finishes its step and
/// writes complete outputs. A second such signal ends the process at once (exit code 130).
/// SIGXFSZ is caught too, so that a file-size limit is a write error, not a crash.
fn interrupt_flag() -> rbsm::error::Result<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM, SIGXFSZ};
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let fail = |e: std::io::Error| rbsm::error::Error::io("signal handler", e);
    for signal in [SIGINT, SIGTERM, SIGHUP] {
        signal_hook::flag::register_conditional_shutdown(signal, 130, flag.clone())
            .map_err(fail)?;
        signal_hook::flag::register(signal, flag.clone()).map_err(fail)?;
    }
    signal_hook::flag::register(
        SIGXFSZ,
        std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false)),
    )
    .map_err(fail)?;
    Ok(flag)
}

/// glibc's `mallopt` parameter for the most malloc arenas (`malloc.h`).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const M_ARENA_MAX: std::ffi::c_int = -8;

#[cfg(all(target_os = "linux", target_env = "gnu"))]
extern "C" {
    fn mallopt(param: std::ffi::c_int, value: std::ffi::c_int) -> std::ffi::c_int;
}

/// Keeps every thread on glibc's one main arena. By default each thread that allocates gets an
/// arena of its own, up to eight per core, and each reserves 64 MiB of address space however
/// little it holds: 4 GiB on 64 threads with a model of 30 MB, so that
/// `ulimit -v` killed runs that fit. The steps allocate nothing, so only the setup's parallel
/// loops could gain from more arenas; on 2 and 8 threads one arena was as fast.
fn bound_malloc_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: `mallopt` is glibc's, called before any thread is started; it only sets a
        // limit that later arena creation reads, and returns 0 where it refuses.
        if unsafe { mallopt(M_ARENA_MAX, 1) } == 1 {
            rbsm::model::memory::arenas_bounded(1);
        }
    }
}

fn main() -> ExitCode {
    bound_malloc_arenas();
    let cli = Cli::parse();
    if cli.json && matches!(cli.command, Command::Schema) {
        use clap::CommandFactory;
        Cli::command()
            .error(
                clap::error::ErrorKind::ArgumentConflict,
                "`--json` does not apply to `schema`: the schema is JSON already",
            )
            .exit();
    }
    if let Some(n) = cli.threads {
        let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
        if n > MAX_THREADS_PER_CORE * cores {
            tell(&format!(
                "error: --threads: at most {} ({MAX_THREADS_PER_CORE} × the {cores} cores of this \
                 machine; 0 takes all cores), got {n}",
                MAX_THREADS_PER_CORE * cores
            ));
            return ExitCode::from(2);
        }
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            tell(&format!("error: --threads: {e}"));
            return ExitCode::from(2);
        }
    }
    match execute(&cli) {
        Ok(code) => code,
        Err(e) => {
            if cli.json {
                // Best effort: standard output may be what failed.
                let _ =
                    say(&serde_json::to_string_pretty(&error_json(&e)).expect("errors serialise"));
            }
            tell(&format!("error: {e}"));
            ExitCode::from(1)
        }
    }
}

/// `--threads` may ask for at most this many threads per core: more only share the cores (and
/// 100,000 took minutes to start before any message).
const MAX_THREADS_PER_CORE: usize = 8;

/// How errors on standard output are named.
const STDOUT: &str = "standard output";

/// Writes `text` and a newline on standard output; an error is returned, not a panic as
/// `println!` gives. A reader that went away (`| head`) is no error: the command goes on and
/// ends with its own exit code (4 for an unstable `check`, 3 for a diverged run).
fn say(text: &str) -> rbsm::error::Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{text}").and_then(|_| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(rbsm::error::Error::io(STDOUT, e))
        }
        _ => Ok(()),
    }
}

/// Writes `text` and a newline on standard error, ignoring a closed stream (`eprintln!` would
/// panic).
fn tell(text: &str) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr().lock(), "{text}");
}

/// An error as `--json` prints it: `{"error": {"kind", "key", "message"}}`, `key` being the
/// scene key, the mesh's body and cell, or the file at fault.
fn error_json(e: &rbsm::error::Error) -> serde_json::Value {
    let (kind, key, message) = e.parts();
    serde_json::json!({"error": {"kind": kind, "key": key, "message": message}})
}

/// Prints a report as JSON, or as its text.
fn print(json: bool, report: &impl Report) -> rbsm::error::Result<()> {
    if json {
        say(&serde_json::to_string_pretty(report).expect("reports serialise"))
    } else {
        say(&report.text())
    }
}

/// The list of files a command wrote, as `--json` and text print it.
#[derive(serde::Serialize)]
struct Written {
    written: Vec<PathBuf>,
}

impl Report for Written {
    fn text(&self) -> String {
        let lines: Vec<String> = self
            .written
            .iter()
            .map(|p| format!("written: {}", p.display()))
            .collect();
        lines.join("\n")
    }
}

/// The setup of the scene file `path` with `overrides`.
fn setup(path: &Path, overrides: Overrides) -> rbsm::error::Result<Setup> {
    Setup::new(&Scene::from_file(path)?, &overrides)
}

/// Runs the command of `cli`; the exit code tells how it ended.
fn execute(cli: &Cli) -> rbsm::error::Result<ExitCode> {
    match &cli.command {
        Command::Schema => {
            say(&serde_json::to_string_pretty(&rbsm::input::scene::schema())
                .expect("the schema serialises"))?;
        }
        Command::Check {
            scene,
            evaluator,
            dt,
        } => {
            // The setup a run takes, so that its `dt` is the run's; `check` adds `Δt_crit` to
            // full precision.
            let overrides = Overrides {
                evaluator: *evaluator,
                dt: *dt,
                ..Default::default()
            };
            let report = check::check(&setup(scene, overrides)?)?;
            print(cli.json, &report)?;
            if report.unstable {
                return Ok(ExitCode::from(check::UNSTABLE_EXIT));
            }
        }
        Command::Draw { scene, out, state } => draw(cli, scene, out, state.as_deref())?,
        Command::Plot { dir } => {
            let written = rbsm::output::plot::histories(dir)?;
            print(cli.json, &Written { written })?;
        }
        Command::Limit {
            scene,
            on,
            points,
            out,
        } => {
            use rbsm::analysis::collapse::{self, Multiplier};
            let on = on.as_deref().map(|on| match on {
                "loads" => Multiplier::Loads,
                "gravity" => Multiplier::Gravity,
                _ => Multiplier::Clamps,
            });
            let setup = setup(scene, Overrides::no_step())?;
            let points = points
                .parse()
                .map_err(|e: String| rbsm::error::Error::scene("--points", e))?;
            let r = collapse::analyse(&setup, on, points)?;
            if let Some(dir) = out {
                collapse::write(dir, &setup, &r)?;
            }
            print(cli.json, &r)?;
        }
        Command::Static { scene, out } => {
            let setup = setup(scene, Overrides::no_step())?;
            let r = statics::analyse(&setup)?;
            if let Some(dir) = out {
                statics::write(dir, &setup, &r)?;
            }
            print(cli.json, &r)?;
        }
        Command::Calibrate { spec, material } => {
            use rbsm::analysis::calibrate;
            let spec = calibrate::CalibrationSpec::from_file(spec)?;
            let r = calibrate::calibrate(
                &spec,
                |jobs| calibrate::run_local(&spec, jobs),
                |round, jobs, last| {
                    if cli.quiet {
                        return;
                    }
                    if let Some(r) = last {
                        tell(&format!(
                            "round {}: f_t, f_c, G_F at {:.4}, {:.4}, {:.4} of the targets",
                            r.round, r.ratios[0], r.ratios[1], r.ratios[2]
                        ));
                    }
                    tell(&format!("round {round}: {jobs} specimen runs"));
                },
            )?;
            if let Some(path) = material {
                let block = serde_json::json!({ spec.name.as_str(): r.material });
                rbsm::output::write_json(path, &block)?;
            }
            print(cli.json, &r)?;
        }
        Command::Effective { scene } => {
            let setup = setup(scene, Overrides::no_step())?;
            print(cli.json, &effective::analyse(&setup)?)?;
        }
        Command::Eigen {
            scene,
            modes,
            method,
            vtk,
            svg,
            out,
        } => {
            let setup = setup(scene, Overrides::exact())?;
            let params = eigen::EigenParams {
                modes: *modes,
                method: *method,
            };
            let r = eigen::analyse(&setup, &params)?;
            let files = eigen::Files {
                out: out.as_deref(),
                vtk: vtk.as_deref(),
                svg: svg.as_deref(),
            };
            files.write(&setup, &r)?;
            print(cli.json, &r)?;
        }
        Command::Stability {
            scene,
            fractions,
            steps,
            out,
        } => {
            let params = stability::StabilityParams {
                fractions: fractions.clone(),
                steps: *steps,
            };
            let r = stability::analyse(&setup(scene, Overrides::exact())?, &params)?;
            if let Some(dir) = out {
                stability::write_fraction_histories(dir, &r.fractions)?;
            }
            print(cli.json, &r)?;
        }
        Command::Tradeoff { scene, sweeps, out } => tradeoff(cli, scene, sweeps, out.as_deref())?,
        Command::Run(args) => return run(cli, args),
    }
    Ok(ExitCode::SUCCESS)
}

/// `rbsm draw`: the model of `scene`, or the final state of the run in `state`, as SVG.
fn draw(cli: &Cli, scene: &Path, out: &Path, state: Option<&Path>) -> rbsm::error::Result<()> {
    let model = rbsm::model::Model::build(&Scene::from_file(scene)?)?;
    let svg = match state {
        None => rbsm::output::drawing::model_svg(&model),
        Some(dir) => {
            let path = dir.join("final_state.json");
            let state = rbsm::output::read_final_state(&path, &model)?;
            rbsm::output::drawing::state_svg(&model, &state)
        }
    };
    rbsm::output::write_atomic(out, svg.as_bytes())?;
    print(
        cli.json,
        &Written {
            written: vec![out.to_path_buf()],
        },
    )
}

/// `rbsm tradeoff`: the sweeps of `scene`, a line per point as it is done, and the report
/// written into `out` (by default the scene's folder under `out/`).
fn tradeoff(
    cli: &Cli,
    scene: &Path,
    sweeps: &[String],
    out: Option<&Path>,
) -> rbsm::error::Result<()> {
    let sweeps = sweeps
        .iter()
        .map(|s| tradeoff::Sweep::parse(s))
        .collect::<rbsm::error::Result<Vec<_>>>()?;
    let scene = Scene::from_file(scene)?;
    let dir = out.map_or_else(|| tradeoff::default_folder(&scene), Path::to_path_buf);
    let total: usize = sweeps.iter().map(|s| s.values.len()).product();
    let mut done = 0;
    let report = tradeoff::sweep(&scene, &sweeps, |p| {
        done += 1;
        if !cli.quiet {
            tell(&format!(
                "[{done}/{total}] {}: {} in {:.3} s, {}",
                tradeoff::describe(&p.settings),
                rbsm::output::count(p.steps as usize, "step", "steps"),
                p.wall_s,
                p.status
            ));
        }
    })?;
    report.write(&dir)?;
    print(cli.json, &report)?;
    if !cli.json {
        say(&format!(
            "written: {}/tradeoff.{{csv,md,svg}}",
            dir.display()
        ))?;
    }
    Ok(())
}

/// `rbsm run`: the run `args` ask for, with a progress bar on a terminal; the exit code tells
/// a diverged (3) or interrupted (130) run from a complete one.
fn run(cli: &Cli, args: &RunArgs) -> rbsm::error::Result<ExitCode> {
    let RunArgs {
        scene,
        out,
        resume,
        evaluator,
        dt,
        dt_factor,
        steps,
        exact_dt_crit,
    } = args;
    let overrides = Overrides {
        evaluator: *evaluator,
        dt: *dt,
        dt_factor: *dt_factor,
        steps: *steps,
        exact_dt_crit: *exact_dt_crit,
        ..Default::default()
    };
    let params = run::RunParams {
        resume: resume.is_some(),
        interrupt: Some(interrupt_flag()?),
        keep_history: false,
    };
    let mut monitor = Terminal {
        quiet: cli.quiet,
        bar: None,
        start: Instant::now(),
    };
    let out = resume
        .as_ref()
        .or(out.as_ref())
        .expect("clap requires --out or --resume");
    let summary = run::run(&setup(scene, overrides)?, &params, out, &mut monitor)?;
    if let Some(bar) = monitor.bar.take() {
        bar.finish_and_clear();
    }
    print(cli.json, &summary)?;
    // A diverged or interrupted run kept its outputs; the exit code tells scripts which.
    Ok(match summary.status {
        RunStatus::Ok => ExitCode::SUCCESS,
        RunStatus::Interrupted => ExitCode::from(130),
        RunStatus::Diverged => ExitCode::from(3),
    })
}

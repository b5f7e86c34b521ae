//! The `rbsm` command line: a thin layer over the library.

use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rbsm::run::{self, Monitor, RunOptions};
use rbsm::scene::{EvaluatorKind, Scene};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

#[derive(Parser)]
#[command(name = "rbsm", version, about = "Rigid-Bodies-Spring Model in 2D with explicit dynamics")]
struct Cli {
    /// Worker threads (default: all cores).
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
    Run {
        /// The scene file (JSON).
        scene: PathBuf,
        /// Output directory (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Override the scene's evaluator.
        #[arg(long, value_enum)]
        evaluator: Option<EvaluatorKind>,
        /// Override the time step (s).
        #[arg(long)]
        dt: Option<f64>,
        /// Override the number of steps.
        #[arg(long)]
        steps: Option<u64>,
    },
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
            eprintln!("{line}");
        }
    }
    fn progress(&mut self, step: u64, total: u64) {
        if self.quiet || !std::io::stderr().is_terminal() {
            return;
        }
        if self.bar.is_none() && self.start.elapsed() > Duration::from_secs(2) {
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
            bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} steps, {elapsed} elapsed, eta {eta}").expect("valid template"));
            self.bar = Some(bar);
        }
        if let Some(bar) = &self.bar {
            bar.set_position(step);
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(n) = cli.threads {
        if let Err(e) = rayon::ThreadPoolBuilder::new().num_threads(n).build_global() {
            eprintln!("error: --threads: {e}");
            return ExitCode::from(2);
        }
    }
    match execute(&cli) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}

fn execute(cli: &Cli) -> rbsm::error::Result<ExitCode> {
    match &cli.command {
        Command::Run { scene, out, evaluator, dt, steps } => {
            let scene = Scene::from_file(scene)?;
            let opts = RunOptions { evaluator: *evaluator, dt: *dt, steps: *steps };
            let mut monitor = Terminal { quiet: cli.quiet, bar: None, start: Instant::now() };
            let summary = run::run(&scene, &opts, out, &mut monitor)?;
            if let Some(bar) = monitor.bar.take() {
                bar.finish_and_clear();
            }
            if cli.json {
                println!("{}", serde_json::to_string_pretty(&summary).expect("summary serialises"));
            } else if let Some(reason) = &summary.reason {
                println!("{}: diverged at {reason}", summary.scene);
                println!(
                    "  the outputs in {} hold the run up to the last state that passed the guard: step {} (t = {:.6e} s)",
                    out.display(),
                    summary.steps,
                    summary.t_end
                );
            } else {
                println!(
                    "{}: ok, {} steps (t = {:.6e} s) in {:.3} s; energy drift {:.3e} of the largest energy; outputs in {}",
                    summary.scene,
                    summary.steps,
                    summary.t_end,
                    summary.wall_time_s,
                    summary.energy.max_relative_drift,
                    out.display()
                );
            }
            // A diverged run kept its outputs; the exit code tells scripts that it diverged.
            Ok(if summary.status == "ok" { ExitCode::SUCCESS } else { ExitCode::from(3) })
        }
    }
}

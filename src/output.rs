//! What a run writes (DESIGN.md §9): `summary.json`, `history.csv` and `final_state.json`.
//! The history is flushed row by row, so that a run that stops early leaves a valid file.

use crate::error::{Error, Result};
use crate::integrator::{Energy, Snapshot};
use crate::model::Model;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// The scene's name.
    pub scene: String,
    /// `rigid` or `hybrid`.
    pub formulation: String,
    /// `assembled` or `element-wise`.
    pub evaluator: String,
    /// Number of elements.
    pub elements: usize,
    /// Number of interfaces (ground springs included).
    pub interfaces: usize,
    /// Free DOFs (fixed ones excluded).
    pub dofs: usize,
    /// Time step (s).
    pub dt: f64,
    /// Critical time step `2/ω_max` (s).
    pub dt_crit: f64,
    /// Steps completed.
    pub steps: u64,
    /// Time reached (s).
    pub t_end: f64,
    /// `ok` or `diverged`.
    pub status: String,
    /// Why a run diverged, with the step and the time; `null` for `ok`.
    pub reason: Option<String>,
    /// Whole run, setup included (s).
    pub wall_time_s: f64,
    /// The time-stepping loop alone.
    pub step_time_s: f64,
    /// Worker threads.
    pub threads: usize,
    /// What the checks of `checks::warnings` found (extreme inputs, dt above Δt_crit).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Energies at the start and the end, and the drift.
    pub energy: EnergySummary,
    /// Contact figures; only for scenes with contact.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactSummary>,
}

/// The contact figures of `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ContactSummary {
    /// `edge-to-edge` or `point`.
    pub model: String,
    /// Coulomb `μ`; `null` is no slip limit.
    pub friction: Option<f64>,
    /// Live contacts per step, mean: vertex–edge contacts (point), pieces of boundary edges
    /// inside another body or below the ground (edge-to-edge).
    pub mean_pairs: f64,
    /// Largest number of live contacts in one step.
    pub max_pairs: usize,
    /// Narrow-phase tests per step: vertex path against a nearby edge (point), boundary edge
    /// against a nearby element or ground strip (edge-to-edge).
    pub tests_per_step: f64,
    /// Builds of the neighbour lists: when a corner moved half their skin.
    pub rebuilds: u64,
    /// Wall time spent in contact (s).
    pub time_s: f64,
}

/// The energy figures of `summary.json` (J).
#[derive(Debug, Clone, Serialize)]
pub struct EnergySummary {
    /// Total energy at the start (J).
    pub initial: f64,
    #[serde(rename = "final")]
    /// Total energy at the end (J).
    pub final_: f64,
    /// Largest `|total − initial|` divided by the largest energy seen in the run.
    pub max_relative_drift: f64,
}

/// One history column beyond the energies: DOF `dof` of element `element`.
#[derive(Debug, Clone)]
pub struct Probe {
    /// Column header.
    pub name: String,
    /// Global DOF index.
    pub dof: usize,
}

/// The columns of `history.csv` before the probes.
pub const HISTORY_COLUMNS: [&str; 7] = ["t", "kinetic", "elastic", "contact", "potential", "external_work", "total"];

/// `history.csv`, written as the run goes.
pub struct History {
    file: std::io::BufWriter<std::fs::File>,
    path: PathBuf,
    probes: Vec<Probe>,
}

impl History {
    /// Creates the file and writes the header.
    pub fn create(dir: &Path, probes: Vec<Probe>) -> Result<History> {
        let path = dir.join("history.csv");
        let file = std::fs::File::create(&path).map_err(|e| Error::io(&path, e))?;
        let mut h = History { file: std::io::BufWriter::new(file), path, probes };
        let mut header = HISTORY_COLUMNS.join(",");
        for p in &h.probes {
            header.push(',');
            header.push_str(&p.name);
        }
        writeln!(h.file, "{header}").map_err(|e| Error::io(&h.path, e))?;
        Ok(h)
    }

    /// Appends the row of one recorded step and flushes it.
    pub fn write(&mut self, s: &Snapshot, e: &Energy) -> Result<()> {
        let mut row = format!(
            "{:e},{:e},{:e},{:e},{:e},{:e},{:e}",
            e.t, e.kinetic, e.elastic, e.contact, e.potential, e.external_work, e.total
        );
        for p in &self.probes {
            row.push_str(&format!(",{:e}", s.u[p.dof]));
        }
        writeln!(self.file, "{row}").and_then(|_| self.file.flush()).map_err(|e| Error::io(&self.path, e))
    }
}

/// One element of `final_state.json`.
#[derive(Serialize)]
struct ElementState<'a> {
    centroid: [f64; 2],
    #[serde(rename = "U")]
    u: &'a [f64],
    #[serde(rename = "V")]
    v: &'a [f64],
    /// `(σ_x, σ_y, τ_xy) = D ε` (Pa), hybrid only.
    #[serde(skip_serializing_if = "Option::is_none")]
    stress: Option<[f64; 3]>,
}

/// `(σ_x, σ_y, τ_xy) = D ε` of a hybrid element's DOFs `u`; `None` for a rigid one.
pub fn element_stress(model: &Model, e: usize, u: &[f64]) -> Option<[f64; 3]> {
    (u.len() == 6).then(|| {
        let s = model.elements[e].d * nalgebra::Vector3::new(u[3], u[4], u[5]);
        [s[0], s[1], s[2]]
    })
}

/// Writes `final_state.json`: per element its reference centroid, `U` and `V`.
pub fn write_final_state(dir: &Path, model: &Model, t: f64, u: &[f64], v: &[f64]) -> Result<()> {
    let nd = model.formulation.ndof();
    let elements: Vec<ElementState> = model
        .elements
        .iter()
        .enumerate()
        .map(|(e, el)| ElementState {
            centroid: [el.props.centroid.x, el.props.centroid.y],
            u: &u[e * nd..(e + 1) * nd],
            v: &v[e * nd..(e + 1) * nd],
            stress: element_stress(model, e, &u[e * nd..(e + 1) * nd]),
        })
        .collect();
    write_json(&dir.join("final_state.json"), &serde_json::json!({ "t": t, "elements": elements }))
}

/// Writes any serialisable value as pretty JSON.
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    serde_json::to_writer_pretty(&mut w, value).map_err(|e| Error::io(path, e.into()))?;
    writeln!(w).and_then(|_| w.flush()).map_err(|e| Error::io(path, e))
}

/// Writes `fraction_F.csv` (`t,total,stored`: s, J, J) for each run of a stability analysis.
pub fn write_fraction_histories(dir: &Path, runs: &[crate::stability::FractionRun]) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    for r in runs {
        let path = dir.join(format!("fraction_{}.csv", r.fraction));
        let mut text = String::from("t,total,stored\n");
        for (t, e, stored) in &r.history {
            text.push_str(&format!("{t:e},{e:e},{stored:e}\n"));
        }
        std::fs::write(&path, text).map_err(|e| Error::io(&path, e))?;
    }
    Ok(())
}

//! What a run writes (the README's *Outputs* section): `summary.json`, `history.csv` and
//! `final_state.json`.
//! The history is written row by row, each row whole; the other files are written to a
//! temporary name and renamed, so that a run that stops early leaves valid files.

pub mod drawing;
pub mod plot;
pub mod vtk;

use crate::error::{Error, Result};
use crate::force::failure::InterfaceStatus;
use crate::model::Model;
use crate::step::integrator::{Energy, RunStatus, Snapshot};
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
    /// Number of interfaces between elements (as `rbsm check` and the run's information line
    /// count them).
    pub interfaces: usize,
    /// Number of ground springs (interfaces tied to ground by a support).
    pub ground_springs: usize,
    /// Free DOFs (fixed ones excluded).
    pub dofs: usize,
    /// Time step (s).
    pub dt: f64,
    /// Critical time step `2/ω_max` (s), by Lanczos: to [`crate::analysis::eigen`]'s
    /// `FOR_STEP` (about four digits) for a run whose step is a `dt_factor`, to full precision
    /// with `--exact-dt-crit`; `null` when `dt` was given (no Lanczos is run).
    pub dt_crit: Option<f64>,
    /// A step proven stable (s), `≤ Δt_crit`, computed without Lanczos: what a given `dt` is
    /// checked against.
    pub dt_safe: f64,
    /// Steps completed.
    pub steps: u64,
    /// Time reached (s).
    pub t_end: f64,
    /// `ok`, `diverged` or `interrupted`.
    pub status: RunStatus,
    /// Why a run diverged, with the step and the time; `null` for `ok`.
    pub reason: Option<String>,
    /// Whole run, setup included (s).
    pub wall_time_s: f64,
    /// The setup alone: model, evaluator, mass, contact and what it computes of `Δt_crit` (s).
    pub setup_time_s: f64,
    /// The time-stepping loop alone, with its checks and history rows (s).
    pub step_time_s: f64,
    /// Worker threads.
    pub threads: usize,
    /// What the checks found (extreme inputs; `dt` above `Δt_crit`, or above the proven-safe
    /// step when `Δt_crit` was not computed).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Energies at the start and the end, and the drift.
    pub energy: EnergySummary,
    /// Contact figures; only for scenes with contact.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactSummary>,
    /// The probe columns of `history.csv` with their units (`rbsm plot` labels its axes so).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub probes: Vec<ProbeColumn>,
    /// The failing interfaces at the end; only when a material's interfaces can fail.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub failure: Option<FailureSummary>,
    /// Each moving clamp's largest reaction and where it was reached (the peak of its
    /// load–displacement curve in `history.csv`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub clamps: Vec<ClampSummary>,
    /// Where a run with `time.stop_ratio` stopped, settled; only for such a run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub balance: Option<BalanceSummary>,
    /// The folder the run wrote into (not in `summary.json`; empty for a run without one).
    #[serde(skip)]
    pub dir: PathBuf,
}

/// The failing interfaces of `summary.json` at the end of the run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FailureSummary {
    /// Interfaces that can fail.
    pub interfaces: usize,
    /// Of these, those with plastic displacement and strength left.
    pub yielding: usize,
    /// Those whose strength is exhausted.
    pub broken: usize,
    /// Those broken and handed over to contact (bodies that fragment).
    pub released: usize,
    /// Work of the strengths (tension and cohesion) (J).
    pub fracture: f64,
    /// Work of friction on the interfaces (J).
    pub friction: f64,
}

impl FailureSummary {
    /// The counts and works of a report of every failing interface.
    pub fn of(
        interfaces: &[crate::force::failure::InterfaceFailure],
        dissipated: [f64; 2],
    ) -> Self {
        let of = |status| interfaces.iter().filter(|i| i.status == status).count();
        FailureSummary {
            interfaces: interfaces.len(),
            yielding: of(InterfaceStatus::Yielding),
            broken: of(InterfaceStatus::Broken),
            released: of(InterfaceStatus::Released),
            fracture: dissipated[0],
            friction: dissipated[1],
        }
    }
}

/// A moving clamp's peak reaction in `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ClampSummary {
    /// The prefix of its history columns, `<body>_s<k>`.
    pub name: String,
    /// The largest reaction along its velocity among the recorded steps (N).
    pub peak_force: f64,
    /// The clamp's displacement there (m).
    pub displacement_at_peak: f64,
}

/// The columns every history has, in this order: the time and the energies (J) of
/// [`Energy`], as [`History::write`] writes them.
pub const HISTORY_COLUMNS: [&str; 7] = [
    "t",
    "kinetic",
    "elastic",
    "contact",
    "potential",
    "external_work",
    "total",
];

/// The works of failing interfaces (J), after [`HISTORY_COLUMNS`] when a material's interfaces
/// can fail.
const FAILURE_COLUMNS: [&str; 2] = ["fracture", "friction"];

/// The work of the elements' plastic flow (J), after them when hybrid elements may yield.
const PLASTIC_COLUMN: &str = "plastic";

/// The work of damping (J), after them when the model is damped.
const DAMPING_COLUMN: &str = "damping";

/// The columns of a moving clamp, after its name (`<body>_s<k>_disp`): its displacement along
/// its velocity (m) and its reaction (N).
const CLAMP_COLUMNS: [&str; 2] = ["disp", "force"];

/// The columns of a moving clamp named `name` ([`crate::model::Prescribed::name`]).
pub(crate) fn clamp_columns(name: &str) -> [String; 2] {
    CLAMP_COLUMNS.map(|c| format!("{name}_{c}"))
}

/// The columns of `history.csv` that are energies or works (J): [`HISTORY_COLUMNS`] after `t`,
/// then those a model may add (failure, plastic flow, damping).
pub(crate) fn energy_columns() -> impl Iterator<Item = &'static str> {
    HISTORY_COLUMNS[1..]
        .iter()
        .chain(&FAILURE_COLUMNS)
        .chain(&[PLASTIC_COLUMN, DAMPING_COLUMN])
        .copied()
}

/// Refuses a probe of `probes` (the scene's `output.probes`, of which `model` is the model)
/// whose column is one of the history's own: [`HISTORY_COLUMNS`], those a model may add
/// (whether or not this one does, so that a probe's name does not depend on the damping or the
/// interface law) and `model`'s moving clamps'. The error names the probe's key; the scene
/// checked the rest of the rule (`Scene::validate`).
///
/// # Errors
/// A probe's name is one of those columns.
pub fn refuse_own_columns(model: &Model, probes: &[crate::input::scene::ProbeSpec]) -> Result<()> {
    let own: std::collections::HashSet<String> = std::iter::once(HISTORY_COLUMNS[0])
        .chain(energy_columns())
        .map(|c| c.to_string())
        .chain(model.prescribed.iter().flat_map(|p| clamp_columns(&p.name)))
        .collect();
    for (k, p) in probes.iter().enumerate() {
        let column = p.column();
        if own.contains(&column) {
            return Err(Error::scene(
                format!("output.probes[{k}].name"),
                format!(
                    "`{column}` is one of the history's own columns: every column needs its own \
                     name"
                ),
            ));
        }
    }
    Ok(())
}

/// The columns of `history.csv` after [`HISTORY_COLUMNS`], as the model asks for them.
#[derive(Debug, Clone, Default)]
pub struct Columns {
    /// `fracture` and `friction`, when interfaces can fail.
    pub failure: bool,
    /// `plastic`, when elements may yield.
    pub plastic: bool,
    /// `damping`, when the model is damped.
    pub damping: bool,
    /// `<name>_disp` and `<name>_force` of each moving clamp.
    pub clamps: Vec<crate::model::Prescribed>,
    /// One column per probe.
    pub probes: Vec<Probe>,
}

impl Columns {
    /// The columns of `model`'s history with `probes`.
    pub fn of(model: &Model, probes: Vec<Probe>) -> Self {
        Columns {
            failure: model.any_fails(),
            plastic: model.any_yields(),
            damping: model.damping > 0.0 || model.local_damping > 0.0,
            clamps: model.prescribed.clone(),
            probes,
        }
    }

    /// The header after [`HISTORY_COLUMNS`].
    fn header(&self) -> Vec<String> {
        let mut h: Vec<String> = Vec::new();
        if self.failure {
            h.extend(FAILURE_COLUMNS.map(String::from));
        }
        if self.plastic {
            h.push(PLASTIC_COLUMN.into());
        }
        if self.damping {
            h.push(DAMPING_COLUMN.into());
        }
        for c in &self.clamps {
            h.extend(clamp_columns(&c.name));
        }
        h.extend(self.probes.iter().map(|p| p.name.clone()));
        h
    }
}

/// A probe column of `history.csv` and its unit.
#[derive(Debug, Clone, Serialize)]
pub struct ProbeColumn {
    /// The column's header.
    pub name: String,
    /// `m` (`u`, `v`), `rad` (`theta`) or `1` (strains).
    pub unit: String,
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
    /// Largest `|total − initial|` divided by the energy put in (the initial kinetic, elastic
    /// and contact energy plus the largest work of the loads, clamps and gravity), up to the
    /// last state that passed the guard.
    pub max_relative_drift: f64,
}

/// The unbalanced-force ratio of a run with `time.stop_ratio` (`step::balance`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BalanceSummary {
    /// The ratio at the last check.
    pub ratio: f64,
    /// The step at which it fell below `time.stop_ratio`, when it did (the run stopped there).
    pub settled_at_step: Option<u64>,
}

/// One history column beyond the energies: DOF `dof` of element `element`, and for `u`, `v`
/// at the reference offset `offset` from its centroid the displacement there, `N_e(x) U_e`.
#[derive(Debug, Clone)]
pub struct Probe {
    /// Column header.
    pub name: String,
    /// The element (global index).
    pub element: usize,
    /// The DOF within the element.
    pub dof: usize,
    /// DOFs per element.
    pub nd: usize,
    /// Where in the element, for a probe placed by point.
    pub offset: Option<crate::mesh::geometry::Vec2>,
    /// The formulation, whose `N_e` carries the element's DOFs to the point.
    pub formulation: crate::model::formulation::Formulation,
}

impl Probe {
    /// The unit of the probe's values: `m`, `rad` or `1` (a strain).
    pub fn unit(&self) -> &'static str {
        match self.dof {
            0 | 1 => "m",
            2 => "rad",
            _ => "1",
        }
    }

    /// The probe's value in the displacements `u` of all elements.
    pub fn value(&self, u: &[f64]) -> f64 {
        let ue = &u[self.element * self.nd..(self.element + 1) * self.nd];
        match self.offset {
            Some(d) if self.dof < 2 => self.formulation.displacement(ue, d)[self.dof],
            _ => ue[self.dof],
        }
    }
}

/// The history of a run: one row per recorded step, the seven energies then the columns of
/// [`Columns`]. Written to `history.csv` row by row (each row whole), kept in memory, or both.
pub struct History {
    /// `history.csv`, its path and the bytes of whole rows written so far.
    file: Option<(std::fs::File, PathBuf, u64)>,
    columns: Columns,
    /// The rows kept in memory, one after the other; `None`: not kept.
    rows: Option<Vec<f64>>,
}

impl History {
    /// A history kept in memory only ([`History::rows`]).
    pub fn memory(columns: Columns) -> History {
        History {
            file: None,
            columns,
            rows: Some(Vec::new()),
        }
    }

    /// Creates `history.csv` in `dir` (a new file renamed into place: a symbolic link there is
    /// replaced, not written through) and writes the header; the rows are kept in memory too
    /// when `keep` is set.
    ///
    /// # Errors
    /// `dir/history.csv` cannot be created or its header written (no folder `dir`, no permission,
    /// disk full).
    pub fn create(dir: &Path, columns: Columns, keep: bool) -> Result<History> {
        let path = dir.join("history.csv");
        let file = write_atomic_open(&path, &[])?;
        let mut h = History {
            file: Some((file, path, 0)),
            columns,
            rows: keep.then(Vec::new),
        };
        h.append(h.header().join(","))?;
        Ok(h)
    }

    /// Opens the history of an earlier run to go on after its first `len` bytes (the rows up to
    /// a checkpoint); the rest is cut off. With `keep`, those rows are read back into memory
    /// first (each value was written in the form that reads back to its bits), so that the rows
    /// kept cover the whole run. A symbolic link in its place is replaced by a file of those
    /// bytes, its target left alone.
    ///
    /// # Errors
    /// `dir/history.csv` is missing, is neither a file nor a symbolic link, holds fewer than `len`
    /// bytes, or cannot be read, cut back to `len` bytes or (in place of a link) written; with
    /// `keep`, a row up to `len` is not as many numbers as the header has columns.
    pub fn resume(dir: &Path, columns: Columns, len: u64, keep: bool) -> Result<History> {
        use std::io::{Read, Seek};
        let path = dir.join("history.csv");
        let fail = |e| Error::io(&path, e);
        let short = |have: u64| {
            Error::io(
                &path,
                std::io::Error::other(format!(
                    "holds {have} bytes, shorter than the {len} the checkpoint counts"
                )),
            )
        };
        let kind = std::fs::symlink_metadata(&path).map_err(fail)?.file_type();
        let file = if kind.is_file() {
            let mut file = std::fs::OpenOptions::new()
                .write(true)
                .open(&path)
                .map_err(fail)?;
            let have = file.metadata().map_err(fail)?.len();
            if have < len {
                return Err(short(have));
            }
            file.set_len(len).map_err(fail)?;
            file.seek(std::io::SeekFrom::Start(len)).map_err(fail)?;
            file
        } else if kind.is_symlink() {
            let mut bytes = Vec::new();
            std::fs::File::open(&path)
                .and_then(|f| f.take(len).read_to_end(&mut bytes))
                .map_err(fail)?;
            if (bytes.len() as u64) < len {
                return Err(short(bytes.len() as u64));
            }
            write_atomic_open(&path, &bytes)?
        } else {
            return Err(Error::io(
                &path,
                std::io::Error::other(format!(
                    "not a regular file ({})",
                    crate::input::scene::kind_of(&kind)
                )),
            ));
        };
        let mut h = History {
            file: Some((file, path, len)),
            columns,
            rows: None,
        };
        if keep {
            h.rows = Some(h.rows_written()?);
        }
        Ok(h)
    }

    /// The rows of `history.csv`, as many bytes as written so far (the whole file once
    /// [`History::resume`] has cut it back), read back as numbers ([`plot::read_csv`]).
    fn rows_written(&self) -> Result<Vec<f64>> {
        let Some((_, path, _)) = &self.file else {
            return Ok(Vec::new());
        };
        let columns = plot::read_csv(path)?;
        if columns.len() != self.header().len() {
            return Err(Error::io(
                path,
                std::io::Error::other(format!(
                    "{} columns where this run has {}: the run cannot be resumed with its \
                     history kept",
                    columns.len(),
                    self.header().len()
                )),
            ));
        }
        let rows = columns.first().map_or(0, |c| c.values.len());
        Ok((0..rows)
            .flat_map(|r| columns.iter().map(move |c| c.values[r]))
            .collect())
    }

    /// The column names: [`HISTORY_COLUMNS`], then those of the model.
    pub fn header(&self) -> Vec<String> {
        let mut h: Vec<String> = HISTORY_COLUMNS.iter().map(|c| c.to_string()).collect();
        h.extend(self.columns.header());
        h
    }

    /// Bytes of whole rows written to `history.csv` so far (0 in memory only).
    pub fn bytes(&self) -> u64 {
        self.file.as_ref().map_or(0, |f| f.2)
    }

    /// The rows kept in memory, one after the other, each as long as [`History::header`];
    /// empty when they are not kept.
    pub fn rows(&self) -> &[f64] {
        self.rows.as_deref().unwrap_or_default()
    }

    /// The rows kept in memory, as [`History::rows`], taken.
    pub fn into_rows(self) -> Vec<f64> {
        self.rows.unwrap_or_default()
    }

    /// Records the row of one recorded step. `history.csv` writes each value in the shortest
    /// form that reads back to the same bits.
    ///
    /// # Errors
    /// The row cannot be appended to `history.csv`, which is then cut back to its whole rows. A
    /// history in memory only never fails.
    pub fn write(&mut self, s: &Snapshot, e: &Energy) -> Result<()> {
        let mut row = vec![
            e.t,
            e.kinetic,
            e.elastic,
            e.contact,
            e.potential,
            e.external_work,
            e.total,
        ];
        let c = &self.columns;
        if c.failure {
            row.extend([e.fracture, e.friction]);
        }
        if c.plastic {
            row.push(e.plastic);
        }
        if c.damping {
            row.push(e.damping);
        }
        for (p, r) in c.clamps.iter().zip(s.reactions) {
            row.extend([p.velocity.norm() * p.travel(s.t), *r]);
        }
        row.extend(c.probes.iter().map(|p| p.value(s.u)));
        // −0 (the potential of a body at rest where it started) is written and kept as 0.
        row.iter_mut().for_each(|x| *x += 0.0);
        if self.file.is_some() {
            let line: Vec<String> = row.iter().map(|x| format!("{x:e}")).collect();
            self.append(line.join(","))?;
        }
        if let Some(rows) = &mut self.rows {
            rows.extend(row);
        }
        Ok(())
    }

    /// Writes `line` and a newline in one call; on failure cuts the file back to whole rows.
    fn append(&mut self, mut line: String) -> Result<()> {
        let Some((file, path, len)) = &mut self.file else {
            return Ok(());
        };
        line.push('\n');
        match file.write_all(line.as_bytes()) {
            Ok(()) => {
                *len += line.len() as u64;
                Ok(())
            }
            Err(e) => {
                use std::io::Seek;
                let _ = file
                    .set_len(*len)
                    .and_then(|_| file.seek(std::io::SeekFrom::Start(*len)));
                Err(Error::io(path, e))
            }
        }
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
    /// `(σ_x, σ_y, τ_xy) = D (ε − ε_p)` (Pa), hybrid only.
    #[serde(skip_serializing_if = "Option::is_none")]
    stress: Option<[f64; 3]>,
    /// The plastic strain `ε_p`, when elements may yield.
    #[serde(skip_serializing_if = "Option::is_none")]
    plastic_strain: Option<[f64; 3]>,
}

/// `(σ_x, σ_y, τ_xy) = D (ε − ε_p)` of a hybrid element's DOFs `u` with plastic strain
/// `plastic`; `None` for a rigid one.
pub fn element_stress(model: &Model, e: usize, u: &[f64], plastic: [f64; 3]) -> Option<[f64; 3]> {
    (u.len() == 6).then(|| {
        let s = model.elements[e].d
            * (nalgebra::Vector3::new(u[3], u[4], u[5]) - nalgebra::Vector3::from(plastic));
        [s[0], s[1], s[2]]
    })
}

/// Writes `final_state.json`: per element its reference centroid, `U` and `V`.
/// `interfaces` lists the failing interfaces' state, written only when the model has any;
/// `plastic`, per element, its plastic strain and whether it yields (empty when no element
/// may yield).
///
/// # Errors
/// `dir/final_state.json` cannot be written.
///
/// # Panics
/// `u` or `v` is shorter than `ndof × elements`.
pub fn write_final_state(
    dir: &Path,
    model: &Model,
    t: f64,
    u: &[f64],
    v: &[f64],
    interfaces: Option<&[crate::force::failure::InterfaceFailure]>,
    plastic: &[([f64; 3], bool)],
) -> Result<()> {
    let nd = model.formulation.ndof();
    let elements: Vec<ElementState> = model
        .elements
        .iter()
        .enumerate()
        .map(|(e, el)| {
            let p = plastic.get(e).map(|p| p.0);
            ElementState {
                centroid: [el.props.centroid.x, el.props.centroid.y],
                u: &u[e * nd..(e + 1) * nd],
                v: &v[e * nd..(e + 1) * nd],
                stress: element_stress(model, e, &u[e * nd..(e + 1) * nd], p.unwrap_or_default()),
                plastic_strain: p,
            }
        })
        .collect();
    // Serialised straight from the slices: a `serde_json::Value` tree of 10⁶ elements took
    // seconds to build.
    write_json(
        &dir.join("final_state.json"),
        &StateOut {
            t,
            elements,
            interfaces,
        },
    )
}

/// What `final_state.json` holds.
#[derive(Serialize)]
struct StateOut<'a> {
    t: f64,
    elements: Vec<ElementState<'a>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    interfaces: Option<&'a [crate::force::failure::InterfaceFailure]>,
}

/// A run's `final_state.json` read back for a model: what `rbsm draw --state` draws.
#[derive(Debug, Clone)]
pub struct FinalState {
    /// Time (s).
    pub t: f64,
    /// Displacements `U`, `ndof` per element.
    pub u: Vec<f64>,
    /// The failing interfaces' states; empty when the run had none.
    pub interfaces: Vec<crate::force::failure::InterfaceFailure>,
}

/// `final_state.json` as [`write_final_state`] writes it; other keys are ignored.
#[derive(serde::Deserialize)]
struct StateFile {
    t: f64,
    elements: Vec<StateElement>,
    #[serde(default)]
    interfaces: Vec<StateInterface>,
}

#[derive(serde::Deserialize)]
struct StateElement {
    centroid: [f64; 2],
    #[serde(rename = "U")]
    u: Vec<f64>,
}

#[derive(serde::Deserialize)]
struct StateInterface {
    interface: usize,
    status: String,
    opening: f64,
    slip: f64,
    dissipated: f64,
}

/// Reads `path`, the `final_state.json` of a run of `model`'s scene.
///
/// # Errors
/// A state that is not one (missing, not JSON, keys missing) or that belongs to another scene:
/// another number of elements or of DOFs per element, centroids elsewhere, interfaces that the
/// model does not have or that cannot fail; the error names the file.
/// A file larger than the final state of `model` could be (1 KiB per element, 512 B per
/// interface and 1 MiB, where `rbsm run` writes about 0.6 kB and 0.2 kB), or not a regular
/// file, is refused before it is read.
pub fn read_final_state(path: &Path, model: &Model) -> Result<FinalState> {
    let fail = |why: String| Error::io(path, std::io::Error::other(crate::error::cut(why)));
    let limit =
        ((model.elements.len() as u64) << 10) + ((model.interfaces.len() as u64) << 9) + (1 << 20);
    let text = crate::input::scene::read_text_limited(
        path,
        limit,
        &format!("the final state of the scene `{}`", model.name),
    )?;
    let file: StateFile = serde_json::from_str(&text)
        .map_err(|e| fail(format!("not a final state of `rbsm run`: {e}")))?;
    let other = "the final state of another scene";
    if file.elements.len() != model.elements.len() {
        return Err(fail(format!(
            "holds {}, the scene `{}` has {}: {other}",
            count(file.elements.len(), "element", "elements"),
            model.name,
            model.elements.len()
        )));
    }
    let nd = model.formulation.ndof();
    let (lo, hi) = model.elements.iter().fold(
        (
            crate::mesh::geometry::Vec2::repeat(f64::MAX),
            crate::mesh::geometry::Vec2::repeat(f64::MIN),
        ),
        |(lo, hi), e| (lo.inf(&e.props.centroid), hi.sup(&e.props.centroid)),
    );
    let tolerance = 1e-9 * (hi - lo).norm().max(f64::MIN_POSITIVE);
    let mut u = Vec::with_capacity(nd * model.elements.len());
    for (k, (e, el)) in file.elements.iter().zip(&model.elements).enumerate() {
        if e.u.len() != nd {
            return Err(fail(format!(
                "element {k}: `U` has {} values, the {} formulation {nd}: {other}",
                e.u.len(),
                model.formulation.name()
            )));
        }
        let c = el.props.centroid;
        if (e.centroid[0] - c.x).hypot(e.centroid[1] - c.y) > tolerance {
            return Err(fail(format!(
                "element {k}: centroid ({:e}, {:e}), the scene's is ({:e}, {:e}): {other}",
                e.centroid[0], e.centroid[1], c.x, c.y
            )));
        }
        u.extend_from_slice(&e.u);
    }
    let mut interfaces = Vec::with_capacity(file.interfaces.len());
    for (k, i) in file.interfaces.iter().enumerate() {
        let status: InterfaceStatus = i
            .status
            .parse()
            .map_err(|why| fail(format!("interfaces[{k}]: {why}")))?;
        let fails = model
            .interfaces
            .get(i.interface)
            .is_some_and(|i| model.fails(i));
        if !fails {
            return Err(fail(format!(
                "interfaces[{k}]: interface {} is not one of the scene's {} that can fail: {other}",
                i.interface,
                model.interfaces.iter().filter(|i| model.fails(i)).count()
            )));
        }
        interfaces.push(crate::force::failure::InterfaceFailure {
            interface: i.interface,
            status,
            opening: i.opening,
            slip: i.slip,
            dissipated: i.dissipated,
        });
    }
    Ok(FinalState {
        t: file.t,
        u,
        interfaces,
    })
}

/// The largest displacement of an element's vertex under `u` (`ndof` per element: a mode
/// shape, a mechanism), rotations and strains included: what the drawings and frames of a
/// shape scale to a tenth of the model's size.
pub fn largest_vertex_displacement(model: &Model, u: &[f64]) -> f64 {
    drawing::element_polygons(model, drawing::displacement(model, u))
        .iter()
        .flat_map(|p| p.2.iter())
        .map(|d| d.norm())
        .fold(0.0, f64::max)
}

/// Writes any serialisable value as pretty JSON, atomically ([`write_atomic`]).
///
/// # Errors
/// `value` does not serialise to JSON, or `path` cannot be written as [`write_atomic`] says.
pub fn write_json(path: &Path, value: &impl Serialize) -> Result<()> {
    // Streamed to the file: the text of a large final state is never whole in memory (it
    // was 67 MB in a vector of twice its room for 10⁵ elements).
    write_atomic_with(path, |file| {
        let mut w = std::io::BufWriter::new(file);
        serde_json::to_writer_pretty(&mut w, value)?;
        w.write_all(b"\n")?;
        w.flush()
    })
    .map(drop)
}

/// The temporary name beside `path` that [`write_atomic`] writes first: hidden, with the same
/// extension (readers such as vtkio pick the format by it).
pub fn temporary(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".part-{name}"))
}

/// Writes `bytes` to a temporary name beside `path`, then renames it over `path`: readers, and
/// a process killed half way, see the old file whole or the new one whole. Nothing is written
/// through a symbolic link: one at `path` is replaced by the file (its target left alone), and
/// the temporary file is created anew ([`create_fresh`]).
///
/// # Errors
/// The temporary file beside `path` cannot be created (no folder, no permission, or what is at that
/// name cannot be removed) or written, or cannot be renamed over `path`; it is then removed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_open(path, bytes).map(drop)
}

/// [`write_atomic`], returning the file written, open for writing at its end: a file that
/// grows (`history.csv`, the collections of VTK frames) goes on through this handle, never
/// through whatever the name may later point to.
///
/// # Errors
/// As [`write_atomic`].
pub fn write_atomic_open(path: &Path, bytes: &[u8]) -> Result<std::fs::File> {
    write_atomic_with(path, |file| file.write_all(bytes))
}

/// [`write_atomic_open`] of what `write` writes into the file.
fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut std::fs::File) -> std::io::Result<()>,
) -> Result<std::fs::File> {
    let tmp = temporary(path);
    let written = create_fresh(&tmp).and_then(|mut file| write(&mut file).map(|_| file));
    let file = written
        .and_then(|file| std::fs::rename(&tmp, path).map(|_| file))
        .map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            Error::io(path, e)
        })?;
    Ok(file)
}

/// Creates the file `path` anew for writing: what is there (a file, a symbolic link) is removed
/// first, and the file is created only if nothing is there then (`O_EXCL`, which follows no
/// link), so that the write cannot land in a link's target.
///
/// # Errors
/// What is at `path` cannot be removed, or the file cannot be created: no folder, no permission, or
/// something was put at `path` in between.
pub fn create_fresh(path: &Path) -> std::io::Result<std::fs::File> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
        _ => {}
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
}

/// `probes.csv`: the columns `keys`, then one column per probe (in the header its unit,
/// `name (m)`, or `unit` for all of them: mode shapes are `M`-normalised), a row per
/// `(key values, displacements)`.
///
/// # Errors
/// `dir/probes.csv` cannot be written; never when `probes` is empty.
pub fn write_probe_rows(
    dir: &Path,
    probes: &[Probe],
    keys: &[&str],
    rows: &[(Vec<String>, &[f64])],
    unit: Option<&str>,
) -> Result<()> {
    if probes.is_empty() {
        return Ok(());
    }
    let mut text = keys.join(",");
    for p in probes {
        text.push_str(&format!(",{} ({})", p.name, unit.unwrap_or(p.unit())));
    }
    text.push('\n');
    for (key, u) in rows {
        text.push_str(&key.join(","));
        for p in probes {
            text.push_str(&format!(",{:e}", p.value(u)));
        }
        text.push('\n');
    }
    crate::output::write_atomic(&dir.join("probes.csv"), text.as_bytes())
}

/// `1 body`, `2 bodies`, `0 bodies`: the one way every report and information line counts
/// things.
pub fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// `1.2 MB`, `35.0 kB`, `512 B`.
pub fn human_bytes(b: usize) -> String {
    match b {
        0..1000 => format!("{b} B"),
        1000..1_000_000 => format!("{:.1} kB", b as f64 / 1e3),
        1_000_000..1_000_000_000 => format!("{:.1} MB", b as f64 / 1e6),
        _ => format!("{:.2} GB", b as f64 / 1e9),
    }
}

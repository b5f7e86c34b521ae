//! Calibration of the facet law (`rbsm calibrate`, `docs/calibrate.md`): the facet parameters
//! that give a Voronoi material of rigid cells the macroscopic `E`, `ν`, `f_t`, `G_F` and `f_c`
//! a user measured. Facet-level strengths are not the material's: a Voronoi lattice peaks above
//! its facets' `f_t` and dissipates several `G_t` per unit section (validation §13), so every
//! code of the field calibrates them on the standard specimens, as this module does.
//!
//! - **Elastic** (round 0): the rigid lattice's `E` scales with the material's and its `ν` is
//!   set by `k_s/k_n` alone, so `rbsm effective` on each specimen mesh at a few material `ν`
//!   gives the material `ν` whose lattice `ν` is the target (interpolated on the seeds' mean),
//!   then the `E` that gives the target `E` ([`effective`]). A target above what the lattice can
//!   reach takes the highest it can, and the report says so.
//! - **Fracture** (rounds 1, 2, …): every cell size and seed runs a tension bar (`4w × w`, its
//!   ends clamped, one pulled) for `f_t`, a notched bar (`2w × w`) for `G_F` and a compression
//!   prism (`w × 2w` between smooth platens) for `f_c`. The three facet parameters
//!   `x = ln(f_t', s', G_t')` are moved towards the targets `y* = ln(f_t, f_c, G_F)` of the
//!   measured means `y` by Broyden's method, `x ← x − J⁻¹ (y − y*)`, from `J₀ = I` (each
//!   macroscopic figure proportional to its facet parameter); the cap and the shear fracture
//!   energy keep fixed ratios to `s'` and `G_t'`. The run stops when every mean is within its
//!   tolerance, or after `rounds` rounds with the best one.
//!
//! Each specimen run is a [`Job`], independent of the others and serialisable, so that the
//! command line runs a round's jobs on the cores ([`run_local`]) and the Python package on a
//! Dask cluster; [`next`] decides the next round from every [`Measured`] so far, so the
//! calibration itself is stateless.

use crate::analysis::effective;
use crate::analysis::setup::{Overrides, Setup};
use crate::analysis::Report;
use crate::error::{Error, Result};
use crate::input::scene::{FormulationSpec, Plane, Scene};
use crate::step::integrator::{CentralDifference, Status};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::time::Instant;

/// What `rbsm calibrate` reads: the material's targets, the mesh recipe and the fixed parts of
/// the facet law (`docs/calibrate.md`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationSpec {
    /// The material's name: the key of the block the calibration writes.
    pub name: String,
    /// The macroscopic figures to reach.
    pub targets: Targets,
    /// Density (kg/m³), > 0.
    pub rho: f64,
    /// Plane stress (default) or strain, as the scenes that will use the material.
    #[serde(default)]
    pub plane: Plane,
    /// The Voronoi meshes: cell sizes and seeds.
    pub cells: Cells,
    /// The specimens' width `w` (m): tension bars `4w × w`, compression prisms `w × 2w`.
    pub width: f64,
    /// The cells' formulation, as the scenes that will use the material: `rigid` (default),
    /// `rigid-poisson` (whose lattice has the material's `ν`) or `hybrid`.
    #[serde(default = "default_formulation")]
    pub formulation: FormulationSpec,
    /// The parts of the facet law that the calibration keeps fixed.
    #[serde(default)]
    pub law: LawRatios,
    /// Largest number of fracture rounds, in [1, 30]; 8 when absent.
    #[serde(default = "default_rounds")]
    pub rounds: usize,
    /// Relative tolerance on each mean.
    #[serde(default)]
    pub tolerance: Tolerance,
}

/// How close each mean over the sizes and seeds must come to its target, relative, each in
/// [0.001, 0.2].
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Tolerance {
    /// On `f_t` (0.02).
    pub tensile_strength: f64,
    /// On `f_c` (0.02).
    pub compressive_strength: f64,
    /// On `G_F` (0.05): a crack's path between cells changes by jumps as the parameters move,
    /// and the work it spends with it.
    pub fracture_energy: f64,
}

impl Default for Tolerance {
    fn default() -> Self {
        Tolerance {
            tensile_strength: 0.02,
            compressive_strength: 0.02,
            fracture_energy: 0.05,
        }
    }
}

impl Tolerance {
    /// In the order of the figures: `f_t`, `f_c`, `G_F`.
    fn each(&self) -> [f64; 3] {
        [
            self.tensile_strength,
            self.compressive_strength,
            self.fracture_energy,
        ]
    }
}

fn default_rounds() -> usize {
    8
}

/// A material's measured figures.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Targets {
    /// Young's modulus (Pa), > 0.
    #[serde(rename = "E")]
    pub e: f64,
    /// Poisson's ratio, in [0, 0.5).
    pub nu: f64,
    /// Uniaxial tensile strength `f_t` (Pa), > 0.
    pub tensile_strength: f64,
    /// Fracture energy `G_F` (J/m²), > 0: the work of fracture per unit ligament of a notched
    /// bar in tension ([`Test::Notched`], [`OPENING`]).
    pub fracture_energy: f64,
    /// Uniaxial compressive strength `f_c` (Pa), > `tensile_strength`.
    pub compressive_strength: f64,
}

/// The meshes of the specimens.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cells {
    /// `voronoi` (default) or `grid`: squares, on which facet and macroscopic figures
    /// coincide (a check of the method, `docs/calibrate.md`).
    #[serde(default)]
    pub kind: CellKind,
    /// Cell sizes `h` (m), 1 to 5 of them, each in (0, w/4]: a specimen of area `A` has
    /// `A/h²` cells.
    pub sizes: Vec<f64>,
    /// Seeds of the random sites, 1 to 20 of them.
    pub seeds: Vec<u64>,
    /// Lloyd iterations, in [0, 100]; 10 when absent.
    #[serde(default = "default_lloyd")]
    pub lloyd: u32,
}

/// The cells of the specimens.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CellKind {
    /// Centroidal Voronoi cells (`seeds` and `lloyd` apply).
    #[default]
    Voronoi,
    /// Squares of side `h` (the seeds only repeat the run).
    Grid,
}

fn default_formulation() -> FormulationSpec {
    FormulationSpec::Rigid
}

fn default_lloyd() -> u32 {
    10
}

/// The facet law's parameters that stay fixed, as ratios.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LawRatios {
    /// The cap `f_c'` over the shear strength `s'`, > 0 (4).
    pub cap: f64,
    /// `G_s / G_t`, > 0 (10).
    pub energy: f64,
    /// Friction coefficient `μ₀`, ≥ 0 (0.6).
    pub friction: f64,
    /// Friction coefficient `μ_∞` at high pressure, in [0, `friction`] (0.1).
    pub friction_residual: f64,
}

impl Default for LawRatios {
    fn default() -> Self {
        LawRatios {
            cap: 4.0,
            energy: 10.0,
            friction: 0.6,
            friction_residual: 0.1,
        }
    }
}

/// The opening, in `G_F/f_t` of the targets, past the notched bar's elastic stretch at which its
/// pull stops: the work of fracture is counted to there, and the load left is reported (`tail`).
pub const OPENING: f64 = 40.0;

/// The depth of each notch of [`Test::Notched`] over the width: the ligament is `1 − 2 NOTCH`
/// of it.
pub const NOTCH: f64 = 0.2;

/// The material `ν` at which round 0 measures the lattice's.
const NU_GRID: [f64; 6] = [0.0, 0.1, 0.2, 0.3, 0.4, 0.49];

/// Largest change of a facet parameter in one round (a factor).
const STEP_LIMIT: f64 = 3.0;

fn positive(key: &str, v: f64, what: &str) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::scene(key, format!("{what}: must be > 0, got {v}")))
    }
}

fn within(key: &str, v: f64, lo: f64, hi: f64) -> Result<()> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(Error::scene(
            key,
            format!("must be in [{lo}, {hi}], got {v}"),
        ))
    }
}

impl CalibrationSpec {
    /// Reads and checks a calibration file.
    ///
    /// # Errors
    /// A file that cannot be read or parsed, an unknown key, or a value out of its range,
    /// named by its path.
    pub fn from_file(path: &std::path::Path) -> Result<CalibrationSpec> {
        let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_json(&text).map_err(|e| match e {
            Error::Parse { message, .. } => Error::Parse {
                path: path.display().to_string(),
                message,
            },
            e => e,
        })
    }

    /// Parses and checks a calibration's JSON text.
    ///
    /// # Errors
    /// As [`CalibrationSpec::from_file`].
    pub fn from_json(text: &str) -> Result<CalibrationSpec> {
        let spec: CalibrationSpec = crate::input::scene::from_json_text(text)?;
        spec.validate()?;
        Ok(spec)
    }

    /// Every key in its range.
    ///
    /// # Errors
    /// The first key out of range, with the range.
    pub fn validate(&self) -> Result<()> {
        let t = &self.targets;
        positive("targets.E", t.e, "Young's modulus (Pa)")?;
        if let FormulationSpec::Hybrid { penalty } = self.formulation {
            positive("formulation.penalty", penalty, "the penalty factor")?;
        }
        if !(t.nu.is_finite() && (0.0..0.5).contains(&t.nu)) {
            return Err(Error::scene(
                "targets.nu",
                format!("must be in [0, 0.5), got {}", t.nu),
            ));
        }
        positive("targets.tensile_strength", t.tensile_strength, "f_t (Pa)")?;
        positive("targets.fracture_energy", t.fracture_energy, "G_F (J/m²)")?;
        positive(
            "targets.compressive_strength",
            t.compressive_strength,
            "f_c (Pa)",
        )?;
        if t.compressive_strength <= t.tensile_strength {
            return Err(Error::scene(
                "targets.compressive_strength",
                format!(
                    "must be above targets.tensile_strength ({}), got {}",
                    t.tensile_strength, t.compressive_strength
                ),
            ));
        }
        positive("rho", self.rho, "density (kg/m³)")?;
        positive("width", self.width, "the specimens' width (m)")?;
        let c = &self.cells;
        if c.sizes.is_empty() || c.sizes.len() > 5 {
            return Err(Error::scene(
                "cells.sizes",
                format!("give 1 to 5 cell sizes, got {}", c.sizes.len()),
            ));
        }
        for (i, &h) in c.sizes.iter().enumerate() {
            let key = format!("cells.sizes[{i}]");
            positive(&key, h, "a cell size (m)")?;
            if h > self.width / 4.0 {
                return Err(Error::scene(
                    key,
                    format!(
                        "must be at most width/4 = {} (4 cells across a specimen), got {h}",
                        self.width / 4.0
                    ),
                ));
            }
            if 8.0 * self.width * self.width / (h * h) > 2.0e5 {
                return Err(Error::scene(
                    key,
                    format!(
                        "gives {:.0} cells per specimen; at most 100000 (h ≥ {:.3e} m)",
                        4.0 * self.width * self.width / (h * h),
                        self.width / 158.0
                    ),
                ));
            }
        }
        if c.seeds.is_empty() || c.seeds.len() > 20 {
            return Err(Error::scene(
                "cells.seeds",
                format!("give 1 to 20 seeds, got {}", c.seeds.len()),
            ));
        }
        within("cells.lloyd", f64::from(c.lloyd), 0.0, 100.0)?;
        let l = &self.law;
        positive("law.cap", l.cap, "the cap over the shear strength")?;
        positive("law.energy", l.energy, "G_s / G_t")?;
        within("law.friction", l.friction, 0.0, 10.0)?;
        within(
            "law.friction_residual",
            l.friction_residual,
            0.0,
            l.friction,
        )?;
        within("rounds", self.rounds as f64, 1.0, 30.0)?;
        let t = &self.tolerance;
        within("tolerance.tensile_strength", t.tensile_strength, 0.001, 0.2)?;
        within(
            "tolerance.compressive_strength",
            t.compressive_strength,
            0.001,
            0.2,
        )?;
        within("tolerance.fracture_energy", t.fracture_energy, 0.001, 0.2)
    }

    /// The wave speed `√(E/ρ)` of the targets (m/s).
    fn wave_speed(&self) -> f64 {
        (self.targets.e / self.rho).sqrt()
    }
}

/// A standard specimen test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Test {
    /// The effective elastic constants of the tension bar's mesh ([`effective`]).
    Elastic,
    /// The tension bar pulled past its peak: `f_t`.
    Tension,
    /// A bar `2w × w` with a notch [`NOTCH`] `w` deep and `2h` wide in each long edge at
    /// mid-length (squares: no notch), pulled to [`OPENING`]: `G_F` over the ligament. The
    /// notches hold the crack to one section, so that its work is that of one crack.
    Notched,
    /// The compression prism pushed until its load levels off: `f_c`.
    Compression,
}

/// The parameters a round gives a specimen's material: the scene's `E`, `ν` and the facet
/// law's three calibrated values (the rest from [`LawRatios`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Facet {
    /// The scene's `E` (Pa).
    #[serde(rename = "E")]
    pub e: f64,
    /// The scene's `ν`.
    pub nu: f64,
    /// The facets' `f_t'` (Pa).
    pub tensile_strength: f64,
    /// The facets' `s'` (Pa).
    pub shear_strength: f64,
    /// The facets' `G_t'` (J/m²).
    pub fracture_energy: f64,
}

/// One specimen run.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Job {
    /// The round (0: elastic).
    pub round: usize,
    /// The test.
    pub test: Test,
    /// The cell size (m).
    pub size: f64,
    /// The seed of the sites.
    pub seed: u64,
    /// The material.
    pub facet: Facet,
}

/// What one specimen run measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measured {
    /// The run.
    pub job: Job,
    /// Elements of the specimen.
    pub elements: usize,
    /// Explicit steps (0 for [`Test::Elastic`]).
    pub steps: u64,
    /// Wall time of the run (s).
    pub seconds: f64,
    /// Elastic: `E` (Pa); the others: the peak stress (Pa), over the ligament when notched.
    pub first: f64,
    /// Elastic: `ν`; notched: the work of fracture per unit ligament (J/m²); else 0.
    pub second: f64,
    /// Notched: the load left at the end over the peak; compression: 1 if the load levelled
    /// off before 2 % strain, else 0; else 0.
    pub third: f64,
}

/// What the calibration does next.
pub enum Next {
    /// Run these jobs and call [`next`] again with their results added; `last` is the fracture
    /// round just measured, if any.
    Run {
        /// The next round's jobs.
        jobs: Vec<Job>,
        /// The round before, as the report will list it.
        last: Option<RoundRow>,
    },
    /// Done: the report.
    Done(Box<CalibrationReport>),
}

/// A scene's material block made of a [`Facet`] and the fixed ratios.
pub fn material_block(spec: &CalibrationSpec, f: &Facet) -> Value {
    let l = &spec.law;
    json!({
        "E": f.e, "nu": f.nu, "rho": spec.rho,
        "interface": {
            "kind": "facet",
            "tensile_strength": f.tensile_strength,
            "shear_strength": f.shear_strength,
            "fracture_energy": f.fracture_energy,
            "fracture_energy_shear": l.energy * f.fracture_energy,
            "compressive_strength": l.cap * f.shear_strength,
            "friction": l.friction,
            "friction_residual": l.friction_residual,
        }
    })
}

/// The specimen scene of a job: a tension bar, a notched bar or a compression prism, loaded
/// by a clamp at a speed that reaches the target's peak strain in many periods of the
/// specimen's first axial mode, with 2 % of critical mass damping on that mode.
pub fn specimen_scene(spec: &CalibrationSpec, job: &Job) -> Value {
    let w = spec.width;
    let c = spec.wave_speed();
    let t = &spec.targets;
    let (size, supports, length) = match job.test {
        Test::Elastic | Test::Tension | Test::Notched => {
            let l = if job.test == Test::Notched { 2.0 } else { 4.0 } * w;
            // 8 periods 2L/c to the peak strain; the ramp over 2 of them.
            let v = t.tensile_strength * c / (16.0 * t.e);
            (
                [l, w],
                json!([{"kind": "clamp", "edge": "left"},
                    {"kind": "clamp", "edge": "right", "velocity": [v, 0.0], "ramp": 4.0 * l / c}]),
                l,
            )
        }
        Test::Compression => {
            let h = 2.0 * w;
            // 24 periods to the elastic strain of f_c: its peak comes later, past yielding.
            let v = t.compressive_strength * c / (48.0 * t.e);
            (
                [w, h],
                json!([{"kind": "clamp", "edge": "bottom", "dofs": ["v"]},
                    {"kind": "clamp", "edge": "top", "dofs": ["v"], "velocity": [0.0, -v],
                     "ramp": 4.0 * h / c}]),
                h,
            )
        }
    };
    let mesh = match spec.cells.kind {
        CellKind::Voronoi if job.test == Test::Notched => {
            let (a, n, m) = (NOTCH * w, 2.0 * job.size, w);
            let notched = [
                [0.0, 0.0],
                [m - n / 2.0, 0.0],
                [m - n / 2.0, a],
                [m + n / 2.0, a],
                [m + n / 2.0, 0.0],
                [2.0 * w, 0.0],
                [2.0 * w, w],
                [m + n / 2.0, w],
                [m + n / 2.0, w - a],
                [m - n / 2.0, w - a],
                [m - n / 2.0, w],
                [0.0, w],
            ];
            json!({"kind": "voronoi", "origin": [0.0, 0.0], "size": size,
                "sites": ((size[0] * size[1] - 2.0 * a * n) / (job.size * job.size)).round() as usize,
                "seed": job.seed, "lloyd": spec.cells.lloyd,
                "domain": {"kind": "polygon", "vertices": notched}})
        }
        CellKind::Voronoi => json!({"kind": "voronoi", "origin": [0.0, 0.0], "size": size,
            "sites": (size[0] * size[1] / (job.size * job.size)).round().max(4.0) as usize,
            "seed": job.seed, "lloyd": spec.cells.lloyd}),
        CellKind::Grid => json!({"kind": "grid", "origin": [0.0, 0.0], "size": size,
            "cells": size.map(|l| (l / job.size).round().max(1.0) as usize), "cell": "rect"}),
    };
    json!({
        "name": format!("{}-{:?}-h{:.3e}-seed{}", spec.name, job.test, job.size, job.seed).to_lowercase(),
        "thickness": 1.0,
        "plane": spec.plane,
        "formulation": spec.formulation,
        "evaluator": "element-wise",
        "materials": {"m": material_block(spec, &job.facet)},
        "damping": 0.04 * std::f64::consts::PI * c / length,
        "bodies": [{"name": "specimen", "material": "m",
            "mesh": mesh,
            "supports": supports}],
        "time": {"dt_factor": 0.5, "end": 1.0},
    })
}

/// Runs one job.
///
/// # Errors
/// A specimen that cannot be built or whose run diverges, named by its test, size and seed.
pub fn specimen(spec: &CalibrationSpec, job: &Job) -> Result<Measured> {
    let started = Instant::now();
    let name = || {
        format!(
            "{:?} specimen, h = {}, seed {}",
            job.test, job.size, job.seed
        )
    };
    let scene = Scene::from_json(&specimen_scene(spec, job).to_string())?;
    let overrides = match job.test {
        Test::Elastic => Overrides::no_step(),
        _ => Overrides::default(),
    };
    let setup = Setup::new(&scene, &overrides)?;
    let elements = setup.model.elements.len();
    let w = spec.width;
    let t = &spec.targets;
    let (steps, first, second, third) = match job.test {
        Test::Elastic => {
            let r = effective::analyse(&setup)?;
            (0, r.young, r.poisson, 0.0)
        }
        test => {
            let length = match test {
                Test::Notched => 2.0 * w,
                Test::Compression => 2.0 * w,
                _ => 4.0 * w,
            };
            let strength = if test == Test::Compression {
                t.compressive_strength
            } else {
                t.tensile_strength
            };
            let elastic = strength / t.e * length;
            let end = if test == Test::Compression {
                0.02 * length
            } else {
                elastic + OPENING * t.fracture_energy / t.tensile_strength
            };
            let (mut mark, mut d_mark, mut levelled) = (0.0, 0.0, false);
            let (pulled, _) = displace(&setup, |p| {
                match test {
                    // Levelled off: the peak has grown by less than 1 % over the last half
                    // of the travel.
                    Test::Compression => {
                        if p.peak > 1.01 * mark {
                            (mark, d_mark) = (p.peak, p.travel);
                        }
                        levelled = p.travel >= 2.0 * d_mark && p.travel >= 2.0 * elastic;
                    }
                    // Past the peak: the load below half of it, beyond the elastic stretch.
                    Test::Tension => levelled = p.travel > elastic && p.load < 0.5 * p.peak,
                    _ => {}
                }
                levelled || p.travel >= end
            })
            .map_err(|e| Error::scene("calibration", format!("{}: {e}", name())))?;
            let section = match (test, spec.cells.kind) {
                (Test::Notched, CellKind::Voronoi) => (1.0 - 2.0 * NOTCH) * w,
                _ => w,
            } * scene.thickness;
            let (work, third) = match test {
                Test::Notched => (
                    pulled.work / section,
                    pulled.load / pulled.peak.max(f64::MIN_POSITIVE),
                ),
                Test::Compression => (0.0, if levelled { 1.0 } else { 0.0 }),
                _ => (0.0, 0.0),
            };
            (pulled.steps, pulled.peak / section, work, third)
        }
    };
    Ok(Measured {
        job: job.clone(),
        elements,
        steps,
        seconds: started.elapsed().as_secs_f64(),
        first,
        second,
        third,
    })
}

/// Where a displacement-controlled run stands, at a check.
#[derive(Debug, Clone, Copy, Default)]
pub struct Pulled {
    /// Steps taken.
    pub steps: u64,
    /// The travel of the last moving clamp (m).
    pub travel: f64,
    /// Its reaction along its velocity (N), what it pulls or pushes with, now.
    pub load: f64,
    /// The largest such reaction so far, over every step (N).
    pub peak: f64,
    /// The work the interfaces have dissipated (the `fracture` and `friction` books, J).
    pub work: f64,
}

/// Steps a setup whose last support is a moving clamp, checking every 200 steps, until `stop`
/// says so; returns where it stands and the integrator (its failure state, for a report).
///
/// # Errors
/// A setup without a moving clamp, or a run that diverges (the step and the reason).
pub fn displace<'s>(
    setup: &'s Setup,
    mut stop: impl FnMut(&Pulled) -> bool,
) -> Result<(Pulled, CentralDifference<'s>)> {
    let clamp = setup.model.prescribed.last().cloned().ok_or_else(|| {
        Error::scene(
            "bodies",
            "a displacement-controlled run needs a moving clamp",
        )
    })?;
    let speed = clamp.velocity.norm();
    let mut cd = setup.integrator(setup.dt);
    let mut now = Pulled::default();
    loop {
        let status = cd.run(
            200,
            200,
            |s, e| {
                now = Pulled {
                    steps: s.step,
                    travel: speed * clamp.travel(s.t),
                    load: s.reactions.last().copied().unwrap_or(0.0),
                    peak: s.peaks.last().map_or(0.0, |p| p[0].max(0.0)),
                    work: e.fracture + e.friction,
                };
                Ok(())
            },
            |_| {},
        )?;
        if status != Status::Ok {
            return Err(Error::scene(
                "time",
                format!("the run stopped at step {}: {status:?}", cd.step),
            ));
        }
        if stop(&now) {
            return Ok((now, cd));
        }
    }
}

/// Runs jobs on this machine's cores, each job on one core at a time (rayon's pool), in order.
pub fn run_local(spec: &CalibrationSpec, jobs: &[Job]) -> Vec<Result<Measured>> {
    jobs.par_iter().map(|j| specimen(spec, j)).collect()
}

/// Calibrates: rounds of jobs run by `run` (which returns their results in order), each round
/// chosen by [`next`] from all results so far; `progress` hears each round's number and jobs
/// and the fracture round measured before it.
///
/// # Errors
/// A job that fails (its error), or a calibration that cannot go on.
pub fn calibrate(
    spec: &CalibrationSpec,
    mut run: impl FnMut(&[Job]) -> Vec<Result<Measured>>,
    mut progress: impl FnMut(usize, usize, Option<&RoundRow>),
) -> Result<CalibrationReport> {
    let started = Instant::now();
    let mut done: Vec<Measured> = Vec::new();
    loop {
        match next(spec, &done)? {
            Next::Done(mut report) => {
                report.wall_seconds = started.elapsed().as_secs_f64();
                return Ok(*report);
            }
            Next::Run { jobs, last } => {
                progress(jobs[0].round, jobs.len(), last.as_ref());
                for r in run(&jobs) {
                    done.push(r?);
                }
            }
        }
    }
}

/// The tests of a fracture round.
const ALL: [Test; 4] = [
    Test::Elastic,
    Test::Tension,
    Test::Notched,
    Test::Compression,
];

/// The jobs of one round at one facet: every test, size and seed.
fn round_jobs(spec: &CalibrationSpec, round: usize, tests: &[Test], facet: Facet) -> Vec<Job> {
    let mut jobs = Vec::new();
    for &test in tests {
        for &size in &spec.cells.sizes {
            for &seed in &spec.cells.seeds {
                jobs.push(Job {
                    round,
                    test,
                    size,
                    seed,
                    facet,
                });
            }
        }
    }
    jobs
}

/// The mean and coefficient of variation of some values.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Stat {
    /// The mean.
    pub mean: f64,
    /// The sample standard deviation over the mean (0 for one value).
    pub cv: f64,
}

impl Stat {
    /// Of some values: their mean and sample standard deviation over the mean.
    pub fn of(values: impl Iterator<Item = f64>) -> Stat {
        let v: Vec<f64> = values.collect();
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let var = if v.len() > 1 {
            v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)
        } else {
            0.0
        };
        Stat {
            mean,
            cv: var.sqrt() / mean.abs(),
        }
    }
}

/// The figures of one round at one cell size, over the seeds.
#[derive(Debug, Clone, Serialize)]
pub struct SizeFigures {
    /// The cell size (m).
    pub size: f64,
    /// Elements of the tension bar, the notched bar and the compression prism (first seed).
    pub elements: [usize; 3],
    /// `E` (Pa).
    #[serde(rename = "E")]
    pub e: Stat,
    /// `ν`.
    pub nu: Stat,
    /// `f_t` (Pa).
    pub tensile_strength: Stat,
    /// `G_F` (J/m²).
    pub fracture_energy: Stat,
    /// `f_c` (Pa).
    pub compressive_strength: Stat,
    /// The largest load left at the end of a notched bar's run over its peak.
    pub tail: f64,
    /// Compression prisms whose load did not level off before 2 % strain.
    pub unlevelled: usize,
}

/// One fracture round: the facet it ran and the means it measured.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RoundRow {
    /// The round (1, 2, …).
    pub round: usize,
    /// The material it ran.
    pub facet: Facet,
    /// Mean `f_t`, `f_c`, `G_F` over every size and seed, over the targets.
    pub ratios: [f64; 3],
}

/// What `rbsm calibrate` reports.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationReport {
    /// The material's name.
    pub name: String,
    /// Whether a round reached every target within the tolerance.
    pub converged: bool,
    /// The targets.
    pub targets: Targets,
    /// The round whose material is reported (the last, or the best when not converged).
    pub chosen: usize,
    /// The calibrated material, a block for a scene's `materials`.
    pub material: Value,
    /// The chosen round's figures per cell size.
    pub sizes: Vec<SizeFigures>,
    /// Every fracture round.
    pub rounds: Vec<RoundRow>,
    /// The lattice's `ν` as round 0 measured it at each material `ν` (means over sizes and seeds).
    pub lattice_nu: Vec<[f64; 2]>,
    /// Said when the target `ν` is beyond what the lattice reaches.
    pub note: Option<String>,
    /// Specimen runs, explicit element-steps and their summed wall time (s).
    pub runs: usize,
    /// Explicit element-steps in all.
    pub element_steps: f64,
    /// The runs' wall times summed (s).
    pub run_seconds: f64,
    /// Wall time of the whole calibration (s).
    pub wall_seconds: f64,
}

/// The next round from the results so far (`done` holds whole rounds, in the order the jobs
/// were given).
///
/// # Errors
/// Results that are not whole rounds of this calibration.
pub fn next(spec: &CalibrationSpec, done: &[Measured]) -> Result<Next> {
    let by_round = |r: usize| done.iter().filter(move |m| m.job.round == r);
    let rounds = done.iter().map(|m| m.job.round).max();
    let Some(last) = rounds else {
        // Round 0: the lattice's E and ν at a few material ν.
        let t = &spec.targets;
        let mut jobs = Vec::new();
        for nu in NU_GRID {
            let facet = Facet {
                e: t.e,
                nu,
                tensile_strength: t.tensile_strength,
                shear_strength: t.compressive_strength / spec.law.cap,
                fracture_energy: t.fracture_energy,
            };
            jobs.extend(round_jobs(spec, 0, &[Test::Elastic], facet));
        }
        return Ok(Next::Run { jobs, last: None });
    };
    let expected = spec.cells.sizes.len() * spec.cells.seeds.len();
    for r in 0..=last {
        let n = by_round(r).count();
        let want = if r == 0 { NU_GRID.len() } else { ALL.len() } * expected;
        if n != want {
            return Err(Error::scene(
                "calibration",
                format!("round {r} has {n} results, {want} expected"),
            ));
        }
    }
    // Round 0: the material ν whose lattice ν is the target, and the E that goes with it.
    let mut lattice = Vec::new();
    for nu in NU_GRID {
        let at = || by_round(0).filter(move |m| m.job.facet.nu == nu);
        let e = at().map(|m| m.first / m.job.facet.e).sum::<f64>() / expected as f64;
        let l = at().map(|m| m.second).sum::<f64>() / expected as f64;
        lattice.push((nu, l, e));
    }
    let (nu, factor, note) = lattice_material(&lattice, spec.targets.nu);
    let t = &spec.targets;
    let y_star = [
        t.tensile_strength.ln(),
        t.compressive_strength.ln(),
        t.fracture_energy.ln(),
    ];
    let all = ALL;
    if last == 0 {
        // Start: the facets at the targets, the shear strength at f_c over the cap ratio.
        let facet = Facet {
            e: t.e / factor,
            nu,
            tensile_strength: t.tensile_strength,
            shear_strength: t.compressive_strength / spec.law.cap,
            fracture_energy: t.fracture_energy,
        };
        return Ok(Next::Run {
            jobs: round_jobs(spec, 1, &all, facet),
            last: None,
        });
    }
    // Replay Broyden's method over the rounds run.
    let mut rows = Vec::new();
    let mut jac = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut prev: Option<([f64; 3], [f64; 3])> = None;
    for r in 1..=last {
        let facet = by_round(r)
            .next()
            .ok_or_else(|| Error::scene("calibration", format!("round {r} has no result")))?
            .job
            .facet;
        let x = [
            facet.tensile_strength.ln(),
            facet.shear_strength.ln(),
            facet.fracture_energy.ln(),
        ];
        let mean = |test: Test, f: fn(&Measured) -> f64| {
            by_round(r)
                .filter(|m| m.job.test == test)
                .map(f)
                .sum::<f64>()
                / expected as f64
        };
        let y = [
            mean(Test::Tension, |m| m.first).ln(),
            mean(Test::Compression, |m| m.first).ln(),
            mean(Test::Notched, |m| m.second).ln(),
        ];
        if let Some((px, py)) = prev {
            broyden(&mut jac, sub(x, px), sub(y, py));
        }
        prev = Some((x, y));
        rows.push((facet, x, y));
    }
    let ratio = |y: &[f64; 3]| [0, 1, 2].map(|i| (y[i] - y_star[i]).exp());
    let &(facet, x, y) = rows
        .last()
        .ok_or_else(|| Error::scene("calibration", "no fracture round to go on from"))?;
    // The largest miss in units of its tolerance: 1 or less is converged.
    let tolerance = spec.tolerance.each();
    let off = |y: &[f64; 3]| {
        (0..3)
            .map(|i| (ratio(y)[i] - 1.0).abs() / tolerance[i])
            .fold(0.0, f64::max)
    };
    let converged = off(&y) <= 1.0;
    if !converged && last < spec.rounds {
        let dx = solve3(jac, sub(y_star, y))
            .unwrap_or_else(|| sub(y_star, y))
            .map(|d| d.clamp(-STEP_LIMIT.ln(), STEP_LIMIT.ln()));
        let x = [x[0] + dx[0], x[1] + dx[1], x[2] + dx[2]];
        let facet = Facet {
            tensile_strength: x[0].exp(),
            shear_strength: x[1].exp(),
            fracture_energy: x[2].exp(),
            ..facet
        };
        return Ok(Next::Run {
            jobs: round_jobs(spec, last + 1, &all, facet),
            last: Some(RoundRow {
                round: last,
                facet: rows[last - 1].0,
                ratios: ratio(&y),
            }),
        });
    }
    let chosen = if converged {
        last
    } else {
        (0..rows.len())
            .min_by(|&a, &b| off(&rows[a].2).total_cmp(&off(&rows[b].2)))
            .map_or(last, |i| i + 1)
    };
    let report = report(spec, done, chosen, converged, &rows, lattice, note, ratio);
    Ok(Next::Done(Box::new(report)))
}

/// The material `ν` (linear between the measured points) whose lattice `ν` is `target`, the
/// lattice's `E` over the material's there, and a note when the target is out of reach. A
/// lattice whose `ν` does not follow the material's (squares: 0) keeps the target as the
/// material's `ν`.
fn lattice_material(points: &[(f64, f64, f64)], target: f64) -> (f64, f64, Option<String>) {
    let lo = points.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let hi = points.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    // Linear in `points` between the pair that brackets `v` in column `col`.
    let along = |col: fn(&(f64, f64, f64)) -> f64, v: f64| {
        points
            .windows(2)
            .find(|p| (col(&p[0]) - v) * (col(&p[1]) - v) <= 0.0 && col(&p[0]) != col(&p[1]))
            .map(|p| {
                let s = (v - col(&p[0])) / (col(&p[1]) - col(&p[0]));
                (
                    p[0].0 + s * (p[1].0 - p[0].0),
                    p[0].2 + s * (p[1].2 - p[0].2),
                )
            })
    };
    if hi - lo < 1e-6 {
        let (_, factor) = along(|p| p.0, target).unwrap_or((target, points[0].2));
        let note = format!(
            "these cells' ν is {:.3} whatever the material's; the material keeps the target's",
            0.5 * (lo + hi) + 0.0
        );
        return (target, factor, Some(note));
    }
    let clamped = target.clamp(lo, hi);
    let note = (clamped != target).then(|| {
        format!(
            "the target ν = {target} is beyond what these cells reach ({:.3} to {:.3}); the \
             material takes the nearest",
            (lo * 1e3).round() / 1e3 + 0.0,
            hi
        )
    });
    let (nu, factor) = along(|p| p.1, clamped).unwrap_or_else(|| {
        // The extreme sits at a grid point that no pair brackets with a change of sign.
        let p = points
            .iter()
            .min_by(|a, b| (a.1 - clamped).abs().total_cmp(&(b.1 - clamped).abs()))
            .expect("a grid");
        (p.0, p.2)
    });
    (nu, factor, note)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Broyden's ("good") update of `J` so that `J Δx = Δy`.
fn broyden(j: &mut [[f64; 3]; 3], dx: [f64; 3], dy: [f64; 3]) {
    let n2: f64 = dx.iter().map(|v| v * v).sum();
    if n2 < 1e-12 {
        return;
    }
    for i in 0..3 {
        let jdx: f64 = (0..3).map(|k| j[i][k] * dx[k]).sum();
        let r = (dy[i] - jdx) / n2;
        for k in 0..3 {
            j[i][k] += r * dx[k];
        }
    }
}

/// `A⁻¹ b` by Cramer's rule; `None` when `A` is nearly singular.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&a);
    if d.abs() < 1e-6 {
        return None;
    }
    Some([0, 1, 2].map(|c| {
        let mut m = a;
        for r in 0..3 {
            m[r][c] = b[r];
        }
        det(&m) / d
    }))
}

#[allow(clippy::too_many_arguments)]
fn report(
    spec: &CalibrationSpec,
    done: &[Measured],
    chosen: usize,
    converged: bool,
    rows: &[(Facet, [f64; 3], [f64; 3])],
    lattice: Vec<(f64, f64, f64)>,
    note: Option<String>,
    ratio: impl Fn(&[f64; 3]) -> [f64; 3],
) -> CalibrationReport {
    let facet = rows[chosen - 1].0;
    let sizes = spec
        .cells
        .sizes
        .iter()
        .map(|&size| {
            let of = |test: Test| {
                done.iter().filter(move |m| {
                    m.job.round == chosen && m.job.test == test && m.job.size == size
                })
            };
            let first = |test: Test| of(test).next().map_or(0, |m| m.elements);
            SizeFigures {
                size,
                elements: [
                    first(Test::Tension),
                    first(Test::Notched),
                    first(Test::Compression),
                ],
                e: Stat::of(of(Test::Elastic).map(|m| m.first)),
                nu: Stat::of(of(Test::Elastic).map(|m| m.second)),
                tensile_strength: Stat::of(of(Test::Tension).map(|m| m.first)),
                fracture_energy: Stat::of(of(Test::Notched).map(|m| m.second)),
                compressive_strength: Stat::of(of(Test::Compression).map(|m| m.first)),
                tail: of(Test::Notched).map(|m| m.third).fold(0.0, f64::max),
                unlevelled: of(Test::Compression).filter(|m| m.third == 0.0).count(),
            }
        })
        .collect();
    CalibrationReport {
        name: spec.name.clone(),
        converged,
        targets: spec.targets,
        chosen,
        material: material_block(spec, &facet),
        sizes,
        rounds: rows
            .iter()
            .enumerate()
            .map(|(i, (facet, _, y))| RoundRow {
                round: i + 1,
                facet: *facet,
                ratios: ratio(y),
            })
            .collect(),
        lattice_nu: lattice.iter().map(|p| [p.0, p.1]).collect(),
        note,
        runs: done.len(),
        element_steps: done
            .iter()
            .map(|m| m.elements as f64 * m.steps as f64)
            .sum(),
        run_seconds: done.iter().map(|m| m.seconds).sum(),
        wall_seconds: 0.0,
    }
}

impl Report for CalibrationReport {
    fn text(&self) -> String {
        let t = &self.targets;
        let mut s = format!(
            "{}: {} after {} round(s) ({} specimen runs, {:.3e} element-steps, {:.1} s of runs, \
             {:.1} s wall)\n",
            self.name,
            if self.converged {
                "converged"
            } else {
                "NOT converged (the best round is reported)"
            },
            self.rounds.len(),
            self.runs,
            self.element_steps,
            self.run_seconds,
            self.wall_seconds
        );
        if let Some(n) = &self.note {
            s += &format!("  note: {n}\n");
        }
        s += "  round | f_t' (Pa) | s' (Pa) | G_t' (J/m²) | f_t/target | f_c/target | G_F/target\n";
        for r in &self.rounds {
            s += &format!(
                "  {:>5} | {:.4e} | {:.4e} | {:.4e} | {:.4} | {:.4} | {:.4}\n",
                r.round,
                r.facet.tensile_strength,
                r.facet.shear_strength,
                r.facet.fracture_energy,
                r.ratios[0],
                r.ratios[1],
                r.ratios[2]
            );
        }
        s += &format!(
            "  round {} per cell size (mean over seeds, CV in brackets), against the targets:\n",
            self.chosen
        );
        s += "  h (m) | cells (bar, notched bar, prism) | E | ν | f_t | G_F | f_c | f_c/f_t | tail\n";
        let pct = |st: &Stat, target: f64| {
            format!(
                "{:+.2} % ({:.1} %)",
                100.0 * (st.mean / target - 1.0),
                100.0 * st.cv
            )
        };
        for z in &self.sizes {
            s += &format!(
                "  {:.3e} | {}, {}, {} | {} | {:.4} ({:.1} %) | {} | {} | {} | {:.2} | {:.3}{}\n",
                z.size,
                z.elements[0],
                z.elements[1],
                z.elements[2],
                pct(&z.e, t.e),
                z.nu.mean,
                100.0 * z.nu.cv,
                pct(&z.tensile_strength, t.tensile_strength),
                pct(&z.fracture_energy, t.fracture_energy),
                pct(&z.compressive_strength, t.compressive_strength),
                z.compressive_strength.mean / z.tensile_strength.mean,
                z.tail,
                if z.unlevelled > 0 {
                    format!(" ({} prisms did not level off)", z.unlevelled)
                } else {
                    String::new()
                }
            );
        }
        s += &format!(
            "  material \"{}\": {}",
            self.name,
            serde_json::to_string(&self.material).expect("a material serialises")
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> CalibrationSpec {
        CalibrationSpec::from_json(
            r#"{"name": "c", "targets": {"E": 3e10, "nu": 0.18, "tensile_strength": 3e6,
                "fracture_energy": 100, "compressive_strength": 3e7}, "rho": 2400,
                "width": 0.05, "cells": {"sizes": [0.01, 0.007], "seeds": [1, 2, 3]}}"#,
        )
        .unwrap()
    }

    /// A made-up lattice with coupled power laws in place of the specimens: `E` 0.9 of the
    /// material's, `ν` 0.5 of it, and `f_t`, `f_c`, `G_F` from all three facet parameters,
    /// with a seed-to-seed scatter of ±1 %.
    fn fake(job: &Job) -> Measured {
        let f = &job.facet;
        let (t, s, g) = (
            f.tensile_strength / 1e6,
            f.shear_strength / 1e6,
            f.fracture_energy,
        );
        let noise = 1.0 + 0.01 * (job.seed as f64 - 2.0);
        let (first, second) = match job.test {
            Test::Elastic => (0.9 * f.e, 0.5 * f.nu),
            Test::Tension => (1.2e6 * t.powf(0.9) * s.powf(0.1) * noise, 0.0),
            Test::Notched => (0.0, 6.0 * g.powf(0.8) * t.powf(0.3) * noise),
            Test::Compression => (2.5e6 * s.powf(0.6) * t.powf(0.5) * noise, 0.0),
        };
        Measured {
            job: job.clone(),
            elements: 100,
            steps: 1000,
            seconds: 0.0,
            first,
            second,
            third: 0.0,
        }
    }

    #[test]
    fn broyden_inverts_coupled_power_laws_to_the_tolerance() {
        let spec = spec();
        let mut done = Vec::new();
        let report = loop {
            match next(&spec, &done).unwrap() {
                Next::Run { jobs, .. } => done.extend(jobs.iter().map(fake)),
                Next::Done(r) => break r,
            }
        };
        assert!(report.converged, "{}", report.text());
        assert!(report.rounds.len() <= 6, "{}", report.text());
        let last = report.rounds.last().unwrap();
        for (r, tol) in last.ratios.iter().zip(spec.tolerance.each()) {
            assert!((r - 1.0).abs() <= tol, "{}", report.text());
        }
        // The inverse in closed form (logs): the seeds' noise averages out to 1.
        let [ft, fc, gf] = [3.0e6 / 1.2e6, 3.0e7 / 2.5e6, 100.0 / 6.0].map(f64::ln);
        // ln f_t = 0.9 a + 0.1 b, ln f_c = 0.5 a + 0.6 b, ln G_F = 0.3 a + 0.8 c (a, b in MPa).
        let det = 0.9 * 0.6 - 0.1 * 0.5;
        let a = (ft * 0.6 - 0.1 * fc) / det;
        let b = (0.9 * fc - 0.5 * ft) / det;
        let c = (gf - 0.3 * a) / 0.8;
        let f = last.facet;
        for (got, want) in [
            (f.tensile_strength / 1e6, a.exp()),
            (f.shear_strength / 1e6, b.exp()),
            (f.fracture_energy, c.exp()),
        ] {
            assert!((got / want - 1.0).abs() < 0.05, "{got} against {want}");
        }
        // The elastic round: `ν` 0.18 needs the material's 0.36, and `E` 1/0.9 of the target.
        assert!((f.nu - 0.36).abs() < 1e-12 && (f.e * 0.9 / 3e10 - 1.0).abs() < 1e-12);
        assert!(report.note.is_none());
    }

    #[test]
    fn a_round_with_a_missing_result_is_refused() {
        let spec = spec();
        let Next::Run { jobs, .. } = next(&spec, &[]).unwrap() else {
            panic!("round 0 first")
        };
        let done: Vec<Measured> = jobs.iter().skip(1).map(fake).collect();
        let e = next(&spec, &done).err().unwrap().to_string();
        assert!(e.contains("round 0 has 35 results, 36 expected"), "{e}");
    }

    #[test]
    fn a_target_beyond_the_lattice_takes_the_nearest_and_says_so() {
        let points: Vec<_> = NU_GRID.iter().map(|&n| (n, 0.3 * n, 0.9)).collect();
        let (nu, factor, note) = lattice_material(&points, 0.2);
        assert_eq!((nu, factor), (0.49, 0.9));
        assert!(note.unwrap().contains("beyond"));
        let flat: Vec<_> = NU_GRID
            .iter()
            .map(|&n| (n, 0.0, 1.0 / (1.0 - n * n)))
            .collect();
        let (nu, factor, note) = lattice_material(&flat, 0.2);
        assert_eq!(nu, 0.2);
        assert!((factor - (1.0 / 0.96)).abs() < 0.01, "{factor}");
        assert!(note.unwrap().contains("whatever"));
    }
}

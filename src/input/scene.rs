//! The scene file: one JSON document, key names fixed, unknown keys refused. Every key, with
//! its type, unit, default and range, is in `docs/scene.md`; [`schema`] (`rbsm
//! schema`) is the JSON Schema of the same types, generated from them and their doc comments.
//!
//! Parsing names the JSON path of an unknown or mistyped key (`bodies[0].mesh.cels`);
//! [`Scene::validate`] then checks every value against its allowed range.

use crate::error::{Error, Result};
use crate::input::kinds::kinds;
use crate::input::names::named;
use crate::input::range::Range;
use schemars::{JsonSchema, Schema};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

// The range of each number of a scene: its schema (`#[schemars(transform = KEY.schema())]`)
// and `Scene::validate` read it.

/// `thickness` (m).
const THICKNESS: Range = Range::above(0.0, "m");
/// `damping`, `α` (1/s).
const DAMPING: Range = Range::at_least(0.0, "1/s");
/// `time.stop_ratio` (dimensionless).
const STOP_RATIO: Range = Range::above(0.0, "").below(1.0);
/// `local_damping`, `α` (dimensionless).
const LOCAL_DAMPING: Range = Range::at_least(0.0, "").below(1.0);
/// `formulation.penalty`, `p` (dimensionless).
const PENALTY: Range = Range::above(0.0, "");
/// A material's `E` (Pa).
const YOUNG: Range = Range::above(0.0, "Pa");
/// A material's `nu` (dimensionless).
const POISSON: Range = Range::above(-1.0, "").below(0.5);
/// A material's `rho` (kg/m³).
const DENSITY: Range = Range::above(0.0, "kg/m³");
/// An interface's `tensile_strength` (Pa).
const TENSILE_STRENGTH: Range = Range::at_least(0.0, "Pa");
/// An interface's `cohesion` (Pa).
const COHESION: Range = Range::at_least(0.0, "Pa");
/// An interface's `friction_angle` (degrees).
const FRICTION_ANGLE: Range = Range::at_least(0.0, "degrees").below(90.0);
/// An element strength's `cohesion` (Pa): a zero strength would leave nothing to carry a load.
const ELEMENT_COHESION: Range = Range::above(0.0, "Pa");
/// An interface's `fracture_energy` (J/m²).
const FRACTURE_ENERGY: Range = Range::above(0.0, "J/m²");
/// An interface's `fracture_energy_shear` (J/m²).
const FRACTURE_ENERGY_SHEAR: Range = Range::above(0.0, "J/m²");
/// A facet law's strengths and pressures (Pa): `tensile_strength`, `shear_strength`,
/// `compressive_strength`, `friction_pressure`.
const FACET_STRENGTH: Range = Range::above(0.0, "Pa");
/// A facet law's `cap_hardening` (Pa/m).
const CAP_HARDENING: Range = Range::at_least(0.0, "Pa/m");
/// A facet law's friction coefficients.
const FRICTION_COEFFICIENT: Range = Range::at_least(0.0, "");
/// Each of a grid's or a Voronoi mesh's `size` (m).
const SIZE: Range = Range::above(0.0, "m");
/// Each of a grid's `cells`, and their product.
const CELLS: Range = Range::at_least(1.0, "").at_most(MAX_CELLS as f64);
/// A Voronoi mesh's `sites`.
const SITES: Range = Range::at_least(
    3.0,
    "the Delaunay triangulation under the cells needs three sites",
)
.at_most(MAX_CELLS as f64);
/// A Voronoi mesh's `lloyd` iterations.
const LLOYD: Range = Range::at_least(0.0, "").at_most(10_000.0);
/// A disk domain's `radius` (m).
const RADIUS: Range = Range::above(0.0, "m");
/// A disk domain's `segments`.
const SEGMENTS: Range = Range::at_least(8.0, "").at_most(1_000_000.0);
/// Each of an array's `count`, and their product.
const COUNT: Range = Range::at_least(1.0, "").at_most(MAX_BODIES as f64);
/// A clamp's `ramp` (s).
const RAMP: Range = Range::at_least(0.0, "s");
/// `contact.friction`, Coulomb's `μ` (dimensionless).
const FRICTION: Range = Range::at_least(0.0, "or null for no slip limit").called("μ");
/// `time.dt` (s).
const DT: Range = Range::above(0.0, "s");
/// `time.dt_factor` (of `Δt_crit`).
const DT_FACTOR: Range = Range::above(0.0, "");
/// `time.end` (s).
const END: Range = Range::above(0.0, "s");
/// `time.steps`.
const STEPS: Range = Range::at_least(1.0, "");
/// `output.every`.
const EVERY: Range = Range::at_least(1.0, "steps between history rows");
/// `output.checkpoint_every`.
const CHECKPOINT_EVERY: Range = Range::at_least(1.0, "steps between checkpoints; absent for none");

/// A scene of `rbsm` (a 2D Rigid-Bodies-Spring Model run with explicit dynamics): one JSON
/// object; units SI (m, kg, s, N, Pa). Every key is described in the repository's
/// `docs/scene.md`; `rbsm schema` prints this schema.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "rbsm scene")]
pub struct Scene {
    /// The JSON Schema the file follows, for editors (`rbsm schema > scene.schema.json`);
    /// ignored by `rbsm`.
    #[serde(rename = "$schema", default)]
    pub schema: Option<String>,
    /// Name of the scene, used in outputs; at most `MAX_NAME` (256) characters.
    #[schemars(length(max = MAX_NAME))]
    pub name: String,
    #[serde(default)]
    /// `stress` (default) or `strain`.
    pub plane: Plane,
    /// Out-of-plane thickness `t` (m), > 0.
    #[schemars(transform = THICKNESS.schema())]
    pub thickness: f64,
    /// `rigid` or `hybrid` with its penalty.
    pub formulation: FormulationSpec,
    #[serde(default)]
    /// `assembled` (default) or `element-wise`.
    pub evaluator: EvaluatorKind,
    /// Gravitational acceleration `[g_x, g_y]` (m/s²), global components; none when absent.
    #[serde(default)]
    pub gravity: Option<[f64; 2]>,
    /// Mass-proportional damping coefficient `α` (1/s), ≥ 0: `C = α M`. Optional, default none.
    #[serde(default)]
    #[schemars(transform = DAMPING.schema())]
    pub damping: Option<f64>,
    /// Local non-viscous damping `α` in [0, 1) (Cundall's, of the DEM codes; for quasi-static
    /// runs): each free DOF's unbalanced force is reduced by `α |F|` against the sign of its
    /// velocity. Optional, default none.
    #[serde(default)]
    #[schemars(transform = LOCAL_DAMPING.schema())]
    pub local_damping: Option<f64>,
    /// Materials by name (at least one).
    #[schemars(extend("minProperties" = 1))]
    pub materials: BTreeMap<String, MaterialSpec>,
    /// The meshed bodies (at least one).
    #[schemars(length(min = 1))]
    pub bodies: Vec<BodySpec>,
    #[serde(default)]
    /// Rigid ground segments for contact.
    pub ground: Vec<GroundSpec>,
    #[serde(default)]
    /// Contact between bodies and with the ground; none when absent.
    pub contact: Option<ContactSpec>,
    /// Time step and duration.
    pub time: TimeSpec,
    #[serde(default)]
    /// What a run writes.
    pub output: OutputSpec,
    /// What `rbsm tradeoff` measures the error against, when the scene has a closed form or a
    /// theory; without it the finest run of the sweep is the reference.
    #[serde(default)]
    pub reference: Option<ReferenceSpec>,
}

kinds! {
    #[derive(Debug, Clone, PartialEq)]
    pub enum ReferenceSpec: "A closed form or theory for the error of `rbsm tradeoff`" {
        /// The first bounce of a body dropped on horizontal ground: its apex returns to the drop
        /// height (the paper's hopping block, module `hopping`).
        "hopping-block" => HoppingBlock,
        /// An axial bar (the first body, a grid from `origin.x` to `origin.x + size.x`) held by a
        /// ground spring on its left edge, loaded at `t = 0` by the traction of its right edge: the
        /// displacement history of the named probe against the bar's modal series.
        "bar-step" => BarStep {
            /// The probe (a `u` DOF) whose history is compared.
            probe: String,
        },
    }
}

/// Plane stress or plane strain (eq. 12 and its plane-strain form).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Plane {
    #[default]
    /// Plane stress (default).
    Stress,
    /// Plane strain.
    Strain,
}

kinds! {
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub enum FormulationSpec: "Which displacement field an element carries" {
        /// Plain RBSM: `(u, v, θ)` per element (eq. 10).
        "rigid" => Rigid,
        /// Rigid cells that keep Poisson's effect: `(u, v, θ)` per element, springs
        /// `k_n = k_s = 2μ/h` (a lattice of `ν = 0`, elastically uniform on Voronoi cells) and a
        /// pressure `λ tr ε` per cell from its facets' tractions, applied on its facets.
        "rigid-poisson" => RigidPoisson,
        /// Rigid plus constant strain (eqs. 5, 8), springs `penalty` times eq. 12.
        "hybrid" => Hybrid {
            /// The penalty factor `p > 0` (dimensionless): larger is more accurate (error O(1/p))
            /// and costs time step (`Δt_crit ∝ 1/√p`).
            #[schemars(transform = PENALTY.schema())]
            penalty: f64,
        },
    }
}

named! {
    /// Which evaluator computes the internal forces (module `evaluator`).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, JsonSchema)]
    pub enum EvaluatorKind {
        /// Global sparse `K`, `f = K U` (eqs. 7–13).
        "assembled" => Assembled,
        /// Per element, the resultant of the tractions on its boundary (eqs. 15–16).
        "element-wise" => ElementWise,
    }
}

/// `assembled`, the scene's evaluator when it names none.
impl Default for EvaluatorKind {
    fn default() -> Self {
        EvaluatorKind::Assembled
    }
}

/// An isotropic linear-elastic material.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Young's modulus (Pa), > 0.
    #[serde(rename = "E")]
    #[schemars(transform = YOUNG.schema())]
    pub e: f64,
    /// Poisson's ratio (dimensionless), in (−1, 0.5).
    #[schemars(transform = POISSON.schema())]
    pub nu: f64,
    /// Density (kg/m³), > 0.
    #[schemars(transform = DENSITY.schema())]
    pub rho: f64,
    /// The law of the interfaces between its elements (eq. 11): `elastic` when absent.
    #[serde(default)]
    pub interface: InterfaceLawSpec,
    /// The strength of its elements' own constant stress (hybrid formulation only):
    /// `elastic` when absent.
    #[serde(default)]
    pub element: ElementStrengthSpec,
}

kinds! {
    ///
    /// `docs/scene.md`, *Elements that yield*.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub enum ElementStrengthSpec: "The strength of a material's elements (hybrid)" {
        /// Elements that never yield.
        "elastic" => Elastic,
        /// Tresca: the largest shear stress at most `c`.
        "tresca" => Tresca(TrescaSpec),
        /// Mohr–Coulomb: `(σ₁ − σ₃)/2 ≤ c cos φ − (σ₁ + σ₃)/2 sin φ` (tension positive).
        "mohr-coulomb" => MohrCoulomb(ElementMohrCoulombSpec),
    }
}

/// `elastic`, the elements of a material that names no strength.
impl Default for ElementStrengthSpec {
    fn default() -> Self {
        ElementStrengthSpec::Elastic
    }
}

/// Tresca's strength of an element: its cohesion (the shear strength).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TrescaSpec {
    /// Cohesion `c` (Pa), > 0.
    #[schemars(transform = ELEMENT_COHESION.schema())]
    pub cohesion: f64,
}

/// Mohr–Coulomb's strength of an element.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ElementMohrCoulombSpec {
    /// Cohesion `c` (Pa), > 0.
    #[schemars(transform = ELEMENT_COHESION.schema())]
    pub cohesion: f64,
    /// Friction angle `φ` (degrees), in [0, 90).
    #[schemars(transform = FRICTION_ANGLE.schema())]
    pub friction_angle: f64,
}

impl ElementStrengthSpec {
    /// `(c, φ)` (Pa, degrees) of a strength (`φ = 0` for Tresca); `None` for elastic elements.
    pub fn cohesion_friction(&self) -> Option<(f64, f64)> {
        match *self {
            ElementStrengthSpec::Elastic => None,
            ElementStrengthSpec::Tresca(s) => Some((s.cohesion, 0.0)),
            ElementStrengthSpec::MohrCoulomb(s) => Some((s.cohesion, s.friction_angle)),
        }
    }

    /// Its keys in range, named under `at` (`materials.clay.element`).
    fn validate(&self, at: &str) -> Result<()> {
        if let Some((c, phi)) = self.cohesion_friction() {
            ELEMENT_COHESION.check(&format!("{at}.cohesion"), c)?;
            FRICTION_ANGLE.check(&format!("{at}.friction_angle"), phi)?;
        }
        Ok(())
    }
}

kinds! {
    ///
    /// `docs/scene.md`, *Interfaces that fail*.
    #[derive(Debug, Clone, Copy, PartialEq)]
    pub enum InterfaceLawSpec: "The law of a material's interfaces" {
        /// Springs that never yield.
        "elastic" => Elastic,
        /// Mohr–Coulomb with a tension cut-off, elastic–perfectly plastic.
        "mohr-coulomb" => MohrCoulomb(StrengthSpec),
        /// The same surface, softening with the plastic opening and slip until it is exhausted.
        "softening" => Softening(SofteningSpec),
        /// The facet law of quasi-brittle materials (concrete, rock): a smooth tension–shear
        /// surface softening with the opening, bounded friction and a compression cap.
        "facet" => Facet(FacetSpec),
    }
}

/// `elastic`, the law of a material that names none.
impl Default for InterfaceLawSpec {
    fn default() -> Self {
        InterfaceLawSpec::Elastic
    }
}

/// The strength of an interface: `σ ≤ f_t` and `|τ| ≤ c − σ tan φ` (compression negative).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StrengthSpec {
    /// Tensile strength `f_t` (Pa), ≥ 0.
    #[schemars(transform = TENSILE_STRENGTH.schema())]
    pub tensile_strength: f64,
    /// Cohesion `c` (Pa), ≥ 0.
    #[schemars(transform = COHESION.schema())]
    pub cohesion: f64,
    /// Friction angle `φ` (degrees), in [0, 90).
    #[schemars(transform = FRICTION_ANGLE.schema())]
    pub friction_angle: f64,
}

/// A softening strength: [`StrengthSpec`]'s keys and the fracture energies that exhaust it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SofteningSpec {
    /// Tensile strength `f_t` (Pa), ≥ 0.
    #[schemars(transform = TENSILE_STRENGTH.schema())]
    pub tensile_strength: f64,
    /// Cohesion `c` (Pa), ≥ 0.
    #[schemars(transform = COHESION.schema())]
    pub cohesion: f64,
    /// Friction angle `φ` (degrees), in [0, 90).
    #[schemars(transform = FRICTION_ANGLE.schema())]
    pub friction_angle: f64,
    /// Mode I fracture energy `G_f` (J/m²), > 0: the work of tension per unit crack area.
    #[schemars(transform = FRACTURE_ENERGY.schema())]
    pub fracture_energy: f64,
    /// Mode II fracture energy `G_f,II` (J/m²), > 0: the work of cohesion per unit crack area.
    #[schemars(transform = FRACTURE_ENERGY_SHEAR.schema())]
    pub fracture_energy_shear: f64,
}

/// The facet law (`model::facet`): `docs/scene.md`, *interface*.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FacetSpec {
    /// Tensile strength `f_t` (Pa), > 0.
    #[schemars(transform = FACET_STRENGTH.schema())]
    pub tensile_strength: f64,
    /// Shear strength `s` (Pa) at no normal traction, > 0.
    #[schemars(transform = FACET_STRENGTH.schema())]
    pub shear_strength: f64,
    /// Fracture energy in tension `G_t` (J/m²), > 0.
    #[schemars(transform = FRACTURE_ENERGY.schema())]
    pub fracture_energy: f64,
    /// Fracture energy in shear `G_s` (J/m²), > 0.
    #[schemars(transform = FRACTURE_ENERGY_SHEAR.schema())]
    pub fracture_energy_shear: f64,
    /// Compressive strength `f_c` (Pa), > 0: where the cap starts.
    #[schemars(transform = FACET_STRENGTH.schema())]
    pub compressive_strength: f64,
    /// The cap's hardening `H` (Pa/m), ≥ 0: its rise per metre of compaction (0: perfectly
    /// plastic).
    #[serde(default)]
    #[schemars(transform = CAP_HARDENING.schema())]
    pub cap_hardening: f64,
    /// Friction coefficient `μ₀` at low pressure, ≥ 0.
    #[schemars(transform = FRICTION_COEFFICIENT.schema())]
    pub friction: f64,
    /// Friction coefficient `μ_∞` at high pressure, in [0, `friction`]; `friction` when absent
    /// (a constant coefficient).
    #[serde(default)]
    #[schemars(transform = FRICTION_COEFFICIENT.schema())]
    pub friction_residual: Option<f64>,
    /// The pressure `σ_N0` (Pa), > 0, over which the coefficient falls from `μ₀` to `μ_∞`;
    /// `compressive_strength` when absent.
    #[serde(default)]
    #[schemars(transform = FACET_STRENGTH.schema())]
    pub friction_pressure: Option<f64>,
}

impl FacetSpec {
    /// Its keys in range, named under `at`.
    fn validate(&self, at: &str) -> Result<()> {
        let key = |k: &str| format!("{at}.{k}");
        FACET_STRENGTH.check(&key("tensile_strength"), self.tensile_strength)?;
        FACET_STRENGTH.check(&key("shear_strength"), self.shear_strength)?;
        FRACTURE_ENERGY.check(&key("fracture_energy"), self.fracture_energy)?;
        FRACTURE_ENERGY_SHEAR.check(&key("fracture_energy_shear"), self.fracture_energy_shear)?;
        FACET_STRENGTH.check(&key("compressive_strength"), self.compressive_strength)?;
        CAP_HARDENING.check(&key("cap_hardening"), self.cap_hardening)?;
        FRICTION_COEFFICIENT.check(&key("friction"), self.friction)?;
        if let Some(mu) = self.friction_residual {
            FRICTION_COEFFICIENT
                .at_most(self.friction)
                .check(&key("friction_residual"), mu)?;
        }
        if let Some(p) = self.friction_pressure {
            FACET_STRENGTH.check(&key("friction_pressure"), p)?;
        }
        Ok(())
    }
}

impl InterfaceLawSpec {
    /// The Mohr–Coulomb strength, and the fracture energies `(G_f, G_f,II)` of a softening law;
    /// `None` for an elastic law and for the facet law.
    pub fn strength(&self) -> Option<(StrengthSpec, Option<[f64; 2]>)> {
        match *self {
            InterfaceLawSpec::Elastic | InterfaceLawSpec::Facet(_) => None,
            InterfaceLawSpec::MohrCoulomb(s) => Some((s, None)),
            InterfaceLawSpec::Softening(s) => Some((
                StrengthSpec {
                    tensile_strength: s.tensile_strength,
                    cohesion: s.cohesion,
                    friction_angle: s.friction_angle,
                },
                Some([s.fracture_energy, s.fracture_energy_shear]),
            )),
        }
    }
}

/// One body: a meshed region of one material.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    /// Name of the body, used in messages, `summary.json` and the history's clamp columns: 1 to
    /// `MAX_NAME` (256) characters, no commas, quotes or control characters, no two bodies
    /// alike (an array's copies included).
    #[schemars(length(min = 1, max = MAX_NAME))]
    pub name: String,
    /// Name of its material in `materials`.
    pub material: String,
    /// How it is cut into elements.
    pub mesh: MeshSpec,
    #[serde(default)]
    /// Ground springs and clamps.
    pub supports: Vec<SupportSpec>,
    #[serde(default)]
    /// Tractions and point forces.
    pub loads: Vec<LoadSpec>,
    #[serde(default)]
    /// Initial velocity, spin and rotation.
    pub initial: InitialSpec,
    /// Copies of the body on a regular pattern (a wall, a pack), each a body of its own.
    #[serde(default)]
    pub array: Option<ArraySpec>,
}

/// `count = [nx, ny]` copies of a body: copy `(i, j)` is shifted by
/// `(i · pitch[0] + (j odd ? row_offset : 0), j · pitch[1])` and named `name[i,j]`. A running-bond
/// wall of bricks is one brick with `row_offset` half a brick.
#[derive(Debug, Clone, Copy, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ArraySpec {
    /// Copies along x and y, each ≥ 1, their product ≤ `MAX_BODIES` (1 000 000).
    #[schemars(transform = COUNT.items())]
    pub count: [usize; 2],
    /// Shift between neighbouring copies along x and y (m).
    pub pitch: [f64; 2],
    /// Extra x shift of every odd row (m).
    #[serde(default)]
    pub row_offset: f64,
}

/// All DOF names, in the order of `U_e` (as scenes name them: `docs/scene.md`).
pub const DOF_NAMES: [&str; 6] = ["u", "v", "theta", "ex", "ey", "gxy"];

/// The longest name (characters) of a scene, a body or a probe.
pub const MAX_NAME: usize = 256;

/// Refuses a name longer than [`MAX_NAME`] characters, naming its key.
fn bounded_name(field: &str, name: &str) -> Result<()> {
    let n = name.chars().count();
    if n <= MAX_NAME {
        return Ok(());
    }
    Err(Error::scene(
        field,
        format!("must be at most {MAX_NAME} characters long, got {n}"),
    ))
}

/// Refuses a name that heads columns of `history.csv` (a probe's; a body's, in its moving
/// clamps' `<body>_s<k>_disp` and `_force`) when it is empty, longer than [`MAX_NAME`]
/// characters or holds a comma, a quote or a control character, naming its key.
fn column_name(field: &str, name: &str) -> Result<()> {
    bounded_name(field, name)?;
    if name.is_empty() || name.chars().any(|c| c == ',' || c == '"' || c.is_control()) {
        return Err(Error::scene(
            field,
            format!(
                "must be a non-empty name without commas, quotes or control characters \
                 (it heads columns of `history.csv`), got {name:?}"
            ),
        ));
    }
    Ok(())
}

/// The largest scene file read (bytes): a scene names its meshes and repeats its bodies with
/// `array`, so a larger file is not a scene (`/dev/zero`, a mesh given as the scene).
pub const MAX_SCENE_BYTES: u64 = 256 << 20;

/// The bytes of `path`, refused with an error (naming `what` the file was to be) when it is not
/// a regular file (a FIFO, a device, a folder) or is larger than `limit` bytes, both told by its
/// metadata before anything is read; a file that grows past `limit` meanwhile is refused when
/// the reading reaches it.
pub(crate) fn read_limited(path: &Path, limit: u64, what: &str) -> Result<Vec<u8>> {
    use std::io::Read;
    let refuse = |why: String| Err(Error::io(path, std::io::Error::other(why)));
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return refuse(format!(
            "not a regular file ({}): not {what}",
            kind_of(&meta.file_type())
        ));
    }
    if meta.len() > limit {
        return refuse(format!(
            "{} bytes, larger than {} MiB: not {what}",
            meta.len(),
            limit >> 20
        ));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut bytes = Vec::new();
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(Error::io(
            path,
            std::io::Error::other(format!("larger than {} MiB: not {what}", limit >> 20)),
        ));
    }
    Ok(bytes)
}

/// [`read_limited`] as UTF-8 text, refused (naming the file) where it is not.
pub(crate) fn read_text_limited(path: &Path, limit: u64, what: &str) -> Result<String> {
    String::from_utf8(read_limited(path, limit, what)?).map_err(|e| {
        Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidData, e),
        )
    })
}

/// Refuses a softening law whose strength `f` (Pa, the key `strength`) and fracture energy `g`
/// (J/m², the key `field`) give no finite softening: the strength is exhausted over the opening
/// `w = 2 g / f` (`model::law::Strength`), along the slope `f / w = f² / (2 g)` (Pa/m); a `w`
/// that underflows to zero or a slope that overflows gives NaN tractions at the first step.
fn softening_slope(field: &str, g: f64, strength: &str, f: f64) -> Result<()> {
    if f == 0.0 {
        return Ok(());
    }
    let w = 2.0 * g / f;
    if w.is_finite() && w >= f64::MIN_POSITIVE && (f / w).is_finite() {
        return Ok(());
    }
    let field_name = field.rsplit('.').next().unwrap_or(field);
    if !w.is_finite() {
        // The most energy whose opening `2 g / f` stays finite, rounded down so that it passes.
        let most = (0.5 * f64::MAX).min(0.5 * f * f64::MAX) * (1.0 - 1e-12);
        return Err(Error::scene(
            field,
            format!(
                "{g:e} J/m² with `{strength}` {f:e} Pa gives an opening 2 {field_name}/{strength} \
                 at which the strength is exhausted that is not a finite number (m): it must be \
                 ≤ {most:e} J/m² for this `{strength}`"
            ),
        ));
    }
    // The least energy that keeps both finite, rounded up so that it passes itself.
    let least = (0.5 * f * (f / f64::MAX)).max(0.5 * f * f64::MIN_POSITIVE) * (1.0 + 1e-12);
    Err(Error::scene(
        field,
        format!(
            "{g:e} J/m² with `{strength}` {f:e} Pa gives a softening slope {strength}²/(2 \
             {field_name}) that is not a finite number (Pa/m): it must be ≥ {least:e} J/m² for \
             this `{strength}` (or lower `{strength}`)"
        ),
    ))
}

/// What a file that is not a regular one is: a folder, a FIFO, a device, a socket.
pub(crate) fn kind_of(t: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a folder"
    } else {
        "not a file"
    }
}

/// Refuses JSON in which an object repeats a key (JSON parsers keep one of the two silently),
/// naming the key by its path. Malformed JSON passes through, for the parser to report.
fn refuse_duplicate_keys(text: &str) -> Result<()> {
    use serde::de::{DeserializeSeed, Error as _, MapAccess, SeqAccess, Visitor};
    struct Keys(String);
    impl<'de> DeserializeSeed<'de> for Keys {
        type Value = ();
        fn deserialize<D: serde::Deserializer<'de>>(
            self,
            d: D,
        ) -> std::result::Result<(), D::Error> {
            d.deserialize_any(self)
        }
    }
    impl<'de> Visitor<'de> for Keys {
        type Value = ();
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("any JSON value")
        }
        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> std::result::Result<(), A::Error> {
            let mut seen = std::collections::HashSet::new();
            while let Some(key) = map.next_key::<String>()? {
                let path = if self.0.is_empty() {
                    key.clone()
                } else {
                    format!("{}.{key}", self.0)
                };
                if !seen.insert(key) {
                    return Err(A::Error::custom(path));
                }
                map.next_value_seed(Keys(path))?;
            }
            Ok(())
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<(), A::Error> {
            let mut i = 0;
            while seq
                .next_element_seed(Keys(format!("{}[{i}]", self.0)))?
                .is_some()
            {
                i += 1;
            }
            Ok(())
        }
        fn visit_bool<E>(self, _: bool) -> std::result::Result<(), E> {
            Ok(())
        }
        fn visit_i64<E>(self, _: i64) -> std::result::Result<(), E> {
            Ok(())
        }
        fn visit_u64<E>(self, _: u64) -> std::result::Result<(), E> {
            Ok(())
        }
        fn visit_f64<E>(self, _: f64) -> std::result::Result<(), E> {
            Ok(())
        }
        fn visit_str<E>(self, _: &str) -> std::result::Result<(), E> {
            Ok(())
        }
        fn visit_unit<E>(self) -> std::result::Result<(), E> {
            Ok(())
        }
    }
    let de = &mut serde_json::Deserializer::from_str(text);
    match Keys(String::new()).deserialize(de) {
        Err(e) if e.classify() == serde_json::error::Category::Data => {
            // The message is the key's path; serde_json adds the line and column.
            let message = e.to_string();
            let path = message.split(" at line ").next().unwrap_or(&message);
            Err(Error::scene(
                path,
                format!(
                    "the key appears twice in one object (line {}); keep one",
                    e.line()
                ),
            ))
        }
        _ => Ok(()),
    }
}

/// Most bodies one scene may make with `array`.
pub const MAX_BODIES: usize = 1_000_000;

impl BodySpec {
    /// The bodies this spec stands for: itself, or its `array` of shifted copies.
    fn copies(self) -> Vec<BodySpec> {
        let Some(a) = self.array else {
            return vec![self];
        };
        let mut out = Vec::with_capacity(a.count[0] * a.count[1]);
        for j in 0..a.count[1] {
            for i in 0..a.count[0] {
                let shift = [
                    i as f64 * a.pitch[0] + if j % 2 == 1 { a.row_offset } else { 0.0 },
                    j as f64 * a.pitch[1],
                ];
                let mut body = BodySpec {
                    name: format!("{}[{i},{j}]", self.name),
                    array: None,
                    ..self.clone()
                };
                let moved = |p: &mut [f64; 2]| {
                    p[0] += shift[0];
                    p[1] += shift[1];
                };
                match &mut body.mesh {
                    MeshSpec::Grid(g) => moved(&mut g.origin),
                    MeshSpec::Voronoi(v) => {
                        moved(&mut v.origin);
                        if let Some(d) = &mut v.domain {
                            d.shift(shift);
                        }
                    }
                    MeshSpec::Polygons(p) => p.vertices.iter_mut().for_each(moved),
                    MeshSpec::Gmsh(_) => unreachable!("validated: an array has no gmsh mesh"),
                }
                out.push(body);
            }
        }
        out
    }
}

kinds! {
    #[derive(Debug, Clone)]
    pub enum MeshSpec: "How a body is cut into elements" {
        /// Rectangles or triangles.
        "grid" => Grid(GridSpec),
        /// Centroidal Voronoi cells.
        "voronoi" => Voronoi(VoronoiSpec),
        /// Explicit cells.
        "polygons" => Polygons(PolygonsSpec),
        /// An MSH 4.1 file.
        "gmsh" => Gmsh(GmshSpec),
    }
}

/// A gmsh MSH 4.1 file of triangles and quadrilaterals; a relative `path` is taken from the
/// scene file's directory. Its physical groups of lines name edges for supports and loads.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GmshSpec {
    /// The MSH file.
    pub path: std::path::PathBuf,
}

/// `cells = [nx, ny]` rectangles (or twice as many triangles) over `origin .. origin + size`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Lower-left corner (m).
    pub origin: [f64; 2],
    /// Width and height (m), each > 0.
    #[schemars(transform = SIZE.items())]
    pub size: [f64; 2],
    /// Cells along x and y, each ≥ 1, their product ≤ `MAX_CELLS` (20 000 000).
    #[schemars(transform = CELLS.items())]
    pub cells: [usize; 2],
    #[serde(default = "default_cell")]
    /// `rect` (default) or `tri`.
    pub cell: Cell,
}

/// `sites` centroidal Voronoi cells clipped to the rectangle, or to a domain inside it, after
/// `lloyd` iterations.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VoronoiSpec {
    /// Lower-left corner (m).
    pub origin: [f64; 2],
    /// Width and height (m), each > 0.
    #[schemars(transform = SIZE.items())]
    pub size: [f64; 2],
    /// Number of cells, 3 to `MAX_CELLS` (20 000 000).
    #[schemars(transform = SITES.schema())]
    pub sites: usize,
    #[serde(default)]
    /// Random seed of the sites (default 0).
    pub seed: u64,
    #[serde(default)]
    /// Lloyd iterations towards centroidal cells, 0 to 10 000 (default 0).
    #[schemars(transform = LLOYD.schema())]
    pub lloyd: usize,
    /// The region the cells fill, inside the rectangle (default: the rectangle itself).
    #[serde(default)]
    pub domain: Option<DomainSpec>,
}

kinds! {
    ///
    /// `docs/scene.md`, *Meshes*.
    #[derive(Debug, Clone)]
    pub enum DomainSpec: "The region a Voronoi mesh fills, inside its rectangle" {
        /// A simple polygon.
        "polygon" => Polygon(DomainPolygonSpec),
        /// A disk, cut as a regular polygon.
        "disk" => Disk(DiskSpec),
    }
}

/// A polygon domain.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DomainPolygonSpec {
    /// Its corners `[x, y]` (m) in order around it (either way), at least 3, its sides not
    /// crossing, all inside the rectangle.
    #[schemars(length(min = 3))]
    pub vertices: Vec<[f64; 2]>,
}

/// A disk domain.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DiskSpec {
    /// Its centre `[x, y]` (m).
    pub centre: [f64; 2],
    /// Its radius (m), > 0; the disk lies inside the rectangle.
    #[schemars(transform = RADIUS.schema())]
    pub radius: f64,
    /// The sides of the regular polygon it is cut as, a multiple of 4 from 8 to 10⁶ (default
    /// `8 √(π sites)` rounded up to one, at least 32: about four per boundary cell), turned so
    /// that a side lies flat at the bottom, top, left and right.
    #[serde(default)]
    #[schemars(transform = SEGMENTS.schema())]
    pub segments: Option<usize>,
}

impl DomainSpec {
    /// Its outline, counter-clockwise for a disk, for a mesh of `sites` cells.
    pub fn outline(&self, sites: usize) -> Vec<[f64; 2]> {
        match self {
            DomainSpec::Polygon(p) => p.vertices.clone(),
            DomainSpec::Disk(d) => {
                let n = d.segments.unwrap_or_else(|| {
                    let n = (8.0 * (std::f64::consts::PI * sites as f64).sqrt()).round() as usize;
                    (n.div_ceil(4) * 4).max(32)
                });
                // Corners half a side off the axes: flat sides at the bottom, top, left and
                // right, on the disk's bounding box, which supports can name.
                (0..n)
                    .map(|k| {
                        let t = std::f64::consts::TAU * (k as f64 + 0.5) / n as f64;
                        [
                            d.centre[0] + d.radius * t.cos(),
                            d.centre[1] + d.radius * t.sin(),
                        ]
                    })
                    .collect()
            }
        }
    }

    /// Moved by `shift` (m).
    fn shift(&mut self, shift: [f64; 2]) {
        let moved = |p: &mut [f64; 2]| {
            p[0] += shift[0];
            p[1] += shift[1];
        };
        match self {
            DomainSpec::Polygon(p) => p.vertices.iter_mut().for_each(moved),
            DomainSpec::Disk(d) => moved(&mut d.centre),
        }
    }

    /// Its keys in range, named under `at` (`bodies[0].mesh.domain`); the mesh checks its
    /// outline's shape (`mesh::voronoi::check_domain`).
    fn validate(&self, at: &str) -> Result<()> {
        let key = |k: &str| format!("{at}.{k}");
        match self {
            DomainSpec::Polygon(p) => {
                if p.vertices.len() < 3 {
                    return Err(Error::scene(key("vertices"), "needs at least 3 vertices"));
                }
                for (i, v) in p.vertices.iter().enumerate() {
                    finite_all(&key(&format!("vertices[{i}]")), v)?;
                }
            }
            DomainSpec::Disk(d) => {
                finite_all(&key("centre"), &d.centre)?;
                RADIUS.check(&key("radius"), d.radius)?;
                if let Some(n) = d.segments {
                    SEGMENTS.check_count(&key("segments"), n as u64)?;
                    if n % 4 != 0 {
                        return Err(Error::scene(
                            key("segments"),
                            format!("{n} is not a multiple of 4 (the disk has flat sides at the bottom, top, left and right)"),
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

/// Explicit polygons, vertex lists counter-clockwise.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PolygonsSpec {
    /// Vertex coordinates `[x, y]` (m), at least 3.
    #[schemars(length(min = 3))]
    pub vertices: Vec<[f64; 2]>,
    /// Cells as lists of vertex indices (from 0), counter-clockwise; at least 1.
    #[schemars(length(min = 1))]
    pub cells: Vec<Vec<usize>>,
}

/// The most cells one mesh may have (about 10 GB of model at ~500 bytes per element).
pub const MAX_CELLS: usize = 20_000_000;

/// The cell shape of a structured grid (`mesh.cell` in the scene).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum Cell {
    /// One rectangle per grid cell.
    Rect,
    /// Two triangles per grid cell (lower-right `2c`, upper-left `2c + 1`).
    Tri,
    /// Four triangles per grid cell, cut by both diagonals (bottom `4c`, right `4c + 1`, top
    /// `4c + 2`, left `4c + 3`): interfaces at 0°, 90° and ±45°.
    Crossed,
}

impl Cell {
    /// The elements of one grid cell.
    pub fn per_cell(self) -> usize {
        match self {
            Cell::Rect => 1,
            Cell::Tri => 2,
            Cell::Crossed => 4,
        }
    }
}

/// A side of a body's bounding box, used to tag boundary edges (supports, loads).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// `x` = smallest.
    Left,
    /// `x` = largest.
    Right,
    /// `y` = smallest.
    Bottom,
    /// `y` = largest.
    Top,
}

/// Which boundary edges a support or load acts on: a side of the body's bounding box
/// (`left`, `right`, `bottom`, `top`) or, any other name, a physical group of a gmsh mesh.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum EdgeSet {
    /// A side of the bounding box.
    Side(Side),
    /// A physical group of a gmsh mesh, by name.
    Group(String),
}

impl<'de> serde::Deserialize<'de> for EdgeSet {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Ok(match name.as_str() {
            "left" => EdgeSet::Side(Side::Left),
            "right" => EdgeSet::Side(Side::Right),
            "bottom" => EdgeSet::Side(Side::Bottom),
            "top" => EdgeSet::Side(Side::Top),
            _ => EdgeSet::Group(name),
        })
    }
}

/// Its name, as scenes write it.
impl Serialize for EdgeSet {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// A string: a side name or the name of a gmsh physical group (any string parses).
impl schemars::JsonSchema for EdgeSet {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "EdgeSet".into()
    }

    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "type": "string",
            "minLength": 1,
            "description": "A side of the body's bounding box (`left`, `right`, `bottom`, `top`) \
                or, any other name, a physical group of lines of the body's gmsh mesh.",
            "examples": ["left", "right", "bottom", "top"]
        })
    }
}

impl std::fmt::Display for EdgeSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EdgeSet::Side(s) => write!(f, "{}", format!("{s:?}").to_lowercase()),
            EdgeSet::Group(g) => write!(f, "{g}"),
        }
    }
}

fn default_cell() -> Cell {
    Cell::Rect
}

kinds! {
    #[derive(Debug, Clone)]
    pub enum SupportSpec: "A support on an edge set of the body" {
        /// Ground springs.
        "ground-spring" => GroundSpring(GroundSpringSpec),
        /// Fixed or moving DOFs.
        "clamp" => Clamp(ClampSpec),
    }
}

/// The edges of a side tied to fixed ground by springs with `h_b = 0`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GroundSpringSpec {
    /// Where: a side or a gmsh group.
    pub edge: EdgeSet,
    /// `["n", "s"]` by default; `["n"]` is a roller. Not empty.
    #[serde(default = "both_components")]
    #[schemars(length(min = 1))]
    pub components: Vec<Component>,
    /// Only the part of the side in `[from, to]` (m) along it: `x` on `bottom` and `top`, `y`
    /// on `left` and `right` (a bearing plate, a pad under a beam, of any width: an edge partly
    /// in the range is held over that part only).
    #[serde(default)]
    pub span: Option<[f64; 2]>,
}

/// The listed DOFs (default all) of the elements with an edge on that side are fixed.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ClampSpec {
    /// Where: a side or a gmsh group.
    pub edge: EdgeSet,
    #[serde(default)]
    /// DOF names (`u`, `v`, `theta`; hybrid also `ex`, `ey`, `gxy`); all when absent.
    #[schemars(transform = items_dof_names)]
    pub dofs: Option<Vec<String>>,
    /// Displacement control: the clamped `u` and `v` move at this velocity `[v_x, v_y]` (m/s)
    /// instead of staying at zero, and the history records the clamp's displacement and
    /// reaction. A component other than 0 needs its DOF clamped.
    #[serde(default)]
    pub velocity: Option<[f64; 2]>,
    /// Time over which the velocity rises linearly from zero (s), ≥ 0: a smooth start; only
    /// with a `velocity`.
    #[serde(default)]
    #[schemars(transform = RAMP.schema())]
    pub ramp: f64,
    /// Only the edges of the side whose midpoints lie in `[from, to]` (m) along it: `x` on
    /// `bottom` and `top`, `y` on `left` and `right` (a footing on part of a surface).
    #[serde(default)]
    pub span: Option<[f64; 2]>,
}

fn both_components() -> Vec<Component> {
    vec![Component::N, Component::S]
}

/// A spring component of a ground support: normal or shear.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Component {
    /// Normal.
    N,
    /// Shear.
    S,
}

kinds! {
    #[derive(Debug, Clone)]
    pub enum LoadSpec: "A load on a body" {
        /// A traction on edges.
        "traction" => Traction(TractionSpec),
        /// A force on one element.
        "force" => Force(ForceSpec),
    }
}

/// Uniform traction (N/m², global components) on the edges of one side.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TractionSpec {
    /// Where: a side or a gmsh group.
    pub edge: EdgeSet,
    /// `[t_x, t_y]` (N/m², global).
    pub value: [f64; 2],
    /// Piecewise-linear factor in time, `[[t, factor], ...]` (s, dimensionless) with strictly
    /// increasing `t`, held constant outside its range; constant 1 when absent.
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub amplitude: Option<Vec<[f64; 2]>>,
}

/// `[F_x, F_y, M]` (N, N, N·m) at the centroid of one element of the body (index within
/// the body).
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ForceSpec {
    /// Element index within the body.
    pub element: usize,
    /// `[F_x, F_y, M]` (N, N, N·m).
    pub value: [f64; 3],
    #[serde(default)]
    /// Piecewise-linear factor in time, `[[t, factor], ...]` (s, dimensionless) with strictly
    /// increasing `t`, held constant outside its range; constant 1 when absent.
    #[schemars(length(min = 1))]
    pub amplitude: Option<Vec<[f64; 2]>>,
}

/// Every item of an array schema (or of an array-or-null) one of the DOF names.
fn items_dof_names(schema: &mut Schema) {
    if let Some(items) = schema.get_mut("items").and_then(|i| i.as_object_mut()) {
        items.insert("enum".into(), DOF_NAMES.as_slice().into());
    }
}

/// Exactly one of the two keys `a` and `b` given with a value other than `null` (as
/// [`Scene::validate`] asks of `time.dt`/`dt_factor`, `time.end`/`steps` and a probe's
/// `element`/`at`).
fn exactly_one_of(schema: &mut Schema, a: &str, b: &str) {
    let given = |key: &str| serde_json::json!({"required": [key], "properties": {key: {"not": {"type": "null"}}}});
    let rule = serde_json::json!({"oneOf": [given(a), given(b)]});
    let object = schema.ensure_object();
    match object.get_mut("allOf").and_then(|all| all.as_array_mut()) {
        Some(all) => all.push(rule),
        None => {
            object.insert("allOf".into(), serde_json::json!([rule]));
        }
    }
}

fn time_exactly_one(schema: &mut Schema) {
    exactly_one_of(schema, "dt", "dt_factor");
    exactly_one_of(schema, "end", "steps");
}

fn probe_exactly_one(schema: &mut Schema) {
    exactly_one_of(schema, "element", "at");
}

/// Initial placement and motion of a body.
#[derive(Debug, Clone, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    /// Velocity of the body's centroid (m/s).
    #[serde(default)]
    pub velocity: [f64; 2],
    /// Angular velocity about the body's centroid (rad/s).
    #[serde(default)]
    pub angular_velocity: f64,
    /// Rotation of the body about its centroid, counter-clockwise (degrees).
    #[serde(default)]
    pub rotation_deg: f64,
}

/// A rigid ground segment (for contact).
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GroundSpec {
    /// Start point (m).
    pub from: [f64; 2],
    /// End point (m), not `from`; the free side is on the left of `from → to`.
    pub to: [f64; 2],
}

/// Contact between bodies and with the ground (paper eqs. 17–20).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// `edge-to-edge` (the paper's) or `point` (one spring per penetrating vertex, DEM).
    pub model: ContactModel,
    /// Coulomb friction coefficient `μ ≥ 0` (dimensionless); `null` or absent is no slip limit.
    #[serde(default)]
    #[schemars(transform = FRICTION.schema())]
    pub friction: Option<f64>,
}

named! {
    /// The contact model (`contact.model`).
    #[derive(Debug, Clone, Copy, PartialEq, Eq, JsonSchema)]
    pub enum ContactModel {
        /// The paper's contact: the penetrating part of the boundary is a temporary interface.
        "edge-to-edge" => EdgeToEdge,
        /// Classic DEM: a spring at each penetrating vertex.
        "point" => Point,
    }
}

/// Time step and duration; exactly one of `dt`, `dt_factor` and one of `end`, `steps`.
#[derive(Debug, Clone, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(transform = time_exactly_one)]
pub struct TimeSpec {
    #[serde(default)]
    /// Time step (s), > 0.
    #[schemars(transform = DT.schema())]
    pub dt: Option<f64>,
    #[serde(default)]
    /// Time step as a fraction of the computed `Δt_crit` (dimensionless), > 0.
    #[schemars(transform = DT_FACTOR.schema())]
    pub dt_factor: Option<f64>,
    #[serde(default)]
    /// End time (s), > 0.
    #[schemars(transform = END.schema())]
    pub end: Option<f64>,
    #[serde(default)]
    /// Number of steps, ≥ 1.
    #[schemars(transform = STEPS.schema())]
    pub steps: Option<u64>,
    #[serde(default)]
    /// Stop once the unbalanced-force ratio falls below this, in (0, 1): the largest
    /// unbalanced force on a free translation over the mean applied force (loads on the free
    /// translations, clamps' reactions on the fixed ones), read at
    /// every check of the run (every 100 steps or `output.every`). Optional, default none: the
    /// run goes to `end` or `steps`.
    #[schemars(transform = STOP_RATIO.schema())]
    pub stop_ratio: Option<f64>,
}

/// What a run writes.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// A history row (and a VTK frame) every this many steps, ≥ 1 (default 100).
    #[serde(default = "default_every")]
    #[schemars(transform = EVERY.schema())]
    pub every: u64,
    /// ParaView output: VTK XML frames (`.vtu`) and a `.pvd` series.
    #[serde(default)]
    pub vtk: bool,
    /// Extra history columns: one DOF of one element (or at one point) each.
    #[serde(default)]
    pub probes: Vec<ProbeSpec>,
    /// Steps between checkpoints (`checkpoint.bin`, for `rbsm run --resume`), ≥ 1; none when
    /// absent.
    #[serde(default)]
    #[schemars(transform = CHECKPOINT_EVERY.schema())]
    pub checkpoint_every: Option<u64>,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            every: default_every(),
            vtk: false,
            probes: Vec::new(),
            checkpoint_every: None,
        }
    }
}

fn default_every() -> u64 {
    100
}

/// A history column: DOF `dof` (`u`, `v`, `theta`, ...) of element `element` (global index),
/// or at the point `at`: of the element containing it, `u` and `v` there through `N_e`.
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(transform = probe_exactly_one)]
pub struct ProbeSpec {
    #[serde(default)]
    /// Column header: 1 to `MAX_NAME` (256) characters, no commas, quotes or control
    /// characters, none of the history's own columns, no two alike; `e<element>_<dof>` or
    /// `<dof>_at_<x>_<y>` when absent.
    #[schemars(length(min = 1, max = MAX_NAME))]
    pub name: Option<String>,
    /// Element (global index); give this or `at`.
    #[serde(default)]
    pub element: Option<usize>,
    /// A point of the reference configuration (m); give this or `element`.
    #[serde(default)]
    pub at: Option<[f64; 2]>,
    /// DOF name: `u`, `v`, `theta`, and hybrid `ex`, `ey`, `gxy`.
    #[schemars(extend("enum" = DOF_NAMES))]
    pub dof: String,
}

impl ProbeSpec {
    /// The history column's header: `name`, or `e<element>_<dof>`, or `<dof>_at_<x>_<y>`.
    pub fn column(&self) -> String {
        self.name
            .clone()
            .unwrap_or_else(|| match (self.element, self.at) {
                (_, Some([x, y])) => format!("{}_at_{x}_{y}", self.dof),
                (e, None) => format!("e{}_{}", e.unwrap_or(0), self.dof),
            })
    }
}

/// The JSON Schema (draft 2020-12) of a scene file, generated from the scene types and their
/// doc comments (`rbsm schema` prints it). It names every key the parser accepts, each object
/// closed (`additionalProperties: false`), with the simple ranges of [`Scene::validate`]; the
/// checks that need the whole scene (material names, probe columns, mesh files, products of
/// counts) are left to `validate`.
pub fn schema() -> serde_json::Value {
    serde_json::Value::from(schemars::schema_for!(Scene))
}

/// A value of type `T` read from JSON `text` (a scene, a calibration): an error in well-formed
/// JSON (a wrong value, key or type) is a [`Error::Scene`] named by its key path, the rest a
/// [`Error::Parse`] placed by line and column.
pub(crate) fn from_json_text<T: serde::de::DeserializeOwned>(text: &str) -> Result<T> {
    let de = &mut serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(de).map_err(|e| {
        let mut path = e.path().to_string();
        let inner = e.into_inner();
        // Where serde_json placed the error, which it appends to its message.
        let located = format!(" at line {} column {}", inner.line(), inner.column());
        let data = inner.classify() == serde_json::error::Category::Data;
        let mut message = inner.to_string();
        if data {
            // Well-formed JSON with a wrong value, key or type is named by its key path
            // (below), which also holds for a scene built in memory (a Python dict) whose
            // text nobody has seen: the line and column go.
            if let Some(m) = message.strip_suffix(&located) {
                message = m.to_string();
            }
        }
        // A variant's own path (see `variant`) continues the outer one.
        if let Some((sub, rest)) = message.strip_prefix('`').and_then(|r| r.split_once("`: ")) {
            path = if path == "." {
                sub.to_string()
            } else {
                format!("{path}.{sub}")
            };
            message = rest.to_string();
        }
        if data {
            message = plain_types(&message);
            // A missing key is named by the path it should have.
            if let Some(key) = message
                .strip_prefix("missing field `")
                .and_then(|r| r.strip_suffix('`'))
            {
                path = if path == "." {
                    key.to_string()
                } else {
                    format!("{path}.{key}")
                };
            }
            if path != "." {
                return Error::scene(path, message);
            }
            // Not an object at all: placed by line and column.
            message.push_str(&located);
        }
        // `?`: the reader stopped before any key (a file cut short).
        let message = if path == "." || path == "?" {
            message
        } else {
            format!("at `{path}`: {message}")
        };
        Error::parse("<json>", message)
    })
}

/// Refuses a list where the scene's schema wants an object, naming it: the reader takes a list
/// for a struct's fields in order, so `"contact": [{"model": "point"}]` was "unknown variant
/// `model`" at `contact[0]`, and `"time": [1e-6, null, 100]` passed as `dt`, `dt_factor`,
/// `steps`.
fn refuse_lists_for_objects(text: &str) -> Result<()> {
    use serde_json::Value;
    /// A schema with its `$ref`s followed.
    fn resolve<'a>(defs: &'a Value, mut s: &'a Value) -> &'a Value {
        while let Some(name) = s["$ref"].as_str().and_then(|r| r.strip_prefix("#/$defs/")) {
            s = &defs[name];
        }
        s
    }
    /// A schema and its options (`anyOf`, `oneOf`), each resolved.
    fn options<'a>(defs: &'a Value, s: &'a Value) -> Vec<&'a Value> {
        let s = resolve(defs, s);
        let mut all = vec![s];
        for key in ["anyOf", "oneOf"] {
            all.extend(
                s[key]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|o| resolve(defs, o)),
            );
        }
        all
    }
    /// The first list under `path` in `value` that `schema` does not take.
    fn walk(defs: &Value, schema: &Value, value: &Value, path: &str) -> Option<String> {
        let schemas = options(defs, schema);
        let takes = |t: &str| {
            schemas.iter().any(|s| match &s["type"] {
                Value::String(x) => x == t,
                Value::Array(x) => x.iter().any(|x| x == t),
                _ => false,
            })
        };
        match value {
            // A root that is no object is the reader's to place by line and column.
            Value::Array(_) if !path.is_empty() && !takes("array") && takes("object") => {
                Some(path.to_string())
            }
            Value::Array(items) => {
                let item = schemas.iter().map(|s| &s["items"]).find(|i| !i.is_null())?;
                items
                    .iter()
                    .enumerate()
                    .find_map(|(k, v)| walk(defs, item, v, &format!("{path}[{k}]")))
            }
            Value::Object(map) => map.iter().find_map(|(key, v)| {
                let inner = schemas
                    .iter()
                    .map(|s| &s["properties"][key])
                    .find(|p| !p.is_null())
                    .or_else(|| {
                        schemas
                            .iter()
                            .map(|s| &s["additionalProperties"])
                            .find(|p| p.is_object())
                    })?;
                let path = if path.is_empty() {
                    key.clone()
                } else {
                    format!("{path}.{key}")
                };
                walk(defs, inner, v, &path)
            }),
            _ => None,
        }
    }
    let Ok(value) = serde_json::from_str::<Value>(text) else {
        return Ok(()); // the reader says where the text is not JSON
    };
    let root = schema();
    match walk(&root["$defs"], &root, &value, "") {
        Some(path) => Err(Error::scene(
            path,
            "must be an object of keys and values (`{…}`, docs/scene.md), not a list",
        )),
        None => Ok(()),
    }
}

/// `message` of the JSON reader with the Rust types it expects said as a scene's author knows
/// them: `expected f64` as a number, `expected usize` as a whole number ≥ 0.
fn plain_types(message: &str) -> String {
    const TYPES: [(&str, &str); 6] = [
        ("expected f64", "expected a number"),
        ("expected usize", "expected a whole number ≥ 0"),
        ("expected u64", "expected a whole number ≥ 0"),
        ("expected u32", "expected a whole number ≥ 0"),
        ("expected i64", "expected a whole number"),
        ("expected i32", "expected a whole number"),
    ];
    TYPES.iter().fold(message.to_string(), |m, (rust, plain)| {
        m.replace(rust, plain)
    })
}

impl Scene {
    /// Reads and validates a scene file.
    ///
    /// # Errors
    /// The file cannot be read or is larger than `MAX_SCENE_BYTES`, is not JSON, repeats a key,
    /// has a key the scene does not know or a value of the wrong type (the error names its JSON
    /// path), or a value out of its range ([`Scene::validate`]).
    pub fn from_file(path: impl AsRef<Path>) -> Result<Scene> {
        let path = path.as_ref();
        let text = read_text_limited(path, MAX_SCENE_BYTES, "a scene file")?;
        Scene::parse(&text, path.parent()).map_err(|e| match e {
            Error::Parse { message, .. } => Error::parse(path.display().to_string(), message),
            other => other,
        })
    }

    /// Parses and validates a scene from JSON text; mesh files are found from the working
    /// directory.
    ///
    /// # Errors
    /// As [`Scene::from_file`], the reading of the file aside.
    pub fn from_json(text: &str) -> Result<Scene> {
        Scene::parse(text, None)
    }

    /// Parses and validates a scene whose relative mesh paths start at `dir`.
    ///
    /// # Errors
    /// As [`Scene::from_json`].
    pub fn from_json_in(text: &str, dir: &Path) -> Result<Scene> {
        Scene::parse(text, Some(dir))
    }

    /// Parses a scene whose relative mesh paths start at `dir`, then validates it.
    fn parse(text: &str, dir: Option<&Path>) -> Result<Scene> {
        refuse_duplicate_keys(text)?;
        refuse_lists_for_objects(text)?;
        let mut scene: Scene = from_json_text(text)?;
        if let Some(dir) = dir {
            for body in &mut scene.bodies {
                if let MeshSpec::Gmsh(GmshSpec { path }) = &mut body.mesh {
                    if path.is_relative() {
                        *path = dir.join(&*path);
                    }
                }
            }
        }
        scene.validate()?;
        scene.bodies = std::mem::take(&mut scene.bodies)
            .into_iter()
            .flat_map(BodySpec::copies)
            .collect();
        Ok(scene)
    }

    /// Of the inputs `names` (`rho`, `E`, `thickness`, `penalty`) of body `body`, the field
    /// whose value lies furthest, in orders of magnitude, from its usual size (2500 kg/m³,
    /// 30 GPa, 0.1 m, 1): the one to blame when their product overflows or underflows.
    pub fn most_extreme(&self, body: usize, names: &[&str]) -> String {
        let material = self
            .bodies
            .get(body)
            .map(|b| b.material.as_str())
            .unwrap_or("");
        let m = self.materials.get(material);
        let penalty = match self.formulation {
            FormulationSpec::Hybrid { penalty } => Some(penalty),
            _ => None,
        };
        let candidates = [
            (
                "rho",
                format!("materials.{material}.rho"),
                m.map(|m| m.rho),
                2500.0,
            ),
            ("E", format!("materials.{material}.E"), m.map(|m| m.e), 3e10),
            (
                "thickness",
                "thickness".to_string(),
                Some(self.thickness),
                0.1,
            ),
            ("penalty", "formulation.penalty".to_string(), penalty, 1.0),
        ];
        candidates
            .into_iter()
            .filter(|(name, _, value, _)| names.contains(name) && value.is_some())
            .map(|(_, field, value, usual)| (field, (value.unwrap_or(1.0) / usual).log10().abs()))
            .fold((String::from("materials"), -1.0), |best, (field, d)| {
                if d > best.1 {
                    (field, d)
                } else {
                    best
                }
            })
            .0
    }

    /// Checks every value against its allowed range; the error names the field. Section by
    /// section: the whole scene's numbers, the materials, the output, the bodies, the ground
    /// and contact, the time. (Whether a probe's column is one of the history's own is the
    /// output stage's to say: `output::refuse_own_columns`, called by the setup.)
    ///
    /// # Errors
    /// The first value out of its range, by its key's path (`bodies[0].mesh.sites`), with the
    /// range it must lie in; a material, side, mesh file or probe that names nothing.
    pub fn validate(&self) -> Result<()> {
        bounded_name("name", &self.name)?;
        THICKNESS.check("thickness", self.thickness)?;
        if let FormulationSpec::Hybrid { penalty } = self.formulation {
            PENALTY.check("formulation.penalty", penalty)?;
        }
        if let Some(g) = self.gravity {
            finite_all("gravity", &g)?;
        }
        if let Some(alpha) = self.damping {
            DAMPING.check("damping", alpha)?;
        }
        if let Some(alpha) = self.local_damping {
            LOCAL_DAMPING.check("local_damping", alpha)?;
        }
        self.validate_materials()?;
        if self.bodies.is_empty() {
            return Err(Error::scene("bodies", "at least one body is needed"));
        }
        self.validate_output()?;
        // Duplicates first: a name that repeats an array's copy (`name[i,j]`) is told so.
        self.refuse_duplicate_bodies()?;
        for (i, b) in self.bodies.iter().enumerate() {
            column_name(&format!("bodies[{i}].name"), &b.name)?;
            self.validate_body(i, b)?;
        }
        self.validate_contact()?;
        self.time.validate()
    }

    /// At least one material, each in range, its interface law included.
    fn validate_materials(&self) -> Result<()> {
        if self.materials.is_empty() {
            return Err(Error::scene("materials", "at least one material is needed"));
        }
        for (name, m) in &self.materials {
            let at = |k: &str| format!("materials.{name}.{k}");
            YOUNG.check(&at("E"), m.e)?;
            DENSITY.check(&at("rho"), m.rho)?;
            POISSON.check(&at("nu"), m.nu)?;
            m.interface.validate(&at("interface"))?;
            m.element.validate(&at("element"))?;
            if m.element != ElementStrengthSpec::Elastic
                && !matches!(self.formulation, FormulationSpec::Hybrid { .. })
            {
                return Err(Error::scene(
                    at("element"),
                    "a rigid element has no strain and so no stress of its own to yield: give \
                     the scene `\"formulation\": {\"kind\": \"hybrid\", ...}` for elements \
                     that yield, or leave the strength to the interfaces (`interface`)",
                ));
            }
            if m.nu < 0.0 && self.formulation == FormulationSpec::RigidPoisson {
                return Err(Error::scene(
                    at("nu"),
                    format!(
                        "must be ≥ 0 for the `rigid-poisson` formulation (its correction adds \
                         λ' ≥ 0 to a lattice of ν = 0), got {}",
                        m.nu
                    ),
                ));
            }
            let fragments = self
                .contact
                .as_ref()
                .is_some_and(|c| c.model == ContactModel::EdgeToEdge);
            if !matches!(m.interface, InterfaceLawSpec::Elastic)
                && self.formulation == FormulationSpec::RigidPoisson
                && fragments
            {
                return Err(Error::scene(
                    at("interface"),
                    "the `rigid-poisson` formulation does not hand broken interfaces over to \
                     edge-to-edge contact (its correction's jump would have to follow the \
                     fragments): give interfaces that fail without `contact`, or use `rigid` or \
                     `hybrid` for fragments that collide",
                ));
            }
        }
        Ok(())
    }

    /// The reference's probe, the probes (placed once, each column named by the rule of
    /// [`column_name`], no two alike) and how often rows and checkpoints are written.
    fn validate_output(&self) -> Result<()> {
        if let Some(ReferenceSpec::BarStep { probe }) = &self.reference {
            if !self
                .output
                .probes
                .iter()
                .any(|p| p.name.as_deref() == Some(probe.as_str()))
            {
                return Err(Error::scene(
                    "reference.probe",
                    format!("must name one of `output.probes`, got `{probe}`"),
                ));
            }
        }
        // Each column's probe, for a search per probe that does not grow with the probes.
        let mut first = std::collections::HashMap::with_capacity(self.output.probes.len());
        for (k, p) in self.output.probes.iter().enumerate() {
            match (p.element, p.at) {
                (Some(_), None) => {}
                (None, Some(at)) => finite_all(&format!("output.probes[{k}].at"), &at)?,
                _ => {
                    return Err(Error::scene(
                        format!("output.probes[{k}].element"),
                        "give exactly one of `element` (global index) and `at` ([x, y], m)",
                    ))
                }
            }
            let (field, column) = (format!("output.probes[{k}].name"), p.column());
            column_name(&field, &column)?;
            if let Some(j) = first.insert(column.clone(), k) {
                return Err(Error::scene(
                    field,
                    format!(
                        "`{column}` is the column of `output.probes[{j}]`: every column needs \
                         its own name"
                    ),
                ));
            }
        }
        EVERY.check_count("output.every", self.output.every)?;
        if let Some(n) = self.output.checkpoint_every {
            CHECKPOINT_EVERY.check_count("output.checkpoint_every", n)?;
        }
        Ok(())
    }

    /// The ground's segments, which act only through contact, and the contact's friction.
    fn validate_contact(&self) -> Result<()> {
        for (i, g) in self.ground.iter().enumerate() {
            finite_all(&format!("ground[{i}].from"), &g.from)?;
            finite_all(&format!("ground[{i}].to"), &g.to)?;
            if g.from == g.to {
                return Err(Error::scene(
                    format!("ground[{i}].to"),
                    "must differ from `from` (a segment of positive length)",
                ));
            }
        }
        if !self.ground.is_empty() && self.contact.is_none() {
            return Err(Error::scene(
                "contact",
                "ground segments act only through contact: add \
                `\"contact\": {\"model\": \"edge-to-edge\"}` (or `point`)",
            ));
        }
        if let Some(ContactSpec {
            friction: Some(mu), ..
        }) = self.contact
        {
            FRICTION.check("contact.friction", mu)?;
        }
        Ok(())
    }

    /// Refuses two bodies of the same name, an array's copies (`name[i,j]`) included: the
    /// history's clamp columns, `summary.json` and the messages tell bodies by their names.
    fn refuse_duplicate_bodies(&self) -> Result<()> {
        let mut first = std::collections::HashMap::with_capacity(self.bodies.len());
        for (k, b) in self.bodies.iter().enumerate() {
            if let Some(j) = first.insert(b.name.as_str(), k) {
                return Err(Error::scene(
                    format!("bodies[{k}].name"),
                    format!(
                        "`{}` is the name of `bodies[{j}]` too: every body needs a name of its own",
                        b.name
                    ),
                ));
            }
        }
        // A name `base[i,j]` that is a copy of the array `base` (an array's own name is not
        // used: its copies have theirs).
        for (k, b) in self
            .bodies
            .iter()
            .enumerate()
            .filter(|(_, b)| b.array.is_none())
        {
            let Some((base, index)) = b.name.strip_suffix(']').and_then(|n| n.rsplit_once('['))
            else {
                continue;
            };
            let Some((i, j)) = index
                .split_once(',')
                .and_then(|(i, j)| Some((i.parse::<usize>().ok()?, j.parse::<usize>().ok()?)))
            else {
                continue;
            };
            if let Some(&a) = first.get(base) {
                if let Some(array) = &self.bodies[a].array {
                    if i < array.count[0] && j < array.count[1] && index == format!("{i},{j}") {
                        return Err(Error::scene(
                            format!("bodies[{k}].name"),
                            format!(
                                "`{}` is the name of a copy of `bodies[{a}]` (its `array`): \
                                 every body needs a name of its own",
                                b.name
                            ),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// Body `i`: its material named, its mesh, supports, loads, array and initial motion.
    fn validate_body(&self, i: usize, b: &BodySpec) -> Result<()> {
        let at = |k: &str| format!("bodies[{i}].{k}");
        if !self.materials.contains_key(&b.material) {
            let known: Vec<_> = self.materials.keys().map(String::as_str).collect();
            return Err(Error::scene(
                at("material"),
                format!(
                    "unknown material `{}`; defined: {}",
                    b.material,
                    known.join(", ")
                ),
            ));
        }
        b.mesh.validate(&at("mesh"))?;
        for (k, s) in b.supports.iter().enumerate() {
            s.validate(&at(&format!("supports[{k}]")))?;
        }
        for (k, l) in b.loads.iter().enumerate() {
            l.validate(&at(&format!("loads[{k}]")))?;
        }
        if let Some(a) = &b.array {
            b.validate_array(&at, a)?;
        }
        finite_all(&at("initial.velocity"), &b.initial.velocity)?;
        finite_all(
            &at("initial.angular_velocity"),
            &[b.initial.angular_velocity],
        )?;
        finite_all(&at("initial.rotation_deg"), &[b.initial.rotation_deg])?;
        Ok(())
    }
}

impl BodySpec {
    /// The array `a` of this body (whose keys `at` names): its counts and shifts, and a body
    /// whose copies can be made (no moving clamp, whose columns a copy's name would break; no
    /// gmsh mesh, which cannot be shifted).
    fn validate_array(&self, at: &dyn Fn(&str) -> String, a: &ArraySpec) -> Result<()> {
        COUNT.check_pair(&at("array.count"), a.count)?;
        if let Some(k) = self.supports.iter().position(|s| {
            matches!(
                s,
                SupportSpec::Clamp(ClampSpec {
                    velocity: Some(_),
                    ..
                })
            )
        }) {
            return Err(Error::scene(
                at(&format!("supports[{k}].velocity")),
                "a moving clamp's columns of `history.csv` are named after its body, and \
                 the copies of an `array` are named `name[i,j]`, with a comma: give a \
                 body with a moving clamp no `array`",
            ));
        }
        finite_all(&at("array.pitch"), &a.pitch)?;
        finite_all(&at("array.row_offset"), &[a.row_offset])?;
        if matches!(self.mesh, MeshSpec::Gmsh(_)) {
            return Err(Error::scene(
                at("array"),
                "copies need a `grid`, `voronoi` or \
                `polygons` mesh (a gmsh mesh cannot be shifted)",
            ));
        }
        Ok(())
    }
}

impl MeshSpec {
    /// Its keys in range, named under `at` (`bodies[0].mesh`); a gmsh file must be there.
    fn validate(&self, at: &str) -> Result<()> {
        let key = |k: &str| format!("{at}.{k}");
        match self {
            MeshSpec::Grid(GridSpec {
                origin,
                size,
                cells,
                ..
            }) => {
                finite_all(&key("origin"), origin)?;
                SIZE.check(&key("size[0]"), size[0])?;
                SIZE.check(&key("size[1]"), size[1])?;
                CELLS.check_pair(&key("cells"), *cells)?;
            }
            MeshSpec::Voronoi(VoronoiSpec {
                origin,
                size,
                sites,
                lloyd,
                domain,
                ..
            }) => {
                finite_all(&key("origin"), origin)?;
                SIZE.check(&key("size[0]"), size[0])?;
                SIZE.check(&key("size[1]"), size[1])?;
                SITES.check_count(&key("sites"), *sites as u64)?;
                LLOYD.check_count(&key("lloyd"), *lloyd as u64)?;
                if let Some(d) = domain {
                    d.validate(&key("domain"))?;
                }
            }
            MeshSpec::Polygons(PolygonsSpec { vertices, cells }) => {
                if vertices.len() < 3 || cells.is_empty() {
                    return Err(Error::scene(at, "needs at least 3 vertices and 1 cell"));
                }
            }
            MeshSpec::Gmsh(GmshSpec { path }) => mesh_file(&key("path"), path)?,
        }
        Ok(())
    }
}

/// Refuses a gmsh mesh file `path` (the key `field`) that is not there or not a regular file.
fn mesh_file(field: &str, path: &Path) -> Result<()> {
    let problem = match std::fs::metadata(path) {
        Ok(m) if m.is_file() => return Ok(()),
        Ok(m) => format!(
            "`{}` is not a regular file ({}): give a gmsh mesh file",
            path.display(),
            kind_of(&m.file_type())
        ),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => format!(
            "no file `{}` (a relative path starts at the scene file's directory, or for a \
             scene given as text, at its base folder: the current one unless one is given)",
            path.display()
        ),
        Err(e) => format!("`{}`: {e}", path.display()),
    };
    Err(Error::scene(field, problem))
}

impl SupportSpec {
    /// Its keys in range, named under `at` (`bodies[0].supports[1]`).
    fn validate(&self, at: &str) -> Result<()> {
        let key = |k: &str| format!("{at}.{k}");
        match self {
            SupportSpec::GroundSpring(GroundSpringSpec {
                edge,
                components,
                span,
            }) => {
                if components.is_empty() {
                    return Err(Error::scene(
                        key("components"),
                        "must list `n`, `s` or both",
                    ));
                }
                check_span(&key("span"), edge, span)
            }
            SupportSpec::Clamp(ClampSpec {
                edge,
                dofs,
                velocity,
                ramp,
                span,
            }) => {
                check_span(&key("span"), edge, span)?;
                if let Some(velocity) = velocity {
                    finite_all(&key("velocity"), velocity)?;
                    for (c, dof) in ["u", "v"].into_iter().enumerate() {
                        let clamped = dofs.as_ref().is_none_or(|d| d.iter().any(|n| n == dof));
                        if velocity[c] != 0.0 && !clamped {
                            return Err(Error::scene(
                                key(&format!("velocity[{c}]")),
                                format!("must be 0 unless `dofs` lists `{dof}`"),
                            ));
                        }
                    }
                }
                RAMP.check(&key("ramp"), *ramp)?;
                if *ramp > 0.0 && velocity.is_none() {
                    return Err(Error::scene(
                        key("ramp"),
                        "is the time over which the clamp's `velocity` rises, and the clamp has \
                         none: give it a `velocity` or remove the ramp",
                    ));
                }
                Ok(())
            }
        }
    }
}

impl LoadSpec {
    /// Its value finite and its amplitude a function of time, named under `at`
    /// (`bodies[0].loads[1]`).
    fn validate(&self, at: &str) -> Result<()> {
        let (value, amplitude): (&[f64], _) = match self {
            LoadSpec::Traction(TractionSpec {
                value, amplitude, ..
            }) => (value, amplitude),
            LoadSpec::Force(ForceSpec {
                value, amplitude, ..
            }) => (value, amplitude),
        };
        finite_all(&format!("{at}.value"), value)?;
        if let Some(a) = amplitude {
            if a.is_empty()
                || a.windows(2).any(|w| !(w[1][0] > w[0][0]))
                || a.iter().any(|p| !p[0].is_finite() || !p[1].is_finite())
            {
                return Err(Error::scene(
                    format!("{at}.amplitude"),
                    "must be a non-empty list of [t, factor] with strictly increasing t",
                ));
            }
        }
        Ok(())
    }
}

impl InterfaceLawSpec {
    /// A strength in range, named under `at` (`materials.concrete.interface`), and fracture
    /// energies that give a finite softening.
    fn validate(&self, at: &str) -> Result<()> {
        if let InterfaceLawSpec::Facet(f) = self {
            return f.validate(at);
        }
        let Some((strength, energies)) = self.strength() else {
            return Ok(());
        };
        let key = |k: &str| format!("{at}.{k}");
        TENSILE_STRENGTH.check(&key("tensile_strength"), strength.tensile_strength)?;
        COHESION.check(&key("cohesion"), strength.cohesion)?;
        FRICTION_ANGLE.check(&key("friction_angle"), strength.friction_angle)?;
        if let Some([g_f, g_s]) = energies {
            FRACTURE_ENERGY.check(&key("fracture_energy"), g_f)?;
            FRACTURE_ENERGY_SHEAR.check(&key("fracture_energy_shear"), g_s)?;
            let f_t = strength.tensile_strength;
            softening_slope(&key("fracture_energy"), g_f, "tensile_strength", f_t)?;
            softening_slope(
                &key("fracture_energy_shear"),
                g_s,
                "cohesion",
                strength.cohesion,
            )?;
        }
        Ok(())
    }
}

impl TimeSpec {
    /// Exactly one of `dt` and `dt_factor`, one of `end` and `steps`, each in range.
    fn validate(&self) -> Result<()> {
        match (self.dt, self.dt_factor) {
            (Some(dt), None) => DT.check("time.dt", dt)?,
            (None, Some(f)) => DT_FACTOR.check("time.dt_factor", f)?,
            _ => {
                return Err(Error::scene(
                    "time.dt",
                    "give exactly one of `dt` (s, > 0) and `dt_factor` (fraction of Δt_crit, > 0)",
                ))
            }
        }
        if let Some(r) = self.stop_ratio {
            STOP_RATIO.check("time.stop_ratio", r)?;
        }
        match (self.end, self.steps) {
            (Some(end), None) => END.check("time.end", end),
            (None, Some(n)) => STEPS.check_count("time.steps", n),
            _ => Err(Error::scene(
                "time.end",
                "give exactly one of `end` (s, > 0) and `steps` (≥ 1)",
            )),
        }
    }
}

/// A support's `span` (`field`): finite, `from < to`, and on a side, not a gmsh group.
fn check_span(field: &str, edge: &EdgeSet, span: &Option<[f64; 2]>) -> Result<()> {
    let Some(span) = span else {
        return Ok(());
    };
    finite_all(field, span)?;
    if !(span[0] < span[1]) {
        return Err(Error::scene(
            field,
            format!("must be [from, to] with from < to, got {span:?}"),
        ));
    }
    if let EdgeSet::Group(_) = edge {
        return Err(Error::scene(
            field,
            "applies to a side (`left`, `right`, `bottom`, `top`) only",
        ));
    }
    Ok(())
}

fn finite_all(field: &str, xs: &[f64]) -> Result<()> {
    match xs.iter().position(|x| !x.is_finite()) {
        None => Ok(()),
        Some(k) => Err(Error::scene(
            format!("{field}[{k}]"),
            "must be a finite number",
        )),
    }
}

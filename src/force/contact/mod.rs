//! Contact between bodies and with rigid ground (eqs. 17–20; the scene's `contact` key in
//! `docs/scene.md`).
//!
//! Every boundary edge of a body, and every ground segment, is a surface that other bodies can
//! enter. Two contact models, one type each, behind one [`Contact`]:
//! - edge-to-edge (the paper's, `overlap.rs`, `Overlap`) treats the part of each boundary edge
//!   that lies inside an element of another body, or below a ground segment, as a temporary
//!   interface: tractions `k δ` per unit length with `δ_n` the depth below the nearest surface
//!   face, integrated exactly by 2-point Gauss on each piece; the normal tractions are the
//!   gradient of one energy, and a neighbour list with a skin keeps the search local;
//! - point (classic DEM, `point.rs`, `PointContact`): a spring at each boundary vertex whose
//!   path over a step entered an edge of another body (eqs. 18–20), with the gap of eq. 17.
//!
//! [`Contact`] holds what the two share: the settings, the elements' frames, the thickness and
//! spring factor, the ledger of the contact forces and their work (`work.rs`), the stored
//! energy, the step of the last evaluation and the counters; each model's own state is in its
//! variant of `Kind`, and every choice between the two models is a `match` on it in this file.
//! The interface law that gives the springs their traction is the model's
//! ([`crate::model::Model::law`]): the caller passes it to [`Contact::apply`].
//!
//! Equal and opposite forces act on both bodies at the same points, so momentum is kept. The
//! springs are those of eq. 12 with the two sides' `h` (`h = 0` for the ground), in series when
//! the materials differ, times the hybrid penalty. A scene without `contact` builds none of this
//! and the integrator does no contact work.

mod boundary;
mod detect;
mod overlap;
mod point;
mod work;

pub use detect::{entry, frame, gap, Gap};
pub use point::Record;

use crate::force::evaluator::Evaluator;
use crate::input::scene::{ContactModel, ContactSpec, EvaluatorKind};
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{rotation, Formulation};
use crate::model::law::InterfaceLaw;
use crate::model::{Model, GROUND};
use boundary::Boundary;
use overlap::Overlap;
use point::PointContact;
use std::time::Instant;
use work::Ledger;

/// Marks a missing edge or body.
const NONE: u32 = u32::MAX;

/// Counters of the contact work of a run.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct ContactStats {
    /// Steps evaluated.
    pub steps: u64,
    /// Vertex–edge contacts summed over the steps (the mean is `pairs / steps`).
    pub pairs: u64,
    /// Most vertex–edge contacts in one step.
    pub max_pairs: usize,
    /// Narrow-phase tests summed over the steps: vertex path against edge (point), source edge
    /// against target element or ground strip (edge-to-edge).
    pub tests: u64,
    /// Builds of the neighbour lists: only when something moved more than half their skin.
    pub rebuilds: u64,
    /// Wall time spent in contact (s), over the steps that had contact work to do (edge-to-edge
    /// does not time a step whose neighbour list is empty and whose bodies stayed within its
    /// skin: a body in flight); of a resumed run, since it resumed, as `step_time_s`.
    pub time_s: f64,
}

/// The contact state of a run and the forces it exerts.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Contact {
    /// What the scene asked for.
    pub settings: ContactSpec,
    frames: Frames,
    thickness: f64,
    factor: f64,
    /// The boundary vertices that can touch and the edges they can touch, ground segments
    /// included ([`Contact::extent`]).
    extent: (usize, usize),
    /// The contact model's own state.
    kind: Kind,
    /// The contact forces and their work.
    ledger: Ledger,
    /// Energy in the contact springs at the last evaluation (J).
    stored: f64,
    /// The step of the last evaluation.
    step: Option<u64>,
    /// Pairs, tests and time spent, for `summary.json`.
    pub stats: ContactStats,
}

/// The state of one contact model: its fields live in its type, and [`Contact`] chooses
/// between them. A third model is a third variant, a type in a file of its own with the same
/// few methods (`new`, `reserve`, `check_saved`, `forces`), and an arm in each `match` here.
/// An enum, not a trait object: a checkpoint serialises it as it is, and a step calls its
/// model without dynamic dispatch.
// One per run, so the bytes that the smaller variant leaves unused cost nothing; a box would
// only add an indirection.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
enum Kind {
    /// Classic DEM vertex-to-edge contact.
    Point(PointContact),
    /// The paper's edge-to-edge contact (eqs. 17–20 over the overlap).
    EdgeToEdge(Overlap),
}

/// What a step of either contact model reads: the shared part of the contact, the interface
/// law and the state.
struct Step<'a> {
    frames: &'a Frames,
    /// The model's interface law (eq. 11), which gives the springs of eq. 12 their traction.
    law: &'a dyn InterfaceLaw,
    /// The model's thickness (m).
    thickness: f64,
    /// The formulation's factor on the springs (the hybrid penalty).
    factor: f64,
    /// Coulomb's `μ`, if any.
    friction: Option<f64>,
    /// No evaluation before this one: the run's first.
    first: bool,
    u: &'a [f64],
    /// `v^{n−½}`: the step that led here moved the bodies by `Δt v^{n−½}`.
    velocity: &'a [f64],
    dt: f64,
}

impl Contact {
    /// The vertices that can touch and the edges they can touch (ground segments included).
    pub fn extent(&self) -> (usize, usize) {
        self.extent
    }

    /// The contact of a model; `None` when its scene declares none.
    pub fn new(model: &Model) -> Option<Contact> {
        let settings = model.contact?;
        let boundary = Boundary::of(model);
        let extent = (boundary.vertices.len(), boundary.edges.len());
        let (tenth, skin) = boundary.skins();
        let kind = match settings.model {
            ContactModel::Point => Kind::Point(PointContact::new(boundary, skin)),
            ContactModel::EdgeToEdge => Kind::EdgeToEdge(Overlap::new(model, tenth)),
        };
        Some(Contact {
            settings,
            frames: Frames {
                formulation: model.formulation,
                centroids: model.elements.iter().map(|e| e.props.centroid).collect(),
            },
            thickness: model.thickness,
            factor: model.formulation.spring_factor(),
            extent,
            kind,
            ledger: Ledger::new(model.elements.len(), model.formulation.ndof()),
            stored: 0.0,
            step: None,
            stats: ContactStats::default(),
        })
    }

    /// A copy of this contact for a new run, with room in its buffers for the steps (a plain
    /// `clone` keeps only their contents, and the steps would then allocate). The contact of
    /// [`Contact::new`] has no such room: it is the setup's initial state, never stepped, and
    /// its room would be address space held for nothing (the neighbour lists and pieces of
    /// every edge of a body that fragments, 1.2 kB per Voronoi element).
    pub fn copy(&self) -> Contact {
        let mut c = self.clone();
        c.ledger.reserve();
        match &mut c.kind {
            Kind::Point(p) => p.reserve(),
            Kind::EdgeToEdge(o) => o.reserve(),
        }
        c
    }

    /// Whether `saved`, the contact state of a checkpoint, belongs to this contact's model (in
    /// its initial state): the same settings, boundary and contact model, and every index it
    /// holds (contacts, neighbour lists, pieces, forces) within them. `Err` says what is off.
    /// A checkpoint that passes is restored by assignment: it holds the whole contact state.
    ///
    /// # Errors
    /// `saved` has other settings, contact vertices and edges, or contact model than this contact,
    /// or holds an index (contact, neighbour list, piece, force) outside them; the message says
    /// which.
    pub fn check_saved(&self, saved: &Contact) -> std::result::Result<(), String> {
        if !same(&self.settings, &saved.settings) || self.extent != saved.extent {
            return Err("its contact vertices and edges are not this model's".into());
        }
        saved.ledger.check(&self.ledger)?;
        match (&self.kind, &saved.kind) {
            (Kind::Point(fresh), Kind::Point(p)) => fresh.check_saved(p),
            (Kind::EdgeToEdge(fresh), Kind::EdgeToEdge(o)) => fresh.check_saved(o),
            _ => Err("its contact model is not this scene's".into()),
        }
    }

    /// Hands the interfaces of `plastic` that `state` has released over to contact: their two
    /// elements touch from now on (`force::failure`). Nothing to do for a scene whose bodies do
    /// not fragment (point contact's never do: `Model::fragments`).
    pub fn release(
        &mut self,
        plastic: &dyn crate::force::failure::PlasticForces,
        state: &crate::force::failure::FailureState,
    ) {
        match &mut self.kind {
            Kind::Point(_) => {}
            Kind::EdgeToEdge(o) => o.release(plastic.interfaces(), &state.released),
        }
    }

    /// The live vertex contacts of point contact after the last step (none for edge-to-edge).
    pub fn records(&self) -> &[Record] {
        match &self.kind {
            Kind::Point(p) => &p.records,
            Kind::EdgeToEdge(_) => &[],
        }
    }

    /// The number of live contacts after the last step: vertex contacts (point), or pieces of
    /// edges inside the part of one face of a target (edge-to-edge).
    pub fn live(&self) -> usize {
        match &self.kind {
            Kind::Point(p) => p.records.len(),
            Kind::EdgeToEdge(o) => o.len(),
        }
    }

    /// Subtracts the contact forces `f_c^n` at step `n`, state `u = U^n`, from `f` (which holds
    /// `f_int − P`) and returns the contact energy `−W`, `W` the work of the contact forces on
    /// the bodies so far: the energy stored in the contact springs plus what friction, and
    /// tangential springs released while stretched, took from the motion (J). `law` is the
    /// model's interface law ([`crate::model::Model::law`]), which gives the contact springs
    /// their traction. `velocity` is `v^{n−½}`, so that `U^n − U^{n−1} = Δt v^{n−½}`. A second
    /// call at the same step gives the same forces. Allocation-free once the buffers have
    /// grown.
    pub fn apply(
        &mut self,
        law: &dyn InterfaceLaw,
        step: u64,
        u: &[f64],
        velocity: &[f64],
        dt: f64,
        f: &mut [f64],
    ) -> f64 {
        if self.step != Some(step) {
            // A step with nothing to do (bodies in flight) is not timed: two clock readings would
            // cost more than it.
            let idle = match &self.kind {
                Kind::Point(_) => false,
                Kind::EdgeToEdge(o) => o.idle(u),
            };
            let clock = (!idle).then(Instant::now);
            self.ledger.next();
            let at = Step {
                frames: &self.frames,
                law,
                thickness: self.thickness,
                factor: self.factor,
                friction: self.settings.friction,
                first: self.step.is_none(),
                u,
                velocity,
                dt,
            };
            let (ledger, stats) = (&mut self.ledger, &mut self.stats);
            self.stored = match &mut self.kind {
                _ if idle => 0.0,
                Kind::Point(p) => p.forces(&at, ledger, stats),
                Kind::EdgeToEdge(o) => o.forces(&at, ledger, stats),
            };
            match self.step {
                Some(_) => self.ledger.add_work(velocity, dt),
                // Springs already pressed at the start (a body placed at rest on another) hold
                // energy that no work of this run put in.
                None => self.ledger.work = -self.stored,
            }
            self.step = Some(step);
            self.stats.steps += 1;
            let live = self.live();
            self.stats.pairs += live as u64;
            self.stats.max_pairs = self.stats.max_pairs.max(live);
            if let Some(clock) = clock {
                self.stats.time_s += clock.elapsed().as_secs_f64();
            }
        }
        self.ledger.subtract_from(f);
        -self.ledger.work
    }

    /// The force that the ground segments exert on the bodies at the last evaluation (N): the
    /// ground's reaction, equal to the weight of what rests on it when nothing moves.
    pub fn ground_reaction(&self) -> Vec2 {
        match &self.kind {
            Kind::Point(p) => p.ground,
            Kind::EdgeToEdge(o) => o.ground,
        }
    }

    /// The generalised contact force `f_c` on element `e` at the last evaluation (`ndof`
    /// entries: N, N, N·m, then for hybrid the strain work-conjugates).
    pub fn element_force(&self, e: usize) -> &[f64] {
        self.ledger.on(e)
    }

    /// Energy in the contact springs at the last evaluation (J); the contact energy minus this
    /// is what contact took from the motion.
    pub fn stored(&self) -> f64 {
        self.stored
    }
}

/// The current frames of the elements: where a force on a moving element acts.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct Frames {
    formulation: Formulation,
    /// Reference centroids (m).
    centroids: Vec<Vec2>,
}

impl Frames {
    /// Current position of the point at reference offset `d` of element `e`.
    fn place(&self, u: &[f64], e: usize, d: Vec2) -> Vec2 {
        let nd = self.formulation.ndof();
        self.formulation
            .current_position(self.centroids[e], &u[e * nd..(e + 1) * nd], d)
    }

    /// [`Frames::place`] for several offsets of one element.
    fn place_all(&self, u: &[f64], e: usize, offsets: &[Vec2], out: &mut [Vec2]) {
        let nd = self.formulation.ndof();
        let ue = &u[e * nd..(e + 1) * nd];
        let (c, r) = (self.centroids[e] + Vec2::new(ue[0], ue[1]), rotation(ue[2]));
        for (x, &d) in out.iter_mut().zip(offsets) {
            *x = c + r * (d + self.formulation.strain_part(ue, d));
        }
    }

    /// How far the material point of element `e` now at `x` moved over the last step, the
    /// element's DOFs having moved by `Δt v` (to first order in that increment).
    fn increment(&self, u: &[f64], velocity: &[f64], dt: f64, e: usize, x: Vec2) -> Vec2 {
        let nd = self.formulation.ndof();
        let (ue, ve) = (&u[e * nd..(e + 1) * nd], &velocity[e * nd..(e + 1) * nd]);
        let arm = x - self.centroids[e] - Vec2::new(ue[0], ue[1]);
        let rigid = Vec2::new(dt * ve[0], dt * ve[1]) + (dt * ve[2]) * Vec2::new(-arm.y, arm.x);
        match self.formulation {
            Formulation::Rigid | Formulation::RigidPoisson => rigid,
            Formulation::Hybrid { .. } => {
                let mut du = [0.0; 6];
                for (d, v) in du.iter_mut().zip(ve) {
                    *d = dt * v;
                }
                let r = rotation(ue[2]);
                rigid + r * self.formulation.strain_part(&du[..nd], r.transpose() * arm)
            }
        }
    }

    /// `f_c += N_eᵀ F` for a force `F` at the current point `x` of element `e`, through the
    /// element's current position and rotation.
    fn push(&self, u: &[f64], ledger: &mut Ledger, e: u32, x: Vec2, force: Vec2) {
        ledger.add(
            e as usize,
            &self.generalised(u, e, x, force)[..self.formulation.ndof()],
        );
    }

    /// `N_eᵀ F` for a force `F` at the current point `x` of element `e` (the first `ndof`
    /// entries), through the element's current position and rotation.
    fn generalised(&self, u: &[f64], e: u32, x: Vec2, force: Vec2) -> [f64; 6] {
        let nd = self.formulation.ndof();
        let e = e as usize;
        let ue = &u[e * nd..(e + 1) * nd];
        let arm = x - self.centroids[e] - Vec2::new(ue[0], ue[1]);
        let mut q = [0.0; 6];
        if nd == 3 {
            // The moment about the current centroid: (R d) × F = d × (Rᵀ F).
            q[..3].copy_from_slice(&[force.x, force.y, arm.perp(&force)]);
            return q;
        }
        let r = rotation(ue[2]);
        self.formulation
            .add_point_force(&mut q[..nd], r.transpose() * arm, r.transpose() * force);
        // The translation entries hold Rᵀ F, in the element's frame: back to global axes.
        q[0] = force.x;
        q[1] = force.y;
        q
    }
}

/// Whether `a` and `b` serialise to the same bytes: a part of a saved contact that its model
/// decides, against the model's own.
fn same<T: serde::Serialize + ?Sized>(a: &T, b: &T) -> bool {
    postcard::to_stdvec(a).ok() == postcard::to_stdvec(b).ok()
}

/// The stiffness of every contact closed at once against rigid ground, per element (row-major
/// `ndof × ndof` blocks): each boundary edge pressed with `k_n` in every direction
/// (edge-to-edge), or each boundary vertex with `k_n ℓ_trib` (point). Contacts between bodies
/// are softer (their springs are in series), so `ω_max` with these blocks bounds the stable
/// step of a contact run from below.
pub fn stiffness_estimate(model: &Model, contact: &Contact) -> Vec<f64> {
    let nd = model.formulation.ndof();
    let t = model.thickness;
    let mut blocks = vec![0.0; model.elements.len() * nd * nd];
    let mut add = |e: usize, d: Vec2, weight: f64| {
        // weight · N(d)ᵀ N(d), with the rows of N from the generalised forces of unit forces.
        let rows = [Vec2::new(1.0, 0.0), Vec2::new(0.0, 1.0)]
            .map(|dir| model.formulation.point_load(d, dir, 0.0));
        for i in 0..nd {
            for j in 0..nd {
                blocks[(e * nd + i) * nd + j] +=
                    weight * (rows[0][i] * rows[0][j] + rows[1][i] * rows[1][j]);
            }
        }
    };
    // The reference boundary, rebuilt from the model: edge-to-edge contact keeps none.
    let boundary = Boundary::of(model);
    for edge in boundary.edges.iter().filter(|e| e.element != GROUND) {
        let e = edge.element as usize;
        let [k, _] = model
            .law
            .springs(edge.compliance.map(|c| contact.factor / c));
        let [a, b] = edge.ends.map(|v| boundary.vertices[v as usize].offset);
        let weight = t * k * 0.5 * edge.length;
        match contact.kind {
            Kind::EdgeToEdge(_) => {
                for g in [-1.0, 1.0] {
                    let xi = 0.5 * (1.0 + g / 3f64.sqrt());
                    add(e, a + xi * (b - a), weight);
                }
            }
            // Half of each edge at each of its ends; a vertex's springs are then at most the
            // stiffest of its edges' (the record averages them).
            Kind::Point(_) => {
                add(e, a, weight);
                add(e, b, weight);
            }
        }
    }
    blocks
}

/// An evaluator plus a block-diagonal stiffness (for `ω_max` with the contact estimate).
pub struct WithBlocks<'a> {
    /// The model's evaluator (`K`).
    pub inner: &'a dyn Evaluator,
    /// DOFs per element.
    pub nd: usize,
    /// One `nd × nd` contact stiffness block per element, row-major (N/m, N, N·m).
    pub blocks: Vec<f64>,
}

impl Evaluator for WithBlocks<'_> {
    fn kind(&self) -> EvaluatorKind {
        self.inner.kind()
    }
    fn bytes(&self) -> usize {
        self.inner.bytes() + std::mem::size_of_val(&self.blocks[..])
    }
    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        self.inner.internal_force(u, f);
        let nd = self.nd;
        for (e, (fe, ue)) in f.chunks_exact_mut(nd).zip(u.chunks_exact(nd)).enumerate() {
            let b = &self.blocks[e * nd * nd..(e + 1) * nd * nd];
            for i in 0..nd {
                fe[i] += (0..nd).map(|j| b[i * nd + j] * ue[j]).sum::<f64>();
            }
        }
    }
}

//! Contact between bodies and with rigid ground (eqs. 17–20; the scene's `contact` key in
//! `docs/scene.md`).
//!
//! Every boundary edge of a body, and every ground segment, is a surface that other bodies can
//! enter. [`ContactModel::EdgeToEdge`] (the paper's, `overlap.rs`) treats the part of each
//! boundary edge that lies inside an element of another body, or below a ground segment, as a
//! temporary interface: tractions `k δ` per unit length with `δ_n` the depth below the nearest
//! surface face, integrated exactly by 2-point Gauss on each piece; the normal tractions are the
//! gradient of one energy, and a neighbour list with a skin keeps the search local.
//! [`ContactModel::Point`] is classic DEM, each step:
//! 1. the boundary vertices are placed with the finite rotation of their element
//!    (`x = x_e + u_e + R(θ_e)(d + E_e d)`, `E_e d` the strain part of a hybrid element);
//! 2. a neighbour list (from a bucket grid of the edges, rebuilt only when a vertex has moved
//!    half its skin) holds the edges near each vertex, and eqs. 18–19 find the paths `p → m`
//!    over the step that enter an edge of another body; the crossing point `c` (eq. 20) is kept
//!    with the contact as a fraction of the
//!    target edge, so it moves with it;
//! 3. each contact's gap `δ_n`, `δ_s` (eq. 17) is measured; the contact is released when the
//!    gap opens (`δ_n ≤ 0`) or the vertex leaves the edge's span; with a Coulomb limit `μ` the
//!    crossing point slides so that `k_s |δ_s| ≤ μ k_n δ_n`;
//! 4. one spring `k ℓ_trib` acts at each contact vertex.
//!
//! Equal and opposite forces act on both bodies at the same points, so momentum is kept. The
//! springs are those of eq. 12 with the two sides' `h` (`h = 0` for the ground), in series when
//! the materials differ, times the hybrid penalty. A scene without `contact` builds none of this
//! and the integrator does no contact work.

mod detect;
mod overlap;
mod work;

pub use detect::{entry, frame, gap, Gap};

use crate::force::evaluator::Evaluator;
use crate::input::scene::{ContactModel, ContactSpec, EvaluatorKind};
use crate::mesh::buckets::{boxes_meet, moved_beyond, BucketLists, Buckets};
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{rotation, Formulation};
use crate::model::law::InterfaceLaw;
use crate::model::{Model, GROUND};
use overlap::Overlap;
use std::time::Instant;
use work::Ledger;

/// Marks a missing edge or body.
const NONE: u32 = u32::MAX;

/// A vertex of an element on its body's boundary: a point that can enter another body.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
struct Vertex {
    element: u32,
    body: u32,
    /// Offset from the element's centroid in the reference configuration (m).
    offset: Vec2,
    /// The element's boundary edges that meet here ([`NONE`] if only one does).
    edges: [u32; 2],
}

/// A surface that vertices can enter: a boundary edge of an element (counter-clockwise, solid
/// on its left) or a ground segment.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
struct Edge {
    /// The element it belongs to, or [`GROUND`].
    element: u32,
    body: u32,
    /// End points, as indices into the current points (vertices first, then ground points).
    ends: [u32; 2],
    /// Compliances `h / E_n` and `h / E_s` of this side (eq. 12 is `k = E / (h_a + h_b)`);
    /// zero for the ground.
    compliance: [f64; 2],
    /// Reference length (m).
    length: f64,
}

/// A vertex in contact with an edge.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct Record {
    /// The vertex (index into the contact's vertices).
    pub vertex: u32,
    /// The edge it touches (index into the contact's edges).
    pub edge: u32,
    /// The crossing point `c` of eq. 20 as a fraction of the edge, `c = b1 + λ (b2 − b1)`.
    pub lambda: f64,
    /// The vertex's tributary length (m): half of each of its edges that faces the target.
    pub ell: f64,
    /// Normal and tangential springs per unit length (Pa/m) at the vertex: those of the
    /// interface law (eq. 11) on the moduli of eq. 12.
    pub k: [f64; 2],
    /// The gap `[δ_n, δ_s]` of this step (m).
    pub gap: [f64; 2],
}

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
    /// skin: a body in flight).
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
    vertices: Vec<Vertex>,
    edges: Vec<Edge>,
    /// Current points: the vertices' positions, then the ground points (fixed).
    points: Vec<Vec2>,
    /// The vertices' positions at the previous step.
    previous: Vec<Vec2>,
    /// Live contacts, sorted by `(vertex, edge)`.
    records: Vec<Record>,
    /// Contacts found this step.
    fresh: Vec<Record>,
    buckets: BucketLists,
    /// Point contact's neighbour list: the edges near vertex `v` are
    /// `near[near_start[v]..near_start[v + 1]]`.
    near_start: Vec<u32>,
    near: Vec<u32>,
    /// The vertices at the last rebuild of the neighbour list.
    anchors: Vec<Vec2>,
    /// The neighbour list is rebuilt when a vertex has moved more than half of this (m): a tenth
    /// of the mean boundary edge, and at least the depth within which a vertex placed inside
    /// an edge counts as touching it.
    skin: f64,
    /// Per edge, the last vertex that tested it (each pair is tested once per step).
    stamp: Vec<u32>,
    /// Edge-to-edge contact's targets, neighbour list and pieces (`None` for point contact).
    overlap: Option<Overlap>,
    /// The contact forces and their work.
    ledger: Ledger,
    /// Energy in the contact springs at the last evaluation (J).
    stored: f64,
    /// The force of the ground on the bodies at the last evaluation of point contact (N).
    ground: Vec2,
    /// The step of the last evaluation.
    step: Option<u64>,
    /// Pairs, tests and time spent, for `summary.json`.
    pub stats: ContactStats,
}

impl Contact {
    /// The vertices that can touch and the edges they can touch (ground segments included).
    pub fn extent(&self) -> (usize, usize) {
        (self.vertices.len(), self.edges.len())
    }

    /// The contact of a model; `None` when its scene declares none.
    pub fn new(model: &Model) -> Option<Contact> {
        let settings = model.contact?;
        let mut vertices = Vec::new();
        let mut edges = Vec::new();
        for (bi, body) in model.bodies.iter().enumerate() {
            let mesh = &body.mesh;
            let moduli = body.moduli;
            // The element's boundary vertices, numbered in order of first appearance.
            let mut index = std::collections::HashMap::new();
            for e in &mesh.boundary {
                let element = body.first_element + e.cell as usize;
                let centroid = model.elements[element].props.centroid;
                let (p1, p2) = (mesh.vertices[e.v1 as usize], mesh.vertices[e.v2 as usize]);
                let (_, n, length) = frame(p1, p2);
                let h = (p1 - centroid).dot(&n).abs();
                let id = edges.len() as u32;
                let mut end = |v: u32, p: Vec2| {
                    *index.entry((element, v)).or_insert_with(|| {
                        vertices.push(Vertex {
                            element: element as u32,
                            body: bi as u32,
                            offset: p - centroid,
                            edges: [NONE; 2],
                        });
                        vertices.len() as u32 - 1
                    })
                };
                let ends = [end(e.v1, p1), end(e.v2, p2)];
                for &v in &ends {
                    let slot = &mut vertices[v as usize].edges;
                    let k = if slot[0] == NONE { 0 } else { 1 };
                    slot[k] = id;
                }
                edges.push(Edge {
                    element: element as u32,
                    body: bi as u32,
                    ends,
                    compliance: [h / moduli[0], h / moduli[1]],
                    length,
                });
            }
        }
        let mut points: Vec<Vec2> = vertices
            .iter()
            .map(|v| model.elements[v.element as usize].props.centroid + v.offset)
            .collect();
        for g in &model.ground {
            // Stored `to → from`: the solid side is then on the left, as for a body's boundary.
            let at = points.len() as u32;
            points.extend([g[1], g[0]]);
            edges.push(Edge {
                element: GROUND,
                body: NONE,
                ends: [at, at + 1],
                compliance: [0.0; 2],
                length: (g[1] - g[0]).norm(),
            });
        }
        let nv = vertices.len();
        // Both neighbour lists keep a skin of a tenth of the mean boundary edge; point contact's
        // also holds the depth within which a vertex placed inside an edge touches it.
        let body_edges = edges.iter().filter(|e| e.element != GROUND);
        let (total, longest) = body_edges
            .clone()
            .fold((0.0, 0.0f64), |(t, l), e| (t + e.length, l.max(e.length)));
        let tenth = 0.1 * total / body_edges.count().max(1) as f64;
        let skin = tenth.max(0.05 * longest);
        let contact = Contact {
            settings,
            frames: Frames {
                formulation: model.formulation,
                centroids: model.elements.iter().map(|e| e.props.centroid).collect(),
            },
            thickness: model.thickness,
            factor: model.formulation.spring_factor(),
            previous: points[..vertices.len()].to_vec(),
            stamp: vec![NONE; edges.len()],
            vertices,
            edges,
            points,
            records: Vec::new(),
            fresh: Vec::new(),
            buckets: BucketLists::default(),
            near_start: Vec::new(),
            near: Vec::new(),
            anchors: vec![Vec2::repeat(f64::INFINITY); nv],
            skin,
            overlap: (settings.model == ContactModel::EdgeToEdge)
                .then(|| Overlap::new(model, settings.friction, tenth)),
            ledger: Ledger::new(model.elements.len(), model.formulation.ndof()),
            stored: 0.0,
            ground: Vec2::zeros(),
            step: None,
            stats: ContactStats::default(),
        };
        Some(contact)
    }

    /// A copy of this contact for a new run, with room in its buffers for the steps (a plain
    /// `clone` keeps only their contents, and the steps would then allocate). The contact of
    /// [`Contact::new`] has no such room: it is the setup's initial state, never stepped, and
    /// its room would be address space held for nothing (the neighbour lists and pieces of
    /// every edge of a body that fragments, 1.2 kB per Voronoi element).
    pub fn copy(&self) -> Contact {
        let mut c = self.clone();
        c.reserve();
        c
    }

    /// Room for two contacts per vertex and for the neighbour lists, so that the steps do not
    /// allocate.
    fn reserve(&mut self) {
        let (nv, ne) = (self.vertices.len(), self.edges.len());
        self.records.reserve_exact(2 * nv);
        self.fresh.reserve_exact(2 * nv);
        self.buckets.reserve(ne);
        self.near_start.reserve_exact(nv + 1);
        self.near.reserve_exact(4 * nv);
        self.ledger.reserve();
        if let Some(o) = self.overlap.as_mut() {
            o.reserve();
        }
    }

    /// Whether `saved`, the contact state of a checkpoint, belongs to this contact's model (in
    /// its initial state): the same vertices, edges and targets, and every index it holds
    /// (contacts, neighbour lists, pieces, forces) within them. `Err` says what is off. A
    /// checkpoint that passes is restored by assignment: it holds the whole contact state.
    pub fn check_saved(&self, saved: &Contact) -> std::result::Result<(), String> {
        if !same(&self.vertices, &saved.vertices)
            || !same(&self.edges, &saved.edges)
            || !same(&self.settings, &saved.settings)
        {
            return Err("its contact vertices and edges are not this model's".into());
        }
        let (nv, ne) = (self.vertices.len(), self.edges.len());
        let lengths = [
            (saved.points.len(), self.points.len()),
            (saved.previous.len(), nv),
            (saved.anchors.len(), nv),
            (saved.stamp.len(), ne),
        ];
        if lengths.iter().any(|(a, b)| a != b) {
            return Err("its contact points are not this model's".into());
        }
        let records = saved.records.iter().chain(&saved.fresh);
        if records
            .clone()
            .any(|r| r.vertex as usize >= nv || r.edge as usize >= ne)
        {
            return Err("a vertex contact names a vertex or an edge out of range".into());
        }
        let start = &saved.near_start;
        if !(start.is_empty() && saved.near.is_empty())
            && (start.len() != nv + 1
                || start.windows(2).any(|w| w[0] > w[1])
                || start.last().is_some_and(|&l| l as usize > saved.near.len())
                || saved.near.iter().any(|&e| e as usize >= ne))
        {
            return Err("its neighbour list is out of range".into());
        }
        saved.ledger.check(&self.ledger)?;
        match (&self.overlap, &saved.overlap) {
            (None, None) => Ok(()),
            (Some(fresh), Some(o)) => fresh.check_saved(o),
            _ => Err("its contact model is not this scene's".into()),
        }
    }

    /// Hands the interfaces of `plastic` that `state` has released over to contact: their two
    /// elements touch from now on (`force::failure`). Nothing to do for a scene whose bodies do
    /// not fragment.
    pub fn release(
        &mut self,
        plastic: &dyn crate::force::failure::PlasticForces,
        state: &crate::force::failure::FailureState,
    ) {
        if let Some(o) = self.overlap.as_mut() {
            o.release(plastic.interfaces(), &state.released);
        }
    }

    /// The live vertex contacts of point contact after the last step.
    pub fn records(&self) -> &[Record] {
        &self.records
    }

    /// The number of live contacts after the last step: vertex contacts (point), or pieces of
    /// edges inside the part of one face of a target (edge-to-edge).
    pub fn live(&self) -> usize {
        self.overlap
            .as_ref()
            .map_or(self.records.len(), Overlap::len)
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
            let idle = self.overlap.as_ref().is_some_and(|o| o.idle(u));
            let clock = (!idle).then(Instant::now);
            self.ledger.next();
            self.stored = match self.overlap.as_mut() {
                Some(_) if idle => 0.0,
                Some(o) => o.forces(
                    &self.frames,
                    law,
                    u,
                    velocity,
                    dt,
                    &mut self.ledger,
                    &mut self.stats.tests,
                ),
                None => {
                    self.place(u);
                    self.detect(law);
                    self.update_gaps();
                    self.point_forces(u)
                }
            };
            match self.step {
                Some(_) => self.ledger.add_work(velocity, dt),
                // Springs already pressed at the start (a body placed at rest on another) hold
                // energy that no work of this run put in.
                None => self.ledger.work = -self.stored,
            }
            if self.overlap.is_none() {
                let n = self.vertices.len();
                self.previous.copy_from_slice(&self.points[..n]);
            }
            self.step = Some(step);
            self.stats.steps += 1;
            let live = self.live();
            self.stats.pairs += live as u64;
            self.stats.max_pairs = self.stats.max_pairs.max(live);
            if let Some(o) = &self.overlap {
                self.stats.rebuilds = o.rebuilds;
            }
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
        self.overlap.as_ref().map_or(self.ground, |o| o.ground)
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

    /// Current positions of the boundary vertices (finite rotation of each element).
    fn place(&mut self, u: &[f64]) {
        for (x, v) in self.points.iter_mut().zip(&self.vertices) {
            *x = self.frames.place(u, v.element as usize, v.offset);
        }
    }

    /// New contacts: vertex paths that entered an edge of another body this step (eqs. 18–20);
    /// at the first step, vertices that start just inside an edge; `law` gives their springs.
    fn detect(&mut self, law: &dyn InterfaceLaw) {
        let n = self.vertices.len();
        if moved_beyond(&self.points[..n], &self.anchors, 0.5 * self.skin) {
            self.rebuild_near();
        }
        self.fresh.clear();
        for v in 0..n {
            let (p, m) = (self.previous[v], self.points[v]);
            let mut best: Option<(f64, u32, f64)> = None;
            for &e in &self.near[self.near_start[v] as usize..self.near_start[v + 1] as usize] {
                let edge = &self.edges[e as usize];
                self.stats.tests += 1;
                let [b1, b2] = edge.ends.map(|i| self.points[i as usize]);
                let found = if self.step.is_some() {
                    // The path relative to the edge: where `p` was with respect to the edge's
                    // previous position, carried to its current one (`p` itself for ground).
                    let [a1, a2] = edge.ends.map(|i| {
                        if (i as usize) < n {
                            self.previous[i as usize]
                        } else {
                            self.points[i as usize]
                        }
                    });
                    let p = relative_start(p, a1, a2, b1, b2);
                    entry(p, m, b1, b2).map(|lambda| (gap(m, b1, b2, lambda).normal, lambda))
                } else {
                    start_inside(m, b1, b2, self.size(v))
                };
                if let Some((depth, lambda)) = found {
                    if best.is_none_or(|b| depth < b.0) {
                        best = Some((depth, e, lambda));
                    }
                }
            }
            if let Some((_, e, lambda)) = best {
                if self.find(v as u32, e).is_none() {
                    let r = self.record(law, v as u32, e, lambda);
                    self.fresh.push(r);
                }
            }
        }
        if !self.fresh.is_empty() {
            self.records.extend_from_slice(&self.fresh);
            self.records.sort_unstable_by_key(|r| (r.vertex, r.edge));
        }
    }

    /// The neighbour list of point contact: for each vertex, the edges of other bodies (and the
    /// ground segments) whose boxes, widened by the skin, reach its own widened box. It holds
    /// every edge that the vertex's path can cross until some vertex has moved half the skin.
    fn rebuild_near(&mut self) {
        let n = self.vertices.len();
        self.anchors.copy_from_slice(&self.points[..n]);
        self.stats.rebuilds += 1;
        let widen = Vec2::repeat(self.skin);
        let (mut lo, mut hi) = (self.points[0], self.points[0]);
        for x in &self.points[..n] {
            lo = lo.inf(x);
            hi = hi.sup(x);
        }
        let grid = Buckets::new(lo - widen, hi + widen, self.edges.len());
        let (points, edges) = (&self.points, &self.edges);
        let boxes = |k: usize| {
            let [a, b] = edges[k].ends.map(|i| points[i as usize]);
            (a.inf(&b) - widen, a.sup(&b) + widen)
        };
        self.buckets.fill(&grid, edges.len(), boxes);
        self.stamp.fill(NONE);
        self.near.clear();
        self.near_start.clear();
        self.near_start.push(0);
        for v in 0..n {
            let (x, body) = (self.points[v], self.vertices[v].body);
            let (vlo, vhi) = (x - widen, x + widen);
            for k in grid.touching(vlo, vhi) {
                for &e in self.buckets.bucket(k) {
                    if self.edges[e as usize].body == body || self.stamp[e as usize] == v as u32 {
                        continue;
                    }
                    self.stamp[e as usize] = v as u32;
                    if boxes_meet(boxes(e as usize), (vlo, vhi)) {
                        self.near.push(e);
                    }
                }
            }
            self.near[*self.near_start.last().unwrap() as usize..].sort_unstable();
            self.near_start.push(self.near.len() as u32);
        }
    }

    /// A size of the element of vertex `v` (m): the depth within which a vertex that starts
    /// inside another body counts as touching it.
    fn size(&self, v: usize) -> f64 {
        let vx = &self.vertices[v];
        vx.edges
            .iter()
            .filter(|&&e| e != NONE)
            .map(|&e| self.edges[e as usize].length)
            .fold(0.0, f64::max)
    }

    /// A new contact of vertex `v` with edge `e`: its tributary length and the springs of the
    /// interface law `law`.
    fn record(&self, law: &dyn InterfaceLaw, v: u32, e: u32, lambda: f64) -> Record {
        let target = &self.edges[e as usize];
        let [b1, b2] = target.ends.map(|i| self.points[i as usize]);
        let (_, n_target, _) = frame(b1, b2);
        // Half of each of the vertex's edges that faces the target (outward normals within 60°
        // of opposed: a threshold well away from the side faces of a flat landing, where
        // `n · n_target` is 0 and round-off would pick one corner's side and not the other's);
        // all of them when none does.
        let faces = |k: u32| {
            let [a, b] = self.edges[k as usize].ends.map(|i| self.points[i as usize]);
            frame(a, b).1.dot(&n_target) <= -0.5
        };
        let mine = self.vertices[v as usize]
            .edges
            .map(|k| (k != NONE).then_some(k))
            .into_iter()
            .flatten();
        let any_facing = mine.clone().any(faces);
        let (mut ell, mut compliance) = (0.0, [0.0; 2]);
        for k in mine.filter(|&k| !any_facing || faces(k)) {
            let ed = &self.edges[k as usize];
            ell += 0.5 * ed.length;
            for c in 0..2 {
                compliance[c] += 0.5 * ed.length * ed.compliance[c];
            }
        }
        let k =
            law.springs([0, 1].map(|c| self.factor / (compliance[c] / ell + target.compliance[c])));
        Record {
            vertex: v,
            edge: e,
            lambda,
            ell,
            k,
            gap: [0.0; 2],
        }
    }

    /// Index of the live contact of vertex `v` with edge `e`.
    fn find(&self, v: u32, e: u32) -> Option<usize> {
        self.records
            .binary_search_by_key(&(v, e), |r| (r.vertex, r.edge))
            .ok()
    }

    /// Eq. 17 for every contact; releases those whose gap opened or that left their edge, and
    /// slides the crossing point of those beyond the Coulomb limit.
    fn update_gaps(&mut self) {
        let (points, edges) = (&self.points, &self.edges);
        let mu = self.settings.friction;
        self.records.retain_mut(|r| {
            let [b1, b2] = edges[r.edge as usize].ends.map(|i| points[i as usize]);
            let m = points[r.vertex as usize];
            let g = gap(m, b1, b2, r.lambda);
            if g.normal <= 0.0 || !(0.0..=1.0).contains(&g.along) {
                return false;
            }
            let mut slip = g.tangential;
            if let Some(mu) = mu {
                let limit = mu * r.k[0] * g.normal / r.k[1];
                if slip.abs() > limit {
                    let kept = limit.copysign(slip);
                    r.lambda += (slip - kept) / (b2 - b1).norm();
                    slip = kept;
                }
            }
            r.gap = [g.normal, slip];
            true
        });
    }

    /// DEM point contact: at each contact vertex `F = t ℓ (k_n δ_n n − k_s δ_s s)`; returns the
    /// stored energy `½ t ℓ (k_n δ_n² + k_s δ_s²)` summed.
    fn point_forces(&mut self, u: &[f64]) -> f64 {
        let mut energy = 0.0;
        self.ground = Vec2::zeros();
        for r in &mut self.records {
            let target = &self.edges[r.edge as usize];
            let [b1, b2] = target.ends.map(|i| self.points[i as usize]);
            let (s, n, _) = frame(b1, b2);
            let [dn, ds] = r.gap;
            let scale = self.thickness * r.ell;
            let force = scale * (r.k[0] * dn * n - r.k[1] * ds * s);
            let x = self.points[r.vertex as usize];
            self.frames.push(
                u,
                &mut self.ledger,
                self.vertices[r.vertex as usize].element,
                x,
                force,
            );
            if target.element != GROUND {
                self.frames
                    .push(u, &mut self.ledger, target.element, x, -force);
            } else {
                self.ground += force;
            }
            energy += 0.5 * scale * (r.k[0] * dn * dn + r.k[1] * ds * ds);
        }
        energy
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
            Formulation::Rigid => rigid,
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
        if self.formulation == Formulation::Rigid {
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

/// The point with the same coordinates in the frame of the edge `b1 → b2` as `p` has in the
/// frame of `a1 → a2` (the same edge one step earlier).
fn relative_start(p: Vec2, a1: Vec2, a2: Vec2, b1: Vec2, b2: Vec2) -> Vec2 {
    if a1 == b1 && a2 == b2 {
        return p;
    }
    let (s0, n0, _) = frame(a1, a2);
    let (s1, n1, _) = frame(b1, b2);
    let d = p - a1;
    b1 + d.dot(&s0) * s1 + d.dot(&n0) * n1
}

/// A vertex that starts inside an edge, within `tol` of it and within its span: a contact from
/// the start (crossing point: its projection), e.g. a block placed at rest on the ground.
fn start_inside(m: Vec2, b1: Vec2, b2: Vec2, tol: f64) -> Option<(f64, f64)> {
    let (s, n, l) = frame(b1, b2);
    let depth = -(m - b1).dot(&n);
    let along = (m - b1).dot(&s) / l;
    (depth > 0.0 && depth <= 0.05 * tol && (0.0..=1.0).contains(&along)).then_some((depth, along))
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
    for edge in contact.edges.iter().filter(|e| e.element != GROUND) {
        let e = edge.element as usize;
        let [k, _] = model
            .law
            .springs(edge.compliance.map(|c| contact.factor / c));
        match contact.settings.model {
            ContactModel::EdgeToEdge => {
                let [a, b] = edge.ends.map(|v| contact.vertices[v as usize].offset);
                for g in [-1.0, 1.0] {
                    let xi = 0.5 * (1.0 + g / 3f64.sqrt());
                    add(e, a + xi * (b - a), t * k * 0.5 * edge.length);
                }
            }
            // Half of each edge at each of its ends; a vertex's springs are then at most the
            // stiffest of its edges' (the record averages them).
            ContactModel::Point => {
                for v in edge.ends {
                    add(
                        e,
                        contact.vertices[v as usize].offset,
                        t * k * 0.5 * edge.length,
                    );
                }
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

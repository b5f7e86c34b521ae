//! Point contact (classic DEM): a spring at each boundary vertex that entered an edge of
//! another body or a ground segment. Each step:
//! 1. the boundary vertices are placed with the finite rotation of their element
//!    (`x = x_e + u_e + R(θ_e)(d + E_e d)`, `E_e d` the strain part of a hybrid element);
//! 2. a neighbour list (from a bucket grid of the edges, rebuilt only when a vertex has moved
//!    half its skin) holds the edges near each vertex, and eqs. 18–19 find the paths `p → m`
//!    over the step that enter an edge of another body; the crossing point `c` (eq. 20) is kept
//!    with the contact as a fraction of the target edge, so it moves with it;
//! 3. each contact's gap `δ_n`, `δ_s` (eq. 17) is measured; the contact is released when the
//!    gap opens (`δ_n ≤ 0`) or the vertex leaves the edge's span; with a Coulomb limit `μ` the
//!    crossing point slides so that `k_s |δ_s| ≤ μ k_n δ_n`;
//! 4. one spring `k ℓ_trib` acts at each contact vertex.

use super::boundary::{Boundary, Edge, Vertex};
use super::{entry, frame, gap, same, ContactStats, Frames, Ledger, Step, NONE};
use crate::mesh::buckets::{boxes_meet, moved_beyond, BucketLists, Buckets};
use crate::mesh::geometry::Vec2;
use crate::model::GROUND;

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

/// The state of point contact: the boundary's vertices and edges, where they are, the live
/// contacts and the neighbour list.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct PointContact {
    vertices: Vec<Vertex>,
    edges: Vec<Edge>,
    /// Current points: the vertices' positions, then the ground points (fixed).
    points: Vec<Vec2>,
    /// The vertices' positions at the previous step.
    previous: Vec<Vec2>,
    /// Live contacts, sorted by `(vertex, edge)`.
    pub records: Vec<Record>,
    /// Contacts found this step.
    fresh: Vec<Record>,
    buckets: BucketLists,
    /// The neighbour list: the edges near vertex `v` are `near[near_start[v]..near_start[v + 1]]`.
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
    /// The force of the ground on the bodies at the last evaluation (N).
    pub ground: Vec2,
}

impl PointContact {
    /// Point contact over `boundary`, in its reference configuration; `skin` (m): the
    /// neighbour list is rebuilt when a vertex has moved half of it.
    pub fn new(boundary: Boundary, skin: f64) -> PointContact {
        let Boundary {
            vertices,
            edges,
            points,
        } = boundary;
        let nv = vertices.len();
        PointContact {
            previous: points[..nv].to_vec(),
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
            ground: Vec2::zeros(),
        }
    }

    /// Room for two contacts per vertex and for the neighbour list, so that the steps do not
    /// allocate (`Contact::copy` makes it, for a run).
    pub fn reserve(&mut self) {
        let (nv, ne) = (self.vertices.len(), self.edges.len());
        self.records.reserve_exact(2 * nv);
        self.fresh.reserve_exact(2 * nv);
        self.buckets.reserve(ne);
        self.near_start.reserve_exact(nv + 1);
        self.near.reserve_exact(4 * nv);
    }

    /// Whether `saved`, read from a checkpoint, belongs to the model of `self` (in its initial
    /// state): the same vertices, edges and ground points, and every index it holds (contacts,
    /// neighbour list) within them.
    pub fn check_saved(&self, saved: &PointContact) -> std::result::Result<(), String> {
        let (nv, ne) = (self.vertices.len(), self.edges.len());
        if !same(&self.vertices, &saved.vertices)
            || !same(&self.edges, &saved.edges)
            || saved.points.len() != self.points.len()
            || !same(&self.points[nv..], &saved.points[nv..])
        {
            return Err("its contact vertices and edges are not this model's".into());
        }
        let lengths = [
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
        Ok(())
    }

    /// The contact forces of the step's state into `ledger`; returns the energy stored in the
    /// contact springs (J). `stats` counts the narrow-phase tests (vertex path against edge)
    /// and the rebuilds of the neighbour list.
    pub fn forces(&mut self, at: &Step, ledger: &mut Ledger, stats: &mut ContactStats) -> f64 {
        self.place(at.frames, at.u);
        self.detect(at, stats);
        self.update_gaps(at.friction);
        let energy = self.point_forces(at, ledger);
        let n = self.vertices.len();
        self.previous.copy_from_slice(&self.points[..n]);
        energy
    }

    /// Current positions of the boundary vertices (finite rotation of each element).
    fn place(&mut self, frames: &Frames, u: &[f64]) {
        for (x, v) in self.points.iter_mut().zip(&self.vertices) {
            *x = frames.place(u, v.element as usize, v.offset);
        }
    }

    /// New contacts: vertex paths that entered an edge of another body this step (eqs. 18–20);
    /// at the first step, vertices that start just inside an edge.
    fn detect(&mut self, at: &Step, stats: &mut ContactStats) {
        let n = self.vertices.len();
        if moved_beyond(&self.points[..n], &self.anchors, 0.5 * self.skin) {
            self.rebuild_near();
            stats.rebuilds += 1;
        }
        self.fresh.clear();
        for v in 0..n {
            let (p, m) = (self.previous[v], self.points[v]);
            let mut best: Option<(f64, u32, f64)> = None;
            for &e in &self.near[self.near_start[v] as usize..self.near_start[v + 1] as usize] {
                let edge = &self.edges[e as usize];
                stats.tests += 1;
                let [b1, b2] = edge.ends.map(|i| self.points[i as usize]);
                let found = if !at.first {
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
                    let r = self.record(at, v as u32, e, lambda);
                    self.fresh.push(r);
                }
            }
        }
        if !self.fresh.is_empty() {
            self.records.extend_from_slice(&self.fresh);
            self.records.sort_unstable_by_key(|r| (r.vertex, r.edge));
        }
    }

    /// The neighbour list: for each vertex, the edges of other bodies (and the ground segments)
    /// whose boxes, widened by the skin, reach its own widened box. It holds every edge that
    /// the vertex's path can cross until some vertex has moved half the skin.
    fn rebuild_near(&mut self) {
        let n = self.vertices.len();
        self.anchors.copy_from_slice(&self.points[..n]);
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
    /// step's interface law.
    fn record(&self, at: &Step, v: u32, e: u32, lambda: f64) -> Record {
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
        let k = at
            .law
            .springs([0, 1].map(|c| at.factor / (compliance[c] / ell + target.compliance[c])));
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
    /// slides the crossing point of those beyond the Coulomb limit `mu`.
    fn update_gaps(&mut self, mu: Option<f64>) {
        let (points, edges) = (&self.points, &self.edges);
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

    /// At each contact vertex `F = t ℓ (k_n δ_n n − k_s δ_s s)`; returns the stored energy
    /// `½ t ℓ (k_n δ_n² + k_s δ_s²)` summed.
    fn point_forces(&mut self, at: &Step, ledger: &mut Ledger) -> f64 {
        let mut energy = 0.0;
        self.ground = Vec2::zeros();
        for r in &mut self.records {
            let target = &self.edges[r.edge as usize];
            let [b1, b2] = target.ends.map(|i| self.points[i as usize]);
            let (s, n, _) = frame(b1, b2);
            let [dn, ds] = r.gap;
            let scale = at.thickness * r.ell;
            let force = scale * (r.k[0] * dn * n - r.k[1] * ds * s);
            let x = self.points[r.vertex as usize];
            let element = self.vertices[r.vertex as usize].element;
            at.frames.push(at.u, ledger, element, x, force);
            if target.element != GROUND {
                at.frames.push(at.u, ledger, target.element, x, -force);
            } else {
                self.ground += force;
            }
            energy += 0.5 * scale * (r.k[0] * dn * dn + r.k[1] * ds * ds);
        }
        energy
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

//! Edge-to-edge contact (§3.2 of the paper) as a temporary interface over the overlap: every
//! boundary edge of a body against every element of another body (and every ground strip) that
//! it enters, with the normal traction `k_n δ_n` and a tangential traction per unit length.
//!
//! The normal part derives from one potential, so it conserves energy. Inside a target element
//! a point's penetration is its distance to the element's surface, measured to the face that
//! minimises `√k_n · δ_n` over the faces on the body's boundary (a weighted nearest-face
//! partition of the element; faces shared with other elements of the same body only bound
//! it). The energy density `½ k_n δ_n²` is then continuous: zero where a source edge leaves
//! the target, equal on both sides of a partition line. Each piece of a source edge that
//! lies in one face's part is linear in `δ_n`, so 2-point Gauss on the clipped piece is exact
//! for force and moment, and the pieces' end terms cancel: the forces are the exact gradient.
//! A ground segment is the strip below it, closed at a free end by a wall perpendicular to it
//! (so a body sliding past the end is let go smoothly) and at a joint with the next segment by
//! the bisector of the two, which hands a body over from one segment to the next.
//!
//! Measuring the depth to the face that a vertex path crossed (eqs. 18–19), as before, made
//! every edge next to a contact vertex an interface with that face over its whole length: a
//! brick whose corner entered a neighbour's face beside that neighbour's corner had its side
//! edge pushed as if 10 mm deep (paper_notes C10).
//!
//! A body whose interfaces can fail (`Model::fragments`) is one contact body until one of its
//! interfaces is released; from then on its elements touch each other: an edge between two
//! elements is a source once its interface is released, it enters any element of the body but
//! the two of an interface that still holds, and other bodies see a face between two elements
//! only once its interface is released.
//!
//! Between two bodies both take the role of the source, each with half the spring, so that two
//! flat faces pressed together carry `k_n` of eq. 12 once, whichever body comes first.
//!
//! The tangential traction of a piece is `−k_s s δ_n(ξ)/δ̄_n`, `s` its slip (the relative
//! tangential displacement at the piece's centre of pressure, summed over the steps since it
//! formed) and `δ̄_n` its mean depth: it follows the penetration profile, and the Coulomb
//! limit `k_s |s| ≤ μ k_n δ̄_n` (a return mapping on `s`) holds at every point of the piece.
//! Its springs store `½ k_s s² Σ w (δ_n/δ̄_n)²`; where the piece alone would raise that (it
//! grows, or its profile steepens, at a given slip), `s` is scaled to keep it: the springs are
//! not derived from a potential, and a sticking corner rolling onto its face otherwise handed
//! the motion energy nobody put in.

use super::{frame, same, ContactStats, Frames, Ledger, Step, NONE};
use crate::mesh::buckets::{boxes_meet, moved_beyond, BucketLists, Buckets};
use crate::mesh::geometry::Vec2;
use crate::model::{Model, GROUND};
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};

/// A region that boundary edges can enter: an element with an edge on its body's boundary (a
/// convex polygon; in a body that fragments, every element) or the strip below a ground segment.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
struct Target {
    /// The element, or [`GROUND`].
    element: u32,
    /// The model's body, or [`NONE`] for the ground.
    body: u32,
    /// Its corners are `corners[first..first + count]`, counter-clockwise; face `k` runs from
    /// corner `k` to corner `k + 1`, and is `faces[first + k]`.
    first: u32,
    count: u32,
}

/// A face of a target.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
struct Face {
    /// Compliances `h / E_n`, `h / E_s` of its side (zero for the ground).
    compliance: [f64; 2],
    /// Whether it is a surface (on the body's boundary, a ground segment or a free end of one,
    /// any face of an element of a body that fragments) or only bounds the target (shared with
    /// another element, a joint between segments). The surfaces partition the target by depth.
    surface: bool,
    /// In a body that fragments, the interface of a face shared with another element, else
    /// [`NONE`]: against other bodies such a face only bounds the target until its interface
    /// is released (it is then *exposed*), as a face shared in a body that does not fragment
    /// does; against the other elements of its body (those not bonded to its element) it is
    /// a surface.
    interface: u32,
}

/// A boundary edge of a body as the source of contact: its end points are two corners of its
/// element's target.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
struct Source {
    element: u32,
    /// The model's body.
    body: u32,
    ends: [u32; 2],
    compliance: [f64; 2],
    /// In a body that fragments, the interface of an edge shared with another element, else
    /// [`NONE`]: such an edge is a source only once its interface is released.
    interface: u32,
}

/// A piece of a source edge inside one face's part of a target, live this step.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
struct Piece {
    source: u32,
    face: u32,
    /// Tangential slip `s` (m).
    slip: f64,
    /// `Σ w (δ_n/δ̄_n)²` over its Gauss points (m²): the springs' stored tangential energy is
    /// `½ k_s s²` times it.
    #[serde(default)]
    spread: f64,
}

/// The state of edge-to-edge contact: targets, the neighbour list and the slips of the pieces.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub(super) struct Overlap {
    targets: Vec<Target>,
    faces: Vec<Face>,
    /// Reference offsets of the corners from their element's centroid; ground corners absolute.
    offsets: Vec<Vec2>,
    /// Current corners.
    corners: Vec<Vec2>,
    /// Current face lines: a point, the unit tangent and the outward normal.
    lines: Vec<(Vec2, Vec2, Vec2)>,
    /// Corners at the last rebuild of the neighbour list.
    anchors: Vec<Vec2>,
    /// Per target, its farthest corner from the centroid (m) and its element's `(u, v, θ)` at
    /// the last rebuild (rigid formulation).
    reach: Vec<(f64, [f64; 3])>,
    /// Whether the formulation is rigid (the idle test bounds rigid motion only).
    rigid: bool,
    sources: Vec<Source>,
    /// Pairs `(source, target)` whose boxes, widened by the skin, overlapped at the last
    /// rebuild; sorted.
    candidates: Vec<(u32, u32)>,
    /// The neighbour list is rebuilt when a corner has moved more than half of this (m).
    skin: f64,
    /// The force of the ground on the bodies at the last evaluation (N).
    pub ground: Vec2,
    buckets: BucketLists,
    /// Live pieces, sorted by `(source, face)`, and those of this step being found.
    pieces: Vec<Piece>,
    next: Vec<Piece>,
    /// The narrow phase's work, block by block (kept: no allocation in the step).
    #[serde(skip)]
    blocks: Vec<Block>,
    /// No evaluation yet: no step to measure slips over, and the neighbour list to build.
    fresh: bool,
    /// The fragments changed: the neighbour list must be rebuilt.
    stale: bool,
    /// Per body of the model, whether it fragments (`Model::fragments`) and whether one of
    /// its interfaces has been released: until then it is one contact body, as a body that
    /// does not fragment is, and its elements are not tested against each other at all.
    fragments: Vec<bool>,
    cracked: Vec<bool>,
    /// Per body of the model, its first interface (ascending): the body of an interface.
    first_interface: Vec<u32>,
    /// In the bodies that fragment, the elements that share an edge with each element, sorted,
    /// with the interface of that edge: `neighbours[neighbour_start[e]..neighbour_start[e + 1]]`.
    neighbour_start: Vec<u32>,
    neighbours: Vec<(u32, u32)>,
    /// Per interface of the model, whether it is released (bodies that fragment only).
    released: Vec<bool>,
    /// Per target, whether a face of it is exposed to other bodies now (at the last rebuild).
    open: Vec<bool>,
}

/// Candidates per block of the narrow phase (a rayon task).
const BLOCK: usize = 1024;

/// What a block of candidates gives: generalised forces on elements, live pieces, the ground's
/// force and the stored energy.
#[derive(Debug, Clone, Default)]
struct Block {
    faces: Vec<FaceNow>,
    /// Where the last step's pieces reach this block's keys.
    cursor: usize,
    forces: Vec<(u32, [f64; 6])>,
    /// The forces of pieces born across a released interface (`Overlap::piece`), again.
    born: Vec<(u32, [f64; 6])>,
    /// The force on the source element of the last pieces, still open to the next ones.
    pending: Option<(u32, [f64; 6])>,
    pieces: Vec<Piece>,
    ground: Vec2,
    energy: f64,
}

/// `a += b`.
fn add(a: &mut [f64; 6], b: &[f64; 6]) {
    for (a, b) in a.iter_mut().zip(b) {
        *a += b;
    }
}

impl Block {
    /// Adds `q` to the force on source element `element`, kept open while the pieces of that
    /// element follow one another (they do: the candidates run in source order).
    fn add_source(&mut self, element: u32, q: &[f64; 6]) {
        match &mut self.pending {
            Some((e, open)) if *e == element => add(open, q),
            pending => {
                if let Some(done) = pending.replace((element, *q)) {
                    self.forces.push(done);
                }
            }
        }
    }

    /// Closes the open source force at the end of the block.
    fn finish(&mut self) {
        if let Some(done) = self.pending.take() {
            self.forces.push(done);
        }
    }

    /// Empties the block for `candidates` candidates, with room for two pieces each (a source
    /// edge rarely lies in more than two faces' parts of one target) and their forces.
    fn clear(&mut self, candidates: usize) {
        self.forces.clear();
        self.born.clear();
        self.pieces.clear();
        self.forces.reserve(8 * candidates);
        self.pieces.reserve(2 * candidates);
        self.ground = Vec2::zeros();
        self.energy = 0.0;
    }
}

/// A piece of a source edge in one face's part of a target: the face, its springs, the depth
/// below it at both ends of the source edge and its axes `(s, n)`, the source edge's ends, the
/// piece's range of the edge parameter `ξ` and the edge's length.
#[derive(Debug, Clone, Copy)]
struct Span {
    face: usize,
    k: [f64; 2],
    depth: [f64; 2],
    axes: (Vec2, Vec2),
    ends: [Vec2; 2],
    range: (f64, f64),
    length: f64,
}

/// A face of the target at hand, in the current configuration.
#[derive(Debug, Clone, Copy, Default)]
struct FaceNow {
    /// Depth below its line at both ends of the source edge (linear along it).
    depth: [f64; 2],
    /// Its unit tangent and outward normal.
    axes: (Vec2, Vec2),
    /// Normal and tangential springs against the source edge (Pa/m), and the square root of
    /// the normal one (surface faces).
    spring: [f64; 2],
    root: f64,
    surface: bool,
}

impl Overlap {
    /// The edge-to-edge contact of `model`, in its reference configuration: its bodies'
    /// targets and sources ([`Shapes::body`]) and the ground's strips ([`Shapes::ground`]).
    /// `skin` (m): the neighbour list is rebuilt when a corner has moved half of it.
    pub fn new(model: &Model, skin: f64) -> Overlap {
        let mut shapes = Shapes::default();
        for bi in 0..model.bodies.len() {
            shapes.body(model, bi);
        }
        shapes.ground(&model.ground);
        let Shapes {
            targets,
            faces,
            offsets,
            sources,
        } = shapes;
        let (neighbour_start, neighbours) = neighbours(model);
        let corners = offsets.clone();
        let lines = vec![(Vec2::zeros(), Vec2::zeros(), Vec2::zeros()); corners.len()];
        let reach = targets
            .iter()
            .map(|t| {
                let r = offsets[t.first as usize..(t.first + t.count) as usize]
                    .iter()
                    .map(|d| d.norm())
                    .fold(0.0, f64::max);
                (r, [0.0; 3])
            })
            .collect();
        let mut overlap = Overlap {
            anchors: vec![Vec2::repeat(f64::INFINITY); corners.len()],
            corners,
            lines,
            reach,
            rigid: model.formulation.ndof() == 3,
            offsets,
            faces,
            buckets: BucketLists::default(),
            targets,
            sources,
            candidates: Vec::new(),
            skin,
            ground: Vec2::zeros(),
            blocks: Vec::new(),
            pieces: Vec::new(),
            next: Vec::new(),
            fresh: true,
            stale: false,
            fragments: (0..model.bodies.len())
                .map(|b| model.fragments(b))
                .collect(),
            cracked: vec![false; model.bodies.len()],
            first_interface: model
                .bodies
                .iter()
                .map(|b| b.first_interface as u32)
                .collect(),
            released: if neighbours.is_empty() {
                Vec::new()
            } else {
                vec![false; model.interfaces.len()]
            },
            neighbour_start,
            neighbours,
            open: Vec::new(),
        };
        overlap.place_lines(true);
        overlap
    }

    /// Room for the candidates and pieces of every source edge, so that the steps do not
    /// allocate (`Contact::copy` makes it, for a run).
    pub(super) fn reserve(&mut self) {
        let n = self.sources.len();
        self.buckets.reserve(self.targets.len());
        self.candidates.reserve_exact(8 * n);
        self.open.reserve_exact(self.targets.len());
        self.pieces.reserve_exact(4 * n);
        self.next.reserve_exact(4 * n);
    }

    /// The contact forces of the step's state into `ledger` (the step's velocity, with which
    /// the step that led here moved the bodies, is not used at the first evaluation). Returns
    /// the energy stored in the contact springs (J). `stats` counts the narrow-phase tests
    /// (source edge against target) and the rebuilds of the neighbour list.
    pub fn forces(&mut self, at: &Step, ledger: &mut Ledger, stats: &mut ContactStats) -> f64 {
        let (frames, u) = (at.frames, at.u);
        self.place(frames, u);
        if self.stale || moved_beyond(&self.corners, &self.anchors, 0.5 * self.skin) {
            self.rebuild(u);
            stats.rebuilds += 1;
            self.stale = false;
        }
        if self.candidates.is_empty() {
            self.pieces.clear();
            self.ground = Vec2::zeros();
            self.fresh = false;
            return 0.0;
        }
        self.place_lines(false);
        // The narrow phase in blocks of candidates, in parallel; the blocks' forces, pieces and
        // energies then join in block order, so the sums do not depend on the thread count.
        let n = self.candidates.len().div_ceil(BLOCK);
        if self.blocks.len() < n {
            self.blocks.resize_with(n, Block::default);
        }
        let mut blocks = std::mem::take(&mut self.blocks);
        let this = &*self;
        let work = |(block, chunk): (&mut Block, &[(u32, u32)])| {
            block.clear(chunk.len());
            block.cursor = this.pieces.partition_point(|p| p.source < chunk[0].0);
            for &(source, target) in chunk {
                this.pair(at, block, source, target);
            }
            block.finish();
        };
        if n > 1 {
            blocks[..n]
                .par_iter_mut()
                .zip(self.candidates.par_chunks(BLOCK))
                .for_each(work);
        } else {
            blocks[..n]
                .iter_mut()
                .zip(self.candidates.chunks(BLOCK))
                .for_each(work);
        }
        self.next.clear();
        self.ground = Vec2::zeros();
        let mut energy = 0.0;
        let nd = frames.formulation.ndof();
        for block in &blocks[..n] {
            for (e, q) in &block.forces {
                ledger.add(*e as usize, &q[..nd]);
            }
            for (e, q) in &block.born {
                ledger.unworked(*e as usize, &q[..nd]);
            }
            self.next.extend_from_slice(&block.pieces);
            self.ground += block.ground;
            energy += block.energy;
        }
        self.blocks = blocks;
        stats.tests += self.candidates.len() as u64;
        std::mem::swap(&mut self.pieces, &mut self.next);
        self.fresh = false;
        energy
    }

    /// Interfaces handed over to contact: `released[k]` tells whether interface
    /// `interfaces[k]` (an index in `Model::interfaces`) is; the two elements of a released
    /// interface touch from now on, through the faces of that interface. Nothing to do when no
    /// body fragments. The neighbour list is rebuilt at the next evaluation.
    pub fn release(&mut self, interfaces: &[u32], released: &[bool]) {
        if self.released.is_empty() {
            return;
        }
        for (&i, &r) in interfaces.iter().zip(released) {
            self.released[i as usize] = r;
            if r {
                let body = self.first_interface.partition_point(|&f| f <= i) - 1;
                self.cracked[body] = true;
            }
        }
        self.stale = true;
    }

    /// Whether a source edge or a face with this interface carries contact now: it has none (a
    /// boundary, the ground) or it is released.
    fn exposed(&self, interface: u32) -> bool {
        interface == NONE || self.released[interface as usize]
    }

    /// Whether source `s` and target `t` may not touch: the same element, the same body unless
    /// it fragments and has a released interface, or two elements still bonded by their
    /// interface (the interface keeps them apart; elements that share a corner, or whose
    /// interface is released, do touch).
    fn apart(&self, s: &Source, t: &Target) -> bool {
        if t.element == s.element {
            return true;
        }
        if t.body != s.body {
            return false;
        }
        let body = s.body as usize;
        if !(self.fragments[body] && self.cracked[body]) {
            return true;
        }
        let e = s.element as usize;
        let range = self.neighbour_start[e] as usize..self.neighbour_start[e + 1] as usize;
        let near = &self.neighbours[range];
        match near.binary_search_by_key(&t.element, |n| n.0) {
            Ok(k) => !self.released[near[k].1 as usize],
            Err(_) => false,
        }
    }

    /// Whether `saved`, read from a checkpoint, belongs to the model of `self` (in its
    /// initial state): the same targets, faces and sources, and every index it holds in range.
    pub(super) fn check_saved(&self, saved: &Overlap) -> std::result::Result<(), String> {
        if !same(&self.targets, &saved.targets)
            || !same(&self.faces, &saved.faces)
            || !same(&self.sources, &saved.sources)
            || !same(&self.offsets, &saved.offsets)
            || !same(&self.neighbours, &saved.neighbours)
            || !same(&self.neighbour_start, &saved.neighbour_start)
            || self.fragments != saved.fragments
            || self.first_interface != saved.first_interface
        {
            return Err("its contact targets and sources are not this model's".into());
        }
        let (ns, nt, nf) = (self.sources.len(), self.targets.len(), self.faces.len());
        let lengths = [
            (saved.corners.len(), self.corners.len()),
            (saved.lines.len(), self.lines.len()),
            (saved.anchors.len(), self.anchors.len()),
            (saved.reach.len(), self.reach.len()),
            (saved.released.len(), self.released.len()),
            (saved.cracked.len(), self.cracked.len()),
        ];
        if lengths.iter().any(|(a, b)| a != b)
            || saved.open.len() > nt
            || saved
                .candidates
                .iter()
                .any(|&(s, t)| s as usize >= ns || t as usize >= nt)
            || saved
                .pieces
                .iter()
                .chain(&saved.next)
                .any(|p| p.source as usize >= ns || p.face as usize >= nf)
        {
            return Err("its contact pieces or neighbour list are out of range".into());
        }
        Ok(())
    }

    /// The number of live pieces.
    pub fn len(&self) -> usize {
        self.pieces.len()
    }

    /// Whether this step has nothing to do: no candidates, and no rigid target can have moved
    /// half the skin since the last rebuild (`|Δu| + r |Δθ|`, `r` its farthest corner), so
    /// that not even the corners need placing (a body in flight).
    pub fn idle(&self, u: &[f64]) -> bool {
        if !self.candidates.is_empty() || self.fresh || self.stale || !self.rigid {
            return false;
        }
        let limit = 0.5 * self.skin;
        self.targets.iter().zip(&self.reach).all(|(t, &(r, a))| {
            let e = t.element as usize;
            t.element == GROUND || {
                let (du, dv, dth) = (u[3 * e] - a[0], u[3 * e + 1] - a[1], u[3 * e + 2] - a[2]);
                (du * du + dv * dv).sqrt() + r * dth.abs() <= limit
            }
        })
    }

    /// Current corners of every body target (the ground's are fixed).
    fn place(&mut self, frames: &Frames, u: &[f64]) {
        for t in self.targets.iter().filter(|t| t.element != GROUND) {
            let r = t.first as usize..(t.first + t.count) as usize;
            frames.place_all(
                u,
                t.element as usize,
                &self.offsets[r.clone()],
                &mut self.corners[r],
            );
        }
    }

    /// Current face lines of the body targets, or with `ground`, of the ground's (fixed).
    fn place_lines(&mut self, ground: bool) {
        for t in self
            .targets
            .iter()
            .filter(|t| (t.element == GROUND) == ground)
        {
            let r = t.first as usize..(t.first + t.count) as usize;
            let (corners, m) = (&self.corners[r.clone()], t.count as usize);
            for (k, line) in self.lines[r].iter_mut().enumerate() {
                let (a, b) = (corners[k], corners[(k + 1) % m]);
                let (s, n, _) = frame(a, b);
                *line = (a, s, n);
            }
        }
    }

    /// The neighbour list: every source edge against every target of another body whose box,
    /// widened by the skin, its own widened box overlaps.
    fn rebuild(&mut self, u: &[f64]) {
        self.anchors.copy_from_slice(&self.corners);
        if self.rigid {
            for (t, reach) in self
                .targets
                .iter()
                .zip(&mut self.reach)
                .filter(|(t, _)| t.element != GROUND)
            {
                let e = t.element as usize;
                reach.1 = [u[3 * e], u[3 * e + 1], u[3 * e + 2]];
            }
        }
        let widen = Vec2::repeat(self.skin);
        let boxes = |t: &Target| {
            let c = &self.corners[t.first as usize..(t.first + t.count) as usize];
            let (lo, hi) = c
                .iter()
                .fold((c[0], c[0]), |(lo, hi), x| (lo.inf(x), hi.sup(x)));
            (lo - widen, hi + widen)
        };
        // The grid spans the bodies; the ground strips, deep below their segments, are filed
        // under the buckets they reach.
        let (mut lo, mut hi) = (Vec2::repeat(f64::INFINITY), Vec2::repeat(f64::NEG_INFINITY));
        for t in self.targets.iter().filter(|t| t.element != GROUND) {
            let (a, b) = boxes(t);
            lo = lo.inf(&a);
            hi = hi.sup(&b);
        }
        let grid = Buckets::new(lo, hi, self.targets.len());
        let targets = &self.targets;
        self.buckets
            .fill(&grid, targets.len(), |k| boxes(&targets[k]));
        // A target none of whose faces is exposed is entered by no source of another body.
        self.open.clear();
        for t in &self.targets {
            let faces = &self.faces[t.first as usize..(t.first + t.count) as usize];
            let open = faces.iter().any(|f| f.surface && self.exposed(f.interface));
            self.open.push(open);
        }
        self.candidates.clear();
        for (si, s) in self.sources.iter().enumerate() {
            if !self.exposed(s.interface) {
                continue;
            }
            let [a, b] = s.ends.map(|i| self.corners[i as usize]);
            let (slo, shi) = (a.inf(&b) - widen, a.sup(&b) + widen);
            for k in grid.touching(slo, shi) {
                for &t in self.buckets.bucket(k) {
                    let target = &self.targets[t as usize];
                    if (target.body != s.body && !self.open[t as usize]) || self.apart(s, target) {
                        continue;
                    }
                    if boxes_meet(boxes(target), (slo, shi)) {
                        self.candidates.push((si as u32, t));
                    }
                }
            }
        }
        // A target filed under several buckets is found once per bucket.
        self.candidates.sort_unstable();
        self.candidates.dedup();
    }

    /// The pieces of source edge `si` inside target `ti`: their forces, pieces and stored
    /// energy into `block`.
    fn pair(&self, at: &Step, block: &mut Block, si: u32, ti: u32) {
        let src = self.sources[si as usize];
        let tgt = self.targets[ti as usize];
        let [q1, q2] = src.ends.map(|i| self.corners[i as usize]);
        // Every field that `pieces_of` reads it writes first: the room is only grown.
        let mut now = std::mem::take(&mut block.faces);
        if now.len() < tgt.count as usize {
            now.resize(tgt.count as usize, FaceNow::default());
        }
        self.pieces_of(
            at,
            block,
            si,
            &src,
            &tgt,
            [q1, q2],
            &mut now[..tgt.count as usize],
        );
        block.faces = now;
    }

    /// [`Overlap::pair`] with room for the target's faces in `now`.
    #[allow(clippy::too_many_arguments)]
    fn pieces_of(
        &self,
        at: &Step,
        block: &mut Block,
        si: u32,
        src: &Source,
        tgt: &Target,
        [q1, q2]: [Vec2; 2],
        now: &mut [FaceNow],
    ) {
        let m = tgt.count as usize;
        // Depth below each face line at both ends of the source edge (linear along it), and
        // the face's frame.
        for (f, &(a, s, n)) in now.iter_mut().zip(&self.lines[tgt.first as usize..]) {
            f.depth = [q1, q2].map(|q| -(q - a).dot(&n));
            f.axes = (s, n);
        }
        // Quick reject: the whole edge outside one face.
        if now.iter().any(|f| f.depth[0] <= 0.0 && f.depth[1] <= 0.0) {
            return;
        }
        // The springs of the interface law on the moduli of eq. 12 with both sides'
        // compliances, on each surface face.
        let half = if tgt.element == GROUND { 1.0 } else { 0.5 };
        // A source of another body sees a target of a body that fragments as it sees one of a
        // body that does not: its exposed faces are its surfaces, the others only bound it.
        // Within a body that fragments (two elements not bonded to each other), every face of
        // the target is a surface: an overlap is an overlap whichever face it crosses.
        let within = src.body == tgt.body;
        for (k, f) in now.iter_mut().enumerate() {
            let face = &self.faces[tgt.first as usize + k];
            f.surface = face.surface && (within || self.exposed(face.interface));
            if face.surface {
                let moduli = [0, 1].map(|c| at.factor / (src.compliance[c] + face.compliance[c]));
                f.spring = at.law.springs(moduli).map(|k| half * k);
                f.root = f.spring[0].sqrt();
            }
        }
        let length = (q2 - q1).norm();
        for i in 0..m {
            if !now[i].surface {
                continue;
            }
            let ri = now[i].root;
            let (mut a, mut b) = (0.0f64, 1.0f64);
            // Keeps where `v0 + ξ (v1 − v0) ≥ 0`; false once nothing is left. A constraint
            // that holds at both ends (or at neither) needs no division.
            let mut keep = |v: [f64; 2]| {
                if v[0] >= 0.0 && v[1] >= 0.0 {
                    return true;
                }
                if v[0] < 0.0 && v[1] < 0.0 {
                    return false;
                }
                let dv = v[1] - v[0];
                if dv > 0.0 {
                    a = a.max(-v[0] / dv);
                } else {
                    b = b.min(-v[0] / dv);
                }
                b > a
            };
            let depth_i = now[i].depth;
            let inside = keep(depth_i)
                && now.iter().enumerate().all(|(j, f)| {
                    j == i
                        || if f.surface {
                            // √k_j δ_j − √k_i δ_i ≥ 0: nearer to face i in the weighted sense.
                            keep([0, 1].map(|e| f.root * f.depth[e] - ri * depth_i[e]))
                        } else {
                            keep(f.depth)
                        }
                });
            if !inside || b <= a {
                continue;
            }
            let piece = Span {
                face: i,
                k: now[i].spring,
                depth: now[i].depth,
                axes: now[i].axes,
                ends: [q1, q2],
                range: (a, b),
                length,
            };
            self.piece(at, block, src, tgt, si, &piece);
        }
    }

    /// One piece of source edge `si` in the part of one face of `tgt`.
    fn piece(&self, at: &Step, block: &mut Block, src: &Source, tgt: &Target, si: u32, p: &Span) {
        let Span {
            face: i,
            k,
            depth,
            axes: (s, n),
            ends: [q1, q2],
            range: (a, b),
            length,
        } = *p;
        let face = tgt.first + i as u32;
        let lerp = |v: [f64; 2], xi: f64| v[0] + xi * (v[1] - v[0]);
        let half = 0.5 * (b - a);
        let w = half * length * at.thickness;
        let gauss = [-1.0, 1.0].map(|g| a + half * (1.0 + g / 3f64.sqrt()));
        let d = gauss.map(|xi| lerp(depth, xi));
        let mean = 0.5 * (d[0] + d[1]);
        // The slip: carried over from the last step, plus the relative tangential motion of
        // the step at the centre of pressure; Coulomb's limit by return mapping.
        // A block's pieces come in `(source, face)` order, as the last step's do: a cursor
        // finds the last step's piece.
        let key = (si, face);
        let last = &self.pieces[block.cursor..];
        let ahead = last.iter().take_while(|p| (p.source, p.face) < key).count();
        block.cursor += ahead;
        let last = self
            .pieces
            .get(block.cursor)
            .filter(|p| (p.source, p.face) == key);
        let mut slip = last.map_or(0.0, |p| p.slip);
        // The springs' stored energy `½ k_s s² Σ w (δ_n/δ̄_n)²` may not grow with the piece
        // alone (longer, or deeper at one end) at a given slip: the slip is scaled down to
        // keep it, so that a sticking corner that rolls onto its face gives the motion no
        // energy it did not take. A piece that shrinks loses what it stored over the part
        // that left, as a piece that vanishes does.
        let spread = if mean > 0.0 {
            w * d.iter().map(|di| (di / mean) * (di / mean)).sum::<f64>()
        } else {
            0.0
        };
        if let Some(last) = last.filter(|p| spread > p.spread && p.spread > 0.0) {
            slip *= (last.spread / spread).sqrt();
        }
        // A piece that appears across a released interface (the hand-over of a broken
        // interface whose elements still overlap) appears with its whole force: it did no work
        // over the step that led here, where the ledger's trapezoid rule would count half.
        let born = last.is_none()
            && (src.interface != NONE || self.faces[face as usize].interface != NONE);
        if mean > 0.0 && !self.fresh {
            let centre = (d[0] * gauss[0] + d[1] * gauss[1]) / (d[0] + d[1]);
            let x = q1 + centre * (q2 - q1);
            let mut step = at
                .frames
                .increment(at.u, at.velocity, at.dt, src.element as usize, x);
            if tgt.element != GROUND {
                step -= at
                    .frames
                    .increment(at.u, at.velocity, at.dt, tgt.element as usize, x);
            }
            slip += step.dot(&s);
        }
        if let Some(mu) = at.friction {
            // A depth that round-off leaves a hair below zero (bodies stacked on one another)
            // holds no friction.
            let limit = if k[1] > 0.0 {
                (mu * k[0] * mean / k[1]).max(0.0)
            } else {
                0.0
            };
            slip = slip.clamp(-limit, limit);
        }
        block.pieces.push(Piece {
            source: si,
            face,
            slip,
            spread,
        });
        let (mut on_source, mut on_target) = ([0.0; 6], [0.0; 6]);
        for (xi, di) in gauss.into_iter().zip(d) {
            let stretch = if mean > 0.0 { slip * di / mean } else { 0.0 };
            let (tn, ts) = (k[0] * di, -k[1] * stretch);
            let x = q1 + xi * (q2 - q1);
            let force = w * (tn * n + ts * s);
            add(
                &mut on_source,
                &at.frames.generalised(at.u, src.element, x, force),
            );
            if tgt.element != GROUND {
                add(
                    &mut on_target,
                    &at.frames.generalised(at.u, tgt.element, x, -force),
                );
            } else {
                block.ground += force;
            }
            block.energy += 0.5 * w * (k[0] * di * di + k[1] * stretch * stretch);
        }
        block.add_source(src.element, &on_source);
        if tgt.element != GROUND {
            block.forces.push((tgt.element, on_target));
        }
        if born {
            block.born.push((src.element, on_source));
            if tgt.element != GROUND {
                block.born.push((tgt.element, on_target));
            }
        }
    }
}

/// The targets with their faces and corners, and the sources: the geometry of edge-to-edge
/// contact in the reference configuration, as [`Overlap::new`] gathers it.
#[derive(Debug, Default)]
struct Shapes {
    targets: Vec<Target>,
    faces: Vec<Face>,
    /// The corners: offsets from their element's centroid, ground corners absolute.
    offsets: Vec<Vec2>,
    sources: Vec<Source>,
}

impl Shapes {
    /// The targets and sources of body `bi`: each element with an edge on the body's boundary
    /// is a target whose boundary faces are surfaces, and each boundary edge a source. In a
    /// body that fragments every element is a target whose faces are all surfaces, and each
    /// edge a source; an edge between two elements is a source, and its face carries
    /// tractions, only once its interface is released (`Overlap::apart`).
    fn body(&mut self, model: &Model, bi: usize) {
        let body = &model.bodies[bi];
        let mesh = &body.mesh;
        let on_boundary: HashSet<(u32, u32)> =
            mesh.boundary.iter().map(|e| (e.cell, e.v1)).collect();
        let fragments = model.fragments(bi);
        let shared: HashMap<(u32, u32), u32> = if fragments {
            mesh.shared
                .iter()
                .enumerate()
                .flat_map(|(j, e)| {
                    let i = (body.first_interface + j) as u32;
                    [((e.a, e.v1), i), ((e.b, e.v2), i)]
                })
                .collect()
        } else {
            HashMap::new()
        };
        let mut cells: Vec<u32> = if fragments {
            (0..mesh.n_cells() as u32).collect()
        } else {
            mesh.boundary.iter().map(|e| e.cell).collect()
        };
        cells.sort_unstable();
        cells.dedup();
        for c in cells {
            let element = body.first_element + c as usize;
            let centroid = model.elements[element].props.centroid;
            let cell = mesh.cell(c as usize);
            let first = self.offsets.len() as u32;
            for (k, &v) in cell.iter().enumerate() {
                let (p1, p2) = (
                    mesh.vertices[v as usize],
                    mesh.vertices[cell[(k + 1) % cell.len()] as usize],
                );
                let (_, n, _) = frame(p1, p2);
                let h = (p1 - centroid).dot(&n).abs();
                let compliance = [h / body.moduli[0], h / body.moduli[1]];
                let surface = fragments || on_boundary.contains(&(c, v));
                let interface = shared.get(&(c, v)).copied().unwrap_or(NONE);
                self.offsets.push(p1 - centroid);
                self.faces.push(Face {
                    compliance,
                    surface,
                    interface,
                });
                if surface {
                    let ends = [first + k as u32, first + ((k + 1) % cell.len()) as u32];
                    self.sources.push(Source {
                        element: element as u32,
                        body: bi as u32,
                        ends,
                        compliance,
                        interface,
                    });
                }
            }
            self.targets.push(Target {
                element: element as u32,
                body: bi as u32,
                first,
                count: cell.len() as u32,
            });
        }
    }

    /// The strip below each ground segment `[from, to]` ([`strip`]): a target of four faces,
    /// the segment, its two end walls (surfaces at a free end) and a bottom.
    fn ground(&mut self, ground: &[[Vec2; 2]]) {
        // The segments by end point, for the joints: `ends[0]` by their `to`, `ends[1]` by
        // their `from`, each point with the first two segments there in index order (one of
        // them is not the asking segment). Exact equality as before: `+ 0.0` makes −0 and 0 one
        // key, and the points are finite (validated).
        let key = |p: Vec2| ((p.x + 0.0).to_bits(), (p.y + 0.0).to_bits());
        let mut ends: [rustc_hash::FxHashMap<(u64, u64), [u32; 2]>; 2] = Default::default();
        for (j, h) in ground.iter().enumerate() {
            for (side, p) in [(0, h[1]), (1, h[0])] {
                let slot = ends[side].entry(key(p)).or_insert([NONE; 2]);
                if let Some(free) = slot.iter_mut().find(|s| **s == NONE) {
                    *free = j as u32;
                }
            }
        }
        for (gi, &[from, to]) in ground.iter().enumerate() {
            let joined = |at: Vec2, me_from: bool| {
                // A joint: this segment's `from` is another's `to` (whose `from` is returned),
                // or its `to` another's `from` (whose `to` is returned); the first such other.
                let (side, other) = if me_from { (0, 0) } else { (1, 1) };
                ends[side]
                    .get(&key(at))
                    .and_then(|s| s.iter().find(|&&j| j != NONE && j as usize != gi))
                    .map(|&j| ground[j as usize][other])
            };
            let (corners, [free_from, free_to]) =
                strip(from, to, joined(from, true), joined(to, false));
            let first = self.offsets.len() as u32;
            self.offsets.extend(corners);
            let face = |surface: bool| Face {
                compliance: [0.0; 2],
                surface,
                interface: NONE,
            };
            self.faces
                .extend([face(true), face(free_from), face(false), face(free_to)]);
            self.targets.push(Target {
                element: GROUND,
                body: NONE,
                first,
                count: 4,
            });
        }
    }
}

/// The strip below the ground segment `from → to`, stored `to → from` as a body's boundary is
/// (solid on the left), closed at each end by a wall: perpendicular at a free end, the
/// bisector with the next segment at a joint (`from_joint`, `to_joint`: the far end of the
/// segment met there). Returns its corners and whether each end wall (at `from`, at `to`) is
/// free, hence a surface.
fn strip(
    from: Vec2,
    to: Vec2,
    from_joint: Option<Vec2>,
    to_joint: Option<Vec2>,
) -> ([Vec2; 4], [bool; 2]) {
    let (_, n, length) = frame(to, from);
    let depth = 1.0e3 * length;
    let wall = |at: Vec2, other: Option<Vec2>| match other {
        // The other segment's normal at the joint: the wall bisects the two.
        Some(o) => {
            let (_, m, _) = if at == from {
                frame(from, o)
            } else {
                frame(o, to)
            };
            (-(n + m).normalize(), false)
        }
        None => (-n, true),
    };
    let (down_from, free_from) = wall(from, from_joint);
    let (down_to, free_to) = wall(to, to_joint);
    // Walls that converge (a free end beside a joint, a segment between a ridge and a valley)
    // would cross below the segment and fold the strip: it stops at half the depth where they
    // meet.
    let gap = to - from;
    let det = down_to.x * down_from.y - down_from.x * down_to.y;
    let depth = if det.abs() > 1e-12 {
        let a = (down_to.x * gap.y - gap.x * down_to.y) / det;
        let b = (down_from.x * gap.y - gap.x * down_from.y) / det;
        if a > 0.0 && b > 0.0 {
            depth.min(0.5 * a.min(b))
        } else {
            depth
        }
    } else {
        depth
    };
    let corners = [to, from, from + depth * down_from, to + depth * down_to];
    (corners, [free_from, free_to])
}

/// The edge neighbours of every element of the bodies that fragment, with the interface of
/// their edge (`Overlap::neighbours`). Empty when no body fragments.
fn neighbours(model: &Model) -> (Vec<u32>, Vec<(u32, u32)>) {
    let mut pairs: Vec<(u32, u32, u32)> = Vec::new();
    for (bi, body) in model.bodies.iter().enumerate() {
        if !model.fragments(bi) {
            continue;
        }
        let element = |c: u32| (body.first_element + c as usize) as u32;
        for (j, e) in body.mesh.shared.iter().enumerate() {
            let i = (body.first_interface + j) as u32;
            pairs.push((element(e.a), element(e.b), i));
            pairs.push((element(e.b), element(e.a), i));
        }
    }
    if pairs.is_empty() {
        return (Vec::new(), Vec::new());
    }
    pairs.sort_unstable();
    let mut start = vec![0u32; model.elements.len() + 1];
    for &(a, ..) in &pairs {
        start[a as usize + 1] += 1;
    }
    for e in 0..model.elements.len() {
        start[e + 1] += start[e];
    }
    (start, pairs.into_iter().map(|(_, b, i)| (b, i)).collect())
}

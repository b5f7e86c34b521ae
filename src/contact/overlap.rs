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
//! Between two bodies both take the role of the source, each with half the spring, so that two
//! flat faces pressed together carry `k_n` of eq. 12 once, whichever body comes first.
//!
//! The tangential traction of a piece is `−k_s s δ_n(ξ)/δ̄_n`, `s` its slip (the relative
//! tangential displacement at the piece's centre of pressure, summed over the steps since it
//! formed) and `δ̄_n` its mean depth: it follows the penetration profile, and the Coulomb
//! limit `k_s |s| ≤ μ k_n δ̄_n` (a return mapping on `s`) holds at every point of the piece.

use super::{frame, Frames, Ledger, NONE};
use crate::buckets::{BucketLists, Buckets};
use crate::geometry::Vec2;
use crate::model::{Model, GROUND};
use std::collections::HashSet;

/// A region that boundary edges can enter: an element with an edge on its body's boundary (a
/// convex polygon) or the strip below a ground segment.
#[derive(Debug, Clone, Copy)]
struct Target {
    /// The element, or [`GROUND`].
    element: u32,
    /// The body, or [`NONE`] for the ground.
    body: u32,
    /// Its corners are `corners[first..first + count]`, counter-clockwise; face `k` runs from
    /// corner `k` to corner `k + 1`, and is `faces[first + k]`.
    first: u32,
    count: u32,
}

/// A face of a target.
#[derive(Debug, Clone, Copy)]
struct Face {
    /// Compliances `h / E_n`, `h / E_s` of its side (zero for the ground).
    compliance: [f64; 2],
    /// Whether it is a surface (on the body's boundary, a ground segment or a free end of one)
    /// or only bounds the target (shared with another element, a joint between segments).
    surface: bool,
}

/// A boundary edge of a body as the source of contact: its end points are two corners of its
/// element's target.
#[derive(Debug, Clone, Copy)]
struct Source {
    element: u32,
    body: u32,
    ends: [u32; 2],
    compliance: [f64; 2],
}

/// A piece of a source edge inside one face's part of a target, live this step.
#[derive(Debug, Clone, Copy)]
struct Piece {
    source: u32,
    face: u32,
    /// Tangential slip `s` (m).
    slip: f64,
}

/// The state of edge-to-edge contact: targets, the neighbour list and the slips of the pieces.
#[derive(Debug, Clone)]
pub(super) struct Overlap {
    targets: Vec<Target>,
    faces: Vec<Face>,
    /// Reference offsets of the corners from their element's centroid; ground corners absolute.
    offsets: Vec<Vec2>,
    /// Current corners.
    corners: Vec<Vec2>,
    /// Corners at the last rebuild of the neighbour list.
    anchors: Vec<Vec2>,
    sources: Vec<Source>,
    /// Pairs `(source, target)` whose boxes, widened by the skin, overlapped at the last
    /// rebuild; sorted.
    candidates: Vec<(u32, u32)>,
    /// The neighbour list is rebuilt when a corner has moved more than half of this (m).
    skin: f64,
    /// Rebuilds of the neighbour list so far.
    pub rebuilds: u64,
    /// The force of the ground on the bodies at the last evaluation (N).
    pub ground: Vec2,
    buckets: BucketLists,
    /// Live pieces, sorted by `(source, face)`, and those of this step being found.
    pieces: Vec<Piece>,
    next: Vec<Piece>,
    /// Room for the faces of one target (no allocation in the step).
    scratch: Vec<FaceNow>,
    thickness: f64,
    factor: f64,
    friction: Option<f64>,
    fresh: bool,
}

/// A face of the target at hand, in the current configuration.
#[derive(Debug, Clone, Copy, Default)]
struct FaceNow {
    /// Depth below its line at both ends of the source edge (linear along it).
    depth: [f64; 2],
    /// Its unit tangent and outward normal.
    axes: (Vec2, Vec2),
    /// Normal and tangential springs against the source edge (Pa/m).
    spring: [f64; 2],
    surface: bool,
}

impl Overlap {
    pub fn new(model: &Model, friction: Option<f64>) -> Overlap {
        let mut targets = Vec::new();
        let mut faces = Vec::new();
        let mut offsets = Vec::new();
        let mut sources = Vec::new();
        let mut edge_length = 0.0;
        for (bi, body) in model.bodies.iter().enumerate() {
            let mesh = &body.mesh;
            let on_boundary: HashSet<(u32, u32)> = mesh.boundary.iter().map(|e| (e.cell, e.v1)).collect();
            let mut cells: Vec<u32> = mesh.boundary.iter().map(|e| e.cell).collect();
            cells.sort_unstable();
            cells.dedup();
            for c in cells {
                let element = body.first_element + c as usize;
                let centroid = model.elements[element].props.centroid;
                let cell = mesh.cell(c as usize);
                let first = offsets.len() as u32;
                for (k, &v) in cell.iter().enumerate() {
                    let (p1, p2) = (mesh.vertices[v as usize], mesh.vertices[cell[(k + 1) % cell.len()] as usize]);
                    let (_, n, length) = frame(p1, p2);
                    let h = (p1 - centroid).dot(&n).abs();
                    let compliance = [h / body.moduli[0], h / body.moduli[1]];
                    let surface = on_boundary.contains(&(c, v));
                    offsets.push(p1 - centroid);
                    faces.push(Face { compliance, surface });
                    if surface {
                        let ends = [first + k as u32, first + ((k + 1) % cell.len()) as u32];
                        sources.push(Source { element: element as u32, body: bi as u32, ends, compliance });
                        edge_length += length;
                    }
                }
                targets.push(Target { element: element as u32, body: bi as u32, first, count: cell.len() as u32 });
            }
        }
        let skin = 0.25 * edge_length / sources.len().max(1) as f64;
        for (gi, g) in model.ground.iter().enumerate() {
            // The strip below the segment, stored `to → from` as a body's boundary is (solid on
            // the left), closed at each end by a wall: perpendicular at a free end, the bisector
            // with the next segment at a joint.
            let (from, to) = (g[0], g[1]);
            let (_, n, length) = frame(to, from);
            let depth = 1.0e3 * length;
            let wall = |at: Vec2, other: Option<Vec2>| match other {
                // The other segment's normal at the joint: the wall bisects the two.
                Some(o) => {
                    let (_, m, _) = if at == from { frame(from, o) } else { frame(o, to) };
                    (-(n + m).normalize(), false)
                }
                None => (-n, true),
            };
            let joined = |at: Vec2, me_from: bool| {
                model.ground.iter().enumerate().find_map(|(j, h)| {
                    // A joint: this segment's `from` is another's `to`, or the reverse.
                    let (end, other) = if me_from { (h[1], h[0]) } else { (h[0], h[1]) };
                    (j != gi && end == at).then_some(other)
                })
            };
            let (down_from, free_from) = wall(from, joined(from, true));
            let (down_to, free_to) = wall(to, joined(to, false));
            let first = offsets.len() as u32;
            offsets.extend([to, from, from + depth * down_from, to + depth * down_to]);
            faces.extend([
                Face { compliance: [0.0; 2], surface: true },
                Face { compliance: [0.0; 2], surface: free_from },
                Face { compliance: [0.0; 2], surface: false },
                Face { compliance: [0.0; 2], surface: free_to },
            ]);
            targets.push(Target { element: GROUND, body: NONE, first, count: 4 });
        }
        let corners = offsets.clone();
        let n_sources = sources.len();
        let targets_max = targets.iter().map(|t| t.count as usize).max().unwrap_or(0);
        Overlap {
            anchors: vec![Vec2::repeat(f64::INFINITY); corners.len()],
            corners,
            offsets,
            faces,
            buckets: BucketLists::with_capacity(targets.len()),
            targets,
            sources,
            candidates: Vec::with_capacity(8 * n_sources),
            skin,
            rebuilds: 0,
            ground: Vec2::zeros(),
            scratch: Vec::with_capacity(targets_max),
            pieces: Vec::with_capacity(4 * n_sources),
            next: Vec::with_capacity(4 * n_sources),
            thickness: model.thickness,
            factor: model.formulation.spring_factor(),
            friction,
            fresh: true,
        }
    }

    /// The contact forces of state `u` into `ledger`; `velocity` is `v^{n−½}`, so that the step
    /// that led here moved the bodies by `Δt v^{n−½}` (not used at the first evaluation).
    /// Returns the energy stored in the contact springs (J).
    /// `tests` counts the narrow-phase tests (source edge against target).
    pub fn forces(&mut self, frames: &Frames, u: &[f64], velocity: &[f64], dt: f64, ledger: &mut Ledger, tests: &mut u64) -> f64 {
        self.place(frames, u);
        if self.moved_beyond_skin() {
            self.rebuild();
            self.rebuilds += 1;
        }
        self.next.clear();
        self.ground = Vec2::zeros();
        let mut energy = 0.0;
        for c in 0..self.candidates.len() {
            let (source, target) = self.candidates[c];
            energy += self.pair(frames, u, velocity, dt, ledger, source, target);
        }
        *tests += self.candidates.len() as u64;
        std::mem::swap(&mut self.pieces, &mut self.next);
        self.fresh = false;
        energy
    }

    /// The number of live pieces.
    pub fn len(&self) -> usize {
        self.pieces.len()
    }

    /// Current corners of every body target (the ground's are fixed).
    fn place(&mut self, frames: &Frames, u: &[f64]) {
        for t in &self.targets {
            if t.element == GROUND {
                continue;
            }
            let r = t.first as usize..(t.first + t.count) as usize;
            frames.place_all(u, t.element as usize, &self.offsets[r.clone()], &mut self.corners[r]);
        }
    }

    fn moved_beyond_skin(&self) -> bool {
        let limit = 0.25 * self.skin * self.skin;
        self.corners.iter().zip(&self.anchors).any(|(x, a)| (x - a).norm_squared() > limit)
    }

    /// The neighbour list: every source edge against every target of another body whose box,
    /// widened by the skin, its own widened box overlaps.
    fn rebuild(&mut self) {
        self.anchors.copy_from_slice(&self.corners);
        let widen = Vec2::repeat(self.skin);
        let boxes = |t: &Target| {
            let c = &self.corners[t.first as usize..(t.first + t.count) as usize];
            let (lo, hi) = c.iter().fold((c[0], c[0]), |(lo, hi), x| (lo.inf(x), hi.sup(x)));
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
        self.buckets.fill(&grid, targets.len(), |k| boxes(&targets[k]));
        self.candidates.clear();
        for (si, s) in self.sources.iter().enumerate() {
            let [a, b] = s.ends.map(|i| self.corners[i as usize]);
            let (slo, shi) = (a.inf(&b) - widen, a.sup(&b) + widen);
            for k in grid.touching(slo, shi) {
                for &t in self.buckets.bucket(k) {
                    let target = &self.targets[t as usize];
                    if target.body == s.body {
                        continue;
                    }
                    let (tlo, thi) = boxes(target);
                    if tlo.x <= shi.x && slo.x <= thi.x && tlo.y <= shi.y && slo.y <= thi.y {
                        self.candidates.push((si as u32, t));
                    }
                }
            }
        }
        // A target filed under several buckets is found once per bucket.
        self.candidates.sort_unstable();
        self.candidates.dedup();
    }

    /// The pieces of source edge `si` inside target `ti`: forces into `ledger`, the stored
    /// energy returned.
    #[allow(clippy::too_many_arguments)]
    fn pair(&mut self, frames: &Frames, u: &[f64], velocity: &[f64], dt: f64, ledger: &mut Ledger, si: u32, ti: u32) -> f64 {
        let src = self.sources[si as usize];
        let tgt = self.targets[ti as usize];
        let [q1, q2] = src.ends.map(|i| self.corners[i as usize]);
        let mut faces = std::mem::take(&mut self.scratch);
        faces.clear();
        faces.resize(tgt.count as usize, FaceNow::default());
        let energy = self.pieces_of(frames, u, velocity, dt, ledger, si, &src, &tgt, [q1, q2], &mut faces);
        self.scratch = faces;
        energy
    }

    /// [`Overlap::pair`] with room for the target's faces in `now`.
    #[allow(clippy::too_many_arguments)]
    fn pieces_of(
        &mut self,
        frames: &Frames,
        u: &[f64],
        velocity: &[f64],
        dt: f64,
        ledger: &mut Ledger,
        si: u32,
        src: &Source,
        tgt: &Target,
        [q1, q2]: [Vec2; 2],
        now: &mut [FaceNow],
    ) -> f64 {
        let m = tgt.count as usize;
        let corner = |k: usize| self.corners[tgt.first as usize + k % m];
        // Depth below each face line at both ends of the source edge (linear along it), and
        // the face's frame.
        for (k, f) in now.iter_mut().enumerate() {
            let (a, b) = (corner(k), corner(k + 1));
            let (s, n, _) = frame(a, b);
            f.depth = [q1, q2].map(|q| -(q - a).dot(&n));
            f.axes = (s, n);
        }
        // Quick reject: the whole edge outside one face.
        if now.iter().any(|f| f.depth[0] <= 0.0 && f.depth[1] <= 0.0) {
            return 0.0;
        }
        // The springs of eq. 12 with both sides' compliances, per face, and whether each face
        // is a surface.
        let half = if tgt.element == GROUND { 1.0 } else { 0.5 };
        for (k, f) in now.iter_mut().enumerate() {
            let face = self.faces[tgt.first as usize + k];
            f.spring = [0, 1].map(|i| half * self.factor / (src.compliance[i] + face.compliance[i]));
            f.surface = face.surface;
        }
        let length = (q2 - q1).norm();
        let mut energy = 0.0;
        for i in 0..m {
            if !now[i].surface {
                continue;
            }
            let ki = now[i].spring;
            let ri = ki[0].sqrt();
            let (mut a, mut b) = (0.0f64, 1.0f64);
            let mut keep = |v: [f64; 2]| {
                // Where `v0 + ξ (v1 − v0) ≥ 0`.
                let dv = v[1] - v[0];
                if dv == 0.0 {
                    if v[0] < 0.0 {
                        b = a - 1.0;
                    }
                } else if dv > 0.0 {
                    a = a.max(-v[0] / dv);
                } else {
                    b = b.min(-v[0] / dv);
                }
            };
            keep(now[i].depth);
            for (_, f) in now.iter().enumerate().filter(|&(j, _)| j != i) {
                if f.surface {
                    // √k_j δ_j − √k_i δ_i ≥ 0: nearer to face i in the weighted sense.
                    let rj = f.spring[0].sqrt();
                    keep([0, 1].map(|e| rj * f.depth[e] - ri * now[i].depth[e]));
                } else {
                    keep(f.depth);
                }
            }
            if b <= a {
                continue;
            }
            energy += self.piece(frames, u, velocity, dt, ledger, src, tgt, si, i, ki, [q1, q2], now[i].depth, now[i].axes, (a, b), length);
        }
        energy
    }

    /// One piece `ξ ∈ [a, b]` of source edge `si` in the part of face `i` of `tgt`.
    #[allow(clippy::too_many_arguments)]
    fn piece(
        &mut self,
        frames: &Frames,
        u: &[f64],
        velocity: &[f64],
        dt: f64,
        ledger: &mut Ledger,
        src: &Source,
        tgt: &Target,
        si: u32,
        i: usize,
        k: [f64; 2],
        [q1, q2]: [Vec2; 2],
        depth: [f64; 2],
        (s, n): (Vec2, Vec2),
        (a, b): (f64, f64),
        length: f64,
    ) -> f64 {
        let face = tgt.first + i as u32;
        let lerp = |v: [f64; 2], xi: f64| v[0] + xi * (v[1] - v[0]);
        let half = 0.5 * (b - a);
        let w = half * length * self.thickness;
        let gauss = [-1.0, 1.0].map(|g| a + half * (1.0 + g / 3f64.sqrt()));
        let d = gauss.map(|xi| lerp(depth, xi));
        let mean = 0.5 * (d[0] + d[1]);
        // The slip: carried over from the last step, plus the relative tangential motion of
        // the step at the centre of pressure; Coulomb's limit by return mapping.
        let mut slip = match self.pieces.binary_search_by_key(&(si, face), |p| (p.source, p.face)) {
            Ok(p) => self.pieces[p].slip,
            Err(_) => 0.0,
        };
        if mean > 0.0 && !self.fresh {
            let centre = (d[0] * gauss[0] + d[1] * gauss[1]) / (d[0] + d[1]);
            let x = q1 + centre * (q2 - q1);
            let mut step = frames.increment(u, velocity, dt, src.element as usize, x);
            if tgt.element != GROUND {
                step -= frames.increment(u, velocity, dt, tgt.element as usize, x);
            }
            slip += step.dot(&s);
        }
        if let Some(mu) = self.friction {
            let limit = mu * k[0] * mean / k[1];
            slip = slip.clamp(-limit, limit);
        }
        self.next.push(Piece { source: si, face, slip });
        let mut energy = 0.0;
        for (xi, di) in gauss.into_iter().zip(d) {
            let stretch = if mean > 0.0 { slip * di / mean } else { 0.0 };
            let (tn, ts) = (k[0] * di, -k[1] * stretch);
            let x = q1 + xi * (q2 - q1);
            let force = w * (tn * n + ts * s);
            frames.push(u, ledger, src.element, x, force);
            if tgt.element != GROUND {
                frames.push(u, ledger, tgt.element, x, -force);
            } else {
                self.ground += force;
            }
            energy += 0.5 * w * (k[0] * di * di + k[1] * stretch * stretch);
        }
        energy
    }
}

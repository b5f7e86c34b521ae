//! The sweep both evaluators evaluate and step with: the internal forces summed over the
//! couplings of element pairs, each computed once and handed to both its elements, and each
//! element advanced as soon as its force is complete ([`FusedStep`](super::FusedStep)).
//!
//! A coupling is what joins two elements `a < b`: for the element-wise evaluator an interface
//! and its tractions (eq. 15), for the assembled one the block `K_ab` of the symmetric `K`
//! (eq. 7), which gives `K_ab U_b` to `a` and `K_abᵀ U_a` to `b`. The couplings are kept in the
//! order of their lower element; a sweep in that order has finished element `e` once it has done
//! the couplings that start at `e` (those that end at `e` started earlier). The element's force
//! is then complete and, in a time step, its velocity and displacement are advanced at once:
//! `U_e` is read by no later coupling, and the step moves each vector once.
//!
//! While it sweeps, an element's force is pending only from its first coupling to its own
//! completion, and a coupling reaches at most `max(b − a)` elements ahead. The pending forces
//! are therefore kept in a ring of the next power of two above that reach (four slots at
//! least), which stays in
//! cache (a 1000 × 1000 grid needs 1024 slots): no global force vector is read or written.
//! An element takes its pending force from the ring when the sweep reaches it and adds its own
//! couplings in registers. The couplings inside a block lie apart from those to the ground and
//! to later blocks, which are rare and need no test in the inner loop. A time step reads the
//! rest of the net force, `−P − f_c`, only at the elements that carry loads when the integrator
//! can name them (no gravity, no contact).
//!
//! On a regular mesh whose couplings share records, consecutive elements often have the same
//! couplings shifted by one element: a [`Run`]. The sweep steps through a run with the
//! couplings of its first element, found once, which are all the couplings of a run it keeps.
//! Where the first of them reaches the next element and the others far enough ([`in_lanes`]),
//! and the couplings can ([`Couplings::WIDE`]), it goes four elements at a time, one in each
//! lane of a [`Wide`]: the same operations in the same order, four at once.
//!
//! An undamped step with a lumped `M⁻¹` may also run on `U`, `v` and `M⁻¹` stored in groups of
//! four elements ([`crate::lanes::grouped`], [`Sweep::advance_grouped`]), and its ring too: four
//! elements that start a group then load, update and store their DOFs in lanes as they are,
//! where the element-by-element layout needs a transpose each way. Its runs go in lanes only
//! where their couplings meet whole groups (rows a multiple of four elements long on a grid).
//!
//! A sweep may carry a wave that leads it ([`Couplings::leads`]): a sum per element of what its
//! couplings read of `U` at `t_n` (the Poisson correction's first moments, whose `q` every
//! coupling of the element then needs). The wave goes through the couplings of the element as
//! far ahead as the block's couplings reach, so that an element's sum is complete before the
//! sweep's first coupling to it, and read before any element it reads has moved; its sums
//! wait in a ring of their own. It reads each coupling's record shortly before the sweep does,
//! which then finds it in the cache: one stream of records for both.
//!
//! Parallel sweeps run over fixed blocks of consecutive elements. A coupling from one block
//! into a later one is computed before the sweeps, from the state at `t_n`, and handed to both
//! blocks. Every element sums its couplings in their order whatever the blocks and the threads,
//! so the result does not depend on the thread count. A wave leaves out the elements with
//! couplings to other blocks ([`Sweep::border`]), whose sums the caller gives before the sweeps.

use crate::lanes::grouped::{as_groups, as_groups_mut};
use crate::lanes::{lane, set_lane, Lanes, Plain, Wide};
use crate::model::mass::{lumped_update, ElementUpdate, Update, WithUpdate};
use crate::model::GROUND;
use rayon::prelude::*;
use std::ops::Range;
use std::sync::{Mutex, MutexGuard};

/// A coupling: its lower element `a`, its higher one `b` or [`GROUND`], and what it needs
/// to give its forces, `R`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Face<R> {
    pub(super) a: u32,
    pub(super) b: u32,
    pub(super) record: R,
}

/// Where `face`, one of `faces`, is in it: the sweep hands a coupling over as a reference into
/// [`Couplings::faces`], whose place names what a coupling keeps beside its face.
#[inline(always)]
pub(super) fn place<R>(faces: &[Face<R>], face: &Face<R>) -> usize {
    let first = faces.as_ptr() as usize;
    (std::ptr::from_ref(face) as usize - first) / std::mem::size_of::<Face<R>>()
}

/// The couplings of a model, in the order of the sweep, and how each adds its internal forces
/// `f_int` to its elements.
pub(super) trait Couplings<const N: usize>: Sync {
    /// What a [`Face`] holds of its coupling.
    type Ref: Copy + Sync;
    /// Whether the sweep asks for the couplings and `U` ahead of their use ([`PREFETCH_AHEAD`]):
    /// a large record per coupling crosses a page every few dozen, which the hardware
    /// prefetchers do not follow.
    const PREFETCH: bool;
    /// Whether its couplings may form [`Run`]s ([`Sweep::find_runs`]); the sweep of others has
    /// no code for them.
    const RUNS: bool;
    fn faces(&self) -> &[Face<Self::Ref>];
    /// What [`Couplings::add_pair`] reads of a coupling between two elements, found from its
    /// [`Face`] once (a [`Run`] finds it once for all its elements).
    type Coupling<'a>: Copy
    where
        Self: 'a;
    fn coupling<'a>(&'a self, face: &'a Face<Self::Ref>) -> Self::Coupling<'a>;
    /// Adds the internal forces of a coupling between two elements to `fa` and `fb`.
    fn add_pair(
        &self,
        lanes: impl Lanes,
        coupling: Self::Coupling<'_>,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    );
    /// [`Couplings::add_pair`] for the four pairs `(a + l, b + l)`, `l = 0..4`, of one
    /// coupling in lanes: the arithmetic of the four calls in their order, which a coupling
    /// may do four lanes at a time.
    #[inline(always)]
    fn add_pairs(
        &self,
        lanes: impl Lanes,
        coupling: Self::Coupling<'_>,
        ua: &Wide<N>,
        ub: &Wide<N>,
        fa: &mut Wide<N>,
        mut fb: Higher<'_, N>,
    ) {
        if let Higher::Next(carry) = &fb {
            for j in 0..N {
                fa[j][0] += carry[j][0];
            }
        }
        for l in 0..4 {
            let mut on_a = lane(fa, l);
            let mut on_b = match &fb {
                Higher::Apart(fb) => fb[l],
                Higher::ApartWide(fb) => lane(fb, l),
                Higher::Next(_) if l < 3 => lane(fa, l + 1),
                // What the last pair gives its `b`, alone: `−0 + x` is `x`.
                Higher::Next(_) => [-0.0; N],
            };
            let (a, b) = (lane(ua, l), lane(ub, l));
            self.add_pair(lanes, coupling, &a, &b, &mut on_a, &mut on_b);
            set_lane(fa, l, &on_a);
            match &mut fb {
                Higher::Apart(fb) => fb[l] = on_b,
                Higher::ApartWide(fb) => set_lane(fb, l, &on_b),
                Higher::Next(_) if l < 3 => set_lane(fa, l + 1, &on_b),
                Higher::Next(carry) => set_lane(carry, 0, &on_b),
            }
        }
    }
    /// Adds the internal force of `face`, to the ground, to `fa`.
    fn add_ground(&self, face: &Face<Self::Ref>, ua: &[f64; N], fa: &mut [f64; N]);
    /// Whether a [`Run`] goes four elements at a time in lanes where it can
    /// ([`Couplings::add_pairs`]); else one at a time.
    const WIDE: bool;
    /// Whether [`Couplings::add_own`] adds anything.
    const OWN: bool = true;
    /// Adds element `e`'s own term to its force `f`, last.
    fn add_own(&self, e: usize, ue: &[f64; N], f: &mut [f64; N]);
    /// Whether the sweep carries a wave that leads it: a sum `s` per element of what each of
    /// its couplings reads of `U` at `t_n` ([`Couplings::lead_pair`]), completed
    /// ([`Couplings::lead_done`]) as many elements ahead of the sweep as its couplings reach,
    /// before any element it reads has moved and before any coupling of the sweep uses it
    /// (the Poisson correction's cells' `q`). Not for couplings that form runs. The elements
    /// with couplings across blocks ([`Sweep::border`]) are left out: theirs come before the
    /// sweeps.
    fn leads(&self) -> bool {
        false
    }
    /// The wave's shares of a coupling between two elements, to `a`'s sum and to `b`'s.
    fn lead_pair(&self, _face: &Face<Self::Ref>, _ua: &[f64; N], _ub: &[f64; N]) -> [f64; 2] {
        [0.0; 2]
    }
    /// The wave's share of a coupling to the ground.
    fn lead_ground(&self, _face: &Face<Self::Ref>, _ua: &[f64; N]) -> f64 {
        0.0
    }
    /// Element `e`'s sum `s` of the wave is complete.
    fn lead_done(&self, _e: usize, _s: f64) {}
}

/// Where [`Couplings::add_pairs`] puts the forces on the pairs' higher elements.
pub enum Higher<'a, const N: usize> {
    /// Four elements of their own, not in lanes.
    Apart(&'a mut [[f64; N]; 4]),
    /// Four elements of their own, in lanes (a ring in groups, [`BlockState::GROUPED`]).
    ApartWide(&'a mut Wide<N>),
    /// Each pair's `b` is the next pair's `a`: the forces on lanes 0–2 go to lanes 1–3 of `fa`,
    /// before the next pair adds its own. Lane 0 of `fa` first gets lane 0 of this carry, what
    /// the last pair of the four before gave it; that on lane 3 goes to lane 0 of the carry.
    /// Each DOF of a higher element gets one addition, so that its force alone, added later,
    /// is the same sum: `p + x` after `p` is `p + (−0 + x)` to the bit.
    Next(&'a mut Wide<N>),
}

/// Consecutive elements swept by one task, with the couplings that start in them.
#[derive(Debug, Clone)]
pub(super) struct Block {
    pub(super) elements: Range<usize>,
    /// The couplings between two of the block's elements, in coupling order; of a [`Run`],
    /// those of its first element only.
    inner: Range<usize>,
    /// Then, in coupling order, those to a later block or to the ground. Of a given element,
    /// these follow its inner ones in the coupling order too (a later `b`, or [`GROUND`]).
    rest: Range<usize>,
    /// Couplings into later blocks, as a range of `Sweep::crossing`.
    outgoing: Range<usize>,
    /// Couplings from earlier blocks, as a range of `Sweep::incoming`.
    pub(super) incoming: Range<usize>,
    /// Slots of the block's ring of pending forces, a power of two above its farthest reach
    /// `max(b − a)`, and at least four (a ring in groups of four, [`BlockState::GROUPED`]).
    pub(super) ring: usize,
    /// Runs of consecutive elements whose couplings repeat ([`Sweep::find_runs`]), in order.
    runs: Vec<Run>,
    /// How far its inner couplings reach, `max(b − a)`: how far a wave leads the sweep
    /// ([`Couplings::leads`]).
    reach: usize,
    /// Its elements with couplings to or from other blocks, as a range of `Sweep::border`.
    border: Range<usize>,
}

/// Consecutive elements of a block, by their index in it, each with couplings equal to the
/// next one's shifted by one element: the same `b − a` and the same record, `width` of them,
/// all inside the block. The sweep keeps the couplings of its first element only, and steps
/// through it with no test per coupling, four elements at a time in lanes if `lanes`
/// ([`in_lanes`]).
#[derive(Debug, Clone)]
struct Run {
    elements: Range<usize>,
    width: usize,
    lanes: bool,
    /// Whether its couplings but the first reach a multiple of four elements: in lanes, they
    /// then meet whole groups of a grouped step ([`BlockState::GROUPED`]), which goes in
    /// lanes only then.
    aligned: bool,
}

/// Whether a [`Run`] whose couplings reach `reach` elements ahead, in increasing order, may
/// go four elements at a time in a ring of `ring` slots: its first coupling reaches the next
/// element (a grid's row), the others at least five elements and four apart, and all within
/// the ring with room for four. Then a coupling of four elements adds to no slot of the same
/// four (but the next's, [`Higher::Next`]), and no slot gets forces from two of their
/// couplings, so the four may add their forces coupling by coupling in lanes
/// ([`Couplings::add_pairs`]) in the order of the element-by-element sweep.
fn in_lanes(reach: &[usize], ring: usize) -> bool {
    match reach {
        [1, second, ..] => {
            *second > 4
                && reach[1..].windows(2).all(|r| r[1] >= r[0] + 4)
                && reach[reach.len() - 1] + 4 <= ring
        }
        _ => false,
    }
}

/// The most couplings an element of a [`Run`] may have.
const MAX_WIDTH: usize = 4;

/// Elements per block: at least this many, and at most 64 blocks in all (fewer couplings
/// cross blocks on large meshes).
const MIN_BLOCK: usize = 4096;
const MAX_BLOCKS: usize = 64;
/// At most this many blocks for a sweep that a wave leads ([`Couplings::leads`]): its elements
/// on the blocks' borders are gathered one by one before the sweeps, and 16 blocks of a
/// 10⁶-element Voronoi panel leave 3 % of them there, 64 blocks 13 %.
const LEADING_BLOCKS: usize = 16;

/// How many couplings ahead of the sweep their records are asked for, and half as many ahead
/// the `U` of their higher element. The hardware prefetchers stop at every 4 KiB page, which
/// a stream of 72-byte records crosses every 57 couplings; 64 couplings take about 0.5 µs to
/// sweep.
const PREFETCH_AHEAD: usize = 64;

/// The blocks of a model's sweep, the couplings that cross them, and the scratch space of one
/// evaluation at a time.
pub(super) struct Sweep<const N: usize> {
    pub(super) blocks: Vec<Block>,
    /// The couplings whose elements lie in two blocks, in coupling order.
    pub(super) crossing: Vec<u32>,
    /// Per block, the couplings that end in it as `(b, index into crossing)`, ordered by
    /// `b` and then in coupling order.
    pub(super) incoming: Vec<(u32, u32)>,
    /// The elements with couplings into other blocks, block by block in order: those a wave
    /// leaves to the caller ([`Couplings::leads`]).
    border: Vec<u32>,
    /// Whether a wave may lead it: its blocks have the wave's rings.
    wave: bool,
    /// The crossing couplings' forces and the blocks' rings.
    pub(super) scratch: Mutex<Scratch<N>>,
}

/// What an evaluation writes besides `U`, `v` and `f`: the crossing couplings' forces and
/// one ring of pending forces per block.
pub(super) struct Scratch<const N: usize> {
    crossing: Vec<[[f64; N]; 2]>,
    pub(super) rings: Vec<Ring<N>>,
    /// Per block, `Σ v̄ᵀ M_e v̄` of a damped step ([`ElementUpdate::element`]).
    powers: Vec<f64>,
}

/// A block's ring of pending forces, and of a leading wave's sums ([`Couplings::leads`]),
/// slot by slot.
pub(super) struct Ring<const N: usize> {
    pub(super) forces: Vec<[f64; N]>,
    wave: Vec<f64>,
}

impl<const N: usize> Sweep<N> {
    /// Orders the couplings of `n` elements for the sweep, each with `a < b` or `b` the
    /// [`GROUND`]: by `(a, b)`, then in each block those inside it first; in the blocks of a
    /// sweep that a wave leads, with its ring, if `wave` ([`Couplings::leads`]).
    pub(super) fn new<R>(n: usize, faces: &mut [Face<R>], wave: bool) -> Self {
        faces.sort_by_key(|f| (f.a, f.b));
        let blocks = if wave { LEADING_BLOCKS } else { MAX_BLOCKS };
        let len = MIN_BLOCK.max(n.div_ceil(blocks)).next_multiple_of(4);
        let (mut blocks, mut crossing) = (Vec::new(), Vec::new());
        for first in (0..n).step_by(len) {
            let elements = first..(first + len).min(n);
            let start = |e: usize| faces.partition_point(|f| (f.a as usize) < e);
            let here = start(elements.start)..start(elements.end);
            // Inner couplings first; a stable sort keeps the coupling order in both parts.
            let is_inner = |f: &Face<R>| f.b != GROUND && (f.b as usize) < elements.end;
            faces[here.clone()].sort_by_key(|f| !is_inner(f));
            let inner = here.start + faces[here.clone()].partition_point(is_inner);
            let reach = faces[here.start..inner]
                .iter()
                .map(|f| (f.b - f.a) as usize)
                .max();
            let reach = reach.unwrap_or(0);
            let ring = (reach + 1).next_power_of_two().max(4);
            let before = crossing.len();
            crossing.extend(
                (inner..here.end)
                    .filter(|&k| faces[k].b != GROUND)
                    .map(|k| k as u32),
            );
            blocks.push(Block {
                elements,
                inner: here.start..inner,
                rest: inner..here.end,
                outgoing: before..crossing.len(),
                incoming: 0..0,
                ring,
                runs: Vec::new(),
                reach,
                border: 0..0,
            });
        }
        let (mut incoming, mut border) = (Vec::new(), Vec::new());
        for block in &mut blocks {
            let before = incoming.len();
            incoming.extend(crossing.iter().enumerate().filter_map(|(c, &k)| {
                let b = faces[k as usize].b;
                block
                    .elements
                    .contains(&(b as usize))
                    .then_some((b, c as u32))
            }));
            incoming[before..].sort_unstable();
            block.incoming = before..incoming.len();
            let first = border.len();
            border.extend(incoming[block.incoming.clone()].iter().map(|&(b, _)| b));
            border.extend(
                crossing[block.outgoing.clone()]
                    .iter()
                    .map(|&k| faces[k as usize].a),
            );
            border[first..].sort_unstable();
            let mut kept = first;
            for j in first..border.len() {
                if kept == first || border[j] != border[kept - 1] {
                    border[kept] = border[j];
                    kept += 1;
                }
            }
            border.truncate(kept);
            block.border = first..kept;
        }
        let scratch = Mutex::new(Scratch {
            crossing: vec![[[0.0; N]; 2]; crossing.len()],
            rings: blocks
                .iter()
                .map(|b| Ring {
                    forces: vec![[0.0; N]; b.ring],
                    wave: vec![0.0; if wave { b.ring } else { 0 }],
                })
                .collect(),
            powers: vec![0.0; blocks.len()],
        });
        Sweep {
            blocks,
            crossing,
            incoming,
            border,
            wave,
            scratch,
        }
    }

    /// Finds the [`Run`]s of each block in `faces`, the couplings as [`Sweep::new`] ordered
    /// them, with records that name shared ones: two couplings repeat when their records are
    /// equal. Runs of fewer than four elements are left to the element-by-element sweep. Of a
    /// run, `faces` keeps the couplings of its first element only.
    pub(super) fn find_runs<R: PartialEq + Copy>(&mut self, faces: &mut Vec<Face<R>>) {
        debug_assert!(
            self.blocks.iter().all(|b| b.runs.is_empty()),
            "runs found twice"
        );
        let mut kept = Vec::with_capacity(faces.len());
        // Where the couplings to other blocks move, by their index in `faces`.
        let mut moved = std::collections::HashMap::new();
        for block in &mut self.blocks {
            let first = block.elements.start;
            let inner = &faces[block.inner.clone()];
            let rest = &faces[block.rest.clone()];
            // Each element's inner couplings, as a range of `inner`.
            let mut k = 0;
            let own: Vec<Range<usize>> = block
                .elements
                .clone()
                .map(|e| {
                    let start = k;
                    k += inner[k..].partition_point(|f| f.a as usize == e);
                    start..k
                })
                .collect();
            let repeats = |x: &Face<R>, y: &Face<R>| y.b - y.a == x.b - x.a && y.record == x.record;
            let fits = |i: usize| {
                let r = &own[i];
                let e = (first + i) as u32;
                (1..=MAX_WIDTH).contains(&r.len())
                    && rest.binary_search_by_key(&e, |f| f.a).is_err()
            };
            let start = kept.len();
            let mut i = 0;
            while i < own.len() {
                let from = i;
                kept.extend_from_slice(&inner[own[i].clone()]);
                if fits(i) {
                    while i + 1 < own.len()
                        && fits(i + 1)
                        && own[i].len() == own[i + 1].len()
                        && inner[own[i].clone()]
                            .iter()
                            .zip(&inner[own[i + 1].clone()])
                            .all(|(x, y)| repeats(x, y))
                    {
                        i += 1;
                    }
                }
                i += 1;
                if i - from >= 4 {
                    let reach: Vec<usize> = inner[own[from].clone()]
                        .iter()
                        .map(|f| (f.b - f.a) as usize)
                        .collect();
                    block.runs.push(Run {
                        elements: from..i,
                        width: own[from].len(),
                        lanes: in_lanes(&reach, block.ring),
                        aligned: reach[1..].iter().all(|r| r.is_multiple_of(4)),
                    });
                } else {
                    for r in &own[from + 1..i] {
                        kept.extend_from_slice(&inner[r.clone()]);
                    }
                }
            }
            let end = kept.len();
            for k in block.rest.clone() {
                moved.insert(k as u32, kept.len() as u32);
                kept.push(faces[k]);
            }
            (block.inner, block.rest) = (start..end, end..kept.len());
        }
        for k in &mut self.crossing {
            *k = moved[k];
        }
        *faces = kept;
    }

    /// How many elements lie in [`Run`]s, how many in runs that may go in lanes, and how many
    /// couplings from earlier blocks enter a ring while the sweep is inside a run, and inside a
    /// run in lanes.
    #[cfg(test)]
    pub(super) fn run_elements(&self) -> (usize, usize, usize, usize) {
        let runs = self.blocks.iter().flat_map(|b| &b.runs);
        let elements = runs.clone().map(|r| r.elements.len()).sum();
        let in_lanes = runs.filter(|r| r.lanes).map(|r| r.elements.len()).sum();
        let (mut entries, mut entries_in_lanes) = (0, 0);
        for b in &self.blocks {
            let at =
                |&(e, _): &(u32, u32)| (e as usize - b.elements.start).saturating_sub(b.ring - 1);
            for i in self.incoming[b.incoming.clone()].iter().map(at) {
                let run = b
                    .runs
                    .iter()
                    .find(|r| r.elements.start < i && i < r.elements.end);
                entries += run.is_some() as usize;
                entries_in_lanes += run.is_some_and(|r| r.lanes) as usize;
            }
        }
        (elements, in_lanes, entries, entries_in_lanes)
    }

    /// The elements with couplings into other blocks, in order: those whose sums a leading
    /// wave leaves to the caller, who gives them before the sweeps ([`Couplings::leads`]).
    pub(super) fn border(&self) -> &[u32] {
        &self.border
    }

    /// Whether some of its runs go four elements at a time in lanes in a grouped step.
    pub(super) fn in_lanes(&self) -> bool {
        self.blocks
            .iter()
            .flat_map(|b| &b.runs)
            .any(|r| r.lanes && r.aligned)
    }

    /// The bytes it holds: the crossing couplings and their forces, the rings, the runs.
    pub(super) fn bytes(&self) -> usize {
        use std::mem::{size_of, size_of_val};
        let rings: usize = self.blocks.iter().map(|b| b.ring).sum();
        let runs: usize = self.blocks.iter().map(|b| size_of_val(&b.runs[..])).sum();
        runs + size_of_val(&self.crossing[..])
            + size_of_val(&self.incoming[..])
            + self.crossing.len() * size_of::<[[f64; N]; 2]>()
            + rings * size_of::<[f64; N]>()
            + if self.wave {
                rings * size_of::<f64>()
            } else {
                0
            }
    }

    /// `f = f_int(u)`, parallel over blocks.
    pub(super) fn evaluate(&self, couplings: &impl Couplings<N>, u: &[f64], f: &mut [f64]) {
        let (u, _) = u.as_chunks::<N>();
        let (f, _) = f.as_chunks_mut::<N>();
        let mut scratch = self.crossing_pass(couplings, |e| u[e]);
        let Scratch {
            crossing, rings, ..
        } = &mut *scratch;
        type Parts<'a, const N: usize> = (
            (&'a Block, &'a mut Ring<N>),
            (&'a [[f64; N]], &'a mut [[f64; N]]),
        );
        let work = |((block, ring), (u, f)): Parts<N>| {
            self.sweep(couplings, block, crossing, ring, Evaluate { u, f })
        };
        match &self.blocks[..] {
            [block] => work(((block, &mut rings[0]), (u, f))),
            blocks => {
                let len = blocks.first().map_or(1, |b| b.elements.len());
                blocks
                    .par_iter()
                    .zip(rings.par_iter_mut())
                    .zip(u.par_chunks(len).zip(f.par_chunks_mut(len)))
                    .for_each(work);
            }
        }
    }

    /// One explicit step ([`FusedStep::advance`](super::FusedStep::advance)), parallel over
    /// blocks.
    pub(super) fn advance(
        &self,
        couplings: &impl Couplings<N>,
        u: &mut [f64],
        v: &mut [f64],
        force: &mut [f64],
        loaded: Option<&[u32]>,
        update: &Update,
    ) -> f64 {
        let (u, _) = u.as_chunks_mut::<N>();
        let (v, _) = v.as_chunks_mut::<N>();
        let (force, _) = force.as_chunks_mut::<N>();
        let mut scratch = self.crossing_pass(couplings, |e| u[e]);
        let Scratch {
            crossing,
            rings,
            powers,
        } = &mut *scratch;
        type Parts<'a, const N: usize> = (
            ((&'a Block, &'a mut Ring<N>), &'a mut f64),
            ((&'a mut [[f64; N]], &'a mut [[f64; N]]), &'a mut [[f64; N]]),
        );
        let work = |(((block, ring), power), ((u, v), force)): Parts<N>| {
            // The loaded elements of this block.
            let loaded = loaded.map(|l| {
                let at = |e: usize| l.partition_point(|&x| (x as usize) < e);
                &l[at(block.elements.start)..at(block.elements.end)]
            });
            update.resolve(
                block.elements.clone(),
                AdvanceBlock {
                    sweep: self,
                    couplings,
                    block,
                    crossing,
                    ring,
                    u,
                    v,
                    force,
                    loaded,
                    power,
                },
            );
        };
        match &self.blocks[..] {
            [block] => work((((block, &mut rings[0]), &mut powers[0]), ((u, v), force))),
            blocks => {
                let len = blocks.first().map_or(1, |b| b.elements.len());
                let vectors = u
                    .par_chunks_mut(len)
                    .zip(v.par_chunks_mut(len))
                    .zip(force.par_chunks_mut(len));
                blocks
                    .par_iter()
                    .zip(rings.par_iter_mut())
                    .zip(powers.par_iter_mut())
                    .zip(vectors)
                    .for_each(work);
            }
        }
        // In block order: the same sum whatever the thread count.
        powers.iter().sum()
    }

    /// One undamped explicit step with a lumped `M⁻¹`, on `U`, `v` and `M⁻¹` in groups of
    /// four elements ([`crate::lanes::grouped`]; `force` and `loaded` as in
    /// [`Sweep::advance`]), parallel over blocks.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn advance_grouped(
        &self,
        couplings: &impl Couplings<N>,
        u: &mut [f64],
        v: &mut [f64],
        inv: &[f64],
        force: &mut [f64],
        loaded: &[u32],
        dt: f64,
    ) {
        let (u, v) = (as_groups_mut::<N>(u), as_groups_mut::<N>(v));
        let inv = as_groups::<N>(inv);
        let (force, _) = force.as_chunks_mut::<N>();
        let mut scratch = self.crossing_pass(couplings, |e| lane(&u[e / 4], e % 4));
        let Scratch {
            crossing, rings, ..
        } = &mut *scratch;
        type Parts<'a, const N: usize> = (
            (&'a Block, &'a mut Ring<N>),
            (
                ((&'a mut [Wide<N>], &'a mut [Wide<N>]), &'a [Wide<N>]),
                &'a mut [[f64; N]],
            ),
        );
        let work = |((block, ring), (((u, v), inv), force)): Parts<N>| {
            let at = |e: usize| loaded.partition_point(|&x| (x as usize) < e);
            let loaded = &loaded[at(block.elements.start)..at(block.elements.end)];
            let state = AdvanceGrouped {
                u,
                v,
                inv,
                force,
                loaded: Loaded::new(Some(loaded)),
                dt,
            };
            self.sweep(couplings, block, crossing, ring, state);
        };
        match &self.blocks[..] {
            [block] => work(((block, &mut rings[0]), (((u, v), inv), force))),
            blocks => {
                let len = blocks.first().map_or(1, |b| b.elements.len());
                let vectors = u
                    .par_chunks_mut(len / 4)
                    .zip(v.par_chunks_mut(len / 4))
                    .zip(inv.par_chunks(len / 4))
                    .zip(force.par_chunks_mut(len));
                blocks
                    .par_iter()
                    .zip(rings.par_iter_mut())
                    .zip(vectors)
                    .for_each(work);
            }
        }
    }

    /// The scratch space, with the crossing couplings' forces from `u` at `t_n`, computed
    /// before any block moves.
    fn crossing_pass(
        &self,
        couplings: &impl Couplings<N>,
        u: impl Fn(usize) -> [f64; N] + Sync,
    ) -> MutexGuard<'_, Scratch<N>> {
        let mut scratch = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        scratch
            .crossing
            .par_iter_mut()
            .zip(self.crossing.par_iter())
            .with_min_len(1024)
            .for_each(|(out, &k)| {
                let f = &couplings.faces()[k as usize];
                let (ua, ub) = (u(f.a as usize), u(f.b as usize));
                *out = [[0.0; N]; 2];
                let [fa, fb] = out;
                couplings.add_pair(Plain, couplings.coupling(f), &ua, &ub, fa, fb);
            });
        scratch
    }

    /// The internal forces over one block: each element's `f_int`, summed in coupling order in
    /// the block's `ring` (all zero before and after), its own term last, and handed to `state`
    /// as soon as it is complete. `crossing` holds the crossing couplings' forces.
    ///
    /// On x86-64 it runs compiled for AVX2 where the processor has it (three-operand
    /// instructions, and [`Lanes`] of 256 bits: fewer of them). The arithmetic is the same, with
    /// no fused multiply-add, so the forces are the same bits on every processor.
    #[inline(always)]
    fn sweep<C: Couplings<N>, S: BlockState<N>>(
        &self,
        couplings: &C,
        block: &Block,
        crossing: &[[[f64; N]; 2]],
        ring: &mut Ring<N>,
        state: S,
    ) {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            return simd.vectorize(InOrder {
                sweep: self,
                simd,
                couplings,
                block,
                crossing,
                ring,
                state,
            });
        }
        self.sweep_in_order(Plain, couplings, block, crossing, ring, state)
    }

    /// [`Sweep::sweep`], as compiled for the processor at hand.
    #[inline(always)]
    fn sweep_in_order<C: Couplings<N>, S: BlockState<N>>(
        &self,
        lanes: impl Lanes,
        couplings: &C,
        block: &Block,
        crossing: &[[[f64; N]; 2]],
        Ring { forces: ring, wave }: &mut Ring<N>,
        mut state: S,
    ) {
        let first = block.elements.start;
        let mask = ring.len() - 1;
        let ring = &mut ring[..=mask];
        let incoming = &self.incoming[block.incoming.clone()];
        let crossing_out = &crossing[block.outgoing.clone()];
        let mut out = 0;
        let inner = &couplings.faces()[block.inner.clone()];
        let rest = &couplings.faces()[block.rest.clone()];
        let (mut k, mut r, mut next_in) = (0, 0, 0);
        // Where the next coupling from an earlier block enters the ring, and the next element
        // with couplings to the ground or to a later block: both are rare, and each element
        // outside a run tests them once (a run has neither).
        let entry = |next_in: usize| {
            incoming.get(next_in).map_or(usize::MAX, |&(b, _)| {
                (b as usize - first).saturating_sub(mask)
            })
        };
        let start = |r: usize| rest.get(r).map_or(usize::MAX, |f| f.a as usize);
        let (mut next_entry, mut next_rest) = (entry(0), start(0));
        // The next run, or what is left of it.
        let none = Run {
            elements: usize::MAX..usize::MAX,
            width: 0,
            lanes: false,
            aligned: false,
        };
        let mut runs = block.runs.iter();
        let mut run = runs.next().unwrap_or(&none).clone();
        let (leads, border) = (couplings.leads(), &self.border[block.border.clone()]);
        debug_assert!(!(leads && C::RUNS), "a wave leads no sweep with runs");
        assert!(!leads || wave.len() > mask, "a sweep built for a wave");
        let wave = if leads { &mut wave[..=mask] } else { &mut [] };
        let mut lead = Lead::default();
        let mut i = 0;
        while i < block.elements.len() {
            let e = first + i;
            // The wave reaches as far ahead as the couplings of element `i`.
            if leads {
                let end = (i + block.reach + 1).min(block.elements.len());
                let at = (first, &mut *wave, &mut lead, &state);
                Self::lead(couplings, (inner, rest, border), at, end);
            }
            // A coupling from an earlier block enters the ring as soon as the ring reaches its
            // element, before any coupling of this block does: coupling order.
            if i >= next_entry {
                while let Some(&(b, c)) = incoming.get(next_in) {
                    let j = b as usize - first;
                    if j > i + mask {
                        break;
                    }
                    let mut x = slot(ring, j & mask, S::GROUPED);
                    add(&mut x, &crossing[c as usize][1]);
                    set_slot(ring, j & mask, S::GROUPED, &x);
                    next_in += 1;
                }
                next_entry = entry(next_in);
            }
            // A run, up to the next entry into the ring.
            if C::RUNS && i == run.elements.start {
                let n = run.elements.end.min(next_entry) - i;
                let template = &inner[k..k + run.width];
                let at = (i, &mut *ring, &mut state);
                let lanes_of = (lanes, C::WIDE && run.lanes && (run.aligned || !S::GROUPED));
                match run.width {
                    1 => Self::run::<C, S, 1>(lanes_of, couplings, template, first, at, n),
                    2 => Self::run::<C, S, 2>(lanes_of, couplings, template, first, at, n),
                    3 => Self::run::<C, S, 3>(lanes_of, couplings, template, first, at, n),
                    _ => Self::run::<C, S, MAX_WIDTH>(lanes_of, couplings, template, first, at, n),
                }
                i += n;
                run.elements.start = i;
                if run.elements.is_empty() {
                    k += run.width;
                    run = runs.next().unwrap_or(&none).clone();
                }
                continue;
            }
            // The forces from earlier elements, then this element's own couplings.
            let mut f = take_slot(ring, i & mask, S::GROUPED);
            let ue = *state.u(i);
            while let Some(face) = inner.get(k).filter(|face| face.a as usize == e) {
                // A leading wave has brought them into the cache.
                if C::PREFETCH && !leads {
                    if let Some(ahead) = inner.get(k + PREFETCH_AHEAD) {
                        prefetch(ahead);
                    }
                    if let Some(ahead) = inner.get(k + PREFETCH_AHEAD / 2) {
                        state.prefetch_u(ahead.b as usize - first);
                    }
                }
                k += 1;
                let j = face.b as usize - first;
                let coupling = couplings.coupling(face);
                if S::GROUPED {
                    let mut fb = slot(ring, j & mask, true);
                    couplings.add_pair(lanes, coupling, &ue, &state.u(j), &mut f, &mut fb);
                    set_slot(ring, j & mask, true, &fb);
                } else {
                    let fb = &mut ring[j & mask];
                    couplings.add_pair(lanes, coupling, &ue, &state.u(j), &mut f, fb);
                }
            }
            if e == next_rest {
                while let Some(face) = rest.get(r).filter(|face| face.a as usize == e) {
                    r += 1;
                    if face.b == GROUND {
                        couplings.add_ground(face, &ue, &mut f);
                    } else {
                        add(&mut f, &crossing_out[out][0]);
                        out += 1;
                    }
                }
                next_rest = start(r);
            }
            couplings.add_own(e, &ue, &mut f);
            state.complete(e, i, &mut f);
            i += 1;
        }
    }

    /// Takes a block's leading wave ([`Couplings::leads`]) through its elements up to `end`
    /// (by their index in the block, `first` the block's first element), none of which, nor
    /// any element they couple with, has moved: each element's sum from the wave's ring, its
    /// couplings' shares (to the ring for the higher element), done. The wave leaves
    /// out the couplings to other blocks, and the `border` elements' sums.
    #[inline(always)]
    fn lead<C: Couplings<N>, S: BlockState<N>>(
        couplings: &C,
        (inner, rest, border): (Faces<'_, C::Ref>, Faces<'_, C::Ref>, &[u32]),
        (first, wave, at, state): (usize, &mut [f64], &mut Lead, &S),
        end: usize,
    ) {
        let mask = wave.len() - 1;
        while at.next < end {
            let (i, e) = (at.next, first + at.next);
            let ue = *state.u(i);
            let mut s = std::mem::take(&mut wave[i & mask]);
            while let Some(face) = inner.get(at.inner).filter(|face| face.a as usize == e) {
                if C::PREFETCH {
                    if let Some(ahead) = inner.get(at.inner + PREFETCH_AHEAD) {
                        prefetch(ahead);
                    }
                    if let Some(ahead) = inner.get(at.inner + PREFETCH_AHEAD / 2) {
                        state.prefetch_u(ahead.b as usize - first);
                    }
                }
                at.inner += 1;
                let j = face.b as usize - first;
                let [sa, sb] = couplings.lead_pair(face, &ue, &state.u(j));
                s += sa;
                wave[j & mask] += sb;
            }
            while let Some(face) = rest.get(at.rest).filter(|face| face.a as usize == e) {
                at.rest += 1;
                if face.b == GROUND {
                    s += couplings.lead_ground(face, &ue);
                }
            }
            if border.get(at.border) == Some(&(e as u32)) {
                at.border += 1;
            } else {
                couplings.lead_done(e, s);
            }
            at.next += 1;
        }
    }

    /// `n` elements of a [`Run`] from the block's element `i`, whose couplings are those of
    /// `template` shifted: as the element-by-element sweep, the same arithmetic in the same
    /// order, four elements at a time if `wide` ([`in_lanes`]).
    #[inline(always)]
    fn run<C: Couplings<N>, S: BlockState<N>, const W: usize>(
        (lanes, wide): (impl Lanes, bool),
        couplings: &C,
        template: &[Face<C::Ref>],
        first: usize,
        (i, ring, state): (usize, &mut [[f64; N]], &mut S),
        n: usize,
    ) {
        let mask = ring.len() - 1;
        let ring = &mut ring[..=mask];
        let template: &[Face<C::Ref>; W] = template.try_into().expect("a run's width");
        let reach = template.each_ref().map(|f| (f.b - f.a) as usize);
        let template = template.each_ref().map(|f| couplings.coupling(f));
        let (end, mut i) = (i + n, i);
        if wide {
            // Grouped, the lanes start at a group's first element.
            let lead = if S::GROUPED {
                i.next_multiple_of(4).min(end)
            } else {
                i
            };
            for i in i..lead {
                Self::element(lanes, couplings, &template, &reach, first, (i, ring, state));
            }
            i = lead;
            let n = (end - i) / 4;
            if n > 0 {
                let at = (i, &mut *ring, &mut *state);
                Self::groups(lanes, couplings, &template, &reach, first, at, n);
            }
            i += 4 * n;
        }
        for i in i..end {
            Self::element(lanes, couplings, &template, &reach, first, (i, ring, state));
        }
    }

    /// The block's element `i` of a [`Run`] whose couplings are `template` reaching `reach`
    /// elements ahead.
    #[inline(always)]
    fn element<C: Couplings<N>, S: BlockState<N>, const W: usize>(
        lanes: impl Lanes,
        couplings: &C,
        template: &[C::Coupling<'_>; W],
        reach: &[usize; W],
        first: usize,
        (i, ring, state): (usize, &mut [[f64; N]], &mut S),
    ) {
        let mask = ring.len() - 1;
        let mut f = take_slot(ring, i & mask, S::GROUPED);
        let ue = *state.u(i);
        for (&coupling, reach) in template.iter().zip(reach) {
            let j = (i + reach) & mask;
            let mut fb = slot(ring, j, S::GROUPED);
            couplings.add_pair(lanes, coupling, &ue, &state.u(i + reach), &mut f, &mut fb);
            set_slot(ring, j, S::GROUPED, &fb);
        }
        couplings.add_own(first + i, &ue, &mut f);
        state.complete(first + i, i, &mut f);
    }

    /// `n` times four elements of a run from the block's element `i`, in lanes
    /// ([`Couplings::add_pairs`]): the first coupling reaches the next element, the others
    /// apart ([`in_lanes`]). The next four's `U` and the force their first element gets from
    /// the last of these four stay in registers.
    #[inline(always)]
    fn groups<C: Couplings<N>, S: BlockState<N>, const W: usize>(
        lanes: impl Lanes,
        couplings: &C,
        template: &[C::Coupling<'_>; W],
        reach: &[usize; W],
        first: usize,
        (i, ring, state): (usize, &mut [[f64; N]], &mut S),
        n: usize,
    ) {
        let mask = ring.len() - 1;
        let mut ua = state.wide(lanes, i);
        // Nothing from the four before: `x + (−0)` is `x`.
        let mut carry = [[-0.0; 4]; N];
        for i in (i..i + 4 * n).step_by(4) {
            let mut fa = if S::GROUPED {
                std::mem::replace(&mut ring_groups(ring)[(i & mask) / 4], [[0.0; 4]; N])
            } else {
                let fa = lanes.wide(&slots(ring, i));
                put_slots(ring, i, &[[0.0; N]; 4]);
                fa
            };
            let un = state.wide(lanes, i + 4);
            let ub = lanes.shift(&ua, &un);
            couplings.add_pairs(
                lanes,
                template[0],
                &ua,
                &ub,
                &mut fa,
                Higher::Next(&mut carry),
            );
            for k in 1..W {
                let j = i + reach[k];
                let ub = state.wide(lanes, j);
                if S::GROUPED {
                    let fb = &mut ring_groups(ring)[(j & mask) / 4];
                    let fb = Higher::ApartWide(fb);
                    couplings.add_pairs(lanes, template[k], &ua, &ub, &mut fa, fb);
                } else {
                    let mut fb = slots(ring, j);
                    let apart = Higher::Apart(&mut fb);
                    couplings.add_pairs(lanes, template[k], &ua, &ub, &mut fa, apart);
                    put_slots(ring, j, &fb);
                }
            }
            if C::OWN {
                for l in 0..4 {
                    let mut f = lane(&fa, l);
                    couplings.add_own(first + i + l, &lane(&ua, l), &mut f);
                    set_lane(&mut fa, l, &f);
                }
            }
            state.complete_wide(lanes, first + i, i, &fa);
            ua = un;
        }
        // The element after the groups: its pending force, then the last pair's.
        let s = (i + 4 * n) & mask;
        let mut after = slot(ring, s, S::GROUPED);
        for j in 0..N {
            after[j] += carry[j][0];
        }
        set_slot(ring, s, S::GROUPED, &after);
    }

    /// `f_int(u)` swept by the plain build, block after block (tests: the AVX2 sweep gives its
    /// bits).
    #[cfg(test)]
    pub(super) fn evaluate_plain(&self, couplings: &impl Couplings<N>, u: &[f64]) -> Vec<f64> {
        let mut f = vec![0.0; u.len()];
        let (u, _) = u.as_chunks::<N>();
        let (fc, _) = f.as_chunks_mut::<N>();
        let mut scratch = self.crossing_pass(couplings, |e| u[e]);
        let Scratch {
            crossing, rings, ..
        } = &mut *scratch;
        for (block, ring) in self.blocks.iter().zip(rings.iter_mut()) {
            let r = block.elements.clone();
            let state = Evaluate {
                u: &u[r.clone()],
                f: &mut fc[r],
            };
            self.sweep_in_order(Plain, couplings, block, crossing, ring, state);
        }
        drop(scratch);
        f
    }
}

/// Couplings in sweep order.
type Faces<'a, R> = &'a [Face<R>];

/// Where a block's leading wave is ([`Sweep::lead`]): its next element (in the block), and
/// the next of its inner couplings, of the others, and of its border elements.
#[derive(Default)]
struct Lead {
    next: usize,
    inner: usize,
    rest: usize,
    border: usize,
}

/// [`Sweep::sweep_in_order`] as the task that AVX2 code runs: a closure would not be inlined
/// into it when large (a hybrid sweep), and then calls its vector instructions one by one.
#[cfg(target_arch = "x86_64")]
struct InOrder<'a, C, S, const N: usize> {
    sweep: &'a Sweep<N>,
    simd: pulp::x86::V3,
    couplings: &'a C,
    block: &'a Block,
    crossing: &'a [[[f64; N]; 2]],
    ring: &'a mut Ring<N>,
    state: S,
}

#[cfg(target_arch = "x86_64")]
impl<C: Couplings<N>, S: BlockState<N>, const N: usize> pulp::NullaryFnOnce
    for InOrder<'_, C, S, N>
{
    type Output = ();
    #[inline(always)]
    fn call(self) {
        let InOrder {
            sweep,
            simd,
            couplings,
            block,
            crossing,
            ring,
            state,
        } = self;
        sweep.sweep_in_order(simd, couplings, block, crossing, ring, state)
    }
}

/// Asks the cache for `x` ahead of its use: a hint, with no effect on any result (a no-op off
/// x86-64).
#[inline(always)]
fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    safe_arch::prefetch_t0(x);
}

/// The ring's slots in groups of four, as `U` in a grouped step ([`BlockState::GROUPED`]);
/// a ring has a multiple of four slots.
#[inline(always)]
fn ring_groups<const N: usize>(ring: &mut [[f64; N]]) -> &mut [Wide<N>] {
    as_groups_mut(ring.as_flattened_mut())
}

/// Ring slot `s`, of a ring in groups if `grouped`.
#[inline(always)]
fn slot<const N: usize>(ring: &mut [[f64; N]], s: usize, grouped: bool) -> [f64; N] {
    match grouped {
        true => lane(&ring_groups(ring)[s / 4], s % 4),
        false => ring[s],
    }
}

/// Sets ring slot `s`, of a ring in groups if `grouped`.
#[inline(always)]
fn set_slot<const N: usize>(ring: &mut [[f64; N]], s: usize, grouped: bool, x: &[f64; N]) {
    match grouped {
        true => set_lane(&mut ring_groups(ring)[s / 4], s % 4, x),
        false => ring[s] = *x,
    }
}

/// Ring slot `s`, left zero.
#[inline(always)]
fn take_slot<const N: usize>(ring: &mut [[f64; N]], s: usize, grouped: bool) -> [f64; N] {
    let x = slot(ring, s, grouped);
    set_slot(ring, s, grouped, &[0.0; N]);
    x
}

/// Ring slots `s..s + 4`.
#[inline(always)]
fn slots<const N: usize>(ring: &[[f64; N]], s: usize) -> [[f64; N]; 4] {
    let (mask, s) = (ring.len() - 1, s & (ring.len() - 1));
    match ring.get(s..s + 4) {
        Some(four) => four.try_into().expect("four slots"),
        None => std::array::from_fn(|l| ring[(s + l) & mask]),
    }
}

/// Sets ring slots `s..s + 4`.
#[inline(always)]
fn put_slots<const N: usize>(ring: &mut [[f64; N]], s: usize, x: &[[f64; N]; 4]) {
    let (mask, s) = (ring.len() - 1, s & (ring.len() - 1));
    match ring.get_mut(s..s + 4) {
        Some(four) => four.copy_from_slice(x),
        None => (0..4).for_each(|l| ring[(s + l) & mask] = x[l]),
    }
}

#[inline(always)]
fn add<const N: usize>(acc: &mut [f64; N], x: &[f64; N]) {
    for j in 0..N {
        acc[j] += x[j];
    }
}

/// The state a sweep reads `U` from, and what it does with an element whose force is complete.
trait BlockState<const N: usize> {
    /// Whether `U` is stored in groups of four elements ([`crate::lanes::grouped`]): a
    /// [`Run`] then goes in lanes from a group's first element.
    const GROUPED: bool = false;
    /// Element `i`'s `U`: a reference where the state holds the element's DOFs together.
    type U<'s>: std::ops::Deref<Target = [f64; N]>
    where
        Self: 's;
    fn u(&self, i: usize) -> Self::U<'_>;
    /// Asks the cache for element `i`'s `U` ([`prefetch`]).
    fn prefetch_u(&self, i: usize);
    /// Elements `i..i + 4` in lanes.
    fn wide(&self, lanes: impl Lanes, i: usize) -> Wide<N>;
    /// Element `e` (index `i` in the block) has its whole internal force `f`.
    fn complete(&mut self, e: usize, i: usize, f: &mut [f64; N]);
    /// Elements `e..e + 4` (`i..i + 4` in the block) have their whole internal forces `f`, in
    /// lanes: as four calls of [`BlockState::complete`] in order.
    #[inline(always)]
    fn complete_wide(&mut self, lanes: impl Lanes, e: usize, i: usize, f: &Wide<N>) {
        for (l, mut f) in lanes.narrow(f).into_iter().enumerate() {
            self.complete(e + l, i + l, &mut f);
        }
    }
}

/// An evaluation: `U` is only read, and each force is written once.
struct Evaluate<'a, const N: usize> {
    u: &'a [[f64; N]],
    f: &'a mut [[f64; N]],
}

impl<const N: usize> BlockState<N> for Evaluate<'_, N> {
    type U<'s>
        = &'s [f64; N]
    where
        Self: 's;
    #[inline(always)]
    fn u(&self, i: usize) -> &[f64; N] {
        &self.u[i]
    }
    #[inline(always)]
    fn prefetch_u(&self, i: usize) {
        prefetch(&self.u[i]);
    }
    #[inline(always)]
    fn wide(&self, lanes: impl Lanes, i: usize) -> Wide<N> {
        lanes.wide(self.u[i..i + 4].try_into().expect("four elements"))
    }
    #[inline(always)]
    fn complete(&mut self, _: usize, i: usize, f: &mut [f64; N]) {
        self.f[i] = *f;
    }
}

/// A time step: a complete element gets the rest of its net force from `force`, is advanced,
/// and leaves its part of `force` zero.
struct Advance<'a, const N: usize, E> {
    u: &'a mut [[f64; N]],
    v: &'a mut [[f64; N]],
    /// The block's part of `−P − f_c`.
    force: &'a mut [[f64; N]],
    /// The elements where `force` may not be zero.
    loaded: Loaded<'a>,
    /// The block's update ([`Update::resolve`]).
    update: E,
    /// The damping's power of the block's elements, summed in order (damped updates only).
    power: &'a mut f64,
}

impl<const N: usize, E: ElementUpdate<N>> BlockState<N> for Advance<'_, N, E> {
    type U<'s>
        = &'s [f64; N]
    where
        Self: 's;
    #[inline(always)]
    fn u(&self, i: usize) -> &[f64; N] {
        &self.u[i]
    }
    #[inline(always)]
    fn prefetch_u(&self, i: usize) {
        prefetch(&self.u[i]);
    }
    #[inline(always)]
    fn wide(&self, lanes: impl Lanes, i: usize) -> Wide<N> {
        lanes.wide(self.u[i..i + 4].try_into().expect("four elements"))
    }
    #[inline(always)]
    fn complete(&mut self, e: usize, i: usize, f: &mut [f64; N]) {
        if self.loaded.take(e) {
            let p = std::mem::replace(&mut self.force[i], [0.0; N]);
            for j in 0..N {
                f[j] += p[j];
            }
        }
        let power = self.update.element(i, f, &mut self.v[i], &mut self.u[i]);
        if E::DAMPED {
            *self.power += power;
        }
    }

    /// Four at once unless one of them is loaded.
    #[inline(always)]
    fn complete_wide(&mut self, lanes: impl Lanes, e: usize, i: usize, f: &Wide<N>) {
        let f = lanes.narrow(f);
        if self.loaded.any_before(e + 4) {
            for (l, mut f) in f.into_iter().enumerate() {
                self.complete(e + l, i + l, &mut f);
            }
            return;
        }
        let v: &mut [[f64; N]; 4] = (&mut self.v[i..i + 4]).try_into().expect("four elements");
        let u: &mut [[f64; N]; 4] = (&mut self.u[i..i + 4]).try_into().expect("four elements");
        let powers = self.update.elements(lanes, i, &f, v, u);
        if E::DAMPED {
            for p in powers {
                *self.power += p;
            }
        }
    }
}

/// An element's DOFs taken out of their lanes ([`AdvanceGrouped::u`]).
struct Lane<const N: usize>([f64; N]);

impl<const N: usize> std::ops::Deref for Lane<N> {
    type Target = [f64; N];
    #[inline(always)]
    fn deref(&self) -> &[f64; N] {
        &self.0
    }
}

/// A time step as [`Advance`], lumped and undamped, on `U`, `v` and `M⁻¹` in groups of four
/// elements ([`crate::lanes::grouped`]): the block starts a group, and four elements that
/// start one are advanced in lanes with no transpose, by the arithmetic of
/// [`ElementUpdate::elements`].
struct AdvanceGrouped<'a, const N: usize> {
    u: &'a mut [Wide<N>],
    v: &'a mut [Wide<N>],
    inv: &'a [Wide<N>],
    /// The block's part of `−P`, element by element.
    force: &'a mut [[f64; N]],
    loaded: Loaded<'a>,
    dt: f64,
}

impl<const N: usize> BlockState<N> for AdvanceGrouped<'_, N> {
    const GROUPED: bool = true;
    type U<'s>
        = Lane<N>
    where
        Self: 's;
    #[inline(always)]
    fn u(&self, i: usize) -> Lane<N> {
        Lane(lane(&self.u[i / 4], i % 4))
    }
    #[inline(always)]
    fn prefetch_u(&self, i: usize) {
        prefetch(&self.u[i / 4]);
    }
    /// Only from a group's first element ([`Run`]'s `aligned`).
    #[inline(always)]
    fn wide(&self, _: impl Lanes, i: usize) -> Wide<N> {
        debug_assert!(i.is_multiple_of(4), "four elements from a group's first");
        self.u[i / 4]
    }
    /// [`Advance::complete`] of a lumped, undamped update, in the element's lanes.
    #[inline(always)]
    fn complete(&mut self, e: usize, i: usize, f: &mut [f64; N]) {
        if self.loaded.take(e) {
            let p = std::mem::replace(&mut self.force[i], [0.0; N]);
            for j in 0..N {
                f[j] += p[j];
            }
        }
        let (g, l) = (i / 4, i % 4);
        let (u, v, w) = (&mut self.u[g], &mut self.v[g], &self.inv[g]);
        for j in 0..N {
            v[j][l] -= self.dt * w[j][l] * f[j];
            u[j][l] += self.dt * v[j][l];
        }
    }
    /// Only from a group's first element ([`Run`]'s `aligned`).
    #[inline(always)]
    fn complete_wide(&mut self, lanes: impl Lanes, e: usize, i: usize, f: &Wide<N>) {
        debug_assert!(i.is_multiple_of(4), "four elements from a group's first");
        if self.loaded.any_before(e + 4) {
            for (l, mut f) in lanes.narrow(f).into_iter().enumerate() {
                self.complete(e + l, i + l, &mut f);
            }
            return;
        }
        let g = i / 4;
        let (u, v, w) = (&mut self.u[g], &mut self.v[g], &self.inv[g]);
        lumped_update(lanes, self.dt, f, w, v, u);
    }
}

/// The elements of a block, in order, where `−P − f_c` may not be zero, for each element to
/// ask in turn with one comparison: most are not loaded.
struct Loaded<'a> {
    /// The next of them, or `usize::MAX`.
    next: usize,
    rest: &'a [u32],
    /// Any element may be loaded (`next` is then `usize::MAX`).
    every: bool,
}

impl<'a> Loaded<'a> {
    /// `None`: every element.
    fn new(loaded: Option<&'a [u32]>) -> Self {
        let rest = loaded.unwrap_or(&[]);
        Loaded {
            next: Self::first(rest),
            rest,
            every: loaded.is_none(),
        }
    }

    fn first(rest: &[u32]) -> usize {
        rest.first().map_or(usize::MAX, |&x| x as usize)
    }

    /// Whether an element before `e` may be loaded, of those not asked for yet.
    #[inline(always)]
    fn any_before(&self, e: usize) -> bool {
        self.every || self.next < e
    }

    /// Whether element `e` may be loaded; `e` grows from call to call.
    #[inline(always)]
    fn take(&mut self, e: usize) -> bool {
        if e == self.next {
            self.rest = self.rest.split_first().map_or(&[], |(_, rest)| rest);
            self.next = Self::first(self.rest);
            return true;
        }
        self.every
    }
}

/// A block's time step, waiting for its update to be resolved.
struct AdvanceBlock<'a, C, const N: usize> {
    sweep: &'a Sweep<N>,
    couplings: &'a C,
    block: &'a Block,
    crossing: &'a [[[f64; N]; 2]],
    ring: &'a mut Ring<N>,
    u: &'a mut [[f64; N]],
    v: &'a mut [[f64; N]],
    force: &'a mut [[f64; N]],
    loaded: Option<&'a [u32]>,
    power: &'a mut f64,
}

impl<C: Couplings<N>, const N: usize> WithUpdate<N> for AdvanceBlock<'_, C, N> {
    fn run<E: ElementUpdate<N>>(self, update: E) {
        let AdvanceBlock {
            sweep,
            couplings,
            block,
            crossing,
            ring,
            u,
            v,
            force,
            loaded,
            power,
        } = self;
        *power = 0.0;
        let state = Advance {
            u,
            v,
            force,
            loaded: Loaded::new(loaded),
            update,
            power,
        };
        sweep.sweep(couplings, block, crossing, ring, state);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Springs of stiffness `1 + 0.37 k` on both DOFs between two elements, `k` the record;
    /// springs to the ground; an own term that depends on the element.
    struct Springs(Vec<Face<u32>>);

    impl Couplings<2> for Springs {
        type Ref = u32;
        const PREFETCH: bool = false;
        const RUNS: bool = true;
        const WIDE: bool = true;
        fn faces(&self) -> &[Face<u32>] {
            &self.0
        }
        type Coupling<'a> = u32;
        fn coupling<'a>(&'a self, face: &'a Face<u32>) -> u32 {
            face.record
        }
        fn add_pair(
            &self,
            _: impl Lanes,
            k: u32,
            ua: &[f64; 2],
            ub: &[f64; 2],
            fa: &mut [f64; 2],
            fb: &mut [f64; 2],
        ) {
            for j in 0..2 {
                let t = (1.0 + 0.37 * k as f64) * (ub[j] - ua[j]);
                fa[j] -= t;
                fb[j] += t;
            }
        }
        fn add_ground(&self, face: &Face<u32>, ua: &[f64; 2], fa: &mut [f64; 2]) {
            for j in 0..2 {
                fa[j] += (1.0 + face.record as f64) * ua[j];
            }
        }
        fn add_own(&self, e: usize, ue: &[f64; 2], f: &mut [f64; 2]) {
            f[0] += 1e-3 * e as f64 * ue[1];
        }
    }

    /// Runs go in lanes when their first coupling reaches the next element and the others
    /// five or more, four apart, within the ring with four slots to spare: at the edges, and
    /// one step past them.
    #[test]
    fn a_run_goes_in_lanes_when_its_reaches_leave_room() {
        for (reach, ring, lanes) in [
            (&[1, 5][..], 16, true),
            (&[1, 4], 16, false),
            (&[1, 12], 16, true),
            (&[1, 13], 16, false),
            (&[1, 5, 9], 16, true),
            (&[1, 5, 8], 16, false),
            (&[1, 5, 9, 13, 17], 32, true),
            (&[2, 8], 16, false),
            (&[1], 16, false),
        ] {
            assert_eq!(in_lanes(reach, ring), lanes, "{reach:?} in {ring} slots");
        }
    }

    /// Stretches of elements whose couplings repeat, of widths 0 to 5, next to stretches of
    /// the same reaches with another record, with couplings to the ground now and then, over
    /// three blocks, and couplings from one block into the next that enter its ring inside
    /// runs: runs are found for widths 1 to 4, some of them in lanes, and never span a change of
    /// record, and the sweep through them gives the bits of the element-by-element sweep.
    #[test]
    fn runs_of_every_width_give_the_bits_of_each_element() {
        let n = 10_000;
        let mut faces = Vec::new();
        // Element `e` lies in stretch `e / 37`, which fixes its width, its reaches and its
        // record; neighbouring stretches of the same width differ in their record only.
        // Reaches that may go in lanes (`in_lanes`) in every other group of 12 stretches.
        let stretch = |e: usize| {
            let s = e / 37;
            let reaches = match s / 12 % 2 {
                0 => [1, 3, 8, 61, 200],
                _ => [1, 8, 61, 200, 3],
            };
            (s / 2 % 6, reaches, (s % 2) as u32)
        };
        for e in 0..n {
            let (width, reaches, record) = stretch(e);
            for &r in &reaches[..width] {
                if e + r < n {
                    let (a, b) = (e as u32, (e + r) as u32);
                    faces.push(Face { a, b, record });
                }
            }
            if e % 101 == 0 {
                let (a, b, record) = (e as u32, GROUND, 2);
                faces.push(Face { a, b, record });
            }
            // Into the next block, past its ring: these enter it midway, in its runs.
            if (e + 600) / 4096 > e / 4096 && e % 13 == 0 && e + 600 < n {
                let (a, b, record) = (e as u32, (e + 600) as u32, 3);
                faces.push(Face { a, b, record });
            }
        }
        let mut each_faces = faces.clone();
        let each = Sweep::<2>::new(n, &mut each_faces, false);
        let mut run_faces = faces;
        let mut runs = Sweep::<2>::new(n, &mut run_faces, false);
        runs.find_runs(&mut run_faces);
        assert!(runs.blocks.len() >= 3 && !runs.crossing.is_empty());
        let (_, _, entries, in_lanes) = runs.run_elements();
        assert!(
            in_lanes > 5,
            "{entries} entries in runs, {in_lanes} in runs in lanes"
        );
        // Widths 0 to 4 in runs keep the couplings of one element in 37; width 5 keeps all.
        assert!(
            2 * run_faces.len() < each_faces.len(),
            "the runs keep few couplings"
        );
        for width in 1..=MAX_WIDTH {
            let found = runs.blocks.iter().flat_map(|b| &b.runs);
            let (wide, one_by_one) = found
                .filter(|r| r.width == width)
                .fold((0, 0), |(w, o), r| {
                    (w + r.lanes as usize, o + !r.lanes as usize)
                });
            assert!(wide + one_by_one > 10, "width {width}");
            assert!(width == 1 || wide > 5, "width {width} in lanes: {wide}");
            assert!(one_by_one > 5, "width {width} one by one: {one_by_one}");
        }
        for block in &runs.blocks {
            for run in &block.runs {
                let es = run.elements.clone().map(|i| block.elements.start + i);
                let (first, last) = (es.clone().min().unwrap(), es.max().unwrap());
                assert_eq!(stretch(first), stretch(last), "a run spans two stretches");
            }
        }
        let u: Vec<f64> = (0..2 * n)
            .map(|i| ((i * 7919) % 1000) as f64 * 1e-3)
            .collect();
        let (mut f_each, mut f_runs) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
        each.evaluate(&Springs(each_faces), &u, &mut f_each);
        runs.evaluate(&Springs(run_faces), &u, &mut f_runs);
        assert!(f_each.iter().any(|&f| f != 0.0));
        assert!(
            f_each
                .iter()
                .zip(&f_runs)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "runs give other bits"
        );
    }
}

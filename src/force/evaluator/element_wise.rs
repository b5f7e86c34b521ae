//! The element-wise evaluator (eqs. 15–16): each element's force is the resultant of the
//! tractions `λ = diag(k_n', k_s') δ` on its own edges, integrated by the edge's 2-point Gauss
//! rule, with `(k_n', k_s')` the springs of the model's linear interface law (eq. 11,
//! [`crate::model::law`]). No global matrix.
//!
//! The two Gauss points of an edge sit at `m ± g` about its midpoint `m`, with
//! `g = L/(2√3) s` along the edge. The displacement jump is affine along the edge,
//! `δ(m ± g) = δ₀ ± δ₁`, and the traction linear in it, so the rule's sum
//! `Σ± N_e(m ± g)ᵀ λ(m ± g) t L/2` splits exactly into
//! `t L [N_e(m)ᵀ λ(δ₀) + (N_e(g) − N_e(0))ᵀ λ(δ₁)]`: the same quadrature in half the work.
//! The split holds for a linear law only.
//!
//! The traction on a shared edge is one physical quantity, `+λ` on one side and `−λ` on the
//! other, so each interface computes it once and hands it to both its elements. The interfaces
//! are kept in the order of their lower element `a < b`; a sweep in that order has finished
//! element `e` once it has done the interfaces that start at `e` (those that end at `e` started
//! earlier). The element's force is then complete and, in a time step, its velocity and
//! displacement are advanced at once ([`ElementWise`] fuses eq. 15 with the update of
//! [`crate::step::integrator`]): `U_e` is read by no later interface, and the step moves each
//! vector once.
//!
//! While it sweeps, an element's force is pending only from its first interface to its own
//! completion, and an interface reaches at most `max(b − a)` elements ahead. The pending forces
//! are therefore kept in a ring of the next power of two above that reach, which stays in
//! cache (a 1000 × 1000 grid needs 1024 slots): no global force vector is read or written.
//! An element takes its pending force from the ring when the sweep reaches it and adds its own
//! interfaces in registers. The records of a block's inner interfaces lie apart from those to
//! the ground and to later blocks, which are rare and need no test in the inner loop.
//! A time step reads the rest of the net force, `−P − f_c`, only at the elements that carry
//! loads when the integrator can name them (no gravity, no contact).
//!
//! Each interface has a [`Record`] of what its traction needs. On a regular mesh most records
//! are copies of a few, equal up to the round-off of the coordinates; then the interfaces share
//! them ([`Shared`], [`share_key`]) and a step reads 12 bytes per interface instead of 72 (80
//! hybrid). A shared record is then also formed, once, into its interface's linear map
//! ([`FaceMap`]: 4 × 4 rigid, 10 × 10 hybrid), which the sweep applies in 4-wide lanes with
//! fewer instructions than the record takes. An irregular mesh keeps its records inline
//! ([`Inline`]): a map per interface would double the bytes a step reads.
//!
//! Parallel sweeps run over fixed blocks of consecutive elements. An interface from one block
//! into a later one is computed before the sweeps, from the state at `t_n`, and handed to both
//! blocks. Every element sums its edges in interface order whatever the blocks and the threads,
//! so the result does not depend on the thread count.

use super::{Evaluator, FusedStep};
use crate::input::scene::EvaluatorKind;
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Hybrid, Kinematics, Rigid, Springs};
use crate::model::mass::{ElementUpdate, Update, WithUpdate};
use crate::model::{Model, GROUND};
use rayon::prelude::*;
use std::marker::PhantomData;
use std::ops::Range;
use std::sync::Mutex;

/// What an interface's traction needs besides its elements (64 bytes rigid, 72 hybrid).
#[derive(Debug)]
pub struct Record<K: Kinematics<N>, const N: usize> {
    /// The edge's midpoint from the centroids of `a` and `b` (m; `db` unused on ground).
    da: Vec2,
    db: Vec2,
    /// The springs times thickness and the rule's total weight, `t L S` (N/m).
    springs: Springs,
    /// What the odd part of the edge's Gauss rule needs, from the Gauss offset
    /// `g = L/(2√3) s` along the edge ([`Kinematics::EdgeOdd`]).
    odd: K::EdgeOdd,
}

// Derived, these would ask `K` itself to be `Copy`.
impl<K: Kinematics<N>, const N: usize> Clone for Record<K, N> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<K: Kinematics<N>, const N: usize> Copy for Record<K, N> {}

/// An interface: its lower element `a`, its higher one `b` or [`GROUND`], and its record `R`:
/// the [`Record`] itself, or its index among records that several interfaces share
/// ([`Shared`]).
#[derive(Debug, Clone, Copy)]
struct Face<R> {
    a: u32,
    b: u32,
    record: R,
}

/// The interfaces with their records, in the order of the sweep.
trait Faces<K: Kernel<N>, const N: usize>: Sync {
    /// What a [`Face`] holds of its record.
    type Ref: Copy + Sync;
    /// Whether the sweep asks for the records and `U` ahead of their use ([`PREFETCH_AHEAD`]):
    /// inline records stream at 72 bytes per interface, shared ones at 12, which the hardware
    /// prefetchers follow unaided (10⁶-element grid, one thread: 14.1 ns per element-step
    /// without, 15.5 with, measured before the [`FaceMap`]s, which left the two within the
    /// noise; `cargo bench --bench step -- grid/rigid/element-wise/1thr` on both builds).
    const PREFETCH: bool;
    fn faces(&self) -> &[Face<Self::Ref>];
    fn record<'a>(&'a self, face: &'a Face<Self::Ref>) -> &'a Record<K, N>;
    /// Adds the internal forces of `face`, between two elements, to `fa` and `fb`.
    fn add_internal(
        &self,
        lanes: impl Lanes,
        face: &Face<Self::Ref>,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    );
}

/// Each interface with its own record (72 bytes rigid, 80 hybrid): an irregular mesh, where
/// interfaces rarely share one.
type Inline<K, const N: usize> = Vec<Face<Record<K, N>>>;

impl<K: Kernel<N>, const N: usize> Faces<K, N> for Inline<K, N> {
    type Ref = Record<K, N>;
    const PREFETCH: bool = true;
    #[inline(always)]
    fn faces(&self) -> &[Face<Record<K, N>>] {
        self
    }
    #[inline(always)]
    fn record<'a>(&'a self, face: &'a Face<Record<K, N>>) -> &'a Record<K, N> {
        &face.record
    }
    #[inline(always)]
    fn add_internal(
        &self,
        lanes: impl Lanes,
        face: &Face<Record<K, N>>,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        let _ = lanes;
        let [on_a, on_b] = ElementWise::face_forces(&face.record, ua, Some(ub));
        sub(fa, &on_a);
        sub(fb, &on_b);
    }
}

/// Interfaces of 12 bytes that name one of few records: a regular mesh, whose interfaces are
/// copies of a handful (a grid's inner ones are of two kinds). The records stay in cache and a
/// step reads 12 bytes per interface instead of 72 (80 hybrid).
struct Shared<K: Kernel<N>, const N: usize> {
    faces: Vec<Face<u32>>,
    records: Vec<Record<K, N>>,
    /// Each record's [`FaceMap`].
    maps: Vec<K::Map>,
}

impl<K: Kernel<N>, const N: usize> Faces<K, N> for Shared<K, N> {
    type Ref = u32;
    const PREFETCH: bool = false;
    #[inline(always)]
    fn faces(&self) -> &[Face<u32>] {
        &self.faces
    }
    #[inline(always)]
    fn record<'a>(&'a self, face: &'a Face<u32>) -> &'a Record<K, N> {
        &self.records[face.record as usize]
    }
    #[inline(always)]
    fn add_internal(
        &self,
        lanes: impl Lanes,
        face: &Face<u32>,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        self.maps[face.record as usize].add_internal(lanes, ua, ub, fa, fb);
    }
}

/// What the sweep needs of the kinematics `K` besides [`Kinematics`]: the size of the
/// [`FaceMap`] of its interfaces with shared records.
pub trait Kernel<const N: usize>: Kinematics<N> + Sized {
    /// The interface map of `K`: `M = 2N − 2` inputs, outputs in `Q` groups of four lanes.
    type Map: Map<N>;
}

/// A rigid interface: 4 inputs, 4 outputs, `(Δu, Δv, θ_a, θ_b) ↦ (T, m_a, m_b)`.
impl Kernel<3> for Rigid {
    type Map = FaceMap<4, 1>;
}

/// A hybrid interface: 10 inputs, 10 outputs in three groups of four (two lanes unused).
impl Kernel<6> for Hybrid {
    type Map = FaceMap<10, 3>;
}

/// An interface's internal forces as one linear map of `M` inputs
/// `x = (u_b − u_a)[0..2], u_a[2..N], u_b[2..N]` (the jump of the translations, then the
/// other DOFs of each side) to `M` outputs `o = (f_a[0..N], f_b[2..N])`, with
/// `f_b[0..2] = −f_a[0..2]`; `M = 2N − 2`. Column `k` holds the outputs of input `k`: the
/// forces of [`ElementWise::face_forces`] for that unit input, so the map is that function,
/// formed once per shared record. Applied, it is `M` products of `4Q` lanes and no shuffles
/// (rigid: 4 × 4; `Q` groups of four lanes hold the outputs, the last padded with zeros).
#[derive(Debug, Clone, Copy)]
pub struct FaceMap<const M: usize, const Q: usize>([[[f64; 4]; Q]; M]);

/// [`FaceMap`] for `N` DOFs per element.
pub trait Map<const N: usize>: Copy + Send + Sync {
    /// The map of the interface with `record`.
    fn new<K: Kernel<N>>(record: &Record<K, N>) -> Self;
    /// Adds the internal forces of the interface between elements with DOFs `ua` and `ub`
    /// to `fa` and `fb`.
    fn add_internal(
        &self,
        lanes: impl Lanes,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    );
}

impl<const N: usize, const M: usize, const Q: usize> Map<N> for FaceMap<M, Q> {
    fn new<K: Kernel<N>>(record: &Record<K, N>) -> Self {
        debug_assert!(M == 2 * N - 2 && M <= 4 * Q, "{M} inputs, {Q} lane groups");
        FaceMap(std::array::from_fn(|k| {
            // The unit input `k`: a translation of `b`, or another DOF of `a`, or of `b`.
            let (mut ua, mut ub) = ([0.0; N], [0.0; N]);
            match k {
                0 | 1 => ub[k] = 1.0,
                _ if k < N => ua[k] = 1.0,
                _ => ub[k + 2 - N] = 1.0,
            }
            let [on_a, on_b] = ElementWise::face_forces(record, &ua, Some(&ub));
            let mut column = [[0.0; 4]; Q];
            let lanes = column.as_flattened_mut();
            lanes[..N].copy_from_slice(&on_a);
            lanes[N..M].copy_from_slice(&on_b[2..]);
            column
        }))
    }

    #[inline(always)]
    fn add_internal(
        &self,
        lanes: impl Lanes,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        let x: [f64; M] = std::array::from_fn(|k| match k {
            0 | 1 => ub[k] - ua[k],
            _ if k < N => ua[k],
            _ => ub[k + 2 - N],
        });
        let o = lanes.combine(&self.0, &x);
        let o = o.as_flattened();
        // The sweep accumulates `f_int`, the negated forces the springs put on the elements.
        for j in 0..N {
            fa[j] -= o[j];
        }
        fb[0] += o[0];
        fb[1] += o[1];
        for j in 2..N {
            fb[j] -= o[N + j - 2];
        }
    }
}

/// Sums of products in groups of four lanes, `o = Σ_k x_k g[k]` in the order of `k`, with no
/// fused multiply-add: the same bits on every path.
pub trait Lanes: Copy {
    fn combine<const M: usize, const Q: usize>(
        self,
        g: &[[[f64; 4]; Q]; M],
        x: &[f64; M],
    ) -> [[f64; 4]; Q];
}

/// [`Lanes`] one number at a time, on any processor.
#[derive(Clone, Copy)]
pub struct Plain;

impl Lanes for Plain {
    #[inline(always)]
    fn combine<const M: usize, const Q: usize>(
        self,
        g: &[[[f64; 4]; Q]; M],
        x: &[f64; M],
    ) -> [[f64; 4]; Q] {
        let mut o = [[0.0; 4]; Q];
        for q in 0..Q {
            for l in 0..4 {
                o[q][l] = g[0][q][l] * x[0];
            }
        }
        for k in 1..M {
            for q in 0..Q {
                for l in 0..4 {
                    o[q][l] += g[k][q][l] * x[k];
                }
            }
        }
        o
    }
}

/// [`Lanes`] in the 256-bit registers of AVX2.
#[cfg(target_arch = "x86_64")]
impl Lanes for pulp::x86::V3 {
    #[inline(always)]
    fn combine<const M: usize, const Q: usize>(
        self,
        g: &[[[f64; 4]; Q]; M],
        x: &[f64; M],
    ) -> [[f64; 4]; Q] {
        let mut o = [[0.0; 4]; Q];
        let x0 = self.splat_f64x4(x[0]);
        for q in 0..Q {
            o[q] = pulp::cast(self.mul_f64x4(pulp::cast(g[0][q]), x0));
        }
        for k in 1..M {
            let xk = self.splat_f64x4(x[k]);
            for q in 0..Q {
                let term = self.mul_f64x4(pulp::cast(g[k][q]), xk);
                o[q] = pulp::cast(self.add_f64x4(pulp::cast(o[q]), term));
            }
        }
        o
    }
}

/// How the evaluator stores its interfaces: shared records when at most half the interfaces
/// have a record of their own.
enum Store<K: Kernel<N>, const N: usize> {
    Inline(Inline<K, N>),
    Shared(Shared<K, N>),
}

/// Which interfaces may share a record: the same key means equal records up to the
/// coordinates' round-off. The offsets and the Gauss offset are compared in units of the
/// edge's length, the normal as is, the springs in units of the normal spring; each to
/// `2⁻⁴⁰` (about 1e-12), the length and the normal spring to their leading 40 bits. The
/// geometry of a grid carries round-off of order `ε |x| / h` (2e-13 on a 1000 × 1000 unit
/// grid), so its copies of one cell differ in their last bits; one of them stands for all.
fn share_key(da: Vec2, db: Vec2, g: Vec2, normal: Vec2, length: f64, k: [f64; 2]) -> [i64; 11] {
    const UNIT: f64 = (1u64 << 40) as f64;
    let q = |x: f64, scale: f64| (x / scale * UNIT).round() as i64;
    let lead = |x: f64| (x.to_bits() >> 12) as i64;
    [
        lead(length),
        lead(k[0]),
        q(da.x, length),
        q(da.y, length),
        q(db.x, length),
        q(db.y, length),
        q(g.x, length),
        q(g.y, length),
        q(normal.x, 1.0),
        q(normal.y, 1.0),
        q(k[1], k[0]),
    ]
}

/// Interfaces from which records may be shared. Fewer interfaces keep theirs inline, exact to
/// the bit: their records (1.2 MB rigid at this count) stay in the caches, so sharing would
/// save no memory traffic.
const SHARE_FROM: usize = 1 << 14;

impl<K: Kernel<N>, const N: usize> Store<K, N> {
    /// The interfaces in sweep order, each naming its index in `records` and `keys`: shared
    /// records when there are [`SHARE_FROM`] interfaces or more and at most half of them need
    /// one of their own, else inline.
    fn new(
        faces: Vec<Face<u32>>,
        records: &[Record<K, N>],
        keys: &[[i64; 11]],
        share: bool,
    ) -> Self {
        let inline = |faces: &[Face<u32>]| {
            let inline = faces.iter().map(|f| Face {
                a: f.a,
                b: f.b,
                record: records[f.record as usize],
            });
            Store::Inline(inline.collect())
        };
        if !share || faces.len() < SHARE_FROM {
            return inline(&faces);
        }
        let mut index = std::collections::HashMap::new();
        let mut shared = Vec::new();
        let mut links = Vec::with_capacity(faces.len());
        for f in &faces {
            let k = f.record as usize;
            let record = *index.entry(keys[k]).or_insert_with(|| {
                shared.push(records[k]);
                shared.len() as u32 - 1
            });
            if 2 * shared.len() > faces.len() {
                return inline(&faces);
            }
            links.push(Face {
                a: f.a,
                b: f.b,
                record,
            });
        }
        Store::Shared(Shared {
            faces: links,
            maps: shared.iter().map(K::Map::new).collect(),
            records: shared,
        })
    }

    fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        match self {
            Store::Inline(faces) => size_of_val(&faces[..]),
            Store::Shared(s) => {
                size_of_val(&s.faces[..]) + size_of_val(&s.records[..]) + size_of_val(&s.maps[..])
            }
        }
    }
}

/// Consecutive elements swept by one task, with the interfaces that start in them.
#[derive(Debug, Clone)]
struct Block {
    elements: Range<usize>,
    /// The interfaces between two of the block's elements, in interface order.
    inner: Range<usize>,
    /// Then, in interface order, those to a later block or to the ground. Of a given element,
    /// these follow its inner ones in the interface order too (a later `b`, or [`GROUND`]).
    rest: Range<usize>,
    /// Interfaces into later blocks, as a range of `ElementWise::crossing`.
    outgoing: Range<usize>,
    /// Interfaces from earlier blocks, as a range of `ElementWise::incoming`.
    incoming: Range<usize>,
    /// Slots of the block's ring of pending forces, a power of two above its farthest reach
    /// `max(b − a)`.
    ring: usize,
}

/// Elements per block: at least this many, and at most 64 blocks in all (fewer interfaces
/// cross blocks on large meshes).
const MIN_BLOCK: usize = 4096;
const MAX_BLOCKS: usize = 64;

/// How many interfaces ahead of the sweep their records are asked for, and half as many ahead
/// the `U` of their higher element. The hardware prefetchers stop at every 4 KiB page, which
/// the stream of inline records crosses every 57 interfaces; 64 interfaces take about 0.5 µs to sweep.
const PREFETCH_AHEAD: usize = 64;

/// Element-wise evaluation of eq. 15 for the kinematics `K` with `N` DOFs per element.
pub struct ElementWise<K: Kernel<N>, const N: usize> {
    /// Block after block: its inner interfaces, then the rest ([`Block`]), each sorted by `(a, b)`.
    faces: Store<K, N>,
    blocks: Vec<Block>,
    /// The interfaces whose elements lie in two blocks, in interface order.
    crossing: Vec<u32>,
    /// Per block, the interfaces that end in it as `(b, index into crossing)`, ordered by
    /// `b` and then in interface order.
    incoming: Vec<(u32, u32)>,
    /// The crossing interfaces' forces and the blocks' rings, one evaluation at a time.
    scratch: Mutex<Scratch<N>>,
    /// `t A D` per element, acting on the strains `U_e[3..6]` (hybrid only; empty for rigid).
    interior: Vec<nalgebra::Matrix3<f64>>,
    kinematics: PhantomData<K>,
}

impl<K: Kernel<N>, const N: usize> ElementWise<K, N> {
    /// Face records, blocks and crossing interfaces from the model's interfaces, with the
    /// springs of its law, which must be linear.
    pub fn new(model: &Model) -> Self {
        Self::build(model, true)
    }

    /// [`ElementWise::new`], with shared records only if `share` ([`Store::new`]).
    fn build(model: &Model, share: bool) -> Self {
        let t = model.thickness;
        // Each interface's record and the key of the records it may share ([`share_key`]).
        let (records, keys): (Vec<Record<K, N>>, Vec<_>) = model
            .interfaces
            .iter()
            .map(|i| {
                let ([g0, g1], _) = i.gauss_points();
                let (mid, tl) = (i.midpoint(), t * i.length);
                let offset = |e: u32| {
                    if e == GROUND {
                        Vec2::zeros()
                    } else {
                        mid - model.elements[e as usize].props.centroid
                    }
                };
                // `S` is even in the normal and `λ` odd in `δ = u_b − u_a`: the sides may swap.
                let (a, b) = if i.b < i.a { (i.b, i.a) } else { (i.a, i.b) };
                let [k_n, k_s] = model.law.springs([i.k_n, i.k_s]);
                let (k_n, k_s) = (k_n * tl, k_s * tl);
                let springs = Springs::new(i.normal, k_n, k_s);
                let (da, db, g) = (offset(a), offset(b), 0.5 * (g1 - g0));
                let key = share_key(da, db, g, i.normal, i.length, [k_n, k_s]);
                let odd = K::edge_odd(g, &springs);
                let record = Record {
                    da,
                    db,
                    springs,
                    odd,
                };
                (record, key)
            })
            .unzip();
        // The interfaces by their model index, ordered for the sweep; their records follow.
        let mut faces: Vec<Face<u32>> = model
            .interfaces
            .iter()
            .enumerate()
            .map(|(k, i)| Face {
                a: i.a.min(i.b),
                b: i.a.max(i.b),
                record: k as u32,
            })
            .collect();
        faces.sort_by_key(|f| (f.a, f.b));
        let n = model.elements.len();
        let len = MIN_BLOCK.max(n.div_ceil(MAX_BLOCKS));
        let (mut blocks, mut crossing) = (Vec::new(), Vec::new());
        for first in (0..n).step_by(len) {
            let elements = first..(first + len).min(n);
            let start = |e: usize| faces.partition_point(|f| (f.a as usize) < e);
            let here = start(elements.start)..start(elements.end);
            // Inner interfaces first; a stable sort keeps the interface order in both parts.
            let is_inner = |f: &Face<u32>| f.b != GROUND && (f.b as usize) < elements.end;
            faces[here.clone()].sort_by_key(|f| !is_inner(f));
            let inner = here.start + faces[here.clone()].partition_point(is_inner);
            let reach = faces[here.start..inner]
                .iter()
                .map(|f| (f.b - f.a) as usize)
                .max();
            let ring = (reach.unwrap_or(0) + 1).next_power_of_two();
            let before = crossing.len();
            crossing.extend(
                (inner..here.end)
                    .filter(|&k| faces[k].b != GROUND)
                    .map(|k| k as u32),
            );
            let outgoing = before..crossing.len();
            blocks.push(Block {
                elements,
                inner: here.start..inner,
                rest: inner..here.end,
                outgoing,
                incoming: 0..0,
                ring,
            });
        }
        let mut incoming = Vec::new();
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
        }
        let interior = if K::HAS_INTERIOR {
            model
                .elements
                .iter()
                .map(|e| e.d * (model.thickness * e.props.area))
                .collect()
        } else {
            Vec::new()
        };
        let scratch = Mutex::new(Scratch {
            crossing: vec![[[0.0; N]; 2]; crossing.len()],
            rings: blocks.iter().map(|b| vec![[0.0; N]; b.ring]).collect(),
            powers: vec![0.0; blocks.len()],
        });
        ElementWise {
            faces: Store::new(faces, &records, &keys, share),
            blocks,
            crossing,
            incoming,
            scratch,
            interior,
            kinematics: PhantomData,
        }
    }

    /// The generalised forces that an interface with record `f` puts on its sides `a` and `b`
    /// (`ub = None` on ground): `± t L [N(m)ᵀ λ(δ₀) + (N(g) − N(0))ᵀ λ(δ₁)]` with
    /// `δ = u_b − u_a` (module doc).
    #[inline(always)]
    fn face_forces(f: &Record<K, N>, ua: &[f64; N], ub: Option<&[f64; N]>) -> [[f64; N]; 2] {
        let s = &f.springs;
        let mut delta = -K::displacement(ua, f.da);
        let mut out = [[0.0; N]; 2];
        let Some(ub) = ub else {
            K::add_force(&mut out[0], f.da, s.apply(delta));
            K::add_edge_odd(&mut out[0], ua, None, &f.odd, s);
            return out;
        };
        delta += K::displacement(ub, f.db);
        let traction = s.apply(delta);
        K::add_force(&mut out[0], f.da, traction);
        K::add_edge_odd(&mut out[0], ua, Some(ub), &f.odd, s);
        K::add_force(&mut out[1], f.db, -traction);
        K::add_edge_odd(&mut out[1], ub, Some(ua), &f.odd, s);
        out
    }

    /// The scratch space, with the crossing interfaces' forces from `u` at `t_n`, computed
    /// before any block moves.
    fn crossing_pass(&self, u: &[[f64; N]]) -> std::sync::MutexGuard<'_, Scratch<N>> {
        fn pass<K: Kernel<N>, const N: usize>(
            faces: &impl Faces<K, N>,
            crossing: &[u32],
            u: &[[f64; N]],
            out: &mut [[[f64; N]; 2]],
        ) {
            out.par_iter_mut()
                .zip(crossing.par_iter())
                .with_min_len(1024)
                .for_each(|(out, &k)| {
                    let f = &faces.faces()[k as usize];
                    let (ua, ub) = (&u[f.a as usize], &u[f.b as usize]);
                    *out = ElementWise::face_forces(faces.record(f), ua, Some(ub));
                });
        }
        let mut scratch = self.scratch.lock().unwrap_or_else(|e| e.into_inner());
        match &self.faces {
            Store::Inline(faces) => pass(faces, &self.crossing, u, &mut scratch.crossing),
            Store::Shared(faces) => pass(faces, &self.crossing, u, &mut scratch.crossing),
        }
        scratch
    }

    /// Eq. 15 over one block: each element's `f_int`, minus the springs' forces plus the
    /// interior term `t A D ε` of hybrid elements, summed in interface order in the block's
    /// `ring` (all zero before and after) and handed to `state` as soon as it is complete.
    /// `crossing` holds the crossing interfaces' forces.
    ///
    /// On x86-64 it runs compiled for AVX2 where the processor has it (three-operand
    /// instructions, and [`FaceMap`]s in 256-bit lanes: fewer of them). The arithmetic is the
    /// same, with no fused multiply-add, so the forces are the same bits on every processor.
    #[inline(always)]
    fn sweep<S: BlockState<N>>(
        &self,
        block: &Block,
        crossing: &[[[f64; N]; 2]],
        ring: &mut [[f64; N]],
        state: S,
    ) {
        match &self.faces {
            Store::Inline(faces) => self.sweep_for(faces, block, crossing, ring, state),
            Store::Shared(faces) => self.sweep_for(faces, block, crossing, ring, state),
        }
    }

    /// [`ElementWise::sweep`] over the interfaces stored as `faces`.
    #[inline(always)]
    fn sweep_for<F: Faces<K, N>, S: BlockState<N>>(
        &self,
        faces: &F,
        block: &Block,
        crossing: &[[[f64; N]; 2]],
        ring: &mut [[f64; N]],
        state: S,
    ) {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            return simd
                .vectorize(move || self.sweep_in_order(simd, faces, block, crossing, ring, state));
        }
        self.sweep_in_order(Plain, faces, block, crossing, ring, state)
    }

    /// [`ElementWise::sweep`], as compiled for the processor at hand.
    #[inline(always)]
    fn sweep_in_order<F: Faces<K, N>, S: BlockState<N>>(
        &self,
        lanes: impl Lanes,
        faces: &F,
        block: &Block,
        crossing: &[[[f64; N]; 2]],
        ring: &mut [[f64; N]],
        mut state: S,
    ) {
        let first = block.elements.start;
        let mask = ring.len() - 1;
        let ring = &mut ring[..=mask];
        let incoming = &self.incoming[block.incoming.clone()];
        let crossing_out = &crossing[block.outgoing.clone()];
        let mut out = 0;
        let inner = &faces.faces()[block.inner.clone()];
        let rest = &faces.faces()[block.rest.clone()];
        let (mut k, mut r, mut next_in) = (0, 0, 0);
        // Where the next interface from an earlier block enters the ring, and the next element
        // with interfaces to the ground or to a later block: both are rare, and each element
        // tests them once.
        let entry = |next_in: usize| {
            incoming.get(next_in).map_or(usize::MAX, |&(b, _)| {
                (b as usize - first).saturating_sub(mask)
            })
        };
        let start = |r: usize| rest.get(r).map_or(usize::MAX, |f| f.a as usize);
        let (mut next_entry, mut next_rest) = (entry(0), start(0));
        for (i, e) in block.elements.clone().enumerate() {
            // An interface from an earlier block enters the ring as soon as the ring reaches its
            // element, before any interface of this block does: interface order.
            if i >= next_entry {
                while let Some(&(b, c)) = incoming.get(next_in) {
                    let j = b as usize - first;
                    if j > i + mask {
                        break;
                    }
                    sub(&mut ring[j & mask], &crossing[c as usize][1]);
                    next_in += 1;
                }
                next_entry = entry(next_in);
            }
            // The forces from earlier elements, then this element's own interfaces.
            let mut f = std::mem::replace(&mut ring[i & mask], [0.0; N]);
            let ue = *state.u(i);
            while let Some(face) = inner.get(k).filter(|face| face.a as usize == e) {
                if F::PREFETCH {
                    if let Some(ahead) = inner.get(k + PREFETCH_AHEAD) {
                        prefetch(ahead);
                    }
                    if let Some(ahead) = inner.get(k + PREFETCH_AHEAD / 2) {
                        prefetch(state.u(ahead.b as usize - first));
                    }
                }
                k += 1;
                let j = face.b as usize - first;
                faces.add_internal(lanes, face, &ue, state.u(j), &mut f, &mut ring[j & mask]);
            }
            if e == next_rest {
                while let Some(face) = rest.get(r).filter(|face| face.a as usize == e) {
                    r += 1;
                    if face.b == GROUND {
                        sub(&mut f, &Self::face_forces(faces.record(face), &ue, None)[0]);
                    } else {
                        sub(&mut f, &crossing_out[out][0]);
                        out += 1;
                    }
                }
                next_rest = start(r);
            }
            if K::HAS_INTERIOR {
                let stress = self.interior[e] * nalgebra::Vector3::new(ue[3], ue[4], ue[5]);
                for j in 0..3 {
                    f[3 + j] += stress[j];
                }
            }
            state.complete(e, i, &mut f);
        }
    }
}

/// What an evaluation writes besides `U`, `v` and `f`: the crossing interfaces' forces and
/// one ring of pending forces per block.
struct Scratch<const N: usize> {
    crossing: Vec<[[f64; N]; 2]>,
    rings: Vec<Vec<[f64; N]>>,
    /// Per block, `Σ v̄ᵀ M_e v̄` of a damped step ([`ElementUpdate::element`]).
    powers: Vec<f64>,
}

/// Asks the cache for `x` ahead of its use: a hint, with no effect on any result (a no-op off
/// x86-64).
#[inline(always)]
fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    safe_arch::prefetch_t0(x);
}

#[inline(always)]
fn sub<const N: usize>(acc: &mut [f64; N], x: &[f64; N]) {
    for j in 0..N {
        acc[j] -= x[j];
    }
}

/// The state a sweep reads `U` from, and what it does with an element whose force is complete.
trait BlockState<const N: usize> {
    fn u(&self, i: usize) -> &[f64; N];
    /// Element `e` (index `i` in the block) has its whole internal force `f`.
    fn complete(&mut self, e: usize, i: usize, f: &mut [f64; N]);
}

/// An evaluation: `U` is only read, and each force is written once.
struct Evaluate<'a, const N: usize> {
    u: &'a [[f64; N]],
    f: &'a mut [[f64; N]],
}

impl<const N: usize> BlockState<N> for Evaluate<'_, N> {
    #[inline(always)]
    fn u(&self, i: usize) -> &[f64; N] {
        &self.u[i]
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
    /// The elements, in order, where `force` may not be zero; `None`: all of them.
    loaded: Option<&'a [u32]>,
    /// The block's update ([`Update::resolve`]).
    update: E,
    /// The damping's power of the block's elements, summed in order (damped updates only).
    power: &'a mut f64,
}

impl<const N: usize, E: ElementUpdate<N>> BlockState<N> for Advance<'_, N, E> {
    #[inline(always)]
    fn u(&self, i: usize) -> &[f64; N] {
        &self.u[i]
    }
    #[inline(always)]
    fn complete(&mut self, e: usize, i: usize, f: &mut [f64; N]) {
        let external = match &mut self.loaded {
            None => true,
            Some([next, rest @ ..]) if *next as usize == e => {
                self.loaded = Some(rest);
                true
            }
            Some(_) => false,
        };
        if external {
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
}

/// A block's time step, waiting for its update to be resolved.
struct AdvanceBlock<'a, K: Kernel<N>, const N: usize> {
    evaluator: &'a ElementWise<K, N>,
    block: &'a Block,
    crossing: &'a [[[f64; N]; 2]],
    ring: &'a mut [[f64; N]],
    u: &'a mut [[f64; N]],
    v: &'a mut [[f64; N]],
    force: &'a mut [[f64; N]],
    loaded: Option<&'a [u32]>,
    power: &'a mut f64,
}

impl<K: Kernel<N>, const N: usize> WithUpdate<N> for AdvanceBlock<'_, K, N> {
    fn run<E: ElementUpdate<N>>(self, update: E) {
        let AdvanceBlock {
            evaluator,
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
        evaluator.sweep(
            block,
            crossing,
            ring,
            Advance {
                u,
                v,
                force,
                loaded,
                update,
                power,
            },
        );
    }
}

impl<K: Kernel<N>, const N: usize> Evaluator for ElementWise<K, N> {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::ElementWise
    }

    fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        let crossing_forces = self.crossing.len() * std::mem::size_of::<[[f64; N]; 2]>();
        let rings: usize = self
            .blocks
            .iter()
            .map(|b| b.ring * std::mem::size_of::<[f64; N]>())
            .sum();
        self.faces.bytes()
            + size_of_val(&self.crossing[..])
            + size_of_val(&self.incoming[..])
            + size_of_val(&self.interior[..])
            + crossing_forces
            + rings
    }

    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        let (u, _) = u.as_chunks::<N>();
        let (f, _) = f.as_chunks_mut::<N>();
        let mut scratch = self.crossing_pass(u);
        let Scratch {
            crossing, rings, ..
        } = &mut *scratch;
        type Parts<'a, const N: usize> = (
            (&'a Block, &'a mut Vec<[f64; N]>),
            (&'a [[f64; N]], &'a mut [[f64; N]]),
        );
        let work = |((block, ring), (u, f)): Parts<N>| {
            self.sweep(block, crossing, ring, Evaluate { u, f })
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

    fn fused(&self) -> Option<&dyn FusedStep> {
        Some(self)
    }
}

impl<K: Kernel<N>, const N: usize> FusedStep for ElementWise<K, N> {
    fn advance(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        force: &mut [f64],
        loaded: Option<&[u32]>,
        update: &Update,
    ) -> f64 {
        let (u, _) = u.as_chunks_mut::<N>();
        let (v, _) = v.as_chunks_mut::<N>();
        let (force, _) = force.as_chunks_mut::<N>();
        let mut scratch = self.crossing_pass(u);
        let Scratch {
            crossing,
            rings,
            powers,
        } = &mut *scratch;
        type Parts<'a, const N: usize> = (
            ((&'a Block, &'a mut Vec<[f64; N]>), &'a mut f64),
            ((&'a mut [[f64; N]], &'a mut [[f64; N]]), &'a mut [[f64; N]]),
        );
        let work = |(((block, ring), power), ((u, v), force)): Parts<N>| {
            // The loaded elements of this block.
            let loaded = loaded.map(|l| {
                let at = |e: usize| l.partition_point(|&x| (x as usize) < e);
                &l[at(block.elements.start)..at(block.elements.end)]
            });
            let ring = &mut ring[..];
            update.resolve(
                block.elements.clone(),
                AdvanceBlock {
                    evaluator: self,
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::force::evaluator::Assembled;
    use crate::input::scene::Scene;
    use crate::model::formulation::{Hybrid, Rigid};

    /// `f_int` swept by the plain build, block after block.
    fn plain_forces<K: Kernel<N>, const N: usize>(ev: &ElementWise<K, N>, u: &[f64]) -> Vec<f64> {
        let mut f = vec![0.0; u.len()];
        let (u, _) = u.as_chunks::<N>();
        let (fc, _) = f.as_chunks_mut::<N>();
        let mut scratch = ev.crossing_pass(u);
        let Scratch {
            crossing, rings, ..
        } = &mut *scratch;
        for (block, ring) in ev.blocks.iter().zip(rings.iter_mut()) {
            let r = block.elements.clone();
            let state = Evaluate {
                u: &u[r.clone()],
                f: &mut fc[r],
            };
            match &ev.faces {
                Store::Inline(faces) => {
                    ev.sweep_in_order(Plain, faces, block, crossing, ring, state)
                }
                Store::Shared(faces) => {
                    ev.sweep_in_order(Plain, faces, block, crossing, ring, state)
                }
            }
        }
        drop(scratch);
        f
    }

    /// A scene of one body on `mesh`, held by ground springs on its left edge.
    fn held(mesh: &str, formulation: &str) -> Model {
        let json = format!(
            r#"{{"name": "v", "thickness": 0.2, "formulation": {formulation},
            "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {mesh},
                "supports": [{{"edge": "left", "kind": "ground-spring"}}]}}],
            "time": {{"dt": 1e-9, "steps": 1}}}}"#
        );
        Model::build(&Scene::from_json(&json).unwrap()).unwrap()
    }

    const VORONOI: &str =
        r#"{"kind": "voronoi", "origin": [0, 0], "size": [4, 1], "sites": 12000, "seed": 3}"#;
    const GRID: &str =
        r#"{"kind": "grid", "origin": [0.3, -7], "size": [4, 1], "cells": [160, 90]}"#;
    const RIGID: &str = r#"{"kind": "rigid"}"#;
    const HYBRID: &str = r#"{"kind": "hybrid", "penalty": 10}"#;

    fn displacements(model: &Model) -> Vec<f64> {
        (0..model.n_dofs())
            .map(|i| ((i * 7919) % 1000) as f64 * 1e-6 - 5e-4)
            .collect()
    }

    /// The sweep compiled for AVX2, where the processor has it, and the plain one give the same
    /// bits, rigid and hybrid, with inline records on a Voronoi mesh and shared ones on a grid,
    /// each of several blocks with ground springs.
    #[test]
    fn the_avx2_sweep_gives_the_plain_bits() {
        fn check<K: Kernel<N>, const N: usize>(model: &Model, shared: bool) {
            let ev = ElementWise::<K, N>::new(model);
            assert!(ev.blocks.len() >= 2 && !ev.crossing.is_empty());
            assert_eq!(matches!(ev.faces, Store::Shared(_)), shared);
            let u = displacements(model);
            let mut f = vec![0.0; u.len()];
            ev.internal_force(&u, &mut f);
            let plain = plain_forces(&ev, &u);
            assert!(
                f.iter()
                    .zip(&plain)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "the two builds differ"
            );
        }
        for (mesh, shared) in [(VORONOI, false), (GRID, true)] {
            check::<Rigid, 3>(&held(mesh, RIGID), shared);
            check::<Hybrid, 6>(&held(mesh, HYBRID), shared);
        }
    }

    /// The interfaces of a grid, off the origin so that its geometry carries round-off, share a
    /// handful of records: the step reads 12 bytes per interface. The forces are those of each
    /// interface's own record to 1e-12 of their scale, rigid and hybrid, and the same bits on 1
    /// and 2 threads.
    #[test]
    fn a_grid_shares_its_records() {
        fn check<K: Kernel<N>, const N: usize>(model: &Model) {
            let (shared, inline) = (
                ElementWise::<K, N>::new(model),
                ElementWise::<K, N>::build(model, false),
            );
            let Store::Shared(records) = &shared.faces else {
                panic!("the grid's records are not shared");
            };
            assert!(
                records.records.len() <= 16,
                "{} records",
                records.records.len()
            );
            assert!(shared.faces.bytes() * 4 < inline.faces.bytes());
            let u = displacements(model);
            let (mut fs, mut fi) = (vec![0.0; u.len()], vec![0.0; u.len()]);
            inline.internal_force(&u, &mut fi);
            for threads in [1, 2] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let mut f = vec![0.0; u.len()];
                pool.install(|| shared.internal_force(&u, &mut f));
                assert!(threads == 1 || f == fs, "{threads} threads give other bits");
                fs = f;
            }
            let scale = fi.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let diff = fs
                .iter()
                .zip(&fi)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                diff > 0.0,
                "the records are the same bits: the test shows nothing"
            );
            assert!(diff <= 1e-12 * scale, "|Δf| = {diff:e} of {scale:e}");
        }
        check::<Rigid, 3>(&held(GRID, RIGID));
        check::<Hybrid, 6>(&held(GRID, HYBRID));
    }

    /// An interface's [`FaceMap`] gives the forces of its record to round-off, rigid and hybrid,
    /// on every interface of a Voronoi mesh, from both sweeps ([`Plain`] and, where the
    /// processor has it, AVX2) with the same bits.
    #[test]
    fn a_face_map_is_its_record() {
        fn check<K: Kernel<N>, const N: usize>(model: &Model) {
            let Store::Inline(faces) = ElementWise::<K, N>::new(model).faces else {
                panic!("a Voronoi mesh's records are shared");
            };
            let u = displacements(model);
            let (u, _) = u.as_chunks::<N>();
            let mut worst = 0.0f64;
            for face in faces.iter().filter(|f| f.b != GROUND) {
                let (ua, ub) = (&u[face.a as usize], &u[face.b as usize]);
                let [on_a, on_b] = ElementWise::face_forces(&face.record, ua, Some(ub));
                let map = K::Map::new(&face.record);
                let mut f = [[0.0; N]; 2];
                let [fa, fb] = &mut f;
                map.add_internal(Plain, ua, ub, fa, fb);
                #[cfg(target_arch = "x86_64")]
                if let Some(simd) = pulp::x86::V3::try_new() {
                    let mut g = [[0.0; N]; 2];
                    let [ga, gb] = &mut g;
                    simd.vectorize(|| map.add_internal(simd, ua, ub, ga, gb));
                    assert_eq!(f, g, "AVX2 and plain maps differ");
                }
                let scale = on_a.iter().chain(&on_b).fold(0.0f64, |m, x| m.max(x.abs()));
                for (got, want) in f.as_flattened().iter().zip(on_a.iter().chain(&on_b)) {
                    worst = worst.max((got + want).abs() / scale);
                }
            }
            assert!(worst <= 1e-12, "relative |Δf| = {worst:e}");
        }
        check::<Rigid, 3>(&held(VORONOI, RIGID));
        check::<Hybrid, 6>(&held(VORONOI, HYBRID));
    }

    /// On a grid of 5000 × 3 cells, in four blocks, an element's upper neighbour lies in the next
    /// block: the rings reach one element, and the interfaces from the earlier block enter them
    /// during the sweep. The forces still equal `K U` to round-off, and the rings are left zero.
    #[test]
    fn rings_take_late_interfaces_from_earlier_blocks() {
        let json = r#"{"name": "g", "thickness": 1.0, "formulation": {"kind": "rigid"},
            "materials": {"m": {"E": 3e10, "nu": 0.2, "rho": 2400}},
            "bodies": [{"name": "b", "material": "m",
                "mesh": {"kind": "grid", "origin": [0, 0], "size": [50, 0.03], "cells": [5000, 3]},
                "supports": [{"edge": "left", "kind": "ground-spring"}]}],
            "time": {"dt": 1e-9, "steps": 1}}"#;
        let model = Model::build(&Scene::from_json(json).unwrap()).unwrap();
        let ev = ElementWise::<Rigid, 3>::new(&model);
        assert!(ev.blocks.len() >= 3 && ev.blocks.iter().all(|b| b.ring == 2));
        let late = ev.blocks.iter().flat_map(|b| {
            ev.incoming[b.incoming.clone()]
                .iter()
                .filter(move |&&(e, _)| e as usize - b.elements.start >= b.ring)
        });
        assert!(
            late.count() > 0,
            "no interface enters a ring late: the test mesh does not exercise it"
        );
        let u: Vec<f64> = (0..model.n_dofs())
            .map(|i| ((i * 7919) % 1000) as f64 * 1e-6 - 5e-4)
            .collect();
        let (mut fa, mut fe) = (vec![0.0; u.len()], vec![0.0; u.len()]);
        Assembled::<Rigid, 3>::new(&model).internal_force(&u, &mut fa);
        ev.internal_force(&u, &mut fe);
        let scale = fa.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = fa
            .iter()
            .zip(&fe)
            .fold(0.0f64, |m, (a, e)| m.max((a - e).abs()));
        assert!(diff <= 1e-12 * scale, "|Δf| = {diff:e} of {scale:e}");
        let scratch = ev.scratch.lock().unwrap();
        assert!(
            scratch.rings.iter().flatten().all(|s| *s == [0.0; 3]),
            "a ring was left with a pending force"
        );
    }
}

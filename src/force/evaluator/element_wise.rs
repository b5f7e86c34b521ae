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
//! other, so each interface computes it once and hands it to both its elements, in the sweep
//! the two evaluators share ([`super::sweep`]: interfaces in the order of their lower element,
//! each element advanced in a time step as soon as its force is complete, pending forces in a
//! ring, parallel blocks with the same bits on any thread count).
//!
//! Each interface has a [`Record`] of what its traction needs. On a regular mesh most records
//! are copies of a few, equal up to the round-off of the coordinates; then the interfaces share
//! them ([`Shared`], [`share_key`]) and a step reads at most 12 bytes per interface instead of
//! 72 (80 hybrid): none for those that a run of repeating interfaces leaves out
//! ([`super::sweep`]). A shared record is then also formed, once, into its interface's linear map
//! ([`FaceMap`]: 4 × 4 rigid, 10 × 10 hybrid), which the sweep applies in 4-wide lanes with
//! fewer instructions than the record takes. An irregular mesh keeps its records inline
//! ([`Inline`]): a map per interface would double the bytes a step reads.

use super::failing::failing_of;
use super::poisson::Pressures;
use super::sweep::{Couplings, Face, Higher, Sweep};
use super::{Evaluator, Failure, FusedStep, GroupedStep};
use crate::force::failure::{FailingInterfaces, FailureState, Jump};
use crate::input::scene::EvaluatorKind;
use crate::lanes::{spread, Lanes, Wide};
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Formulation, Hybrid, Kinematics, Rigid, Springs};
use crate::model::mass::Update;
use crate::model::{Model, GROUND};

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

/// Each interface with its own record (72 bytes rigid, 80 hybrid): an irregular mesh, where
/// interfaces rarely share one.
struct Inline<K: Kernel<N>, const N: usize> {
    faces: Vec<Face<Record<K, N>>>,
    interior: Interior,
}

impl<K: Kernel<N>, const N: usize> Couplings<N> for Inline<K, N> {
    type Ref = Record<K, N>;
    /// Inline records stream at 72 bytes per interface and cross a 4 KiB page every 57, where
    /// the hardware prefetchers stop.
    const PREFETCH: bool = true;
    /// Each interface has its own record: none repeats.
    const RUNS: bool = false;
    const WIDE: bool = false;
    #[inline(always)]
    fn faces(&self) -> &[Face<Record<K, N>>] {
        &self.faces
    }
    type Coupling<'a> = &'a Record<K, N>;
    #[inline(always)]
    fn coupling<'a>(&'a self, face: &'a Face<Record<K, N>>) -> &'a Record<K, N> {
        &face.record
    }
    #[inline(always)]
    fn add_pair(
        &self,
        _: impl Lanes,
        record: &Record<K, N>,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        let [on_a, on_b] = K::face_forces(record, ua, Some(ub));
        sub(fa, &on_a);
        sub(fb, &on_b);
    }
    #[inline(always)]
    fn add_ground(&self, face: &Face<Record<K, N>>, ua: &[f64; N], fa: &mut [f64; N]) {
        sub(fa, &K::face_forces(&face.record, ua, None)[0]);
    }
    #[inline(always)]
    fn add_own(&self, e: usize, ue: &[f64; N], f: &mut [f64; N]) {
        self.interior.add::<K, N>(e, ue, f);
    }
}

/// Interfaces of 12 bytes that name one of few records: a regular mesh, whose interfaces are
/// copies of a handful (a grid's inner ones are of two kinds). The records stay in cache and a
/// step reads 12 bytes per interface instead of 72 (80 hybrid), of the interfaces that the
/// sweep's runs keep.
struct Shared<K: Kernel<N>, const N: usize> {
    faces: Vec<Face<u32>>,
    records: Vec<Record<K, N>>,
    /// Each record's [`FaceMap`].
    maps: Vec<K::Map>,
    interior: Interior,
}

impl<K: Kernel<N>, const N: usize> Couplings<N> for Shared<K, N> {
    type Ref = u32;
    /// 12 bytes per interface, which the hardware prefetchers follow unaided (10⁶-element grid,
    /// one thread: 14.1 ns per element-step without, 15.5 with, measured before the
    /// [`FaceMap`]s, which left the two within the noise; `cargo bench --bench step --
    /// grid/rigid/element-wise/1thr` on both builds).
    const PREFETCH: bool = false;
    const RUNS: bool = true;
    const WIDE: bool = K::WIDE;
    #[inline(always)]
    fn faces(&self) -> &[Face<u32>] {
        &self.faces
    }
    type Coupling<'a> = &'a K::Map;
    #[inline(always)]
    fn coupling<'a>(&'a self, face: &'a Face<u32>) -> &'a K::Map {
        &self.maps[face.record as usize]
    }
    #[inline(always)]
    fn add_pair(
        &self,
        lanes: impl Lanes,
        map: &K::Map,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        map.add_internal(lanes, ua, ub, fa, fb);
    }
    #[inline(always)]
    fn add_pairs(
        &self,
        lanes: impl Lanes,
        map: &K::Map,
        ua: &Wide<N>,
        ub: &Wide<N>,
        fa: &mut Wide<N>,
        fb: Higher<'_, N>,
    ) {
        map.add_internal_wide(lanes, ua, ub, fa, fb);
    }
    #[inline(always)]
    fn add_ground(&self, face: &Face<u32>, ua: &[f64; N], fa: &mut [f64; N]) {
        let record = &self.records[face.record as usize];
        sub(fa, &K::face_forces(record, ua, None)[0]);
    }
    const OWN: bool = K::HAS_INTERIOR;
    #[inline(always)]
    fn add_own(&self, e: usize, ue: &[f64; N], f: &mut [f64; N]) {
        self.interior.add::<K, N>(e, ue, f);
    }
}

/// Where interfaces fail, the faces of the sweeps that step them. A failing interface names
/// its place in [`Model::failing_interfaces`] (marked [`BY_LAW`]) and gives its whole traction
/// through its law ([`FailingInterfaces::couple_whole`]): its step reads a face of 12 bytes and
/// the failing interface's 80, not an elastic record as well. The others name their record in
/// `records`. Where `K` [screens](Kernel::SCREENS), a failing interface in its initial state
/// whose traction passes its screen takes its elastic record instead, and reads nothing else.
struct ByLaw<K: Kernel<N>, const N: usize> {
    faces: Vec<Face<u32>>,
    records: Vec<Record<K, N>>,
    /// Per failing interface, its elastic record and its [`Screen`]; empty unless `K` screens.
    screens: Vec<(Record<K, N>, Screen)>,
    /// Per failing interface of a `rigid-poisson` model, `t L k_s h`: what the odd part of the
    /// correction's jump, `(q_a − q_b) g`, adds to `t L |λ₁|` per unit `|q_a − q_b|`
    /// ([`Kernel::screened_jumped`]); empty otherwise.
    jump_odd: Vec<f64>,
}

/// The mark of a [`ByLaw`] face whose interface fails.
const BY_LAW: u32 = 1 << 31;

/// Records and failing interfaces are read by index this many faces ahead of their use.
const BY_LAW_AHEAD: usize = 48;

impl<K: Kernel<N>, const N: usize> ByLaw<K, N> {
    /// The faces in sweep order, each naming its interface in the model, with their `records`.
    fn new(model: &Model, faces: &[Face<u32>], records: &[Record<K, N>]) -> Self {
        let failing = model.failing_interfaces();
        let mut rank = vec![u32::MAX; model.interfaces.len()];
        for (j, &k) in failing.iter().enumerate() {
            rank[k as usize] = j as u32 | BY_LAW;
        }
        let mut kept = Vec::new();
        let faces = faces
            .iter()
            .map(|f| {
                let record = match rank[f.record as usize] {
                    u32::MAX => {
                        kept.push(records[f.record as usize]);
                        kept.len() as u32 - 1
                    }
                    j => j,
                };
                Face {
                    a: f.a,
                    b: f.b,
                    record,
                }
            })
            .collect();
        let screens = if K::SCREENS {
            failing
                .iter()
                .map(|&k| {
                    let i = &model.interfaces[k as usize];
                    let r = crate::force::failure::initial_disc(model.law_of(i));
                    let reach = model.thickness * i.length * r;
                    (
                        records[k as usize],
                        [(1.0 + 1e-9) / i.gauss_offset(), reach],
                    )
                })
                .collect()
        } else {
            Vec::new()
        };
        let jump_odd = if K::SCREENS && model.formulation == Formulation::RigidPoisson {
            failing
                .iter()
                .map(|&k| {
                    let i = &model.interfaces[k as usize];
                    let [_, k_s] = model.law_of(i).springs([i.k_n, i.k_s]);
                    model.thickness * i.length * k_s * i.gauss_offset()
                })
                .collect()
        } else {
            Vec::new()
        };
        ByLaw {
            faces,
            records: kept,
            screens,
            jump_odd,
        }
    }
}

/// [`ByLaw`] in one sweep that updates the failing interfaces' `state`; under the Poisson
/// correction (`rigid-poisson`) with the cells' `q`, whose jump every interface's springs take
/// ([`Corrected`]) and every failing interface's law bounds ([`Jump`]).
struct ByLawSweep<'a, K: Kernel<N>, const N: usize> {
    by_law: &'a ByLaw<K, N>,
    interior: &'a Interior,
    failing: &'a FailingInterfaces<K, N>,
    state: &'a FailureState,
    q: Option<&'a Pressures<'a>>,
}

impl<K: Kernel<N>, const N: usize> Couplings<N> for ByLawSweep<'_, K, N> {
    type Ref = u32;
    /// The sweep asks for the faces and `U` ahead; the records and the failing interfaces,
    /// read by index, are asked for by [`Couplings::add_pair`].
    const PREFETCH: bool = true;
    const RUNS: bool = false;
    const WIDE: bool = false;
    const OWN: bool = K::HAS_INTERIOR;
    #[inline(always)]
    fn faces(&self) -> &[Face<u32>] {
        &self.by_law.faces
    }
    /// The face's index, with its elements' `q` under the Poisson correction.
    type Coupling<'b>
        = (u32, Jump)
    where
        Self: 'b;
    #[inline(always)]
    fn coupling(&self, face: &Face<u32>) -> (u32, Jump) {
        let jump = self
            .q
            .map(|q| [q.get(face.a as usize), q.get(face.b as usize)]);
        (face.record, jump)
    }
    /// A sweep computes each face once: the points of a failing interface are its alone. A
    /// fresh failing interface is screened on its elastic record, with the correction's jump
    /// where there is one ([`Kernel::screened_jumped`]).
    #[inline(always)]
    fn add_pair(
        &self,
        _: impl Lanes,
        (record, jump): (u32, Jump),
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        if record & BY_LAW != 0 {
            let j = (record & !BY_LAW) as usize;
            if K::SCREENS {
                let screens = &self.by_law.screens;
                #[cfg(target_arch = "x86_64")]
                if let Some(ahead) = screens.get(j + BY_LAW_AHEAD) {
                    safe_arch::prefetch_t0(ahead);
                }
                if self.failing.is_fresh(j, self.state) {
                    let (record, screen) = &screens[j];
                    let passed = match jump {
                        None => K::screened(record, ua, ub, screen),
                        Some([qa, qb]) => K::screened_jumped(
                            record,
                            ua,
                            ub,
                            screen,
                            record.da * qa - record.db * qb,
                            self.by_law.jump_odd[j] * (qa - qb).abs(),
                        ),
                    };
                    if let Some([on_a, on_b]) = passed {
                        sub(fa, &on_a);
                        sub(fb, &on_b);
                        return;
                    }
                }
            } else {
                self.failing.prefetch(j);
            }
            self.failing
                .couple_whole(j, self.state, (ua, ub), jump, fa, fb);
        } else {
            let records = &self.by_law.records;
            #[cfg(target_arch = "x86_64")]
            if let Some(ahead) = records.get(record as usize + BY_LAW_AHEAD) {
                safe_arch::prefetch_t0(ahead);
            }
            let r = &records[record as usize];
            let [on_a, on_b] = match jump {
                Some([qa, qb]) => K::jumped_forces(r, ua, Some(ub), r.da * qa - r.db * qb),
                None => K::face_forces(r, ua, Some(ub)),
            };
            sub(fa, &on_a);
            sub(fb, &on_b);
        }
    }
    #[inline(always)]
    fn add_ground(&self, face: &Face<u32>, ua: &[f64; N], fa: &mut [f64; N]) {
        let r = &self.by_law.records[face.record as usize];
        let on_a = match self.q {
            Some(q) => K::jumped_forces(r, ua, None, r.da * q.get(face.a as usize)),
            None => K::face_forces(r, ua, None),
        };
        sub(fa, &on_a[0]);
    }
    #[inline(always)]
    fn add_own(&self, e: usize, ue: &[f64; N], f: &mut [f64; N]) {
        self.interior.add::<K, N>(e, ue, f);
    }
}

/// An interface's shares in its elements' first moments of the spring tractions, times the
/// thickness ([`super::poisson::Pressures`]): `t ∫ (x − x_a)·S δ ds` to `a` and
/// `−t ∫ (x − x_b)·S δ ds` to `b`, the springs on `δ = u_b − u_a` with no correction. Of the
/// two Gauss points `m ± g`, the odd part of the jump lies along the normal and `g` along the
/// edge (rigid), so only the midpoint's traction `T = t L S δ₀` enters: `d_a · T` and
/// `−d_b · T`.
#[inline(always)]
fn lead_shares<K: Kinematics<N>, const N: usize>(
    f: &Record<K, N>,
    ua: &[f64; N],
    ub: Option<&[f64; N]>,
) -> [f64; 2] {
    let mut delta = -K::displacement(ua, f.da);
    if let Some(ub) = ub {
        delta += K::displacement(ub, f.db);
    }
    let t = f.springs.apply(delta);
    [f.da.dot(&t), -f.db.dot(&t)]
}

/// `t A D` per element, acting on the strains `U_e[3..6]`: the interior term of eq. 15 (hybrid
/// only; empty for rigid).
struct Interior(Vec<nalgebra::Matrix3<f64>>);

impl Interior {
    #[inline(always)]
    fn add<K: Kinematics<N>, const N: usize>(&self, e: usize, ue: &[f64; N], f: &mut [f64; N]) {
        if K::HAS_INTERIOR {
            let stress = self.0[e] * nalgebra::Vector3::new(ue[3], ue[4], ue[5]);
            for j in 0..3 {
                f[3 + j] += stress[j];
            }
        }
    }
}

#[inline(always)]
fn sub<const N: usize>(acc: &mut [f64; N], x: &[f64; N]) {
    for j in 0..N {
        acc[j] -= x[j];
    }
}

/// What the sweep needs of the kinematics `K` besides [`Kinematics`]: the size of the
/// [`FaceMap`] of its interfaces with shared records.
pub trait Kernel<const N: usize>: Kinematics<N> + Sized {
    /// The interface map of `K`: `M = 2N − 2` inputs, outputs in `Q` groups of four lanes.
    type Map: Map<N>;
    /// Whether runs of its interfaces go four elements at a time in lanes
    /// ([`Couplings::add_pairs`]): worth it for the 4 × 4 rigid map, not for the hybrid 10 × 10
    /// (10⁶-element grid, one thread, `step_only` timed in turns: rigid 9.1–9.4 → 8.5–8.8 ns
    /// per element-step; hybrid 38–40 → 46 ns with it set).
    const WIDE: bool = false;
    /// The generalised forces that an interface with record `f` puts on its sides `a` and `b`
    /// (`ub = None` on ground): [`gauss_forces`], unless `K` has a cheaper form of it.
    #[inline(always)]
    fn face_forces(f: &Record<Self, N>, ua: &[f64; N], ub: Option<&[f64; N]>) -> [[f64; N]; 2] {
        gauss_forces(f, ua, ub, None)
    }
    /// [`Kernel::face_forces`] with the jump at the midpoint increased by `extra`: the Poisson
    /// correction's `q_a d_a − q_b d_b` ([`Corrected`]).
    #[inline(always)]
    fn jumped_forces(
        f: &Record<Self, N>,
        ua: &[f64; N],
        ub: Option<&[f64; N]>,
        extra: Vec2,
    ) -> [[f64; N]; 2] {
        gauss_forces(f, ua, ub, Some(extra))
    }
    /// Whether a failing interface of `K` in its initial state is first screened on its elastic
    /// record ([`Kernel::screened`]).
    const SCREENS: bool = false;
    /// [`Kernel::face_forces`] of an interface between two elements when its tractions at both
    /// Gauss points lie in the disc `|λ| ≤ r` (a [`Screen`]), else `None`: for a failing
    /// interface in its initial state, a disc inside its law's initial region, where the law
    /// leaves it elastic. `None` for a `K` that does not [screen](Kernel::SCREENS).
    #[inline(always)]
    fn screened(
        _f: &Record<Self, N>,
        _ua: &[f64; N],
        _ub: &[f64; N],
        _screen: &Screen,
    ) -> Option<[[f64; N]; 2]> {
        None
    }
    /// [`Kernel::screened`] under the Poisson correction: [`Kernel::jumped_forces`] with the
    /// jump's midpoint value `extra`, where its odd part adds at most `odd` to `t L |λ₁|`.
    #[inline(always)]
    fn screened_jumped(
        _f: &Record<Self, N>,
        _ua: &[f64; N],
        _ub: &[f64; N],
        _screen: &Screen,
        _extra: Vec2,
        _odd: f64,
    ) -> Option<[[f64; N]; 2]> {
        None
    }
}

/// A disc of tractions `|λ| ≤ r` about the origin for an edge of length `L`, as
/// [`Kernel::screened`] tests it on a rigid record: `[1/h, t L r]` with `h = L/(2√3)` the Gauss
/// offset; a negative `t L r` where the law gives no disc.
pub type Screen = [f64; 2];

/// The generalised forces that an interface with record `f` puts on its sides `a` and `b`
/// (`ub = None` on ground): `± t L [N(m)ᵀ λ(δ₀) + (N(g) − N(0))ᵀ λ(δ₁)]` with
/// `δ = u_b − u_a` (module doc), its midpoint value `δ₀` increased by `extra`, through the
/// shape matrices of any [`Kinematics`].
#[inline(always)]
fn gauss_forces<K: Kinematics<N>, const N: usize>(
    f: &Record<K, N>,
    ua: &[f64; N],
    ub: Option<&[f64; N]>,
    extra: Option<Vec2>,
) -> [[f64; N]; 2] {
    let s = &f.springs;
    let mut delta = -K::displacement(ua, f.da);
    if let Some(extra) = extra {
        delta += extra;
    }
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

/// A rigid interface: 4 inputs, 4 outputs, `(Δu, Δv, θ_a, θ_b) ↦ (T, m_a, m_b)`.
impl Kernel<3> for Rigid {
    type Map = FaceMap<4, 1>;
    const WIDE: bool = true;
    /// [`gauss_forces`] with each offset turned a quarter, `r = ẑ × d`: the jump is
    /// `δ = Δu + θ_b r_b − θ_a r_a` and the moment of the traction `T = S δ` about a centroid
    /// `r · T`, so each side's forces are `±T` and `±(r · T + k_θ (θ_b − θ_a))`. The same forces
    /// up to round-off (`tests::the_rigid_form_is_the_gauss_rule`) in fewer operations: the
    /// inline records of a 10⁶-element Voronoi mesh step in about 10 % less time.
    #[inline(always)]
    fn face_forces(f: &Record<Self, 3>, ua: &[f64; 3], ub: Option<&[f64; 3]>) -> [[f64; 3]; 2] {
        rigid_forces(f, ua, ub, None)
    }
    #[inline(always)]
    fn jumped_forces(
        f: &Record<Self, 3>,
        ua: &[f64; 3],
        ub: Option<&[f64; 3]>,
        extra: Vec2,
    ) -> [[f64; 3]; 2] {
        rigid_forces(f, ua, ub, Some(extra))
    }
    const SCREENS: bool = true;
    /// The tractions at the Gauss points are `λ₀ ∓ λ₁`, with `t L λ₀ = S δ₀` the force on `a`
    /// and `λ₁ = k_n h Δθ n`, `t L |λ₁| = k_θ |Δθ| / h`: the test is
    /// `|S δ₀|₁ + k_θ |Δθ| / h ≤ t L r`, which bounds `|λ₀| + |λ₁|`.
    #[inline(always)]
    fn screened(
        f: &Record<Self, 3>,
        ua: &[f64; 3],
        ub: &[f64; 3],
        &[per_h, reach]: &Screen,
    ) -> Option<[[f64; 3]; 2]> {
        let [on_a, on_b] = Self::face_forces(f, ua, Some(ub));
        let w = f.odd * (ub[2] - ua[2]);
        (on_a[0].abs() + on_a[1].abs() + w.abs() * per_h <= reach).then_some([on_a, on_b])
    }
    /// The jump's odd part `(q_a − q_b) g` lies along the edge: `t L |λ₁|` grows by at most
    /// `t L k_s h |q_a − q_b|` (`odd`).
    #[inline(always)]
    fn screened_jumped(
        f: &Record<Self, 3>,
        ua: &[f64; 3],
        ub: &[f64; 3],
        &[per_h, reach]: &Screen,
        extra: Vec2,
        odd: f64,
    ) -> Option<[[f64; 3]; 2]> {
        let [on_a, on_b] = rigid_forces(f, ua, Some(ub), Some(extra));
        let w = f.odd * (ub[2] - ua[2]);
        (on_a[0].abs() + on_a[1].abs() + w.abs() * per_h + odd <= reach).then_some([on_a, on_b])
    }
}

/// [`Kernel::face_forces`] of a rigid interface, its jump at the midpoint increased by
/// `extra` (the Poisson correction's, [`Corrected`]).
#[inline(always)]
fn rigid_forces(
    f: &Record<Rigid, 3>,
    ua: &[f64; 3],
    ub: Option<&[f64; 3]>,
    extra: Option<Vec2>,
) -> [[f64; 3]; 2] {
    let (ra, rb) = (Vec2::new(-f.da.y, f.da.x), Vec2::new(-f.db.y, f.db.x));
    let ub = ub.unwrap_or(&[0.0; 3]);
    let (ta, tb) = (ra * ua[2], rb * ub[2]);
    let mut delta = Vec2::new(ub[0] - ua[0], ub[1] - ua[1]) + (tb - ta);
    if let Some(extra) = extra {
        delta += extra;
    }
    let t = f.springs.apply(delta);
    let w = f.odd * (ub[2] - ua[2]);
    [[t.x, t.y, ra.dot(&t) + w], [-t.x, -t.y, -(rb.dot(&t) + w)]]
}

/// The interfaces of a `rigid-poisson` model with the Poisson correction in their tractions
/// ([`crate::model::poisson`]): the springs act on `δ + q_a (x − x_a) − q_b (x − x_b)`, with
/// the cells' `q` of the step (`q_b = 0` on ground). That jump's odd part along the edge,
/// `(q_a − q_b) g`, meets the springs as `k_s (q_a − q_b) g`, which has neither resultant nor
/// moment over the two Gauss points: only its midpoint value `q_a d_a − q_b d_b` enters.
struct Corrected<'a, const WAVE: bool> {
    inline: &'a Inline<Rigid, 3>,
    q: &'a Pressures<'a>,
}

/// With `WAVE`, the cells' wave leads the sweep ([`Pressures`]).
impl<const WAVE: bool> Couplings<3> for Corrected<'_, WAVE> {
    type Ref = Record<Rigid, 3>;
    const PREFETCH: bool = true;
    const RUNS: bool = false;
    const WIDE: bool = false;
    const OWN: bool = false;
    #[inline(always)]
    fn faces(&self) -> &[Face<Record<Rigid, 3>>] {
        &self.inline.faces
    }
    /// The record, and the jump the correction adds at its midpoint.
    type Coupling<'b>
        = (&'b Record<Rigid, 3>, Vec2)
    where
        Self: 'b;
    #[inline(always)]
    fn coupling<'b>(&'b self, face: &'b Face<Record<Rigid, 3>>) -> Self::Coupling<'b> {
        let r = &face.record;
        let (qa, qb) = (self.q.get(face.a as usize), self.q.get(face.b as usize));
        (r, r.da * qa - r.db * qb)
    }
    #[inline(always)]
    fn add_pair(
        &self,
        _: impl Lanes,
        (record, extra): (&Record<Rigid, 3>, Vec2),
        ua: &[f64; 3],
        ub: &[f64; 3],
        fa: &mut [f64; 3],
        fb: &mut [f64; 3],
    ) {
        let [on_a, on_b] = rigid_forces(record, ua, Some(ub), Some(extra));
        sub(fa, &on_a);
        sub(fb, &on_b);
    }
    #[inline(always)]
    fn add_ground(&self, face: &Face<Record<Rigid, 3>>, ua: &[f64; 3], fa: &mut [f64; 3]) {
        let r = &face.record;
        let extra = r.da * self.q.get(face.a as usize);
        sub(fa, &rigid_forces(r, ua, None, Some(extra))[0]);
    }
    #[inline(always)]
    fn add_own(&self, _: usize, _: &[f64; 3], _: &mut [f64; 3]) {}
    fn leads(&self) -> bool {
        WAVE
    }
    #[inline(always)]
    fn lead_pair(&self, face: &Face<Record<Rigid, 3>>, ua: &[f64; 3], ub: &[f64; 3]) -> [f64; 2] {
        lead_shares(&face.record, ua, Some(ub))
    }
    #[inline(always)]
    fn lead_ground(&self, face: &Face<Record<Rigid, 3>>, ua: &[f64; 3]) -> f64 {
        lead_shares(&face.record, ua, None)[0]
    }
    #[inline(always)]
    fn lead_done(&self, e: usize, s: f64) {
        self.q.done(e, s);
    }
}

/// A hybrid interface: 10 inputs, 10 outputs in three groups of four (two lanes unused).
impl Kernel<6> for Hybrid {
    type Map = FaceMap<10, 3>;
}

/// An interface's internal forces as one linear map of `M` inputs
/// `x = (u_b − u_a)[0..2], u_a[2..N], u_b[2..N]` (the jump of the translations, then the
/// other DOFs of each side) to `M` outputs `o = (f_a[0..N], f_b[2..N])`, with
/// `f_b[0..2] = −f_a[0..2]`; `M = 2N − 2`. Column `k` holds the outputs of input `k`: the
/// forces of [`Kernel::face_forces`] for that unit input, so the map is that function,
/// formed once per shared record. Applied, it is `M` products of `4Q` lanes and no shuffles
/// (rigid: 4 × 4; `Q` groups of four lanes hold the outputs, the last padded with zeros).
/// Applied to four interfaces in lanes, its entries are read spread over four lanes
/// ([`spread`]: 512 bytes rigid, 3.2 kB hybrid, per shared record).
#[derive(Debug, Clone, Copy)]
pub struct FaceMap<const M: usize, const Q: usize>([[[f64; 4]; Q]; M], [[[f64; 4]; M]; M]);

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
    /// [`Map::add_internal`] for four interfaces in lanes ([`Couplings::add_pairs`]).
    fn add_internal_wide(
        &self,
        lanes: impl Lanes,
        ua: &Wide<N>,
        ub: &Wide<N>,
        fa: &mut Wide<N>,
        fb: Higher<'_, N>,
    );
}

impl<const N: usize, const M: usize, const Q: usize> Map<N> for FaceMap<M, Q> {
    fn new<K: Kernel<N>>(record: &Record<K, N>) -> Self {
        debug_assert!(M == 2 * N - 2 && M <= 4 * Q, "{M} inputs, {Q} lane groups");
        let columns: [[[f64; 4]; Q]; M] = std::array::from_fn(|k| {
            // The unit input `k`: a translation of `b`, or another DOF of `a`, or of `b`.
            let (mut ua, mut ub) = ([0.0; N], [0.0; N]);
            match k {
                0 | 1 => ub[k] = 1.0,
                _ if k < N => ua[k] = 1.0,
                _ => ub[k + 2 - N] = 1.0,
            }
            let [on_a, on_b] = K::face_forces(record, &ua, Some(&ub));
            let mut column = [[0.0; 4]; Q];
            let lanes = column.as_flattened_mut();
            lanes[..N].copy_from_slice(&on_a);
            lanes[N..M].copy_from_slice(&on_b[2..]);
            column
        });
        FaceMap(columns, spread(&columns))
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

    #[inline(always)]
    fn add_internal_wide(
        &self,
        lanes: impl Lanes,
        ua: &Wide<N>,
        ub: &Wide<N>,
        fa: &mut Wide<N>,
        fb: Higher<'_, N>,
    ) {
        let x: Wide<M> = std::array::from_fn(|k| match k {
            0 | 1 => lanes.sub(ub[k], ua[k]),
            _ if k < N => ua[k],
            _ => ub[k + 2 - N],
        });
        let o = lanes.combine_spread(&self.1, &x);
        // `x − o` is `x + (−o)` to the bit.
        let on_b: Wide<N> = std::array::from_fn(|j| match j {
            0 | 1 => o[j],
            _ => lanes.neg(o[N + j - 2]),
        });
        // As `add_internal`: DOF `j` of `b` gets `+o[j]` or `−o[N + j − 2]`.
        match fb {
            Higher::Apart(fb) => {
                let on_b = lanes.narrow(&on_b);
                let (fb, _) = fb.as_flattened_mut().as_chunks_mut::<4>();
                let (on_b, _) = on_b.as_flattened().as_chunks::<4>();
                for (fb, on_b) in fb.iter_mut().zip(on_b) {
                    *fb = lanes.add(*fb, *on_b);
                }
            }
            Higher::ApartWide(fb) => {
                for j in 0..N {
                    fb[j] = lanes.add(fb[j], on_b[j]);
                }
            }
            // Lanes 1–3 get the force of the pair before them first, as in the pairs' order;
            // lane 0 that of the last pair of the four before.
            Higher::Next(carry) => {
                for j in 0..N {
                    fa[j] = lanes.add_carried(fa[j], on_b[j], &mut carry[j]);
                }
            }
        }
        for j in 0..N {
            fa[j] = lanes.sub(fa[j], o[j]);
        }
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
/// A part that lies near a rounding step falls on either side of it from copy to copy, so
/// [`Store::new`] also takes a key one unit from a kept record's key, in each part, for that
/// record: the inner interfaces of the grids in the tests and the bench then name two records,
/// not six at random, and repeat along their rows ([`super::sweep`]'s runs).
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

/// A record's key is compared with those of the first this many records kept, for a key one
/// unit away ([`Store::new`]).
const NEAR: usize = 64;

impl<K: Kernel<N>, const N: usize> Store<K, N> {
    /// The interfaces in sweep order, each naming its index in `records` and `keys`: shared
    /// records when there are [`SHARE_FROM`] interfaces or more and at most half of them need
    /// one of their own, else inline.
    fn new(
        faces: Vec<Face<u32>>,
        records: &[Record<K, N>],
        keys: &[[i64; 11]],
        interior: Interior,
        share: bool,
    ) -> Self {
        let inline = |faces: &[Face<u32>], interior| {
            let inline = faces.iter().map(|f| Face {
                a: f.a,
                b: f.b,
                record: records[f.record as usize],
            });
            Store::Inline(Inline {
                faces: inline.collect(),
                interior,
            })
        };
        if !share || faces.len() < SHARE_FROM {
            return inline(&faces, interior);
        }
        let mut index = std::collections::HashMap::new();
        let (mut shared, mut shared_keys) = (Vec::new(), Vec::new());
        let mut links = Vec::with_capacity(faces.len());
        for f in &faces {
            let k = f.record as usize;
            let record = *index.entry(keys[k]).or_insert_with(|| {
                // A key one unit from a kept one in each part: the same record, whose parts
                // fell on either side of a rounding step ([`share_key`]). Few records to look
                // through on a regular mesh; on another, sharing is given up below.
                let near =
                    |kept: &[i64; 11]| kept.iter().zip(&keys[k]).all(|(x, y)| x.abs_diff(*y) <= 1);
                let found = shared_keys.iter().take(NEAR).position(near);
                found.map_or_else(
                    || {
                        shared.push(records[k]);
                        shared_keys.push(keys[k]);
                        shared.len() as u32 - 1
                    },
                    |r| r as u32,
                )
            });
            if 2 * shared.len() > faces.len() {
                return inline(&faces, interior);
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
            interior,
        })
    }

    /// The bytes of the interfaces and their records.
    fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        match self {
            Store::Inline(s) => size_of_val(&s.faces[..]),
            Store::Shared(s) => {
                size_of_val(&s.faces[..]) + size_of_val(&s.records[..]) + size_of_val(&s.maps[..])
            }
        }
    }
}

/// Element-wise evaluation of eq. 15 for the kinematics `K` with `N` DOFs per element.
pub struct ElementWise<K: Kernel<N>, const N: usize> {
    /// Block after block: its inner interfaces, then the rest, each sorted by `(a, b)`; of a
    /// run of repeating interfaces, those of its first element only ([`Sweep::find_runs`]).
    faces: Store<K, N>,
    /// The blocks and the interfaces that cross them ([`Sweep`]).
    sweep: Sweep<N>,
    /// Where interfaces fail, the faces of the sweeps that step them ([`ByLaw`]).
    by_law: Option<ByLaw<K, N>>,
}

impl<K: Kernel<N>, const N: usize> ElementWise<K, N> {
    /// Face records, blocks and crossing interfaces from the model's interfaces, with the
    /// springs of their laws (`force::failure` adds the plastic part of a law that is not linear).
    pub fn new(model: &Model) -> Self {
        Self::build(model, true, true, false)
    }

    /// [`ElementWise::new`], with shared records only if `share` ([`Store::new`]), and runs of
    /// them only if `runs` ([`Sweep::find_runs`]; never where interfaces fail, whose couplings
    /// the sweep meets one by one, `super::failing`), for a wave if `wave` ([`Sweep::new`]).
    fn build(model: &Model, share: bool, runs: bool, wave: bool) -> Self {
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
                let [k_n, k_s] = model.law_of(i).springs([i.k_n, i.k_s]);
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
        let mut sweep = Sweep::new(model.elements.len(), &mut faces, wave);
        let by_law = model
            .any_fails()
            .then(|| ByLaw::new(model, &faces, &records));
        let interior = Interior(if K::HAS_INTERIOR {
            model
                .elements
                .iter()
                .map(|e| e.d * (model.thickness * e.props.area))
                .collect()
        } else {
            Vec::new()
        });
        let mut faces = Store::new(faces, &records, &keys, interior, share);
        if let (Store::Shared(shared), true) = (&mut faces, runs && by_law.is_none()) {
            sweep.find_runs(&mut shared.faces);
        }
        ElementWise {
            faces,
            sweep,
            by_law,
        }
    }
}

impl<K: Kernel<N>, const N: usize> ElementWise<K, N> {
    fn interior(&self) -> &Interior {
        match &self.faces {
            Store::Inline(s) => &s.interior,
            Store::Shared(s) => &s.interior,
        }
    }

    /// The faces of a sweep that updates the failing interfaces `plastic` in `state`.
    ///
    /// # Panics
    /// If the evaluator was built for a model whose interfaces do not fail, or `plastic` is not
    /// of the formulation `K`.
    fn by_law_sweep<'a>(
        &'a self,
        (plastic, state): Failure<'a>,
        q: Option<&'a Pressures<'a>>,
    ) -> ByLawSweep<'a, K, N> {
        ByLawSweep {
            q,
            by_law: self
                .by_law
                .as_ref()
                .expect("an evaluator built for a model whose interfaces fail"),
            interior: self.interior(),
            failing: failing_of::<K, N>(plastic),
            state,
        }
    }
}

/// The rigid springs of a `rigid-poisson` model, stepped with the Poisson correction's
/// tractions of the cells' `q` (`Corrected`; `super::poisson` computes `q`).
impl ElementWise<Rigid, 3> {
    /// The evaluator of a `rigid-poisson` model: every interface with its record inline, whose
    /// offsets the correction's jump needs; in the larger blocks of a sweep that a wave leads
    /// if `wave`.
    pub fn with_poisson(model: &Model, wave: bool) -> Self {
        Self::build(model, false, false, wave)
    }

    /// The cells whose `q` the sweep's wave leaves out ([`super::sweep::Sweep::border`]).
    pub(super) fn border(&self) -> &[u32] {
        self.sweep.border()
    }

    fn corrected<'a, const WAVE: bool>(&'a self, q: &'a Pressures<'a>) -> Corrected<'a, WAVE> {
        match &self.faces {
            Store::Inline(inline) => Corrected { inline, q },
            Store::Shared(_) => unreachable!("built by `with_poisson`, inline"),
        }
    }

    /// `f = f_int(u)` with the correction's forces of the cells' `q`, the failing interfaces
    /// `failure` return-mapped in the same pass.
    pub(super) fn internal_force_corrected(
        &self,
        u: &[f64],
        f: &mut [f64],
        q: &Pressures<'_>,
        failure: Option<Failure<'_>>,
    ) {
        match failure {
            Some(failure) => self
                .sweep
                .evaluate(&self.by_law_sweep(failure, Some(q)), u, f),
            None if q.wave => self.sweep.evaluate(&self.corrected::<true>(q), u, f),
            None => self.sweep.evaluate(&self.corrected::<false>(q), u, f),
        }
    }

    /// [`FusedStep::advance`] with the correction's forces of the cells' `q` at `u`, the
    /// failing interfaces `failure` return-mapped in the same pass.
    pub(super) fn advance_corrected(
        &self,
        (u, v, force): (&mut [f64], &mut [f64], &mut [f64]),
        loaded: Option<&[u32]>,
        update: &Update,
        q: &Pressures<'_>,
        failure: Option<Failure<'_>>,
    ) -> f64 {
        match failure {
            Some(failure) => {
                let faces = self.by_law_sweep(failure, Some(q));
                self.sweep.advance(&faces, u, v, force, loaded, update)
            }
            None if q.wave => {
                let faces = self.corrected::<true>(q);
                self.sweep.advance(&faces, u, v, force, loaded, update)
            }
            None => {
                let faces = self.corrected::<false>(q);
                self.sweep.advance(&faces, u, v, force, loaded, update)
            }
        }
    }
}

impl<K: Kernel<N>, const N: usize> Evaluator for ElementWise<K, N> {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::ElementWise
    }

    fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        let by_law = self.by_law.as_ref().map_or(0, |b| {
            size_of_val(&b.faces[..])
                + size_of_val(&b.records[..])
                + size_of_val(&b.screens[..])
                + size_of_val(&b.jump_odd[..])
        });
        self.faces.bytes() + size_of_val(&self.interior().0[..]) + self.sweep.bytes() + by_law
    }

    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        match &self.faces {
            Store::Inline(faces) => self.sweep.evaluate(faces, u, f),
            Store::Shared(faces) => self.sweep.evaluate(faces, u, f),
        }
    }

    fn internal_force_failing(&self, u: &[f64], f: &mut [f64], failure: Failure<'_>) {
        self.sweep.evaluate(&self.by_law_sweep(failure, None), u, f);
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
        match &self.faces {
            Store::Inline(faces) => self.sweep.advance(faces, u, v, force, loaded, update),
            Store::Shared(faces) => self.sweep.advance(faces, u, v, force, loaded, update),
        }
    }

    fn advance_failing(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        force: &mut [f64],
        loaded: Option<&[u32]>,
        update: &Update,
        failure: Failure<'_>,
    ) -> f64 {
        let faces = self.by_law_sweep(failure, None);
        self.sweep.advance(&faces, u, v, force, loaded, update)
    }

    fn grouped(&self) -> Option<&dyn GroupedStep> {
        let lanes = matches!(self.faces, Store::Shared(_)) && K::WIDE && self.sweep.in_lanes();
        lanes.then_some(self)
    }
}

impl<K: Kernel<N>, const N: usize> GroupedStep for ElementWise<K, N> {
    fn advance_grouped(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        inv: &[f64],
        force: &mut [f64],
        loaded: &[u32],
        dt: f64,
    ) {
        match &self.faces {
            Store::Inline(faces) => self
                .sweep
                .advance_grouped(faces, u, v, inv, force, loaded, dt),
            Store::Shared(faces) => self
                .sweep
                .advance_grouped(faces, u, v, inv, force, loaded, dt),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::force::evaluator::{stiffness_triplets, Assembled};
    use crate::input::scene::Scene;
    use crate::lanes::Plain;
    use crate::model::formulation::{Hybrid, Rigid};

    /// `f_int` swept by the plain build, block after block.
    fn plain_forces<K: Kernel<N>, const N: usize>(ev: &ElementWise<K, N>, u: &[f64]) -> Vec<f64> {
        match &ev.faces {
            Store::Inline(faces) => ev.sweep.evaluate_plain(faces, u),
            Store::Shared(faces) => ev.sweep.evaluate_plain(faces, u),
        }
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
            assert!(ev.sweep.blocks.len() >= 2 && !ev.sweep.crossing.is_empty());
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

    /// The interfaces of a grid, off the origin so that its geometry carries round-off, share
    /// three records: the step reads at most 12 bytes per interface. The forces are those of each
    /// interface's own record to 1e-12 of their scale, rigid and hybrid, and the same bits on 1
    /// and 2 threads.
    #[test]
    fn a_grid_shares_its_records() {
        fn check<K: Kernel<N>, const N: usize>(model: &Model) {
            let (shared, inline) = (
                ElementWise::<K, N>::new(model),
                ElementWise::<K, N>::build(model, false, false, false),
            );
            let Store::Shared(records) = &shared.faces else {
                panic!("the grid's records are not shared");
            };
            // The two kinds of inner interfaces and the ground springs, despite the round-off of
            // the coordinates.
            assert!(
                records.records.len() == 3,
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

    /// On a grid of four blocks, most elements lie in runs of repeating interfaces, which the
    /// sweep steps through without reading them, four elements at a time in lanes if rigid; on a
    /// strip whose vertical interfaces cross blocks, the top row's runs are entered by those
    /// interfaces midway. The forces and the steps (with loads at some elements, so that some
    /// fours are advanced one by one, damped and not) are the bits of the element-by-element
    /// sweep, rigid and hybrid.
    #[test]
    fn runs_give_the_bits_of_the_element_by_element_sweep() {
        use crate::model::mass::{Mass, Update};
        fn check<K: Kernel<N>, const N: usize>(model: &Model, share: f64) {
            let runs = ElementWise::<K, N>::new(model);
            let each = ElementWise::<K, N>::build(model, true, false, false);
            let n = model.elements.len();
            let (in_runs, in_lanes, entries, _) = runs.sweep.run_elements();
            assert!(
                runs.sweep.blocks.len() >= 4,
                "{} blocks",
                runs.sweep.blocks.len()
            );
            assert!(
                in_runs as f64 >= share * n as f64,
                "{in_runs} of {n} elements in runs"
            );
            // The strip's runs are of width 1 (its vertical interfaces cross blocks): not in
            // lanes. The grid's are, but only rigid ones go in lanes (`Kernel::WIDE`).
            assert!(
                (in_lanes as f64 >= share * n as f64) == (share > 0.5),
                "{in_lanes} of {n} elements in runs that may go in lanes"
            );
            assert_eq!(K::WIDE, N == 3, "rigid runs go in lanes, hybrid ones not");
            assert!(
                share > 0.5 || entries > 0,
                "no coupling enters a ring inside a run"
            );
            let u = displacements(model);
            let (mut f1, mut f2) = (vec![0.0; u.len()], vec![0.0; u.len()]);
            runs.internal_force(&u, &mut f1);
            each.internal_force(&u, &mut f2);
            assert!(f1.iter().zip(&f2).all(|(a, b)| a.to_bits() == b.to_bits()));
            assert!(
                plain_forces(&runs, &u) == f1,
                "the plain build of runs differs"
            );
            let mass = Mass::new(model);
            let loaded: Vec<u32> = (0..n as u32).step_by(7).collect();
            for damping in [(1.0, 1.0), (0.9, 1.0 / 1.1)] {
                let update = Update {
                    mass: &mass,
                    dt: 1e-7,
                    damping,
                };
                let step = |ev: &ElementWise<K, N>| {
                    let (mut u, mut v) = (u.clone(), vec![0.0; u.len()]);
                    let mut power = Vec::new();
                    for _ in 0..3 {
                        let mut force: Vec<f64> = (0..u.len()).map(|i| (i % 11) as f64).collect();
                        for (e, p) in force.as_chunks_mut::<N>().0.iter_mut().enumerate() {
                            if e % 7 != 0 {
                                *p = [0.0; N];
                            }
                        }
                        let p = ev.advance(&mut u, &mut v, &mut force, Some(&loaded), &update);
                        power.push(p);
                    }
                    (u, v, power)
                };
                let (a, b) = (step(&runs), step(&each));
                assert!(a
                    .0
                    .iter()
                    .zip(&b.0)
                    .all(|(x, y)| x.to_bits() == y.to_bits()));
                assert!(a
                    .1
                    .iter()
                    .zip(&b.1)
                    .all(|(x, y)| x.to_bits() == y.to_bits()));
                assert_eq!(a.2, b.2, "the damping's power");
            }
        }
        const STRIP: &str =
            r#"{"kind": "grid", "origin": [0, 0], "size": [50, 0.03], "cells": [5000, 3]}"#;
        check::<Rigid, 3>(&held(GRID, RIGID), 0.9);
        check::<Hybrid, 6>(&held(GRID, HYBRID), 0.9);
        check::<Rigid, 3>(&held(STRIP, RIGID), 0.3);
    }

    /// An interface's [`FaceMap`] gives the forces of its record to round-off, rigid and hybrid,
    /// on every interface of a Voronoi mesh, from both sweeps ([`Plain`] and, where the
    /// processor has it, AVX2) with the same bits.
    #[test]
    fn a_face_map_is_its_record() {
        fn check<K: Kernel<N>, const N: usize>(model: &Model) {
            let Store::Inline(Inline { faces, .. }) = ElementWise::<K, N>::new(model).faces else {
                panic!("a Voronoi mesh's records are shared");
            };
            let u = displacements(model);
            let (u, _) = u.as_chunks::<N>();
            let mut worst = 0.0f64;
            for face in faces.iter().filter(|f| f.b != GROUND) {
                let (ua, ub) = (&u[face.a as usize], &u[face.b as usize]);
                let [on_a, on_b] = K::face_forces(&face.record, ua, Some(ub));
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
                    assert!(got.is_finite() && want.is_finite());
                    worst = worst.max((got + want).abs() / scale);
                }
            }
            assert!(worst <= 1e-12, "relative |Δf| = {worst:e}");
        }
        check::<Rigid, 3>(&held(VORONOI, RIGID));
        check::<Hybrid, 6>(&held(VORONOI, HYBRID));
    }

    /// The rigid form of an interface's forces ([`Kernel::face_forces`] of [`Rigid`]) is the
    /// Gauss rule through the shape matrices ([`gauss_forces`]) to round-off, on every interface
    /// of a Voronoi mesh, to its elements and to the ground: within 1e-12 of the forces' scale,
    /// as [`FaceMap`]s are (1.0e-13 measured).
    #[test]
    fn the_rigid_form_is_the_gauss_rule() {
        let model = held(VORONOI, RIGID);
        let Store::Inline(Inline { faces, .. }) = ElementWise::<Rigid, 3>::new(&model).faces else {
            panic!("a Voronoi mesh's records are shared");
        };
        let u = displacements(&model);
        let (u, _) = u.as_chunks::<3>();
        let (mut worst, mut ground) = (0.0f64, 0);
        for face in faces.iter() {
            let ua = &u[face.a as usize];
            let ub = (face.b != GROUND).then(|| &u[face.b as usize]);
            ground += usize::from(ub.is_none());
            let got = Rigid::face_forces(&face.record, ua, ub);
            let want = gauss_forces(&face.record, ua, ub, None);
            let sides = if ub.is_some() { 2 } else { 1 };
            let scale = want[..sides]
                .as_flattened()
                .iter()
                .fold(0.0f64, |m, x| m.max(x.abs()));
            assert!(scale > 0.0);
            for (g, w) in got[..sides]
                .as_flattened()
                .iter()
                .zip(want[..sides].as_flattened())
            {
                assert!(g.is_finite() && w.is_finite());
                worst = worst.max((g - w).abs() / scale);
            }
        }
        assert!(ground > 0, "no interface to the ground");
        assert!(worst <= 1e-12, "relative |Δf| = {worst:e}");
    }

    /// On a grid of 5000 × 3 cells, in four blocks, an element's upper neighbour lies in the next
    /// block: the rings reach one element (of four slots, the fewest), and the interfaces from
    /// the earlier block enter them
    /// during the sweep. The forces of both evaluators, which share the sweep, still equal `K U`
    /// to round-off, and the rings are left zero.
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
        let sweep = &ev.sweep;
        assert!(sweep.blocks.len() >= 3 && sweep.blocks.iter().all(|b| b.ring == 4));
        let late = sweep.blocks.iter().flat_map(|b| {
            sweep.incoming[b.incoming.clone()]
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
        // `K U` from the scalar triplets of `K`, with no sweep; then both evaluators, whose
        // sweeps take the same late entries.
        let mut fk = vec![0.0; u.len()];
        for (r, c, k) in stiffness_triplets(&model) {
            fk[r] += k * u[c];
        }
        let scale = fk.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let assembled = Assembled::<Rigid, 3>::new(&model);
        for other in [&assembled as &dyn Evaluator, &ev] {
            let mut f = vec![0.0; u.len()];
            other.internal_force(&u, &mut f);
            let diff = fk
                .iter()
                .zip(&f)
                .fold(0.0f64, |m, (a, e)| m.max((a - e).abs()));
            assert!(
                diff <= 1e-12 * scale,
                "{:?}: |Δf| = {diff:e} of {scale:e}",
                other.kind()
            );
        }
        let scratch = sweep.scratch.lock().unwrap();
        assert!(
            scratch
                .rings
                .iter()
                .flat_map(|r| &r.forces)
                .all(|s| *s == [0.0; 3]),
            "a ring was left with a pending force"
        );
    }
}

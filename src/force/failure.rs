//! Interfaces that fail: the plastic part of the internal forces of the interfaces whose law
//! (eq. 11, [`InterfaceLaw`]) is not linear, such as a strength ([`crate::model::law::Strength`]).
//!
//! The traction at a Gauss point is `λ = diag(k_n, k_s) (δ − δ_p)`, so the internal forces
//! split into the elastic ones of the evaluator and a plastic correction:
//! `f_int = f_el(U) − f_p`, `f_p = Σ_gp t w Nᵀ diag(k_n, k_s) δ_p` (eq. 7 with the plastic
//! relative displacements as eigen-displacements). The assembled evaluator keeps its blocks of
//! `K` and adds, in the same pass of its sweep, the failing interfaces of each block
//! ([`FailingInterfaces::couple`]): the relative displacement `δ = N_b U_b − N_a U_a` at each
//! of their two Gauss points, the return mapping of their law ([`InterfaceLaw::update`]) and,
//! once a point has flowed, its share `±N_e(x)ᵀ T_p` of `f_p` (eq. 15), with no stored
//! matrix. The element-wise evaluator has a failing interface give its whole traction
//! `k (δ − δ_p)` the same way ([`FailingInterfaces::couple_whole`]), in place of its elastic
//! record. One pass computes the relative displacement once,
//! in both evaluators, and a time step fuses it with the update of the elements
//! (`evaluator::FusedStep`).
//!
//! A point that has never flowed is in the law's initial state, which the step then does not
//! read: it return-maps a fresh state and keeps it only if the point flows
//! ([`FailureState::touched`], one byte per interface). While a failing scene stays elastic, a
//! step reads the interfaces' geometry and that byte, and writes nothing.
//!
//! Only the interfaces between elements whose law is not linear have points, kept in the order
//! of the sweep ([`Model::failing_interfaces`]); ground springs (supports) keep their law's
//! springs.
//!
//! **Hand-over to contact.** In a scene with edge-to-edge contact a broken interface whose
//! elements have moved apart by more than [`RELEASE`] of its length (in opening or in slip),
//! beyond the range where its linear kinematics hold, is *released*: its springs stop acting
//! (`δ_p` follows `δ`, the traction is zero) and its two elements touch through edge-to-edge
//! contact from then on, so that the fragments the released interfaces cut out collide as
//! blocks (`force::contact`, where every element of a body that fragments is a contact body).
//! The elastic energy the interface still held goes to the contact account
//! ([`FailureState::handover`]); both sides' forces stay equal and opposite, so momentum is
//! kept.

use crate::input::names::named;
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Formulation, Hybrid, Kinematics, Rigid};
use crate::model::law::{InterfaceLaw, LawPoint, Strength};
use crate::model::Model;
use std::any::Any;
use std::marker::PhantomData;
use std::sync::atomic::Ordering::Relaxed;
use std::sync::atomic::{AtomicBool, AtomicU64};
use std::sync::Arc;

/// How far ahead of its use a sweep asks for a failing interface: a stream of 80-byte records
/// crosses a 4 KiB page, where the hardware prefetchers stop, every 51 interfaces.
const PREFETCH_AHEAD: usize = 48;

/// A broken interface is released to contact once its elements have moved apart by more than
/// this fraction of its length.
pub const RELEASE: f64 = 0.01;

/// The radius `r` of the largest disc of tractions `|λ| ≤ r` about the origin inside `law`'s
/// [initial region](InterfaceLaw::initial_region) `σ ≤ cap`, `|τ| ≤ c − σ tan φ`, narrowed by
/// 1e-9 of itself against the round-off of the two ways of computing a traction (its own
/// springs', and the evaluators' records or blocks); negative where the law gives no region.
/// The evaluators screen a fresh interface on it: inside it, its law leaves it elastic.
pub(crate) fn initial_disc(law: &dyn InterfaceLaw) -> f64 {
    law.initial_region().map_or(-1.0, |[cap, c, tan_phi]| {
        cap.min(c / (1.0 + tan_phi * tan_phi).sqrt()) * (1.0 - 1e-9)
    })
}

/// The Poisson correction's pressures `[q_a, q_b]` of a failing interface's two elements
/// (`rigid-poisson`; `None` otherwise): its law acts on `δ + q_a (x − x_a) − q_b (x − x_b)` at
/// each Gauss point, the relative displacement whose springs give the material's traction.
pub type Jump = Option<[f64; 2]>;

/// The state of every Gauss point of the failing interfaces: two per interface, in the order of
/// [`PlasticForces::interfaces`]. A sweep updates it in place through a shared reference, each
/// interface by the one coupling that carries it ([`PointCell`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FailureState {
    /// One per Gauss point.
    pub points: Vec<PointCell>,
    /// Per failing interface, whether it has been released to contact (only in scenes whose
    /// fragments collide, else all false).
    pub released: Vec<bool>,
    /// The elastic energy the released interfaces held when they were released (J): contact
    /// energy from then on.
    pub handover: f64,
    /// Whether the last update released an interface (contact must be told).
    pub changed: bool,
    /// Per failing interface, whether a point of it has left the law's initial state: until
    /// then a step does not read its points (they are `LawPoint::default()`). Follows from
    /// `points`, so not saved ([`FailureState::retouch`]).
    #[serde(skip)]
    pub touched: Vec<Flag>,
}

impl FailureState {
    /// Becomes a copy of `other` in the room it has (the derived `clone_from` would allocate).
    pub fn copy_from(&mut self, other: &FailureState) {
        self.points.clone_from(&other.points);
        self.released.clone_from(&other.released);
        self.touched.clone_from(&other.touched);
        self.handover = other.handover;
        self.changed = other.changed;
    }

    /// Sets [`FailureState::touched`] from the points (a state read back from a checkpoint).
    pub fn retouch(&mut self) {
        let fresh = LawPoint::default();
        self.touched = self
            .points
            .chunks(2)
            .map(|p| Flag::new(p.iter().any(|p| p.get() != fresh)))
            .collect();
    }
}

/// A Gauss point's [`LawPoint`] in cells that a parallel sweep updates through a shared
/// reference: relaxed atomics, which are plain loads and stores, since one thread alone reaches
/// a point in a sweep. Saved and compared as its `LawPoint`.
#[derive(Default)]
pub struct PointCell([AtomicU64; 6]);

impl PointCell {
    /// A cell holding `p`.
    pub fn new(p: &LawPoint) -> Self {
        let cell = PointCell::default();
        cell.set(p);
        cell
    }
    /// The point's state.
    #[inline(always)]
    pub fn get(&self) -> LawPoint {
        let x = self.0.each_ref().map(|x| f64::from_bits(x.load(Relaxed)));
        LawPoint {
            p: [x[0], x[1]],
            kappa: [x[2], x[3]],
            fracture: x[4],
            friction: x[5],
        }
    }
    /// Sets the point's state.
    #[inline(always)]
    pub fn set(&self, p: &LawPoint) {
        let x = [
            p.p[0], p.p[1], p.kappa[0], p.kappa[1], p.fracture, p.friction,
        ];
        for (cell, x) in self.0.iter().zip(x) {
            cell.store(x.to_bits(), Relaxed);
        }
    }
    /// Sets its plastic relative displacement `δ_p`.
    #[inline(always)]
    fn set_p(&self, p: [f64; 2]) {
        self.0[0].store(p[0].to_bits(), Relaxed);
        self.0[1].store(p[1].to_bits(), Relaxed);
    }
}

impl Clone for PointCell {
    fn clone(&self) -> Self {
        PointCell::new(&self.get())
    }
    fn clone_from(&mut self, other: &Self) {
        self.set(&other.get());
    }
}

impl PartialEq for PointCell {
    fn eq(&self, other: &Self) -> bool {
        self.get() == other.get()
    }
}

impl std::fmt::Debug for PointCell {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.get().fmt(f)
    }
}

impl serde::Serialize for PointCell {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.get().serialize(s)
    }
}

impl<'de> serde::Deserialize<'de> for PointCell {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        LawPoint::deserialize(d).map(|p| PointCell::new(&p))
    }
}

/// A flag that a parallel sweep sets through a shared reference ([`PointCell`]).
#[derive(Default)]
pub struct Flag(AtomicBool);

impl Flag {
    /// A flag set to `x`.
    pub fn new(x: bool) -> Self {
        Flag(AtomicBool::new(x))
    }
    /// Whether it is set.
    #[inline(always)]
    pub fn get(&self) -> bool {
        self.0.load(Relaxed)
    }
    #[inline(always)]
    fn set(&self) {
        self.0.store(true, Relaxed);
    }
}

impl Clone for Flag {
    fn clone(&self) -> Self {
        Flag::new(self.get())
    }
}

impl PartialEq for Flag {
    fn eq(&self, other: &Self) -> bool {
        self.get() == other.get()
    }
}

impl std::fmt::Debug for Flag {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.get().fmt(f)
    }
}

named! {
    /// The state of a failing interface, from its two Gauss points; serialised (in
    /// `final_state.json`) as its name. `ALL` is in the order of the crack-frame codes
    /// (`output::vtk::status_code`).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum InterfaceStatus {
        /// No plastic displacement.
        "elastic" => Elastic,
        /// Plastic displacement, strength left.
        "yielding" => Yielding,
        /// Strength exhausted at both Gauss points.
        "broken" => Broken,
        /// Broken and handed over to contact.
        "released" => Released,
    }
}

/// What an interface has done so far, from its two Gauss points.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct InterfaceFailure {
    /// The interface (index in `Model::interfaces`).
    pub interface: usize,
    /// Its state.
    pub status: InterfaceStatus,
    /// Mean plastic opening `δ_p,n` (m): the crack opening.
    pub opening: f64,
    /// Mean plastic slip `δ_p,s` (m).
    pub slip: f64,
    /// Work of the strength and of friction on the interface (J).
    pub dissipated: f64,
}

/// The failing interfaces of a model: their Gauss points' state, its update and what follows
/// from it, for one formulation.
pub trait PlasticForces: Send + Sync {
    /// The failing interfaces (indices in `Model::interfaces`), two Gauss points each, in the
    /// order of [`Model::failing_interfaces`].
    fn interfaces(&self) -> &[u32];
    /// A state with every point elastic.
    fn initial(&self) -> FailureState {
        let n = self.interfaces().len();
        FailureState {
            points: vec![PointCell::default(); 2 * n],
            released: vec![false; n],
            handover: 0.0,
            changed: false,
            touched: vec![Flag::default(); n],
        }
    }
    /// `f −= f_p` at `u`, the Gauss points return-mapped at `u` in `state`: the failing
    /// interfaces one after the other, for an evaluator that does not carry them in its own
    /// pass (`evaluator::Evaluator::internal_force_failing`).
    fn add_plastic(&self, u: &[f64], state: &mut FailureState, f: &mut [f64]);
    /// Whether a step must look for interfaces to release ([`PlasticForces::release`]): some
    /// body fragments.
    fn releases(&self) -> bool;
    /// Hands over to contact the broken interfaces whose elements have moved apart beyond their
    /// range at `u`, the displacements their state was just updated at, setting
    /// [`FailureState::changed`]; `f`, the internal forces at `u`, loses their tractions.
    fn release(&self, u: &[f64], state: &mut FailureState, f: &mut [f64]);
    /// `½ Uᵀ f_int` minus the elastic energy `½ Σ t w (δ − δ_p)ᵀ k (δ − δ_p)` of the failing
    /// interfaces: `½ Σ t w (δ − δ_p)ᵀ k δ_p` (J).
    fn energy_offset(&self, u: &[f64], state: &FailureState) -> f64;
    /// The work of the strengths and of friction so far (J).
    fn dissipated(&self, state: &FailureState) -> [f64; 2];
    /// Each failing interface's status, openings and dissipated work.
    fn report(&self, state: &FailureState) -> Vec<InterfaceFailure>;
    /// Itself, for an evaluator to find its [`FailingInterfaces`] of its own formulation.
    fn as_any(&self) -> &dyn Any;
}

/// The failing interfaces of `model`; `None` when no interface can fail.
pub fn build(model: &Model) -> Option<Box<dyn PlasticForces>> {
    if !model.any_fails() {
        return None;
    }
    Some(match model.formulation {
        Formulation::Rigid | Formulation::RigidPoisson => {
            Box::new(FailingInterfaces::<Rigid, 3>::new(model))
        }
        Formulation::Hybrid { .. } => Box::new(FailingInterfaces::<Hybrid, 6>::new(model)),
    })
}

/// A failing interface, seen from its lower element `a` (the sides of a model interface with
/// `b < a` are swapped, and its axes turned with them: `δ_n` and `δ_s` are the same); 80
/// bytes, which a step reads (the coupling that carries it knows `a` and `b`).
#[derive(Debug, Clone, Copy)]
struct Failing {
    /// Its law, in `FailingInterfaces::laws` (an index: the interfaces stay small).
    law: u32,
    /// The edge's midpoint from the centroids of `a` and `b` (m).
    da: Vec2,
    db: Vec2,
    /// Unit normal from `a` to `b`; the tangent `s` is `(n_y, −n_x)` (`n = ẑ × s`).
    normal: Vec2,
    /// Elastic springs `(k_n, k_s)` (Pa/m).
    k: [f64; 2],
    /// `t w`: thickness times the Gauss weight `L/2` (m²).
    tw: f64,
}

impl Failing {
    #[inline(always)]
    fn tangent(&self) -> Vec2 {
        Vec2::new(self.normal.y, -self.normal.x)
    }

    /// The Gauss offset `g = L/(2√3) s`: the Gauss points are at the midpoint `∓ g`.
    #[inline(always)]
    fn gauss_offset(&self, half_per_tw: f64) -> Vec2 {
        (half_per_tw * self.tw) * self.tangent()
    }

    /// `δ = N_b U_b − N_a U_a` at both Gauss points on the interface's axes `(δ_n, δ_s)`, from
    /// the jump at the midpoint and its linear part over the Gauss offset: `δ₀ ∓ δ₁` (the jump
    /// is affine along the edge).
    #[inline(always)]
    fn deltas<K: Kinematics<N>, const N: usize>(
        &self,
        half_per_tw: f64,
        ua: &[f64; N],
        ub: &[f64; N],
    ) -> [[f64; 2]; 2] {
        let (n, s, g) = (self.normal, self.tangent(), self.gauss_offset(half_per_tw));
        let d0 = K::displacement(ub, self.db) - K::displacement(ua, self.da);
        let d1 = K::gradient(ub, g) - K::gradient(ua, g);
        let (d0, d1) = ([n.dot(&d0), s.dot(&d0)], [n.dot(&d1), s.dot(&d1)]);
        [
            [d0[0] - d1[0], d0[1] - d1[1]],
            [d0[0] + d1[0], d0[1] + d1[1]],
        ]
    }

    /// `deltas` with the Poisson correction's jump `q_a (x − x_a) − q_b (x − x_b)` added at
    /// each Gauss point `x = m ∓ g` (`rigid-poisson`, [`crate::model::poisson`]): the relative
    /// displacement whose springs' traction is the material's, which the law bounds.
    #[inline(always)]
    fn jumped(&self, half_per_tw: f64, deltas: [[f64; 2]; 2], [qa, qb]: [f64; 2]) -> [[f64; 2]; 2] {
        let (n, s, g) = (self.normal, self.tangent(), self.gauss_offset(half_per_tw));
        let (j0, j1) = (qa * self.da - qb * self.db, (qa - qb) * g);
        let (j0, j1) = ([n.dot(&j0), s.dot(&j0)], [n.dot(&j1), s.dot(&j1)]);
        let [d0, d1] = deltas;
        [
            [d0[0] + j0[0] - j1[0], d0[1] + j0[1] - j1[1]],
            [d1[0] + j0[0] + j1[0], d1[1] + j0[1] + j1[1]],
        ]
    }

    /// `T = t w (k_n e_n n + k_s e_s s)`: the force of the springs at a relative displacement
    /// `e` on the interface's axes (`δ − δ_p`, or `−δ_p` for the plastic part alone).
    #[inline(always)]
    fn traction(&self, e: &[f64; 2]) -> Vec2 {
        self.tw * (self.k[0] * e[0] * self.normal + self.k[1] * e[1] * self.tangent())
    }
}

/// The failing interfaces of a model with kinematics `K`, in the order of
/// [`Model::failing_interfaces`].
pub struct FailingInterfaces<K: Kinematics<N>, const N: usize> {
    failing: Vec<Failing>,
    /// The lower and higher element of each.
    pairs: Vec<[u32; 2]>,
    /// The model's laws ([`Model::laws`]), then its default law.
    laws: Vec<Arc<dyn InterfaceLaw>>,
    /// Each law [as the crate's `Strength`](InterfaceLaw::as_strength), which the steps
    /// return-map in line: through the seam, a point's state goes to the stack and back (the
    /// cracking 10⁵-element rigid panel of `cargo bench --bench failure`, element-wise, one
    /// thread, stepped in turns with the elastic panel by a driver not kept: 154–160 ns per
    /// element-step through the seam, 133–144 in line; the bench's own run, 147 in line).
    strengths: Vec<Option<Strength>>,
    /// Each law's [`InterfaceLaw::initial_region`], or one that holds no traction.
    regions: Vec<[f64; 3]>,
    interfaces: Vec<u32>,
    /// `L/(2√3)` over `t w`: the Gauss offset from the weight.
    half_per_tw: f64,
    /// Per failing interface, the separation beyond which a broken one is released (m):
    /// [`RELEASE`] of its length where its body fragments (`Model::fragments`), else infinite;
    /// empty when no body fragments (then no step looks for releases).
    release: Vec<f64>,
    kinematics: PhantomData<K>,
}

impl<K: Kinematics<N>, const N: usize> FailingInterfaces<K, N> {
    fn new(model: &Model) -> Self {
        let mut laws = model.laws.clone();
        laws.push(model.law.clone());
        let interfaces = model.failing_interfaces();
        let centroid = |e: u32| model.elements[e as usize].props.centroid;
        let fragments: Vec<bool> = (0..model.bodies.len())
            .map(|b| model.fragments(b))
            .collect();
        let mut release = Vec::with_capacity(interfaces.len());
        let mut pairs = Vec::with_capacity(interfaces.len());
        let failing = interfaces
            .iter()
            .map(|&k| {
                let i = &model.interfaces[k as usize];
                // The model's laws, then its default law (`laws`).
                let law = match i.law {
                    crate::model::DEFAULT_LAW => model.laws.len() as u32,
                    k => k,
                };
                let body = model.elements[i.a as usize].body as usize;
                release.push(if fragments[body] {
                    RELEASE * i.length
                } else {
                    f64::INFINITY
                });
                let (a, b, normal) = if i.a < i.b {
                    (i.a, i.b, i.normal)
                } else {
                    (i.b, i.a, -i.normal)
                };
                let mid = i.midpoint();
                pairs.push([a, b]);
                Failing {
                    law,
                    da: mid - centroid(a),
                    db: mid - centroid(b),
                    normal,
                    k: laws[law as usize].springs([i.k_n, i.k_s]),
                    tw: model.thickness * 0.5 * i.length,
                }
            })
            .collect();
        if release.iter().all(|r| r.is_infinite()) {
            release.clear();
        }
        FailingInterfaces {
            failing,
            pairs,
            regions: laws
                .iter()
                .map(|l| l.initial_region().unwrap_or([f64::NEG_INFINITY, 0.0, 0.0]))
                .collect(),
            strengths: laws.iter().map(|l| l.as_strength().copied()).collect(),
            laws,
            interfaces,
            half_per_tw: 1.0 / (3f64.sqrt() * model.thickness),
            release,
            kinematics: PhantomData,
        }
    }

    /// The failing interfaces `range` of one coupling between `a` (DOFs `ua`) and `b` (`ub`),
    /// `a < b`, in `state`: each Gauss point's relative displacement, the return mapping of its
    /// law, and `f_int,a += N_aᵀ T_p`, `f_int,b −= N_bᵀ T_p` for the points that have flowed.
    /// A sweep calls it once per interface, from one thread: the points of `range` are its
    /// alone ([`PointCell`]). Under the Poisson correction, `jump` holds the cells' `q_a`, `q_b`:
    /// the law acts on the jumped relative displacement ([`Jump`]).
    #[inline(always)]
    pub fn couple(
        &self,
        range: std::ops::Range<usize>,
        state: &FailureState,
        (ua, ub): (&[f64; N], &[f64; N]),
        jump: Jump,
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        self.prefetch(range.start);
        for j in range {
            let f = &self.failing[j];
            let delta = self.delta(f, ua, ub, jump);
            if let Some(p) = self.plastic(j, delta, state) {
                self.add_forces(f, p.map(|p| [-p[0], -p[1]]), fa, fb);
            }
        }
    }

    /// The whole traction of failing interface `j` between `a` (DOFs `ua`) and `b` (`ub`),
    /// `a < b`, in `state`: `f_int,a −= N_aᵀ T`, `f_int,b += N_bᵀ T` with
    /// `T = t w diag(k_n, k_s) (δ − δ_p)` at each Gauss point, the elastic and the plastic part
    /// of [`FailingInterfaces::couple`] in one, for a sweep that keeps no elastic record of the
    /// interface (element-wise); under the Poisson correction `T` is the material's traction
    /// `t w S (δ + j − δ_p)` with its jump `j` ([`Jump`]). Called as `couple`.
    #[inline(always)]
    pub fn couple_whole(
        &self,
        j: usize,
        state: &FailureState,
        (ua, ub): (&[f64; N], &[f64; N]),
        jump: Jump,
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        let f = &self.failing[j];
        let delta = self.delta(f, ua, ub, jump);
        let elastic = match self.plastic(j, delta, state) {
            // `δ − 0` is `δ` to the bit: a point in its initial region is not return-mapped,
            // and gives the same forces as one that is and does not flow.
            None => delta,
            Some(p) => [0, 1].map(|g| [delta[g][0] - p[g][0], delta[g][1] - p[g][1]]),
        };
        self.add_forces(f, elastic, fa, fb);
    }

    /// The relative displacements at the Gauss points of `f`, jumped by `jump`.
    #[inline(always)]
    fn delta(&self, f: &Failing, ua: &[f64; N], ub: &[f64; N], jump: Jump) -> [[f64; 2]; 2] {
        let delta = f.deltas::<K, N>(self.half_per_tw, ua, ub);
        match jump {
            Some(q) => f.jumped(self.half_per_tw, delta, q),
            None => delta,
        }
    }

    /// `moments[e]`: the first moment `Σ_gp (L/2) (x − x_e)·S δ_p` of the plastic relative
    /// displacements on element `e`'s failing facets, per unit thickness (`+` on the lower
    /// element, as [`crate::model::poisson`]'s `s`), in model `thickness`. What the Poisson
    /// correction's `s = G U` loses to them: a cell reads its strain from the springs'
    /// tractions `S (δ − δ_p)`, so that an open crack is not a strain of its cells. In the order
    /// of the failing interfaces, on one thread: the same bits on any number of threads.
    pub(crate) fn plastic_moments(
        &self,
        state: &FailureState,
        thickness: f64,
        moments: &mut [f64],
    ) {
        moments.fill(0.0);
        for (k, f) in self.failing.iter().enumerate() {
            if !state.touched[k].get() {
                continue;
            }
            let g = f.gauss_offset(self.half_per_tw);
            let [a, b] = self.pairs[k].map(|e| e as usize);
            for (point, off) in state.points[2 * k..2 * k + 2].iter().zip([-g, g]) {
                let t = f.traction(&point.get().p) / thickness;
                moments[a] += (f.da + off).dot(&t);
                moments[b] -= (f.db + off).dot(&t);
            }
        }
    }

    /// Whether failing interface `j` is in its initial state in `state`: never flowed, not
    /// released.
    #[inline(always)]
    pub(crate) fn is_fresh(&self, j: usize, state: &FailureState) -> bool {
        !state.touched[j].get() && (self.release.is_empty() || !state.released[j])
    }

    /// Asks for the failing interface `PREFETCH_AHEAD` after `j`.
    #[inline(always)]
    pub(crate) fn prefetch(&self, _j: usize) {
        #[cfg(target_arch = "x86_64")]
        if let Some(ahead) = self.failing.get(_j + PREFETCH_AHEAD) {
            safe_arch::prefetch_t0(ahead);
        }
    }

    /// `f_int,a −= N_aᵀ T`, `f_int,b += N_bᵀ T` with `T = t w diag(k_n, k_s) e` at the Gauss
    /// points of `f`, for a relative displacement `e` on its axes at each. `N` is affine in the
    /// offset, so over the points `d ∓ g` the sum is `N(d)ᵀ (T₀ + T₁) + (N(g) − N(0))ᵀ (T₁ − T₀)`.
    #[inline(always)]
    fn add_forces(&self, f: &Failing, e: [[f64; 2]; 2], fa: &mut [f64; N], fb: &mut [f64; N]) {
        let (t0, t1) = (f.traction(&e[0]), f.traction(&e[1]));
        let (sum, odd) = (t0 + t1, t1 - t0);
        let g = f.gauss_offset(self.half_per_tw);
        K::add_force(fa, f.da, -sum);
        K::add_linear(fa, g, -odd);
        K::add_force(fb, f.db, sum);
        K::add_linear(fb, g, odd);
    }

    /// The plastic relative displacements of failing interface `j` at relative displacements
    /// `delta`, its points return-mapped and their state updated; `None` while both points are
    /// in the initial state and stay there: a fresh interface inside its law's initial region
    /// at both points (the quick test: nothing to read, write or add), or one whose fresh
    /// points the law leaves elastic.
    #[inline(always)]
    fn plastic(
        &self,
        j: usize,
        delta: [[f64; 2]; 2],
        state: &FailureState,
    ) -> Option<[[f64; 2]; 2]> {
        if self.is_fresh(j, state) {
            let f = &self.failing[j];
            let [cap, c, tan_phi] = self.regions[f.law as usize];
            let inside = |d: &[f64; 2]| {
                let (sigma, tau) = (f.k[0] * d[0], f.k[1] * d[1]);
                sigma <= cap && tau.abs() <= c - sigma * tan_phi
            };
            if inside(&delta[0]) && inside(&delta[1]) {
                return None;
            }
        }
        self.flow(j, delta, state)
    }

    /// [`FailingInterfaces::plastic`] outside the quick test: the return mapping of the points
    /// of interface `j` at relative displacements `delta`.
    #[inline(never)]
    fn flow(&self, j: usize, delta: [[f64; 2]; 2], state: &FailureState) -> Option<[[f64; 2]; 2]> {
        let law = self.failing[j].law as usize;
        match &self.strengths[law] {
            Some(strength) => self.flow_by(strength, j, delta, state),
            None => self.flow_by(&*self.laws[law], j, delta, state),
        }
    }

    /// [`FailingInterfaces::flow`] by the law `law` of interface `j`.
    #[inline(always)]
    fn flow_by<L: InterfaceLaw + ?Sized>(
        &self,
        law: &L,
        j: usize,
        delta: [[f64; 2]; 2],
        state: &FailureState,
    ) -> Option<[[f64; 2]; 2]> {
        let f = &self.failing[j];
        let (cells, touched) = (&state.points[2 * j..2 * j + 2], &state.touched[j]);
        let mut p = [[0.0; 2]; 2];
        if !self.release.is_empty() && state.released[j] {
            p = delta;
            for g in 0..2 {
                cells[g].set_p(p[g]);
            }
        } else if touched.get() {
            for g in 0..2 {
                let mut point = cells[g].get();
                if law.update(f.k, delta[g], &mut point).1 {
                    cells[g].set(&point);
                }
                p[g] = point.p;
            }
        } else {
            for g in 0..2 {
                let mut point = LawPoint::default();
                if law.update(f.k, delta[g], &mut point).1 {
                    cells[g].set(&point);
                    touched.set();
                }
                p[g] = point.p;
            }
            if !touched.get() {
                return None;
            }
        }
        Some(p)
    }
}

impl<K: Kinematics<N>, const N: usize> PlasticForces for FailingInterfaces<K, N> {
    fn interfaces(&self) -> &[u32] {
        &self.interfaces
    }

    fn releases(&self) -> bool {
        !self.release.is_empty()
    }

    fn add_plastic(&self, u: &[f64], state: &mut FailureState, f: &mut [f64]) {
        let (u, _) = u.as_chunks::<N>();
        let (f, _) = f.as_chunks_mut::<N>();
        for (j, &[a, b]) in self.pairs.iter().enumerate() {
            let (a, b) = (a as usize, b as usize);
            let (mut fa, mut fb) = ([0.0; N], [0.0; N]);
            self.couple(j..j + 1, state, (&u[a], &u[b]), None, &mut fa, &mut fb);
            for r in 0..N {
                f[a][r] += fa[r];
                f[b][r] += fb[r];
            }
        }
    }

    fn release(&self, u: &[f64], state: &mut FailureState, f: &mut [f64]) {
        let (u, _) = u.as_chunks::<N>();
        let (f, _) = f.as_chunks_mut::<N>();
        state.changed = false;
        for (k, &range) in self.release.iter().enumerate() {
            if range.is_infinite() || state.released[k] {
                continue;
            }
            let (i, s) = (&self.failing[k], &state.points[2 * k..2 * k + 2]);
            let law = &*self.laws[i.law as usize];
            if !s.iter().all(|s| law.is_broken(&s.get())) {
                continue;
            }
            let [a, b] = self.pairs[k].map(|e| e as usize);
            let d = i.deltas::<K, N>(self.half_per_tw, &u[a], &u[b]);
            if (0..2).any(|c| (0.5 * (d[0][c] + d[1][c])).abs() > range) {
                // `δ_p` goes from `p` to `δ`: the plastic forces grow by those of `e = δ − p`.
                let mut grow = [[0.0; 2]; 2];
                for g in 0..2 {
                    let p = s[g].get().p;
                    let e = [d[g][0] - p[0], d[g][1] - p[1]];
                    state.handover += 0.5 * i.tw * (i.k[0] * e[0] * e[0] + i.k[1] * e[1] * e[1]);
                    s[g].set_p(d[g]);
                    grow[g] = [-e[0], -e[1]];
                }
                let (below, from_b) = f.split_at_mut(b);
                self.add_forces(i, grow, &mut below[a], &mut from_b[0]);
                state.released[k] = true;
                state.touched[k].set();
                state.changed = true;
            }
        }
    }

    fn energy_offset(&self, u: &[f64], state: &FailureState) -> f64 {
        let (u, _) = u.as_chunks::<N>();
        let mut offset = 0.0;
        for (k, f) in self.failing.iter().enumerate() {
            if !state.touched[k].get() {
                continue;
            }
            let [a, b] = self.pairs[k].map(|e| e as usize);
            let (ua, ub) = (&u[a], &u[b]);
            let deltas = f.deltas::<K, N>(self.half_per_tw, ua, ub);
            for (g, d) in deltas.iter().enumerate() {
                let p = state.points[2 * k + g].get().p;
                offset += 0.5 * f.tw * (0..2).map(|c| (d[c] - p[c]) * f.k[c] * p[c]).sum::<f64>();
            }
        }
        offset
    }

    fn dissipated(&self, state: &FailureState) -> [f64; 2] {
        state
            .points
            .chunks(2)
            .zip(&self.failing)
            .flat_map(|(s, f)| s.iter().map(move |s| (f.tw, s.get())))
            .fold([0.0; 2], |[a, b], (tw, s)| {
                [a + tw * s.fracture, b + tw * s.friction]
            })
    }

    fn report(&self, state: &FailureState) -> Vec<InterfaceFailure> {
        self.interfaces
            .iter()
            .zip(&self.failing)
            .enumerate()
            .map(|(k, (&i, f))| {
                let s = [0, 1].map(|g| state.points[2 * k + g].get());
                let law = &*self.laws[f.law as usize];
                let broken = s.iter().all(|s| law.is_broken(s));
                let plastic = s.iter().any(|s| s.p != [0.0; 2]);
                InterfaceFailure {
                    interface: i as usize,
                    status: if state.released[k] {
                        InterfaceStatus::Released
                    } else if broken {
                        InterfaceStatus::Broken
                    } else if plastic {
                        InterfaceStatus::Yielding
                    } else {
                        InterfaceStatus::Elastic
                    },
                    opening: 0.5 * (s[0].p[0] + s[1].p[0]),
                    slip: 0.5 * (s[0].p[1] + s[1].p[1]),
                    dissipated: s.iter().map(|s| f.tw * (s.fracture + s.friction)).sum(),
                }
            })
            .collect()
    }

    fn as_any(&self) -> &dyn Any {
        self
    }
}

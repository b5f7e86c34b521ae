//! The Poisson correction's forces (formulation `rigid-poisson`, [`crate::model::poisson`]) in
//! the two evaluators' manners, with the rigid springs in their sweep. A cell's `q = Λ G U^n`
//! needs its neighbours' `U^n`, and an element's force its neighbours' `q`:
//!
//! 1. the cells' `q` ([`Pressures`]): each cell sums the first moment `s` of its facets' spring
//!    tractions from its own and its neighbours' `U`. Gathered before the sweep, cell by cell,
//!    through each facet's coefficients integrated in closed form once (`G` by block rows,
//!    [`FacetPressures`]); or, in the element-wise sweep of a mesh of [`WAVE_FROM`] elements or
//!    more, by a wave that leads the sweep ([`super::sweep`]) and takes each interface's shares
//!    `d_a · T` and `−d_b · T` from the record the sweep reads next, `T = t L S δ₀` the
//!    midpoint traction of its springs: only the cells with interfaces across the sweep's
//!    blocks are gathered before it;
//! 2. the rigid springs' sweep with the correction's forces, each element advanced as soon as
//!    its force is complete: element-wise ([`ElementWisePoisson`]) each interface's springs get
//!    the jump the correction adds, `q_a (x − x_a) − q_b (x − x_b)`, so that its traction is
//!    the material's; assembled ([`AssembledPoisson`]) `f += t Gᵀ q` with `G`'s entries from its
//!    compressed rows ([`PressureOperator`]), pair by pair with `K_ab`: `t ∂s_b/∂U_a q_b` to
//!    `a`, `t ∂s_a/∂U_b q_a` to `b`, and `t ∂s_e/∂U_e q_e` to each element last.
//!
//! `t Gᵀ Λ G` is the correction's part of `K` ([`PressureOperator::triplets`]). `q` is kept in
//! a buffer of its own (locked for an evaluation, no allocation), each cell's computed in an
//! order fixed by the mesh, so the result does not depend on the thread count.

use super::assembled::Block;
use super::failing::{failing_of, Carrying, WithFailure};
use super::sweep::{place, Couplings, Face};
use crate::force::evaluator::{Assembled, ElementWise, Evaluator, Failure, FusedStep};
use crate::force::failure::{FailureState, PlasticForces};
use crate::input::scene::EvaluatorKind;
use crate::lanes::Lanes;
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Kinematics, Rigid};
use crate::model::mass::Update;
use crate::model::poisson::{load_moment, springs, Poisson};
use crate::model::{Model, GROUND};
use crate::parallel::{for_each_chunk, CHUNK};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// A rigid evaluator that steps with the Poisson correction's forces of the cells' `q`.
pub trait Correction: Send + Sync {
    /// Which evaluator this is.
    fn kind(&self) -> EvaluatorKind;
    /// `f = f_int(u)`: the springs' forces and the correction's of `q`, the failing
    /// interfaces `failure` return-mapped in the same pass, their laws acting on the jump of `q`.
    fn internal_force(
        &self,
        u: &[f64],
        f: &mut [f64],
        q: &Pressures<'_>,
        failure: Option<Failure<'_>>,
    );
    /// [`FusedStep::advance`] (or [`FusedStep::advance_failing`]) with the correction's forces
    /// of `q`.
    fn advance(
        &self,
        state: (&mut [f64], &mut [f64], &mut [f64]),
        loaded: Option<&[u32]>,
        update: &Update,
        q: &Pressures<'_>,
        failure: Option<Failure<'_>>,
    ) -> f64;
    /// Bytes it reads in an evaluation.
    fn bytes(&self) -> usize;
    /// The cells whose `q` its sweep's wave leaves to [`Pressures`]' caller, in order
    /// ([`super::sweep::Sweep::border`]); `None` if no wave leads its sweep, which reads the
    /// `q` of every cell.
    fn border(&self) -> Option<&[u32]>;
}

/// The cells' `q` of an evaluation, `q_e = Λ_e (s_e − s_p,e)` with `s_e` the first moment of
/// element `e`'s spring tractions per unit thickness and `s_p` the plastic moments of failing
/// interfaces (empty where none fail). The cells with couplings across the sweep's blocks get
/// theirs before the sweeps (gathered through [`FacetPressures`]); the others from the
/// sweep's leading wave, which hands each its sum `t s_e` (`done`) before any of the sweep's
/// couplings reads it, and after no element it reads has moved. Written by one block's task
/// and read by it (a cell's `q` in another block is read only by the crossing couplings,
/// computed before the sweeps), so relaxed atomics order them.
pub struct Pressures<'a> {
    q: &'a [AtomicU64],
    scale: &'a [f64],
    plastic: &'a [f64],
    per_thickness: f64,
    /// Whether the sweep's wave gives the `q` of the cells not gathered before it.
    pub(super) wave: bool,
}

impl Pressures<'_> {
    /// Cell `e`'s `q`.
    #[inline(always)]
    pub(super) fn get(&self, e: usize) -> f64 {
        f64::from_bits(self.q[e].load(Ordering::Relaxed))
    }
    /// Cell `e`'s `q` from the sum `ts = t s_e` of its facets' shares.
    #[inline(always)]
    pub(super) fn done(&self, e: usize, ts: f64) {
        self.set(e, ts * self.per_thickness);
    }
    /// Cell `e`'s `q` from its first moment `s` per unit thickness.
    #[inline(always)]
    fn set(&self, e: usize, s: f64) {
        let q = pressure(self.scale[e], s, self.plastic.get(e));
        self.q[e].store(q.to_bits(), Ordering::Relaxed);
    }
}

/// The rigid springs' evaluator with the Poisson correction: the cells' `q` (`G` by block rows),
/// then the sweep.
pub struct WithPoisson<C: Correction> {
    rows: FacetPressures,
    correction: C,
    cells: Mutex<Cells>,
    thickness: f64,
}

/// The cells' buffers of an evaluation: `q` ([`Pressures`]), and where interfaces fail the
/// plastic moments `s_p` that `s = G U − s_p` loses.
struct Cells {
    q: Vec<AtomicU64>,
    plastic: Vec<f64>,
}

/// `q = Λ (s − s_p)` of a cell with scale `Λ`, first moment `s` and plastic moment `s_p`, if
/// its interfaces fail.
#[inline(always)]
fn pressure(scale: f64, s: f64, plastic: Option<&f64>) -> f64 {
    scale
        * match plastic {
            Some(p) => s - p,
            None => s,
        }
}

impl<C: Correction> WithPoisson<C> {
    /// The evaluator `correction` of `model`.
    pub fn new(model: &Model, correction: C) -> Self {
        let n = model.elements.len();
        let failing = if model.any_fails() { n } else { 0 };
        WithPoisson {
            rows: FacetPressures::new(model),
            correction,
            cells: Mutex::new(Cells {
                q: (0..n).map(|_| AtomicU64::new(0)).collect(),
                plastic: vec![0.0; failing],
            }),
            thickness: model.thickness,
        }
    }

    /// The cells' buffers with the plastic moments of the failing interfaces in `failure`'s
    /// state and the `q` at `u` of the cells on the sweep's borders, whose sweep gives the
    /// others (a poisoned lock only means another evaluation panicked; the buffers are
    /// scratch).
    fn cells(&self, u: &[f64], failure: Option<&Failure<'_>>) -> std::sync::MutexGuard<'_, Cells> {
        let mut cells = self.cells.lock().unwrap_or_else(|e| e.into_inner());
        let Cells {
            q,
            plastic: moments,
        } = &mut *cells;
        if let Some((plastic, state)) = failure {
            failing_of::<Rigid, 3>(*plastic).plastic_moments(state, self.thickness, moments);
        }
        let failing = failure.is_some();
        match self.border(failing) {
            Some(border) => self
                .rows
                .border(u, border, &self.pressures(q, moments, failing)),
            None => self.rows.fill(u, if failing { moments } else { &[] }, q),
        }
        cells
    }

    /// The cells that the wave of the sweep leaves out, `None` if none leads it: where
    /// interfaces fail the sweep gathers (its faces name their records by index, which a wave
    /// would read a second time out of order: `cargo bench --bench failure` stepped a failing
    /// 10⁵-element panel that stays elastic in 118 ns per element led, 68 ns gathered, on one
    /// thread).
    fn border(&self, failing: bool) -> Option<&[u32]> {
        match failing {
            true => None,
            false => self.correction.border(),
        }
    }

    /// The cells' [`Pressures`] in `cells`' buffers, less the plastic moments if `failing`.
    fn pressures<'a>(
        &'a self,
        q: &'a [AtomicU64],
        plastic: &'a [f64],
        failing: bool,
    ) -> Pressures<'a> {
        Pressures {
            q,
            scale: &self.rows.scale,
            plastic: if failing { plastic } else { &[] },
            per_thickness: 1.0 / self.thickness,
            wave: self.border(failing).is_some(),
        }
    }
}

impl<C: Correction> Evaluator for WithPoisson<C> {
    fn kind(&self) -> EvaluatorKind {
        self.correction.kind()
    }
    fn internal_force(&self, u: &[f64], f: &mut [f64]) {
        let cells = self.cells(u, None);
        let q = self.pressures(&cells.q, &cells.plastic, false);
        self.correction.internal_force(u, f, &q, None);
    }
    fn internal_force_failing(&self, u: &[f64], f: &mut [f64], failure: Failure<'_>) {
        let cells = self.cells(u, Some(&failure));
        let q = self.pressures(&cells.q, &cells.plastic, true);
        self.correction.internal_force(u, f, &q, Some(failure));
    }
    /// `½ t Σ_c (q_c (G U)_c − Λ_c s_c²)`, `q` of the last evaluation (at `u`) and
    /// `s = G U − s_p` with the plastic moments of `state`: `½ Uᵀ f_P` less the correction's
    /// energy `½ t Σ Λ s²`.
    fn energy_offset(
        &self,
        u: &[f64],
        (plastic, state): (&dyn PlasticForces, &FailureState),
    ) -> f64 {
        let mut cells = self.cells.lock().unwrap_or_else(|e| e.into_inner());
        let Cells {
            q,
            plastic: moments,
        } = &mut *cells;
        failing_of::<Rigid, 3>(plastic).plastic_moments(state, self.thickness, moments);
        let (u, _) = u.as_chunks::<3>();
        let offset: f64 = (0..q.len())
            .map(|e| {
                let (m, s) = (self.rows.moment(e, u), self.rows.scale[e]);
                let q = f64::from_bits(q[e].load(Ordering::Relaxed));
                q * m - s * (m - moments[e]) * (m - moments[e])
            })
            .sum();
        0.5 * self.thickness * offset
    }
    fn bytes(&self) -> usize {
        self.rows.bytes() + self.correction.bytes()
    }
    fn fused(&self) -> Option<&dyn FusedStep> {
        Some(self)
    }
}

impl<C: Correction> FusedStep for WithPoisson<C> {
    fn advance(
        &self,
        u: &mut [f64],
        v: &mut [f64],
        force: &mut [f64],
        loaded: Option<&[u32]>,
        update: &Update,
    ) -> f64 {
        let cells = self.cells(u, None);
        let q = self.pressures(&cells.q, &cells.plastic, false);
        self.correction
            .advance((u, v, force), loaded, update, &q, None)
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
        let cells = self.cells(u, Some(&failure));
        let q = self.pressures(&cells.q, &cells.plastic, true);
        self.correction
            .advance((u, v, force), loaded, update, &q, Some(failure))
    }
}

/// The element-wise sweep of a `rigid-poisson` model: the rigid springs with the correction's
/// jump on each interface, led by the cells' wave on a large mesh.
pub struct ElementWisePoisson {
    springs: ElementWise<Rigid, 3>,
    wave: bool,
}

/// The fewest elements whose element-wise sweep a wave leads (its cells' `q`). The wave reads
/// each interface's record once with the sweep where the gather reads `G`'s coefficients too
/// (`cargo bench --bench formulations`: 2.1–2.2 → 1.7–1.8 × the rigid step at 10⁶ elements,
/// out of the cache), but it does more arithmetic (2.3–2.4 × at 10⁴, where the data stay in
/// the cache, against 2.0–2.1 × with the gather). Between 10⁴ and 10⁵, not tuned.
pub const WAVE_FROM: usize = 50_000;

impl ElementWisePoisson {
    /// The evaluator of a `rigid-poisson` model, led by the wave from [`WAVE_FROM`] elements.
    pub fn new(model: &Model) -> Self {
        Self::with_wave(model, model.elements.len() >= WAVE_FROM)
    }

    /// The evaluator of a `rigid-poisson` model, its sweep led by the cells' wave if `wave`,
    /// else after every cell's `q` gathered.
    pub fn with_wave(model: &Model, wave: bool) -> Self {
        ElementWisePoisson {
            springs: ElementWise::with_poisson(model, wave),
            wave,
        }
    }
}

impl Correction for ElementWisePoisson {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::ElementWise
    }
    fn internal_force(
        &self,
        u: &[f64],
        f: &mut [f64],
        q: &Pressures<'_>,
        failure: Option<Failure<'_>>,
    ) {
        self.springs.internal_force_corrected(u, f, q, failure);
    }
    fn advance(
        &self,
        state: (&mut [f64], &mut [f64], &mut [f64]),
        loaded: Option<&[u32]>,
        update: &Update,
        q: &Pressures<'_>,
        failure: Option<Failure<'_>>,
    ) -> f64 {
        self.springs
            .advance_corrected(state, loaded, update, q, failure)
    }
    fn bytes(&self) -> usize {
        self.springs.bytes()
    }
    fn border(&self) -> Option<&[u32]> {
        self.wave.then(|| self.springs.border())
    }
}

/// The assembled sweep of a `rigid-poisson` model: `K`'s blocks with `t Gᵀ q` added pair by
/// pair (`G`'s entries from its compressed rows, [`PressureOperator`]).
pub struct AssembledPoisson {
    springs: Assembled<Rigid, 3>,
    /// Per pair of `springs`, in its order: `t ∂s_b/∂U_a` (the force on `a` per `q_b`) and
    /// `t ∂s_a/∂U_b` (on `b` per `q_a`).
    pairs: Vec<[[f64; 3]; 2]>,
    /// Per element, `t ∂s_e/∂U_e`.
    own: Vec<[f64; 3]>,
}

impl AssembledPoisson {
    /// The evaluator of a `rigid-poisson` model.
    pub fn new(model: &Model) -> Self {
        let springs = Assembled::<Rigid, 3>::new(model);
        let (g, t) = (&PressureOperator::new(model).g, model.thickness);
        // `t ∂s_cell/∂U_e`, from `G`'s row of the cell.
        let read = |cell: u32, e: u32| {
            let mut c = [0.0; 3];
            for j in g.range(cell as usize) {
                let col = g.col[j] as usize;
                if col / 3 == e as usize {
                    c[col % 3] = t * g.val[j];
                }
            }
            c
        };
        let pairs = springs
            .faces()
            .iter()
            .map(|f| [read(f.b, f.a), read(f.a, f.b)])
            .collect();
        let own = (0..model.elements.len() as u32)
            .map(|e| read(e, e))
            .collect();
        AssembledPoisson {
            springs,
            pairs,
            own,
        }
    }
}

/// [`AssembledPoisson`]'s pairs in the sweep, with the cells' `q`.
struct Pairs<'a> {
    of: &'a AssembledPoisson,
    q: &'a Pressures<'a>,
}

impl Pairs<'_> {
    /// The correction's forces on `a` and `b` of the pair at `face`.
    #[inline(always)]
    fn correction(&self, face: &Face<Block<3>>) -> [[f64; 3]; 2] {
        let [on_a, on_b] = &self.of.pairs[place(self.faces(), face)];
        let (qa, qb) = (self.q.get(face.a as usize), self.q.get(face.b as usize));
        [on_a.map(|c| c * qb), on_b.map(|c| c * qa)]
    }
}

/// Adds a pair's correction forces.
#[inline(always)]
fn add_correction([pa, pb]: [[f64; 3]; 2], fa: &mut [f64; 3], fb: &mut [f64; 3]) {
    for p in 0..3 {
        fa[p] += pa[p];
        fb[p] += pb[p];
    }
}

impl Couplings<3> for Pairs<'_> {
    type Ref = Block<3>;
    const PREFETCH: bool = true;
    const RUNS: bool = false;
    const WIDE: bool = false;
    #[inline(always)]
    fn faces(&self) -> &[Face<Block<3>>] {
        self.of.springs.faces()
    }
    /// `K_ab`, and the correction's forces on `a` and `b`.
    type Coupling<'b>
        = (&'b Block<3>, [[f64; 3]; 2])
    where
        Self: 'b;
    #[inline(always)]
    fn coupling<'b>(&'b self, face: &'b Face<Block<3>>) -> Self::Coupling<'b> {
        (&face.record, self.correction(face))
    }
    #[inline(always)]
    fn add_pair(
        &self,
        lanes: impl Lanes,
        (k, correction): (&Block<3>, [[f64; 3]; 2]),
        ua: &[f64; 3],
        ub: &[f64; 3],
        fa: &mut [f64; 3],
        fb: &mut [f64; 3],
    ) {
        self.of.springs.add_pair(lanes, k, ua, ub, fa, fb);
        add_correction(correction, fa, fb);
    }
    fn add_ground(&self, face: &Face<Block<3>>, ua: &[f64; 3], fa: &mut [f64; 3]) {
        self.of.springs.add_ground(face, ua, fa);
    }
    #[inline(always)]
    fn add_own(&self, e: usize, ue: &[f64; 3], f: &mut [f64; 3]) {
        self.of.springs.add_own(e, ue, f);
        let q = self.q.get(e);
        for (f, c) in f.iter_mut().zip(&self.of.own[e]) {
            *f += c * q;
        }
    }
}

/// [`Pairs`] whose blocks carry failing interfaces ([`WithFailure`], its laws acting on the
/// jump of `q`).
struct FailingPairs<'a> {
    pairs: Pairs<'a>,
    failing: WithFailure<'a, Rigid, 3>,
}

impl Couplings<3> for FailingPairs<'_> {
    type Ref = Block<3>;
    const PREFETCH: bool = true;
    const RUNS: bool = false;
    const WIDE: bool = false;
    #[inline(always)]
    fn faces(&self) -> &[Face<Block<3>>] {
        self.pairs.faces()
    }
    /// What the block carries, and the correction's forces on `a` and `b`.
    type Coupling<'b>
        = (Carrying<'b, [f64; 2], 3>, [[f64; 3]; 2])
    where
        Self: 'b;
    #[inline(always)]
    fn coupling<'b>(&'b self, face: &'b Face<Block<3>>) -> Self::Coupling<'b> {
        (self.failing.coupling(face), self.pairs.correction(face))
    }
    #[inline(always)]
    fn add_pair(
        &self,
        lanes: impl Lanes,
        (carried, correction): (Carrying<'_, [f64; 2], 3>, [[f64; 3]; 2]),
        ua: &[f64; 3],
        ub: &[f64; 3],
        fa: &mut [f64; 3],
        fb: &mut [f64; 3],
    ) {
        self.failing.add_pair(lanes, carried, ua, ub, fa, fb);
        add_correction(correction, fa, fb);
    }
    fn add_ground(&self, face: &Face<Block<3>>, ua: &[f64; 3], fa: &mut [f64; 3]) {
        self.pairs.add_ground(face, ua, fa);
    }
    #[inline(always)]
    fn add_own(&self, e: usize, ue: &[f64; 3], f: &mut [f64; 3]) {
        self.pairs.add_own(e, ue, f);
    }
}

impl Correction for AssembledPoisson {
    fn kind(&self) -> EvaluatorKind {
        EvaluatorKind::Assembled
    }
    fn internal_force(
        &self,
        u: &[f64],
        f: &mut [f64],
        q: &Pressures<'_>,
        failure: Option<Failure<'_>>,
    ) {
        let pairs = Pairs { of: self, q };
        let sweep = self.springs.sweep();
        match failure {
            Some(failure) => {
                let failing = self.springs.with_failure(failure).jumped(q);
                sweep.evaluate(&FailingPairs { pairs, failing }, u, f);
            }
            None => sweep.evaluate(&pairs, u, f),
        }
    }
    fn advance(
        &self,
        (u, v, force): (&mut [f64], &mut [f64], &mut [f64]),
        loaded: Option<&[u32]>,
        update: &Update,
        q: &Pressures<'_>,
        failure: Option<Failure<'_>>,
    ) -> f64 {
        let pairs = Pairs { of: self, q };
        let sweep = self.springs.sweep();
        match failure {
            Some(failure) => {
                let failing = self.springs.with_failure(failure).jumped(q);
                let pairs = FailingPairs { pairs, failing };
                sweep.advance(&pairs, u, v, force, loaded, update)
            }
            None => sweep.advance(&pairs, u, v, force, loaded, update),
        }
    }
    fn bytes(&self) -> usize {
        use std::mem::size_of_val;
        self.springs.bytes() + size_of_val(&self.pairs[..]) + size_of_val(&self.own[..])
    }
    fn border(&self) -> Option<&[u32]> {
        None
    }
}

/// `G` by block rows: each cell's first moment `s` from its own and its neighbours' DOFs.
/// Element `I`'s facets to other elements are `start[I] .. start[I + 1]` in `sides` (the
/// element `J` across and the coefficients of `U_J` in `s_I`: `∫ S (x − x_I) ds` on `(u, v)`,
/// `∫ (x − x_I)·S (ẑ × (x − x_J)) ds` on `θ`, side by side so that `s` reads one stream) and
/// `read_by` (those of `U_I` in `s_J`, for the bracket alone); `own` holds the coefficients of
/// `U_I` in `s_I`, ground springs included.
pub struct FacetPressures {
    sides: Vec<Side>,
    read_by: Vec<[f64; 3]>,
    start: Vec<u32>,
    own: Vec<[f64; 3]>,
    scale: Vec<f64>,
    thickness: f64,
}

/// `(∫ S (x − x_i) ds, ∫ (x − x_i)·S (ẑ × (x − x_j)) ds)` over an interface (two Gauss points,
/// exact): the coefficients of `(u_j, v_j, θ_j)` in `∫ (x − x_i)·S u_j(x) ds`.
fn reading(model: &Model, i: &crate::model::Interface, xi: Vec2, xj: Vec2) -> [f64; 3] {
    let s = springs(model, i);
    let (points, w) = i.gauss_points();
    let mut c = [0.0; 3];
    for x in points {
        let t = s.apply(x - xi) * w;
        let turn = x - xj;
        c[0] += t.x;
        c[1] += t.y;
        c[2] += t.dot(&Vec2::new(-turn.y, turn.x));
    }
    c
}

/// A facet of a cell in [`FacetPressures`]: the element across and the coefficients of its DOFs
/// in the cell's `s`.
struct Side {
    reads: [f64; 3],
    other: u32,
}

impl FacetPressures {
    /// The facets and own coefficients of a `rigid-poisson` model.
    pub fn new(model: &Model) -> Self {
        let poisson = Poisson::new(model);
        let n = model.elements.len();
        let centroid = |e: u32| model.elements[e as usize].props.centroid;
        let mut own = vec![[0.0; 3]; n];
        let (mut sides, mut read_by) = (Vec::new(), Vec::new());
        let mut start = vec![0u32; n + 1];
        for e in 0..n {
            let me = e as u32;
            for &k in poisson.facets_of(e) {
                let i = &model.interfaces[k as usize];
                let across = if i.a == me { i.b } else { i.a };
                // `δ = u_b − u_a` and the traction on `I` is `±S δ`: in `s_I` the other's
                // displacement enters with `+`, its own with `−`.
                let self_read = reading(model, i, centroid(me), centroid(me));
                own[e].iter_mut().zip(self_read).for_each(|(o, c)| *o -= c);
                if across != GROUND {
                    sides.push(Side {
                        reads: reading(model, i, centroid(me), centroid(across)),
                        other: across,
                    });
                    read_by.push(reading(model, i, centroid(across), centroid(me)));
                }
            }
            start[e + 1] = sides.len() as u32;
        }
        FacetPressures {
            sides,
            read_by,
            start,
            own,
            scale: poisson.scale,
            thickness: model.thickness,
        }
    }

    fn sides(&self, e: usize) -> std::ops::Range<usize> {
        self.start[e] as usize..self.start[e + 1] as usize
    }

    /// `s_e`: the first moment `∫ (x − x_e)·S δ ds` of the spring tractions on element `e`'s
    /// facets (per unit thickness), from its own and its neighbours' DOFs (`u` by element).
    /// Summed in six sums, per DOF and for the even and the odd sides: chains of a few
    /// additions, which the processor overlaps (a 10⁵-cell panel: 12 ns per cell with one chain
    /// per DOF).
    #[inline(always)]
    fn moment(&self, e: usize, u: &[[f64; 3]]) -> f64 {
        let (own, ue) = (&self.own[e], &u[e]);
        let mut s = [[own[0] * ue[0], own[1] * ue[1], own[2] * ue[2]], [0.0; 3]];
        let sides = &self.sides[self.sides(e)];
        let (pairs, last) = sides.as_chunks::<2>();
        for pair in pairs {
            for (s, Side { reads: c, other: j }) in s.iter_mut().zip(pair) {
                let uj = &u[*j as usize];
                for d in 0..3 {
                    s[d] += c[d] * uj[d];
                }
            }
        }
        for Side { reads: c, other: j } in last {
            let uj = &u[*j as usize];
            for d in 0..3 {
                s[1][d] += c[d] * uj[d];
            }
        }
        (s[0][0] + s[1][0]) + (s[0][1] + s[1][1]) + (s[0][2] + s[1][2])
    }

    /// The correction's diagonal blocks `K^P_ee` (row-major, nine per element), and the most
    /// elements a cell's `q` reads (`K_P`'s terms couple that many): what the stability limit's
    /// bracket needs ([`crate::analysis::limit::Limit`]). `K^P_ee = t Σ_c Λ_c g_ce g_ceᵀ` over
    /// the cells `c` whose `s` reads element `e`: itself (`own`) and its neighbours (`read_by`).
    pub fn diagonal_blocks(&self) -> (Vec<f64>, usize) {
        let n = self.own.len();
        let mut blocks = vec![0.0; 9 * n];
        for (e, block) in blocks.chunks_exact_mut(9).enumerate() {
            let r = self.sides(e);
            let cells = std::iter::once((e, &self.own[e])).chain(
                self.sides[r.clone()]
                    .iter()
                    .map(|side| side.other as usize)
                    .zip(&self.read_by[r]),
            );
            for (c, g) in cells {
                let w = self.thickness * self.scale[c];
                for (k, b) in block.iter_mut().enumerate() {
                    *b += w * g[k / 3] * g[k % 3];
                }
            }
        }
        let most = (0..n).map(|e| 1 + self.sides(e).len()).max().unwrap_or(0);
        (blocks, most)
    }

    /// The cells' `q_e = Λ_e s_e` at `u`, from the springs alone (the loads' share is in `P`).
    pub fn cells(&self, u: &[f64]) -> Vec<f64> {
        let mut q: Vec<AtomicU64> = (0..self.own.len()).map(|_| AtomicU64::new(0)).collect();
        self.fill(u, &[], &mut q);
        q.into_iter()
            .map(|q| f64::from_bits(q.into_inner()))
            .collect()
    }

    /// Every cell's `q` at `u`, less its plastic moment in `plastic` (empty where none fail),
    /// each from its facets gathered, in fixed chunks.
    fn fill(&self, u: &[f64], plastic: &[f64], q: &mut [AtomicU64]) {
        let (u, _) = u.as_chunks::<3>();
        for_each_chunk(q, CHUNK, |first, chunk| {
            for (k, q) in chunk.iter_mut().enumerate() {
                let e = first + k;
                let q_e = pressure(self.scale[e], self.moment(e, u), plastic.get(e));
                *q.get_mut() = q_e.to_bits();
            }
        });
    }

    /// The `q` at `u` of the `border` cells, those the sweep's wave leaves out, each from its
    /// facets gathered.
    fn border(&self, u: &[f64], border: &[u32], q: &Pressures<'_>) {
        let (u, _) = u.as_chunks::<3>();
        border.par_iter().with_min_len(256).for_each(|&e| {
            let e = e as usize;
            q.set(e, self.moment(e, u));
        });
    }
}
/// The cells' `q_e = λ' tr ε_e / 2μ` of a `rigid-poisson` model at `u` under its loads at
/// their full value: what the correction's tractions on its facets are made of
/// ([`crate::model::poisson::correction`]; the static analysis reports them).
pub fn cells(model: &Model, u: &[f64]) -> Vec<f64> {
    let facets = FacetPressures::new(model);
    let mut q = facets.cells(u);
    for l in &model.loads {
        let e = l.element as usize;
        q[e] += facets.scale[e] * load_moment(model, e, l.point, l.force);
    }
    q
}

impl FacetPressures {
    /// The bytes that [`FacetPressures::cells`] reads.
    fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.sides[..])
            + std::mem::size_of_val(&self.start[..])
            + std::mem::size_of_val(&self.own[..])
            + std::mem::size_of_val(&self.scale[..])
    }
}

/// A sparse matrix in compressed rows.
#[derive(Debug, Clone, Default)]
struct Rows {
    start: Vec<u32>,
    col: Vec<u32>,
    val: Vec<f64>,
}

impl Rows {
    /// From `(row, col, value)` triplets over `n` rows, duplicates summed.
    fn new(n: usize, mut t: Vec<(usize, usize, f64)>) -> Rows {
        t.sort_unstable_by_key(|&(r, c, _)| (r, c));
        let mut rows = Rows {
            start: vec![0; n + 1],
            ..Rows::default()
        };
        let mut last = None;
        for (r, c, v) in t {
            if last == Some((r, c)) {
                *rows.val.last_mut().expect("a previous entry") += v;
            } else {
                rows.col.push(c as u32);
                rows.val.push(v);
                last = Some((r, c));
            }
            rows.start[r + 1] = rows.col.len() as u32;
        }
        for r in 0..n {
            rows.start[r + 1] = rows.start[r + 1].max(rows.start[r]);
        }
        rows
    }
    fn range(&self, r: usize) -> std::ops::Range<usize> {
        self.start[r] as usize..self.start[r + 1] as usize
    }
}

/// The correction as sparse operators: `q = Λ G U`, and `K_P = t Gᵀ Λ G`.
pub struct PressureOperator {
    /// `G`: per cell, the first moment `s` of its tractions from the DOFs.
    g: Rows,
    /// `Λ` per cell.
    scale: Vec<f64>,
    thickness: f64,
}

impl PressureOperator {
    /// `G` and `Λ` of a `rigid-poisson` model.
    pub fn new(model: &Model) -> Self {
        let poisson = Poisson::new(model);
        let centroid = |e: u32| model.elements[e as usize].props.centroid;
        let mut g = Vec::new();
        for i in &model.interfaces {
            let s = springs(model, i);
            let (x, w) = i.gauss_points();
            // The first moment of the traction on side `e`, `±w (x − x_e)ᵀ S (u_b(x) − u_a(x))`.
            for (e, sign) in [(i.a, 1.0), (i.b, -1.0)] {
                if e == GROUND {
                    continue;
                }
                for &xg in &x {
                    let r = s.apply(xg - centroid(e)) * (sign * w);
                    for (side, dir) in [(i.a, -1.0), (i.b, 1.0)] {
                        if side == GROUND {
                            continue;
                        }
                        let shape = Rigid::shape(xg - centroid(side));
                        for d in 0..3 {
                            let v = dir * (r.x * shape[(0, d)] + r.y * shape[(1, d)]);
                            g.push((e as usize, 3 * side as usize + d, v));
                        }
                    }
                }
            }
        }
        let n = model.elements.len();
        PressureOperator {
            g: Rows::new(n, g),
            scale: poisson.scale,
            thickness: model.thickness,
        }
    }

    /// The correction's part of `K`, `t Gᵀ Λ G`, as triplets over all DOFs, duplicates summed:
    /// each cell `c` adds `t Λ_c G_ci G_cj` at `(i, j)`.
    pub fn triplets(&self) -> Vec<(usize, usize, f64)> {
        let n = self.g.start.len() - 1;
        let mut products = Vec::new();
        for cell in 0..n {
            let w = self.thickness * self.scale[cell];
            for i in self.g.range(cell) {
                let wi = w * self.g.val[i];
                let row = self.g.col[i] as usize;
                products.extend(
                    self.g
                        .range(cell)
                        .map(|j| (row, self.g.col[j] as usize, wi * self.g.val[j])),
                );
            }
        }
        let k = Rows::new(3 * n, products);
        (0..3 * n)
            .flat_map(|r| k.range(r).map(move |j| (r, j)))
            .map(|(r, j)| (r, k.col[j] as usize, k.val[j]))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::scene::Scene;

    fn voronoi(nu: f64) -> Model {
        voronoi_with(nu, "")
    }

    /// [`voronoi`] with `interface` added to the material.
    fn voronoi_with(nu: f64, interface: &str) -> Model {
        voronoi_of(nu, interface, "\"sites\": 300, \"seed\": 3, \"lloyd\": 30")
    }

    /// A Voronoi panel of 6,000 cells: two blocks of the sweep, with cells on their border
    /// (the wave leaves their `q` to a gather before the sweeps, [`Pressures`]).
    fn two_blocks() -> Model {
        voronoi_of(0.3, "", "\"sites\": 6000, \"seed\": 5, \"lloyd\": 2")
    }

    /// Each evaluator of a `rigid-poisson` model: assembled, element-wise after every cell's
    /// `q` gathered, and element-wise led by the cells' wave.
    fn evaluators(m: &Model) -> [(&'static str, Box<dyn Evaluator>); 3] {
        [
            (
                "assembled",
                Box::new(WithPoisson::new(m, AssembledPoisson::new(m))),
            ),
            (
                "element-wise",
                Box::new(WithPoisson::new(m, ElementWisePoisson::with_wave(m, false))),
            ),
            (
                "element-wise led",
                Box::new(WithPoisson::new(m, ElementWisePoisson::with_wave(m, true))),
            ),
        ]
    }

    fn voronoi_of(nu: f64, interface: &str, sites: &str) -> Model {
        Model::build(
            &Scene::from_json(&format!(
                r#"{{"name": "p", "thickness": 0.5, "plane": "stress", "formulation": {{"kind": "rigid-poisson"}},
                "materials": {{"m": {{"E": 1e10, "nu": {nu}, "rho": 2000{interface}}}}},
                "bodies": [{{"name": "b", "material": "m",
                    "mesh": {{"kind": "voronoi", "origin": [0, 0], "size": [1, 1], {sites}}}}}],
                "time": {{"dt": 1e-6, "steps": 1}}}}"#
            ))
            .unwrap(),
        )
        .unwrap()
    }

    /// Under a uniform strain (each cell at the affine field), an interior cell's
    /// `q = λ' tr ε / 2μ` to the lattice's uniformity.
    #[test]
    fn interior_pressures_under_a_uniform_strain() {
        let m = voronoi(0.25);
        let lambda = m.elements[0].d[(0, 1)];
        // Interior: no edge without springs (`B = 0`).
        let poisson = Poisson::new(&m);
        let interior: Vec<bool> = (0..m.elements.len())
            .map(|e| {
                let el = &m.elements[e];
                let two_mu = el.d[(0, 0)] - lambda;
                (poisson.scale[e] * two_mu * two_mu * el.props.area / lambda - 1.0).abs() < 1e-9
            })
            .collect();
        for (ex, ey, g) in [
            (1e-3, 0.0, 0.0),
            (0.0, 1e-3, 0.0),
            (0.0, 0.0, 1e-3),
            (1e-3, -4e-4, 6e-4),
        ] {
            let u: Vec<f64> = m
                .elements
                .iter()
                .flat_map(|el| {
                    let c = el.props.centroid;
                    [ex * c.x + 0.5 * g * c.y, ey * c.y + 0.5 * g * c.x, 0.0]
                })
                .collect();
            let p = cells(&m, &u);
            // `q = λ' tr ε / 2μ`.
            let exact = lambda * (ex + ey) / (m.elements[0].d[(0, 0)] - lambda);
            let worst = (0..m.elements.len())
                .filter(|&e| interior[e])
                .map(|e| (p[e] - exact).abs())
                .fold(0.0, f64::max);
            assert!(
                worst
                    <= 0.03
                        * exact
                            .abs()
                            .max(lambda * 1e-3 / (m.elements[0].d[(0, 0)] - lambda)),
                "ε = ({ex}, {ey}, {g}): worst interior |p − λ' tr ε| = {worst:e}"
            );
        }
    }

    /// The two evaluators' corrections, and `K`'s triplets, give the same force on any `U`; `K`
    /// is symmetric. On one block of the sweep, and on two, where the cells on their border
    /// take their `q` before the sweep.
    #[test]
    fn the_evaluators_agree_on_any_displacement() {
        let two = two_blocks();
        assert!(
            ElementWise::with_poisson(&two, true).border().len() > 100,
            "cells on the border"
        );
        for m in [voronoi(0.3), two] {
            evaluators_agree(&m);
        }
    }

    fn evaluators_agree(m: &Model) {
        use crate::force::evaluator::stiffness_triplets;
        let n = m.n_dofs();
        let u: Vec<f64> = (0..n)
            .map(|k| 1e-4 * ((k as f64 * 0.7).sin() + 0.3 * (k as f64 * 1.9).cos()))
            .collect();
        let [fa, fe, fl] = evaluators(m).map(|(_, ev)| {
            let mut f = vec![0.0; n];
            ev.internal_force(&u, &mut f);
            f
        });
        let mut fk = vec![0.0; n];
        let k = stiffness_triplets(m);
        for &(r, c, v) in &k {
            fk[r] += v * u[c];
        }
        let mut entries = std::collections::BTreeMap::new();
        for &(r, c, v) in &k {
            *entries.entry((r, c)).or_insert(0.0) += v;
        }
        let big = entries.values().fold(0.0f64, |s, v| s.max(v.abs()));
        for (&(r, c), v) in &entries {
            let vt = entries.get(&(c, r)).copied().unwrap_or(0.0);
            assert!(
                (v - vt).abs() <= 1e-12 * big,
                "K[{r}][{c}] = {v:e}, K[{c}][{r}] = {vt:e}"
            );
        }
        let scale = fa.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        for (name, g) in [("element-wise", &fe), ("led", &fl), ("triplets", &fk)] {
            let worst = fa
                .iter()
                .zip(g)
                .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
            assert!(
                worst <= 1e-12 * scale,
                "assembled against {name}: {worst:e} of {scale:e}"
            );
        }
    }

    /// Interfaces that can fail but stay elastic give the correction's forces of the elastic
    /// sweep in both evaluators, to round-off: the failing sweeps carry the same jump; and a
    /// weak law, which yields, changes them.
    #[test]
    fn failing_sweeps_carry_the_correction() {
        use crate::force::failure;
        let law = |f_t: f64| {
            format!(
                r#", "interface": {{"kind": "mohr-coulomb", "tensile_strength": {f_t}, "cohesion": {f_t}, "friction_angle": 30}}"#
            )
        };
        let u: Vec<f64> = (0..3 * voronoi(0.3).elements.len())
            .map(|k| 1e-5 * ((k as f64 * 0.7).sin() + 0.3 * (k as f64 * 1.9).cos()))
            .collect();
        let elastic = evaluators(&voronoi(0.3)).map(|(_, ev)| {
            let mut f = vec![0.0; u.len()];
            ev.internal_force(&u, &mut f);
            f
        });
        let failing = |f_t| {
            let m = voronoi_with(0.3, &law(f_t));
            let plastic = failure::build(&m).expect("failing interfaces");
            evaluators(&m).map(|(name, ev)| {
                let mut state = plastic.initial();
                let mut f = vec![0.0; u.len()];
                ev.internal_force_failing(&u, &mut f, (&*plastic, &mut state));
                (name, f)
            })
        };
        let (strong, weak) = (failing(1e12), failing(1e4));
        for ((want, (name, strong)), (_, weak)) in elastic.iter().zip(strong).zip(weak) {
            let scale = want.iter().fold(0.0f64, |s, x| s.max(x.abs()));
            let diff = |f: &[f64]| {
                want.iter()
                    .zip(f)
                    .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()))
            };
            let strong = diff(&strong);
            assert!(strong <= 1e-12 * scale, "{name}: {strong:e} of {scale:e}");
            let weak = diff(&weak);
            assert!(weak > 1e-3 * scale, "{name}: a weak law changed {weak:e}");
        }
    }

    /// The wave gives the same bits on one and two threads (two blocks, cells on their
    /// border), and so does the gather of the same evaluator where interfaces yield.
    #[test]
    fn the_wave_does_not_depend_on_the_thread_count() {
        use crate::force::failure;
        let law = r#", "interface": {"kind": "mohr-coulomb", "tensile_strength": 1e4, "cohesion": 1e4, "friction_angle": 30}"#;
        let m = voronoi_of(0.3, law, "\"sites\": 6000, \"seed\": 5, \"lloyd\": 2");
        let plastic = failure::build(&m).expect("failing interfaces");
        let ev = WithPoisson::new(&m, ElementWisePoisson::with_wave(&m, true));
        let u: Vec<f64> = (0..m.n_dofs())
            .map(|k| 1e-5 * ((k as f64 * 0.7).sin() + 0.3 * (k as f64 * 1.9).cos()))
            .collect();
        let forces = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let (mut elastic, mut failing) = (vec![0.0; u.len()], vec![0.0; u.len()]);
                ev.internal_force(&u, &mut elastic);
                let mut state = plastic.initial();
                ev.internal_force_failing(&u, &mut failing, (&*plastic, &mut state));
                (elastic, failing)
            })
        };
        let (one, two) = (forces(1), forces(2));
        let bits = |f: &[f64]| f.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert!(bits(&one.0) == bits(&two.0), "elastic");
        assert!(bits(&one.1) == bits(&two.1), "failing");
        assert!(bits(&one.0) != bits(&one.1), "the law yields");
    }

    /// A fused step of either evaluator is the evaluation followed by the update, loads
    /// included, to round-off: the correction's forces reach every element in the sweep, and
    /// the cells' `q` are those of `U` at `t_n` though elements move while the wave leads
    /// (one block of the sweep, and two).
    #[test]
    fn a_fused_step_is_the_evaluation_then_the_update() {
        for m in [voronoi(0.3), two_blocks()] {
            fused_step_is_evaluation_then_update(&m);
        }
    }

    fn fused_step_is_evaluation_then_update(m: &Model) {
        use crate::model::mass::{Mass, Update};
        let n = m.n_dofs();
        let mass = Mass::new(m);
        let u0: Vec<f64> = (0..n).map(|k| 1e-4 * (k as f64 * 0.37).sin()).collect();
        let v0: Vec<f64> = (0..n).map(|k| 1e-2 * (k as f64 * 0.91).cos()).collect();
        let load: Vec<f64> = (0..n).map(|k| if k % 5 == 0 { 1e3 } else { 0.0 }).collect();
        let dt = 1e-7;
        for (kind, ev) in evaluators(m) {
            let (mut u, mut v, mut f) = (u0.clone(), v0.clone(), vec![0.0; n]);
            ev.internal_force(&u, &mut f);
            f.iter_mut().zip(&load).for_each(|(f, p)| *f += p);
            mass.advance(&f, &mut v, &mut u, dt, (1.0, 1.0));
            let (mut uf, mut vf, mut force) = (u0.clone(), v0.clone(), load.clone());
            let update = Update {
                mass: &mass,
                dt,
                damping: (1.0, 1.0),
            };
            let fused = ev.fused().expect("rigid-poisson steps fused");
            fused.advance(&mut uf, &mut vf, &mut force, None, &update);
            assert!(force.iter().all(|&x| x == 0.0), "{kind} left a force");
            for (name, a, b) in [("U", &u, &uf), ("v", &v, &vf)] {
                let scale = a.iter().fold(0.0f64, |s, x| s.max(x.abs()));
                let worst = a
                    .iter()
                    .zip(b)
                    .fold(0.0f64, |s, (x, y)| s.max((x - y).abs()));
                assert!(
                    worst <= 1e-13 * scale,
                    "{kind} {name}: {worst:e} of {scale:e}"
                );
            }
        }
    }

    /// The bracket's diagonal blocks, from each element's own records, are those of `K_P`'s
    /// triplets.
    #[test]
    fn the_diagonal_blocks_are_those_of_k() {
        let m = voronoi(0.3);
        let (blocks, most) = FacetPressures::new(&m).diagonal_blocks();
        let mut from_k = vec![0.0; blocks.len()];
        for (r, c, v) in PressureOperator::new(&m).triplets() {
            if r / 3 == c / 3 {
                from_k[9 * (r / 3) + 3 * (r % 3) + c % 3] += v;
            }
        }
        let big = from_k.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        let worst = blocks
            .iter()
            .zip(&from_k)
            .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
        assert!(worst <= 1e-12 * big, "{worst:e} of {big:e}");
        assert!(
            (4..=12).contains(&most),
            "a Voronoi cell reads {most} elements"
        );
    }
}

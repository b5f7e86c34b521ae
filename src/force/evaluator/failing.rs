//! The assembled evaluator's couplings with the failing interfaces they carry
//! (`force::failure`): each block `K_ab` adds its elastic forces, then return-maps the Gauss
//! points of the failing interfaces between its two elements and adds their plastic part, in
//! one pass of the sweep ([`super::sweep`]), evaluating or stepping. A block that carries one
//! interface, in its initial state, first screens it on the products the block has computed
//! (`K_abᵀ U_a − K_ab U_b` is the interface's resultant traction; [`Screened`]; under the
//! Poisson correction with a bound of its jump, [`Jumped`]), and reads nothing else where the
//! screen passes. (The element-wise evaluator gives a failing
//! interface its whole traction through its law instead, `super::element_wise`.)

use super::assembled::{Assembled, Block};
use super::poisson::Pressures;
use super::sweep::{place, Couplings, Face};
use crate::force::failure::{self, FailingInterfaces, FailureState, Jump, PlasticForces};
use crate::lanes::Lanes;
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Formulation, Hybrid, Kinematics, Rigid};
use crate::model::{Interface, Model};

/// Per coupling of the assembled evaluator (in the order of its sweep), what it carries of the
/// failing interfaces ([`Carry`]), and under the Poisson correction what its screen adds for
/// the correction's jump ([`Jumped`]).
pub(super) struct Carried<S> {
    carries: Vec<Carry<S>>,
    /// Per coupling, empty unless the model is `rigid-poisson`.
    jumped: Vec<Jumped>,
}

/// What the correction's jump `j(x) = q_a (x − x_a) − q_b (x − x_b)` adds to the
/// [screen](Screened) of a rigid coupling that carries one failing interface: its midpoint value
/// `j₀ = q_a d_a − q_b d_b` (`d` from each centroid to the edge's midpoint) gives the force
/// `t L S j₀`, with `|t L S j₀|₁ ≤ |q_a| t L |S d_a|₁ + |q_b| t L |S d_b|₁`, and its odd part
/// `(q_a − q_b) g` along the edge adds `t L k_s' h |q_a − q_b|` to `t L |S δ₁|`; a bound of both
/// added to the screen's left side keeps it a sufficient test. `[t L |S d_a|₁, t L |S d_b|₁,
/// t L k_s' h]`.
pub(super) type Jumped = [f64; 3];

/// What [`WithFailure`] reads of a coupling: its block, what it carries, and under the Poisson
/// correction its elements' `[q_a, q_b]` with its [`Jumped`].
pub(super) type Carrying<'b, S, const N: usize> =
    (&'b Block<N>, &'b Carry<S>, Option<([f64; 2], &'b Jumped)>);

/// What one coupling carries: a range of [`Model::failing_interfaces`], and the
/// [screen](Screened) of the one it carries (one that never passes where it carries more). One
/// record per coupling, read in the sweep's order beside its block.
#[derive(Debug, Clone, Copy)]
pub(super) struct Carry<S> {
    range: [u32; 2],
    screen: S,
}

/// The screen of the assembled evaluator: whether a failing interface in its initial state,
/// carried alone by a block `K_ab`, stays elastic, tested on the products the block has
/// computed. Its relative displacements at the Gauss points are `δ₀ ∓ δ₁`, with
/// `t L S δ₀ = T = K_abᵀ U_a − K_ab U_b` the force of its springs at the midpoint (the
/// translation rows of `K_ab` hold that part alone) and `δ₁ = (N(g) − N(0)) (U_b − U_a)` at
/// its Gauss offset `g = L/(2√3) s`: its tractions there lie in the [disc](failure::initial_disc)
/// `|λ| ≤ r` of its law's initial region when `|T|₁ + t L |S δ₁| ≤ t L r`, where its law
/// leaves it elastic.
pub trait Screened<const N: usize>: Kinematics<N> {
    /// What the test reads per coupling.
    type Screen: Copy + Send + Sync + std::fmt::Debug;
    /// A screen that never passes.
    const NEVER: Self::Screen;
    /// The screen of interface `i` with springs `(k_n', k_s')`, disc `r` and thickness `t`.
    fn screen(i: &Interface, springs: [f64; 2], r: f64, t: f64) -> Self::Screen;
    /// Whether the interface passes, at a midpoint force `T` (either sign) and DOFs `ua`,
    /// `ub`, with `extra` added to the left side of its test (the bound of the Poisson
    /// correction's jump, [`Jumped`]; 0 without).
    fn passes(
        screen: &Self::Screen,
        force: [f64; 2],
        extra: f64,
        ua: &[f64; N],
        ub: &[f64; N],
    ) -> bool;
}

/// Rigid: `δ₁ = (θ_b − θ_a) ẑ × g = (θ_b − θ_a) h n`, so `t L |S δ₁| = t L k_n' h |θ_b − θ_a|`;
/// the screen is `[t L k_n' h, t L r]`.
impl Screened<3> for Rigid {
    type Screen = [f64; 2];
    const NEVER: [f64; 2] = [0.0, -1.0];
    fn screen(i: &Interface, [k_n, _]: [f64; 2], r: f64, t: f64) -> [f64; 2] {
        [t * i.length * k_n * i.gauss_offset(), t * i.length * r]
    }
    #[inline(always)]
    fn passes(
        &[per_rotation, reach]: &[f64; 2],
        [tx, ty]: [f64; 2],
        extra: f64,
        ua: &[f64; 3],
        ub: &[f64; 3],
    ) -> bool {
        tx.abs() + ty.abs() + per_rotation * (ub[2] - ua[2]).abs() + extra <= reach
    }
}

/// Hybrid: `δ₁` takes the strains too; `t L |S δ₁| ≤ t L k_max |δ₁|₁`, with `k_max` the larger
/// spring; the screen is `[g, t L k_max, t L r]`.
impl Screened<6> for Hybrid {
    type Screen = [f64; 4];
    const NEVER: [f64; 4] = [0.0, 0.0, 0.0, -1.0];
    fn screen(i: &Interface, [k_n, k_s]: [f64; 2], r: f64, t: f64) -> [f64; 4] {
        let g = i.gauss_offset() * i.tangent;
        [g.x, g.y, t * i.length * k_n.max(k_s), t * i.length * r]
    }
    #[inline(always)]
    fn passes(
        &[gx, gy, k_max, reach]: &[f64; 4],
        [tx, ty]: [f64; 2],
        extra: f64,
        ua: &[f64; 6],
        ub: &[f64; 6],
    ) -> bool {
        let jump: [f64; 6] = std::array::from_fn(|p| ub[p] - ua[p]);
        let odd = Self::gradient(&jump, Vec2::new(gx, gy));
        tx.abs() + ty.abs() + k_max * (odd.x.abs() + odd.y.abs()) + extra <= reach
    }
}

impl<S: Copy> Carried<S> {
    /// The failing interfaces between the elements `(a, b)`, `a < b`, of each coupling (a
    /// block `K_ab`), and their screens for the kinematics `K`.
    ///
    /// # Panics
    /// If a failing interface has no coupling: an evaluator that left out a pair of elements
    /// with an interface between them.
    pub(super) fn new<K: Screened<N, Screen = S>, const N: usize, R>(
        model: &Model,
        faces: &[Face<R>],
    ) -> Self {
        let failing = model.failing_interfaces();
        let screen = |k: u32| {
            let i = &model.interfaces[k as usize];
            let law = model.law_of(i);
            let springs = law.springs([i.k_n, i.k_s]);
            K::screen(i, springs, failure::initial_disc(law), model.thickness)
        };
        let pairs: Vec<(u32, u32)> = failing
            .iter()
            .map(|&k| {
                let i = &model.interfaces[k as usize];
                (i.a.min(i.b), i.a.max(i.b))
            })
            .collect();
        let mut taken = vec![false; pairs.len()];
        // Where the coupling carries one interface under the Poisson correction: what its
        // screen adds per unit of the jump (`Jumped`).
        let jumped = |f: &Face<R>, [start, end]: [u32; 2]| -> Jumped {
            if end != start + 1 {
                return [0.0; 3];
            }
            let i = &model.interfaces[failing[start as usize] as usize];
            let [k_n, k_s] = model.law_of(i).springs([i.k_n, i.k_s]);
            let tl = model.thickness * i.length;
            let lever = |e: u32| {
                let d = i.midpoint() - model.elements[e as usize].props.centroid;
                let (dn, ds) = (i.normal.dot(&d), i.tangent.dot(&d));
                let sd = k_n * dn * i.normal + k_s * ds * i.tangent;
                tl * (sd.x.abs() + sd.y.abs())
            };
            [lever(f.a), lever(f.b), tl * k_s * i.gauss_offset()]
        };
        let mut jumps = Vec::new();
        let carries = faces
            .iter()
            .map(|f| {
                // The failing interfaces are sorted by their elements.
                let start = pairs.partition_point(|&p| p < (f.a, f.b));
                let end = start
                    + pairs[start..]
                        .iter()
                        .take_while(|&&p| p == (f.a, f.b))
                        .count();
                let range = if taken[start..end].iter().any(|&t| t) {
                    [0, 0]
                } else {
                    [start as u32, end as u32]
                };
                taken[range[0] as usize..range[1] as usize].fill(true);
                if model.formulation == Formulation::RigidPoisson {
                    jumps.push(jumped(f, range));
                }
                Carry {
                    range,
                    screen: if range[1] == range[0] + 1 {
                        screen(failing[start])
                    } else {
                        K::NEVER
                    },
                }
            })
            .collect();
        assert!(
            taken.iter().all(|&t| t),
            "every failing interface lies in a coupling"
        );
        Carried {
            carries,
            jumped: jumps,
        }
    }
}

/// The failing interfaces `plastic` as those of the formulation `K`.
///
/// # Panics
/// If they are of another formulation.
pub(super) fn failing_of<K: Kinematics<N>, const N: usize>(
    plastic: &dyn PlasticForces,
) -> &FailingInterfaces<K, N> {
    plastic
        .as_any()
        .downcast_ref::<FailingInterfaces<K, N>>()
        .expect("the failing interfaces of the evaluator's formulation")
}

/// The assembled couplings with the failing interfaces they carry, for one sweep that updates
/// `state`; under the Poisson correction (`rigid-poisson`) with the cells' `q`, whose jump the
/// failing interfaces' laws bound ([`Jump`]; the correction's own forces are
/// `super::poisson`'s).
pub(super) struct WithFailure<'a, K: Screened<N>, const N: usize> {
    assembled: &'a Assembled<K, N>,
    carried: &'a Carried<K::Screen>,
    failing: &'a FailingInterfaces<K, N>,
    state: &'a FailureState,
    q: Option<&'a Pressures<'a>>,
}

impl<'a, K: Screened<N>, const N: usize> WithFailure<'a, K, N> {
    /// `assembled` with what its blocks carry, the failing interfaces `plastic` (of the
    /// formulation `K`) in `state`.
    ///
    /// # Panics
    /// If the evaluator was built for a model whose interfaces do not fail (no `carried`), or
    /// `plastic` is not of the formulation `K`, or `carried` not of `assembled`.
    pub(super) fn new(
        assembled: &'a Assembled<K, N>,
        carried: Option<&'a Carried<K::Screen>>,
        plastic: &'a dyn PlasticForces,
        state: &'a mut FailureState,
    ) -> Self {
        let failing = failing_of::<K, N>(plastic);
        let carried = carried.expect("an evaluator built for a model whose interfaces fail");
        assert_eq!(carried.carries.len(), assembled.faces().len());
        WithFailure {
            assembled,
            carried,
            failing,
            state,
            q: None,
        }
    }

    /// The same couplings, whose failing interfaces' laws act on the jump of the Poisson
    /// correction's `q`.
    pub(super) fn jumped(self, q: &'a Pressures<'a>) -> Self {
        WithFailure { q: Some(q), ..self }
    }

    /// Where `face` is in the blocks.
    #[inline(always)]
    fn index(&self, face: &Face<Block<N>>) -> usize {
        place(self.assembled.faces(), face)
    }
}

impl<K: Screened<N>, const N: usize> WithFailure<'_, K, N> {
    /// The plastic forces on `a` and `b` of the failing interfaces `range` of one coupling
    /// ([`FailingInterfaces::couple`]). Out of line, so that the sweep keeps an element's
    /// forces in registers past a coupling whose screen passes (10⁴-element rigid Voronoi
    /// panel that stays elastic, one thread: 24–30 ns per element-step, as against 28–30 with
    /// the screen's checks alone and the return mapping in line, and 17–20 elastic).
    #[inline(never)]
    fn plastic_forces(
        &self,
        range: std::ops::Range<usize>,
        ua: &[f64; N],
        ub: &[f64; N],
        jump: Jump,
    ) -> [[f64; N]; 2] {
        let [mut fa, mut fb] = [[0.0; N]; 2];
        // A sweep computes each coupling once, and `Carried` gives each failing interface to
        // one coupling.
        self.failing
            .couple(range, self.state, (ua, ub), jump, &mut fa, &mut fb);
        [fa, fb]
    }
}

impl<K: Screened<N>, const N: usize> Couplings<N> for WithFailure<'_, K, N> {
    type Ref = Block<N>;
    const PREFETCH: bool = <Assembled<K, N> as Couplings<N>>::PREFETCH;
    /// The evaluators find no runs where interfaces fail: each coupling is met on its own.
    const RUNS: bool = false;
    const WIDE: bool = false;
    const OWN: bool = <Assembled<K, N> as Couplings<N>>::OWN;
    #[inline(always)]
    fn faces(&self) -> &[Face<Block<N>>] {
        self.assembled.faces()
    }
    type Coupling<'b>
        = Carrying<'b, K::Screen, N>
    where
        Self: 'b;
    /// The sweep names a coupling by its place in [`Couplings::faces`] (a reference into it),
    /// which gives what it carries; with its elements' `q` under the Poisson correction.
    #[inline(always)]
    fn coupling<'b>(&'b self, face: &'b Face<Block<N>>) -> Self::Coupling<'b> {
        let jump = self
            .q
            .map(|q| [q.get(face.a as usize), q.get(face.b as usize)]);
        let k = self.index(face);
        let jump = jump.map(|q| (q, &self.carried.jumped[k]));
        (&face.record, &self.carried.carries[k], jump)
    }
    /// A fresh interface carried alone is screened on the block's products, and its bound of
    /// the correction's jump where there is one ([`Jumped`]).
    #[inline(always)]
    fn add_pair(
        &self,
        _: impl Lanes,
        (block, carry, jumped): Carrying<'_, K::Screen, N>,
        ua: &[f64; N],
        ub: &[f64; N],
        fa: &mut [f64; N],
        fb: &mut [f64; N],
    ) {
        let [on_a, on_b] = Assembled::<K, N>::products(block, ua, ub);
        for p in 0..N {
            fa[p] += on_a[p];
            fb[p] += on_b[p];
        }
        let [start, end] = carry.range.map(|j| j as usize);
        if start == end {
            return;
        }
        let force = [on_b[0] - on_a[0], on_b[1] - on_a[1]];
        let slack = jumped.map_or(0.0, |([qa, qb], &[per_a, per_b, per_odd])| {
            per_a * qa.abs() + per_b * qb.abs() + per_odd * (qa - qb).abs()
        });
        if K::passes(&carry.screen, force, slack, ua, ub)
            && self.failing.is_fresh(start, self.state)
        {
            return;
        }
        let jump = jumped.map(|(q, _)| q);
        let [plastic_a, plastic_b] = self.plastic_forces(start..end, ua, ub, jump);
        for p in 0..N {
            fa[p] += plastic_a[p];
            fb[p] += plastic_b[p];
        }
    }
    #[inline(always)]
    fn add_ground(&self, face: &Face<Block<N>>, ua: &[f64; N], fa: &mut [f64; N]) {
        self.assembled.add_ground(face, ua, fa);
    }
    #[inline(always)]
    fn add_own(&self, e: usize, ue: &[f64; N], f: &mut [f64; N]) {
        self.assembled.add_own(e, ue, f);
    }
}

//! The mass matrix `M`: block-diagonal, one block per element (eqs. 7–9), inverted once.
//!
//! Fixed DOFs get a zero row in `M⁻¹`, so they never move; the explicit step stays
//! element-local.

use crate::lanes::Lanes;
use crate::model::Model;
use crate::parallel::{for_each_chunk_pair, CHUNK};
use std::ops::Range;

/// The explicit update of a step ([`crate::step::integrator`]): `M`, `Δt` and the damping factors,
/// for
/// evaluators that fuse it with the evaluation ([`crate::force::evaluator::FusedStep::advance`])
/// and
/// apply it element by element ([`Update::resolve`]).
#[derive(Debug, Clone, Copy)]
pub struct Update<'a> {
    /// The model's mass matrix.
    pub mass: &'a Mass,
    /// Time step (s).
    pub dt: f64,
    /// `(1 − αΔt/2, 1/(1 + αΔt/2))` of mass-proportional damping `α`.
    pub damping: (f64, f64),
}

impl Update<'_> {
    /// Runs `then` with this update for the consecutive `elements`, its `M` and `M⁻¹` sliced to
    /// them and its kind (lumped or block) and whether it is damped fixed at compile time: the
    /// loop that calls it per element then tests neither.
    pub fn resolve<const N: usize>(&self, elements: Range<usize>, then: impl WithUpdate<N>) {
        debug_assert_eq!(self.mass.nd(), N, "the update of {N} DOFs per element");
        fn run<B: ElementInverse<N>, const N: usize>(
            (m, inv): (&[B], &[B]),
            dt: f64,
            damping: (f64, f64),
            then: impl WithUpdate<N>,
        ) {
            match damping != (1.0, 1.0) {
                true => then.run(Resolved::<B, true> {
                    m,
                    inv,
                    dt,
                    damping,
                }),
                false => then.run(Resolved::<B, false> {
                    m,
                    inv,
                    dt,
                    damping,
                }),
            }
        }
        match self.mass {
            Mass::Diagonal { m, inv, .. } => run(
                (
                    &m.as_chunks::<N>().0[elements.clone()],
                    &inv.as_chunks::<N>().0[elements],
                ),
                self.dt,
                self.damping,
                then,
            ),
            Mass::Blocks { m, inv, .. } => run(
                (
                    &m.as_chunks::<N>().0.as_chunks::<N>().0[elements.clone()],
                    &inv.as_chunks::<N>().0.as_chunks::<N>().0[elements],
                ),
                self.dt,
                self.damping,
                then,
            ),
        }
    }
}

/// What runs with an [`ElementUpdate`] once [`Update::resolve`] has fixed its type.
pub trait WithUpdate<const N: usize> {
    /// Called once, with the update of the resolved elements.
    fn run<E: ElementUpdate<N>>(self, update: E);
}

/// The update of an element of a run ([`Update::resolve`]).
pub trait ElementUpdate<const N: usize> {
    /// Whether the update is damped (then [`ElementUpdate::element`] returns the damping's power).
    const DAMPED: bool;
    /// `v_i ← (c₁ v_i − Δt M_i⁻¹ f_i) c₂`, then `u_i ← u_i + Δt v_i`, for the run's element `i`.
    /// Returns `v̄ᵀ M_i v̄` with `v̄` the mean of the old and new `v_i` when damped (the damping's
    /// work of the step is `α Δt` times its sum), else 0.
    fn element(&self, i: usize, f: &[f64; N], v: &mut [f64; N], u: &mut [f64; N]) -> f64;

    /// [`ElementUpdate::element`] for the run's elements `i..i + 4`, with their powers.
    fn elements(
        &self,
        lanes: impl Lanes,
        i: usize,
        f: &[[f64; N]; 4],
        v: &mut [[f64; N]; 4],
        u: &mut [[f64; N]; 4],
    ) -> [f64; 4];
}

/// An element's `M_e⁻¹` (or `M_e`): its diagonal (lumped) or its row-major block.
trait ElementInverse<const N: usize> {
    /// `aᵀ B a` for this block `B`.
    fn quadratic(&self, a: &[f64; N]) -> f64;
    /// The undamped update of four elements, `v` then `u`, if these blocks have a form for it
    /// (`false`: `v` and `u` are untouched).
    #[inline(always)]
    fn update_of_four(
        lanes: impl Lanes,
        blocks: &[Self; 4],
        f: &[[f64; N]; 4],
        v: &mut [[f64; N]; 4],
        u: &mut [[f64; N]; 4],
        dt: f64,
    ) -> bool
    where
        Self: Sized,
    {
        let _ = (lanes, blocks, f, v, u, dt);
        false
    }
    /// `v ← (c₁ v − Δt M_e⁻¹ f) c₂`; undamped, `c₁ = c₂ = 1` are left out, which changes no bit.
    fn velocity<const DAMPED: bool>(
        &self,
        v: &mut [f64; N],
        f: &[f64; N],
        dt: f64,
        damping: (f64, f64),
    );
}

impl<const N: usize> ElementInverse<N> for [f64; N] {
    #[inline(always)]
    fn quadratic(&self, a: &[f64; N]) -> f64 {
        (0..N).map(|j| self[j] * a[j] * a[j]).sum()
    }
    #[inline(always)]
    fn velocity<const DAMPED: bool>(
        &self,
        v: &mut [f64; N],
        f: &[f64; N],
        dt: f64,
        damping: (f64, f64),
    ) {
        lumped_velocity::<DAMPED>(v, f, self, dt, damping)
    }
    /// [`lumped_update`] of the four elements' numbers as they lie.
    #[inline(always)]
    fn update_of_four(
        lanes: impl Lanes,
        blocks: &[Self; 4],
        f: &[[f64; N]; 4],
        v: &mut [[f64; N]; 4],
        u: &mut [[f64; N]; 4],
        dt: f64,
    ) -> bool {
        let (f, _) = f.as_flattened().as_chunks::<4>();
        let (w, _) = blocks.as_flattened().as_chunks::<4>();
        let (v, _) = v.as_flattened_mut().as_chunks_mut::<4>();
        let (u, _) = u.as_flattened_mut().as_chunks_mut::<4>();
        lumped_update(lanes, dt, f, w, v, u);
        true
    }
}

impl<const N: usize> ElementInverse<N> for [[f64; N]; N] {
    #[inline(always)]
    fn quadratic(&self, a: &[f64; N]) -> f64 {
        (0..N)
            .map(|i| a[i] * (0..N).map(|j| self[i][j] * a[j]).sum::<f64>())
            .sum()
    }
    #[inline(always)]
    fn velocity<const DAMPED: bool>(
        &self,
        v: &mut [f64; N],
        f: &[f64; N],
        dt: f64,
        damping: (f64, f64),
    ) {
        block_velocity::<DAMPED>(v, f, self.as_flattened(), dt, damping)
    }
}

/// An [`Update`] resolved for a run of elements: their `M_e` and `M_e⁻¹`, `B` per element.
#[derive(Clone, Copy)]
struct Resolved<'a, B, const DAMPED: bool> {
    m: &'a [B],
    inv: &'a [B],
    dt: f64,
    damping: (f64, f64),
}

impl<B: ElementInverse<N>, const N: usize, const DAMPED: bool> ElementUpdate<N>
    for Resolved<'_, B, DAMPED>
{
    const DAMPED: bool = DAMPED;
    #[inline(always)]
    fn element(&self, i: usize, f: &[f64; N], v: &mut [f64; N], u: &mut [f64; N]) -> f64 {
        // `v_i` is updated in registers: read back from memory, its fresh scalar stores could not
        // be forwarded to a vector load.
        let mut vi = *v;
        self.inv[i].velocity::<DAMPED>(&mut vi, f, self.dt, self.damping);
        for j in 0..N {
            u[j] += self.dt * vi[j];
        }
        let power = if DAMPED {
            self.m[i].quadratic(&std::array::from_fn(|j| 0.5 * (v[j] + vi[j])))
        } else {
            0.0
        };
        *v = vi;
        power
    }

    /// Lumped and undamped, four numbers at a time; else element by element.
    #[inline(always)]
    fn elements(
        &self,
        lanes: impl Lanes,
        i: usize,
        f: &[[f64; N]; 4],
        v: &mut [[f64; N]; 4],
        u: &mut [[f64; N]; 4],
    ) -> [f64; 4] {
        let inv: &[B; 4] = self.inv[i..i + 4].try_into().expect("four elements");
        if DAMPED || !B::update_of_four(lanes, inv, f, v, u, self.dt) {
            return std::array::from_fn(|l| self.element(i + l, &f[l], &mut v[l], &mut u[l]));
        }
        [0.0; 4]
    }
}

/// The undamped lumped update `v ← v − Δt w f`, then `u ← u + Δt v`, four numbers at a time,
/// whatever DOFs the lanes hold: four elements' DOFs one after the other, or the same DOF of
/// four elements (a step on the state in groups, [`crate::lanes::grouped`]).
#[inline(always)]
pub fn lumped_update(
    lanes: impl Lanes,
    dt: f64,
    f: &[[f64; 4]],
    w: &[[f64; 4]],
    v: &mut [[f64; 4]],
    u: &mut [[f64; 4]],
) {
    for (((v, u), w), f) in v.iter_mut().zip(u).zip(w).zip(f) {
        *v = lanes.sub(*v, lanes.mul(lanes.mul([dt; 4], *w), *f));
        *u = lanes.add(*u, lanes.mul([dt; 4], *v));
    }
}

/// `v ← (c₁ v − Δt w f) c₂` with the lumped `M_e⁻¹ = diag(w)`.
#[inline(always)]
fn lumped_velocity<const DAMPED: bool>(
    v: &mut [f64],
    f: &[f64],
    w: &[f64],
    dt: f64,
    (c1, c2): (f64, f64),
) {
    for ((v, f), w) in v.iter_mut().zip(f).zip(w) {
        *v = if DAMPED {
            (c1 * *v - dt * w * f) * c2
        } else {
            *v - dt * w * f
        };
    }
}

/// `v ← (c₁ v − Δt B f) c₂` with the row-major block `M_e⁻¹ = B` of `v.len()` rows (a
/// constant wherever the caller's is).
#[inline(always)]
fn block_velocity<const DAMPED: bool>(
    v: &mut [f64],
    f: &[f64],
    b: &[f64],
    dt: f64,
    (c1, c2): (f64, f64),
) {
    let nd = v.len();
    for i in 0..nd {
        let a: f64 = (0..nd).map(|j| b[i * nd + j] * f[j]).sum();
        v[i] = if DAMPED {
            (c1 * v[i] - dt * a) * c2
        } else {
            v[i] - dt * a
        };
    }
}

/// `M` and `M⁻¹` of a model. Diagonal blocks are stored as diagonals.
#[derive(Debug, Clone)]
pub enum Mass {
    /// Lumped: a diagonal `M` (the rigid formulation, eq. 9).
    Diagonal {
        /// DOFs per element.
        nd: usize,
        /// `m[i]` per DOF (kg, kg·m²).
        m: Vec<f64>,
        /// `1/m[i]`, 0 for a fixed DOF.
        inv: Vec<f64>,
    },
    /// One dense `nd × nd` block per element, row-major (the hybrid formulation, eq. 8). Zero
    /// rows and columns on fixed DOFs in `inv`, `l` and `l_inv`.
    Blocks {
        /// DOFs per element.
        nd: usize,
        /// The blocks `M_e`.
        m: Vec<f64>,
        /// The inverse of each block's free part.
        inv: Vec<f64>,
        /// The Cholesky factor `L` of each block's free part, `M_e = L Lᵀ`.
        l: Vec<f64>,
        /// `L⁻¹`.
        l_inv: Vec<f64>,
    },
}

impl Mass {
    /// The mass of every element from the formulation (eq. 9 for rigid).
    pub fn new(model: &Model) -> Mass {
        let nd = model.formulation.ndof();
        let blocks: Vec<Vec<f64>> = model
            .elements
            .iter()
            .map(|el| model.formulation.mass(&el.props, el.rho * model.thickness))
            .collect();
        if blocks
            .iter()
            .any(|b| (0..nd).any(|i| (0..nd).any(|j| i != j && b[i * nd + j] != 0.0)))
        {
            return Mass::blocks(model, nd, blocks);
        }
        let mut m = Vec::with_capacity(model.n_dofs());
        for block in &blocks {
            m.extend((0..nd).map(|i| block[i * nd + i]));
        }
        let mut inv: Vec<f64> = m.iter().map(|x| 1.0 / x).collect();
        for &d in &model.fixed {
            inv[d] = 0.0;
        }
        Mass::Diagonal { nd, m, inv }
    }

    /// The consistent block mass of eq. 8, each block's free part inverted once.
    fn blocks(model: &Model, nd: usize, blocks: Vec<Vec<f64>>) -> Mass {
        let mut fixed = vec![false; model.n_dofs()];
        for &d in &model.fixed {
            fixed[d] = true;
        }
        let (mut m, mut inv, mut l, mut l_inv) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (e, b) in blocks.iter().enumerate() {
            let free: Vec<usize> = (0..nd).filter(|&i| !fixed[e * nd + i]).collect();
            let sub = nalgebra::DMatrix::from_fn(free.len(), free.len(), |i, j| {
                b[free[i] * nd + free[j]]
            });
            let chol = sub
                .cholesky()
                .expect("element mass blocks are positive definite");
            let (si, sf) = (chol.inverse(), chol.l());
            let sl = sf
                .clone()
                .try_inverse()
                .expect("a Cholesky factor is invertible");
            let (mut bi, mut bf, mut bl) =
                (vec![0.0; nd * nd], vec![0.0; nd * nd], vec![0.0; nd * nd]);
            for (i, &fi) in free.iter().enumerate() {
                for (j, &fj) in free.iter().enumerate() {
                    bi[fi * nd + fj] = si[(i, j)];
                    bf[fi * nd + fj] = sf[(i, j)];
                    bl[fi * nd + fj] = sl[(i, j)];
                }
            }
            m.extend_from_slice(b);
            inv.extend(bi);
            l.extend(bf);
            l_inv.extend(bl);
        }
        Mass::Blocks {
            nd,
            m,
            inv,
            l,
            l_inv,
        }
    }

    /// The diagonal of `M` (the whole matrix when lumped).
    pub fn diagonal(&self) -> Vec<f64> {
        match self {
            Mass::Diagonal { m, .. } => m.clone(),
            Mass::Blocks { nd, m, .. } => (0..m.len() / nd)
                .map(|k| m[(k / nd) * nd * nd + (k % nd) * (nd + 1)])
                .collect(),
        }
    }

    /// Whether `M` is diagonal (lumped).
    pub fn is_diagonal(&self) -> bool {
        matches!(self, Mass::Diagonal { .. })
    }

    /// The entries of `M` as triplets `(row, col, value)` over all DOFs.
    pub fn triplets(&self) -> Vec<(usize, usize, f64)> {
        match self {
            Mass::Diagonal { m, .. } => m.iter().enumerate().map(|(i, &v)| (i, i, v)).collect(),
            Mass::Blocks { nd, m, .. } => (0..m.len())
                .map(|k| {
                    let (e, r) = (k / (nd * nd), k % (nd * nd));
                    (e * nd + r / nd, e * nd + r % nd, m[k])
                })
                .collect(),
        }
    }

    /// Number of DOFs.
    pub fn n(&self) -> usize {
        match self {
            Mass::Diagonal { m, .. } => m.len(),
            Mass::Blocks { nd, m, .. } => m.len() / nd,
        }
    }

    /// One explicit update from the net force `f = f_int − P − f_c` ([`crate::step::integrator`]):
    /// `v ← (c₁ v − Δt M⁻¹ f) c₂`, then `u ← u + Δt v` unless `u` is empty. Element-local and
    /// in parallel, one pass over the vectors; the result does not depend on the thread count.
    pub fn advance(&self, f: &[f64], v: &mut [f64], u: &mut [f64], dt: f64, (c1, c2): (f64, f64)) {
        let nd = self.nd();
        for_each_chunk_pair(v, u, CHUNK * nd, |first, v, u| {
            let f = &f[first..first + v.len()];
            for (k, (ve, fe)) in v.chunks_exact_mut(nd).zip(f.chunks_exact(nd)).enumerate() {
                self.velocity_update(first / nd + k, fe, ve, dt, (c1, c2));
            }
            for (u, v) in u.iter_mut().zip(v.iter()) {
                *u += dt * v;
            }
        });
    }

    /// `v_e ← (c₁ v_e − Δt M_e⁻¹ f_e) c₂` for element `e`.
    #[inline(always)]
    fn velocity_update(&self, e: usize, f: &[f64], v: &mut [f64], dt: f64, damping: (f64, f64)) {
        let nd = v.len();
        match self {
            Mass::Diagonal { inv, .. } => {
                lumped_velocity::<true>(v, f, &inv[e * nd..(e + 1) * nd], dt, damping)
            }
            Mass::Blocks { inv, .. } => {
                block_velocity::<true>(v, f, &inv[e * nd * nd..(e + 1) * nd * nd], dt, damping)
            }
        }
    }

    /// Kinetic energy `½ vᵀ M v`.
    pub fn kinetic_energy(&self, v: &[f64]) -> f64 {
        self.kinetic_product(v, v)
    }

    /// `½ aᵀ M b`.
    pub fn kinetic_product(&self, a: &[f64], b: &[f64]) -> f64 {
        match self {
            Mass::Diagonal { m, .. } => {
                0.5 * a
                    .iter()
                    .zip(b)
                    .zip(m)
                    .map(|((a, b), m)| m * a * b)
                    .sum::<f64>()
            }
            Mass::Blocks { nd, m, .. } => {
                0.5 * a
                    .chunks_exact(*nd)
                    .zip(b.chunks_exact(*nd))
                    .enumerate()
                    .map(|(e, (ae, be))| {
                        let blk = &m[e * nd * nd..(e + 1) * nd * nd];
                        (0..*nd)
                            .map(|i| ae[i] * (0..*nd).map(|j| blk[i * nd + j] * be[j]).sum::<f64>())
                            .sum::<f64>()
                    })
                    .sum::<f64>()
            }
        }
    }

    /// `y = L⁻ᵀ x` with `M = L Lᵀ` on the free DOFs (0 on fixed DOFs): `L⁻¹ K L⁻ᵀ` has the
    /// squared frequencies `ω²` of `K φ = ω² M φ` as eigenvalues. For a lumped mass,
    /// `L = M^{½}`.
    pub fn inv_factor_t(&self, x: &[f64], y: &mut [f64]) {
        self.apply_range(0, x, y, true, true)
    }

    /// `y = L⁻¹ x` (see [`Mass::inv_factor_t`]).
    pub fn inv_factor(&self, x: &[f64], y: &mut [f64]) {
        self.apply_range(0, x, y, false, true)
    }

    /// `y = L x` on the free DOFs (the shift-invert operator `Lᵀ (K − σM)⁻¹ L` uses it).
    pub fn factor(&self, x: &[f64], y: &mut [f64]) {
        self.apply_range(0, x, y, false, false)
    }

    /// `y = Lᵀ x` on the free DOFs.
    pub fn factor_t(&self, x: &[f64], y: &mut [f64]) {
        self.apply_range(0, x, y, true, false)
    }

    /// The diagonal of a lumped `M⁻¹` (zero on fixed DOFs); `None` for blocks.
    pub fn lumped_inverse(&self) -> Option<&[f64]> {
        match self {
            Mass::Diagonal { inv, .. } => Some(inv),
            Mass::Blocks { .. } => None,
        }
    }

    /// DOFs per element.
    pub fn nd(&self) -> usize {
        match self {
            Mass::Diagonal { nd, .. } | Mass::Blocks { nd, .. } => *nd,
        }
    }

    /// `L`, `Lᵀ`, `L⁻¹` or `L⁻ᵀ` applied element by element to the DOFs `first ..` of the whole
    /// vector (`first` a multiple of `nd`), so that chunks can be done in parallel.
    pub fn apply_range(
        &self,
        first: usize,
        x: &[f64],
        y: &mut [f64],
        transpose: bool,
        inverse: bool,
    ) {
        match self {
            // `L = M^{½}` on the free DOFs, square roots taken here rather than stored.
            Mass::Diagonal { inv, .. } if inverse => {
                for ((y, x), w) in y.iter_mut().zip(x).zip(&inv[first..]) {
                    *y = x * w.sqrt();
                }
            }
            Mass::Diagonal { m, inv, .. } => {
                for (((y, x), w), m) in y.iter_mut().zip(x).zip(&inv[first..]).zip(&m[first..]) {
                    *y = if *w == 0.0 { 0.0 } else { x * m.sqrt() };
                }
            }
            Mass::Blocks { nd, l, l_inv, .. } => {
                let factor = &(if inverse { l_inv } else { l })[first * nd..];
                for (e, (ye, xe)) in y.chunks_exact_mut(*nd).zip(x.chunks_exact(*nd)).enumerate() {
                    let b = &factor[e * nd * nd..(e + 1) * nd * nd];
                    for i in 0..*nd {
                        ye[i] = (0..*nd).map(|j| if transpose { b[j * nd + i] } else { b[i * nd + j] } * xe[j]).sum();
                    }
                }
            }
        }
    }
}

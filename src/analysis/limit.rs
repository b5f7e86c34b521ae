//! The stability limit of central difference, `Δt_crit = 2/ω_max`, as a setup knows it: a
//! proven bracket of `ω_max` from the elements' diagonal blocks (one pass over the interfaces),
//! and `ω_max` itself by Lanczos when the time step or the analysis needs it, to the precision
//! it needs. `rbsm stability` compares the cheap bounds with it
//! ([`crate::analysis::stability`]).

use crate::analysis::free::FreeSystem;
use crate::force::evaluator::{interface_stiffness, Evaluator};
use crate::model::formulation::{Formulation, Hybrid, Kinematics, Rigid};
use crate::model::mass::Mass;
use crate::model::{Model, GROUND};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::Par;
use nalgebra::{DMatrix, SMatrix};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};

/// `Δt_crit = 2 / ω_max` (s).
pub fn critical_time_step(omega_max: f64) -> f64 {
    2.0 / omega_max
}

/// Settling tolerance of the Lanczos `ω_max²` when the exact value is asked for (`check`,
/// `stability`, `eigen`, `tradeoff`, `run --exact-dt-crit`): see [`omega_max`].
pub const EXACT: f64 = 1e-11;

/// Settling tolerance of the Lanczos `ω_max²` for the time step of a run given as a `dt_factor`,
/// which needs a few digits. Measured on a 10⁶-element rigid grid (3·10⁶ DOFs): 90 iterations
/// instead of 2640, `ω_max` within 4e-5 of the exact value (below it, so the step is longer by
/// as much).
pub const FOR_STEP: f64 = 1e-4;

/// Lanczos iterations done in this process, by every `ω_max` and every thread.
static ITERATIONS: AtomicU64 = AtomicU64::new(0);

/// How many Lanczos iterations this process has done so far (tests count them).
pub fn lanczos_iterations() -> u64 {
    ITERATIONS.load(Ordering::Relaxed)
}

/// The largest circular frequency `ω_max` (rad/s) of `K φ = ω² M φ` over the free DOFs, matrix
/// free: Lanczos on `L⁻¹ K L⁻ᵀ` (`M = L Lᵀ`; `M^{−½} K M^{−½}` for a lumped mass) applied
/// through the evaluator, three vectors of memory.
///
/// Without reorthogonalisation Lanczos still gives the extreme eigenvalue exactly (lost
/// orthogonality only adds copies of converged values). We stop when the largest Ritz value has
/// moved by less than `tolerance` (relative; [`EXACT`] or [`FOR_STEP`]) over the last 20
/// iterations (looked at every 10); it never exceeds `ω_max²`, so the value converges from
/// below. (faer's Krylov–Schur, which waits
/// for the eigenvector's residual, took 10× longer on a 10⁵-DOF square grid, whose top
/// eigenvalues are clustered: 9.8 s against 1.0 s, 353 s at 10⁶ DOFs.)
///
/// On long thin models the top of the spectrum is a cluster of spacing `~ω²/N²` (`N` elements
/// along) that the Ritz value creeps into as `~1/k²`: that stop took 12 600 iterations on a free
/// 20 000-element chain and fell 2e-9 short (6.6e-9 on 300 elements, where it settled on a
/// plateau). So after 200, 400, 800, … unsettled iterations, once a sparse Cholesky of
/// `σM − K` (`K` probed through the evaluator on the model's element graph) is estimated to
/// cost less than the iterations done, we bisect on its inertia instead: `σM − K` factors
/// exactly when `σ > ω_max²`. From the Ritz value the bracket closes to 1e-12 (relative, in
/// `ω²`) and its upper end is returned. (Against dense: ≤ 2.5e-13 on chains and strips up to
/// 3000 DOFs.)
///
/// `rigid-poisson`: its `K` couples the neighbours of each cell with each other, which the
/// element graph of the inertia's probes does not hold, so Lanczos alone settles it.
pub fn omega_max(model: &Model, evaluator: &dyn Evaluator, mass: &Mass, tolerance: f64) -> f64 {
    let probed = model.formulation != Formulation::RigidPoisson;
    top(
        evaluator,
        mass,
        tolerance,
        || Graph::of_model(model, mass.nd()),
        |g| {
            probed
                .then(|| Inertia::probed(model, g, evaluator, mass))
                .flatten()
        },
    )
}

/// [`omega_max`], with the graph of `K`'s blocks and the [`Inertia`] built from it when needed.
fn top(
    evaluator: &dyn Evaluator,
    mass: &Mass,
    tolerance: f64,
    graph: impl FnOnce() -> Graph,
    inertia_of: impl FnOnce(&Graph) -> Option<Inertia>,
) -> f64 {
    const MAX_ITER: usize = 20_000;
    let mut history: Vec<f64> = Vec::new();
    let mut result = None;
    let (mut graph, mut inertia_of) = (Some(graph), Some(inertia_of));
    let mut plan: Option<(Graph, f64, f64)> = None;
    let mut inertia: Option<Option<Inertia>> = None;
    lanczos(evaluator, mass, MAX_ITER, |alpha, beta, b| {
        let j = alpha.len() - 1;
        let a = alpha[j];
        if !a.is_finite() {
            result = Some(f64::NAN);
            return true;
        }
        // The bisection costs O(j): look every 10 iterations (or at breakdown or the end), so
        // that the tridiagonal work stays well below the operator's on large models.
        let breakdown = b <= 1e-14 * a.abs().max(history.last().copied().unwrap_or(0.0));
        if j % 10 == 0 || breakdown || j + 1 == MAX_ITER.min(mass.n()) {
            let top = largest_tridiagonal_eigenvalue(alpha, beta);
            history.push(top);
            let k = history.len();
            let settled = k > 2 && (top - history[k - 3]).abs() <= tolerance * top;
            if settled || breakdown {
                result = Some(top.max(0.0).sqrt());
                return true;
            }
        }
        // Unsettled after 200 · 2^m iterations: switch if the factorisations would cost less
        // than the iterations done, first by the banded bound, then by the symbolic Cholesky.
        let done = j + 1;
        if done % INERTIA_FROM == 0 && (done / INERTIA_FROM).is_power_of_two() {
            let (g, banded, per_iteration) = plan.get_or_insert_with(|| {
                let g = graph.take().expect("built once")();
                let (banded, per_iteration) = g.costs();
                (g, banded, per_iteration)
            });
            let budget = done as f64 * *per_iteration / INERTIA_FACTORISATIONS;
            if *banded <= budget {
                let inertia = inertia.get_or_insert_with(|| inertia_of.take().and_then(|f| f(g)));
                if let Some(l) = inertia
                    .as_ref()
                    .filter(|x| x.flops <= budget)
                    .and_then(|x| x.bisect(largest_tridiagonal_eigenvalue(alpha, beta)))
                {
                    result = Some(l.sqrt());
                    return true;
                }
            }
        }
        false
    });
    result.unwrap_or_else(|| history.last().copied().unwrap_or(0.0).max(0.0).sqrt())
}

/// Which blocks of `K` may be non-zero: `nd × nd` blocks between nodes (elements, or single
/// DOFs) and their neighbours.
struct Graph {
    nd: usize,
    neighbours: Vec<Vec<usize>>,
}

impl Graph {
    /// Elements and the interfaces between them.
    fn of_model(model: &Model, nd: usize) -> Graph {
        let mut neighbours = vec![Vec::new(); model.elements.len()];
        for i in model
            .interfaces
            .iter()
            .filter(|i| i.a != GROUND && i.b != GROUND && i.a != i.b)
        {
            neighbours[i.a as usize].push(i.b as usize);
            neighbours[i.b as usize].push(i.a as usize);
        }
        for l in neighbours.iter_mut() {
            l.sort_unstable();
            l.dedup();
        }
        Graph { nd, neighbours }
    }

    /// The free DOFs and the pattern of `K_ff`.
    fn of_system(sys: &FreeSystem) -> Graph {
        let neighbours = (0..sys.n())
            .map(|j| {
                sys.k
                    .symbolic()
                    .row_idx_of_col_raw(j)
                    .iter()
                    .copied()
                    .filter(|&i| i != j)
                    .collect()
            })
            .collect();
        Graph { nd: 1, neighbours }
    }

    /// Flops of one Cholesky factorisation in breadth-first level order from a far node of each
    /// component (a banded factor: a DOF of level `ℓ` has at most `nd (w_ℓ + w_{ℓ+1})`
    /// entries), and of one Lanczos iteration (`2 nnz(K)` and the vector work).
    fn costs(&self) -> (f64, f64) {
        let n = self.neighbours.len();
        let nd = self.nd as f64;
        let mut level = vec![usize::MAX; n];
        let mut seen = vec![false; n];
        let mut queue = Vec::new();
        let mut banded = 0.0;
        for root in 0..n {
            if seen[root] {
                continue;
            }
            // A breadth-first pass to the component's farthest node, then levels from it.
            queue.clear();
            queue.push(root);
            seen[root] = true;
            let mut head = 0;
            while head < queue.len() {
                let v = queue[head];
                head += 1;
                for &w in &self.neighbours[v] {
                    if !seen[w] {
                        seen[w] = true;
                        queue.push(w);
                    }
                }
            }
            let far = *queue.last().expect("the root is queued");
            queue.clear();
            queue.push(far);
            level[far] = 0;
            let mut widths = vec![0usize];
            let mut head = 0;
            while head < queue.len() {
                let v = queue[head];
                head += 1;
                widths[level[v]] += 1;
                for &w in &self.neighbours[v] {
                    if level[w] == usize::MAX {
                        level[w] = level[v] + 1;
                        if widths.len() <= level[w] {
                            widths.push(0);
                        }
                        queue.push(w);
                    }
                }
            }
            widths.push(0);
            banded += widths
                .windows(2)
                .map(|w| w[0] as f64 * nd * (nd * (w[0] + w[1]) as f64).powi(2))
                .sum::<f64>();
        }
        let blocks: usize = self.neighbours.iter().map(|l| 1 + l.len()).sum();
        (banded, 2.0 * blocks as f64 * nd * nd + 12.0 * n as f64 * nd)
    }
}

/// Lanczos iterations before the first look at [`Inertia`], and the factorisations its cost
/// estimate allows for (the bisection takes about 25).
const INERTIA_FROM: usize = 200;
const INERTIA_FACTORISATIONS: f64 = 40.0;

/// `σ M_ff − K_ff` for any `σ`, and its symbolic Cholesky (fill-reducing order, computed once):
/// by Sylvester's law of inertia it is positive definite exactly when `σ > ω_max²`, so one
/// numeric factorisation tells on which side of `ω_max²` a shift lies.
struct Inertia {
    /// `K_ff` and `M_ff` values (lower triangle) in the order of `argsort`.
    k: Vec<f64>,
    m: Vec<f64>,
    pattern: faer::sparse::SymbolicSparseColMat<usize>,
    argsort: faer::sparse::Argsort<usize>,
    symbolic: faer::sparse::linalg::cholesky::SymbolicCholesky<usize>,
    /// Estimated flops of one numeric factorisation.
    flops: f64,
}

impl Inertia {
    /// Probes `K_ff` through the evaluator: elements are coloured so that no two of a colour
    /// are neighbours or share one (interfaces), so one evaluation per colour and DOF gives
    /// those elements' columns without overlap. `None` when there are no free DOFs.
    fn probed(
        model: &Model,
        graph: &Graph,
        evaluator: &dyn Evaluator,
        mass: &Mass,
    ) -> Option<Inertia> {
        use faer::sparse::Pair;
        let (nd, ne) = (mass.nd(), mass.n() / mass.nd());
        let mut index = vec![0usize; mass.n()];
        for &d in &model.fixed {
            index[d] = usize::MAX;
        }
        let mut n = 0;
        for i in index.iter_mut().filter(|i| **i == 0) {
            *i = n;
            n += 1;
        }
        let neighbours = &graph.neighbours;
        // Greedy distance-2 colouring.
        let mut colour = vec![usize::MAX; ne];
        let mut taken: Vec<usize> = Vec::new();
        let mut colours = 0;
        for e in 0..ne {
            taken.clear();
            for &f in &neighbours[e] {
                taken.push(colour[f]);
                taken.extend(neighbours[f].iter().map(|&g| colour[g]));
            }
            taken.sort_unstable();
            let c = (0..)
                .find(|c| taken.binary_search(c).is_err())
                .expect("a free colour");
            colour[e] = c;
            colours = colours.max(c + 1);
        }
        let mut members = vec![Vec::new(); colours];
        for (e, &c) in colour.iter().enumerate() {
            members[c].push(e);
        }
        let (mut x, mut kx) = (vec![0.0; mass.n()], vec![0.0; mass.n()]);
        let (mut entries, mut k, mut m) = (Vec::new(), Vec::new(), Vec::new());
        for group in &members {
            for i in 0..nd {
                for &e in group {
                    x[e * nd + i] = 1.0;
                }
                evaluator.internal_force(&x, &mut kx);
                for &e in group {
                    x[e * nd + i] = 0.0;
                    let col = index[e * nd + i];
                    if col == usize::MAX {
                        continue;
                    }
                    for f in std::iter::once(e).chain(neighbours[e].iter().copied()) {
                        for r in f * nd..(f + 1) * nd {
                            if index[r] != usize::MAX && index[r] >= col {
                                entries.push(Pair::new(index[r], col));
                                k.push(kx[r]);
                                m.push(0.0);
                            }
                        }
                    }
                }
            }
        }
        for (r, c, v) in mass.triplets() {
            if index[r] != usize::MAX && index[c] != usize::MAX && index[r] >= index[c] && v != 0.0
            {
                entries.push(Pair::new(index[r], index[c]));
                k.push(0.0);
                m.push(v);
            }
        }
        Inertia::new(n, &entries, k, m)
    }

    /// From `K_ff` and `M_ff` of a [`FreeSystem`].
    fn of_system(sys: &FreeSystem) -> Option<Inertia> {
        let (mut entries, mut k, mut m) = (Vec::new(), Vec::new(), Vec::new());
        for (mat, is_k) in [(&sys.k, true), (&sys.m, false)] {
            for j in 0..sys.n() {
                for (&i, &v) in mat
                    .symbolic()
                    .row_idx_of_col_raw(j)
                    .iter()
                    .zip(mat.val_of_col(j))
                {
                    if i >= j {
                        entries.push(faer::sparse::Pair::new(i, j));
                        k.push(if is_k { v } else { 0.0 });
                        m.push(if is_k { 0.0 } else { v });
                    }
                }
            }
        }
        Inertia::new(sys.n(), &entries, k, m)
    }

    /// The symbolic Cholesky of the pattern `entries` (lower triangle, `n` free DOFs).
    fn new(
        n: usize,
        entries: &[faer::sparse::Pair<usize, usize>],
        k: Vec<f64>,
        m: Vec<f64>,
    ) -> Option<Inertia> {
        use faer::sparse::{linalg::cholesky, SymbolicSparseColMat};
        if n == 0 {
            return None;
        }
        let (pattern, argsort) = SymbolicSparseColMat::try_new_from_indices(n, n, entries).ok()?;
        let symbolic = cholesky::factorize_symbolic_cholesky(
            pattern.as_ref(),
            faer::Side::Lower,
            Default::default(),
            Default::default(),
        )
        .ok()?;
        let flops = match symbolic.raw() {
            cholesky::SymbolicCholeskyRaw::Simplicial(s) => s
                .col_ptr()
                .windows(2)
                .map(|w| ((w[1] - w[0]) as f64).powi(2))
                .sum(),
            cholesky::SymbolicCholeskyRaw::Supernodal(s) => {
                let rows = s.col_ptr_for_row_idx();
                (0..s.n_supernodes())
                    .map(|j| {
                        let w = (s.supernode_end()[j] - s.supernode_begin()[j]) as f64;
                        w * (w + (rows[j + 1] - rows[j]) as f64).powi(2)
                    })
                    .sum()
            }
        };
        Some(Inertia {
            k,
            m,
            pattern,
            argsort,
            symbolic,
            flops,
        })
    }

    /// Whether `σ M − K` is positive definite (its Cholesky factorisation succeeds; sequential,
    /// so the answer does not depend on the thread count).
    fn above(&self, sigma: f64) -> bool {
        let values: Vec<f64> = self
            .k
            .iter()
            .zip(&self.m)
            .map(|(k, m)| sigma * m - k)
            .collect();
        let Ok(a) = faer::sparse::SparseColMat::new_from_argsort(
            self.pattern.clone(),
            &self.argsort,
            &values,
        ) else {
            return false;
        };
        let mut l = vec![0.0; self.symbolic.len_val()];
        let par = Par::Seq;
        let mut mem = MemBuffer::new(
            self.symbolic
                .factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        );
        self.symbolic
            .factorize_numeric_llt(
                &mut l,
                a.as_ref(),
                faer::Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .is_ok()
    }

    /// `ω_max²` from a lower bound `low > 0` (a Ritz value): a shift above it found by steps
    /// of ×10 in `σ/low − 1` from 1e-6, then bisection until the bracket is 1e-12 (relative);
    /// the bracket's upper end. `None` if no shift up to `low · 10⁶` factors.
    fn bisect(&self, low: f64) -> Option<f64> {
        if !(low > 0.0 && low.is_finite()) {
            return None;
        }
        let (mut lo, mut step) = (low, 1e-6);
        let mut hi = loop {
            let sigma = low * (1.0 + step);
            if self.above(sigma) {
                break sigma;
            }
            lo = sigma;
            step *= 10.0;
            if step > 1e6 {
                return None;
            }
        };
        while hi - lo > 1e-12 * hi {
            let mid = 0.5 * (lo + hi);
            if self.above(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Some(hi)
    }
}

/// Runs Lanczos on `L⁻¹ K L⁻ᵀ` from a fixed random start, calling `look(α, β, b)` after each
/// step with `α` of length `j + 1`, `β` of length `j` and the new `b = β_j`; stops when `look`
/// says so or after `max_iter` steps.
fn lanczos(
    evaluator: &dyn Evaluator,
    mass: &Mass,
    max_iter: usize,
    mut look: impl FnMut(&[f64], &[f64], f64) -> bool,
) {
    use rayon::prelude::*;
    let n = mass.n();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut q: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
    let mut tmp = vec![0.0; n];
    // Start in the free DOFs only (L⁻ᵀ is zero on the fixed ones).
    mass.inv_factor_t(&q, &mut tmp);
    for (q, t) in q.iter_mut().zip(&tmp) {
        if *t == 0.0 {
            *q = 0.0;
        }
    }
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm == 0.0 {
        return;
    }
    q.iter_mut().for_each(|x| *x /= norm);
    mass.inv_factor_t(&q, &mut tmp);
    // The vector work in three fused passes, parallel over element-aligned chunks; partial sums
    // are added in chunk order, so the result does not depend on the thread count.
    let len = crate::parallel::CHUNK * mass.nd();
    let sum = |parts: Vec<f64>| parts.iter().sum::<f64>();
    let (mut q_prev, mut w, mut kx) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut alpha, mut beta): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    for _ in 0..max_iter.min(n) {
        ITERATIONS.fetch_add(1, Ordering::Relaxed);
        evaluator.internal_force(&tmp, &mut kx);
        // w = L⁻¹ K L⁻ᵀ q and α = wᵀ q.
        let a = sum(w
            .par_chunks_mut(len)
            .zip(kx.par_chunks(len))
            .zip(q.par_chunks(len))
            .enumerate()
            .map(|(c, ((w, kx), q))| {
                mass.apply_range(c * len, kx, w, false, true);
                w.iter().zip(q).map(|(w, q)| w * q).sum::<f64>()
            })
            .collect());
        let b_prev = beta.last().copied().unwrap_or(0.0);
        // w −= α q + β q_prev and β = |w|.
        let b = sum(w
            .par_chunks_mut(len)
            .zip(q.par_chunks(len))
            .zip(q_prev.par_chunks(len))
            .map(|((w, q), qp)| {
                let mut s = 0.0;
                for ((w, q), qp) in w.iter_mut().zip(q).zip(qp) {
                    *w -= a * q + b_prev * qp;
                    s += *w * *w;
                }
                s
            })
            .collect())
        .sqrt();
        alpha.push(a);
        if look(&alpha, &beta, b) {
            return;
        }
        beta.push(b);
        // q_prev ← q, q ← w / β, and the next operand L⁻ᵀ q.
        std::mem::swap(&mut q_prev, &mut q);
        q.par_chunks_mut(len)
            .zip(w.par_chunks(len))
            .zip(tmp.par_chunks_mut(len))
            .enumerate()
            .for_each(|(c, ((q, w), t))| {
                for (q, w) in q.iter_mut().zip(w) {
                    *q = w / b;
                }
                mass.apply_range(c * len, q, t, true, true);
            });
    }
}

/// The largest eigenvalue of the symmetric tridiagonal matrix with diagonal `a` and
/// off-diagonal `b` (`b.len() ≥ a.len() − 1`), by Sturm-sequence bisection.
fn largest_tridiagonal_eigenvalue(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..n {
        let r = if i > 0 { b[i - 1].abs() } else { 0.0 } + if i + 1 < n { b[i].abs() } else { 0.0 };
        lo = lo.min(a[i] - r);
        hi = hi.max(a[i] + r);
    }
    // The number of eigenvalues below x (signs of the LDLᵀ pivots of T − x I).
    let count_below = |x: f64| {
        let mut d = 1.0;
        let mut count = 0;
        for i in 0..n {
            d = a[i] - x - if i > 0 { b[i - 1] * b[i - 1] / d } else { 0.0 };
            if d == 0.0 {
                d = f64::EPSILON * (x.abs() + 1.0);
            }
            if d < 0.0 {
                count += 1;
            }
        }
        count
    };
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if count_below(mid) >= n {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// `ω_max` of a free system (its `K_ff` through `evaluator`), to full precision: Lanczos, with
/// the bisection on the inertia of `σM − K_ff` for long thin models (see [`omega_max`]).
pub fn omega_max_of_system(sys: &FreeSystem, evaluator: &dyn Evaluator, mass: &Mass) -> f64 {
    top(
        evaluator,
        mass,
        EXACT,
        || Graph::of_system(sys),
        |_| Inertia::of_system(sys),
    )
}

/// Which DOFs are fixed, over all DOFs.
pub(crate) fn fixed_dofs(model: &Model) -> Vec<bool> {
    let mut fixed = vec![false; model.n_dofs()];
    for &d in &model.fixed {
        fixed[d] = true;
    }
    fixed
}

/// `max_e λ_max(K_ee + C_e, M_e)` over the free DOFs: `K_ee` the diagonal block of element `e`
/// (its interfaces' own blocks and its interior stiffness), `C_e` its block of `contact`
/// (row-major `N × N` per element, [`crate::force::contact::stiffness_estimate`]) if given.
/// One pass over the interfaces, then the elements in parallel.
fn largest_block_eigenvalue<K: Kinematics<N>, const N: usize>(
    model: &Model,
    contact: Option<&[f64]>,
) -> f64 {
    let t = model.thickness;
    let mut k_diag: Vec<SMatrix<f64, N, N>> = model
        .elements
        .iter()
        .enumerate()
        .map(|(e, el)| {
            let interior = if K::HAS_INTERIOR {
                K::interior_stiffness(&el.props, &el.d, t)
            } else {
                SMatrix::zeros()
            };
            let c = contact.map_or(SMatrix::zeros(), |c| {
                SMatrix::from_row_slice(&c[e * N * N..(e + 1) * N * N])
            });
            interior + c
        })
        .collect();
    for i in &model.interfaces {
        let centroid = |e: u32| model.elements[e as usize].props.centroid;
        let xb = if i.b == GROUND {
            i.midpoint()
        } else {
            centroid(i.b)
        };
        let [kaa, _, _, kbb] =
            interface_stiffness::<K, N>(i, model.law_of(i), centroid(i.a), xb, t);
        k_diag[i.a as usize] += kaa;
        if i.b != GROUND {
            k_diag[i.b as usize] += kbb;
        }
    }
    let fixed = fixed_dofs(model);
    k_diag
        .par_iter()
        .enumerate()
        .map(|(e, k)| {
            let el = &model.elements[e];
            let m = K::mass(&el.props, el.rho * t);
            generalized_max(
                &DMatrix::from_fn(N, N, |i, j| k[(i, j)]),
                &DMatrix::from_fn(N, N, |i, j| m[(i, j)]),
                &fixed[e * N..(e + 1) * N]
                    .iter()
                    .map(|f| !f)
                    .collect::<Vec<_>>(),
            )
        })
        // A NaN (extreme inputs) must not be passed over by the maximum.
        .map(|x| if x.is_nan() { f64::INFINITY } else { x })
        .reduce(|| 0.0, f64::max)
}

/// `λ_max` of `K x = λ M x` restricted to the DOFs marked free (`M` positive definite there);
/// infinite when `M` cannot be factored.
pub(crate) fn generalized_max(k: &DMatrix<f64>, m: &DMatrix<f64>, free: &[bool]) -> f64 {
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    if idx.is_empty() {
        return 0.0;
    }
    let kf = DMatrix::from_fn(idx.len(), idx.len(), |i, j| k[(idx[i], idx[j])]);
    let mf = DMatrix::from_fn(idx.len(), idx.len(), |i, j| m[(idx[i], idx[j])]);
    // A mass that under- or overflows (extreme inputs) gives an infinite frequency, which the
    // setup refuses naming the extreme value.
    let Some(li) = mf.cholesky().and_then(|c| c.l().try_inverse()) else {
        return f64::INFINITY;
    };
    let a = &li * kf * li.transpose();
    let a = 0.5 * (&a + a.transpose());
    a.symmetric_eigenvalues().max()
}

/// What a setup knows of `ω_max` (rad/s), of `K` plus the contact estimate when the scene has
/// contact: a proven bracket from the elements' diagonal blocks, always (one pass over the
/// interfaces), and the Lanczos value when the time step or the analysis needs it.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Limit {
    /// `√max_e λ_max(K_ee, M_e)`: a proven lower bound of `ω_max` (the Rayleigh quotient of a
    /// motion of one element alone).
    pub floor: f64,
    /// `√2` × the floor: a proven upper bound of `ω_max` (the `per-body` bound of
    /// [`crate::analysis::stability::bounds`]).
    pub bound: f64,
    /// `ω_max` by Lanczos ([`omega_max`]), when it was computed.
    pub omega_max: Option<f64>,
    /// The tolerance it was settled to ([`crate::analysis::limit::EXACT`] or
    /// [`crate::analysis::limit::FOR_STEP`]).
    pub tolerance: Option<f64>,
    /// `√(1 + α)` of the model's local damping `α` (1 without): in the highest mode the local
    /// damping force has the sign of the elastic one and stiffens it by `1 + α`, so every step
    /// limit here is `2 / (ω √(1 + α))` (`step::local`).
    #[serde(skip)]
    pub stiffening: f64,
}

impl Limit {
    /// The proven bracket of `model` with the `contact` estimate's blocks, without Lanczos.
    pub fn bracket(model: &Model, contact: Option<&[f64]>) -> Limit {
        let top = match model.formulation {
            Formulation::Rigid => largest_block_eigenvalue::<Rigid, 3>(model, contact),
            Formulation::RigidPoisson => return Limit::poisson_bracket(model, contact),
            Formulation::Hybrid { .. } => largest_block_eigenvalue::<Hybrid, 6>(model, contact),
        };
        Limit {
            floor: top.sqrt(),
            bound: (2.0 * top).sqrt(),
            omega_max: None,
            tolerance: None,
            stiffening: (1.0 + model.local_damping).sqrt(),
        }
    }

    /// [`Limit::bracket`] of `rigid-poisson`. `K = Σ_f K_f + Σ_I K_I`: the springs' terms couple
    /// two elements, the correction's `t Λ_I g_I g_Iᵀ` the `m` elements of a cell's
    /// neighbourhood, and a positive semi-definite term on `k` elements is at most `k` times
    /// its diagonal blocks. So with `K^s_ee`, `K^P_ee` the diagonal blocks, `ω_max² ≤
    /// max_e λ_max(2 K^s_ee + m K^P_ee, M_e)`; the floor is `max_e λ_max(K^s_ee + K^P_ee, M_e)`
    /// as for the other formulations.
    fn poisson_bracket(model: &Model, contact: Option<&[f64]>) -> Limit {
        let (blocks, m) = crate::force::evaluator::FacetPressures::new(model).diagonal_blocks();
        let with = |weight: f64| {
            let mut b = blocks.iter().map(|x| weight * x).collect::<Vec<f64>>();
            if let Some(c) = contact {
                b.iter_mut().zip(c).for_each(|(x, c)| *x += c);
            }
            largest_block_eigenvalue::<Rigid, 3>(model, Some(&b))
        };
        Limit {
            floor: with(1.0).sqrt(),
            bound: (2.0 * with(0.5 * m as f64)).sqrt(),
            omega_max: None,
            tolerance: None,
            stiffening: (1.0 + model.local_damping).sqrt(),
        }
    }

    /// The stability limit of a run's step for a highest frequency `omega`:
    /// `2 / (ω √(1 + α))` with the local damping `α` ([`Limit::stiffening`]).
    pub fn step_limit(&self, omega: f64) -> f64 {
        critical_time_step(omega) / self.stiffening
    }

    /// `Δt_crit = 2/ω_max` (s; over `√(1 + α)` with local damping), when `ω_max` was computed.
    pub fn dt_crit(&self) -> Option<f64> {
        self.omega_max.map(|w| self.step_limit(w))
    }

    /// `2/bound`: a step proven stable (s), at most `Δt_crit`.
    pub fn dt_safe(&self) -> f64 {
        self.step_limit(self.bound)
    }

    /// `2/floor`: an upper bound of `Δt_crit` (s); above it a run is proven unstable.
    pub fn dt_ceiling(&self) -> f64 {
        self.step_limit(self.floor)
    }

    /// `Δt_crit` when `ω_max` was computed, else the proven-safe step: a lower bound of it.
    pub fn dt_crit_at_least(&self) -> f64 {
        self.dt_crit().unwrap_or_else(|| self.dt_safe())
    }

    /// `dt` against what is known: `Δt_crit` and the ratio, or the proven-safe step.
    pub fn describe(&self, dt: f64) -> String {
        match (self.dt_crit(), self.tolerance) {
            (Some(crit), Some(tol)) if tol > crate::analysis::limit::EXACT => format!(
                "dt = {dt:.6e} s, Δt_crit = {crit:.6e} s (Lanczos to {tol:.0e}), dt/Δt_crit = {:.4}",
                dt / crit
            ),
            (Some(crit), _) => format!(
                "dt = {dt:.6e} s, Δt_crit = {crit:.6e} s, dt/Δt_crit = {:.4}",
                dt / crit
            ),
            (None, _) => format!(
                "dt = {dt:.6e} s = {:.4} × the proven-safe step {:.6e} s (Δt_crit not computed: \
                 --exact-dt-crit computes it)",
                dt / self.dt_safe(),
                self.dt_safe()
            ),
        }
    }

    /// The warning for a run stepped at `dt`, if any.
    pub fn warning(&self, dt: f64) -> Option<String> {
        match self.dt_crit() {
            Some(crit) => above_limit(dt, crit, 4),
            None if dt > self.dt_ceiling() => Some(format!(
                "dt is {:.4} × an upper bound of Δt_crit (2/ω of the stiffest element alone, \
                 {:.6e} s): central difference is unstable; expect the guard to stop the run",
                dt / self.dt_ceiling(),
                self.dt_ceiling()
            )),
            None if dt > self.dt_safe() => Some(format!(
                "dt is {:.4} × the proven-safe step {:.6e} s; Δt_crit lies between that and \
                 {:.6e} s, so the run may be unstable, and near the limit the guard may stop a \
                 stable run: `rbsm check` or `run --exact-dt-crit` computes Δt_crit",
                dt / self.dt_safe(),
                self.dt_safe(),
                self.dt_ceiling()
            )),
            None => None,
        }
    }
}

/// The warning for a step `dt` above the stability limit `crit`, if it is, the ratio with
/// `digits` decimals.
pub fn above_limit(dt: f64, crit: f64, digits: usize) -> Option<String> {
    (dt > crit).then(|| {
        format!(
            "dt is {:.digits$} × Δt_crit: central difference is unstable above 1; expect the \
             guard to stop the run",
            dt / crit
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tridiagonal_top_eigenvalue_of_the_1d_laplacian() {
        // Diagonal 2, off-diagonal −1: eigenvalues 2 − 2 cos(kπ/(n+1)).
        let n = 50;
        let top = largest_tridiagonal_eigenvalue(&vec![2.0; n], &vec![-1.0; n - 1]);
        let exact = 2.0 - 2.0 * (n as f64 * std::f64::consts::PI / (n as f64 + 1.0)).cos();
        assert!((top - exact).abs() < 1e-12, "{top} {exact}");
    }
}

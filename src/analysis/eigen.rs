//! Eigen analysis (`rbsm eigen`, the README's *Commands*): `K φ = ω² M φ` over the free DOFs.
//!
//! - **dense**: all modes from faer's `self_adjoint_eigen` of `M^{−½} K M^{−½}` (small models);
//! - **sparse**: `ω_max` by Lanczos on `M^{−½} K M^{−½}` applied through an evaluator (no
//!   matrix at all; long thin models end with a bisection on the inertia of `σM − K`), and the
//!   lowest modes by faer's matrix-free `partial_self_adjoint_eigen` (Krylov–Schur) on the
//!   shift-inverted `M^{½} (K − σ M)^{−1} M^{½}` with a sparse Cholesky.

use crate::analysis::free::FreeSystem;
use crate::analysis::setup::Setup;
use crate::analysis::Report;
use crate::error::{Error, Result};
use crate::force::evaluator::Evaluator;
use crate::model::mass::Mass;
use crate::model::{Model, GROUND};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::solvers::Solve;
use faer::matrix_free::eigen::{
    partial_self_adjoint_eigen, partial_self_adjoint_eigen_scratch, PartialEigenParams,
};
use faer::matrix_free::LinOp;
use faer::{Col, Mat, MatMut, MatRef, Par};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use std::path::Path;

/// Free DOFs up to which `Method::Auto` solves densely. The dense solver's absolute error,
/// about `n ε ω_max²`, is felt by the lowest modes of stiff models (relative error
/// `n ε (ω_max/ω_1)²`: 7e-7 for the 1920-DOF cantilever), which shift-invert gets to 1e-10.
pub const DENSE_LIMIT: usize = 500;

/// How to solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Dense up to 500 free DOFs (`DENSE_LIMIT`), sparse above.
    Auto,
    /// Dense symmetric eigensolver (nalgebra), all modes.
    Dense,
    /// Lanczos for `ω_max`, Krylov–Schur shift-invert (faer) for the lowest modes.
    Sparse,
}

/// The lowest modes and the top of the spectrum.
#[derive(Debug, Clone)]
pub struct Modes {
    /// Circular frequencies `ω` (rad/s), ascending.
    pub omega: Vec<f64>,
    /// Mode shapes over all DOFs (zero on fixed DOFs), `M`-normalised, one per `omega`.
    pub shapes: Vec<Vec<f64>>,
    /// The largest circular frequency (rad/s).
    pub omega_max: f64,
    /// `dense` or `sparse`.
    pub method: &'static str,
}

/// `n_modes` lowest modes and `ω_max` of a system.
pub fn modes(
    sys: &FreeSystem,
    evaluator: &dyn Evaluator,
    mass: &Mass,
    n_modes: usize,
    method: Method,
) -> Result<Modes> {
    let dense = match method {
        Method::Auto => sys.n() <= DENSE_LIMIT,
        Method::Dense => true,
        Method::Sparse => false,
    };
    if dense {
        dense_modes(sys, mass, n_modes)
    } else {
        let omega_max = top(
            evaluator,
            mass,
            || Graph::of_system(sys),
            |_| Inertia::of_system(sys),
        );
        let (omega, shapes) = lowest_modes(sys, mass, n_modes, omega_max)?;
        Ok(Modes {
            omega,
            shapes,
            omega_max,
            method: "sparse",
        })
    }
}

/// Every mode of `L⁻¹ K_ff L⁻ᵀ` (`M_ff = L Lᵀ`, element by element; `M^{−½} K M^{−½}` for a
/// lumped mass), densely; returns the lowest `n_modes` and `ω_max`. Shapes are `φ = L⁻ᵀ y`,
/// `M`-normalised.
pub fn dense_modes(sys: &FreeSystem, mass: &Mass, n_modes: usize) -> Result<Modes> {
    let n = sys.n();
    let mut k = DMatrix::<f64>::zeros(n, n);
    for j in 0..n {
        for (&i, &v) in sys
            .k
            .symbolic()
            .row_idx_of_col_raw(j)
            .iter()
            .zip(sys.k.val_of_col(j))
        {
            k[(i, j)] = v;
        }
    }
    // B = L⁻¹ K column by column, then A = L⁻¹ Bᵀ = L⁻¹ K L⁻ᵀ (K is symmetric).
    let left = |m: &DMatrix<f64>| {
        let mut out = DMatrix::<f64>::zeros(n, n);
        let mut y = vec![0.0; n];
        for j in 0..n {
            sys.apply_free(m.column(j).as_slice(), &mut y, |x, y| mass.inv_factor(x, y));
            out.column_mut(j).copy_from_slice(&y);
        }
        out
    };
    let a = left(&left(&k).transpose());
    let (lambda, vectors) = symmetric_eigen(0.5 * (&a + a.transpose()));
    let omega_max = lambda.last().copied().unwrap_or(0.0).max(0.0).sqrt();
    let k = n_modes.min(n);
    let omega = lambda[..k].iter().map(|l| l.max(0.0).sqrt()).collect();
    let shapes = (0..k)
        .map(|j| {
            let mut full = vec![0.0; sys.index.len()];
            mass.inv_factor_t(&sys.scatter(vectors.column(j).as_slice()), &mut full);
            full
        })
        .collect();
    Ok(Modes {
        omega,
        shapes,
        omega_max,
        method: "dense",
    })
}

/// Eigenvalues (ascending) and eigenvectors of a dense symmetric matrix, by nalgebra's
/// `SymmetricEigen`. (faer 0.24's `self_adjoint_eigen` returned eigenpairs with residuals of
/// order one on the 1920-DOF cantilever while its values-only routine was right; nalgebra's
/// pairs have residuals near round-off.)
pub fn symmetric_eigen(a: DMatrix<f64>) -> (Vec<f64>, DMatrix<f64>) {
    let eig = nalgebra::SymmetricEigen::new(a);
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let values = order.iter().map(|&i| eig.eigenvalues[i]).collect();
    let vectors = DMatrix::from_fn(eig.eigenvectors.nrows(), order.len(), |r, c| {
        eig.eigenvectors[(r, order[c])]
    });
    (values, vectors)
}

/// The largest circular frequency `ω_max` (rad/s) of `K φ = ω² M φ` over the free DOFs, matrix
/// free: Lanczos on `L⁻¹ K L⁻ᵀ` (`M = L Lᵀ`; `M^{−½} K M^{−½}` for a lumped mass) applied
/// through the evaluator, three vectors of memory.
///
/// Without reorthogonalisation Lanczos still gives the extreme eigenvalue exactly (lost
/// orthogonality only adds copies of converged values). We stop when the largest Ritz value has
/// moved by less than 1e-11 (relative) over the last 20 iterations (looked at every 10); it
/// never exceeds `ω_max²`, so the value converges from below. (faer's Krylov–Schur, which waits
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
pub fn omega_max(model: &Model, evaluator: &dyn Evaluator, mass: &Mass) -> f64 {
    top(
        evaluator,
        mass,
        || Graph::of_model(model, mass.nd()),
        |g| Inertia::probed(model, g, evaluator, mass),
    )
}

/// [`omega_max`], with the graph of `K`'s blocks and the [`Inertia`] built from it when needed.
fn top(
    evaluator: &dyn Evaluator,
    mass: &Mass,
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
            let settled = k > 2 && (top - history[k - 3]).abs() <= 1e-11 * top;
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

/// The `k` eigenvalues of largest magnitude of a symmetric operator, and their vectors.
fn largest(op: &dyn LinOp<f64>, k: usize, tolerance: f64) -> (Vec<f64>, Mat<f64>) {
    let n = op.nrows();
    let k = k.min(n);
    let params = PartialEigenParams {
        min_dim: 2 * k + 8,
        max_dim: 4 * k + 24,
        max_restarts: 2000,
        ..Default::default()
    };
    if params.max_dim >= n {
        // faer's Krylov–Schur needs a subspace smaller than the problem: solve small ones densely.
        let mut a = Mat::<f64>::zeros(n, n);
        op.apply(
            a.as_mut(),
            Mat::<f64>::identity(n, n).as_ref(),
            Par::Seq,
            MemStack::new(&mut MemBuffer::new(StackReq::EMPTY)),
        );
        let (values, vectors) =
            symmetric_eigen(DMatrix::from_fn(n, n, |i, j| 0.5 * (a[(i, j)] + a[(j, i)])));
        let vals = (0..k).map(|j| values[n - 1 - j]).collect();
        let vecs = Mat::<f64>::from_fn(n, k, |i, j| vectors[(i, n - 1 - j)]);
        return (vals, vecs);
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut v0 = Col::<f64>::from_fn(n, |_| rng.random::<f64>() - 0.5);
    let norm = v0.norm_l2();
    v0 /= norm;
    // An operator that overflows would keep the Krylov–Schur restarts going on NaNs.
    let mut probe = Mat::<f64>::zeros(n, 1);
    op.apply(
        probe.as_mut(),
        v0.as_mat(),
        Par::Seq,
        MemStack::new(&mut MemBuffer::new(StackReq::EMPTY)),
    );
    if !(0..n).all(|i| probe[(i, 0)].is_finite()) {
        return (vec![f64::NAN; k], Mat::zeros(n, k));
    }
    let mut mem = MemBuffer::new(partial_self_adjoint_eigen_scratch(op, k, Par::Seq, params));
    let mut vecs = Mat::<f64>::zeros(n, k);
    let mut vals = vec![0.0; k];
    let info = partial_self_adjoint_eigen(
        vecs.as_mut(),
        &mut vals,
        op,
        v0.as_ref(),
        tolerance,
        Par::Seq,
        MemStack::new(&mut mem),
        params,
    );
    // Unconverged pairs are reported as NaN rather than passed off as eigenvalues.
    for v in vals.iter_mut().skip(info.n_converged_eigen) {
        *v = f64::NAN;
    }
    (vals, vecs)
}

/// `Lᵀ (K − σ M)^{−1} L` on the free DOFs (`M = L Lᵀ`): its largest eigenvalues
/// `μ = 1/(ω² − σ)` are the lowest modes.
struct ShiftInvert<'a> {
    llt: faer::sparse::linalg::solvers::Llt<usize, f64>,
    sys: &'a FreeSystem,
    mass: &'a Mass,
}

impl std::fmt::Debug for ShiftInvert<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "shift-invert ({} DOFs)", self.sys.n())
    }
}

impl LinOp<f64> for ShiftInvert<'_> {
    fn apply_scratch(&self, _: usize, _: Par) -> StackReq {
        StackReq::EMPTY
    }
    fn nrows(&self) -> usize {
        self.sys.n()
    }
    fn ncols(&self) -> usize {
        self.sys.n()
    }
    fn apply(&self, out: MatMut<'_, f64>, rhs: MatRef<'_, f64>, _: Par, _: &mut MemStack) {
        let n = self.sys.n();
        let (mut col, mut y) = (vec![0.0; n], vec![0.0; n]);
        let mut x = Mat::<f64>::zeros(n, rhs.ncols());
        // `dst[:, j] = op(src[:, j])` over the free DOFs, column by column.
        let mut columns =
            |src: MatRef<'_, f64>, mut dst: MatMut<'_, f64>, op: &dyn Fn(&[f64], &mut [f64])| {
                for j in 0..src.ncols() {
                    for i in 0..n {
                        col[i] = src[(i, j)];
                    }
                    self.sys.apply_free(&col, &mut y, op);
                    for i in 0..n {
                        dst[(i, j)] = y[i];
                    }
                }
            };
        columns(rhs, x.as_mut(), &|a, b| self.mass.factor(a, b));
        self.llt.solve_in_place(x.as_mut());
        columns(x.as_ref(), out, &|a, b| self.mass.factor_t(a, b));
    }
    fn conj_apply(
        &self,
        out: MatMut<'_, f64>,
        rhs: MatRef<'_, f64>,
        par: Par,
        stack: &mut MemStack,
    ) {
        self.apply(out, rhs, par, stack)
    }
}

/// The `k` lowest modes by shift-invert, `σ = 0` when `K_ff` is positive definite (a supported
/// model). A model with free rigid modes gets `σ = −1e-8 ω_max²`, which makes `K − σ M`
/// positive definite (the rigid modes then come out at `ω ≈ 0`); a shift that large would
/// crowd the lowest modes of a stiff supported model (large penalties), so it is used only
/// there. Shapes are `φ = L⁻ᵀ y`, `M`-normalised.
pub fn lowest_modes(
    sys: &FreeSystem,
    mass: &Mass,
    k: usize,
    omega_max: f64,
) -> Result<(Vec<f64>, Vec<Vec<f64>>)> {
    let (sigma, llt) = match sys.k.sp_cholesky(faer::Side::Lower) {
        Ok(llt) => (0.0, llt),
        Err(_) => {
            let sigma = -1e-8 * omega_max * omega_max;
            let llt = sys
                .shifted(sigma)
                .sp_cholesky(faer::Side::Lower)
                .map_err(|e| {
                    Error::scene(
                        "eigen",
                        format!("the shifted stiffness K − σM could not be factored: {e:?}"),
                    )
                })?;
            (sigma, llt)
        }
    };
    let op = ShiftInvert { llt, sys, mass };
    let (mu, vecs) = largest(&op, k, 1e-12);
    let mut pairs: Vec<(f64, Vec<f64>)> = mu
        .iter()
        .enumerate()
        .map(|(j, &m)| {
            let omega2 = 1.0 / m + sigma;
            let y: Vec<f64> = (0..sys.n()).map(|i| vecs[(i, j)]).collect();
            let mut shape = vec![0.0; sys.index.len()];
            mass.inv_factor_t(&sys.scatter(&y), &mut shape);
            (omega2.max(0.0).sqrt(), shape)
        })
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(pairs.into_iter().unzip())
}

/// `rbsm eigen --json`.
#[derive(Serialize)]
pub struct EigenReport {
    /// Free DOFs.
    pub dofs: usize,
    /// Frequencies of the lowest modes (Hz).
    pub frequencies_hz: Vec<f64>,
    /// Their circular frequencies `ω` (rad/s).
    pub omega: Vec<f64>,
    /// Largest circular frequency (rad/s).
    pub omega_max: f64,
    /// `2/ω_max` (s).
    pub dt_crit: f64,
    /// `dense` or `sparse`.
    pub method: &'static str,
    /// The mode shapes, for the files of [`write()`].
    #[serde(skip)]
    pub modes: Modes,
}

/// `eigen` parameters: how many of the lowest modes, and by which method.
#[derive(Debug, Clone, Copy)]
pub struct EigenParams {
    /// Number of lowest modes.
    pub modes: usize,
    /// Dense, sparse, or dense up to [`DENSE_LIMIT`] free DOFs.
    pub method: Method,
}

/// The lowest modes of a setup's `K φ = ω² M φ` (without contact), with `ω_max` and
/// `Δt_crit` of the setup (contact included when the scene has contact: the run's limit).
pub fn analyse(setup: &Setup, params: &EigenParams) -> Result<EigenReport> {
    let sys = FreeSystem::new(&setup.model, &setup.mass);
    let modes = modes(
        &sys,
        setup.evaluator.as_ref(),
        &setup.mass,
        params.modes,
        params.method,
    )?;
    Ok(EigenReport {
        dofs: sys.n(),
        frequencies_hz: modes
            .omega
            .iter()
            .map(|w| w / (2.0 * std::f64::consts::PI))
            .collect(),
        omega: modes.omega.clone(),
        omega_max: setup.omega_max,
        dt_crit: setup.dt_crit,
        method: modes.method,
        modes,
    })
}

impl Report for EigenReport {
    fn text(&self) -> String {
        let mut t = format!(
            "{} free DOFs ({} solver); ω_max = {:.6e} rad/s, Δt_crit = {:.6e} s\n",
            self.dofs, self.method, self.omega_max, self.dt_crit
        );
        for (i, f) in self.frequencies_hz.iter().enumerate() {
            t.push_str(&format!("  mode {:>3}: {:.6e} Hz\n", i + 1, f));
        }
        t.trim_end().to_string()
    }
}

/// Writes what `rbsm eigen --out DIR` gives: `summary.json` (the report), the shapes as
/// `mode_NNN.vtu` with `modes.pvd`, and `probes.csv` (per mode its number, frequency and each
/// probe of the `M`-normalised shape).
pub fn write(dir: &Path, setup: &Setup, report: &EigenReport) -> Result<()> {
    let modes = &report.modes;
    crate::output::vtk::write_mode_shapes(dir, &setup.model, &modes.shapes)?;
    crate::output::write_json(&dir.join("summary.json"), report)?;
    let rows: Vec<(Vec<String>, &[f64])> = modes
        .shapes
        .iter()
        .zip(&report.frequencies_hz)
        .enumerate()
        .map(|(k, (shape, f))| {
            (
                vec![(k + 1).to_string(), format!("{f:e}")],
                shape.as_slice(),
            )
        })
        .collect();
    crate::output::write_probe_rows(dir, &setup.probes()?, &["mode", "frequency_hz"], &rows)
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

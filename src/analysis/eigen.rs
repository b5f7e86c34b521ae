//! Eigen analysis (`rbsm eigen`, the README's *Commands*): `K φ = ω² M φ` over the free DOFs.
//!
//! - **dense**: all modes from faer's `self_adjoint_eigen` of `M^{−½} K M^{−½}` (small models);
//! - **sparse**: `ω_max` by Lanczos on `M^{−½} K M^{−½}` applied through an evaluator (no
//!   matrix at all; long thin models end with a bisection on the inertia of `σM − K`), and the
//!   lowest modes by faer's matrix-free `partial_self_adjoint_eigen` (Krylov–Schur) on the
//!   shift-inverted `M^{½} (K − σ M)^{−1} M^{½}` with a sparse Cholesky.

use crate::analysis::free::FreeSystem;
use crate::analysis::limit;
use crate::analysis::setup::Setup;
use crate::analysis::Report;
use crate::error::{Error, Result};
use crate::force::evaluator::Evaluator;
use crate::model::mass::Mass;
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

crate::input::names::named! {
    /// How to solve (`rbsm eigen --method`).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Method {
        /// Dense up to 500 free DOFs (`DENSE_LIMIT`), sparse above.
        "auto" => Auto,
        /// Dense symmetric eigensolver (nalgebra), all modes.
        "dense" => Dense,
        /// Lanczos for `ω_max`, Krylov–Schur shift-invert (faer) for the lowest modes.
        "sparse" => Sparse,
    }
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
///
/// # Errors
/// By the sparse method only (`Method::Sparse`, or `Method::Auto` above [`DENSE_LIMIT`] free DOFs),
/// when the shifted stiffness cannot be factored ([`lowest_modes`]).
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
        let omega_max = limit::omega_max_of_system(sys, evaluator, mass);
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
///
/// # Errors
/// Never: the `Result` is that of [`modes`], whose sparse method can fail.
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
///
/// # Errors
/// Neither `K_ff` nor the shifted `K − σ M` can be factored by sparse Cholesky (an error at the
/// scene key `eigen`).
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
    /// The run's stability limit (s): `2/ω_max`, over `√(1 + α)` with local damping `α`.
    pub dt_crit: f64,
    /// `√(1 + α)`, 1 without local damping: `2/ω_max` is `dt_crit` times it.
    pub local_damping_factor: f64,
    /// Whether `ω_max` and `Δt_crit` include the contact springs' estimate (a scene with
    /// contact: the run's limit); the modes never do.
    pub with_contact: bool,
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
///
/// # Errors
/// As [`modes`]: the sparse method cannot factor the shifted stiffness.
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
        omega_max: setup.omega_max(),
        dt_crit: setup.dt_crit(),
        local_damping_factor: setup.limit.stiffening,
        with_contact: setup.contact.is_some(),
        method: modes.method,
        modes,
    })
}

impl Report for EigenReport {
    fn text(&self) -> String {
        let mut t = format!(
            "{} ({} solver); ω_max = {:.6e} rad/s, Δt_crit = {:.6e} s\n",
            crate::output::count(self.dofs, "free DOF", "free DOFs"),
            self.method,
            self.omega_max,
            self.dt_crit
        );
        if self.local_damping_factor != 1.0 {
            t.push_str(&format!(
                "  (Δt_crit of a run with the scene's local damping α: 2/ω_max = {:.6e} s over \
                 √(1 + α) = {:.4})\n",
                self.dt_crit * self.local_damping_factor,
                self.local_damping_factor
            ));
        }
        if self.with_contact {
            t.push_str(
                "  (ω_max and Δt_crit with the contact springs' estimate; the modes below are \
                 the bonded springs' alone)\n",
            );
        }
        for (i, f) in self.frequencies_hz.iter().enumerate() {
            t.push_str(&format!("  mode {:>3}: {:.6e} Hz\n", i + 1, f));
        }
        t.trim_end().to_string()
    }
}

/// Where `rbsm eigen` writes its files; each folder only when given.
#[derive(Debug, Clone, Copy, Default)]
pub struct Files<'a> {
    /// `--out`: the files of [`write()`].
    pub out: Option<&'a Path>,
    /// `--vtk`: the shapes as VTK.
    pub vtk: Option<&'a Path>,
    /// `--svg`: the shapes drawn over the reference mesh.
    pub svg: Option<&'a Path>,
}

impl Files<'_> {
    /// Writes the files asked for.
    ///
    /// # Errors
    /// A folder asked for cannot be created or a file written in it, or, with `out`, a probe of the
    /// scene names an element outside the model, a point `at` in no element or a DOF the
    /// formulation does not have (as [`write()`]).
    pub fn write(&self, setup: &Setup, report: &EigenReport) -> Result<()> {
        let modes = &report.modes;
        if let Some(dir) = self.out {
            write(dir, setup, report)?;
        }
        if let Some(dir) = self.vtk {
            crate::output::vtk::write_mode_shapes(dir, &setup.model, &modes.shapes)?;
        }
        if let Some(dir) = self.svg {
            crate::output::drawing::write_mode_shapes(
                dir,
                &setup.model,
                &modes.omega,
                &modes.shapes,
            )?;
        }
        Ok(())
    }
}

/// Writes what `rbsm eigen --out DIR` gives: `summary.json` (the report), the shapes as
/// `mode_NNN.vtu` with `modes.pvd`, and `probes.csv` (per mode its number, frequency and each
/// probe of the `M`-normalised shape).
///
/// # Errors
/// `dir` cannot be created or a file written in it, or a probe of the scene names an element
/// outside the model, a point `at` in no element or a DOF the formulation does not have.
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
    crate::output::write_probe_rows(
        dir,
        &setup.probes()?,
        &["mode", "frequency_hz"],
        &rows,
        Some("M-normalised"),
    )
}

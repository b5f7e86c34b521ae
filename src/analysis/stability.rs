//! The stability limit of central difference ([`crate::step::integrator`]; `rbsm stability`):
//! `Δt_crit = 2 / ω_max`, the cheap
//! bounds that codes use instead of `ω_max`, each with its ratio to the exact value, and the
//! limit found empirically by running.

use crate::analysis::free::FreeSystem;
use crate::analysis::limit::{fixed_dofs, generalized_max, Limit};
use crate::analysis::setup::Setup;
use crate::analysis::Report;
use crate::error::{Error, Result};
use crate::force::contact::Contact;
use crate::force::evaluator::interface_stiffness;
use crate::model::formulation::{Formulation, Hybrid, Kinematics, Rigid};
use crate::model::loads::Loads;
use crate::model::mass::Mass;
use crate::model::{Model, GROUND};
use crate::step::integrator::{CentralDifference, RunStatus};
use nalgebra::{DMatrix, SMatrix};
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// A cheap estimate of `Δt_crit` and how it compares with the exact value.
#[derive(Debug, Clone, Serialize)]
pub struct Bound {
    /// `gershgorin`, `irons-treharne`, `per-body` or `single-body`.
    pub name: &'static str,
    /// The estimate (s).
    pub dt: f64,
    /// `dt / Δt_crit`.
    pub ratio: f64,
    /// Whether stepping at `dt` is stable (`ratio ≤ 1`). Proven bounds are safe by theory; the
    /// naive estimate is not.
    pub safe: bool,
}

/// The cheap estimates of `Δt_crit`, each as `2/ω` with `ω²` from (`gershgorin` and
/// `single-body` only for a lumped mass, whose diagonal they read):
/// - `gershgorin`: the largest absolute row sum of `M^{−½} K M^{−½}` (a proven upper bound on
///   `ω_max²`, so a safe `Δt`);
/// - `irons-treharne`: the largest `λ_max(K_s, M_s)` over interfaces `s`, each element's mass
///   shared equally among its interfaces (`K = Σ K_s`, `M = Σ M_s`: a proven bound; for
///   `rigid-poisson` of its springs alone, not a bound: its correction is not in it);
/// - `per-body`: `2 max_e λ_max(K_ee, M_e)`, `K_ee` the diagonal block of element `e` (proven:
///   `K ≤ 2 blockdiag(K)` because each interface's form stays positive when `U_b → −U_b`;
///   `rigid-poisson` weighs its correction's blocks by the elements they couple,
///   [`Limit::bracket`]);
/// - `single-body`: the naive DEM estimate `2 √(m/k)`, the smallest over elements and DOFs of
///   `M_ii / K_ii` (not a bound: unsafe on a lattice, where neighbours move against each other).
pub fn bounds(model: &Model, sys: &FreeSystem, mass: &Mass, dt_crit: f64) -> Vec<Bound> {
    let mk = |name, omega2: f64, proven: bool| {
        let dt = 2.0 / omega2.sqrt();
        let ratio = dt / dt_crit;
        Bound {
            name,
            dt,
            ratio,
            safe: if proven { true } else { ratio <= 1.0 },
        }
    };
    let n = sys.n();
    // Gershgorin on the scaled matrix, and the diagonal ratio of the naive estimate.
    let mut rows = vec![0.0; n];
    let mut diag_ratio = 0.0f64;
    for j in 0..n {
        for (&i, &v) in sys
            .k
            .symbolic()
            .row_idx_of_col_raw(j)
            .iter()
            .zip(sys.k.val_of_col(j))
        {
            rows[i] += v.abs() / (sys.mass[i] * sys.mass[j]).sqrt();
            if i == j {
                diag_ratio = diag_ratio.max(v / sys.mass[i]);
            }
        }
    }
    let gershgorin = rows.iter().cloned().fold(0.0, f64::max);
    let it = match model.formulation {
        Formulation::Rigid | Formulation::RigidPoisson => interface_bound::<Rigid, 3>(model),
        Formulation::Hybrid { .. } => interface_bound::<Hybrid, 6>(model),
    };
    let per_body = Limit::bracket(model, None).bound.powi(2);
    let springs_alone = model.formulation == Formulation::RigidPoisson;
    if mass.is_diagonal() {
        vec![
            mk("gershgorin", gershgorin, true),
            mk("irons-treharne", it, !springs_alone),
            mk("per-body", per_body, true),
            mk("single-body", diag_ratio, false),
        ]
    } else {
        vec![
            mk("irons-treharne", it, !springs_alone),
            mk("per-body", per_body, true),
        ]
    }
}

/// `max_s λ_max(K_s, M_s)` over the free DOFs (Irons–Treharne).
fn interface_bound<K: Kinematics<N>, const N: usize>(model: &Model) -> f64 {
    let ne = model.elements.len();
    let fixed = fixed_dofs(model);
    let mass: Vec<SMatrix<f64, N, N>> = model
        .elements
        .iter()
        .map(|e| K::mass(&e.props, e.rho * model.thickness))
        .collect();
    // Each element's mass is shared equally among its interfaces and, for hybrid, its interior
    // term, so that the shares add up to M (Irons–Treharne).
    let mut count = vec![usize::from(K::HAS_INTERIOR); ne];
    for i in &model.interfaces {
        count[i.a as usize] += 1;
        if i.b != GROUND {
            count[i.b as usize] += 1;
        }
    }
    let mut it = 0.0f64;
    for i in &model.interfaces {
        let xa = model.elements[i.a as usize].props.centroid;
        let xb = if i.b == GROUND {
            i.midpoint()
        } else {
            model.elements[i.b as usize].props.centroid
        };
        let [kaa, kab, kba, kbb] =
            interface_stiffness::<K, N>(i, model.law_of(i), xa, xb, model.thickness);
        let mut elements = vec![i.a as usize];
        if i.b != GROUND {
            elements.push(i.b as usize);
        }
        let m = elements.len() * N;
        let (mut ks, mut ms) = (DMatrix::<f64>::zeros(m, m), DMatrix::<f64>::zeros(m, m));
        for (p, &e) in elements.iter().enumerate() {
            ms.view_mut((p * N, p * N), (N, N))
                .copy_from(&(mass[e] / count[e] as f64));
        }
        ks.view_mut((0, 0), (N, N)).copy_from(&kaa);
        if i.b != GROUND {
            ks.view_mut((0, N), (N, N)).copy_from(&kab);
            ks.view_mut((N, 0), (N, N)).copy_from(&kba);
            ks.view_mut((N, N), (N, N)).copy_from(&kbb);
        }
        let dofs: Vec<usize> = elements
            .iter()
            .flat_map(|&e| (0..N).map(move |d| e * N + d))
            .collect();
        it = it.max(generalized_max(
            &ks,
            &ms,
            &dofs.iter().map(|&d| !fixed[d]).collect::<Vec<_>>(),
        ));
    }
    if K::HAS_INTERIOR {
        for (e, el) in model.elements.iter().enumerate() {
            let kint = K::interior_stiffness(&el.props, &el.d, model.thickness);
            let (k, m) = (
                DMatrix::from_fn(N, N, |i, j| kint[(i, j)]),
                DMatrix::from_fn(N, N, |i, j| mass[e][(i, j)] / count[e] as f64),
            );
            let free: Vec<bool> = (0..N).map(|d| !fixed[e * N + d]).collect();
            it = it.max(generalized_max(&k, &m, &free));
        }
    }
    it
}

/// The outcome of an undamped run at `fraction · Δt_crit`.
#[derive(Debug, Clone, Serialize)]
pub struct FractionRun {
    /// `dt / Δt_crit`.
    pub fraction: f64,
    /// Time step (s).
    pub dt: f64,
    /// Steps taken (fewer than asked when it diverged).
    pub steps: u64,
    /// `ok` or `diverged`.
    pub status: RunStatus,
    /// Why a diverged run was stopped (what the guard saw: energy growth or a NaN), with the
    /// step; `null` for `ok`.
    pub reason: Option<String>,
    /// Largest `|total − initial|` over the energy put in; `null` for a diverged run,
    /// whose total stays conserved to round-off while its stored energy grows (see `history`),
    /// so that the drift says nothing of it.
    pub max_relative_drift: Option<f64>,
    /// `(t, total, kinetic + elastic)` energies (J) at the recorded steps: 200 or so per run
    /// below `Δt_crit`, every step above.
    /// The total stays conserved to round-off even in an unstable run (central difference
    /// conserves a modified energy); the stored `kinetic + elastic` is what grows.
    #[serde(skip)]
    pub history: Vec<(f64, f64, f64)>,
}

/// Runs the setup's model undamped and unloaded for `steps` steps at `fraction · Δt_crit`
/// from a seeded random displacement (which excites every mode, the highest included).
pub fn run_at_fraction(setup: &Setup, fraction: f64, steps: u64) -> FractionRun {
    let (model, dt_crit) = (&setup.model, undamped_dt_crit(setup));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let u0: Vec<f64> = (0..model.n_dofs())
        .map(|_| 1e-6 * (rng.random::<f64>() - 0.5))
        .collect();
    let loads = Loads::none(model);
    let dt = fraction * dt_crit;
    let mut cd = CentralDifference::from_state(
        model,
        setup.evaluator.as_ref(),
        &setup.mass,
        &loads,
        setup.contact.as_ref().map(Contact::copy),
        dt,
        u0,
        vec![0.0; model.n_dofs()],
    )
    .undamped();
    cd.set_stability_limit(dt_crit);
    // Above the limit every step, so that the few steps before the guard stops it show.
    let every = if fraction > 1.0 {
        1
    } else {
        (steps / 200).max(1)
    };
    let mut history = Vec::new();
    // `run` fails only when its observer does, and this one cannot.
    let Ok(status) = cd.run(
        steps,
        every,
        |_, e| {
            history.push((e.t, e.total, e.kinetic + e.elastic));
            Ok(())
        },
        |_| {},
    ) else {
        unreachable!("the observer cannot fail")
    };
    // No interrupt flag is set: a run ends or diverges.
    let reason = status.detail();
    FractionRun {
        fraction,
        dt,
        steps: cd.step,
        status: status.kind(),
        max_relative_drift: reason.is_none().then(|| cd.max_relative_drift()),
        reason,
        history,
    }
}

/// How far from `Δt_crit` the empirical limit is looked for: between `Δt_crit / BRACKET` and
/// `BRACKET Δt_crit`.
pub const BRACKET: f64 = 64.0;

/// The empirical limit: bisection on `fraction` between a stable and an unstable run of
/// `steps` steps each, to a relative width of `tol`. Returns `(dt, dt / Δt_crit)`.
///
/// # Errors
/// No run diverges up to [`BRACKET`] `Δt_crit` (nothing in the scene is excited within
/// `steps` steps: a body in free flight, a contact not reached), or one diverges down to
/// `Δt_crit /` [`BRACKET`]; the error is keyed `--steps`.
pub fn empirical_limit(setup: &Setup, steps: u64, tol: f64) -> Result<(f64, f64)> {
    let stable = |f: f64| run_at_fraction(setup, f, steps).status == RunStatus::Ok;
    let (mut lo, mut hi) = (0.5, 2.0);
    while !stable(lo) {
        lo *= 0.5;
        if lo < 1.0 / BRACKET {
            return Err(Error::scene(
                "--steps",
                format!(
                    "runs of {steps} steps diverge even at Δt_crit / {BRACKET}: the scene's \
                     energy grows for a reason other than the time step (check it with `rbsm run`)"
                ),
            ));
        }
    }
    while stable(hi) {
        hi *= 2.0;
        if hi > BRACKET {
            return Err(Error::scene(
                "--steps",
                format!(
                    "no run of {steps} steps diverges even at {BRACKET} Δt_crit: nothing in the \
                     scene is excited within the runs (a body in free flight, a contact not yet \
                     reached), so they cannot show the limit; give more steps, or a scene whose \
                     elements are coupled from the start"
                ),
            ));
        }
    }
    while hi - lo > tol * lo {
        let mid = 0.5 * (lo + hi);
        if stable(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok((lo * undamped_dt_crit(setup), lo))
}

/// Writes `fraction_F.csv` (`t,total,stored`: s, J, J) for each run of a stability analysis.
///
/// # Errors
/// `dir` cannot be created, or a `fraction_F.csv` cannot be written in it.
pub fn write_fraction_histories(
    dir: &std::path::Path,
    runs: &[FractionRun],
) -> crate::error::Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| crate::error::Error::io(dir, e))?;
    for r in runs {
        let path = dir.join(format!("fraction_{}.csv", r.fraction));
        let mut text = String::from("t,total,stored\n");
        for (t, e, stored) in &r.history {
            text.push_str(&format!("{t:e},{e:e},{stored:e}\n"));
        }
        crate::output::write_atomic(&path, text.as_bytes())?;
    }
    Ok(())
}

#[derive(Serialize)]
/// The empirical stability limit found by bisection.
pub struct Empirical {
    /// Largest stable time step found (s).
    pub dt: f64,
    /// Its ratio to `Δt_crit`.
    pub ratio: f64,
}

/// `rbsm stability --json`.
#[derive(Serialize)]
pub struct StabilityReport {
    /// Largest circular frequency (rad/s).
    pub omega_max: f64,
    /// `2/ω_max` (s).
    pub dt_crit: f64,
    /// The cheap estimates and how they compare.
    pub bounds: Vec<Bound>,
    /// The limit found by running.
    pub empirical: Empirical,
    /// The runs at the asked fractions of `Δt_crit`.
    pub fractions: Vec<FractionRun>,
}

/// `stability` parameters: the fractions of `Δt_crit` to run at, and the steps of each run.
#[derive(Debug, Clone)]
pub struct StabilityParams {
    /// Fractions of `Δt_crit`, each > 0.
    pub fractions: Vec<f64>,
    /// Steps of each run (bisection and fractions).
    pub steps: u64,
}

/// The setup's `Δt_crit` (the one every command uses), the cheap bounds, the empirical limit
/// (bisection to `1e-4`) and undamped runs at the given fractions of `Δt_crit`.
///
/// # Errors
/// A fraction of `params.fractions` is not a finite number > 0 (`--fractions`),
/// `params.steps` is 0 (`--steps`), or the runs find no limit ([`empirical_limit`]).
pub fn analyse(setup: &Setup, params: &StabilityParams) -> Result<StabilityReport> {
    if params.steps == 0 {
        return Err(Error::scene(
            "--steps",
            "must be ≥ 1: each run of the bisection and of the fractions takes that many steps",
        ));
    }
    if let Some(f) = params
        .fractions
        .iter()
        .find(|f| !(**f > 0.0 && f.is_finite()))
    {
        return Err(Error::scene(
            "--fractions",
            format!("each fraction must be a finite number > 0, got {f}"),
        ));
    }
    let sys = FreeSystem::new(&setup.model, &setup.mass);
    let bounds = bounds(&setup.model, &sys, &setup.mass, undamped_dt_crit(setup));
    let (dt, ratio) = empirical_limit(setup, params.steps, 1e-4)?;
    let fractions = params
        .fractions
        .iter()
        .map(|&f| run_at_fraction(setup, f, params.steps))
        .collect();
    Ok(StabilityReport {
        omega_max: setup.omega_max(),
        dt_crit: undamped_dt_crit(setup),
        bounds,
        empirical: Empirical { dt, ratio },
        fractions,
    })
}

impl Report for StabilityReport {
    fn text(&self) -> String {
        let mut t = format!(
            "ω_max = {:.6e} rad/s, Δt_crit = {:.6e} s (undamped: the runs below leave the \
             scene's damping out)\n",
            self.omega_max, self.dt_crit
        );
        for b in &self.bounds {
            t.push_str(&format!(
                "  {:<15} Δt = {:.6e} s  ratio {:.4}  {}\n",
                b.name,
                b.dt,
                b.ratio,
                if b.safe { "safe" } else { "UNSAFE" }
            ));
        }
        if !self.bounds.iter().any(|b| b.name == "gershgorin") {
            t.push_str("  (gershgorin and single-body need a lumped mass; this one has blocks)\n");
        }
        t.push_str(&format!(
            "  empirical       Δt = {:.6e} s  ratio {:.4}\n",
            self.empirical.dt, self.empirical.ratio
        ));
        for f in &self.fractions {
            let outcome = match (&f.reason, f.max_relative_drift) {
                (Some(reason), _) => format!("diverged {reason}"),
                (None, drift) => format!(
                    "ok, {}, energy drift {:.3e}",
                    crate::output::count(f.steps as usize, "step", "steps"),
                    drift.unwrap_or_default()
                ),
            };
            t.push_str(&format!("  run at {:.3} Δt_crit: {outcome}\n", f.fraction));
        }
        t.trim_end().to_string()
    }
}

/// `Δt_crit = 2/ω_max` of the undamped scheme the analysis measures: without the local
/// damping's `√(1 + α)` (`Limit::stiffening`), which its runs leave out.
fn undamped_dt_crit(setup: &Setup) -> f64 {
    crate::analysis::limit::critical_time_step(setup.omega_max())
}

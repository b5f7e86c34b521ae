//! Static analysis (`rbsm static`, the README's *Commands*): `K_ff U_f = P_f − K_fp U_p` by sparse Cholesky (faer), with
//! `U_p = 0` (supports fix DOFs at zero). A mechanism is refused with its free modes named.

use crate::error::{Error, Result};
use crate::force::evaluator;
use crate::mesh::geometry::Vec2;
use crate::model::loads::Loads;
use crate::model::mass::Mass;
use crate::model::{Model, GROUND};
use crate::analysis::rigid_modes::free_modes;
use crate::input::scene::EvaluatorKind;
use crate::analysis::free::FreeSystem;
use faer::linalg::solvers::Solve;

/// The static solution: `U` over all DOFs and the strain energy `½ Uᵀ K U` (J).
pub struct StaticSolution {
    /// Displacements over all DOFs (zero on fixed ones).
    pub u: Vec<f64>,
    /// Strain energy `½ Uᵀ K U` (J).
    pub energy: f64,
}

/// Solves `K U = P` for the model's loads at their full value (gravity included).
pub fn solve(model: &Model) -> Result<StaticSolution> {
    let ev = evaluator::build(model, EvaluatorKind::Assembled);
    let modes = free_modes(model, ev.as_ref());
    if !modes.is_empty() {
        let list: Vec<String> = modes.iter().map(|m| m.to_string()).collect();
        return Err(Error::scene(
            "bodies[].supports",
            format!(
            "the model is a mechanism ({} free rigid mode{}): {}; add supports that restrain them",
            modes.len(), if modes.len() == 1 { "" } else { "s" }, list.join("; ")),
        ));
    }
    let mass = Mass::new(model);
    let sys = FreeSystem::new(model, &mass);
    let p = Loads::new(model).static_vector(model.n_dofs());
    let llt = sys.k.sp_cholesky(faer::Side::Lower).map_err(|e| {
        Error::scene(
            "bodies[].supports",
            format!("K_ff is not positive definite ({e:?}) although no free rigid mode was found"),
        )
    })?;
    let mut rhs = faer::Mat::<f64>::from_fn(sys.n(), 1, |i, _| p[sys.free[i]]);
    llt.solve_in_place(rhs.as_mut());
    let u = sys.scatter(&(0..sys.n()).map(|i| rhs[(i, 0)]).collect::<Vec<_>>());
    let mut f = vec![0.0; u.len()];
    ev.internal_force(&u, &mut f);
    let energy = 0.5 * crate::step::integrator::dot(&u, &f);
    Ok(StaticSolution { u, energy })
}

/// The traction `[t_n, t_s]` (Pa) at the midpoint of an interface by the model's law (eq. 11;
/// `λ = diag(k_n, k_s) δ` for [`crate::model::law::Elastic`]), with `δ = u_b − u_a` on the
/// interface's `(n, s)` axes.
pub fn midpoint_traction(model: &Model, i: &crate::model::Interface, u: &[f64]) -> [f64; 2] {
    let nd = model.formulation.ndof();
    let m = i.midpoint();
    let disp = |e: u32| -> Vec2 {
        if e == GROUND {
            return Vec2::zeros();
        }
        let e = e as usize;
        model.formulation.displacement(
            &u[e * nd..(e + 1) * nd],
            m - model.elements[e].props.centroid,
        )
    };
    let delta = disp(i.b) - disp(i.a);
    model.law.traction(
        [i.k_n, i.k_s],
        [i.normal.dot(&delta), i.tangent.dot(&delta)],
    )
}

//! Limit analysis (`rbsm limit`, the README's *Commands*): the collapse load of the discrete
//! model a scene builds, by conic programming (a linear program where no element has a strength).
//! RBSM began as discrete limit analysis (Kawai):
//! a structure of rigid elements collapses when enough of its interfaces reach their strength.
//!
//! **The static problem**, on the explicit law's own Gauss points. Unknowns: the traction
//! `λ = (σ, τ)` (Pa) on the interface's `(n, s)` axes at each of the two Gauss points of every
//! interface, supports included, and the load factor `α`. Equilibrium on every free DOF:
//! `G λ = α P_live + P_dead`, where `G λ` is the internal force of those tractions (eq. 15 with
//! `λ` in place of `diag(k) δ`: `f_a −= t w N_aᵀ λ`, `f_b += t w N_bᵀ λ`). Strength at the Gauss
//! points of the interfaces that fail ([`Strength`], unsoftened: the peak surface):
//! `σ ≤ cap`, `τ + σ tan φ ≤ c`, `−τ + σ tan φ ≤ c`; the other interfaces and the supports carry
//! any traction. Maximise `α`. With moving clamps the clamps' DOFs leave the equilibrium rows
//! and the objective is the clamps' reaction along their velocity instead,
//! `R = Σ_d (G λ − P_dead)_d v̂_d`.
//!
//! **Its dual** is the kinematic problem: the multipliers of the equilibrium rows are the
//! element velocities of the collapse mechanism (at the scale where the live loads do unit
//! power; reported so that the largest speed of an element's vertex is 1),
//! those of the strength rows the plastic rates, normal to the surface (associated flow). At the
//! optimum the two give one value: the collapse load of the discrete model, which the explicit
//! run with the same strength, perfectly plastic, reaches where its flow is associated as well
//! (`φ = 0` and the cut-off); with `φ > 0` the explicit law does not dilate and may carry more.
//!
//! **Formulations.** The equilibrium rows are the rigid DOFs `(u, v, θ)` of the elements. A
//! hybrid element without a strength balances any traction on its strain DOFs with its free
//! stress, so hybrid elements with elastic interiors collapse as rigid ones of the same shapes.
//! One with a strength (Tresca or Mohr–Coulomb, [`crate::model::plasticity`]) takes its stress
//! from its own equilibrium on its strain DOFs, `G_s λ + t A σ = P_s` (the interior term of
//! eq. 15), written into its strength's cones directly rather than kept as three
//! unknowns and three rows: the interior-point method factors a KKT system of the unknowns and
//! constraints at every iteration, and on a 10,240-element hybrid footing of crossed triangles
//! that system shrinks from 274,904 to 213,920 rows and its factor from 9.3e8 to 3.2e8
//! multiply-adds (in the minimum-degree order the solver gives it), the solve from 46 s to
//! 16 s; on gmsh's 9,224 triangles of the same footing the solve takes as long as before
//! (33 s both). The strain rates of
//! the mechanism are then the cones' multipliers mapped back, `Cᵀ z_c/(t A)`.
//!
//! The solver is Clarabel (an interior-point conic solver in Rust, `LDLᵀ` by QDLDL); the
//! problem is sparse, with four unknowns per interface.

use crate::analysis::setup::Setup;
use crate::analysis::Report;
use crate::error::{Error, Result};
use crate::mesh::geometry::Vec2;
use crate::model::formulation::{Hybrid, Kinematics, Rigid};
use crate::model::law::Strength;
use crate::model::loads::Loads;
use crate::model::{Model, GROUND};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use serde::Serialize;
use std::time::Instant;

/// The solver's iterations at most (Clarabel's default is 200; a 400-cell Voronoi footing takes
/// more).
const MAX_ITERATIONS: u32 = 2000;

/// What grows until the model collapses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Multiplier {
    /// The scene's loads (gravity held at its value): the factor `α` on them.
    Loads,
    /// Gravity (the loads held at their value): the factor on it.
    Gravity,
    /// The reaction of the scene's moving clamp along its velocity (N): displacement control.
    Clamps,
}

impl Multiplier {
    /// What the scene offers, in this order: its moving clamp, its loads, its gravity.
    pub fn of(model: &Model) -> Option<Multiplier> {
        if !model.prescribed.is_empty() {
            Some(Multiplier::Clamps)
        } else if !model.loads.is_empty() {
            Some(Multiplier::Loads)
        } else if model.gravity != Vec2::zeros() {
            Some(Multiplier::Gravity)
        } else {
            None
        }
    }
}

/// The collapse load and its mechanism.
#[derive(Debug, Clone, Serialize)]
pub struct CollapseReport {
    /// The scene's name.
    pub scene: String,
    /// What grows.
    pub multiplier: Multiplier,
    /// The load factor at collapse, or the clamp's reaction (N) for [`Multiplier::Clamps`].
    pub collapse: f64,
    /// The interfaces whose strength bounds the problem.
    pub failing_interfaces: usize,
    /// The unknowns and the constraints of the linear program.
    pub unknowns: usize,
    /// Equilibrium rows, interface strength rows and the rows of the elements' cones.
    pub constraints: usize,
    /// The solver's iterations.
    pub iterations: u32,
    /// Wall time of the solve (s), set-up included.
    pub seconds: f64,
    /// The element velocities of the mechanism `[u̇, v̇, θ̇]` per element, scaled so that the
    /// largest speed of an element's vertex is 1 (rotations and strain rates included).
    #[serde(skip)]
    pub velocities: Vec<[f64; 3]>,
    /// The plastic strain rates `[ε̇_x, ε̇_y, γ̇_xy]` of the mechanism per element, on the same
    /// scale (zero for an element without a strength); empty for a rigid model.
    #[serde(skip)]
    pub strain_rates: Vec<[f64; 3]>,
    /// The statically admissible stresses `[σ_x, σ_y, τ_xy]` (Pa) of the elements that have a
    /// strength, zero for the others; empty when none has.
    #[serde(skip)]
    pub stresses: Vec<[f64; 3]>,
    /// The elements whose strength bounds the problem (hybrid).
    pub yielding_elements: usize,
    /// The statically admissible tractions `[σ, τ]` (Pa) at the two Gauss points of each
    /// interface, in the order of `Model::interfaces`.
    #[serde(skip)]
    pub tractions: Vec<[[f64; 2]; 2]>,
}

impl Report for CollapseReport {
    fn text(&self) -> String {
        let what = match self.multiplier {
            Multiplier::Loads => format!("load factor at collapse: {:.6}", self.collapse),
            Multiplier::Gravity => format!("gravity factor at collapse: {:.6}", self.collapse),
            Multiplier::Clamps => format!("clamp reaction at collapse: {:.6e} N", self.collapse),
        };
        format!(
            "{}: {what}\n  {} failing interfaces, {} yielding elements; {} unknowns, {} constraints; {} iterations in {:.3} s",
            self.scene,
            self.failing_interfaces,
            self.yielding_elements,
            self.unknowns,
            self.constraints,
            self.iterations,
            self.seconds
        )
    }
}

/// The generalised forces `(DOF, value)` of a unit traction along `dir` at `x` on interface
/// `(a, b)` with weight `t w`: `−t w N_aᵀ dir` on `a`'s DOFs and `t w N_bᵀ dir` on `b`'s (none
/// on ground), the strain DOFs of hybrid elements included: one column of `G`.
fn point_forces(
    model: &Model,
    (a, b): (u32, u32),
    x: Vec2,
    dir: Vec2,
    tw: f64,
) -> impl Iterator<Item = (usize, f64)> + '_ {
    let nd = model.formulation.ndof();
    [(a, -tw), (b, tw)]
        .into_iter()
        .filter(|&(e, _)| e != GROUND)
        .flat_map(move |(e, sign)| {
            let mut f = [0.0; 6];
            let d = x - model.elements[e as usize].props.centroid;
            if nd == 6 {
                Hybrid::add_force(&mut f, d, dir);
            } else {
                let mut r = [0.0; 3];
                Rigid::add_force(&mut r, d, dir);
                f[..3].copy_from_slice(&r);
            }
            (0..nd).map(move |k| (e as usize * nd + k, sign * f[k]))
        })
}

/// Where the interface strengths are checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Points {
    /// At the explicit law's two Gauss points: the model the explicit run steps.
    #[default]
    Gauss,
    /// At the interface's end points (as finite-element limit analysis does: the linear
    /// traction of the two Gauss points is extreme there), a stronger condition.
    Ends,
}

impl std::str::FromStr for Points {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "gauss" => Ok(Points::Gauss),
            "ends" => Ok(Points::Ends),
            _ => Err(format!(
                "`{s}`: the strengths are checked at `gauss` or `ends`"
            )),
        }
    }
}

/// The weights of the two Gauss point tractions in the linear traction at the edge's ends
/// `p1` and `p2` (the Gauss points lie at `∓ L/(2√3)` from the midpoint, `p1` side first):
/// `λ(p1) = (1 + √3)/2 λ₀ + (1 − √3)/2 λ₁`, and the mirror at `p2`.
fn end_weights(points: Points) -> [[f64; 2]; 2] {
    match points {
        Points::Gauss => [[1.0, 0.0], [0.0, 1.0]],
        Points::Ends => {
            let (near, far) = (0.5 * (1.0 + 3f64.sqrt()), 0.5 * (1.0 - 3f64.sqrt()));
            [[near, far], [far, near]]
        }
    }
}

/// The collapse load of the setup's model under `multiplier` (the scene's own when `None`:
/// [`Multiplier::of`]).
///
/// # Errors
/// A scene with contact (the program models bonded interfaces alone); one with nothing to grow,
/// or with more than one moving clamp; a failing interface whose law is not the crate's
/// [`Strength`]; a model that cannot carry its dead load (infeasible) or that does not collapse
/// (unbounded: no mechanism is bounded by the strengths); a solver that stops short.
pub fn analyse(
    setup: &Setup,
    multiplier: Option<Multiplier>,
    points: Points,
) -> Result<CollapseReport> {
    let started = Instant::now();
    let model = &setup.model;
    if model.contact.is_some() || !model.ground.is_empty() {
        return Err(Error::scene(
            "contact",
            "rbsm limit models the bonded interfaces alone: remove `contact` and the ground \
             segments from the scene",
        ));
    }
    let Some(multiplier) = multiplier.or_else(|| Multiplier::of(model)) else {
        return Err(Error::scene(
            "bodies[*].loads",
            "nothing to grow: the scene has no loads, no gravity and no moving clamp",
        ));
    };
    if multiplier == Multiplier::Clamps && model.prescribed.len() != 1 {
        return Err(Error::scene(
            "bodies[*].supports",
            format!(
                "rbsm limit on the clamps takes one moving clamp (a clamp with `velocity`); the \
                 scene has {}",
                model.prescribed.len()
            ),
        ));
    }
    let nd = model.formulation.ndof();
    let n = model.n_dofs();
    // The equilibrium rows: the rigid DOFs that are not fixed (a moving clamp's DOFs are fixed).
    let mut row_of = vec![usize::MAX; n];
    let mut fixed = vec![false; n];
    for &d in &model.fixed {
        fixed[d] = true;
    }
    let mut rows = 0;
    for e in 0..model.elements.len() {
        for k in 0..3 {
            if !fixed[e * nd + k] {
                row_of[e * nd + k] = rows;
                rows += 1;
            }
        }
    }
    // The elements with a strength, and where each of their stresses comes from ([`Stress`]).
    let yielding: Vec<usize> = (0..model.elements.len())
        .filter(|&e| model.elements[e].strength.is_some())
        .collect();
    if !yielding.is_empty() && nd != 6 {
        return Err(Error::scene(
            "materials.*.element",
            "an element strength needs the hybrid formulation (its stress lives in the strain \
             DOFs): rigid elements cannot yield inside",
        ));
    }
    let mut stress_of = vec![[Stress::Free(usize::MAX); 3]; yielding.len()];
    let mut strain_row = vec![usize::MAX; n];
    let mut strain_rows: Vec<Vec<(usize, f64)>> = Vec::new();
    let n_lambda = 4 * model.interfaces.len();
    let mut free_stresses = 0;
    for (j, &e) in yielding.iter().enumerate() {
        for k in 0..3 {
            let d = e * nd + 3 + k;
            stress_of[j][k] = if fixed[d] {
                free_stresses += 1;
                Stress::Free(n_lambda + free_stresses - 1)
            } else {
                strain_row[d] = strain_rows.len();
                strain_rows.push(Vec::new());
                Stress::Balanced(strain_row[d])
            };
        }
    }
    // The loads, gravity apart from the others.
    let all = Loads::new(model);
    let (gravity, loads, total) = (
        all.gravity_vector(n),
        all.applied_vector(n),
        all.static_vector(n),
    );
    let (live, dead) = match multiplier {
        Multiplier::Loads => (&loads, &gravity),
        Multiplier::Gravity => (&gravity, &loads),
        Multiplier::Clamps => (&vec![0.0; n], &total),
    };
    if multiplier != Multiplier::Clamps && live.iter().all(|&p| p == 0.0) {
        let (what, key) = match multiplier {
            Multiplier::Gravity => ("gravity", "gravity"),
            _ => ("loads", "bodies[*].loads"),
        };
        return Err(Error::scene(
            key,
            format!("rbsm limit on the {what}: the scene has none"),
        ));
    }
    // The clamp's DOFs and the unit vector of its velocity, for its reaction.
    let clamp: Vec<(usize, f64)> = match multiplier {
        Multiplier::Clamps => {
            let p = &model.prescribed[0];
            let unit = p.velocity / p.velocity.norm();
            p.dofs.iter().map(|&(d, c)| (d, unit[c])).collect()
        }
        _ => Vec::new(),
    };
    let mut clamp_row = vec![0.0; n];
    for &(d, v) in &clamp {
        clamp_row[d] = v;
    }

    // Columns: `[σ, τ]` at each Gauss point of each interface, then the free stresses, then `α`.
    let unknowns = n_lambda + free_stresses + usize::from(multiplier != Multiplier::Clamps);
    let mut q = vec![0.0; unknowns];
    let mut columns: Vec<Vec<(usize, f64)>> = Vec::with_capacity(unknowns);
    // `Σ a x ≤ b`: the interfaces' strengths at their Gauss points or ends.
    let mut strength_rows: Vec<(Vec<(usize, f64)>, f64)> = Vec::new();
    let weights = end_weights(points);
    let mut failing = 0;
    for (k, i) in model.interfaces.iter().enumerate() {
        let (points, w) = i.gauss_points();
        let tw = model.thickness * w;
        let law = model.law_of(i);
        let strength: Option<&Strength> = if i.b != GROUND && model.fails(i) {
            Some(law.as_strength().ok_or_else(|| {
                let body = model.elements[i.a as usize].body as usize;
                Error::scene(
                    format!("bodies[{body}].material"),
                    format!(
                        "the interfaces of body `{}` follow a law that rbsm limit cannot write \
                         into its program (the `facet` law, or a law given in code): it knows \
                         `mohr-coulomb` and `softening` (at its unsoftened strength)",
                        model.bodies[body].name
                    ),
                )
            })?)
        } else {
            None
        };
        failing += usize::from(strength.is_some());
        for (g, &x) in points.iter().enumerate() {
            for (c, dir) in [i.normal, i.tangent].into_iter().enumerate() {
                let col = 4 * k + 2 * g + c;
                let mut column = Vec::new();
                for (d, f) in point_forces(model, (i.a, i.b), x, dir, tw) {
                    if f == 0.0 {
                        continue;
                    }
                    if row_of[d] != usize::MAX {
                        column.push((row_of[d], f));
                    } else if strain_row[d] != usize::MAX {
                        strain_rows[strain_row[d]].push((col, f));
                    }
                    // The clamp's reaction `Σ_d (G λ)_d v̂_d`, maximised.
                    q[col] -= f * clamp_row[d];
                }
                columns.push(column);
            }
        }
        if let Some(s) = strength {
            let (cap, c, tan_phi) = (s.cap(), s.c, s.tan_phi);
            for w in weights {
                // `(a_σ, a_τ)` of a row on the traction `Σ_g w_g λ_g` at the point checked.
                let row = |a_sigma: f64, a_tau: f64| -> Vec<(usize, f64)> {
                    (0..2)
                        .flat_map(|g| {
                            [
                                (4 * k + 2 * g, w[g] * a_sigma),
                                (4 * k + 2 * g + 1, w[g] * a_tau),
                            ]
                        })
                        .filter(|&(_, v)| v != 0.0)
                        .collect()
                };
                strength_rows.push((row(1.0, 0.0), cap));
                strength_rows.push((row(tan_phi, 1.0), c));
                strength_rows.push((row(tan_phi, -1.0), c));
            }
        }
    }
    // Nothing bounds a mechanism: the program is unbounded, which the solver does not tell when
    // it has no inequality (it returns a solution of the equalities alone).
    if failing == 0 && yielding.is_empty() {
        return Err(Error::scene(
            "materials.*.interface",
            "the model does not collapse: none of its interfaces can fail and no element has a \
             strength; give the interfaces a strength (`mohr-coulomb` or `softening`) or the \
             elements one (`materials.*.element`, hybrid)",
        ));
    }
    columns.resize(n_lambda + free_stresses, Vec::new());
    let alpha = columns.len();
    if multiplier != Multiplier::Clamps {
        let mut column = Vec::new();
        for d in (0..n).filter(|&d| live[d] != 0.0) {
            if row_of[d] != usize::MAX {
                column.push((row_of[d], -live[d]));
            } else if strain_row[d] != usize::MAX {
                strain_rows[strain_row[d]].push((alpha, -live[d]));
            }
        }
        columns.push(column);
        q[alpha] = -1.0;
    }
    for (r, (entries, _)) in strength_rows.iter().enumerate() {
        for &(col, v) in entries {
            columns[col].push((rows + r, v));
        }
    }
    let first_cone = rows + strength_rows.len();
    let mut b = vec![0.0; first_cone];
    for d in 0..n {
        if row_of[d] != usize::MAX {
            b[row_of[d]] = dead[d];
        }
    }
    for (r, (_, bound)) in strength_rows.iter().enumerate() {
        b[rows + r] = *bound;
    }
    // The elements' strengths, second-order cones `‖(x₁, x₂)‖ ≤ t` of `r − C σ`
    // (`model::plasticity`): `t = r − a p`, `x = ((σ_x − σ_y)/2, τ)` for each side `a p + R ≤ r`,
    // with `σ` from the element's equilibrium where it is balanced ([`Stress`]).
    let mut element_cones = Vec::new();
    for (j, &e) in yielding.iter().enumerate() {
        let volume = model.thickness * model.elements[e].props.area;
        let Some(strength) = model.elements[e].strength else {
            continue;
        };
        let (sides, count) = strength.sides();
        for side in &sides[..count - 1] {
            let (a, r) = (side[0], side[2]);
            let at = b.len();
            b.extend([r, 0.0, 0.0]);
            let c = cone_coefficients(a);
            for (i, row) in c.iter().enumerate() {
                for (k, &ck) in row.iter().enumerate().filter(|&(_, &ck)| ck != 0.0) {
                    match stress_of[j][k] {
                        Stress::Free(col) => columns[col].push((at + i, ck)),
                        Stress::Balanced(s) => {
                            // `σ_k = (P_k − (G_s λ)_k)/(t A)`.
                            let d = e * nd + 3 + k;
                            b[at + i] -= ck * dead[d] / volume;
                            for &(col, f) in &strain_rows[s] {
                                columns[col].push((at + i, -ck * f / volume));
                            }
                        }
                    }
                }
            }
            element_cones.push((j, c, at));
        }
    }
    let constraints = b.len();
    // The stresses in units of the largest cohesion `s₀` (`λ = s₀ λ'`; the loads divided by
    // `s₀` alike, `α` as it is): the interior-point steps then see numbers near 1 (in pascals,
    // the cones of a 40 × 20 footing stopped short). A tensile strength may be far larger (a
    // cut-off set out of the way), so the cohesions set the unit; the caps when all are zero.
    let largest = |rows: &mut dyn Iterator<Item = f64>| rows.fold(0.0f64, |m, x| m.max(x.abs()));
    let s0 = [
        largest(&mut strength_rows.iter().skip(1).step_by(3).map(|r| r.1)),
        largest(
            &mut yielding
                .iter()
                .filter_map(|&e| model.elements[e].strength)
                .map(|s| s.cohesion),
        ),
        largest(&mut b[rows..].iter().copied()),
        1.0,
    ]
    .into_iter()
    .find(|&s| s > 0.0)
    .unwrap_or(1.0);
    b.iter_mut().for_each(|x| *x /= s0);
    if let Some(column) = columns.get_mut(alpha) {
        column.iter_mut().for_each(|(_, v)| *v /= s0);
    }
    let mut cones = vec![
        SupportedConeT::ZeroConeT(rows),
        SupportedConeT::NonnegativeConeT(strength_rows.len()),
    ];
    cones.extend(
        element_cones
            .iter()
            .map(|_| SupportedConeT::SecondOrderConeT(3)),
    );
    let a = csc(constraints, columns);
    let p = CscMatrix::<f64>::zeros((unknowns, unknowns));
    // Without Clarabel's equilibration: the unknowns are already in units of the strength, and
    // with it the interior-point steps of hybrid models with cones on unstructured triangles
    // stalled at a relative gap of 1e-4 (`NumericalError`).
    let settings = DefaultSettingsBuilder::default()
        .verbose(std::env::var_os("RBSM_LP_VERBOSE").is_some())
        .max_iter(MAX_ITERATIONS)
        .equilibrate_enable(false)
        .build()
        .map_err(|e| Error::scene("bodies", format!("the solver's settings: {e}")))?;
    let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings)
        .map_err(|e| Error::scene("bodies", format!("the linear program is malformed: {e}")))?;
    solver.solve();
    let solution = &solver.solution;
    match solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {}
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
            return Err(Error::scene(
                "bodies[*].loads",
                "the model cannot carry its dead load with the strengths of its interfaces \
                 (the program is infeasible): it collapses under the loads held at their value",
            ))
        }
        SolverStatus::DualInfeasible | SolverStatus::AlmostDualInfeasible => {
            return Err(Error::scene(
                "materials.*.interface",
                "the model does not collapse: no mechanism is bounded by the strengths (the \
                 program is unbounded); give the interfaces a strength, or check the supports",
            ))
        }
        status => {
            return Err(Error::scene(
                "bodies",
                format!("the solver stopped short: {status:?}"),
            ))
        }
    }
    let (x, z) = (&solution.x, &solution.z);
    let collapse = match multiplier {
        Multiplier::Clamps => {
            let dead_power: f64 = clamp.iter().map(|&(d, v)| total[d] * v).sum();
            -s0 * solution.obj_val - dead_power
        }
        _ => x[alpha],
    };
    // The mechanism: `v = −z` on the equilibrium rows, the clamp's velocity on its DOFs.
    let mut velocities = vec![[0.0; 3]; model.elements.len()];
    for (e, v) in velocities.iter_mut().enumerate() {
        for k in 0..3 {
            let d = e * nd + k;
            v[k] = if row_of[d] != usize::MAX {
                -z[row_of[d]]
            } else {
                clamp_row[d]
            };
        }
    }
    // The strain rates: the multipliers of the balanced strain DOFs' equilibrium, which the
    // substitution removed, `−z_s = Cᵀ z_c / (t A)` (the stationarity of the program in `σ`).
    let mut strain_rates = vec![[0.0; 3]; if nd == 6 { model.elements.len() } else { 0 }];
    for &(j, c, at) in &element_cones {
        let e = yielding[j];
        let volume = model.thickness * model.elements[e].props.area;
        for k in 0..3 {
            if let Stress::Balanced(_) = stress_of[j][k] {
                strain_rates[e][k] += (0..3).map(|i| c[i][k] * z[at + i]).sum::<f64>() / volume;
            }
        }
    }
    let largest = crate::output::largest_vertex_displacement(
        model,
        &mechanism(model, &velocities, &strain_rates),
    );
    if largest > 0.0 {
        for v in velocities.iter_mut().chain(&mut strain_rates) {
            v.iter_mut().for_each(|x| *x /= largest);
        }
    }
    let mut stresses = vec![
        [0.0; 3];
        if yielding.is_empty() {
            0
        } else {
            model.elements.len()
        }
    ];
    // The unknowns in their units: tractions and stresses in Pa, `α` as it is.
    let value = |col: usize| if col == alpha { x[col] } else { s0 * x[col] };
    for (j, &e) in yielding.iter().enumerate() {
        for k in 0..3 {
            stresses[e][k] = match stress_of[j][k] {
                Stress::Free(col) => value(col),
                Stress::Balanced(s) => {
                    let d = e * nd + 3 + k;
                    let volume = model.thickness * model.elements[e].props.area;
                    let internal: f64 = strain_rows[s].iter().map(|&(c, f)| f * value(c)).sum();
                    (dead[d] - internal) / volume
                }
            };
        }
    }
    let tractions = (0..model.interfaces.len())
        .map(|k| [0, 1].map(|g| [value(4 * k + 2 * g), value(4 * k + 2 * g + 1)]))
        .collect();
    Ok(CollapseReport {
        scene: model.name.clone(),
        multiplier,
        collapse,
        failing_interfaces: failing,
        unknowns,
        constraints,
        iterations: solution.iterations,
        seconds: started.elapsed().as_secs_f64(),
        velocities,
        strain_rates,
        stresses,
        yielding_elements: yielding.len(),
        tractions,
    })
}

/// Where a yielding element's stress component comes from in the program.
#[derive(Debug, Clone, Copy)]
enum Stress {
    /// An unknown of its own (its column): the component's strain DOF is fixed, so no
    /// equilibrium binds it.
    Free(usize),
    /// The element's equilibrium on its strain DOF (`G_s λ + t A σ = P_s`, the interior term of
    /// eq. 15), row `s` of `G_s`: `σ = (P_s − G_s λ)/(t A)` is written into the cones directly.
    /// A 10,240-element hybrid footing's program then has 213,692 rows and columns in its KKT
    /// system instead of 274,904, and its factor half the work.
    Balanced(usize),
}

/// The coefficients `C` of `(σ_x, σ_y, τ_xy)` in a side's cone `r − C σ`, `(t, x₁, x₂)` with
/// `t = r − a (σ_x + σ_y)/2`, `x₁ = (σ_x − σ_y)/2`, `x₂ = τ_xy` (signs as `b − A x`).
fn cone_coefficients(a: f64) -> [[f64; 3]; 3] {
    [[0.5 * a, 0.5 * a, 0.0], [-0.5, 0.5, 0.0], [0.0, 0.0, -1.0]]
}

/// A sparse matrix of `m` rows from its columns (entries in any order).
fn csc(m: usize, mut columns: Vec<Vec<(usize, f64)>>) -> CscMatrix<f64> {
    let mut colptr = Vec::with_capacity(columns.len() + 1);
    let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
    colptr.push(0);
    for column in &mut columns {
        column.sort_unstable_by_key(|&(r, _)| r);
        let mut last = usize::MAX;
        let start = rowval.len();
        for &(r, v) in column.iter() {
            if r == last {
                *nzval.last_mut().expect("an entry") += v;
            } else {
                rowval.push(r);
                nzval.push(v);
                last = r;
            }
        }
        // Entries that cancelled (a cone's `x₁` row reads `(f_x − f_y)/2`) are left out.
        let mut kept = start;
        for k in start..rowval.len() {
            if nzval[k] != 0.0 {
                (rowval[kept], nzval[kept]) = (rowval[k], nzval[k]);
                kept += 1;
            }
        }
        rowval.truncate(kept);
        nzval.truncate(kept);
        colptr.push(rowval.len());
    }
    CscMatrix::new(m, columns.len(), colptr, rowval, nzval)
}

/// The mechanism's DOFs over the model: each element's `velocities` and, hybrid, its
/// `strain_rates`.
fn mechanism(model: &Model, velocities: &[[f64; 3]], strain_rates: &[[f64; 3]]) -> Vec<f64> {
    let nd = model.formulation.ndof();
    let mut shape = vec![0.0; model.n_dofs()];
    for (e, v) in velocities.iter().enumerate() {
        shape[e * nd..e * nd + 3].copy_from_slice(v);
    }
    for (e, r) in strain_rates.iter().enumerate() {
        shape[e * nd + 3..e * nd + 6].copy_from_slice(r);
    }
    shape
}

/// Writes what `rbsm limit --out DIR` gives: `summary.json` (the report), the collapse
/// mechanism as `mechanism.vtu` (its velocities as the frame's velocity, its displacement
/// scaled for viewing: the largest vertex displacement a tenth of the model's size) and
/// `mechanism.svg` (the mesh moved along the mechanism over the reference), and
/// `tractions.csv` (per interface and Gauss point, `σ` and `τ` in Pa: a statically admissible
/// field at collapse; and the mechanism's opening and slip rates there, on the scale of its
/// velocities).
///
/// # Errors
/// The folder cannot be created or a file written in it.
pub fn write(dir: &std::path::Path, setup: &Setup, report: &CollapseReport) -> Result<()> {
    use crate::output::write_atomic;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let model = &setup.model;
    crate::output::write_json(&dir.join("summary.json"), report)?;
    let nd = model.formulation.ndof();
    let shape = mechanism(model, &report.velocities, &report.strain_rates);
    crate::output::vtk::write_shape(&dir.join("mechanism.vtu"), model, &shape, &shape)?;
    let caption = format!("{}: collapse mechanism", model.name);
    let svg = crate::output::drawing::displaced_svg(model, &shape, &caption);
    write_atomic(&dir.join("mechanism.svg"), svg.as_bytes())?;
    let mut csv = String::from(
        "interface,a,b,point,x (m),y (m),sigma (Pa),tau (Pa),opening rate,slip rate\n",
    );
    // The mechanism's velocity of element `e` at `x` (zero on ground).
    let velocity = |e: u32, x: Vec2| {
        if e == GROUND {
            return Vec2::zeros();
        }
        let e = e as usize;
        let d = x - model.elements[e].props.centroid;
        model
            .formulation
            .displacement(&shape[e * nd..(e + 1) * nd], d)
    };
    for (k, (i, t)) in model.interfaces.iter().zip(&report.tractions).enumerate() {
        let (points, _) = i.gauss_points();
        let b = if i.b == GROUND {
            "ground".to_string()
        } else {
            i.b.to_string()
        };
        for g in 0..2 {
            let jump = velocity(i.b, points[g]) - velocity(i.a, points[g]);
            csv.push_str(&format!(
                "{k},{},{b},{g},{},{},{},{},{},{}\n",
                i.a,
                points[g].x,
                points[g].y,
                t[g][0],
                t[g][1],
                i.normal.dot(&jump),
                i.tangent.dot(&jump)
            ));
        }
    }
    write_atomic(&dir.join("tractions.csv"), csv.as_bytes())
}

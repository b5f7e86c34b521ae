//! Static analysis (`rbsm static`, the README's *Commands*): `K_ff U_f = P_f − K_fp U_p` by sparse
//! Cholesky (faer), with
//! `U_p = 0` (supports fix DOFs at zero). A mechanism is refused with its free modes named.

use crate::analysis::free::FreeSystem;
use crate::analysis::rigid_modes::free_modes;
use crate::analysis::setup::Setup;
use crate::analysis::Report;
use crate::error::{Error, Result};
use crate::force::evaluator;
use crate::input::scene::EvaluatorKind;
use crate::mesh::geometry::Vec2;
use crate::model::formulation::Formulation;
use crate::model::loads::Loads;
use crate::model::mass::Mass;
use crate::model::{Model, GROUND};
use crate::output::count;
use faer::linalg::solvers::Solve;
use serde::Serialize;
use std::path::Path;

/// The static solution: `U` over all DOFs and the strain energy `½ Uᵀ K U` (J).
pub struct StaticSolution {
    /// Displacements over all DOFs (zero on fixed ones).
    pub u: Vec<f64>,
    /// Strain energy `½ Uᵀ K U` (J).
    pub energy: f64,
    /// The cells' `q_e = λ' tr ε_e / 2μ` of a `rigid-poisson` model, loads included
    /// ([`crate::model::poisson`]); empty for the other formulations.
    pub cells: Vec<f64>,
}

impl StaticSolution {
    /// The traction `[t_n, t_s]` (Pa) at an interface's midpoint: its springs'
    /// ([`midpoint_traction`]) and, for `rigid-poisson`, the correction's of its cells
    /// ([`crate::model::poisson::correction`]).
    pub fn traction(&self, model: &Model, i: &crate::model::Interface) -> [f64; 2] {
        let [t_n, t_s] = midpoint_traction(model, i, &self.u);
        if self.cells.is_empty() {
            return [t_n, t_s];
        }
        let q = |e: u32| {
            if e == GROUND {
                0.0
            } else {
                self.cells[e as usize]
            }
        };
        let c = crate::model::poisson::correction(model, i, q(i.a), q(i.b), i.midpoint());
        [t_n + c.dot(&i.normal), t_s + c.dot(&i.tangent)]
    }
}

/// Solves `K U = P` for the model's loads at their full value (gravity included).
///
/// # Errors
/// The model is a mechanism: it has free rigid modes, named in the error (under
/// `bodies[k].supports` of the first one's body); or `K_ff` is not positive definite although
/// no free rigid mode was found.
pub fn solve(model: &Model) -> Result<StaticSolution> {
    let ev = evaluator::build(model, EvaluatorKind::Assembled);
    let modes = free_modes(model, ev.as_ref());
    if let Some(first) = modes.first() {
        let list: Vec<String> = modes.iter().map(|m| m.to_string()).collect();
        return Err(Error::scene(
            format!("bodies[{}].supports", first.body),
            format!(
                "the model is a mechanism ({}): {}; add supports that restrain them",
                crate::output::count(modes.len(), "free rigid mode", "free rigid modes"),
                list.join("; ")
            ),
        ));
    }
    let mass = Mass::new(model);
    let sys = FreeSystem::new(model, &mass);
    let p = Loads::new(model).static_vector(model.n_dofs());
    let llt = sys.k.sp_cholesky(faer::Side::Lower).map_err(|e| {
        Error::scene(
            "bodies[*].supports",
            format!("K_ff is not positive definite ({e:?}) although no free rigid mode was found"),
        )
    })?;
    let mut rhs = faer::Mat::<f64>::from_fn(sys.n(), 1, |i, _| p[sys.free[i]]);
    llt.solve_in_place(rhs.as_mut());
    let u = sys.scatter(&(0..sys.n()).map(|i| rhs[(i, 0)]).collect::<Vec<_>>());
    let mut f = vec![0.0; u.len()];
    ev.internal_force(&u, &mut f);
    let energy = 0.5 * crate::step::integrator::dot(&u, &f);
    let cells = if model.formulation == Formulation::RigidPoisson {
        evaluator::cells(model, &u)
    } else {
        Vec::new()
    };
    Ok(StaticSolution { u, energy, cells })
}

/// The traction `[t_n, t_s]` (Pa) at the midpoint of an interface by the springs of its law
/// (eq. 11; `λ = diag(k_n', k_s') δ`, `(k_n, k_s)` for [`crate::model::law::Elastic`]), with
/// `δ = u_b − u_a` on the interface's `(n, s)` axes: the analysis is linear.
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
    let [k_n, k_s] = model.law_of(i).springs([i.k_n, i.k_s]);
    [k_n * i.normal.dot(&delta), k_s * i.tangent.dot(&delta)]
}

#[derive(Serialize)]
/// One element of `rbsm static --json`.
pub struct StaticElement {
    /// Reference centroid (m).
    pub centroid: [f64; 2],
    #[serde(rename = "U")]
    /// Its DOFs `U_e` (m, rad, strains).
    pub u: Vec<f64>,
    /// `(σ_x, σ_y, τ_xy) = D ε` (Pa), hybrid only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stress: Option<[f64; 3]>,
}

#[derive(Serialize)]
/// One interface of `rbsm static --json`.
pub struct StaticInterface {
    /// The first element.
    pub a: u32,
    /// The other element, or `null` for a ground spring.
    pub b: Option<u32>,
    /// Midpoint of the edge (m).
    pub midpoint: [f64; 2],
    /// Unit normal from `a` to `b`.
    pub normal: [f64; 2],
    /// `[t_n, t_s]` (Pa) at the midpoint.
    pub traction: [f64; 2],
}

/// `rbsm static --json`.
#[derive(Serialize)]
pub struct StaticReport {
    /// Every element.
    pub elements: Vec<StaticElement>,
    /// Every interface, ground springs included.
    pub interfaces: Vec<StaticInterface>,
    /// Strain energy `½ Uᵀ K U` (J).
    pub energy: f64,
    /// What the linear analysis leaves out of the scene: the interfaces' strengths, the
    /// clamps' motion.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// `U` over all DOFs (m, rad, strains), for the files of [`write()`].
    #[serde(skip)]
    pub u: Vec<f64>,
}

/// The static analysis of a setup: `U`, per element and interface, and the strain energy.
///
/// # Errors
/// As [`solve`]: the model is a mechanism, or `K_ff` is not positive definite.
pub fn analyse(setup: &Setup) -> Result<StaticReport> {
    let model = &setup.model;
    let sol = solve(model)?;
    let nd = model.formulation.ndof();
    let elements = model
        .elements
        .iter()
        .enumerate()
        .map(|(e, el)| {
            let u = &sol.u[e * nd..(e + 1) * nd];
            StaticElement {
                centroid: [el.props.centroid.x, el.props.centroid.y],
                u: u.to_vec(),
                stress: crate::output::element_stress(model, e, u, [0.0; 3]),
            }
        })
        .collect();
    let interfaces = model
        .interfaces
        .iter()
        .map(|i| StaticInterface {
            a: i.a,
            b: (i.b != GROUND).then_some(i.b),
            midpoint: [i.midpoint().x, i.midpoint().y],
            normal: [i.normal.x, i.normal.y],
            traction: sol.traction(model, i),
        })
        .collect();
    let mut notes = Vec::new();
    if model.any_fails() {
        notes.push(
            "the analysis is linear: the interfaces' strengths are ignored (`rbsm run` with a \
             moving clamp gives the collapse)"
                .to_string(),
        );
    }
    if !model.prescribed.is_empty() {
        notes.push("moving clamps are held at their initial place".to_string());
    }
    Ok(StaticReport {
        elements,
        interfaces,
        energy: sol.energy,
        notes,
        u: sol.u,
    })
}

impl Report for StaticReport {
    fn text(&self) -> String {
        let max = self
            .elements
            .iter()
            .map(|e| e.u[0].hypot(e.u[1]))
            .fold(0.0, f64::max);
        let springs = self.interfaces.iter().filter(|i| i.b.is_none()).count();
        let mut text = format!(
            "{}, {} between elements and {}; strain energy {:.6e} J; largest displacement \
             {:.6e} m",
            count(self.elements.len(), "element", "elements"),
            count(self.interfaces.len() - springs, "interface", "interfaces"),
            count(springs, "ground spring", "ground springs"),
            self.energy,
            max
        );
        for n in &self.notes {
            text.push_str(&format!("\nnote: {n}"));
        }
        text
    }
}

/// Writes what `rbsm static --out DIR` gives: `summary.json` (the report), `final_state.json`
/// (`U`, zero `V`), `probes.csv` (`probe,value,unit` for the scene's probes) and the frame
/// `static.vtu` with its collection `series.pvd`.
///
/// # Errors
/// `dir` cannot be created or a file written in it, or a probe of the scene names an element
/// outside the model, a point `at` in no element or a DOF the formulation does not have.
pub fn write(dir: &Path, setup: &Setup, report: &StaticReport) -> Result<()> {
    let (model, u) = (&setup.model, report.u.as_slice());
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    crate::output::write_json(&dir.join("summary.json"), report)?;
    let v = vec![0.0; u.len()];
    crate::output::write_final_state(dir, model, 0.0, u, &v, None, &[])?;
    crate::output::write_probe_rows(
        dir,
        &setup.probes()?,
        &["case"],
        &[(vec!["static".to_string()], u)],
        None,
    )?;
    crate::output::vtk::write_frame(
        &dir.join("static.vtu"),
        model,
        (u, &v),
        &[],
        crate::output::vtk::Placement::Linear,
    )?;
    crate::output::vtk::write_collection(&dir.join("series.pvd"), &[(0.0, "static.vtu".into())])
}

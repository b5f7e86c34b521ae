//! Formulations: which displacement field an element carries (eq. 5, DESIGN.md §2).
//!
//! A formulation is a [`Kinematics`] with `N` DOFs per element: the shape matrix `N_e(x)`
//! evaluated at an offset `d = x − x_e` from the element's centroid, and its transpose acting on
//! a point force. The evaluators are generic over it, so a new formulation touches neither the
//! integrator nor the evaluators' callers.

use crate::geometry::{AreaProperties, Vec2};
use crate::scene::FormulationSpec;
use nalgebra::SMatrix;

/// The displacement field of one element, `u(x) = N_e(x) U_e`, with `N` DOFs.
pub trait Kinematics<const N: usize>: Send + Sync + 'static {
    /// `N_e(x) U_e` at offset `d` from the centroid (eq. 5).
    fn displacement(u: &[f64; N], d: Vec2) -> Vec2;
    /// `f += N_e(x)ᵀ F`: the generalised force of a point force `F` at offset `d`.
    fn add_force(f: &mut [f64; N], d: Vec2, force: Vec2);
    /// The 2 × N shape matrix `N_e(x)` at offset `d`.
    fn shape(d: Vec2) -> SMatrix<f64, 2, N>;
    /// Consistent mass `ρ t ∫ N_eᵀ N_e dA` of an element (eqs. 8, 9).
    fn mass(props: &AreaProperties, rho_t: f64) -> SMatrix<f64, N, N>;
}

/// Plain RBSM (eq. 10): `U_e = (u, v, θ)`, `N_e = [[1, 0, −Δy], [0, 1, Δx]]`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Rigid;

impl Kinematics<3> for Rigid {
    #[inline(always)]
    fn displacement(u: &[f64; 3], d: Vec2) -> Vec2 {
        Vec2::new(u[0] - u[2] * d.y, u[1] + u[2] * d.x)
    }
    #[inline(always)]
    fn add_force(f: &mut [f64; 3], d: Vec2, force: Vec2) {
        f[0] += force.x;
        f[1] += force.y;
        f[2] += d.x * force.y - d.y * force.x;
    }
    fn shape(d: Vec2) -> SMatrix<f64, 2, 3> {
        SMatrix::<f64, 2, 3>::new(1.0, 0.0, -d.y, 0.0, 1.0, d.x)
    }
    /// `ρ t diag(A, A, I_p)` (eq. 9): with the centroid as reference the terms couple no DOFs.
    fn mass(props: &AreaProperties, rho_t: f64) -> SMatrix<f64, 3, 3> {
        SMatrix::<f64, 3, 3>::from_diagonal(&(nalgebra::Vector3::new(props.area, props.area, props.polar()) * rho_t))
    }
}

/// The formulation a scene asks for, chosen at run time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Formulation {
    /// 3 DOF per element: `(u, v, θ)`.
    Rigid,
}

impl Formulation {
    /// The formulation of a scene; hybrid is refused until it is implemented.
    pub fn from_spec(spec: FormulationSpec) -> crate::error::Result<Self> {
        match spec {
            FormulationSpec::Rigid => Ok(Formulation::Rigid),
            FormulationSpec::Hybrid { .. } => Err(crate::error::Error::scene(
                "formulation.kind",
                "`hybrid` is not implemented yet; the available formulation is `rigid`",
            )),
        }
    }

    /// DOFs per element.
    pub fn ndof(self) -> usize {
        match self {
            Formulation::Rigid => 3,
        }
    }

    /// The name used in outputs.
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Rigid => "rigid",
        }
    }

    /// Names of the element DOFs, in order (`u, v, theta`, then the strains for hybrid).
    pub fn dof_names(self) -> &'static [&'static str] {
        &DOF_NAMES[..self.ndof()]
    }

    /// `N_e(d)ᵀ F` plus a moment `M` on the rotation, as a vector of `ndof` entries.
    pub fn point_load(self, d: Vec2, force: Vec2, moment: f64) -> Vec<f64> {
        match self {
            Formulation::Rigid => {
                let mut f = [0.0, 0.0, moment];
                Rigid::add_force(&mut f, d, force);
                f.to_vec()
            }
        }
    }

    /// `N_e(d) U_e`: the displacement at offset `d` of an element with DOFs `u`.
    pub fn displacement(self, u: &[f64], d: Vec2) -> Vec2 {
        match self {
            Formulation::Rigid => Rigid::displacement(u.try_into().expect("3 DOFs per rigid element"), d),
        }
    }

    /// The element mass block, row-major `ndof × ndof`.
    pub fn mass(self, props: &AreaProperties, rho_t: f64) -> Vec<f64> {
        match self {
            Formulation::Rigid => Rigid::mass(props, rho_t).transpose().as_slice().to_vec(),
        }
    }
}

/// All DOF names, in the order of `U_e` (DESIGN.md §9).
pub const DOF_NAMES: [&str; 6] = ["u", "v", "theta", "ex", "ey", "gxy"];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rigid_fast_paths_match_the_shape_matrix() {
        let u = [0.3, -0.2, 0.05];
        let d = Vec2::new(0.7, -1.1);
        let n = Rigid::shape(d);
        let via_n = n * nalgebra::Vector3::from(u);
        assert_eq!(Rigid::displacement(&u, d), Vec2::new(via_n[0], via_n[1]));
        let force = Vec2::new(2.0, 3.0);
        let mut f = [0.0; 3];
        Rigid::add_force(&mut f, d, force);
        let via_nt = n.transpose() * force;
        assert_eq!(f, [via_nt[0], via_nt[1], via_nt[2]]);
    }
}

//! Formulations: which displacement field an element carries (eq. 5; the crate documentation's
//! *Kinematics*).
//!
//! A formulation is a [`Kinematics`] with `N` DOFs per element: the shape matrix `N_e(x)`
//! evaluated at an offset `d = x − x_e` from the element's centroid, and its transpose acting on
//! a point force. The evaluators are generic over it, so a new formulation touches neither the
//! integrator nor the evaluators' callers.

use crate::input::scene::FormulationSpec;
use crate::mesh::geometry::{AreaProperties, Vec2};
use nalgebra::{Matrix3, SMatrix};

/// The displacement field of one element, `u(x) = N_e(x) U_e`, with `N` DOFs.
pub trait Kinematics<const N: usize>: Send + Sync + 'static {
    /// `N_e(x) U_e` at offset `d` from the centroid (eq. 5).
    fn displacement(u: &[f64; N], d: Vec2) -> Vec2;
    /// `f += N_e(x)ᵀ F`: the generalised force of a point force `F` at offset `d`.
    fn add_force(f: &mut [f64; N], d: Vec2, force: Vec2);
    /// The part of the displacement linear in the offset, `(N_e(d) − N_e(0)) U_e`: how the
    /// displacement changes from `x_e` to `x_e + d`.
    fn gradient(u: &[f64; N], d: Vec2) -> Vec2;
    /// `f += (N_e(d) − N_e(0))ᵀ F`: [`Kinematics::add_force`] without the translation part.
    fn add_linear(f: &mut [f64; N], d: Vec2, force: Vec2);
    /// What [`Kinematics::add_edge_odd`] needs of an edge, formed once from its Gauss offset
    /// `g` and springs `S` ([`Kinematics::edge_odd`]).
    type EdgeOdd: Copy + Send + Sync + std::fmt::Debug;
    /// [`Kinematics::EdgeOdd`] of an edge with Gauss offset `g` (along the edge) and springs `s`.
    fn edge_odd(g: Vec2, s: &Springs) -> Self::EdgeOdd;
    /// The part of an edge's 2-point Gauss rule that is odd in the Gauss offset `g` (eq. 15,
    /// see `evaluator::element_wise`): `f += (N_e(g) − N_e(0))ᵀ S δ₁`, with
    /// `δ₁ = gradient(u_o, g) − gradient(u_e, g)` (`u_o = None` on ground).
    fn add_edge_odd(
        f: &mut [f64; N],
        ue: &[f64; N],
        uo: Option<&[f64; N]>,
        odd: &Self::EdgeOdd,
        s: &Springs,
    );
    /// The 2 × N shape matrix `N_e(x)` at offset `d`.
    fn shape(d: Vec2) -> SMatrix<f64, 2, N>;
    /// Consistent mass `ρ t ∫ N_eᵀ N_e dA` of an element (eqs. 8, 9).
    fn mass(props: &AreaProperties, rho_t: f64) -> SMatrix<f64, N, N>;
    /// Interior stiffness of the element's own strain energy `½ t A εᵀ D ε` (the `+D` of
    /// eq. 8); zero for a rigid element.
    fn interior_stiffness(props: &AreaProperties, d: &Matrix3<f64>, t: f64) -> SMatrix<f64, N, N>;
    /// Whether `interior_stiffness` can be non-zero (evaluators skip it otherwise).
    const HAS_INTERIOR: bool;
}

/// The penalty springs of an edge acting on a displacement jump `δ`:
/// `λ = S δ = k_s δ + (k_n − k_s)(n·δ) n` (eq. 12), a symmetric 2 × 2 matrix stored as its
/// three entries (N/m³, or N/m when it carries the factor `t L` of an edge's integral).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Springs {
    xx: f64,
    xy: f64,
    yy: f64,
}

impl Springs {
    /// `S = k_s I + (k_n − k_s) n nᵀ` for the unit normal `n`.
    pub fn new(normal: Vec2, k_n: f64, k_s: f64) -> Self {
        let dk = k_n - k_s;
        Springs {
            xx: k_s + dk * normal.x * normal.x,
            xy: dk * normal.x * normal.y,
            yy: k_s + dk * normal.y * normal.y,
        }
    }
    /// `S δ`.
    #[inline(always)]
    pub fn apply(&self, d: Vec2) -> Vec2 {
        Vec2::new(self.xx * d.x + self.xy * d.y, self.xy * d.x + self.yy * d.y)
    }
    /// `dᵀ S d`.
    #[inline(always)]
    pub fn quadratic(&self, d: Vec2) -> f64 {
        self.xx * d.x * d.x + 2.0 * self.xy * d.x * d.y + self.yy * d.y * d.y
    }
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
    #[inline(always)]
    fn gradient(u: &[f64; 3], d: Vec2) -> Vec2 {
        Vec2::new(-u[2] * d.y, u[2] * d.x)
    }
    #[inline(always)]
    fn add_linear(f: &mut [f64; 3], d: Vec2, force: Vec2) {
        f[2] += d.x * force.y - d.y * force.x;
    }
    /// `δ₁ = Δθ ẑ × g`, so the term is a rotational spring on `θ`: `k_θ Δθ` with
    /// `k_θ = (ẑ × g)ᵀ S (ẑ × g) = k_n |g|²` (N·m with `S` carrying `t L`), kept as that scalar.
    type EdgeOdd = f64;
    fn edge_odd(g: Vec2, s: &Springs) -> f64 {
        s.quadratic(Vec2::new(-g.y, g.x))
    }
    #[inline(always)]
    fn add_edge_odd(
        f: &mut [f64; 3],
        ue: &[f64; 3],
        uo: Option<&[f64; 3]>,
        k_theta: &f64,
        _: &Springs,
    ) {
        f[2] += k_theta * (uo.map_or(0.0, |uo| uo[2]) - ue[2]);
    }
    fn shape(d: Vec2) -> SMatrix<f64, 2, 3> {
        SMatrix::<f64, 2, 3>::new(1.0, 0.0, -d.y, 0.0, 1.0, d.x)
    }
    /// `ρ t diag(A, A, I_p)` (eq. 9): with the centroid as reference the terms couple no DOFs.
    fn mass(props: &AreaProperties, rho_t: f64) -> SMatrix<f64, 3, 3> {
        SMatrix::<f64, 3, 3>::from_diagonal(
            &(nalgebra::Vector3::new(props.area, props.area, props.polar()) * rho_t),
        )
    }
    fn interior_stiffness(_: &AreaProperties, _: &Matrix3<f64>, _: f64) -> SMatrix<f64, 3, 3> {
        SMatrix::zeros()
    }
    const HAS_INTERIOR: bool = false;
}

/// Rigid motion plus constant strain (eqs. 5, 8): `U_e = (u, v, θ, ε_x, ε_y, γ_xy)`,
/// `N_e = [[1, 0, −Δy, Δx, 0, Δy/2], [0, 1, Δx, 0, Δy, Δx/2]]` (engineering shear strain).
#[derive(Debug, Clone, Copy, Default)]
pub struct Hybrid;

impl Kinematics<6> for Hybrid {
    #[inline(always)]
    fn displacement(u: &[f64; 6], d: Vec2) -> Vec2 {
        Vec2::new(
            u[0] - u[2] * d.y + u[3] * d.x + 0.5 * u[5] * d.y,
            u[1] + u[2] * d.x + u[4] * d.y + 0.5 * u[5] * d.x,
        )
    }
    #[inline(always)]
    fn add_force(f: &mut [f64; 6], d: Vec2, force: Vec2) {
        f[0] += force.x;
        f[1] += force.y;
        f[2] += d.x * force.y - d.y * force.x;
        f[3] += d.x * force.x;
        f[4] += d.y * force.y;
        f[5] += 0.5 * (d.y * force.x + d.x * force.y);
    }
    #[inline(always)]
    fn gradient(u: &[f64; 6], d: Vec2) -> Vec2 {
        Vec2::new(
            -u[2] * d.y + u[3] * d.x + 0.5 * u[5] * d.y,
            u[2] * d.x + u[4] * d.y + 0.5 * u[5] * d.x,
        )
    }
    #[inline(always)]
    fn add_linear(f: &mut [f64; 6], d: Vec2, force: Vec2) {
        f[2] += d.x * force.y - d.y * force.x;
        f[3] += d.x * force.x;
        f[4] += d.y * force.y;
        f[5] += 0.5 * (d.y * force.x + d.x * force.y);
    }
    /// The Gauss offset itself: the strains make `δ₁` a full vector.
    type EdgeOdd = Vec2;
    fn edge_odd(g: Vec2, _: &Springs) -> Vec2 {
        g
    }
    #[inline(always)]
    fn add_edge_odd(
        f: &mut [f64; 6],
        ue: &[f64; 6],
        uo: Option<&[f64; 6]>,
        &g: &Vec2,
        s: &Springs,
    ) {
        let delta = uo.map_or(Vec2::zeros(), |uo| Self::gradient(uo, g)) - Self::gradient(ue, g);
        Self::add_linear(f, g, s.apply(delta));
    }
    fn shape(d: Vec2) -> SMatrix<f64, 2, 6> {
        SMatrix::<f64, 2, 6>::from_row_slice(&[
            1.0,
            0.0,
            -d.y,
            d.x,
            0.0,
            0.5 * d.y,
            0.0,
            1.0,
            d.x,
            0.0,
            d.y,
            0.5 * d.x,
        ])
    }
    /// `ρ t ∫ Nᵀ N dA`: the translations decouple (`∫ Δx dA = ∫ Δy dA = 0` about the centroid);
    /// `(θ, ε_x, ε_y, γ_xy)` couple through `I_xx = ∫ Δy²`, `I_yy = ∫ Δx²`, `I_xy = ∫ Δx Δy`.
    fn mass(p: &AreaProperties, rho_t: f64) -> SMatrix<f64, 6, 6> {
        let (ixx, iyy, ixy) = (p.i_xx, p.i_yy, p.i_xy);
        let mut m = SMatrix::<f64, 6, 6>::zeros();
        m[(0, 0)] = p.area;
        m[(1, 1)] = p.area;
        let block = [
            [ixx + iyy, -ixy, ixy, 0.5 * (iyy - ixx)],
            [-ixy, iyy, 0.0, 0.5 * ixy],
            [ixy, 0.0, ixx, 0.5 * ixy],
            [0.5 * (iyy - ixx), 0.5 * ixy, 0.5 * ixy, 0.25 * (ixx + iyy)],
        ];
        for i in 0..4 {
            for j in 0..4 {
                m[(i + 2, j + 2)] = block[i][j];
            }
        }
        m * rho_t
    }
    /// `t A D` on the strain DOFs.
    fn interior_stiffness(p: &AreaProperties, d: &Matrix3<f64>, t: f64) -> SMatrix<f64, 6, 6> {
        let mut k = SMatrix::<f64, 6, 6>::zeros();
        k.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(d * (t * p.area)));
        k
    }
    const HAS_INTERIOR: bool = true;
}

/// The elasticity matrix `D` (Pa) for `ε = (ε_x, ε_y, γ_xy)`, plane stress or plane strain.
pub fn elasticity(e: f64, nu: f64, plane: crate::input::scene::Plane) -> Matrix3<f64> {
    match plane {
        crate::input::scene::Plane::Stress => {
            e / (1.0 - nu * nu)
                * Matrix3::new(1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, 0.5 * (1.0 - nu))
        }
        crate::input::scene::Plane::Strain => {
            e / ((1.0 + nu) * (1.0 - 2.0 * nu))
                * Matrix3::new(1.0 - nu, nu, 0.0, nu, 1.0 - nu, 0.0, 0.0, 0.0, 0.5 - nu)
        }
    }
}

/// The formulation a scene asks for, chosen at run time.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Formulation {
    /// 3 DOF per element: `(u, v, θ)`.
    Rigid,
    /// The rigid element's 3 DOFs, springs of `ν = 0` and the Poisson correction of
    /// [`crate::model::poisson`].
    RigidPoisson,
    /// 6 DOF per element: `(u, v, θ, ε_x, ε_y, γ_xy)`; interface springs `penalty` × eq. 12.
    Hybrid {
        /// The penalty factor `p > 0` on the springs of eq. 12.
        penalty: f64,
    },
}

impl Formulation {
    /// The formulation of a scene.
    ///
    /// # Errors
    /// Never: both formulations a scene can name are implemented (hybrid was refused here
    /// before it was).
    pub fn from_spec(spec: FormulationSpec) -> crate::error::Result<Self> {
        match spec {
            FormulationSpec::Rigid => Ok(Formulation::Rigid),
            FormulationSpec::RigidPoisson => Ok(Formulation::RigidPoisson),
            FormulationSpec::Hybrid { penalty } => Ok(Formulation::Hybrid { penalty }),
        }
    }

    /// DOFs per element.
    pub fn ndof(self) -> usize {
        match self {
            Formulation::Rigid | Formulation::RigidPoisson => 3,
            Formulation::Hybrid { .. } => 6,
        }
    }

    /// The name used in outputs.
    pub fn name(self) -> &'static str {
        match self {
            Formulation::Rigid => "rigid",
            Formulation::RigidPoisson => "rigid-poisson",
            Formulation::Hybrid { .. } => "hybrid",
        }
    }

    /// Names of the element DOFs, in order (`u, v, theta`, then the strains for hybrid).
    pub fn dof_names(self) -> &'static [&'static str] {
        &crate::input::scene::DOF_NAMES[..self.ndof()]
    }

    /// `N_e(d)ᵀ F` plus a moment `M` on the rotation, as a vector of `ndof` entries.
    pub fn point_load(self, d: Vec2, force: Vec2, moment: f64) -> Vec<f64> {
        match self {
            Formulation::Rigid | Formulation::RigidPoisson => {
                let mut f = [0.0, 0.0, moment];
                Rigid::add_force(&mut f, d, force);
                f.to_vec()
            }
            Formulation::Hybrid { .. } => {
                let mut f = [0.0, 0.0, moment, 0.0, 0.0, 0.0];
                Hybrid::add_force(&mut f, d, force);
                f.to_vec()
            }
        }
    }

    /// `f += N_e(d)ᵀ F` on the `ndof` entries of one element (no allocation).
    ///
    /// # Panics
    /// `f.len()` is not [`Formulation::ndof`]: 3 for rigid, 6 for hybrid.
    pub fn add_point_force(self, f: &mut [f64], d: Vec2, force: Vec2) {
        match self {
            Formulation::Rigid | Formulation::RigidPoisson => {
                Rigid::add_force(f.try_into().expect("3 DOFs per rigid element"), d, force)
            }
            Formulation::Hybrid { .. } => {
                Hybrid::add_force(f.try_into().expect("6 DOFs per hybrid element"), d, force)
            }
        }
    }

    /// `N_e(d) U_e`: the displacement at offset `d` of an element with DOFs `u`.
    ///
    /// # Panics
    /// `u.len()` is not [`Formulation::ndof`]: 3 for rigid, 6 for hybrid.
    pub fn displacement(self, u: &[f64], d: Vec2) -> Vec2 {
        match self {
            Formulation::Rigid | Formulation::RigidPoisson => {
                Rigid::displacement(u.try_into().expect("3 DOFs per rigid element"), d)
            }
            Formulation::Hybrid { .. } => {
                Hybrid::displacement(u.try_into().expect("6 DOFs per hybrid element"), d)
            }
        }
    }

    /// Where the point at reference offset `d` from the centroid `x_e` of an element with DOFs
    /// `ue` is, with the element's finite rotation: `x_e + u_e + R(θ_e)(d + E_e d)`, `E_e d` the
    /// strain part (zero for rigid). The springs stay small-rotation (eq. 5); this places
    /// contact points and draws the elements.
    pub fn current_position(self, centroid: Vec2, ue: &[f64], d: Vec2) -> Vec2 {
        centroid + Vec2::new(ue[0], ue[1]) + rotation(ue[2]) * (d + self.strain_part(ue, d))
    }

    /// The strain part `E_e d` of an element's displacement at offset `d` (zero for rigid).
    pub fn strain_part(self, ue: &[f64], d: Vec2) -> Vec2 {
        match self {
            Formulation::Rigid | Formulation::RigidPoisson => Vec2::zeros(),
            Formulation::Hybrid { .. } => {
                let mut w = [0.0; 6];
                w[3..].copy_from_slice(&ue[3..6]);
                self.displacement(&w, d)
            }
        }
    }

    /// The element mass block, row-major `ndof × ndof`.
    pub fn mass(self, props: &AreaProperties, rho_t: f64) -> Vec<f64> {
        match self {
            Formulation::Rigid | Formulation::RigidPoisson => {
                Rigid::mass(props, rho_t).transpose().as_slice().to_vec()
            }
            Formulation::Hybrid { .. } => {
                Hybrid::mass(props, rho_t).transpose().as_slice().to_vec()
            }
        }
    }

    /// The factor on the springs of eq. 12: 1 for rigid, the penalty `p` for hybrid.
    pub fn spring_factor(self) -> f64 {
        match self {
            Formulation::Rigid | Formulation::RigidPoisson => 1.0,
            Formulation::Hybrid { penalty } => penalty,
        }
    }
}

/// The rotation matrix of angle `theta`.
pub fn rotation(theta: f64) -> nalgebra::Matrix2<f64> {
    let (s, c) = theta.sin_cos();
    nalgebra::Matrix2::new(c, -s, s, c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::geometry::area_properties;

    /// `∫ f dA` over a polygon by splitting it into triangles from its centroid and using the
    /// 3-point edge-midpoint rule on each (exact for quadratics).
    fn integrate(pts: &[Vec2], f: impl Fn(Vec2) -> f64) -> f64 {
        let c = area_properties(pts).centroid;
        (0..pts.len())
            .map(|i| {
                let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
                let area = 0.5 * (a - c).perp(&(b - c));
                area / 3.0 * (f(0.5 * (a + b)) + f(0.5 * (b + c)) + f(0.5 * (c + a)))
            })
            .sum()
    }

    #[test]
    fn hybrid_mass_is_the_integral_of_nt_n() {
        let pts = [
            Vec2::new(0.1, 0.0),
            Vec2::new(1.3, 0.2),
            Vec2::new(1.1, 0.9),
            Vec2::new(0.4, 1.2),
            Vec2::new(-0.2, 0.5),
        ];
        let p = area_properties(&pts);
        let m = Hybrid::mass(&p, 2.5);
        for i in 0..6 {
            for j in 0..6 {
                let exact = 2.5
                    * integrate(&pts, |x| {
                        let n = Hybrid::shape(x - p.centroid);
                        n[(0, i)] * n[(0, j)] + n[(1, i)] * n[(1, j)]
                    });
                assert!(
                    (m[(i, j)] - exact).abs() <= 1e-13 * m.norm(),
                    "M[{i},{j}] = {} vs {exact}",
                    m[(i, j)]
                );
            }
        }
        assert!(
            m.cholesky().is_some(),
            "the consistent mass is positive definite"
        );
    }

    #[test]
    fn hybrid_fast_paths_match_the_shape_matrix() {
        let u = [0.3, -0.2, 0.05, 1e-3, -2e-3, 3e-3];
        let d = Vec2::new(0.7, -1.1);
        let n = Hybrid::shape(d);
        let via_n = n * nalgebra::SVector::<f64, 6>::from(u);
        assert!((Hybrid::displacement(&u, d) - Vec2::new(via_n[0], via_n[1])).norm() < 1e-15);
        let force = Vec2::new(2.0, 3.0);
        let mut f = [0.0; 6];
        Hybrid::add_force(&mut f, d, force);
        let via_nt = n.transpose() * force;
        assert!((0..6).all(|i| (f[i] - via_nt[i]).abs() < 1e-15));
        let at_centroid = Hybrid::shape(Vec2::zeros()) * nalgebra::SVector::<f64, 6>::from(u);
        assert!(
            (Hybrid::gradient(&u, d)
                - Vec2::new(via_n[0] - at_centroid[0], via_n[1] - at_centroid[1]))
            .norm()
                < 1e-15
        );
        let mut g = [0.0; 6];
        Hybrid::add_linear(&mut g, d, force);
        assert!(g[..2] == [0.0, 0.0] && (2..6).all(|i| (g[i] - via_nt[i]).abs() < 1e-15));
    }

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
        assert!(
            (Rigid::gradient(&u, d) - Vec2::new(via_n[0] - u[0], via_n[1] - u[1])).norm() < 1e-15
        );
        let mut g = [0.0; 3];
        Rigid::add_linear(&mut g, d, force);
        assert_eq!(g, [0.0, 0.0, via_nt[2]]);
    }
}

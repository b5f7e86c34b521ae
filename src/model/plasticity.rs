//! The strength of a hybrid element's own constant stress (issue 43): Tresca and Mohr–Coulomb,
//! plane strain and plane stress, and its return mapping.
//!
//! A hybrid element carries the constant strain `ε = (ε_x, ε_y, γ_xy)` (eq. 5) and so the
//! constant stress `σ = D (ε − ε_p)`, with `ε_p` its plastic strain. In 2D the criteria depend
//! on the stress through two numbers only, the mean in-plane stress `p = (σ_x + σ_y)/2` and the
//! radius of Mohr's circle `R = √(((σ_x − σ_y)/2)² + τ²)` (tension positive):
//!
//! - **plane strain** (`σ_z` the intermediate principal stress, as associated flow with
//!   `ε̇_z = 0` makes it): `R + p sin φ ≤ c cos φ`;
//! - **plane stress** (`σ_z = 0` a principal stress): the same for the in-plane pair, and the
//!   pairs with zero, `σ₁ = p + R ≤ f_t` and `−σ₂ = R − p ≤ f_c`, with
//!   `f_t = 2c cos φ/(1 + sin φ)`, `f_c = 2c cos φ/(1 − sin φ)`.
//!
//! Tresca is `φ = 0`. Each condition is a half-plane `a p + b R ≤ r` of the `(p, R)` plane, so
//! the elastic region is a convex polygon there (with `R ≥ 0`), and, in 2D, a second-order
//! cone in `σ` (the collapse load's conic program uses them as such).
//!
//! **Return mapping** (backward Euler, associated flow): the stress is the closest point of the
//! region to the trial stress `σ* = D (ε − ε_p)` in the energy norm `Δσᵀ D⁻¹ Δσ`. `D` is
//! isotropic, so that norm is `Δp²/K + (Δs² + Δτ²)/μ` with `K = (D₁₁ + D₁₂)/2` (the 2D bulk
//! modulus) and `μ = D₃₃`; the return keeps the principal directions (`(s, τ)` scales with `R`)
//! and is the Euclidean projection of `(p/√K, R/√μ)` onto the polygon, found exactly by trying
//! each side and each corner. The plastic strain grows by `D⁻¹ (σ* − σ)`.

use crate::input::scene::Plane;
use nalgebra::{Matrix3, Vector3};

/// A hybrid element's strength: Mohr–Coulomb on its constant stress (Tresca when `φ = 0`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementStrength {
    /// Cohesion `c` (Pa), > 0.
    pub cohesion: f64,
    /// Friction angle `φ` (rad), in `[0, π/2)`.
    pub friction: f64,
    /// Plane strain or plane stress: which criterion in `(p, R)`.
    pub plane: Plane,
}

/// At most three sides `a p + b R ≤ r` and `R ≥ 0`.
type Sides = ([[f64; 3]; 4], usize);

impl ElementStrength {
    /// The strength of `c` (Pa) and `φ` (degrees).
    pub fn new(cohesion: f64, friction_deg: f64, plane: Plane) -> Self {
        ElementStrength {
            cohesion,
            friction: friction_deg.to_radians(),
            plane,
        }
    }

    /// The sides `[a, b, r]` of the elastic region, `a p + b R ≤ r`, `R ≥ 0` last.
    pub fn sides(&self) -> Sides {
        let (sin, cos) = self.friction.sin_cos();
        let c = self.cohesion;
        let mut s = [[0.0; 3]; 4];
        s[0] = [sin, 1.0, c * cos];
        let n = match self.plane {
            Plane::Strain => 1,
            Plane::Stress => {
                s[1] = [1.0, 1.0, 2.0 * c * cos / (1.0 + sin)];
                s[2] = [-1.0, 1.0, 2.0 * c * cos / (1.0 - sin)];
                3
            }
        };
        s[n] = [0.0, -1.0, 0.0];
        (s, n + 1)
    }

    /// The largest of `a p + b R − r` over the criterion's sides (not `R ≥ 0`): ≤ 0 inside.
    pub fn excess(&self, sigma: &Vector3<f64>) -> f64 {
        let (p, r) = mohr(sigma);
        let (sides, n) = self.sides();
        sides[..n - 1]
            .iter()
            .map(|s| s[0] * p + s[1] * r - s[2])
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The stress of the region closest to the trial stress `trial` in the energy norm of the
    /// isotropic elasticity `d` (the module's *Return mapping*); `trial` itself inside. A trial
    /// that is not finite (a run gone unstable) comes back as it is, for the run's guard to
    /// stop on.
    pub fn return_map(&self, d: &Matrix3<f64>, trial: &Vector3<f64>) -> Vector3<f64> {
        // Relative to the strength, so that round-off on the boundary does not count as flow.
        if self.excess(trial) <= 1e-12 * self.cohesion || !trial.iter().all(|x| x.is_finite()) {
            return *trial;
        }
        let (bulk, mu) = (0.5 * (d[(0, 0)] + d[(0, 1)]), d[(2, 2)]);
        let (sk, sm) = (bulk.sqrt(), mu.sqrt());
        let (p, r) = mohr(trial);
        let q = [p / sk, r / sm];
        let (sides, n) = self.sides();
        // The sides in the scaled plane: a' x + b' y ≤ r with x = p/√K, y = R/√μ.
        let mut lines = [[0.0; 3]; 4];
        for (l, s) in lines.iter_mut().zip(&sides) {
            *l = [s[0] * sk, s[1] * sm, s[2]];
        }
        let lines = &lines[..n];
        let inside = |z: [f64; 2]| {
            lines
                .iter()
                .all(|l| l[0] * z[0] + l[1] * z[1] - l[2] <= 1e-9 * (self.cohesion + l[2].abs()))
        };
        let mut best: Option<([f64; 2], f64)> = None;
        let mut consider = |z: [f64; 2]| {
            let dist = (z[0] - q[0]).powi(2) + (z[1] - q[1]).powi(2);
            if inside(z) && best.is_none_or(|(_, b)| dist < b) {
                best = Some((z, dist));
            }
        };
        for (i, l) in lines.iter().enumerate() {
            let norm2 = l[0] * l[0] + l[1] * l[1];
            let over = (l[0] * q[0] + l[1] * q[1] - l[2]) / norm2;
            consider([q[0] - over * l[0], q[1] - over * l[1]]);
            for m in &lines[i + 1..] {
                let det = l[0] * m[1] - l[1] * m[0];
                if det.abs() > 1e-12 * norm2.sqrt() * (m[0] * m[0] + m[1] * m[1]).sqrt() {
                    consider([
                        (l[2] * m[1] - l[1] * m[2]) / det,
                        (l[0] * m[2] - l[2] * m[0]) / det,
                    ]);
                }
            }
        }
        // The region holds the origin, so some side or corner is admissible unless the moduli
        // are not finite: then no stress is, and the NaN stops the run at its guard.
        let Some(([x, y], _)) = best else {
            return Vector3::repeat(f64::NAN);
        };
        let (p_new, r_new) = (x * sk, (y * sm).max(0.0));
        let scale = if r > 0.0 { r_new / r } else { 0.0 };
        let s = 0.5 * (trial[0] - trial[1]) * scale;
        Vector3::new(p_new + s, p_new - s, trial[2] * scale)
    }
}

/// `D⁻¹ x` for the isotropic elasticity `d`, through its 2D bulk and shear moduli (no matrix
/// inverse): `ε_x + ε_y = (x_x + x_y)/(2K)`, `ε_x − ε_y = (x_x − x_y)/(2μ)`, `γ = x_τ/μ`.
pub fn compliance_times(d: &Matrix3<f64>, x: &Vector3<f64>) -> Vector3<f64> {
    let (bulk, mu) = (0.5 * (d[(0, 0)] + d[(0, 1)]), d[(2, 2)]);
    let volumetric = 0.5 * (x[0] + x[1]) / bulk;
    let deviatoric = 0.5 * (x[0] - x[1]) / mu;
    Vector3::new(
        0.5 * (volumetric + deviatoric),
        0.5 * (volumetric - deviatoric),
        x[2] / mu,
    )
}

/// `(p, R)`: the mean in-plane stress and the radius of Mohr's circle of `σ = (σ_x, σ_y, τ)`.
pub fn mohr(sigma: &Vector3<f64>) -> (f64, f64) {
    let p = 0.5 * (sigma[0] + sigma[1]);
    let s = 0.5 * (sigma[0] - sigma[1]);
    (p, s.hypot(sigma[2]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::formulation::elasticity;

    #[test]
    fn tresca_in_plane_strain_returns_the_circle_radius_to_c_at_fixed_mean_stress() {
        let d = elasticity(1e9, 0.3, Plane::Strain);
        let st = ElementStrength::new(1e5, 0.0, Plane::Strain);
        let trial = Vector3::new(3e5, -1e5, 2e5);
        let s = st.return_map(&d, &trial);
        let (p, r) = mohr(&s);
        assert!((p - 1e5).abs() < 1e-6 && (r - 1e5).abs() < 1e-6, "{p} {r}");
        // Principal directions kept: (σ_x − σ_y)/2 : τ as in the trial.
        assert!((0.5 * (s[0] - s[1]) / s[2] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_compliance_inverts_the_elasticity_in_both_planes() {
        for plane in [Plane::Strain, Plane::Stress] {
            let d = elasticity(3e10, 0.2, plane);
            let x = Vector3::new(1e6, -3e5, 4e5);
            let back = d * compliance_times(&d, &x);
            assert!((back - x).norm() < 1e-9 * x.norm(), "{plane:?}: {back:?}");
        }
    }
}

//! The facet law of quasi-brittle materials (`"kind": "facet"`): the traction–separation law of
//! the lattice and rigid-body-spring models of concrete and rock (Cusatis' LDPM facet law,
//! Grassl's and Bolander's lattice laws), written for eq. 11's interfaces through the one seam
//! [`InterfaceLaw`].
//!
//! **Tension and shear** (a trial traction with `σ > 0`). The effective traction
//! `σ_eff = √(σ² + τ²/α)`, `α = k_s/k_n`, and its direction `ω`
//! (`σ = σ_eff sin ω`, `τ = √α σ_eff cos ω`, from `ω = 0` in pure shear to `π/2` in pure
//! tension). The strength surface is LDPM's parabola `τ² = s² (1 − σ/f_t)`: `f_t` in pure
//! tension, `s` in pure shear, smooth in between; in the direction `ω` it is met at
//! `σ_eff = σ₀(ω) = 2 f_t / (sin ω + √(sin² ω + 4 α f_t² cos² ω / s²))`. It softens with
//! one dimensionless variable `ψ`: `σ_eff ≤ σ₀(ω) e^{−ψ}`, `dψ = σ₀(ω) dw / G(ω)`, with `dw` the
//! effective inelastic opening `√(dδ_p,n² + α dδ_p,s²)` and
//! `G(ω) = G_t sin² ω + G_s cos² ω` (the shares of the elastic energy in opening and in
//! slip). A trial traction outside is scaled back along its own direction (the return of
//! LDPM's stress-boundary algorithm), implicitly: along a straight path of `δ` the traction
//! follows `σ_eff = σ₀ e^{−σ₀ w / G}`, `|δ|_eff = w + σ_eff / k_n`, and a facet that opens to
//! the end dissipates `G(ω)` per unit area, whatever its size (the softening is written in
//! opening, not in strain).
//!
//! **Compression** (a trial traction with `σ ≤ 0`). A cap `σ ≥ −(f_c + H κ_c)` hardening with
//! the compaction `κ_c` (m), and friction that stays bounded as the pressure grows (LDPM):
//! `|τ| ≤ s e^{−ψ} + (μ₀ − μ_∞) σ_N0 (1 − e^{σ/σ_N0}) − μ_∞ σ`, a coefficient `μ₀` at low
//! pressure falling to `μ_∞` beyond `σ_N0`. The cohesive part `s e^{−ψ}` is the shear strength
//! the tension–shear surface has left, and softens with the slip as there
//! (`dψ = s dδ_p,s / G_s`); the frictional part dissipates without softening. No dilatancy.
//!
//! The state of a point: `δ_p`, `κ = [ψ, κ_c]`, the works (fracture: opening and cohesion;
//! friction: friction and the cap's compaction). A point is broken once `ψ ≥ ln 100` (1 % of
//! its strength left, then dropped: it keeps the cap and friction, and hands over to contact);
//! its crack closes with its faces, pressing them only once they touch
//! ([`LawPoint::close_crack`]).

use crate::model::law::{InterfaceLaw, LawPoint};

/// The softening variable `ψ` at which a point counts as broken: `e^{−ψ}` = 1 % of its
/// strength left.
pub const BROKEN: f64 = 4.605_170_185_988_091; // ln 100

/// The parameters of the facet law (`docs/scene.md`, *interface*).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Facet {
    /// Tensile strength `f_t` (Pa), > 0.
    pub f_t: f64,
    /// Shear strength `s` (Pa) at zero normal traction, > 0.
    pub s: f64,
    /// Fracture energy in tension `G_t` (J/m²), > 0.
    pub g_t: f64,
    /// Fracture energy in shear `G_s` (J/m²), > 0.
    pub g_s: f64,
    /// Compressive strength `f_c` (Pa), > 0: the cap before it hardens.
    pub f_c: f64,
    /// Hardening of the cap `H` (Pa/m): its rise per metre of compaction.
    pub cap_hardening: f64,
    /// Friction coefficient `μ₀` at low pressure.
    pub mu_0: f64,
    /// Friction coefficient `μ_∞` at high pressure, at most `μ₀`.
    pub mu_inf: f64,
    /// The pressure `σ_N0` (Pa) over which the coefficient passes from `μ₀` to `μ_∞`, > 0.
    pub sigma_n0: f64,
}

/// The increment `x ≥ 0` that brings a trial `a` back to a strength that softens with it:
/// `a − k x = b + A e^{−β x}` (Newton from `x = 0`, which approaches the root from above on
/// this concave function, so every iterate after the first is an upper bound). Where the
/// softening is steeper than the spring (`A β ≥ k`, a snap-back at the point), the strength
/// of the start of the update: `x = (a − b − A) / k`.
#[inline]
fn soften(a: f64, k: f64, b: f64, strength: f64, beta: f64) -> f64 {
    if strength * beta >= k {
        return (a - b - strength) / k;
    }
    let mut x = 0.0;
    for _ in 0..50 {
        let e = strength * (-beta * x).exp();
        let step = (a - k * x - b - e) / (k - beta * e);
        x += step;
        if step.abs() <= 4.0 * f64::EPSILON * x.abs() {
            break;
        }
    }
    x
}

/// The work `∫₀ˣ A e^{−β y} dy` of a strength `A` softening at `β` over `x`.
#[inline]
fn softening_work(strength: f64, beta: f64, x: f64) -> f64 {
    if beta > 0.0 {
        strength * -(-beta * x).exp_m1() / beta
    } else {
        strength * x
    }
}

impl Facet {
    /// The strength `σ₀(ω)` of the unsoftened surface in the direction `(sin ω, cos ω)` of the
    /// effective traction, for `α = k_s/k_n`.
    pub fn sigma_0(&self, sin: f64, cos: f64, alpha: f64) -> f64 {
        let r = self.f_t / self.s;
        2.0 * self.f_t / (sin + (sin * sin + 4.0 * alpha * r * r * cos * cos).sqrt())
    }

    /// The fracture energy `G(ω) = G_t sin² ω + G_s cos² ω` (J/m²).
    pub fn energy(&self, sin: f64, cos: f64) -> f64 {
        self.g_t * sin * sin + self.g_s * cos * cos
    }

    /// The frictional part of the shear strength at a normal traction `σ ≤ 0` (Pa):
    /// `(μ₀ − μ_∞) σ_N0 (1 − e^{σ/σ_N0}) − μ_∞ σ`.
    pub fn friction(&self, sigma: f64) -> f64 {
        -(self.mu_0 - self.mu_inf) * self.sigma_n0 * (sigma / self.sigma_n0).exp_m1()
            - self.mu_inf * sigma
    }
}

impl InterfaceLaw for Facet {
    fn springs(&self, k: [f64; 2]) -> [f64; 2] {
        k
    }
    fn is_linear(&self) -> bool {
        false
    }
    /// A triangle inside the unsoftened surface: `σ ≤ f_t/2` and
    /// `|τ| ≤ c (1 + σ/f_c)` with `c = 0.7 s / (1 + f_t/(2 f_c))` (the negative `tan φ` closes
    /// it at the cap `σ = −f_c`): below the parabola at `σ = 0` and `f_t/2` (where it is
    /// `s/√2`), hence between, and below the cohesion `s` in compression.
    fn initial_region(&self) -> Option<[f64; 3]> {
        let c = 0.7 * self.s / (1.0 + 0.5 * self.f_t / self.f_c);
        Some([0.5 * self.f_t, c, -c / self.f_c])
    }
    /// The stress-boundary update at `δ` on springs `k`: the trial `k (δ − δ_p)`, scaled back
    /// to the softened tension–shear surface along its direction, or in compression returned
    /// to the cap and then to the friction surface; the softening, the compaction and the
    /// works updated (each return implicit, the work the exact area under the softening). A
    /// broken point's crack closes with its faces ([`LawPoint::close_crack`]).
    fn update(&self, k: [f64; 2], delta: [f64; 2], point: &mut LawPoint) -> ([f64; 2], bool) {
        // Broken: a crack, which closes with its faces.
        let closed = self.is_broken(point) && point.close_crack(delta[0]);
        let mut sigma = k[0] * (delta[0] - point.p[0]);
        let mut tau = k[1] * (delta[1] - point.p[1]);
        let alpha = k[1] / k[0];
        let psi = point.kappa[0];
        let mut flowed = false;
        if sigma > 0.0 {
            let eff = (sigma * sigma + tau * tau / alpha).sqrt();
            let (sin, cos) = (sigma / eff, tau.abs() / (alpha.sqrt() * eff));
            let s0 = self.sigma_0(sin, cos, alpha);
            let strength = s0 * (-psi).exp();
            if eff > strength {
                let beta = s0 / self.energy(sin, cos);
                let w = soften(eff, k[0], 0.0, strength, beta);
                let scale = (eff - k[0] * w) / eff;
                sigma *= scale;
                tau *= scale;
                point.kappa[0] += beta * w;
                point.fracture += softening_work(strength, beta, w);
                flowed = true;
            }
        } else {
            let cap = self.f_c + self.cap_hardening * point.kappa[1];
            if -sigma > cap {
                let y = (-sigma - cap) / (k[0] + self.cap_hardening);
                sigma = -(cap + self.cap_hardening * y);
                point.kappa[1] += y;
                point.friction += (cap + 0.5 * self.cap_hardening * y) * y;
                flowed = true;
            }
            let (friction, cohesion) = (self.friction(sigma), self.s * (-psi).exp());
            if tau.abs() > friction + cohesion {
                let beta = self.s / self.g_s;
                let slide = soften(tau.abs(), k[1], friction, cohesion, beta);
                tau -= slide.copysign(tau) * k[1];
                point.kappa[0] += beta * slide;
                point.fracture += softening_work(cohesion, beta, slide);
                point.friction += friction * slide;
                flowed = true;
            }
        }
        if flowed {
            point.p = [delta[0] - sigma / k[0], delta[1] - tau / k[1]];
        }
        ([sigma, tau], flowed || closed)
    }
    /// Once 1 % of the strength is left ([`BROKEN`]).
    fn is_broken(&self, point: &LawPoint) -> bool {
        point.kappa[0] >= BROKEN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Concrete-like facets: `f_t` 3 MPa, `s` 2.7 f_t, `G_t` 100 J/m², `G_s` 10 G_t,
    /// `f_c` 10 f_t hardening at `E/10` per metre over a 0.1 m cell.
    fn law() -> Facet {
        Facet {
            f_t: 3.0e6,
            s: 8.1e6,
            g_t: 100.0,
            g_s: 1000.0,
            f_c: 3.0e7,
            cap_hardening: 3.0e10,
            mu_0: 0.6,
            mu_inf: 0.1,
            sigma_n0: 1.0e7,
        }
    }

    /// Springs of a 0.1 m cell of `E` = 30 GPa, `α` = 0.4.
    const K: [f64; 2] = [3.0e11, 1.2e11];

    /// Drives one point along `δ = ρ d` for `ρ` in `n` steps to `end`, returning each step's
    /// `(|δ|_eff, σ_eff)` and the point.
    fn ray(d: [f64; 2], end: f64, n: usize) -> (Vec<(f64, f64, [f64; 2])>, LawPoint) {
        let law = law();
        let alpha = K[1] / K[0];
        let mut point = LawPoint::default();
        let path = (1..=n)
            .map(|i| {
                let r = end * i as f64 / n as f64;
                let delta = [r * d[0], r * d[1]];
                let (t, _) = law.update(K, delta, &mut point);
                let eff = (t[0] * t[0] + t[1] * t[1] / alpha).sqrt();
                let opening = (delta[0].powi(2) + alpha * delta[1].powi(2)).sqrt();
                (opening, eff, t)
            })
            .collect();
        (path, point)
    }

    /// Along a straight opening path the traction keeps its direction, lies on
    /// `σ_eff = σ₀ e^{−σ₀ w / G}` with `w = |δ|_eff − σ_eff/k_n` once it has left the elastic
    /// line, and the fracture work tends to `G(ω)` per unit area: pure tension, pure shear and
    /// a mixed path, each against the closed form.
    #[test]
    fn straight_paths_follow_the_closed_form_and_spend_g() {
        let law = law();
        let alpha = K[1] / K[0];
        for (d, name) in [
            ([1.0, 0.0], "tension"),
            ([0.0, 1.0], "shear"),
            ([1.0, 1.0], "mixed"),
        ] {
            // `ω` of the traction `(k_n δ_n, k_s δ_s)` on that path.
            let eff = (d[0] * d[0] + alpha * d[1] * d[1]).sqrt();
            let (sin, cos) = (d[0] / eff, alpha.sqrt() * d[1] / eff);
            let (s0, g) = (law.sigma_0(sin, cos, alpha), law.energy(sin, cos));
            // To 40 times the opening that spends the strength once.
            let (path, point) = ray(d, 40.0 * g / s0 / eff, 20_000);
            let mut peak: f64 = 0.0;
            for &(opening, sigma, t) in &path {
                peak = peak.max(sigma);
                let w = opening - sigma / K[0];
                let expected = if w <= 1e-15 {
                    (K[0] * opening).min(s0)
                } else {
                    s0 * (-s0 * w / g).exp()
                };
                assert!(
                    (sigma - expected).abs() <= 1e-9 * s0,
                    "{name}: σ_eff {sigma} against {expected} at w {w}"
                );
                // The direction of the traction is the path's.
                let along = t[0] * d[1] * K[1] - t[1] * d[0] * K[0];
                assert!(along.abs() <= 1e-9 * s0 * K[0], "{name}: turned");
            }
            // The steps sample the peak: the first one past it has softened a little.
            assert!(
                peak <= s0 * (1.0 + 1e-9) && peak >= 0.99 * s0,
                "{name}: peak {peak}, σ₀ {s0}"
            );
            let left = (-40.0f64).exp();
            assert!(
                (point.fracture / g - (1.0 - left)).abs() < 1e-9,
                "{name}: fracture work {} G",
                point.fracture / g
            );
            assert!(law.is_broken(&point), "{name}: not broken");
        }
        // The surface: `f_t` in tension, `s` in shear.
        assert!((law.sigma_0(1.0, 0.0, alpha) - law.f_t).abs() < 1e-6);
        assert!((law.sigma_0(0.0, 1.0, alpha) * alpha.sqrt() - law.s).abs() < 1e-6);
    }

    /// The cap in pure compression: elastic to `f_c`, then hardening at `H k / (k + H)`, the
    /// compaction's work booked as the area under the path's plastic part; shear under
    /// pressure slides at the bounded friction, whose coefficient falls from `μ₀` to `μ_∞`.
    #[test]
    fn compression_has_a_hardening_cap_and_bounded_friction() {
        let law = law();
        let mut point = LawPoint::default();
        let mut last = 0.0;
        for i in 1..=1000 {
            let d = -4.0 * law.f_c / K[0] * i as f64 / 1000.0;
            let (t, _) = law.update(K, [d, 0.0], &mut point);
            let h = law.cap_hardening;
            let expected = if -K[0] * d <= law.f_c {
                K[0] * d
            } else {
                -(law.f_c + h * K[0] / (K[0] + h) * (-d - law.f_c / K[0]))
            };
            assert!(
                (t[0] - expected).abs() < 1e-6 * law.f_c,
                "σ {} ≠ {expected}",
                t[0]
            );
            last = t[0];
        }
        let y = point.kappa[1];
        let work = (law.f_c + 0.5 * law.cap_hardening * y) * y;
        assert!((point.friction - work).abs() < 1e-9 * work);
        assert!(-last > law.f_c);
        // Friction: the coefficient `d|τ|/d(−σ)` is `μ₀` at no pressure and `μ_∞` far beyond
        // `σ_N0`; its strength is finite and grows no faster than `μ₀ |σ|`.
        let slope = |sigma: f64| (law.friction(sigma - 1.0) - law.friction(sigma + 1.0)) / 2.0;
        assert!((slope(0.0) - law.mu_0).abs() < 1e-6);
        assert!((slope(-20.0 * law.sigma_n0) - law.mu_inf).abs() < 1e-6);
        // Sliding under a pressure `p` after the cohesion is gone: `|τ| = friction(−p)`.
        let mut point = LawPoint {
            kappa: [40.0, 0.0],
            ..LawPoint::default()
        };
        let p = 5.0e6;
        let (t, flowed) = law.update(K, [-p / K[0], 1e-3], &mut point);
        assert!(flowed && (t[1] - law.friction(-p)).abs() < 1e-6 * p);
    }

    /// A fresh point inside the quick test's region is left elastic: the region lies inside
    /// the law's own.
    #[test]
    fn the_initial_region_lies_inside_the_surface() {
        let law = law();
        let [cap, c, tan_phi] = law.initial_region().unwrap();
        for i in 0..=400 {
            let sigma = -law.f_c + (cap + law.f_c) * i as f64 / 400.0;
            let tau = c - sigma * tan_phi;
            if tau < 0.0 {
                continue;
            }
            for t in [tau, -tau] {
                let mut point = LawPoint::default();
                let delta = [sigma / K[0], t / K[1]];
                let (_, flowed) = law.update(K, delta, &mut point);
                assert!(!flowed, "({sigma}, {t}) flowed");
            }
        }
        // And a point just outside the parabola does flow.
        let mut point = LawPoint::default();
        let (_, flowed) = law.update(K, [1.001 * law.f_t / K[0], 0.0], &mut point);
        assert!(flowed);
    }
}

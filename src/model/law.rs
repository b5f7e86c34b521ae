//! The interface law (eq. 11): what an interface's springs do with its relative displacement.
//!
//! On an interface with unit normal `n` and tangent `s`, the relative displacement
//! `δ = u_b − u_a` has the components `(δ_n, δ_s) = (n·δ, s·δ)`, and the traction on `a` from
//! `b` is `λ = λ_n n + λ_s s` (Pa). An [`InterfaceLaw`] maps `(δ_n, δ_s)` and the state of the
//! Gauss point ([`LawPoint`]) to `(λ_n, λ_s)`, given the interface's elastic moduli
//! `k = (k_n, k_s)` of eq. 12 (Pa/m, the hybrid penalty included). It is the one seam of eq. 11:
//! the elastic springs ([`Elastic`]), the strength of interfaces that fail ([`Strength`]) and
//! the contact springs all go through it, and a law defined outside the crate reaches the
//! evaluators, the statics and the contact the same way (`tests/law.rs` adds two).
//!
//! Every law is written as springs and a plastic relative displacement:
//! `λ = diag(k_n', k_s') (δ − δ_p)`, with `(k_n', k_s')` its [`springs`](InterfaceLaw::springs)
//! and `δ_p` the point's [`LawPoint::p`], which [`InterfaceLaw::update`] keeps (any traction
//! can be written so). That is what lets the evaluators keep their elastic hot loops for every
//! law: they assemble a constant `K` (or split the Gauss rule of an edge into `δ₀ ± δ₁`,
//! `force::evaluator::ElementWise`) from the springs, and `force::failure` adds the plastic
//! forces `−Σ t w Nᵀ diag(k) δ_p` of the interfaces whose law is not
//! [linear](InterfaceLaw::is_linear), in the same pass.
//! A linear law has no state: no point of it is stored or updated.

use std::fmt::Debug;

/// A traction–separation law of the interfaces (eq. 11), on each interface's `(n, s)` axes.
///
/// A linear law implements [`springs`](InterfaceLaw::springs) and
/// [`is_linear`](InterfaceLaw::is_linear) (`true`); a law with a state per Gauss point also
/// [`update`](InterfaceLaw::update), [`is_broken`](InterfaceLaw::is_broken) when its
/// interfaces can be handed over to contact, and
/// [`initial_region`](InterfaceLaw::initial_region) to spare the steps its `update` where a
/// fresh point stays elastic.
pub trait InterfaceLaw: Send + Sync + Debug {
    /// The springs `(k_n', k_s')` (Pa/m) of an interface with elastic moduli `k = (k_n, k_s)`
    /// (eq. 12): `λ = diag(k_n', k_s') (δ − δ_p)`. `(k_n, k_s)` for [`Elastic`].
    fn springs(&self, k: [f64; 2]) -> [f64; 2];
    /// Whether `λ = diag(k_n', k_s') δ` at every `δ`, with no state: only then does the model
    /// store no point for its interfaces (the evaluators' constant `K` is then the whole
    /// force).
    fn is_linear(&self) -> bool;
    /// The traction `(λ_n, λ_s)` (Pa) at the relative displacement `δ = (δ_n, δ_s)` (m) of a
    /// Gauss point in the state `point`, which it updates, on the interface's springs
    /// `k = (k_n', k_s')` ([`springs`](InterfaceLaw::springs) of its moduli): the plastic
    /// relative displacement `δ_p` with `λ = diag(k) (δ − δ_p)`, the law's internal variables,
    /// and the work dissipated, booked in [`LawPoint::fracture`] and [`LawPoint::friction`]
    /// (J/m²). Returns whether the point flowed. Called once per Gauss point and time step, in
    /// parallel, for the interfaces whose law is not linear. The default is a linear law's: no
    /// flow.
    #[inline]
    fn update(&self, k: [f64; 2], delta: [f64; 2], point: &mut LawPoint) -> ([f64; 2], bool) {
        (
            [
                k[0] * (delta[0] - point.p[0]),
                k[1] * (delta[1] - point.p[1]),
            ],
            false,
        )
    }
    /// A region where a point in the initial state ([`LawPoint::default`]) stays elastic, for
    /// a quick test before [`update`](InterfaceLaw::update): `Some([σ_max, c, tan φ])` says
    /// that at a trial traction `(σ, τ) = (k_n δ_n, k_s δ_s)` with `σ ≤ σ_max` and
    /// `|τ| ≤ c − σ tan φ` (a Mohr–Coulomb region inside the law's own, evaluated in that
    /// order of operations; a negative `tan φ` closes it in compression) `update` would not flow, so the steps leave it out there. `None`,
    /// the default, asks for `update` at every point.
    fn initial_region(&self) -> Option<[f64; 3]> {
        None
    }
    /// The tangent `dλ/dδ` (Pa/m) at `δ` in the state `point`, on the springs `k` as in
    /// [`update`](InterfaceLaw::update), row by row:
    /// `[[dλ_n/dδ_n, dλ_n/dδ_s], [dλ_s/dδ_n, dλ_s/dδ_s]]`, for a solver that needs it. The
    /// default is the springs' (exact for a linear law; the unloading tangent of a plastic one).
    fn tangent(&self, k: [f64; 2], _delta: [f64; 2], _point: &LawPoint) -> [[f64; 2]; 2] {
        [[k[0], 0.0], [0.0, k[1]]]
    }
    /// Whether the point carries no more than compression and friction: once both points of an
    /// interface are, and its elements have moved apart, it is handed over to contact
    /// (`force::failure`). Never, by default.
    fn is_broken(&self, _point: &LawPoint) -> bool {
        false
    }
    /// This law as the crate's [`Strength`], which the steps then return-map in line rather
    /// than through the seam; `None`, the default, for any other law.
    fn as_strength(&self) -> Option<&Strength> {
        None
    }
}

/// The state of one Gauss point of an interface whose law is not linear (two per interface,
/// owned by the run, `force::failure::FailureState`).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LawPoint {
    /// Plastic relative displacement `δ_p = (δ_p,n, δ_p,s)` (m):
    /// `λ = diag(k_n', k_s') (δ − δ_p)`.
    pub p: [f64; 2],
    /// The law's internal variables; for [`Strength`], the plastic opening and slip accumulated
    /// on the cut-off and the shear surface (m).
    pub kappa: [f64; 2],
    /// Work of the strength (tension and cohesion) per unit area (J/m²).
    pub fracture: f64,
    /// Work of friction per unit area (J/m²).
    pub friction: f64,
}

impl LawPoint {
    /// Closes the crack of a broken point (eq. 11 once its law's strength is spent) with its
    /// faces, which are `δ_n` apart while `δ_n ≥ 0` and touch where `δ_n < 0`: the plastic
    /// opening is kept at `δ_p,n ≤ max(δ_n, 0)`, at no work, so that the law's springs press
    /// the faces only once they touch, with `k_n δ_n`. Without it a crack that had opened by `w`
    /// would push back with `k_n (δ_n − w)` as soon as it began to close, its faces still `δ_n`
    /// apart. Returns whether `δ_p` moved.
    #[inline(always)]
    pub fn close_crack(&mut self, delta_n: f64) -> bool {
        let gap = delta_n.max(0.0);
        let moved = self.p[0] > gap;
        if moved {
            self.p[0] = gap;
        }
        moved
    }
}

/// Linear elastic springs (eqs. 11, 12): `λ = diag(k_n, k_s) δ`, the default law.
#[derive(Debug, Clone, Copy, Default)]
pub struct Elastic;

impl InterfaceLaw for Elastic {
    fn springs(&self, k: [f64; 2]) -> [f64; 2] {
        k
    }
    fn is_linear(&self) -> bool {
        true
    }
}

/// The strength of an interface that fails (eq. 11 beyond its elastic range): Mohr–Coulomb with
/// a tension cut-off, `σ ≤ f_t` and `|τ| ≤ c − σ tan φ` on the traction `(σ, τ) = (λ_n, λ_s)`
/// (compression negative), softening linearly with the plastic opening and slip until it is
/// exhausted (`paper_notes.md`, item 22).
///
/// Inside the surface the springs are elastic, `λ = diag(k_n, k_s) (δ − δ_p)`; on it the plastic
/// relative displacement `δ_p` grows. The flow is not associated and has no dilatancy: the
/// tension cut-off opens `δ_p,n`, the shear surface slides `δ_p,s`, so the return of each is
/// one division and the two do not interact (its [`InterfaceLaw::update`]). With fracture energies
/// `G_f`, `G_f,II` the strengths scale by `1 − ξ`, `ξ = κ_n / w_n + κ_s / w_s` (at most 1),
/// where `κ_n` and `κ_s` are the plastic opening and slip accumulated on the cut-off and on the
/// shear surface, and `w_n = 2 G_f / f_t`, `w_s = 2 G_f,II / c` the opening and slip at which
/// linear softening has spent `G_f` and `G_f,II` per unit area: written in displacement, the
/// dissipated energy does not depend on the element size. The law keeps `1 / w_n` and
/// `1 / w_s`, so that its return mapping multiplies where it would divide. An interface with
/// `ξ = 1` is broken: a crack, which keeps compression once its faces touch (`δ_n < 0`,
/// [`LawPoint::close_crack`]) and Coulomb friction, `|τ| ≤ −σ tan φ`, and nothing else.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Strength {
    /// Tensile strength `f_t` (Pa).
    pub f_t: f64,
    /// Cohesion `c` (Pa).
    pub c: f64,
    /// `tan φ` of the friction angle.
    pub tan_phi: f64,
    /// `1 / w_n` (1/m), with `w_n = 2 G_f / f_t` the plastic opening that exhausts the
    /// strength in tension: the share of it each metre of opening spends; 0 for perfect
    /// plasticity.
    pub per_w_n: f64,
    /// `1 / w_s` (1/m), with `w_s = 2 G_f,II / c` the plastic slip that exhausts it in shear; 0
    /// for perfect plasticity.
    pub per_w_s: f64,
}

impl Strength {
    /// The strength of a scene's law, `None` for an elastic one.
    pub fn from_spec(spec: &crate::input::scene::InterfaceLawSpec) -> Option<Strength> {
        let (s, energies) = spec.strength()?;
        // `1 / w` with `w = 2 G / strength`, the displacement that exhausts a strength.
        let per_w = |g: Option<f64>, strength: f64| match g {
            Some(g) if strength > 0.0 => strength / (2.0 * g),
            _ => 0.0,
        };
        Some(Strength {
            f_t: s.tensile_strength,
            c: s.cohesion,
            tan_phi: s.friction_angle.to_radians().tan(),
            per_w_n: per_w(energies.map(|e| e[0]), s.tensile_strength),
            per_w_s: per_w(energies.map(|e| e[1]), s.cohesion),
        })
    }

    /// The cut-off, lowered to the apex of the shear surface when that comes first (Pa).
    pub fn cap(&self) -> f64 {
        if self.tan_phi > 0.0 {
            self.f_t.min(self.c / self.tan_phi)
        } else {
            self.f_t
        }
    }

    /// The part of a plastic displacement `d` (m) along which a strength spent by `xi` softens
    /// at `per_w` (1/m), `min(d, (1 − ξ) w)`: all of it, or what exhausts the strength (none
    /// once it is exhausted).
    #[inline(always)]
    fn softening_part(d: f64, xi: f64, per_w: f64) -> f64 {
        if d * per_w > 1.0 - xi {
            (1.0 - xi) / per_w
        } else {
            d
        }
    }

    /// How much of the strength is spent, `ξ` in [0, 1].
    pub fn softening(&self, point: &LawPoint) -> f64 {
        (point.kappa[0] * self.per_w_n + point.kappa[1] * self.per_w_s).min(1.0)
    }
}

/// Mohr–Coulomb with cut-off and softening through the seam: the springs are the moduli, the
/// update is the return mapping.
impl InterfaceLaw for Strength {
    fn springs(&self, k: [f64; 2]) -> [f64; 2] {
        k
    }
    fn is_linear(&self) -> bool {
        false
    }
    /// Its own surface unsoftened: the cut-off `σ ≤ cap` and `|τ| ≤ c − σ tan φ`, which
    /// [`update`](InterfaceLaw::update) tests on a fresh point with the same operations.
    fn initial_region(&self) -> Option<[f64; 3]> {
        Some([self.cap(), self.c, self.tan_phi])
    }
    /// The return mapping at relative displacement `δ` with elastic springs `k` (Pa/m): the
    /// traction `(σ, τ)` (Pa), with the point's plastic displacement, softening and dissipated
    /// work updated. Backward Euler: the tension cut-off returns to the surface softened by its
    /// own plastic opening, then the shear surface to the one softened by both, so that the
    /// traction lies on the softening curve and the work booked is the work done; when an
    /// increment exhausts the strength, the traction returns to the broken surface instead.
    /// Where the softening is steeper than the spring (`k < f_t / w_n`, a snap-back at the
    /// point) the strength of the start of the update is used. An exhausted point is a crack
    /// that closes with its faces ([`LawPoint::close_crack`]): open, it carries nothing and
    /// dissipates nothing, its `δ_p` following `δ` with no return. Returns
    /// whether the point flowed. It divides in its two returns, by `k − slope` (or `k`), for the
    /// cut-off's apex `c / tan φ` in tension, and where an increment exhausts a strength; the
    /// rest multiplies.
    #[inline(always)]
    fn update(&self, k: [f64; 2], delta: [f64; 2], point: &mut LawPoint) -> ([f64; 2], bool) {
        // A point that has not flowed has spent nothing (and costs no division).
        let xi = if point.kappa == [0.0; 2] {
            0.0
        } else {
            self.softening(point)
        };
        // Exhausted: a crack, which closes with its faces.
        let closed = xi >= 1.0 && point.close_crack(delta[0]);
        let mut sigma = k[0] * (delta[0] - point.p[0]);
        if xi >= 1.0 && sigma >= 0.0 {
            // Exhausted and open: it carries nothing, `δ_p` follows `δ` (what the returns below
            // give, to round-off, with no division and no work).
            let dp = [delta[0] - point.p[0], delta[1] - point.p[1]];
            point.p = delta;
            point.kappa[0] += dp[0];
            point.kappa[1] += dp[1].abs();
            return ([0.0; 2], closed || dp != [0.0; 2]);
        }
        // The cut-off scales with `1 − ξ` and is not negative: compression never reaches it, so
        // its division is needed in tension only.
        let cap = if sigma > 0.0 { self.cap() } else { 0.0 };
        let mut dp_n = 0.0;
        let mut spent = xi;
        // The work of the flow: the area under the (linear) softening curve it followed, from
        // the surface at the start to the traction at the end.
        let mut work = 0.0;
        if sigma > 0.0 && sigma > cap * (1.0 - xi) {
            let slope = cap * self.per_w_n;
            dp_n = if k[0] > slope {
                (sigma - cap * (1.0 - xi)) / (k[0] - slope)
            } else {
                (sigma - cap * (1.0 - xi)) / k[0]
            };
            spent = (xi + dp_n * self.per_w_n).min(1.0);
            if spent >= 1.0 {
                dp_n = sigma / k[0];
            }
            sigma -= k[0] * dp_n;
            // The softening part of the opening, then none: a broken cut-off does no work.
            let softening = Self::softening_part(dp_n, xi, self.per_w_n);
            work += 0.5 * cap * (2.0 * (1.0 - xi) - softening * self.per_w_n) * softening;
        }
        let friction_limit = (-sigma * self.tan_phi).max(0.0);
        let limit = (self.c * (1.0 - spent) - sigma * self.tan_phi).max(0.0);
        let mut tau = k[1] * (delta[1] - point.p[1]);
        let mut dp_s = 0.0;
        if tau.abs() > limit {
            let slope = self.c * self.per_w_s;
            let mut slide = if k[1] > slope && limit > friction_limit {
                (tau.abs() - limit) / (k[1] - slope)
            } else {
                (tau.abs() - limit) / k[1]
            };
            if spent + slide * self.per_w_s >= 1.0 && self.c > 0.0 {
                slide = ((tau.abs() - friction_limit) / k[1]).max(0.0);
            }
            dp_s = slide.copysign(tau);
            tau -= k[1] * dp_s;
            // Friction over the whole slide; the cohesion, softening, over its part of it.
            let cohesion = |xi: f64| (self.c * (1.0 - xi) - sigma.max(0.0) * self.tan_phi).max(0.0);
            let softening = if self.c > 0.0 {
                Self::softening_part(slide, spent, self.per_w_s)
            } else {
                0.0
            };
            work += friction_limit * slide
                + 0.5 * (cohesion(spent) + cohesion(spent + softening * self.per_w_s)) * softening;
        }
        let flowed = dp_n != 0.0 || dp_s != 0.0;
        if flowed {
            point.p[0] += dp_n;
            point.p[1] += dp_s;
            point.kappa[0] += dp_n;
            point.kappa[1] += dp_s.abs();
            let friction = friction_limit * dp_s.abs();
            point.friction += friction;
            point.fracture += work - friction;
        }
        ([sigma, tau], flowed || closed)
    }
    /// Whether the point's strength is exhausted.
    fn is_broken(&self, point: &LawPoint) -> bool {
        self.softening(point) >= 1.0 && (self.f_t > 0.0 || self.c > 0.0)
    }
    fn as_strength(&self) -> Option<&Strength> {
        Some(self)
    }
}

//! The hopping block of the paper (§4; `validation/report.md` §8): a block dropped flat on rigid
//! ground,
//! the theory of its bounces, and a tracker that measures them from a run.

use crate::mesh::geometry::Vec2;
use crate::model::Model;

/// A rigid block of mass `m` on a contact spring `K_c = k_n B t`, dropped from height `H`
/// under gravity `g`, with no energy loss.
#[derive(Debug, Clone, Copy)]
pub struct Theory {
    /// Mass (kg).
    pub mass: f64,
    /// Contact stiffness `K_c` (N/m).
    pub stiffness: f64,
    /// Gravitational acceleration (m/s²).
    pub g: f64,
    /// Drop height of the lower face (m).
    pub height: f64,
}

impl Theory {
    /// Time of the first impact, `√(2H/g)` (s).
    pub fn impact_time(&self) -> f64 {
        (2.0 * self.height / self.g).sqrt()
    }

    /// Impact (and rebound) speed `√(2gH)` (m/s).
    pub fn impact_speed(&self) -> f64 {
        (2.0 * self.g * self.height).sqrt()
    }

    /// `ω = √(K_c/m)` (rad/s).
    pub fn omega(&self) -> f64 {
        (self.stiffness / self.mass).sqrt()
    }

    /// Contact time of the spring alone, `π/ω` (s).
    pub fn contact_time_without_gravity(&self) -> f64 {
        std::f64::consts::PI / self.omega()
    }

    /// Contact time with gravity: the spring oscillates about the static penetration
    /// `δ_s = mg/K_c` with amplitude `A = √(δ_s² + (v₀/ω)²)`, and the contact lasts
    /// `(π + 2 arcsin(δ_s/A)) / ω` (s).
    pub fn contact_time(&self) -> f64 {
        let w = self.omega();
        let ds = self.mass * self.g / self.stiffness;
        let a = (ds * ds + (self.impact_speed() / w).powi(2)).sqrt();
        (std::f64::consts::PI + 2.0 * (ds / a).asin()) / w
    }

    /// Period of one bounce, from impact to impact: flight `2√(2H/g)` plus contact (s).
    pub fn period(&self) -> f64 {
        2.0 * self.impact_time() + self.contact_time()
    }
}

/// One bounce as measured: contact from `impact` to `release`, then flight up to `apex`.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct Bounce {
    /// When the lowest point reached the ground (s), interpolated between steps.
    pub impact: f64,
    /// When it left the ground again (s).
    pub release: f64,
    /// Downward speed at impact and upward speed at release (m/s).
    pub impact_speed: f64,
    /// Upward speed at release (m/s).
    pub rebound_speed: f64,
    /// Highest lowest-point height of the flight that follows (m); `NaN` until it is reached.
    pub apex: f64,
}

/// Measures bounces from samples of the lowest point's height `y` and the body's vertical
/// velocity `v`, one sample per step; the ground is at `y = 0`.
#[derive(Debug, Clone, Default)]
pub struct Tracker {
    last: Option<(f64, f64, f64)>,
    /// Completed and current bounces.
    pub bounces: Vec<Bounce>,
    in_contact: bool,
}

impl Tracker {
    /// Adds the sample `(t, y, v)`.
    pub fn push(&mut self, t: f64, y: f64, v: f64) {
        if let Some((t0, y0, v0)) = self.last {
            // Linear interpolation to the crossing of y = 0.
            let cross = |a: f64, b: f64| (y0 / (y0 - y)).clamp(0.0, 1.0) * (b - a) + a;
            if !self.in_contact && y0 > 0.0 && y <= 0.0 {
                self.in_contact = true;
                self.bounces.push(Bounce {
                    impact: cross(t0, t),
                    impact_speed: -cross(v0, v),
                    apex: f64::NAN,
                    ..Default::default()
                });
            } else if self.in_contact && y0 <= 0.0 && y > 0.0 {
                self.in_contact = false;
                if let Some(b) = self.bounces.last_mut() {
                    b.release = cross(t0, t);
                    b.rebound_speed = cross(v0, v);
                }
            } else if !self.in_contact && y > 0.0 {
                if let Some(b) = self.bounces.last_mut() {
                    if b.release > 0.0 && !(b.apex >= y) {
                        b.apex = y;
                    }
                }
            }
        }
        self.last = Some((t, y, v));
    }
}

/// The height of the lowest mesh vertex of all bodies in state `u` (m), each element moved
/// with its finite rotation.
pub fn lowest_point(model: &Model, u: &[f64]) -> f64 {
    let nd = model.formulation.ndof();
    let mut low = f64::INFINITY;
    for body in &model.bodies {
        let mesh = &body.mesh;
        for e in &mesh.boundary {
            let el = body.first_element + e.cell as usize;
            let c = model.elements[el].props.centroid;
            for v in [e.v1, e.v2] {
                let x = model.formulation.current_position(
                    c,
                    &u[el * nd..(el + 1) * nd],
                    mesh.vertices[v as usize] - c,
                );
                low = low.min(x.y);
            }
        }
    }
    low
}

/// The velocity of the centre of mass of all bodies, from the element velocities `v` (m/s).
pub fn centre_velocity(model: &Model, v: &[f64]) -> Vec2 {
    let nd = model.formulation.ndof();
    let (mut p, mut m) = (Vec2::zeros(), 0.0);
    for (e, el) in model.elements.iter().enumerate() {
        let me = el.rho * el.props.area;
        p += me * Vec2::new(v[e * nd], v[e * nd + 1]);
        m += me;
    }
    p / m
}

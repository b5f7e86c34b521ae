//! External loads `P(t)`: gravity on every element and the scene's point and edge loads,
//! mapped to element DOFs by `N_eᵀ` (the right-hand side of eq. 7), with, for `rigid-poisson`,
//! the facet forces of the cells' pressures that the loads drive
//! ([`crate::model::poisson::Poisson::load_share`]).

use crate::mesh::geometry::Vec2;
use crate::model::formulation::Formulation;
use crate::model::poisson::Poisson;
use crate::model::{Amplitude, Model};

/// The loads of a model, ready for the time loop (no allocation per step).
#[derive(Debug, Clone)]
pub struct Loads {
    nd: usize,
    /// Gravity force per element, `ρ t A g` on `(u, v)`; empty without gravity.
    weight: Vec<Vec2>,
    /// Applied loads as `(dof, value, amplitude index)`; `usize::MAX` means constant.
    entries: Vec<(usize, f64, usize)>,
    amplitudes: Vec<Amplitude>,
}

impl Loads {
    /// Gravity and the applied loads of a model.
    pub fn new(model: &Model) -> Loads {
        let nd = model.formulation.ndof();
        let weight = if model.gravity == Vec2::zeros() {
            Vec::new()
        } else {
            model
                .elements
                .iter()
                .map(|e| model.gravity * (e.rho * model.thickness * e.props.area))
                .collect()
        };
        let mut entries = Vec::new();
        let mut amplitudes = Vec::new();
        // The cells' pressures that the loads drive (`rigid-poisson`).
        let poisson = (model.formulation == Formulation::RigidPoisson).then(|| Poisson::new(model));
        for l in &model.loads {
            let amp = match &l.amplitude {
                None => usize::MAX,
                Some(a) => {
                    amplitudes.push(a.clone());
                    amplitudes.len() - 1
                }
            };
            let d = l.point - model.elements[l.element as usize].props.centroid;
            let p = model.formulation.point_load(d, l.force, l.moment);
            for (k, v) in p.into_iter().enumerate() {
                if v != 0.0 {
                    entries.push((l.element as usize * nd + k, v, amp));
                }
            }
            if let Some(poisson) = &poisson {
                let share = poisson.load_share(model, l.element as usize, l.point, l.force);
                entries.extend(share.into_iter().map(|(d, v)| (d, v, amp)));
            }
        }
        Loads {
            nd,
            weight,
            entries,
            amplitudes,
        }
    }

    /// The load vector `P` over all DOFs with every load at its full value (amplitudes are
    /// time histories; a static analysis applies the loads as given).
    pub fn static_vector(&self, n: usize) -> Vec<f64> {
        let mut p = self.gravity_vector(n);
        for &(d, v, _) in &self.entries {
            p[d] += v;
        }
        p
    }

    /// Gravity's part of [`Loads::static_vector`]: the weights on the translations.
    pub fn gravity_vector(&self, n: usize) -> Vec<f64> {
        let mut p = vec![0.0; n];
        for (e, w) in self.weight.iter().enumerate() {
            p[e * self.nd] += w.x;
            p[e * self.nd + 1] += w.y;
        }
        p
    }

    /// The applied loads' part of [`Loads::static_vector`] (gravity left out).
    pub fn applied_vector(&self, n: usize) -> Vec<f64> {
        let mut p = vec![0.0; n];
        for &(d, v, _) in &self.entries {
            p[d] += v;
        }
        p
    }

    /// No loads and no gravity (free vibration).
    pub fn none(model: &Model) -> Loads {
        Loads {
            nd: model.formulation.ndof(),
            weight: Vec::new(),
            entries: Vec::new(),
            amplitudes: Vec::new(),
        }
    }

    fn factor(&self, amp: usize, t: f64) -> f64 {
        if amp == usize::MAX {
            1.0
        } else {
            self.amplitudes[amp].at(t)
        }
    }

    /// The elements that carry applied loads, in order, when `P` is zero elsewhere at all
    /// times; `None` with gravity, which loads every element.
    pub fn loaded_elements(&self) -> Option<Vec<u32>> {
        if !self.weight.is_empty() {
            return None;
        }
        let mut elements: Vec<u32> = self
            .entries
            .iter()
            .map(|&(d, _, _)| (d / self.nd) as u32)
            .collect();
        elements.sort_unstable();
        elements.dedup();
        Some(elements)
    }

    /// `f −= P(t)`.
    pub fn subtract(&self, t: f64, f: &mut [f64]) {
        for (e, w) in self.weight.iter().enumerate() {
            f[e * self.nd] -= w.x;
            f[e * self.nd + 1] -= w.y;
        }
        for &(d, v, a) in &self.entries {
            f[d] -= v * self.factor(a, t);
        }
    }

    /// Change in gravitational potential energy, `−Σ_e m_e g · (u_e, v_e)`.
    pub fn gravity_potential(&self, u: &[f64]) -> f64 {
        -self
            .weight
            .iter()
            .enumerate()
            .map(|(e, w)| w.x * u[e * self.nd] + w.y * u[e * self.nd + 1])
            .sum::<f64>()
    }

    /// Work of the applied loads over a step from `t` to `t + dt` with displacement increment
    /// `dt · v` (trapezoidal rule in time, exact for loads linear in time).
    /// `v(d)` is the velocity of DOF `d`.
    pub fn work_increment(&self, t: f64, dt: f64, v: impl Fn(usize) -> f64) -> f64 {
        self.entries
            .iter()
            .map(|&(d, val, a)| {
                0.5 * (self.factor(a, t) + self.factor(a, t + dt)) * val * dt * v(d)
            })
            .sum()
    }
}

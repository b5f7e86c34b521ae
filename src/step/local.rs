//! Local non-viscous damping (Cundall's, of the DEM codes PFC, UDEC and 3DEC): for quasi-static
//! runs, each free DOF's unbalanced force `F_i = P_i + f_c,i − f_int,i` is reduced by
//! `α |F_i|` against the sign of its velocity,
//!
//! `F_i ← F_i − α |F_i| sign(v_i^{n−½})`, `0 ≤ α < 1`,
//!
//! before the central-difference update (`scene.md`, *Quasi-static runs*). It takes the same
//! fraction of every mode's motion whatever its frequency, where mass-proportional damping
//! `C = α M` must be tuned to one: a quasi-static run can then be loaded faster and reach its
//! peak in fewer steps. It vanishes at equilibrium (`F = 0`), so the static solution is the
//! undamped one, and it is a force on the bodies that the energy books count: its work over a
//! step, `Δt Σ α |F_i| sign(v_i^{n−½}) v̄_i` with `v̄ = (v^{n−½} + v^{n+½}) / 2`, goes to the
//! damping's account. Clamped DOFs are left alone: their force is the clamp's reaction.

use crate::parallel::for_each_chunk_pair;

/// The local damping of a run: its coefficient, which DOFs it acts on, and its forces of the
/// step under way.
#[derive(Debug, Clone)]
pub struct LocalDamping {
    /// `α` in [0, 1).
    alpha: f64,
    /// Per DOF, 1 where it acts (free DOFs), 0 where it does not (fixed ones).
    free: Vec<f64>,
    /// `α |F_i| sign(v_i)` of the step under way (N, N m or N per strain): what it takes from
    /// each DOF's force.
    force: Vec<f64>,
}

impl LocalDamping {
    /// The local damping `alpha` of a model with `dofs` DOFs of which `fixed` are fixed; `None`
    /// for `alpha = 0`.
    pub fn new(alpha: f64, dofs: usize, fixed: &[usize]) -> Option<LocalDamping> {
        if alpha == 0.0 {
            return None;
        }
        let mut free = vec![1.0; dofs];
        for &d in fixed {
            free[d] = 0.0;
        }
        Some(LocalDamping {
            alpha,
            free,
            force: vec![0.0; dofs],
        })
    }

    /// Damps the net force `force` (`f_int − f_c − P`, minus the unbalanced force) of a state
    /// whose velocities are `v` (`v^{n−½}`): `force_i += α |force_i| sign(v_i)` at the free
    /// DOFs. No allocation.
    pub fn apply(&mut self, force: &mut [f64], v: &[f64]) {
        let (alpha, free) = (self.alpha, &self.free);
        for_each_chunk_pair(
            &mut self.force,
            force,
            crate::parallel::STREAM_CHUNK,
            |first, d, f| {
                let (v, free) = (&v[first..first + d.len()], &free[first..first + d.len()]);
                for (((d, f), v), free) in d.iter_mut().zip(f.iter_mut()).zip(v).zip(free) {
                    let sign = if *v > 0.0 {
                        1.0
                    } else if *v < 0.0 {
                        -1.0
                    } else {
                        0.0
                    };
                    *d = free * alpha * f.abs() * sign;
                    *f += *d;
                }
            },
        );
    }

    /// The work it did against the motion over the step (J, ≥ 0 to round-off but for a
    /// velocity that changed sign): `Δt Σ d_i (old_i + new_i) / 2` with `old = v^{n−½}` and
    /// `new = v^{n+½}`. Summed in DOF order, whatever the threads.
    pub fn work(&self, old: &[f64], new: &[f64], dt: f64) -> f64 {
        let sum: f64 = self
            .force
            .iter()
            .zip(old.iter().zip(new))
            .map(|(d, (a, b))| d * (a + b))
            .sum();
        0.5 * dt * sum
    }
}

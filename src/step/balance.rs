//! The unbalanced-force ratio of a run and its stop (`time.stop_ratio`), as the DEM codes
//! control a quasi-static run: at every check, the largest unbalanced force on a free
//! translation, `max_i |P_i + f_c,i − f_int,i|`, over the mean applied force, `mean |P_i|` over
//! the loaded free translations and the clamps' reactions on the fixed ones (all in N). A run
//! that has settled under its loads, the local damping's work done (`step::local`), has a small
//! ratio; the run stops at the first check below the scene's threshold.

use crate::model::loads::Loads;

/// The ratio's state: the free and the fixed translations, room for `P`, the last ratio.
#[derive(Debug, Clone)]
pub struct Balance {
    /// Stop below this ratio.
    tol: f64,
    /// The free translational DOFs (`u`, `v` of every element not fixed).
    free: Vec<u32>,
    /// The fixed translational DOFs, whose net force is a clamp's reaction.
    fixed: Vec<u32>,
    /// `−P(t)` of the check under way.
    load: Vec<f64>,
    /// The ratio at the last check; infinite before the first.
    ratio: f64,
}

impl Balance {
    /// The stop of a model with `dofs` DOFs, `nd` per element, of which `fixed` are fixed
    /// (sorted), at the ratio `tol`; `None` without one.
    pub fn new(tol: Option<f64>, nd: usize, dofs: usize, fixed: &[usize]) -> Option<Balance> {
        let tol = tol?;
        let (mut free, mut held) = (Vec::new(), Vec::new());
        for d in (0..dofs).filter(|d| d % nd < 2) {
            match fixed.binary_search(&d) {
                Ok(_) => held.push(d as u32),
                Err(_) => free.push(d as u32),
            }
        }
        Some(Balance {
            tol,
            free,
            fixed: held,
            load: vec![0.0; dofs],
            ratio: f64::INFINITY,
        })
    }

    /// The ratio of the check at time `t` from its net force `force` (`f_int − f_c − P`, minus
    /// the unbalanced force on the free DOFs and the reaction on the fixed ones): 0 when nothing
    /// is unbalanced, infinite when something is and no force is applied. No allocation.
    pub fn measure(&mut self, force: &[f64], loads: &Loads, t: f64) {
        self.load.fill(0.0);
        loads.subtract(t, &mut self.load);
        let (mut sum, mut count) = (0.0, 0usize);
        for (&d, source) in self
            .free
            .iter()
            .map(|d| (d, &self.load[..]))
            .chain(self.fixed.iter().map(|d| (d, force)))
        {
            let f = source[d as usize].abs();
            if f > 0.0 {
                sum += f;
                count += 1;
            }
        }
        let largest = self
            .free
            .iter()
            .map(|&d| force[d as usize].abs())
            .fold(0.0, f64::max);
        self.ratio = if largest == 0.0 {
            0.0
        } else {
            largest / (sum / count.max(1) as f64)
        };
    }

    /// The ratio at the last check.
    pub fn ratio(&self) -> f64 {
        self.ratio
    }

    /// Whether the last check's ratio is below the threshold.
    pub fn reached(&self) -> bool {
        self.ratio < self.tol
    }
}

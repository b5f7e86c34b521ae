//! The unbalanced-force ratio of a run and its stop (`time.stop_ratio`), as the DEM codes
//! control a quasi-static run: at every check, the largest unbalanced force on a free
//! translation, `max_i |P_i + f_c,i − f_int,i|`, over the mean internal force on them,
//! `mean_i |f_int,i|` (both in N). A run that has settled under its loads, the local damping's
//! work done (`step::local`), has a small ratio; the run stops at the first check below the
//! scene's threshold.

/// The ratio's state: the free translations, the last mean internal force and ratio.
#[derive(Debug, Clone)]
pub struct Balance {
    /// Stop below this ratio.
    tol: f64,
    /// The free translational DOFs (`u`, `v` of every element not fixed).
    free: Vec<u32>,
    /// `mean |f_int|` over them at the last check (N).
    internal: f64,
    /// The ratio at the last check; infinite before the first.
    ratio: f64,
}

impl Balance {
    /// The stop of a model with `dofs` DOFs, `nd` per element, of which `fixed` are fixed, at
    /// the ratio `tol`; `None` without one.
    pub fn new(tol: Option<f64>, nd: usize, dofs: usize, fixed: &[usize]) -> Option<Balance> {
        let tol = tol?;
        let mut free: Vec<u32> = (0..dofs).filter(|d| d % nd < 2).map(|d| d as u32).collect();
        free.retain(|d| fixed.binary_search(&(*d as usize)).is_err());
        Some(Balance {
            tol,
            free,
            internal: 0.0,
            ratio: f64::INFINITY,
        })
    }

    /// Takes `mean |f_int|` from `f_int`, the internal forces of the check under way.
    pub fn internal(&mut self, f_int: &[f64]) {
        let sum: f64 = self.free.iter().map(|&d| f_int[d as usize].abs()).sum();
        self.internal = sum / self.free.len().max(1) as f64;
    }

    /// The ratio of the check under way from its net force `force` (`f_int − f_c − P`, minus
    /// the unbalanced force): 0 when nothing is unbalanced, infinite when something is and no
    /// internal force acts.
    pub fn measure(&mut self, force: &[f64]) {
        let largest = self
            .free
            .iter()
            .map(|&d| force[d as usize].abs())
            .fold(0.0, f64::max);
        self.ratio = if largest == 0.0 {
            0.0
        } else {
            largest / self.internal
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

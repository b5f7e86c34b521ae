//! The critical time step of central difference, `Δt_crit = 2 / ω_max` (DESIGN.md §7), with
//! `ω_max²` the largest eigenvalue of `K φ = ω² M φ`, found by Lanczos on the operator
//! `M^{−½} K M^{−½}` applied through the evaluator (no matrix needed).

use crate::evaluator::Evaluator;
use crate::mass::Mass;
use rand::{Rng, SeedableRng};

/// The largest `ω` (rad/s) of `K φ = ω² M φ` over the free DOFs, by Lanczos iteration without
/// reorthogonalisation (which leaves the extreme Ritz value exact), stopped when the largest
/// Ritz value changes by less than `1e-10` relative, or after `max_iter` iterations. The
/// largest Ritz value never exceeds `ω_max²`, so the result converges from below.
pub fn omega_max(evaluator: &dyn Evaluator, mass: &Mass, n: usize, max_iter: usize) -> f64 {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut q: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
    // Project out the fixed DOFs (M^{−½} is zero there), then normalise.
    let mut tmp = vec![0.0; n];
    mass.inv_sqrt(&q, &mut tmp);
    for (q, t) in q.iter_mut().zip(&tmp) {
        if *t == 0.0 {
            *q = 0.0;
        }
    }
    let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm == 0.0 {
        return 0.0;
    }
    q.iter_mut().for_each(|x| *x /= norm);
    let (mut q_prev, mut w, mut ku) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    let mut last = 0.0;
    for j in 0..max_iter.min(n) {
        mass.inv_sqrt(&q, &mut tmp);
        evaluator.internal_force(&tmp, &mut ku);
        mass.inv_sqrt(&ku, &mut w);
        let b_prev = if j > 0 { beta[j - 1] } else { 0.0 };
        let a: f64 = w.iter().zip(&q).map(|(w, q)| w * q).sum();
        for i in 0..n {
            w[i] -= a * q[i] + b_prev * q_prev[i];
        }
        alpha.push(a);
        let b = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        let top = largest_tridiagonal_eigenvalue(&alpha, &beta);
        if (j >= 8 && (top - last).abs() <= 1e-10 * top) || b <= 1e-14 * top.abs() {
            return top.max(0.0).sqrt();
        }
        last = top;
        beta.push(b);
        std::mem::swap(&mut q_prev, &mut q);
        for i in 0..n {
            q[i] = w[i] / b;
        }
    }
    last.max(0.0).sqrt()
}

/// The largest eigenvalue of the symmetric tridiagonal matrix with diagonal `a` and
/// off-diagonal `b` (`b.len() ≥ a.len() − 1`), by Sturm-sequence bisection.
fn largest_tridiagonal_eigenvalue(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len();
    // Gershgorin interval.
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..n {
        let r = if i > 0 { b[i - 1].abs() } else { 0.0 } + if i + 1 < n { b[i].abs() } else { 0.0 };
        lo = lo.min(a[i] - r);
        hi = hi.max(a[i] + r);
    }
    // Number of eigenvalues below x.
    let count_below = |x: f64| {
        let mut d = 1.0;
        let mut count = 0;
        for i in 0..n {
            let off = if i > 0 { b[i - 1] * b[i - 1] } else { 0.0 };
            d = a[i] - x - if i > 0 { off / d } else { 0.0 };
            if d == 0.0 {
                d = f64::EPSILON * (x.abs() + 1.0);
            }
            if d < 0.0 {
                count += 1;
            }
        }
        count
    };
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if count_below(mid) >= n {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// `Δt_crit = 2 / ω_max` (s).
pub fn critical_time_step(omega_max: f64) -> f64 {
    2.0 / omega_max
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tridiagonal_top_eigenvalue_of_the_1d_laplacian() {
        // Diagonal 2, off-diagonal -1: eigenvalues 2 - 2 cos(kπ/(n+1)).
        let n = 50;
        let top = largest_tridiagonal_eigenvalue(&vec![2.0; n], &vec![-1.0; n - 1]);
        let exact = 2.0 - 2.0 * (n as f64 * std::f64::consts::PI / (n as f64 + 1.0)).cos();
        assert!((top - exact).abs() < 1e-12, "{top} {exact}");
    }
}

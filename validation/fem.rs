//! A small continuum reference for the validation suite: 8-node serendipity quadrilaterals
//! (Q8), plane stress, consistent mass, 3 × 3 Gauss, on a rectangle clamped on its left edge.
//! Dense generalised eigen solve: fine for the ~1000-DOF meshes used here.

use crate::q8::{self, Lattice};
use nalgebra::{DMatrix, SMatrix};

/// The lowest `k` circular frequencies (rad/s) of a cantilever `length × depth`, thickness `t`,
/// meshed with `nx × ny` Q8 elements, left edge clamped.
#[allow(clippy::too_many_arguments)] // the data of one FEM model
pub fn cantilever_frequencies(
    length: f64,
    depth: f64,
    t: f64,
    e: f64,
    nu: f64,
    rho: f64,
    nx: usize,
    ny: usize,
    k: usize,
) -> Vec<f64> {
    let mesh = Lattice::new(length, depth, nx, ny);
    let n = 2 * mesh.coords.len();
    let (mut kg, mut mg) = (DMatrix::<f64>::zeros(n, n), DMatrix::<f64>::zeros(n, n));
    let (ke, me) = q8::matrices(mesh.h, t, &q8::plane_stress(e, nu), rho);
    for ej in 0..ny {
        for ei in 0..nx {
            let nodes = mesh.element(ei, ej);
            for p in 0..16 {
                for q in 0..16 {
                    let (gp, gq) = (2 * nodes[p / 2] + p % 2, 2 * nodes[q / 2] + q % 2);
                    kg[(gp, gq)] += ke[(p, q)];
                    mg[(gp, gq)] += me[(p, q)];
                }
            }
        }
    }
    let free: Vec<usize> = (0..n)
        .filter(|&dof| mesh.coords[dof / 2].0 > 1e-12 * length)
        .collect();
    let kf = DMatrix::from_fn(free.len(), free.len(), |i, j| kg[(free[i], free[j])]);
    let mf = DMatrix::from_fn(free.len(), free.len(), |i, j| mg[(free[i], free[j])]);
    let l = mf
        .cholesky()
        .expect("the consistent mass is positive definite")
        .l();
    let li = l.try_inverse().expect("invertible factor");
    let a = &li * kf * li.transpose();
    let (values, _) = rbsm::analysis::eigen::symmetric_eigen(0.5 * (&a + a.transpose()));
    values.iter().take(k).map(|v| v.max(0.0).sqrt()).collect()
}

/// Static displacements of linear triangles (constant strain, plane stress) on the given
/// vertices and triangles: nodes with `x ≤ x_min + tol` clamped, a uniform traction `q`
/// (N/m², global) on the edges lying on `x = x_max`. Returns `(u, v)` per vertex.
pub fn cst_static(
    vertices: &[(f64, f64)],
    triangles: &[[usize; 3]],
    t: f64,
    e: f64,
    nu: f64,
    q: (f64, f64),
) -> Vec<(f64, f64)> {
    let n = 2 * vertices.len();
    let d = q8::plane_stress(e, nu);
    let mut k = DMatrix::<f64>::zeros(n, n);
    let mut f = nalgebra::DVector::<f64>::zeros(n);
    for tri in triangles {
        let p: Vec<(f64, f64)> = tri.iter().map(|&i| vertices[i]).collect();
        let area2 = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
        let mut b = SMatrix::<f64, 3, 6>::zeros();
        for a in 0..3 {
            let (j, k2) = ((a + 1) % 3, (a + 2) % 3);
            let (bx, by) = ((p[j].1 - p[k2].1) / area2, (p[k2].0 - p[j].0) / area2);
            b[(0, 2 * a)] = bx;
            b[(1, 2 * a + 1)] = by;
            b[(2, 2 * a)] = by;
            b[(2, 2 * a + 1)] = bx;
        }
        let ke = b.transpose() * d * b * (0.5 * area2 * t);
        for r in 0..6 {
            for c in 0..6 {
                k[(2 * tri[r / 2] + r % 2, 2 * tri[c / 2] + c % 2)] += ke[(r, c)];
            }
        }
    }
    let x_min = vertices.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let x_max = vertices
        .iter()
        .map(|p| p.0)
        .fold(f64::NEG_INFINITY, f64::max);
    let tol = 1e-9 * (x_max - x_min);
    for tri in triangles {
        for a in 0..3 {
            let (i, j) = (tri[a], tri[(a + 1) % 3]);
            if (vertices[i].0 - x_max).abs() <= tol && (vertices[j].0 - x_max).abs() <= tol {
                let len = (vertices[i].1 - vertices[j].1).abs();
                for node in [i, j] {
                    f[2 * node] += 0.5 * q.0 * len * t;
                    f[2 * node + 1] += 0.5 * q.1 * len * t;
                }
            }
        }
    }
    let free: Vec<usize> = (0..n)
        .filter(|&dof| vertices[dof / 2].0 > x_min + tol)
        .collect();
    let kf = DMatrix::from_fn(free.len(), free.len(), |i, j| k[(free[i], free[j])]);
    let ff = nalgebra::DVector::from_fn(free.len(), |i, _| f[free[i]]);
    let uf = kf
        .cholesky()
        .expect("a clamped CST model is positive definite")
        .solve(&ff);
    let mut u = vec![(0.0, 0.0); vertices.len()];
    for (i, &dof) in free.iter().enumerate() {
        if dof % 2 == 0 {
            u[dof / 2].0 = uf[i];
        } else {
            u[dof / 2].1 = uf[i];
        }
    }
    u
}

//! A small continuum reference for the validation suite: 8-node serendipity quadrilaterals
//! (Q8), plane stress, consistent mass, 3 × 3 Gauss, on a rectangle clamped on its left edge.
//! Dense generalised eigen solve: fine for the ~1000-DOF meshes used here.

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
    // Nodes on a (2nx+1) × (2ny+1) lattice, minus the element centres.
    let (cols, rows) = (2 * nx + 1, 2 * ny + 1);
    let mut id = vec![usize::MAX; cols * rows];
    let mut coords = Vec::new();
    for j in 0..rows {
        for i in 0..cols {
            if i % 2 == 1 && j % 2 == 1 {
                continue;
            }
            id[i + cols * j] = coords.len();
            coords.push((
                length * i as f64 / (cols - 1) as f64,
                depth * j as f64 / (rows - 1) as f64,
            ));
        }
    }
    let n = 2 * coords.len();
    let (mut kg, mut mg) = (DMatrix::<f64>::zeros(n, n), DMatrix::<f64>::zeros(n, n));
    let d = e / (1.0 - nu * nu)
        * SMatrix::<f64, 3, 3>::new(1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, 0.5 * (1.0 - nu));
    let (hx, hy) = (length / nx as f64, depth / ny as f64);
    let gauss = [-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()];
    let weight = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    // Serendipity nodes in natural coordinates, counter-clockwise from the lower-left corner.
    let nat = [
        (-1.0, -1.0),
        (1.0, -1.0),
        (1.0, 1.0),
        (-1.0, 1.0),
        (0.0, -1.0),
        (1.0, 0.0),
        (0.0, 1.0),
        (-1.0, 0.0),
    ];
    for ej in 0..ny {
        for ei in 0..nx {
            let (i0, j0) = (2 * ei, 2 * ej);
            let lattice = [
                (0, 0),
                (2, 0),
                (2, 2),
                (0, 2),
                (1, 0),
                (2, 1),
                (1, 2),
                (0, 1),
            ];
            let nodes: Vec<usize> = lattice
                .iter()
                .map(|&(a, b)| id[(i0 + a) + cols * (j0 + b)])
                .collect();
            let (mut ke, mut me) = (
                SMatrix::<f64, 16, 16>::zeros(),
                SMatrix::<f64, 16, 16>::zeros(),
            );
            for (gx, wx) in gauss.iter().zip(weight) {
                for (gy, wy) in gauss.iter().zip(weight) {
                    let (xi, eta) = (*gx, *gy);
                    let mut shape = [0.0; 8];
                    let mut dxi = [0.0; 8];
                    let mut deta = [0.0; 8];
                    for (a, &(s, r)) in nat.iter().enumerate() {
                        if a < 4 {
                            shape[a] =
                                0.25 * (1.0 + s * xi) * (1.0 + r * eta) * (s * xi + r * eta - 1.0);
                            dxi[a] = 0.25 * s * (1.0 + r * eta) * (2.0 * s * xi + r * eta);
                            deta[a] = 0.25 * r * (1.0 + s * xi) * (s * xi + 2.0 * r * eta);
                        } else if s == 0.0 {
                            shape[a] = 0.5 * (1.0 - xi * xi) * (1.0 + r * eta);
                            dxi[a] = -xi * (1.0 + r * eta);
                            deta[a] = 0.5 * r * (1.0 - xi * xi);
                        } else {
                            shape[a] = 0.5 * (1.0 + s * xi) * (1.0 - eta * eta);
                            dxi[a] = 0.5 * s * (1.0 - eta * eta);
                            deta[a] = -eta * (1.0 + s * xi);
                        }
                    }
                    // Rectangular element: x = x0 + (1 + ξ) hx/2, so d/dx = (2/hx) d/dξ.
                    let det = 0.25 * hx * hy;
                    let w = wx * wy * det * t;
                    let mut b = SMatrix::<f64, 3, 16>::zeros();
                    let mut nmat = SMatrix::<f64, 2, 16>::zeros();
                    for a in 0..8 {
                        let (dx, dy) = (2.0 / hx * dxi[a], 2.0 / hy * deta[a]);
                        b[(0, 2 * a)] = dx;
                        b[(1, 2 * a + 1)] = dy;
                        b[(2, 2 * a)] = dy;
                        b[(2, 2 * a + 1)] = dx;
                        nmat[(0, 2 * a)] = shape[a];
                        nmat[(1, 2 * a + 1)] = shape[a];
                    }
                    ke += w * b.transpose() * d * b;
                    me += (w * rho) * nmat.transpose() * nmat;
                }
            }
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
        .filter(|&dof| coords[dof / 2].0 > 1e-12 * length)
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
    let d = e / (1.0 - nu * nu)
        * SMatrix::<f64, 3, 3>::new(1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, 0.5 * (1.0 - nu));
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

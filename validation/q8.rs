//! 8-node serendipity quadrilaterals (Q8): the lattice of nodes of a rectangle cut into
//! `nx × ny` equal elements, the element matrices (3 × 3 Gauss) of its rectangles, and the
//! stiffness of an isoparametric element on mapped nodes, which the continuum references of the
//! validation share (`fem.rs`, `cohesive.rs`).
#![allow(dead_code)] // each example takes its part

use nalgebra::SMatrix;

/// The nodes of a `length × depth` rectangle's Q8 mesh: a `(2nx+1) × (2ny+1)` lattice of
/// half-element steps, minus the element centres.
pub struct Lattice {
    /// The element's size `(hx, hy)`.
    pub h: (f64, f64),
    cols: usize,
    id: Vec<usize>,
    /// Node coordinates.
    pub coords: Vec<(f64, f64)>,
}

impl Lattice {
    pub fn new(length: f64, depth: f64, nx: usize, ny: usize) -> Self {
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
        Lattice {
            h: (length / nx as f64, depth / ny as f64),
            cols,
            id,
            coords,
        }
    }

    /// The nodes of element `(ei, ej)`: the corners counter-clockwise from the lower left, then
    /// the mid-sides from the bottom one.
    pub fn element(&self, ei: usize, ej: usize) -> [usize; 8] {
        let (i0, j0) = (2 * ei, 2 * ej);
        [
            (0, 0),
            (2, 0),
            (2, 2),
            (0, 2),
            (1, 0),
            (2, 1),
            (1, 2),
            (0, 1),
        ]
        .map(|(a, b)| self.id[(i0 + a) + self.cols * (j0 + b)])
    }
}

/// The plane-stress elasticity matrix `D` (Voigt order `xx, yy, xy`).
pub fn plane_stress(e: f64, nu: f64) -> SMatrix<f64, 3, 3> {
    e / (1.0 - nu * nu)
        * SMatrix::<f64, 3, 3>::new(1.0, nu, 0.0, nu, 1.0, 0.0, 0.0, 0.0, 0.5 * (1.0 - nu))
}

/// The serendipity nodes in natural coordinates, in [`Lattice::element`]'s order.
const NATURAL: [(f64, f64); 8] = [
    (-1.0, -1.0),
    (1.0, -1.0),
    (1.0, 1.0),
    (-1.0, 1.0),
    (0.0, -1.0),
    (1.0, 0.0),
    (0.0, 1.0),
    (-1.0, 0.0),
];

/// The 3 × 3 Gauss points `(ξ, η)` and their weights.
fn gauss() -> impl Iterator<Item = ((f64, f64), f64)> {
    let points = [-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()];
    let weights = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    points.into_iter().zip(weights).flat_map(move |(xi, wx)| {
        points
            .into_iter()
            .zip(weights)
            .map(move |(eta, wy)| ((xi, eta), wx * wy))
    })
}

/// The shape functions at `(ξ, η)` and their derivatives in `ξ` and in `η`.
fn shapes(xi: f64, eta: f64) -> [[f64; 8]; 3] {
    let mut n = [[0.0; 8]; 3];
    for (a, &(s, r)) in NATURAL.iter().enumerate() {
        n[0][a] = if a < 4 {
            n[1][a] = 0.25 * s * (1.0 + r * eta) * (2.0 * s * xi + r * eta);
            n[2][a] = 0.25 * r * (1.0 + s * xi) * (s * xi + 2.0 * r * eta);
            0.25 * (1.0 + s * xi) * (1.0 + r * eta) * (s * xi + r * eta - 1.0)
        } else if s == 0.0 {
            n[1][a] = -xi * (1.0 + r * eta);
            n[2][a] = 0.5 * r * (1.0 - xi * xi);
            0.5 * (1.0 - xi * xi) * (1.0 + r * eta)
        } else {
            n[1][a] = 0.5 * s * (1.0 - eta * eta);
            n[2][a] = -eta * (1.0 + s * xi);
            0.5 * (1.0 + s * xi) * (1.0 - eta * eta)
        };
    }
    n
}

/// `B` (strains from the 16 DOFs) at a point whose shape derivatives in `x` and `y` are `dx`,
/// `dy`.
fn strains(dx: &[f64; 8], dy: &[f64; 8]) -> SMatrix<f64, 3, 16> {
    let mut b = SMatrix::<f64, 3, 16>::zeros();
    for a in 0..8 {
        b[(0, 2 * a)] = dx[a];
        b[(1, 2 * a + 1)] = dy[a];
        b[(2, 2 * a)] = dy[a];
        b[(2, 2 * a + 1)] = dx[a];
    }
    b
}

/// The stiffness and consistent mass of a rectangular Q8 element `hx × hy`, thickness `t`, DOFs
/// `(u, v)` per node in [`Lattice::element`]'s order.
pub fn matrices(
    (hx, hy): (f64, f64),
    t: f64,
    d: &SMatrix<f64, 3, 3>,
    rho: f64,
) -> (SMatrix<f64, 16, 16>, SMatrix<f64, 16, 16>) {
    let (mut ke, mut me) = (
        SMatrix::<f64, 16, 16>::zeros(),
        SMatrix::<f64, 16, 16>::zeros(),
    );
    for ((xi, eta), weight) in gauss() {
        let [shape, dxi, deta] = shapes(xi, eta);
        // Rectangular element: x = x0 + (1 + ξ) hx/2, so d/dx = (2/hx) d/dξ.
        let det = 0.25 * hx * hy;
        let w = weight * det * t;
        let b = strains(&dxi.map(|v| 2.0 / hx * v), &deta.map(|v| 2.0 / hy * v));
        let mut nmat = SMatrix::<f64, 2, 16>::zeros();
        for a in 0..8 {
            nmat[(0, 2 * a)] = shape[a];
            nmat[(1, 2 * a + 1)] = shape[a];
        }
        ke += w * b.transpose() * d * b;
        me += (w * rho) * nmat.transpose() * nmat;
    }
    (ke, me)
}

/// The stiffness and the area of an isoparametric Q8 element on the nodes `x` (curved sides
/// through their middle nodes), thickness `t`.
///
/// # Panics
/// If the element is folded (its Jacobian not positive at a Gauss point).
pub fn stiffness(
    x: &[(f64, f64); 8],
    t: f64,
    d: &SMatrix<f64, 3, 3>,
) -> (SMatrix<f64, 16, 16>, f64) {
    let (mut ke, mut area) = (SMatrix::<f64, 16, 16>::zeros(), 0.0);
    for ((xi, eta), weight) in gauss() {
        let [_, dxi, deta] = shapes(xi, eta);
        let sum = |dn: &[f64; 8], c: fn(&(f64, f64)) -> f64| {
            (0..8).map(|a| dn[a] * c(&x[a])).sum::<f64>()
        };
        let (j11, j12) = (sum(&dxi, |p| p.0), sum(&dxi, |p| p.1));
        let (j21, j22) = (sum(&deta, |p| p.0), sum(&deta, |p| p.1));
        let det = j11 * j22 - j12 * j21;
        assert!(det > 0.0, "a Q8 element is folded");
        // (d/dx, d/dy) = J⁻¹ (d/dξ, d/dη), J = [[x_ξ, y_ξ], [x_η, y_η]].
        let dx = std::array::from_fn(|a| (j22 * dxi[a] - j12 * deta[a]) / det);
        let dy = std::array::from_fn(|a| (-j21 * dxi[a] + j11 * deta[a]) / det);
        let b = strains(&dx, &dy);
        ke += (weight * det * t) * b.transpose() * d * b;
        area += weight * det;
    }
    (ke, area)
}

//! 8-node serendipity quadrilaterals (Q8) on a rectangle cut into `nx × ny` equal elements:
//! the lattice of nodes and the element matrices (3 × 3 Gauss) that the continuum references
//! of the validation share (`fem.rs`, `cohesive.rs`).

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

/// The stiffness and consistent mass of a rectangular Q8 element `hx × hy`, thickness `t`, DOFs
/// `(u, v)` per node in [`Lattice::element`]'s order.
pub fn matrices(
    (hx, hy): (f64, f64),
    t: f64,
    d: &SMatrix<f64, 3, 3>,
    rho: f64,
) -> (SMatrix<f64, 16, 16>, SMatrix<f64, 16, 16>) {
    let gauss = [-(0.6f64).sqrt(), 0.0, (0.6f64).sqrt()];
    let weight = [5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0];
    // Serendipity nodes in natural coordinates, in `Lattice::element`'s order.
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
    let (mut ke, mut me) = (
        SMatrix::<f64, 16, 16>::zeros(),
        SMatrix::<f64, 16, 16>::zeros(),
    );
    for (&xi, wx) in gauss.iter().zip(weight) {
        for (&eta, wy) in gauss.iter().zip(weight) {
            let mut shape = [0.0; 8];
            let mut dxi = [0.0; 8];
            let mut deta = [0.0; 8];
            for (a, &(s, r)) in nat.iter().enumerate() {
                if a < 4 {
                    shape[a] = 0.25 * (1.0 + s * xi) * (1.0 + r * eta) * (s * xi + r * eta - 1.0);
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
    (ke, me)
}

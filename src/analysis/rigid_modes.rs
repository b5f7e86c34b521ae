//! Free rigid motions (mechanisms): for each group of elements connected by interfaces, the
//! combinations of its two translations and its rotation that no support restrains and no
//! spring resists. A static solve refuses them by name; an eigen analysis expects them.

use crate::analysis::eigen::symmetric_eigen;
use crate::force::evaluator::Evaluator;
use crate::mesh::geometry::Vec2;
use crate::model::{Model, GROUND};
use nalgebra::DMatrix;

/// One free rigid motion of a group of elements.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeMode {
    /// Which elements move: a whole body, or a range of its elements.
    pub what: String,
    /// The index of their body in the scene.
    pub body: usize,
    /// The motion: a translation direction or a rotation centre.
    pub motion: Motion,
}

/// The shape of a free rigid motion.
#[derive(Debug, Clone, PartialEq)]
pub enum Motion {
    /// Translation along a unit direction.
    Translation(Vec2),
    /// Rotation about a point (m).
    Rotation(Vec2),
}

impl std::fmt::Display for FreeMode {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self.motion {
            Motion::Translation(d) => write!(
                f,
                "{} can translate along ({:.3}, {:.3})",
                self.what, d.x, d.y
            ),
            Motion::Rotation(p) => write!(
                f,
                "{} can rotate about ({:.4e}, {:.4e})",
                self.what, p.x, p.y
            ),
        }
    }
}

/// Groups of elements connected through interfaces (union–find), in element order.
fn components(model: &Model) -> Vec<Vec<usize>> {
    let n = model.elements.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for i in &model.interfaces {
        if i.b != GROUND {
            let (a, b) = (
                root(&mut parent, i.a as usize),
                root(&mut parent, i.b as usize),
            );
            parent[a.max(b)] = a.min(b);
        }
    }
    let mut groups: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for e in 0..n {
        let r = root(&mut parent, e);
        groups.entry(r).or_default().push(e);
    }
    groups.into_values().collect()
}

/// The free rigid motions of the model. For each connected group, the rigid motions
/// `R = [r_x, r_y, r_θ]` (rotation about the group's centroid, scaled by its size so that the
/// three columns are alike) are first restricted to those that keep every fixed DOF at zero;
/// the remaining ones whose energy `Rᵀ K R` vanishes (below 1e-10 of the stiffest diagonal
/// entry) are free.
pub fn free_modes(model: &Model, evaluator: &dyn Evaluator) -> Vec<FreeMode> {
    let nd = model.formulation.ndof();
    let n = model.n_dofs();
    let groups = components(model);
    let mut fixed = vec![false; n];
    for &d in &model.fixed {
        fixed[d] = true;
    }
    // The three rigid motions of every group at once: groups do not couple through K.
    let mut r = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    let mut frames = Vec::with_capacity(groups.len());
    for g in &groups {
        let area: f64 = g.iter().map(|&e| model.elements[e].props.area).sum();
        let c = g
            .iter()
            .map(|&e| model.elements[e].props.area * model.elements[e].props.centroid)
            .sum::<Vec2>()
            / area;
        let size = area.sqrt();
        for &e in g {
            let d = (model.elements[e].props.centroid - c) / size;
            r[0][e * nd] = 1.0;
            r[1][e * nd + 1] = 1.0;
            r[2][e * nd] = -d.y;
            r[2][e * nd + 1] = d.x;
            r[2][e * nd + 2] = 1.0 / size;
        }
        frames.push((c, size));
    }
    let mut kr = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    for j in 0..3 {
        evaluator.internal_force(&r[j], &mut kr[j]);
    }
    // The stiffest spring (N/m) sets the scale of Rᵀ K R (whose columns are displacements of
    // order one): K R itself vanishes for exactly the motions we look for.
    let scale = model
        .interfaces
        .iter()
        .map(|i| (i.k_n + i.k_s) * model.thickness * i.length)
        .fold(0.0, f64::max);
    let mut out = Vec::new();
    for (g, &(c, size)) in groups.iter().zip(&frames) {
        // Constraints C w = 0 from the fixed DOFs of the group.
        let mut cons: Vec<[f64; 3]> = Vec::new();
        let mut gram = [[0.0; 3]; 3];
        for &e in g {
            for k in e * nd..(e + 1) * nd {
                if fixed[k] {
                    cons.push([r[0][k], r[1][k], r[2][k]]);
                }
                for i in 0..3 {
                    for j in 0..3 {
                        gram[i][j] += r[i][k] * kr[j][k];
                    }
                }
            }
        }
        let basis = null_space(&cons);
        if basis.is_empty() {
            continue;
        }
        // Energy of the admissible motions: Zᵀ G Z, scaled.
        let z = DMatrix::<f64>::from_fn(3, basis.len(), |i, j| basis[j][i]);
        let gmat = DMatrix::<f64>::from_fn(3, 3, |i, j| {
            0.5 * (gram[i][j] + gram[j][i]) / scale.max(f64::MIN_POSITIVE)
        });
        let (values, vectors) = symmetric_eigen(z.transpose() * &gmat * &z);
        let free: Vec<[f64; 3]> = (0..basis.len())
            .filter(|&j| values[j].abs() <= 1e-10)
            .map(|j| {
                let w = &z * vectors.column(j);
                [w[0], w[1], w[2]]
            })
            .collect();
        for w in named_basis(&free) {
            let theta = w[2] / size;
            let motion = if theta.abs() < 1e-8 * (w[0].hypot(w[1])) {
                let d = Vec2::new(w[0], w[1]).normalize();
                Motion::Translation(if d.x < -1e-12 || (d.x.abs() <= 1e-12 && d.y < 0.0) {
                    -d
                } else {
                    d
                })
            } else {
                Motion::Rotation(Vec2::new(c.x - w[1] / theta, c.y + w[0] / theta))
            };
            out.push(FreeMode {
                what: describe(model, g),
                body: model.elements[g[0]].body as usize,
                motion,
            });
        }
    }
    out
}

/// An orthonormal basis of the free rigid motions spanned by the orthonormal `free` (in the
/// coordinates `[t_x, t_y, θ·size]` about the group's centroid) that names them: its
/// translations first (along x and y when both are free), then the one motion orthogonal to
/// them, a rotation (about the centroid when the translations are both free). The eigenvectors
/// of a degenerate energy are an arbitrary basis of the same space, each mixing translation
/// and rotation.
fn named_basis(free: &[[f64; 3]]) -> Vec<[f64; 3]> {
    // The rotation parts `r`: the free motions `Σ a_j free_j` with `r · a = 0` translate.
    let r: Vec<f64> = free.iter().map(|w| w[2]).collect();
    let norm = r.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm < 1e-8 {
        // Pure translations (the null space is orthonormal, so at most two of them).
        return match free.len() {
            2 => vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            _ => free.to_vec(),
        };
    }
    let combine = |a: &[f64]| -> [f64; 3] {
        let mut w = [0.0; 3];
        for (x, f) in a.iter().zip(free) {
            for i in 0..3 {
                w[i] += x * f[i];
            }
        }
        w
    };
    // The rotation: the free motion along `r`, orthogonal to every translation.
    let rotation = combine(&r.iter().map(|x| x / norm).collect::<Vec<_>>());
    let mut out = match free.len() {
        // Two translations: the whole plane of them.
        3 => vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        // One: the free motion orthogonal to `r`.
        2 => vec![combine(&[-r[1] / norm, r[0] / norm])],
        _ => Vec::new(),
    };
    out.push(rotation);
    out
}

/// An orthonormal basis (3-vectors) of `{w : C w = 0}`.
fn null_space(cons: &[[f64; 3]]) -> Vec<[f64; 3]> {
    if cons.is_empty() {
        return vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    }
    // Eigenvectors of CᵀC with (relatively) zero eigenvalues.
    let mut ctc = DMatrix::<f64>::zeros(3, 3);
    for row in cons {
        for i in 0..3 {
            for j in 0..3 {
                ctc[(i, j)] += row[i] * row[j];
            }
        }
    }
    let top = (0..3).map(|i| ctc[(i, i)]).fold(0.0, f64::max);
    let (values, vectors) = symmetric_eigen(ctc);
    (0..3)
        .filter(|&j| values[j] <= 1e-12 * top)
        .map(|j| [vectors[(0, j)], vectors[(1, j)], vectors[(2, j)]])
        .collect()
}

fn describe(model: &Model, group: &[usize]) -> String {
    let body = &model.bodies[model.elements[group[0]].body as usize];
    if group.len() == body.mesh.n_cells() {
        format!("body `{}`", body.name)
    } else if group.len() == 1 {
        format!("element {} of body `{}`", group[0], body.name)
    } else {
        format!(
            "{} elements of body `{}` ({} to {})",
            group.len(),
            body.name,
            group[0],
            group[group.len() - 1]
        )
    }
}

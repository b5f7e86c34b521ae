//! Continuum references for the fracture benchmarks of `calibrated` and `splitting`:
//! Hillerborg's fictitious (cohesive) crack on a straight path through an elastic body, solved
//! by Petersson's influence method. The crack's faces carry `σ(w) = f_t e^{−f_t w / G_F}` (the
//! facet law's softening in pure opening, rigid before `f_t`), lumped to the path's nodes with
//! the edges' Simpson weights. The body, cut into Q8 plane-stress elements, is condensed onto
//! the normal displacement `u` of the path's nodes and one load parameter `p` (a force, or a
//! prescribed displacement): a small dense problem, solved at each value of a controlling
//! opening by Newton's method on the set of open nodes, which is updated until no closed node
//! carries more than `f_t` and no open one overlaps.
//!
//! - [`load_cmod`]: the notched beam in three-point bending (the half beam, mirror symmetry at
//!   mid-span, square elements; `p` the load, a pressure; the crack mouth opening controls).
//! - [`split_load`]: the Brazilian disk between bonded rigid strips (a quarter disk, symmetric
//!   about both diameters, mapped elements; `p` the strip's travel; the opening at the centre
//!   controls).
#![allow(dead_code)] // each example takes its benchmark

use crate::q8::{self, Lattice};
use faer::linalg::solvers::Solve as _;
use faer::sparse::{SparseColMat, Triplet};
use nalgebra::{DMatrix, DVector, SMatrix};

/// A notched beam in three-point bending (SI units).
pub struct Beam {
    pub length: f64,
    pub span: f64,
    pub depth: f64,
    /// The notch's depth from the bottom face, at mid-span.
    pub notch: f64,
    pub thickness: f64,
    pub e: f64,
    pub nu: f64,
    pub f_t: f64,
    pub g_f: f64,
    /// The width of each support (0: a point): it holds `v` over it.
    pub support_width: f64,
    /// The width of the load: a uniform pressure over it.
    pub load_width: f64,
    /// The CMOD is the opening between the points of the bottom face this far either side of
    /// the notch.
    pub gauge: f64,
}

/// The load (N) at each crack mouth opening of `cmods` (m, increasing from zero), on elements
/// `h` (m) square: `h` must divide the half length, the depth, the notch, the support's place,
/// the gauge and half the widths of the supports and of the load.
pub fn load_cmod(beam: &Beam, h: f64, cmods: &[f64]) -> Vec<f64> {
    assert!(
        beam.load_width > 0.0,
        "the load is a pressure over a width > 0"
    );
    let half = 0.5 * beam.length;
    let (nx, ny) = (
        (half / h).round() as usize,
        (beam.depth / h).round() as usize,
    );
    let mesh = Lattice::new(half, beam.depth, nx, ny);
    let tol = 1e-6 * h;
    let on = |a: f64, b: f64| (a - b).abs() <= tol;
    let support = 0.5 * (beam.length - beam.span);
    for (what, x) in [
        ("half the length", half),
        ("the depth", beam.depth),
        ("the notch", beam.notch),
        ("the support's place", support),
        ("the gauge", beam.gauge),
        ("half the support", 0.5 * beam.support_width),
        ("half the load", 0.5 * beam.load_width),
    ] {
        assert!(on(x / h, (x / h).round()), "h = {h} must divide {what}");
    }
    // The ligament's nodes from the notch tip up, and the DOFs the model holds: `u` on the
    // ligament (the crack), `v` on the support.
    let ligament = path(&mesh.coords, |(x, y)| on(x, half) && y >= beam.notch - tol);
    let mut place = vec![Place::Free(0); 2 * mesh.coords.len()];
    for (k, &node) in ligament.iter().enumerate() {
        place[2 * node] = Place::Path(k);
    }
    for (i, c) in mesh.coords.iter().enumerate() {
        if on(c.1, 0.0) && (c.0 - support).abs() <= 0.5 * beam.support_width + tol {
            place[2 * i + 1] = Place::Held;
        }
    }
    // The crack's tributary areas; the load, half of a unit load on the half beam, spread over
    // half the patch.
    let (hx, hy) = mesh.h;
    let mut area = vec![0.0; ligament.len()];
    let mut load = vec![0.0; place.len()];
    let (ke, _) = q8::matrices(
        mesh.h,
        beam.thickness,
        &q8::plane_stress(beam.e, beam.nu),
        0.0,
    );
    let mut elements = Vec::with_capacity(nx * ny);
    for ej in 0..ny {
        for ei in 0..nx {
            let nodes = mesh.element(ei, ej);
            if ei == nx - 1 && mesh.coords[nodes[1]].1 >= beam.notch - tol {
                // The right edge (corners 1, 2, middle 5) lies on the ligament.
                lump(
                    &place,
                    [nodes[1], nodes[2], nodes[5]],
                    hy * beam.thickness,
                    &mut area,
                );
            }
            if ej == ny - 1 && mesh.coords[nodes[3]].0 >= half - 0.5 * beam.load_width - tol {
                // The top edge (corners 3, 2, middle 6) is under the load.
                for (node, w) in [nodes[3], nodes[2], nodes[6]].into_iter().zip(SIMPSON) {
                    load[2 * node + 1] -= w * hx * 0.5 / (0.5 * beam.load_width);
                }
            }
            elements.push((nodes, ke));
        }
    }
    let gauge = (0..mesh.coords.len())
        .find(|&i| on(mesh.coords[i].0, half - beam.gauge) && on(mesh.coords[i].1, 0.0))
        .expect("the gauge point is a node");
    let body = condense(&elements, &mut place, &load, 2 * gauge);
    let crack = Crack {
        body: &body,
        area,
        f_t: beam.f_t,
        g_f: beam.g_f,
        side: -1.0,
    };
    crack
        .follow(cmods, vec![false; ligament.len()], |_, _| false)
        .into_iter()
        .map(|(_, p)| p)
        .collect()
}

/// A Brazilian disk pressed between two bonded rigid strips on a diameter (SI units).
pub struct Disk {
    pub diameter: f64,
    pub thickness: f64,
    pub e: f64,
    pub nu: f64,
    pub f_t: f64,
    pub g_f: f64,
    /// The strips' width, each centred on the loaded diameter: the strip holds the arc within
    /// half of it of that diameter, in both directions.
    pub strip: f64,
    /// A rigid block under each strip, if any: as wide as the strip, from the arc down to
    /// this distance (m) from the centre. A clamp that holds whole cells holds such a block.
    pub block: Option<f64>,
}

impl Disk {
    /// Its material's characteristic length `E G_F / f_t²` (m).
    pub fn l_ch(&self) -> f64 {
        self.e * self.g_f / (self.f_t * self.f_t)
    }
}

/// The disk's elements (a quarter, `n × n`) and its strips' load at each opening of
/// `openings` (m, increasing from zero) of the crack at the disk's centre: the load `P` (N) on
/// each strip, which the opening there follows from first cracking, up to the first load at
/// which `stop` holds. Also returns the quarter's area over `π D²/16`, a check of its mapped
/// elements.
pub fn split_load(
    disk: &Disk,
    n: usize,
    openings: &[f64],
    mut stop: impl FnMut(f64) -> bool,
) -> (Vec<f64>, f64) {
    let r = 0.5 * disk.diameter;
    // The unit square `(ξ, η)` onto the quarter disk `x, y ≥ 0`: `ξ` stretched so that the
    // strip's end falls on the column of nodes `m / n`, then the square-to-disc map
    // `(r u √(1 − v²/2), r v √(1 − u²/2))`, which takes the sides `u = 1` and `v = 1` to the
    // arc (the top side's `x = r u / √2`) and the sides `u = 0`, `v = 0` to the radii.
    let u_end = disk.strip / (2f64.sqrt() * r);
    assert!(
        u_end > 0.0 && u_end < 1.0,
        "the strip is narrower than the disk"
    );
    let m = ((u_end * n as f64).round() as usize).clamp(1, n - 1);
    let s = m as f64 / n as f64;
    let map = |(xi, eta): (f64, f64)| {
        let u = if xi <= s {
            u_end * xi / s
        } else {
            u_end + (1.0 - u_end) * (xi - s) / (1.0 - s)
        };
        (
            r * u * (1.0 - 0.5 * eta * eta).sqrt(),
            r * eta * (1.0 - 0.5 * u * u).sqrt(),
        )
    };
    let lattice = Lattice::new(1.0, 1.0, n, n);
    let tol = 1e-9;
    let coords: Vec<(f64, f64)> = lattice.coords.iter().map(|&c| map(c)).collect();
    // The crack's path: the loaded diameter from the centre up, less the nodes the strip (and
    // its block) holds. Symmetry: `v` held on the other diameter; the strip: `u` held, `v = −p`.
    let on_strip = |(xi, eta): (f64, f64)| {
        let in_block = disk.block.is_some_and(|y| {
            let (x, at) = map((xi, eta));
            x <= 0.5 * disk.strip * (1.0 + tol) && at >= y
        });
        (eta >= 1.0 - tol && xi <= s + tol) || in_block
    };
    let crack = path(&lattice.coords, |c| c.0 <= tol && !on_strip(c));
    let mut place = vec![Place::Free(0); 2 * coords.len()];
    for (k, &node) in crack.iter().enumerate() {
        place[2 * node] = Place::Path(k);
    }
    for (i, &c) in lattice.coords.iter().enumerate() {
        if c.1 <= tol {
            place[2 * i + 1] = Place::Held;
        }
        if on_strip(c) {
            place[2 * i] = Place::Held;
            place[2 * i + 1] = Place::Driven(-1.0);
        }
    }
    let d = q8::plane_stress(disk.e, disk.nu);
    let mut area = vec![0.0; crack.len()];
    let mut quarter = 0.0;
    let mut elements = Vec::with_capacity(n * n);
    for ej in 0..n {
        for ei in 0..n {
            let nodes = lattice.element(ei, ej);
            let (ke, a) = q8::stiffness(&nodes.map(|k| coords[k]), disk.thickness, &d);
            quarter += a;
            if ei == 0 {
                // The left edge (corners 0, 3, middle 7) lies on the diameter, straight and
                // `r / n` long.
                lump(
                    &place,
                    [nodes[0], nodes[3], nodes[7]],
                    r / n as f64 * disk.thickness,
                    &mut area,
                );
            }
            elements.push((nodes, ke));
        }
    }
    let unloaded = vec![0.0; place.len()];
    let body = condense(&elements, &mut place, &unloaded, 2 * crack[0]);
    let crack = Crack {
        body: &body,
        area,
        f_t: disk.f_t,
        g_f: disk.g_f,
        side: 1.0,
    };
    // The centre opens first: the opening there is what the steps prescribe.
    let mut open = vec![false; crack.area.len()];
    open[0] = true;
    let load = |u: &DVector<f64>, p: f64| 2.0 * (body.c.dot(u) + body.d * p);
    let loads = crack
        .follow(openings, open, |u, p| stop(load(u, p)))
        .into_iter()
        .map(|(u, p)| load(&u, p))
        .collect();
    (loads, quarter / (0.25 * std::f64::consts::PI * r * r))
}

/// Simpson's weights on a Q8 edge: its corners 1/6, its middle 2/3.
const SIMPSON: [f64; 3] = [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0];

/// The nodes for which `on` holds, in order along the path they lie on (by `y`).
fn path(coords: &[(f64, f64)], on: impl Fn((f64, f64)) -> bool) -> Vec<usize> {
    let mut nodes: Vec<usize> = (0..coords.len()).filter(|&i| on(coords[i])).collect();
    nodes.sort_by(|&a, &b| coords[a].1.total_cmp(&coords[b].1));
    nodes
}

/// Adds to `area` the tributary areas of an edge of the crack's path (its corners, then its
/// middle) whose length times the thickness is `length`; a node the model holds (the disk's
/// under its strip) takes none.
fn lump(place: &[Place], edge: [usize; 3], length: f64, area: &mut [f64]) {
    for (node, w) in edge.into_iter().zip(SIMPSON) {
        if let Place::Path(k) = place[2 * node] {
            area[k] += w * length;
        }
    }
}

/// What the model does with a DOF.
#[derive(Clone, Copy)]
enum Place {
    /// Free: its index among the free DOFs.
    Free(usize),
    /// Its displacement normal to the crack's path: its index there.
    Path(usize),
    /// Held at zero (a support, a symmetry).
    Held,
    /// Prescribed at this multiple of `p`.
    Driven(f64),
}

/// A body condensed onto its crack's path and its load parameter `p`, linear in `(u, p)`.
struct Condensed {
    /// `r = k u + b p`: the forces the path's nodes need.
    k: DMatrix<f64>,
    b: DVector<f64>,
    /// `a·u + g p`: the gauge's displacement.
    a: DVector<f64>,
    g: f64,
    /// `c·u + d p`: the reaction along the driven DOFs, `Σ s f` over those prescribed at `s p`.
    c: DVector<f64>,
    d: f64,
}

/// `elements` (their nodes and stiffness) condensed, with `load` the forces of `p = 1` on the
/// DOFs (on free ones alone) and `gauge` a DOF, free or on the path; numbers the free DOFs of
/// `place`.
fn condense(
    elements: &[([usize; 8], SMatrix<f64, 16, 16>)],
    place: &mut [Place],
    load: &[f64],
    gauge: usize,
) -> Condensed {
    let mut nf = 0;
    for p in place.iter_mut() {
        if let Place::Free(f) = p {
            *f = nf;
            nf += 1;
        }
    }
    let nl = place.iter().filter(|p| matches!(p, Place::Path(_))).count();
    // K_ff; the path's rows K_lf, its block K_ll; what `p` does to the free DOFs, the path and
    // the driven DOFs' reaction.
    let mut kff = Vec::new();
    let mut klf: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nl];
    let mut k = DMatrix::<f64>::zeros(nl, nl);
    let mut b = DVector::<f64>::zeros(nl);
    let mut rhs = vec![0.0; nf];
    let (mut on_free, mut c, mut d) = (vec![0.0; nf], DVector::<f64>::zeros(nl), 0.0);
    for (dof, &f) in load.iter().enumerate() {
        if let Place::Free(i) = place[dof] {
            rhs[i] += f;
        }
    }
    for (nodes, ke) in elements {
        let dof = |p: usize| 2 * nodes[p / 2] + p % 2;
        for p in 0..16 {
            for q in 0..16 {
                let v = ke[(p, q)];
                match (place[dof(p)], place[dof(q)]) {
                    (Place::Free(i), Place::Free(j)) => kff.push(Triplet::new(i, j, v)),
                    (Place::Free(i), Place::Driven(s)) => rhs[i] -= v * s,
                    (Place::Path(i), Place::Free(j)) => klf[i].push((j, v)),
                    (Place::Path(i), Place::Path(j)) => k[(i, j)] += v,
                    (Place::Path(i), Place::Driven(s)) => b[i] += v * s,
                    (Place::Driven(s), Place::Free(j)) => on_free[j] += s * v,
                    (Place::Driven(s), Place::Path(j)) => c[j] += s * v,
                    (Place::Driven(s), Place::Driven(t)) => d += s * v * t,
                    _ => {}
                }
            }
        }
    }
    let kff = SparseColMat::try_new_from_triplets(nf, nf, &kff).unwrap();
    let llt = kff
        .sp_cholesky(faer::Side::Lower)
        .expect("the body held on its path and supports is positive definite");
    // The free DOFs for a unit `u` at each node of the path (columns 0..nl) and for `p = 1`.
    let mut x = faer::Mat::<f64>::zeros(nf, nl + 1);
    for (i, row) in klf.iter().enumerate() {
        for &(f, v) in row {
            x[(f, i)] -= v;
        }
    }
    for (f, &v) in rhs.iter().enumerate() {
        x[(f, nl)] = v;
    }
    llt.solve_in_place(x.as_mut());
    for (i, row) in klf.iter().enumerate() {
        for &(f, v) in row {
            for j in 0..nl {
                k[(i, j)] += v * x[(f, j)];
            }
            b[i] += v * x[(f, nl)];
        }
    }
    for (f, &s) in on_free.iter().enumerate() {
        for j in 0..nl {
            c[j] += s * x[(f, j)];
        }
        d += s * x[(f, nl)];
    }
    let (a, g) = match place[gauge] {
        Place::Free(f) => (DVector::from_fn(nl, |j, _| x[(f, j)]), x[(f, nl)]),
        Place::Path(i) => (DVector::from_fn(nl, |j, _| f64::from(j == i)), 0.0),
        _ => panic!("the gauge is a free DOF or on the path"),
    };
    Condensed { k, b, a, g, c, d }
}

/// A cohesive crack on the path of a condensed body.
struct Crack<'a> {
    body: &'a Condensed,
    /// Each node's tributary area (m²).
    area: Vec<f64>,
    f_t: f64,
    g_f: f64,
    /// The side of the path the body lies on, along `u`: its crack opens by `w = 2 side u`
    /// (the other half mirrors it) and closes on `u = 0`.
    side: f64,
}

impl Crack<'_> {
    /// `(u, p)` at each gauge opening `2 side (a·u + g p)` of `controls`, from the set of open
    /// nodes `open`, up to the first at which `stop` holds.
    fn follow(
        &self,
        controls: &[f64],
        mut open: Vec<bool>,
        mut stop: impl FnMut(&DVector<f64>, f64) -> bool,
    ) -> Vec<(DVector<f64>, f64)> {
        let Condensed { k, b, a, g, .. } = self.body;
        let (nl, side, f_t, g_f) = (self.area.len(), self.side, self.f_t, self.g_f);
        let sigma = |w: f64| f_t * (-f_t * w / g_f).exp();
        let mut z = DVector::<f64>::zeros(nl + 1); // u on the path, then p
        let mut states = Vec::with_capacity(controls.len());
        for &control in controls {
            for round in 0.. {
                assert!(
                    round <= 2 * nl,
                    "the crack's open set cycles at an opening of {control} m"
                );
                let (mut converged, mut last) = (false, f64::INFINITY);
                for _ in 0..100 {
                    let (u, p) = (z.rows(0, nl), z[nl]);
                    let r = k * u + b * p;
                    let mut res = DVector::<f64>::zeros(nl + 1);
                    let mut jac = DMatrix::<f64>::zeros(nl + 1, nl + 1);
                    for i in 0..nl {
                        if open[i] {
                            // The crack's force on the node, `−side A σ(w)`, is what it needs.
                            let s = sigma(2.0 * side * u[i]);
                            res[i] = r[i] + side * self.area[i] * s;
                            jac.row_mut(i).columns_mut(0, nl).copy_from(&k.row(i));
                            jac[(i, i)] -= 2.0 * self.area[i] * f_t / g_f * s;
                            jac[(i, nl)] = b[i];
                        } else {
                            res[i] = u[i];
                            jac[(i, i)] = 1.0;
                        }
                    }
                    res[nl] = 2.0 * side * (a.dot(&u) + g * p) - control;
                    jac.row_mut(nl)
                        .columns_mut(0, nl)
                        .copy_from(&(2.0 * side * a.transpose()));
                    jac[(nl, nl)] = 2.0 * side * g;
                    let step = jac
                        .lu()
                        .solve(&res)
                        .expect("the crack's Jacobian is regular");
                    z -= &step;
                    // Converged, or stalled on round-off near it (a disk large against `l_ch`).
                    let (du, scale) = (step.rows(0, nl).amax(), z.rows(0, nl).amax().max(1e-12));
                    if (du <= 1e-13 * scale || (du <= 1e-9 * scale && du >= 0.5 * last))
                        && step[nl].abs() <= 1e-12 * z[nl].abs().max(1.0)
                    {
                        converged = true;
                        break;
                    }
                    last = du;
                }
                assert!(
                    converged,
                    "Newton's method did not converge at an opening of {control} m (path of {nl} \
                     nodes, step {last:e} of {:e})",
                    z.rows(0, nl).amax()
                );
                let (u, p) = (z.rows(0, nl), z[nl]);
                let r = k * u + b * p;
                let mut changed = false;
                for i in 0..nl {
                    if open[i] && side * u[i] < 0.0 {
                        open[i] = false;
                        changed = true;
                    } else if !open[i] && -side * r[i] > self.area[i] * f_t * (1.0 + 1e-9) {
                        open[i] = true;
                        changed = true;
                    }
                }
                if !changed {
                    break;
                }
            }
            let u = z.rows(0, nl).into_owned();
            let done = stop(&u, z[nl]);
            states.push((u, z[nl]));
            if done {
                break;
            }
        }
        states
    }
}

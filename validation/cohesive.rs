//! A continuum reference for the notched beam of `calibrated`'s section 4: Hillerborg's
//! fictitious (cohesive) crack up the ligament of an elastic beam, solved by Petersson's
//! influence method. The half beam (mirror symmetry at mid-span) is cut into square Q8
//! plane-stress elements; the crack's faces on the ligament carry `σ(w) = f_t e^{−f_t w / G_F}`
//! (the facet law's softening in pure opening, rigid before `f_t`), lumped to the nodes with the
//! edges' Simpson weights. Condensed onto the ligament's `u` and the load, the crack is a small
//! dense problem, solved at each crack mouth opening (CMOD control) by Newton's method on the
//! set of open nodes, which is updated until no closed node carries more than `f_t` and no open
//! one overlaps.

use crate::q8::{self, Lattice};
use faer::linalg::solvers::Solve as _;
use faer::sparse::{SparseColMat, Triplet};
use nalgebra::{DMatrix, DVector};

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
    let mut ligament: Vec<usize> = (0..mesh.coords.len())
        .filter(|&i| on(mesh.coords[i].0, half) && mesh.coords[i].1 >= beam.notch - tol)
        .collect();
    ligament.sort_by(|&a, &b| mesh.coords[a].1.total_cmp(&mesh.coords[b].1));
    let n = 2 * mesh.coords.len();
    let mut place = vec![Place::Free(0); n];
    for (k, &node) in ligament.iter().enumerate() {
        place[2 * node] = Place::Ligament(k);
    }
    for (i, c) in mesh.coords.iter().enumerate() {
        if on(c.1, 0.0) && (c.0 - support).abs() <= 0.5 * beam.support_width + tol {
            place[2 * i + 1] = Place::Held;
        }
    }
    let mut nf = 0;
    for p in place.iter_mut() {
        if let Place::Free(f) = p {
            *f = nf;
            nf += 1;
        }
    }
    let free = |dof: usize| match place[dof] {
        Place::Free(f) => Some(f),
        _ => None,
    };
    // Stiffness: K_ff, the ligament's rows K_lf and its block K_ll; the crack's tributary areas.
    let nl = ligament.len();
    let (ke, _) = q8::matrices(
        mesh.h,
        beam.thickness,
        &q8::plane_stress(beam.e, beam.nu),
        0.0,
    );
    let mut kff = Vec::new();
    let mut klf: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nl];
    let mut kll = DMatrix::<f64>::zeros(nl, nl);
    let mut area = vec![0.0; nl];
    let mut load = vec![0.0; nf];
    let (hx, hy) = mesh.h;
    for ej in 0..ny {
        for ei in 0..nx {
            let nodes = mesh.element(ei, ej);
            let dof = |p: usize| 2 * nodes[p / 2] + p % 2;
            for p in 0..16 {
                for q in 0..16 {
                    let v = ke[(p, q)];
                    match (place[dof(p)], place[dof(q)]) {
                        (Place::Free(a), Place::Free(b)) => kff.push(Triplet::new(a, b, v)),
                        (Place::Ligament(k), Place::Free(b)) => klf[k].push((b, v)),
                        (Place::Ligament(k), Place::Ligament(m)) => kll[(k, m)] += v,
                        _ => {}
                    }
                }
            }
            // Simpson's weights on an edge: its corners 1/6, its middle 2/3.
            let simpson = [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0];
            if ei == nx - 1 && mesh.coords[nodes[1]].1 >= beam.notch - tol {
                // The right edge (corners 1, 2, middle 5) lies on the ligament.
                for (node, w) in [nodes[1], nodes[2], nodes[5]].into_iter().zip(simpson) {
                    let Place::Ligament(k) = place[2 * node] else {
                        unreachable!("a node of the ligament's edge is on the ligament")
                    };
                    area[k] += w * hy * beam.thickness;
                }
            }
            if ej == ny - 1 && mesh.coords[nodes[3]].0 >= half - 0.5 * beam.load_width - tol {
                // The top edge (corners 3, 2, middle 6) is under the load: the half beam
                // carries half of a unit load, spread over half the patch.
                for (node, w) in [nodes[3], nodes[2], nodes[6]].into_iter().zip(simpson) {
                    load[free(2 * node + 1).unwrap()] -= w * hx * 0.5 / (0.5 * beam.load_width);
                }
            }
        }
    }
    let kff = SparseColMat::try_new_from_triplets(nf, nf, &kff).unwrap();
    let llt = kff
        .sp_cholesky(faer::Side::Lower)
        .expect("the half beam held on its ligament and support is positive definite");
    // The free DOFs for a unit `u` at each ligament node (columns 0..nl) and for a unit load.
    let mut x = faer::Mat::<f64>::zeros(nf, nl + 1);
    for (k, row) in klf.iter().enumerate() {
        for &(f, v) in row {
            x[(f, k)] -= v;
        }
    }
    for (f, &v) in load.iter().enumerate() {
        x[(f, nl)] = v;
    }
    llt.solve_in_place(x.as_mut());
    // The ligament's reactions `r = K_L u + b P`; the gauge's `u = a·u + g P`.
    let mut k_l = kll;
    let mut b = DVector::<f64>::zeros(nl);
    for (k, row) in klf.iter().enumerate() {
        for &(f, v) in row {
            for j in 0..nl {
                k_l[(k, j)] += v * x[(f, j)];
            }
            b[k] += v * x[(f, nl)];
        }
    }
    let gauge = (0..mesh.coords.len())
        .find(|&i| on(mesh.coords[i].0, half - beam.gauge) && on(mesh.coords[i].1, 0.0))
        .expect("the gauge point is a node");
    let gf = free(2 * gauge).unwrap();
    let a = DVector::<f64>::from_fn(nl, |j, _| x[(gf, j)]);
    let g = x[(gf, nl)];

    let (f_t, g_f) = (beam.f_t, beam.g_f);
    let sigma = |w: f64| f_t * (-f_t * w / g_f).exp();
    let mut open = vec![false; nl];
    let mut z = DVector::<f64>::zeros(nl + 1); // u on the ligament, then P
    let mut loads = Vec::with_capacity(cmods.len());
    for &cmod in cmods {
        for round in 0.. {
            assert!(
                round <= 2 * nl,
                "the crack's open set cycles at CMOD {cmod} m"
            );
            let mut converged = false;
            for _ in 0..100 {
                let (u, p) = (z.rows(0, nl), z[nl]);
                let r = &k_l * u + &b * p;
                let mut res = DVector::<f64>::zeros(nl + 1);
                let mut jac = DMatrix::<f64>::zeros(nl + 1, nl + 1);
                for i in 0..nl {
                    if open[i] {
                        let s = sigma(-2.0 * u[i]);
                        res[i] = r[i] - area[i] * s;
                        jac.row_mut(i).columns_mut(0, nl).copy_from(&k_l.row(i));
                        jac[(i, i)] -= 2.0 * area[i] * f_t / g_f * s;
                        jac[(i, nl)] = b[i];
                    } else {
                        res[i] = u[i];
                        jac[(i, i)] = 1.0;
                    }
                }
                res[nl] = -2.0 * (a.dot(&u) + g * p) - cmod;
                jac.row_mut(nl)
                    .columns_mut(0, nl)
                    .copy_from(&(-2.0 * a.transpose()));
                jac[(nl, nl)] = -2.0 * g;
                let step = jac
                    .lu()
                    .solve(&res)
                    .expect("the crack's Jacobian is regular");
                z -= &step;
                if step.rows(0, nl).amax() <= 1e-13 * z.rows(0, nl).amax().max(1e-12)
                    && step[nl].abs() <= 1e-12 * z[nl].abs().max(1.0)
                {
                    converged = true;
                    break;
                }
            }
            assert!(
                converged,
                "Newton's method did not converge at CMOD {cmod} m"
            );
            let (u, p) = (z.rows(0, nl), z[nl]);
            let r = &k_l * u + &b * p;
            let mut changed = false;
            for i in 0..nl {
                if open[i] && u[i] > 0.0 {
                    open[i] = false;
                    changed = true;
                } else if !open[i] && r[i] > area[i] * f_t * (1.0 + 1e-9) {
                    open[i] = true;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        loads.push(z[nl]);
    }
    loads
}

/// What the model does with a DOF.
#[derive(Clone, Copy)]
enum Place {
    /// Free: its index among the free DOFs.
    Free(usize),
    /// `u` on the ligament: its index there.
    Ligament(usize),
    /// Held at zero (a support).
    Held,
}

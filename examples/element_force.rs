//! # The force on one element, traced along its boundary (eq. 15)
//!
//! **Purpose.** Show the element-wise form of RBSM at work. The internal force of one element is
//! the resultant of the tractions on its own boundary, and no global matrix is needed. The
//! example follows every Gauss point of every edge of one element of a 3 × 3 grid and adds up
//! what each contributes. The element is the middle of the bottom row, so one of its edges is
//! on ground springs. The example then compares the sum with the library's two evaluators:
//! element-wise and assembled `K U`.
//!
//! **Equations.**
//! - The relative displacement, seen from the element `e` towards its neighbour `o`, is
//!   `δ(x) = N_o(x) U_o − N_e(x) U_e` (eq. 6). An edge on fixed ground has `U_o = 0`.
//! - The traction is `τ = S δ`, with `S = k_n n nᵀ + k_s s sᵀ` (eqs. 11, 12).
//! - The resultant `R_e = t ∮ N_eᵀ τ dℓ` is taken with the two-point Gauss rule on each edge,
//!   which is exact here (eq. 15).
//! - `M_e Ü_e = R_e + P_e`: the internal force of eq. 7 is `f_int,e = (K U)_e = −R_e`
//!   (eqs. 15, 16).
//!
//! **Run.** `cargo run --release --example element_force`
//!
//! **Key number.** The largest difference between the traced `R_e` and `−f_int,e` from the
//! element-wise evaluator, relative to `|R_e|`: round-off, below 1e-15. The assembled `K U`
//! agrees to round-off too.

use rbsm::force::evaluator;
use rbsm::input::scene::{EvaluatorKind, Scene};
use rbsm::mesh::geometry::Vec2;
use rbsm::model::{Model, GROUND};

/// The element whose force is traced: the middle of the bottom row, with three neighbours and
/// one edge on ground springs.
const TRACED: usize = 1;

/// A 3 × 3 grid of 1 m rigid squares, its bottom edge on ground springs.
fn scene() -> Scene {
    Scene::from_json(
        r#"{"name": "element_force", "plane": "stress", "thickness": 0.1, "formulation": {"kind": "rigid"},
        "materials": {"m": {"E": 3.0e10, "nu": 0.2, "rho": 2400.0}},
        "bodies": [{"name": "grid", "material": "m",
            "mesh": {"kind": "grid", "origin": [0, 0], "size": [3, 3], "cells": [3, 3], "cell": "rect"},
            "supports": [{"edge": "bottom", "kind": "ground-spring"}]}],
        "time": {"dt": 1e-6, "steps": 1}}"#,
    )
    .expect("a valid scene")
}

/// Some displacements of every element, neither rigid nor smooth, so that every spring works:
/// `U_e = 1e-4 (sin(e + 1), cos(2e + 1), sin(3e + 2))` (m, m, rad).
fn displacements(n_elements: usize) -> Vec<f64> {
    (0..n_elements)
        .flat_map(|e| {
            [
                (e as f64 + 1.0).sin(),
                (2.0 * e as f64 + 1.0).cos(),
                (3.0 * e as f64 + 2.0).sin(),
            ]
        })
        .map(|x| 1e-4 * x)
        .collect()
}

/// What the example prints and the test checks.
struct Outcome {
    /// One line per Gauss point of the traced element.
    trace: Vec<String>,
    /// The traced resultant `R_e` (N, N, N·m).
    resultant: [f64; 3],
    /// `f_int,e` from the element-wise and the assembled evaluator.
    element_wise: [f64; 3],
    assembled: [f64; 3],
    /// `max |R_e + f_int,e| / |R_e|` for each evaluator.
    difference: [f64; 2],
    /// Edges of the traced element: three neighbours and the ground.
    edges: usize,
}

fn compute() -> Outcome {
    let model = Model::build(&scene()).expect("the model builds");
    let f = model.formulation;
    let u = displacements(model.elements.len());
    let (t, xe) = (model.thickness, model.elements[TRACED].props.centroid);
    let ue = &u[3 * TRACED..3 * TRACED + 3];
    let mut resultant = vec![0.0; 3];
    let (mut trace, mut edges) = (Vec::new(), 0);
    for i in model
        .interfaces
        .iter()
        .filter(|i| i.a as usize == TRACED || i.b as usize == TRACED)
    {
        edges += 1;
        // Seen from the traced element: the other side, and the normal pointing out of it.
        let (other, outward) = if i.a as usize == TRACED {
            (i.b, i.normal)
        } else {
            (i.a, -i.normal)
        };
        let s_dir = Vec2::new(-outward.y, outward.x);
        let (points, w) = i.gauss_points();
        for x in points {
            let own = f.displacement(ue, x - xe);
            let theirs = match other {
                GROUND => Vec2::zeros(),
                o => f.displacement(
                    &u[3 * o as usize..3 * o as usize + 3],
                    x - model.elements[o as usize].props.centroid,
                ),
            };
            let delta = theirs - own;
            let (d_n, d_s) = (outward.dot(&delta), s_dir.dot(&delta));
            let traction = outward * (i.k_n * d_n) + s_dir * (i.k_s * d_s);
            let before = resultant.clone();
            f.add_point_force(&mut resultant, x - xe, traction * (t * w));
            trace.push(format!(
                "edge to {:>6}, x = ({:.3}, {:.3}) m: δ_n = {:+.4e} m, δ_s = {:+.4e} m (on the \
                    edge's outward normal and tangent), τ = ({:+.4e}, {:+.4e}) Pa (x, y), adds \
                    ({:+.4e} N, {:+.4e} N, {:+.4e} N·m)",
                if other == GROUND {
                    "ground".to_string()
                } else {
                    format!("e{other}")
                },
                x.x,
                x.y,
                d_n,
                d_s,
                traction.x,
                traction.y,
                resultant[0] - before[0],
                resultant[1] - before[1],
                resultant[2] - before[2]
            ));
        }
    }
    let force = |kind| {
        let mut f_int = vec![0.0; u.len()];
        evaluator::build(&model, kind).internal_force(&u, &mut f_int);
        [
            f_int[3 * TRACED],
            f_int[3 * TRACED + 1],
            f_int[3 * TRACED + 2],
        ]
    };
    let (element_wise, assembled) = (
        force(EvaluatorKind::ElementWise),
        force(EvaluatorKind::Assembled),
    );
    let size = resultant.iter().map(|x| x * x).sum::<f64>().sqrt();
    let diff = |g: &[f64; 3]| {
        (0..3)
            .map(|k| (resultant[k] + g[k]).abs())
            .fold(0.0, f64::max)
            / size
    };
    Outcome {
        trace,
        resultant: [resultant[0], resultant[1], resultant[2]],
        difference: [diff(&element_wise), diff(&assembled)],
        element_wise,
        assembled,
        edges,
    }
}

fn main() {
    let o = compute();
    println!(
        "element {TRACED} (bottom middle) of a 3 x 3 grid, {} edges, two Gauss points each:",
        o.edges
    );
    for line in &o.trace {
        println!("  {line}");
    }
    println!(
        "traced resultant R_e       = ({:+.6e} N, {:+.6e} N, {:+.6e} N·m)",
        o.resultant[0], o.resultant[1], o.resultant[2]
    );
    println!(
        "-f_int,e, element-wise     = ({:+.6e} N, {:+.6e} N, {:+.6e} N·m)",
        -o.element_wise[0], -o.element_wise[1], -o.element_wise[2]
    );
    println!(
        "-(K U)_e, assembled        = ({:+.6e} N, {:+.6e} N, {:+.6e} N·m)",
        -o.assembled[0], -o.assembled[1], -o.assembled[2]
    );
    println!(
        "largest |R_e + f_int,e| / |R_e|: element-wise {:.3e}, assembled {:.3e}",
        o.difference[0], o.difference[1]
    );
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_traced_resultant_is_the_evaluators_force() {
        let o = super::compute();
        assert_eq!(o.edges, 4);
        assert_eq!(
            o.trace.iter().filter(|l| l.contains("ground")).count(),
            2,
            "one edge on ground, two Gauss points"
        );
        assert!(
            o.resultant.iter().all(|r| r.abs() > 1e3),
            "every spring works: {:?}",
            o.resultant
        );
        assert!(
            o.difference[0] < 1e-15 && o.difference[1] < 1e-14,
            "{:?}",
            o.difference
        );
    }
}

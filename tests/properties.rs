//! Property tests (proptest) where a law holds for every input and a handful of examples would
//! miss the corner that breaks it: the meshes cover their domain conformingly, the shape
//! matrix `N_e` and its transpose agree, and a rigid motion stretches no spring in either
//! evaluator.

mod common;

use proptest::prelude::*;
use rbsm::input::scene::Cell;
use rbsm::mesh::geometry::{area_properties, Vec2};
use rbsm::mesh::{grid::grid, voronoi::voronoi, Mesh};
use rbsm::model::formulation::{Hybrid, Kinematics, Rigid};

/// Cases per property: enough to find a broken corner, few enough for the suite's budget.
fn config() -> ProptestConfig {
    ProptestConfig {
        cases: 48,
        ..ProptestConfig::default()
    }
}

/// A case the property below found: a Voronoi vertex 5.6e-6 m from the bottom side of a
/// 4.3 × 6.8 m rectangle, which the weld used to take for the clipped points there, pulling
/// the side in by as much.
#[test]
fn a_voronoi_vertex_near_a_side_keeps_the_rectangle() {
    let size = Vec2::new(4.300362600714516, 6.798656690613665);
    let mesh = voronoi(
        "b",
        Vec2::new(0.0, 0.0),
        size,
        15,
        12731460188093093101,
        1,
        None,
    )
    .unwrap();
    assert_eq!(mesh.n_cells(), 15);
    assert_conforming(&mesh, size);
}

/// The laws of a conforming mesh of the rectangle `lo .. lo + size`: every cell counter-clockwise
/// with positive area, the areas summing to the rectangle's, each shared edge run once each way
/// by its two cells, and the boundary edges' length the rectangle's perimeter.
fn assert_conforming(mesh: &Mesh, size: Vec2) {
    let points = |c: usize| -> Vec<Vec2> {
        mesh.cell(c)
            .iter()
            .map(|&v| mesh.vertices[v as usize])
            .collect()
    };
    let scale = size.x * size.y;
    let mut area = 0.0;
    for c in 0..mesh.n_cells() {
        let a = area_properties(&points(c)).area;
        assert!(a > 0.0, "cell {c} has area {a}");
        area += a;
    }
    assert!(
        (area - scale).abs() <= 1e-9 * scale,
        "areas sum to {area}, not {scale}"
    );
    // A directed edge `v1 → v2` of a cell is run backwards by its neighbour, or is on the boundary.
    let mut directed = std::collections::HashSet::new();
    for c in 0..mesh.n_cells() {
        let cell = mesh.cell(c);
        for k in 0..cell.len() {
            let edge = (cell[k], cell[(k + 1) % cell.len()]);
            assert!(
                directed.insert(edge),
                "edge {edge:?} run twice the same way"
            );
        }
    }
    for s in &mesh.shared {
        assert!(directed.contains(&(s.v1, s.v2)) && directed.contains(&(s.v2, s.v1)));
    }
    let perimeter: f64 = mesh
        .boundary
        .iter()
        .map(|b| (mesh.vertices[b.v2 as usize] - mesh.vertices[b.v1 as usize]).norm())
        .sum();
    let expected = 2.0 * (size.x + size.y);
    assert!(
        (perimeter - expected).abs() <= 1e-9 * expected,
        "boundary {perimeter}, perimeter {expected}"
    );
    assert_eq!(
        2 * mesh.shared.len() + mesh.boundary.len(),
        directed.len(),
        "every edge is shared or on the boundary"
    );
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn grids_cover_their_rectangle(
        nx in 1usize..12, ny in 1usize..12, tri in any::<bool>(),
        x0 in -5.0..5.0f64, y0 in -5.0..5.0f64, w in 0.01..10.0f64, h in 0.01..10.0f64,
    ) {
        let cell = if tri { Cell::Tri } else { Cell::Rect };
        let mesh = grid("b", Vec2::new(x0, y0), Vec2::new(w, h), nx, ny, cell).unwrap();
        prop_assert_eq!(mesh.n_cells(), nx * ny * if tri { 2 } else { 1 });
        assert_conforming(&mesh, Vec2::new(w, h));
    }

    #[test]
    fn voronoi_cells_cover_their_rectangle(
        sites in 3usize..80, seed in any::<u64>(), lloyd in 0usize..4,
        w in 0.1..10.0f64, h in 0.1..10.0f64,
    ) {
        let mesh = voronoi("b", Vec2::new(0.0, 0.0), Vec2::new(w, h), sites, seed, lloyd, None).unwrap();
        prop_assert_eq!(mesh.n_cells(), sites);
        assert_conforming(&mesh, Vec2::new(w, h));
    }

    /// `N_e(d)ᵀ` is the transpose of `N_e(d)`: `F · (N_e U) = (N_eᵀ F) · U` for every state,
    /// offset and force, rigid and hybrid; and `add_linear` is `add_force` less its translation.
    #[test]
    fn the_shape_matrix_and_its_transpose_agree(
        u in prop::array::uniform6(-1.0..1.0f64),
        d in prop::array::uniform2(-2.0..2.0f64),
        f in prop::array::uniform2(-3.0..3.0f64),
    ) {
        let (d, force) = (Vec2::new(d[0], d[1]), Vec2::new(f[0], f[1]));
        let rigid = [u[0], u[1], u[2]];
        let mut gr = [0.0; 3];
        Rigid::add_force(&mut gr, d, force);
        let lhs = force.dot(&Rigid::displacement(&rigid, d));
        let rhs: f64 = gr.iter().zip(&rigid).map(|(g, u)| g * u).sum();
        prop_assert!((lhs - rhs).abs() <= 1e-12 * (1.0 + lhs.abs()));
        let mut gh = [0.0; 6];
        Hybrid::add_force(&mut gh, d, force);
        let lhs = force.dot(&Hybrid::displacement(&u, d));
        let rhs: f64 = gh.iter().zip(&u).map(|(g, u)| g * u).sum();
        prop_assert!((lhs - rhs).abs() <= 1e-12 * (1.0 + lhs.abs()));
        let mut lin = [0.0; 6];
        Hybrid::add_linear(&mut lin, d, force);
        prop_assert_eq!(&lin[2..], &gh[2..]);
        prop_assert_eq!(&lin[..2], &[0.0, 0.0]);
        let grad = Hybrid::gradient(&u, d);
        let full = Hybrid::displacement(&u, d) - Hybrid::displacement(&u, Vec2::zeros());
        prop_assert!((grad - full).norm() <= 1e-12 * (1.0 + full.norm()));
    }

    /// A small rigid motion of a free model stretches no interface: both evaluators give no
    /// force (to round-off of the springs' scale), on grids and Voronoi cells.
    #[test]
    fn a_rigid_motion_stretches_no_spring(
        tx in -1e-3..1e-3f64, ty in -1e-3..1e-3f64, theta in -1e-3..1e-3f64,
        voronoi in any::<bool>(), seed in 0u64..1000,
    ) {
        let mesh = if voronoi {
            format!(r#"{{"kind": "voronoi", "origin": [0, 0], "size": [1, 1], "sites": 30, "seed": {seed}}}"#)
        } else {
            r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [5, 4]}"#.to_string()
        };
        let model = common::model(&mesh, "[]");
        let nd = model.formulation.ndof();
        // u = t + θ ẑ × x, θ the same everywhere: N_e U_e with U_e = (t + θ ẑ × x_e, θ).
        let mut u = vec![0.0; model.n_dofs()];
        for (e, el) in model.elements.iter().enumerate() {
            let x = el.props.centroid;
            u[e * nd] = tx - theta * x.y;
            u[e * nd + 1] = ty + theta * x.x;
            u[e * nd + 2] = theta;
        }
        let (fa, fe) = common::forces(&model, &u);
        // The springs' scale: k (h ≈ 0.2 m, E = 1e9) times the motion, per unit length.
        let scale = 1e10 * (tx.abs() + ty.abs() + theta.abs());
        prop_assert!(common::norm(&fa) <= 1e-9 * scale, "assembled {}", common::norm(&fa));
        prop_assert!(common::norm(&fe) <= 1e-9 * scale, "element-wise {}", common::norm(&fe));
    }
}

//! Time of `ω_max` (matrix-free Krylov–Schur through the element-wise evaluator) for square
//! grids of 10⁴, 10⁵ and 10⁶ DOFs: `cargo bench --bench omega_max`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use rbsm::model::Model;
use rbsm::scene::{EvaluatorKind, Scene};
use rbsm::{eigen, evaluator, mass::Mass};

fn grid(cells: usize) -> Model {
    let json = format!(
        r#"{{"name": "bench", "thickness": 1.0, "formulation": {{"kind": "rigid"}},
            "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m",
                "mesh": {{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [{cells}, {cells}]}},
                "supports": [{{"edge": "bottom", "kind": "ground-spring"}}]}}],
            "time": {{"dt": 1e-6, "steps": 1}}}}"#
    );
    Model::build(&Scene::from_json(&json).unwrap()).unwrap()
}

fn omega_max(c: &mut Criterion) {
    let mut group = c.benchmark_group("omega_max");
    group.sample_size(10);
    // 3 DOFs per element: 58² ≈ 10⁴, 183² ≈ 10⁵, 578² ≈ 10⁶ DOFs.
    for cells in [58usize, 183, 578] {
        let model = grid(cells);
        let mass = Mass::new(&model);
        let ev = evaluator::build(&model, EvaluatorKind::ElementWise);
        group.bench_with_input(BenchmarkId::from_parameter(model.n_dofs()), &cells, |b, _| b.iter(|| eigen::omega_max(ev.as_ref(), &mass)));
    }
    group.finish();
}

criterion_group!(benches, omega_max);
criterion_main!(benches);

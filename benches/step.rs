//! Time of one internal-force evaluation (the heart of an explicit step) for both evaluators on
//! square grids and Voronoi meshes, reported per element: `cargo bench --bench step`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rbsm::evaluator;
use rbsm::model::Model;
use rbsm::scene::{EvaluatorKind, Scene};

fn model(mesh: &str) -> Model {
    let json = format!(
        r#"{{"name": "bench", "thickness": 1.0, "formulation": {{"kind": "rigid"}},
            "materials": {{"m": {{"E": 3e10, "nu": 0.2, "rho": 2400}}}},
            "bodies": [{{"name": "b", "material": "m", "mesh": {mesh},
                         "supports": [{{"edge": "left", "kind": "ground-spring"}}]}}],
            "time": {{"dt": 1e-6, "steps": 1}}}}"#
    );
    Model::build(&Scene::from_json(&json).unwrap()).unwrap()
}

fn internal_force(c: &mut Criterion) {
    let mut group = c.benchmark_group("internal_force");
    group.sample_size(20);
    let meshes = [
        ("grid", 10_000usize, r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [100, 100]}"#.to_string()),
        ("grid", 250_000, r#"{"kind": "grid", "origin": [0, 0], "size": [1, 1], "cells": [500, 500]}"#.to_string()),
        ("voronoi", 10_000, r#"{"kind": "voronoi", "origin": [0, 0], "size": [1, 1], "sites": 10000, "seed": 1, "lloyd": 5}"#.to_string()),
    ];
    for (kind, n, mesh) in meshes {
        let m = model(&mesh);
        let u: Vec<f64> = (0..m.n_dofs()).map(|i| ((i * 7919) % 1000) as f64 * 1e-6).collect();
        let mut f = vec![0.0; m.n_dofs()];
        group.throughput(Throughput::Elements(n as u64));
        for ev in [EvaluatorKind::Assembled, EvaluatorKind::ElementWise] {
            let e = evaluator::build(&m, ev);
            group.bench_with_input(BenchmarkId::new(format!("{kind}/{}", ev.name()), n), &n, |b, _| b.iter(|| e.internal_force(&u, &mut f)));
        }
    }
    group.finish();
}

criterion_group!(benches, internal_force);
criterion_main!(benches);

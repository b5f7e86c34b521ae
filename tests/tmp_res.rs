use rbsm::{eigen::{self, Method}, evaluator, mass::Mass, model::Model, scene::{Scene, EvaluatorKind}, system::FreeSystem};
#[test]
fn res() {
    let scene = Scene::from_file(format!("{}/examples/scenes/cantilever.json", env!("CARGO_MANIFEST_DIR"))).unwrap();
    let model = Model::build(&scene).unwrap();
    let mass = Mass::new(&model); let sys = FreeSystem::new(&model, &mass);
    let ev = evaluator::build(&model, EvaluatorKind::Assembled);
    for m in [Method::Dense, Method::Sparse] {
        let r = eigen::modes(&sys, ev.as_ref(), &mass, 8, m).unwrap();
        for j in 3..7 {
            let phi = &r.shapes[j]; let mut kf = vec![0.0; phi.len()]; ev.internal_force(phi, &mut kf);
            let md = mass.diagonal(); let w2 = r.omega[j]*r.omega[j];
            let res: f64 = (0..phi.len()).map(|i| (kf[i] - w2*md[i]*phi[i]).powi(2)/md[i]).sum::<f64>().sqrt();
            let rq: f64 = (0..phi.len()).map(|i| phi[i]*kf[i]).sum::<f64>() / (0..phi.len()).map(|i| phi[i]*md[i]*phi[i]).sum::<f64>();
            eprintln!("{:?} mode {j}: omega {:.12e}, rayleigh {:.12e}, residual/omega2 {:.3e}", m, r.omega[j], rq.sqrt(), res / w2);
        }
    }
}

//! `rbsm calibrate` (issue 44, item 3): the calibration's inverse where it is known, and bad
//! calibration files refused by key.

use rbsm::analysis::calibrate::{
    calibrate, run_local, specimen, CalibrationSpec, Facet, Job, Test,
};

/// On squares the facets' strengths are the material's: a bar in tension carries its stress
/// on the facets across it, which open at `f_t'`; a prism between smooth platens carries it
/// on the facets along it, which crush at the cap `f_c' = 4 s'`. So the calibration must keep
/// the start's `f_t' = f_t` and `s' = f_c/4`. A crack across the bar spends `G_t'` per unit
/// section, and the columns of facets that soften beside it before it localises spend some
/// more: `G_t'` must come out at most `G_F`, and not far below.
#[test]
fn on_squares_the_facets_strengths_are_the_targets() {
    let spec = CalibrationSpec::from_json(
        r#"{"name": "squares", "rho": 2400, "width": 0.05,
            "targets": {"E": 3e10, "nu": 0.2, "tensile_strength": 3e6, "fracture_energy": 100,
                        "compressive_strength": 3e7},
            "cells": {"kind": "grid", "sizes": [0.0125], "seeds": [1]}}"#,
    )
    .unwrap();
    let report = calibrate(&spec, |jobs| run_local(&spec, jobs), |_, _, _| {}).unwrap();
    let text = rbsm::analysis::Report::text(&report);
    assert!(report.converged, "{text}");
    assert!(report.rounds.len() <= 3, "{text}");
    let [f_t, f_c, _] = report.rounds[0].ratios;
    assert!(
        (f_t - 1.0).abs() < 1e-3 && (f_c - 1.0).abs() < 1e-3,
        "{text}"
    );
    let law = &report.material["interface"];
    let value = |key: &str| law[key].as_f64().unwrap();
    assert!(
        (value("tensile_strength") / 3e6 - 1.0).abs() < 1e-3,
        "{text}"
    );
    assert!(
        (value("compressive_strength") / 3e7 - 1.0).abs() < 1e-3,
        "{text}"
    );
    let g = value("fracture_energy");
    assert!((90.0..=100.0).contains(&g), "{text}");
    // Squares have ν = 0 whatever the material's: the material keeps the target's, and its
    // E is the one whose lattice E (E/(1 − ν²) in plane stress) is the target.
    assert_eq!(report.material["nu"], 0.2);
    let e = report.material["E"].as_f64().unwrap();
    assert!((e / (3e10 * (1.0 - 0.04)) - 1.0).abs() < 1e-6, "{e}");
    assert!(
        report.note.as_deref().unwrap().contains("whatever"),
        "{text}"
    );
    assert!((report.sizes[0].e.mean / 3e10 - 1.0).abs() < 1e-6, "{text}");
}

#[test]
fn bad_calibration_files_name_the_key() {
    let base = serde_json::json!({"name": "c", "rho": 2400, "width": 0.05,
        "targets": {"E": 3e10, "nu": 0.2, "tensile_strength": 3e6, "fracture_energy": 100,
                    "compressive_strength": 3e7},
        "cells": {"sizes": [0.005], "seeds": [1]}});
    let cases = [
        (
            "/targets/fracture_energy",
            serde_json::json!(-1.0),
            "targets.fracture_energy",
            "> 0",
        ),
        (
            "/targets/compressive_strength",
            serde_json::json!(2e6),
            "targets.compressive_strength",
            "above",
        ),
        (
            "/targets/nu",
            serde_json::json!(0.5),
            "targets.nu",
            "[0, 0.5)",
        ),
        (
            "/cells/sizes",
            serde_json::json!([0.02]),
            "cells.sizes[0]",
            "width/4",
        ),
        (
            "/cells/seeds",
            serde_json::json!([]),
            "cells.seeds",
            "1 to 20",
        ),
        (
            "/tolerance/fracture_energy",
            serde_json::json!(0.5),
            "tolerance.fracture_energy",
            "[0.001, 0.2]",
        ),
        (
            "/law/friction_residual",
            serde_json::json!(0.9),
            "law.friction_residual",
            "[0, 0.6]",
        ),
        (
            "/formulation",
            serde_json::json!({"kind": "hybrid", "penalty": -1.0}),
            "formulation.penalty",
            "> 0",
        ),
        // Read by the JSON reader: the key path too, and the type as the author knows it.
        (
            "/tolerance/tensile_strength",
            serde_json::json!("0.01"),
            "tolerance.tensile_strength",
            "expected a number",
        ),
        (
            "/tolerance/tensile_strenght",
            serde_json::json!(0.01),
            "tolerance.tensile_strenght",
            "unknown field",
        ),
    ];
    for (pointer, value, key, range) in cases {
        let mut v = base.clone();
        for group in ["law", "tolerance"] {
            if pointer.starts_with(&format!("/{group}")) && v.get(group).is_none() {
                v[group] = serde_json::json!({});
            }
        }
        let (parent, last) = pointer.rsplit_once('/').unwrap();
        v.pointer_mut(parent).unwrap_or_else(|| panic!("{pointer}"))[last] = value;
        let e = CalibrationSpec::from_json(&v.to_string()).err().unwrap();
        let (_, field, message) = e.parts();
        assert_eq!(field, key, "{e}");
        assert!(message.contains(range), "{e}");
    }
    let mut v = base.clone();
    v["targets"]["G_F"] = serde_json::json!(100);
    let e = CalibrationSpec::from_json(&v.to_string()).err().unwrap();
    assert!(e.to_string().contains("unknown field `G_F`"), "{e}");
    assert_eq!(e.parts().1, "targets.G_F");
    CalibrationSpec::from_json(&base.to_string()).unwrap();
}

/// The tension bar is pulled slowly enough for its peak: at half the speed (and twice the
/// ramp) the peak of a 400-cell bar moves by less than 1 %.
#[test]
fn the_tension_peak_holds_at_half_the_speed() {
    use rbsm::analysis::calibrate::{displace, specimen_scene, Facet, Job, Test};
    use rbsm::analysis::setup::{Overrides, Setup};
    let spec = CalibrationSpec::from_json(
        r#"{"name": "c", "rho": 2400, "width": 0.05,
            "targets": {"E": 3e10, "nu": 0.18, "tensile_strength": 3e6,
                        "fracture_energy": 100, "compressive_strength": 3e7},
            "cells": {"sizes": [0.005], "seeds": [1]}}"#,
    )
    .unwrap();
    let job = Job {
        round: 1,
        test: Test::Tension,
        size: 0.005,
        seed: 1,
        facet: Facet {
            e: 2.7e10,
            nu: 0.49,
            tensile_strength: 3e6,
            shear_strength: 7.6e6,
            fracture_energy: 17.0,
        },
    };
    let peak = |slower: f64| {
        let mut scene = specimen_scene(&spec, &job);
        let clamp = &mut scene["bodies"][0]["supports"][1];
        let v = clamp["velocity"][0].as_f64().unwrap();
        let ramp = clamp["ramp"].as_f64().unwrap();
        clamp["velocity"][0] = serde_json::json!(v / slower);
        clamp["ramp"] = serde_json::json!(ramp * slower);
        let scene = rbsm::input::scene::Scene::from_json(&scene.to_string()).unwrap();
        let setup = Setup::new(&scene, &Overrides::default()).unwrap();
        // Past the peak: the load has fallen below half of it, after the bar has carried half
        // the target strength.
        let (pulled, _) = displace(&setup, |p| {
            p.peak > 0.5 * 3e6 * 0.05 && p.load < 0.5 * p.peak
        })
        .unwrap();
        pulled.peak / 0.05
    };
    let (fast, slow) = (peak(1.0), peak(2.0));
    assert!(fast > 2e6, "{fast}");
    assert!((fast / slow - 1.0).abs() < 0.01, "{fast} against {slow}");
}

/// The specimens are of the spec's `formulation`: round 0's elastic job on Voronoi cells
/// finds the material's `ν` with `rigid-poisson`, and the rigid lattice's (below 0.15) without.
#[test]
fn the_specimens_take_the_formulation() {
    let nu = |formulation: &str| {
        let spec = CalibrationSpec::from_json(&format!(
            r#"{{"name": "c", "rho": 2400, "width": 0.05, "formulation": {formulation},
                "targets": {{"E": 3e10, "nu": 0.18, "tensile_strength": 3e6, "fracture_energy": 100,
                            "compressive_strength": 3e7}},
                "cells": {{"sizes": [0.005], "seeds": [1]}}}}"#
        ))
        .unwrap();
        let job = Job {
            round: 0,
            test: Test::Elastic,
            size: 0.005,
            seed: 1,
            facet: Facet {
                e: 3e10,
                nu: 0.18,
                tensile_strength: 3e6,
                shear_strength: 7.5e6,
                fracture_energy: 100.0,
            },
        };
        specimen(&spec, &job).unwrap().second
    };
    let poisson = nu(r#"{"kind": "rigid-poisson"}"#);
    assert!(
        (poisson / 0.18 - 1.0).abs() < 0.03,
        "rigid-poisson ν = {poisson}"
    );
    let rigid = nu(r#"{"kind": "rigid"}"#);
    assert!(rigid < 0.15, "rigid ν = {rigid}");
}

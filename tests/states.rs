//! The typed states (a run's, a trade-off point's, a failing interface's): each is written as
//! the text that the README's *Outputs* and `docs/scene.md` name, and read back from it.

use rbsm::analysis::tradeoff::PointStatus;
use rbsm::force::failure::InterfaceStatus;
use rbsm::step::integrator::{RunStatus, Status};

#[test]
fn a_run_status_is_written_as_its_lowercase_name() {
    for (status, text) in [
        (RunStatus::Ok, "ok"),
        (RunStatus::Interrupted, "interrupted"),
        (RunStatus::Diverged, "diverged"),
    ] {
        assert_eq!(
            serde_json::to_string(&status).unwrap(),
            format!("\"{text}\"")
        );
        assert_eq!(status.to_string(), text);
        let back: RunStatus = serde_json::from_str(&format!("\"{text}\"")).unwrap();
        assert_eq!(back, status);
    }
    assert!(serde_json::from_str::<RunStatus>("\"Ok\"").is_err());
}

#[test]
fn an_interface_status_is_written_as_its_name_and_parsed_back() {
    let names = ["elastic", "yielding", "broken", "released"];
    for (status, text) in InterfaceStatus::ALL.iter().copied().zip(names) {
        assert_eq!(
            serde_json::to_string(&status).unwrap(),
            format!("\"{text}\"")
        );
        assert_eq!(status.to_string(), text);
        assert_eq!(text.parse::<InterfaceStatus>(), Ok(status));
    }
    let refused = "cracked".parse::<InterfaceStatus>().unwrap_err();
    assert!(
        refused.contains("`cracked`") && refused.contains("elastic, yielding, broken or released"),
        "{refused}"
    );
}

#[test]
fn a_point_status_is_the_run_description_and_is_read_back_whole() {
    let diverged = Status::Diverged {
        step: 3,
        t: 7.642645e-5,
        reason: "energy growth: kinetic + elastic + contact = 1.8e1 J".into(),
    };
    let interrupted = Status::Interrupted { step: 12, t: 0.5 };
    for run in [Status::Ok, diverged, interrupted] {
        let point = PointStatus::from(&run);
        let json = serde_json::to_string(&point).unwrap();
        assert_eq!(json, serde_json::to_string(&run.describe()).unwrap());
        assert_eq!(point.to_string(), run.describe());
        assert_eq!(serde_json::from_str::<PointStatus>(&json).unwrap(), point);
        assert_eq!(point.is_ok(), run == Status::Ok);
    }
    assert_eq!(
        PointStatus::from(&Status::Interrupted { step: 12, t: 0.5 }).to_string(),
        "interrupted at step 12 (t = 5.000000e-1 s)"
    );
    for text in ["\"diverged\"", "\"okay\"", "\"stopped at step 3\""] {
        assert!(serde_json::from_str::<PointStatus>(text).is_err(), "{text}");
    }
}

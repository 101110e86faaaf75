//! The diagnosis, run blind on the shared recordings: each must give exactly its
//! `expected_findings` and a held-out RMS after fitting within 1.25 x its noise floor.

mod common;

use common::{print_trials, recording};
use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::{diagnose, Options};

fn check(id: &str) {
    let (spec, rec, truth) = recording(id);
    let d = diagnose(&ModelSpec::from_spec(&spec), &rec, &Options::default()).unwrap();
    let r = &d.report;
    let found: Vec<&str> = r.findings.iter().map(|f| f.effect.as_str()).collect();
    let expected: Vec<&str> = truth["expected_findings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    let floor = truth["noise_floor_rms_mm"].as_f64().unwrap();
    eprintln!(
        "{id}: found {found:?} (expected {expected:?}); baseline {:.3}/{:.3} -> final {:.3}/{:.3} held out, floor {floor:.3}, noise est {:.3}",
        r.baseline.rms_mm, r.baseline.heldout_rms_mm, r.final_.rms_mm, r.final_.heldout_rms_mm, r.noise.rms_mm
    );
    print_trials(r);
    for f in &r.findings {
        eprintln!("   {} | {} | {}", f.explanation, f.where_, f.parameters);
    }
    eprintln!("   {}", r.unexplained);
    assert_eq!(found, expected, "{id}");
    assert!(r.final_.heldout_rms_mm <= 1.25 * floor, "{id}");
}

#[test]
fn dev_clean() {
    check("dev-clean");
}

#[test]
fn dev_clearance() {
    check("dev-clearance");
}

#[test]
fn dev_friction() {
    check("dev-friction");
}

#[test]
fn dev_gravity() {
    check("dev-gravity");
}

#[test]
fn dev_latency() {
    check("dev-latency");
}

#[test]
fn dev_registration() {
    check("dev-registration");
}

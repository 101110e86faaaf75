//! Helpers shared by the tests of ctr-diagnosis: the shared data and the report's trials
//! printed for a failing case.
#![allow(dead_code)]

use ctr_diagnosis::Report;
use ctr_formats::{Recording, RobotSpec};
use serde_json::Value;
use std::path::PathBuf;

/// `shared/data` beside the repository (override with `CTR_SHARED_DATA`).
pub fn shared() -> PathBuf {
    std::env::var_os("CTR_SHARED_DATA").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
        PathBuf::from,
    )
}

/// A robot of `shared/data/robots`.
pub fn robot(name: &str) -> RobotSpec {
    RobotSpec::from_path(&shared().join(format!("robots/{name}.toml"))).unwrap()
}

/// A recording of `shared/data/recordings`, the robot its truth file names, and the
/// truth file.
pub fn recording(id: &str) -> (RobotSpec, Recording, Value) {
    let dir = shared().join("recordings");
    let truth: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join(format!("{id}.truth.json"))).unwrap(),
    )
    .unwrap();
    let robot = truth["robot_file"]
        .as_str()
        .unwrap()
        .trim_start_matches("shared/data/");
    let spec = RobotSpec::from_path(&shared().join(robot)).unwrap();
    let rec = Recording::from_path(&dir.join(format!("{id}.csv")), spec.robot.n_tubes()).unwrap();
    (spec, rec, truth)
}

/// Every candidate the diagnosis fitted, round by round, on stderr.
pub fn print_trials(r: &Report) {
    for t in &r.tried {
        eprintln!(
            "   round {} {:>13}: fit {:.4} held {:.4} bic {:>9.1} {}{}",
            t.round,
            t.effect.as_str(),
            t.rms_mm,
            t.heldout_rms_mm,
            t.bic_change,
            if t.added { "ADDED " } else { "" },
            t.note
        );
    }
}

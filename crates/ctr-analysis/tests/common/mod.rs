//! Set-up shared by the tests of ctr-analysis and of the crates above it: the tests of
//! ctr-diagnosis and ctr-cli include this file too (`#[path]` in their `common/mod.rs`).
//! It names nothing but `ctr_core`, `ctr_formats` and `serde_json`, which all three have.
#![allow(dead_code)]

use ctr_core::{Joints, Model, Request, Robot, Solver};
use ctr_formats::{FkResult, Recording, RobotSpec};
use serde_json::Value;
use std::path::PathBuf;

/// The project's copy of the shared reference data (`tests/data/shared`; override with
/// `CTR_SHARED_DATA`).
pub fn shared() -> PathBuf {
    std::env::var_os("CTR_SHARED_DATA").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/shared"),
        PathBuf::from,
    )
}

/// A robot of `tests/data/shared/robots`.
pub fn robot(name: &str) -> RobotSpec {
    RobotSpec::from_path(&shared().join(format!("robots/{name}.toml"))).unwrap()
}

/// A recording of `tests/data/shared/recordings`, the robot its truth file names, and the
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

/// The stable increment ranges of `tests/data/shared/manifest.json` (`valid_ranges`), mm; all
/// robots take every rotation in [-180, 180] degrees.
pub fn stable_increments(name: &str) -> Vec<[f64; 2]> {
    match name {
        "liu2023" => vec![[20.0, 70.0], [25.0, 95.0]],
        "nitinol2" => vec![[10.0, 60.0], [10.0, 80.0]],
        "nitinol3" => vec![[10.0, 50.0]; 3],
        _ => panic!("unknown robot {name}"),
    }
}

/// xorshift64: deterministic pseudo-random numbers from a seed.
pub struct Rng(pub u64);

impl Rng {
    /// The next number, uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Distance between two points, mm.
pub fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The core called row by row on `joints` (file units, `2 N` a row) with a fresh
/// `Solver` every `chunk` rows.
pub fn core_rows<const N: usize>(
    robot: &Robot<f64, N>,
    joints: &[f64],
    model: Model,
    chunk: usize,
) -> Vec<FkResult> {
    let mut solver = Solver::<f64, N>::default();
    joints
        .chunks(2 * N)
        .enumerate()
        .map(|(i, q)| {
            if i % chunk == 0 {
                solver = Solver::default();
            }
            let q = Joints::from_mm_deg(
                core::array::from_fn(|k| q[2 * k]),
                core::array::from_fn(|k| q[2 * k + 1]),
            );
            FkResult::from_solution(
                &solver.solve(robot, Request::new(q, model)).unwrap(),
                f64::NAN,
            )
        })
        .collect()
}

//! Joint sweeps along which a two-tube robot does or does not snap, and the independent
//! continuation they are checked against.
#![allow(dead_code)]

pub mod continuation;

use ctr_core::TubeParams;
use ctr_formats::{RobotFile, RobotSpec};

/// The seed's robot (`data/robots/liu2023.toml`) with every transmission `extra_mm`
/// longer.
pub fn long_transmissions(extra_mm: f64) -> RobotSpec {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../data/robots/liu2023.toml"
    );
    let text = std::fs::read_to_string(path).unwrap();
    let mut file = RobotFile::parse(&text, path).unwrap();
    for t in &mut file.tube {
        t.length_mm += extra_mm;
    }
    file.validate(path).unwrap()
}

/// The relative angle at which two tubes' curvatures bend the same way (their
/// relaxed configuration), degrees: 0 for curvatures of one sign, 180 for opposed.
pub fn relaxed_deg(params: &[TubeParams<f64>]) -> f64 {
    let sign = |p: &TubeParams<f64>| p.curvature_radius_mm.map_or(1.0, f64::signum);
    if sign(&params[0]) * sign(&params[1]) > 0.0 {
        0.0
    } else {
        180.0
    }
}

/// A turn of tube 2 against tube 1 at fixed feeds: from `start_deg` a full turn forward
/// and back, `step_deg` a row; each row `[s1, theta1, s2, theta2]` in file units.
pub fn full_turn(s_mm: [f64; 2], start_deg: f64, step_deg: f64) -> Vec<[f64; 4]> {
    let n = (360.0 / step_deg).round() as usize;
    (0..=2 * n)
        .map(|k| {
            let along = if k <= n { k } else { 2 * n - k };
            [s_mm[0], 0.0, s_mm[1], start_deg + along as f64 * step_deg]
        })
        .collect()
}

//! Writes the bundled static configuration set `data/examples/liu2023-static.csv`: the
//! seed paper's two-tube robot (`data/robots/liu2023.toml`) held at 60 poses drawn over
//! its joint space in two sessions, each pose measured as 20 tracker frames of 0.2 mm
//! noise and written averaged (`n_frames,spread_mm`), with one effect the robot file
//! leaves out concealed in it: the outer tube's precurvature radius 12 % longer than
//! the file says (`precurvature`, radius factor 1.12 on tube 1).
//!
//! `cargo run --release -p ctr-diagnosis --example example_static_set > data/examples/liu2023-static.csv`
//!
//! The truth is printed on stderr; `ctr-cli diagnose` is meant to find it blind.

use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::synth::{static_set, write_csv, Ranges, StaticSpec};
use ctr_formats::{Precurvature, RobotSpec};
use std::path::Path;

/// The concealed radius factor of tube 1 (the outer tube).
const RADIUS_FACTOR: f64 = 1.12;
/// Poses per session, and tracker frames per pose.
const POSES: [usize; 2] = [30, 30];
const FRAMES: usize = 20;
/// Tracker noise of one frame per axis, mm.
const NOISE_MM: f64 = 0.2;
/// The robot's stable ranges (`tests/data/shared/manifest.json`): s1, s2 - s1 in mm.
const INCREMENTS_MM: [[f64; 2]; 2] = [[20.0, 70.0], [25.0, 95.0]];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let spec = RobotSpec::from_path(&root.join("data/robots/liu2023.toml"))?;
    let mut world = ModelSpec::from_spec(&spec);
    world.effects.precurvature = Some(Precurvature {
        radius_factor: vec![RADIUS_FACTOR, 1.0],
    });
    let ranges = Ranges {
        increments_mm: INCREMENTS_MM.to_vec(),
        theta_deg: [-180.0, 180.0],
    };
    let set = StaticSpec {
        seed: 41,
        poses: POSES.to_vec(),
        frames: FRAMES,
        averaged: true,
        noise_sigma_mm: NOISE_MM,
        same_poses: false,
        file: "liu2023-static.csv".into(),
    };
    let s = static_set(&[world.clone(), world], &ranges, &set)?;
    eprintln!(
        "concealed: precurvature radius factor {RADIUS_FACTOR} on tube 1; {} poses of {FRAMES} \
         frames averaged, a row's noise {:.4} mm per axis",
        s.recording.rows.len(),
        NOISE_MM / (FRAMES as f64).sqrt()
    );
    write_csv(&s.recording, std::io::stdout().lock())?;
    Ok(())
}

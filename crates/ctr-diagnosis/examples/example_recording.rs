//! Writes the bundled example recording `data/examples/liu2023-recording.csv`: the seed
//! paper's two-tube robot (`data/robots/liu2023.toml`) measured by a simulated tracker,
//! with two effects the robot file leaves out concealed in it — clearance between the
//! tubes (a 2.2 deg kink, largest at a relative angle of 200 deg) and a 0.3 s lag of the
//! robot behind its commands — plus 0.2 mm tracker noise and a few outliers.
//!
//! `cargo run --release -p ctr-diagnosis --example example_recording > data/examples/liu2023-recording.csv`
//!
//! The truth is printed on stderr; `ctr-cli diagnose` is meant to find it blind.

use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::synth::{generate, write_csv, Ranges, SynthSpec};
use ctr_formats::{Clearance, Latency, RobotSpec};
use std::path::Path;

/// The concealed kink, deg, and the relative angle where it peaks, deg.
const KINK_DEG: f64 = 2.2;
const KINK_PEAK_DEG: f64 = 200.0;
/// The concealed lag, s.
const LAG_S: f64 = 0.3;
/// Tracker noise per axis, mm, and the fraction of rows with an outlier.
const NOISE_MM: f64 = 0.2;
const OUTLIERS: f64 = 0.005;
/// The robot's stable ranges (`tests/data/shared/manifest.json`): s1, s2 - s1 in mm.
const INCREMENTS_MM: [[f64; 2]; 2] = [[20.0, 70.0], [25.0, 95.0]];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let spec = RobotSpec::from_path(&root.join("data/robots/liu2023.toml"))?;
    let mut world = ModelSpec::from_spec(&spec);
    world.effects.clearance = Some(Clearance {
        max_deflection_deg: vec![KINK_DEG],
        peak_deg: vec![KINK_PEAK_DEG],
        table_deg: vec![],
    });
    world.effects.latency = Some(Latency { tau_s: LAG_S });
    let ranges = Ranges {
        increments_mm: INCREMENTS_MM.to_vec(),
        theta_deg: [-180.0, 180.0],
    };
    let synth = SynthSpec {
        seed: 2023,
        noise_sigma_mm: NOISE_MM,
        outlier_fraction: OUTLIERS,
        file: "liu2023-recording.csv".into(),
        ..SynthSpec::default()
    };
    let s = generate(&world, &ranges, &synth)?;
    eprintln!(
        "concealed: clearance {KINK_DEG} deg at {KINK_PEAK_DEG} deg, latency {LAG_S} s; {} rows, \
         noise floor {:.4} mm RMS (inliers), {} outliers",
        s.recording.rows.len(),
        s.noise_floor_rms_mm(),
        s.outlier_rows.len()
    );
    write_csv(&s.recording, std::io::stdout().lock())?;
    Ok(())
}

//! Short seeded two-tube recordings with angular columns, and the same recordings
//! without them (the tests of the units kept apart and of the sensor's rotation).

use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::synth::{generate, Ranges, SynthSpec};
use ctr_formats::{AngularColumns, Recording};

/// Tracker noise of these recordings' positions, mm per axis.
pub const SIGMA_MM: f64 = 0.2;

/// What a short two-tube recording measures, with seed `seed`: the positions with
/// [`SIGMA_MM`] of noise and `angular` with `sigma_deg` (override the walk's length or
/// add unmodelled effects by struct update).
pub fn angular_spec(seed: u64, angular: AngularColumns, sigma_deg: f64) -> SynthSpec {
    SynthSpec {
        seed,
        noise_sigma_mm: SIGMA_MM,
        feed_steps: 20,
        rotation_step_deg: 12.0,
        walk_rows: 120,
        angular: Some(angular),
        angular_noise_sigma_deg: sigma_deg,
        ..SynthSpec::default()
    }
}

/// A recording of the two-tube `world` as `spec` says, over increments of 20-60 and
/// 20-80 mm and full turns; every row solved.
pub fn angular_recording(world: &ModelSpec, spec: &SynthSpec) -> Recording {
    let ranges = Ranges {
        increments_mm: vec![[20.0, 60.0], [20.0, 80.0]],
        theta_deg: [-180.0, 180.0],
    };
    let out = generate(world, &ranges, spec).unwrap();
    assert_eq!(out.failed, 0);
    out.recording
}

/// `rec` without its angular columns.
pub fn positions_only(rec: &Recording) -> Recording {
    let mut out = rec.clone();
    for r in &mut out.rows {
        r.quaternion = None;
        r.tangent = None;
    }
    out
}

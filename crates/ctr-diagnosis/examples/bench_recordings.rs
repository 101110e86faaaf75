//! Writes the generated recordings `scripts/bench_diagnose.sh` times, beside the public
//! ones: a 10,000-row recording of a three-tube robot with three effects of the
//! vocabulary, and ~1,000-row recordings whose cause lies outside the vocabulary (a wrong
//! feed or gear ratio, a gear's once-per-turn error, a creeping or miscalibrated tracker),
//! alone or beside effects of it — what a real robot holds, and the slow case.
//!
//! `cargo run --release -p ctr-diagnosis --example bench_recordings -- OUT_DIR`
//!
//! Prints one line per recording on stdout: `RECORDING.csv ROBOT.toml`, the robot being
//! the project's copy of the shared robot (`tests/data/shared/robots`).

use ctr_analysis::model::ModelSpec;
use ctr_core::Model;
use ctr_diagnosis::synth::{generate, write_csv, Ranges, SynthSpec, Unmodelled};
use ctr_formats::{Clearance, Effects, Friction, Latency, RobotSpec};
use std::path::{Path, PathBuf};

/// Rows of the long recording (about; the walk makes up the rest).
const LONG_ROWS: usize = 10_000;
/// Rotation step of the rotation runs, degrees: the shared recordings' sampling.
const ROTATION_STEP_DEG: f64 = 3.0;
/// The same for three tubes (three rotation runs: ~1,000 rows in all).
const THREE_TUBE_ROTATION_STEP_DEG: f64 = 4.0;
/// Random-walk rows of a ~1,000-row recording of two / three tubes.
const WALK_ROWS: [usize; 2] = [400, 250];

/// One recording to write.
struct Bench {
    name: &'static str,
    robot: &'static str,
    seed: u64,
    effects: Effects,
    unmodelled: Vec<Unmodelled>,
    long: bool,
}

fn benches() -> Vec<Bench> {
    let b = |name, robot, seed, unmodelled| Bench {
        name,
        robot,
        seed,
        effects: Effects::default(),
        unmodelled,
        long: false,
    };
    let mut long = b("gen-10k-nitinol3", "nitinol3", 91, vec![]);
    long.long = true;
    long.effects.latency = Some(Latency { tau_s: 0.3 });
    long.effects.friction = Some(Friction {
        rotation_friction_coefficient: vec![],
        rotation_play_deg: vec![4.0, 4.0],
        feed_play_mm: vec![],
    });
    long.effects.clearance = Some(Clearance {
        max_deflection_deg: vec![1.5, 1.5],
        peak_deg: vec![200.0, 160.0],
        table_deg: vec![],
    });
    let mut drift_friction = b(
        "gen-drift-friction-liu2023",
        "liu2023",
        97,
        vec![Unmodelled::TrackerDrift {
            velocity_mm_s: [-0.003, 0.004, 0.0],
        }],
    );
    drift_friction.effects.friction = Some(Friction {
        rotation_friction_coefficient: vec![],
        rotation_play_deg: vec![6.0],
        feed_play_mm: vec![],
    });
    vec![
        long,
        b(
            "gen-feed-gain-nitinol3",
            "nitinol3",
            92,
            vec![Unmodelled::FeedGain {
                tube: 2,
                gain: 0.94,
            }],
        ),
        b(
            "gen-rotation-gain-nitinol2",
            "nitinol2",
            93,
            vec![Unmodelled::RotationGain {
                tube: 1,
                gain: 1.06,
            }],
        ),
        b(
            "gen-gear-runout-nitinol3",
            "nitinol3",
            94,
            vec![Unmodelled::GearRunout {
                tube: 2,
                amplitude_deg: 8.0,
                phase_deg: 30.0,
            }],
        ),
        b(
            "gen-tracker-scale-liu2023",
            "liu2023",
            95,
            vec![Unmodelled::TrackerScale {
                scale_error: [0.01, -0.008, 0.006],
            }],
        ),
        b(
            "gen-tracker-drift-nitinol2",
            "nitinol2",
            96,
            vec![Unmodelled::TrackerDrift {
                velocity_mm_s: [0.004, -0.003, 0.002],
            }],
        ),
        drift_friction,
    ]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: bench_recordings OUT_DIR")?,
    );
    std::fs::create_dir_all(&out)?;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let shared = root.join("tests/data/shared");
    let manifest = std::fs::read_to_string(shared.join("manifest.json"))?;
    for bench in benches() {
        let robot_file = shared.join(format!("robots/{}.toml", bench.robot));
        let spec = RobotSpec::from_path(&robot_file)?;
        let ranges = Ranges::from_manifest(&manifest, bench.robot)?;
        let world = ModelSpec {
            robot: spec.robot,
            model: Model::Torsion,
            effects: bench.effects.clone(),
            empirical: None,
            discrepancy: None,
        };
        let three = spec.robot.n_tubes() >= 3;
        let default = SynthSpec::default();
        let mut synth = SynthSpec {
            seed: bench.seed,
            rotation_step_deg: if three {
                THREE_TUBE_ROTATION_STEP_DEG
            } else {
                ROTATION_STEP_DEG
            },
            walk_rows: WALK_ROWS[usize::from(three)],
            file: format!("{}.csv", bench.name),
            unmodelled: bench.unmodelled.clone(),
            ..default
        };
        if bench.long {
            // ten times the sampling of the rotation and feed runs, the walk the rest
            synth.rotation_step_deg /= 10.0;
            synth.feed_steps *= 10;
            synth.sample_period_s /= 10.0;
            synth.walk_rows = 0;
        }
        let mut s = generate(&world, &ranges, &synth)?;
        if bench.long && s.recording.rows.len() < LONG_ROWS {
            synth.walk_rows = LONG_ROWS - s.recording.rows.len();
            s = generate(&world, &ranges, &synth)?;
        }
        let file = out.join(&synth.file);
        write_csv(&s.recording, std::fs::File::create(&file)?)?;
        println!("{} {}", file.display(), robot_file.display());
        eprintln!("{}: {} rows", synth.file, s.recording.rows.len());
    }
    Ok(())
}

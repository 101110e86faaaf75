//! The grades over seeded families of generated recordings (issue 42): how often a
//! real effect beside one outside the vocabulary is established (the miss rate), and
//! how often a tracker's scale error alone, or beside latency or friction, is read as
//! physics (the false-finding rate).
//!
//! `cargo run --release -p ctr-diagnosis --example grade_families -- [--draws N]
//!  [--seed S] [--threads T] [--why] [--write DIR]`
//!
//! `--why` prints every finding's grade and its reason on standard error; `--write DIR`
//! keeps each draw's recording as `DIR/<family>-<draw>.csv` (`friction-3.csv`,
//! `tracker-3.csv`), to diagnose again by hand with the shared robot file.
//!
//! Two families of `--draws` (default 20) draws each, on the shared two-tube robot
//! (`nitinol2`), default split, tracker noise 0.2 mm per axis:
//! - **friction beside a slip**: a rotation play of 2-6 deg between the tubes, and the
//!   inner tube's coupling slipping once, by 3-8 deg either way, half-way through the
//!   recording (outside the vocabulary). Counted: friction established.
//! - **tracker scale**: every axis of the tracker scaled by 1-4 % (either way) about
//!   W's origin, alone, beside a latency of 0.3-0.7 s or beside a 2-6 deg play (a third
//!   each). Counted: precurvature, clearance or stiffness established (physics read
//!   into the tracker's error).
//!
//! One Markdown line per draw and the two rates. Exit status 0 whatever the rates.

use ctr_analysis::model::ModelSpec;
use ctr_analysis::rng::Rng;
use ctr_core::Model;
use ctr_diagnosis::synth::{generate, write_csv, Ranges, SynthSpec, Unmodelled};
use ctr_diagnosis::{diagnose, Grade, Options, Report};
use ctr_formats::{Effects, Friction, Latency, RobotSpec};
use std::path::PathBuf;

/// Tracker noise of the draws, mm per axis.
const SIGMA_MM: f64 = 0.2;
/// The shared robot of the families.
const ROBOT: &str = "nitinol2";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let draws: u64 = value("--draws").map_or(Ok(20), |s| s.parse())?;
    let seed: u64 = value("--seed").map_or(Ok(1), |s| s.parse())?;
    let threads: usize = value("--threads").map_or(Ok(0), |s| s.parse())?;
    let shared = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/data/shared");
    let spec = RobotSpec::from_path(&shared.join(format!("robots/{ROBOT}.toml")))?;
    let ranges = Ranges::from_manifest(
        &std::fs::read_to_string(shared.join("manifest.json"))?,
        ROBOT,
    )?;
    let n = spec.robot.n_tubes();
    let user = ModelSpec {
        robot: spec.robot,
        model: Model::Torsion,
        effects: Effects::default(),
        empirical: None,
        discrepancy: None,
    };
    let opt = Options {
        threads,
        ..Options::default()
    };
    let play = |rng: &mut Rng| Friction {
        rotation_play_deg: vec![2.0 + 4.0 * rng.uniform(); n - 1],
        feed_play_mm: Vec::new(),
        rotation_friction_coefficient: Vec::new(),
    };
    let sign = |rng: &mut Rng| if rng.uniform() < 0.5 { -1.0 } else { 1.0 };

    println!("| family | draw | concealed | established | predictive | counted |");
    println!("|---|---|---|---|---|---|");
    let (mut friction_found, mut scale_read) = (0, 0);
    for family in ["friction beside a slip", "tracker scale"] {
        for d in 0..draws {
            let mut rng =
                Rng::new(seed * 1_000 + d + if family == "tracker scale" { 500 } else { 0 });
            let mut effects = Effects::default();
            let mut unmodelled = Vec::new();
            let concealed;
            let slip_at_half = |duration_s: f64, rng: &mut Rng| Unmodelled::RotationSlip {
                tube: n - 1,
                at_s: 0.5 * duration_s,
                jump_deg: sign(rng) * (3.0 + 5.0 * rng.uniform()),
            };
            if family == "friction beside a slip" {
                let f = play(&mut rng);
                concealed = format!("play {:.2} deg", f.rotation_play_deg[0]);
                effects.friction = Some(f);
                unmodelled.push(None);
            } else {
                let s = sign(&mut rng) * (0.01 + 0.03 * rng.uniform());
                let mut words = format!("scale {:+.2} %", 100.0 * s);
                match rng.below(3) {
                    0 => {}
                    1 => {
                        let tau_s = 0.3 + 0.4 * rng.uniform();
                        words += &format!(", latency {tau_s:.2} s");
                        effects.latency = Some(Latency { tau_s });
                    }
                    _ => {
                        let f = play(&mut rng);
                        words += &format!(", play {:.2} deg", f.rotation_play_deg[0]);
                        effects.friction = Some(f);
                    }
                }
                concealed = words;
                unmodelled.push(Some(Unmodelled::TrackerScale {
                    scale_error: [s; 3],
                }));
            }
            let world = ModelSpec {
                effects: effects.clone(),
                ..user.clone()
            };
            let mut synth = SynthSpec {
                seed: 7_000 + seed * 1_000 + d,
                noise_sigma_mm: SIGMA_MM,
                unmodelled: unmodelled.into_iter().flatten().collect(),
                ..SynthSpec::default()
            };
            let mut concealed = concealed;
            if family == "friction beside a slip" {
                // the slip half-way through: the recording's length from a first draw
                let first = generate(&world, &ranges, &synth)?;
                let end = first.recording.rows.last().map_or(0.0, |r| r.t_s);
                let slip = slip_at_half(end, &mut rng);
                if let Unmodelled::RotationSlip { jump_deg, .. } = slip {
                    concealed += &format!(", slip {jump_deg:+.2} deg at {:.0} s", 0.5 * end);
                }
                synth.unmodelled.push(slip);
            }
            let gen = generate(&world, &ranges, &synth)?;
            if let Some(dir) = value("--write") {
                let family_word = family.split(' ').next().unwrap_or("draw");
                let path = PathBuf::from(dir).join(format!("{family_word}-{d}.csv"));
                write_csv(&gen.recording, std::fs::File::create(&path)?)?;
            }
            let r = diagnose(&user, &gen.recording, &opt)?.report;
            let est = names(&r, Grade::Established);
            if args.iter().any(|a| a == "--why") {
                for f in &r.findings {
                    eprintln!("  {}: {:?}: {}", f.effect.as_str(), f.grade, f.grade_reason);
                }
            }
            let counted = if family == "friction beside a slip" {
                let found = est.iter().any(|e| e == "friction");
                friction_found += usize::from(found);
                found
            } else {
                let read = est
                    .iter()
                    .any(|e| ["precurvature", "clearance", "stiffness"].contains(&e.as_str()));
                scale_read += usize::from(read);
                read
            };
            println!(
                "| {family} | {d} | {concealed} | {} | {} | {} |",
                est.join(", "),
                names(&r, Grade::Predictive).join(", "),
                if counted { "yes" } else { "no" }
            );
        }
    }
    println!();
    println!(
        "friction beside a slip: established in {friction_found} of {draws} draws ({:.0} %)",
        100.0 * friction_found as f64 / draws as f64
    );
    println!(
        "tracker scale: precurvature, clearance or stiffness established in {scale_read} of \
         {draws} draws ({:.0} %)",
        100.0 * scale_read as f64 / draws as f64
    );
    Ok(())
}

/// The effects of `r`'s findings graded `grade`.
fn names(r: &Report, grade: Grade) -> Vec<String> {
    r.findings
        .iter()
        .filter(|f| f.grade == grade)
        .map(|f| f.effect.as_str().to_string())
        .collect()
}

//! The re-framing proof on any recording ([`ctr_diagnosis::synth::Reframe`]): the
//! recording diagnosed as it is, then transformed so that the true change to the model
//! is exact (a turned tracker, a moved encoder zero, commands shifted in time,
//! glitches, runs reordered, rows thinned) and diagnosed again; one line per
//! transformation says what was recovered against the truth and whether the rest of
//! the account held. `scripts/reframe.sh` runs it on a real recording.
//!
//! `cargo run --release -p ctr-diagnosis --example reframe -- ROBOT.toml REC.csv
//!  [--holdout SPLIT] [--draws N] [--seed S] [--fixed] [--threads T] [--write DIR]`
//!
//! `--fixed` runs issue 40's four transformations (a frame turned 4 deg about
//! (0.2, 0.3, 0.93) and shifted (3, -2, 1.5) mm; the inner tube's zero moved by 6 deg
//! and 1.5 mm; the commands 0.3 s ahead; 1 % of the rows jumped 12 mm) before the
//! seeded draws. `--write DIR` keeps each transformed recording as
//! `DIR/reframe-<i>.csv` (in the table's order), to diagnose again by hand. Prints a
//! Markdown table; exit status 0 also when a line fails.

use ctr_analysis::model::ModelSpec;
use ctr_analysis::rng::Rng;
use ctr_diagnosis::synth::Reframe;
use ctr_diagnosis::{diagnose, Holdout, Options, Report};
use ctr_formats::{Recording, RobotSpec};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let (Some(robot), Some(recording)) = (args.first(), args.get(1)) else {
        return Err(
            "usage: reframe ROBOT.toml REC.csv [--holdout SPLIT] [--draws N] \
                    [--seed S] [--fixed] [--threads T]"
                .into(),
        );
    };
    let spec = RobotSpec::from_path(Path::new(robot))?;
    let rec = Recording::from_path(Path::new(recording), spec.robot.n_tubes())?;
    let model = ModelSpec::from_spec(&spec);
    let opt = Options {
        holdout: value("--holdout").map_or(Ok(Holdout::default()), |s| s.parse())?,
        threads: value("--threads").map_or(Ok(0), |s| s.parse())?,
        ..Options::default()
    };
    let draws: usize = value("--draws").map_or(Ok(20), |s| s.parse())?;
    let seed: u64 = value("--seed").map_or(Ok(1), |s| s.parse())?;
    let mut family = Vec::new();
    if args.iter().any(|a| a == "--fixed") {
        let n = spec.robot.n_tubes();
        family.extend([
            Reframe::Frame {
                rotation_vector_deg: unit_times([0.2, 0.3, 0.93], 4.0),
                translation_mm: [3.0, -2.0, 1.5],
            },
            Reframe::EncoderZero {
                tube: n - 1,
                feed_mm: 1.5,
                rotation_deg: 6.0,
            },
            Reframe::TimeShift { shift_s: 0.3 },
            Reframe::Glitches {
                fraction: 0.01,
                size_mm: 12.0,
                seed,
            },
        ]);
    }
    let mut rng = Rng::new(seed);
    let robot_spec = &spec.robot;
    for _ in 0..draws {
        family.push(Reframe::draw(&mut rng, &rec, |q| {
            robot_spec.validate_joints(q).is_ok()
        }));
    }
    let based = diagnose(&model, &rec, &opt)?;
    let base = &based.report;
    println!(
        "unmodified: held out {:.3} mm ({:.3} mm without outliers); {}",
        base.final_.heldout_rms_mm,
        base.final_inliers.heldout_rms_mm,
        account(base)
    );
    println!();
    println!("| transformation | true change | recovered (error) | its grade | held out / unmodified | other findings | holds |");
    println!("|---|---|---|---|---|---|---|");
    let mut held = 0;
    let write = value("--write");
    for (i, r) in family.iter().enumerate() {
        let moved = r.apply(&rec)?;
        if let Some(dir) = &write {
            let path = Path::new(dir).join(format!("reframe-{}.csv", i + 1));
            ctr_diagnosis::synth::write_csv(
                &moved.recording,
                std::io::BufWriter::new(std::fs::File::create(&path)?),
            )?;
        }
        let d = diagnose(&model, &moved.recording, &opt)?;
        let got = r.recovered(&based, &rec, &d, &moved.recording, &moved.glitch_rows);
        let ok = got.holds(r);
        held += usize::from(ok);
        let error = match (r.changed(), got.error) {
            (None, _) => match got.glitches_flagged {
                Some((f, all)) => format!("{f} of {all} glitches flagged"),
                None => "-".into(),
            },
            (Some(c), None) => format!("{} not found", c.as_str()),
            (Some(_), Some(e)) => match r {
                Reframe::TimeShift { .. } => format!("{:.4} s", e[0]),
                Reframe::Frame { .. } => format!("{:.3} deg, {:.3} mm", e[0], e[1]),
                _ => format!("{:.3} deg, {:.3} mm", e[0], e[1]),
            },
        };
        let others = if got.others_differ.0.is_empty() && got.others_differ.1.is_empty() {
            let grades = if got.grades_differ.is_empty() {
                String::new()
            } else {
                format!("; grades differ: {}", got.grades_differ.join(", "))
            };
            format!("the same (worst {:.1} %){grades}", 100.0 * got.worst_other)
        } else {
            format!(
                "gained [{}], lost [{}]",
                got.others_differ.0.join(", "),
                got.others_differ.1.join(", ")
            )
        };
        println!(
            "| {} | {} | {} | {} | {:.3} | {} | {} |",
            name(r),
            r.change(),
            error,
            got.grade.map_or("-", |g| g.as_str()),
            got.heldout_ratio,
            others,
            if ok { "yes" } else { "no" }
        );
    }
    println!();
    println!("{held} of {} hold", family.len());
    Ok(())
}

/// The findings of a report and their grades, in words.
fn account(r: &Report) -> String {
    r.findings
        .iter()
        .map(|f| format!("{} ({})", f.effect.as_str(), f.grade.as_str()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A transformation in a few words.
fn name(r: &Reframe) -> String {
    match r {
        Reframe::Frame {
            rotation_vector_deg: v,
            translation_mm: t,
        } => {
            let angle = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let shift = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
            format!("frame {angle:.2} deg, {shift:.2} mm")
        }
        Reframe::EncoderZero {
            tube,
            feed_mm,
            rotation_deg,
        } => format!(
            "tube {} zero {rotation_deg:+.2} deg, {feed_mm:+.2} mm",
            tube + 1
        ),
        Reframe::TimeShift { shift_s } => format!("commands {shift_s:.3} s ahead"),
        Reframe::Glitches {
            fraction, size_mm, ..
        } => {
            format!("{:.1} % of rows jumped {size_mm} mm", 100.0 * fraction)
        }
        Reframe::RunsReordered { .. } => "runs reordered".into(),
        Reframe::Thinned => "every other row".into(),
    }
}

/// `axis` scaled to length `angle`.
fn unit_times(axis: [f64; 3], angle: f64) -> [f64; 3] {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    axis.map(|a| a * angle / n)
}

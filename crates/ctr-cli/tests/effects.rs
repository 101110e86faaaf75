//! `ctr-cli fk` and `ctr-cli ik` with the robot file's `[model.effects]`: every effect is
//! honoured as `ctr_analysis::simulate::predict` simulates it (the same composition; the
//! warm starts differ, so equal to a few 1e-9 mm, 1e-8 mm with gravity's loaded solve), time effects along the rows (`t_s`, `run`),
//! a fitted robot file written by `RobotSpec::to_toml` is used as is, and IK(FK(q))
//! returns through the static effects.

use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_core::Model;
use ctr_formats::{
    Clearance, Effects, JointOffset, Recording, Registration, RobotSpec, SensorOffset, Stiffness,
};

use std::path::{Path, PathBuf};

mod common;
use common::{arg, cli, fk_args, ik_args, repo, stderr};

const LIU: &str = "data/robots/liu2023.toml";

/// liu2023 with `tables` appended (`[model.effects.*]` tables, or a `[model]` table).
fn robot_with(dir: &Path, name: &str, tables: &str) -> PathBuf {
    let text = std::fs::read_to_string(repo(LIU)).unwrap() + "\n" + tables;
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Smooth joint rows of liu2023 inside its stable ranges, in two runs (`a`, then `b`)
/// with times: `(t_s, run, joints)`. The rotations reverse, so friction's play acts.
fn rows() -> Vec<(f64, &'static str, [f64; 4])> {
    (0..90)
        .map(|k| {
            let (run, j) = if k < 50 { ("a", k) } else { ("b", k - 50) };
            let u = j as f64 / 10.0;
            let s1 = 40.0 + 10.0 * (0.7 * u).sin();
            let s2 = s1 + 55.0 + 15.0 * (0.5 * u + 1.0).sin();
            let t1 = 60.0 * (0.9 * u).sin();
            let t2 = 150.0 * (0.6 * u + 0.5).sin();
            (0.1 * j as f64, run, [s1, t1, s2, t2])
        })
        .collect()
}

/// A joint file of `rows` with `t_s` and `run` columns if asked, and a label column.
fn joint_csv(rows: &[(f64, &str, [f64; 4])], time: bool, run: bool) -> String {
    let mut s = String::from("label,");
    if time {
        s += "t_s,";
    }
    if run {
        s += "run,";
    }
    s += "s1_mm,theta1_deg,s2_mm,theta2_deg\n";
    for (k, (t, r, q)) in rows.iter().enumerate() {
        s += &format!("r{k},");
        if time {
            s += &format!("{t:?},");
        }
        if run {
            s += &format!("{r},");
        }
        s += &format!("{:?},{:?},{:?},{:?}\n", q[0], q[1], q[2], q[3]);
    }
    s
}

/// The same rows as a recording (tips unknown: zeros), for the simulator.
fn recording(rows: &[(f64, &str, [f64; 4])], time: bool, run: bool) -> Recording {
    let csv = joint_csv(rows, time, run).replace(
        "s1_mm,theta1_deg,s2_mm,theta2_deg\n",
        "s1_mm,theta1_deg,s2_mm,theta2_deg,x_mm,y_mm,z_mm\n",
    );
    let csv: String = csv
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("{l}\n")
            } else {
                format!("{l},0,0,0\n")
            }
        })
        .collect();
    Recording::read(csv.as_bytes(), "rec.csv", 2).unwrap()
}

/// Runs `ctr-cli fk` and returns the tip positions (the output's x_mm,y_mm,z_mm).
fn cli_fk(dir: &Path, robot: &Path, joints: &str, extra: &[&str]) -> Vec<[f64; 3]> {
    let j = dir.join("joints.csv");
    let out = dir.join("tips.csv");
    std::fs::write(&j, joints).unwrap();
    let o = cli()
        .args(fk_args(robot, &j, &["-o", arg(&out)]))
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let mut rdr = csv::Reader::from_path(&out).unwrap();
    let h = rdr.headers().unwrap().clone();
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    let (x, y, z) = (col("x_mm"), col("y_mm"), col("z_mm"));
    rdr.records()
        .map(|r| {
            let r = r.unwrap();
            [x, y, z].map(|i| r[i].parse().unwrap())
        })
        .collect()
}

/// Largest distance between two lists of points, mm.
fn max_diff(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt())
        .fold(0.0, f64::max)
}

fn simulated(spec: &ModelSpec, rec: &Recording) -> Vec<[f64; 3]> {
    let runs: Vec<usize> = (0..rec.runs.len()).collect();
    let pred = predict(spec, rec, &runs).unwrap();
    assert_eq!(pred.failed, 0);
    pred.p
}

/// Every static effect at once (the Python tests append the same tables).
const STATIC: &str = include_str!("../../../tests/fixtures/static-effects.toml");

/// Each effect alone, and combinations, through the CLI and through the simulator.
#[test]
fn every_effect_matches_the_simulator() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, &str, bool, bool)] = &[
        // name, tables, t_s column, run column
        (
            "joint_offset",
            "[model.effects.joint_offset]\nfeed_mm = [0.4, -0.3]\nrotation_deg = [2.0, -3.0]\n",
            false,
            false,
        ),
        (
            "clearance",
            "[model.effects.clearance]\nmax_deflection_deg = [2.5]\npeak_deg = [205.0]\n",
            false,
            false,
        ),
        (
            "clearance_table",
            "[model.effects.clearance]\ntable_deg = [[0.0, 0.5, 1.5, 2.5, 1.5, 0.5]]\n",
            false,
            false,
        ),
        (
            "gravity",
            "[model.effects.gravity]\ndirection_W = [-1.0, 0.0, 0.0]\n",
            false,
            false,
        ),
        (
            "stiffness",
            "[model.effects.stiffness]\nfactor = [1.1, 0.9]\n",
            false,
            false,
        ),
        (
            "precurvature",
            "[model.effects.precurvature]\nradius_factor = [1.05, 0.95]\n",
            false,
            false,
        ),
        (
            "sensor_offset",
            "[model.effects.sensor_offset]\noffset_mm = [0.5, -0.3, -2.0]\n",
            false,
            false,
        ),
        (
            "registration",
            "[model.effects.registration]\ntranslation_mm = [3.0, -2.0, 5.0]\n\
             rotation_axis = [0.3, 0.9, 0.3]\nrotation_deg = 2.0\n",
            false,
            false,
        ),
        ("static", STATIC, true, true),
        (
            "gravity_registration_offsets",
            "[model.effects.gravity]\ndirection_W = [0.0, -1.0, 0.0]\ng_m_s2 = 9.81\n\
             [model.effects.joint_offset]\nrotation_deg = [5.0, 0.0]\n\
             [model.effects.sensor_offset]\noffset_mm = [0.0, 0.0, -1.5]\n\
             [model.effects.registration]\ntranslation_mm = [1.0, 2.0, 3.0]\n",
            false,
            false,
        ),
        (
            "latency",
            "[model.effects.latency]\ntau_s = 0.25\n",
            true,
            true,
        ),
        (
            "friction_runs",
            "[model.effects.friction]\nrotation_play_deg = [8.0]\nfeed_play_mm = [0.0, 0.5]\n",
            true,
            true,
        ),
        (
            "friction_row_order",
            "[model.effects.friction]\nrotation_play_deg = [8.0]\n",
            false,
            false,
        ),
        (
            "time_and_static",
            "[model.effects.latency]\ntau_s = 0.15\n\
             [model.effects.friction]\nrotation_play_deg = [6.0]\n\
             [model.effects.joint_offset]\nfeed_mm = [0.2, 0.0]\nrotation_deg = [0.0, 4.0]\n\
             [model.effects.clearance]\nmax_deflection_deg = [2.0]\npeak_deg = [90.0]\n\
             [model.effects.registration]\ntranslation_mm = [0.5, 0.0, -1.0]\n",
            true,
            true,
        ),
    ];
    let rows = rows();
    let plain = cli_fk(dir.path(), &repo(LIU), &joint_csv(&rows, false, false), &[]);
    for &(name, tables, time, run) in cases {
        let robot = robot_with(dir.path(), name, tables);
        let spec = RobotSpec::from_path(&robot).unwrap();
        assert!(!spec.effects.is_empty(), "{name}");
        let got = cli_fk(dir.path(), &robot, &joint_csv(&rows, time, run), &[]);
        let want = simulated(&ModelSpec::from_spec(&spec), &recording(&rows, time, run));
        // the same composition; only the warm starts differ (the CLI restarts every 32
        // rows, the simulator once per run): below the Newton tolerances (2.2e-9 mm
        // seen), looser for the loaded (gravity) solve (1.1e-8 mm seen)
        let tolerance = if tables.contains("gravity") {
            1e-7
        } else {
            1e-8
        };
        let d = max_diff(&got, &want);
        assert!(
            d <= tolerance,
            "{name}: fk and the simulator differ by {d:e} mm"
        );
        // and the effect does something
        let moved = max_diff(&got, &plain);
        assert!(moved > 1e-3, "{name}: moves the tips by only {moved:e} mm");
    }
}

/// Two runs restart friction's memory and latency's path: the second run of a file
/// equals that run alone.
#[test]
fn runs_are_simulated_on_their_own() {
    let dir = tempfile::tempdir().unwrap();
    let robot = robot_with(
        dir.path(),
        "time",
        "[model.effects.latency]\ntau_s = 0.25\n[model.effects.friction]\nrotation_play_deg = [8.0]\n",
    );
    let rows = rows();
    let both = cli_fk(dir.path(), &robot, &joint_csv(&rows, true, true), &[]);
    let b: Vec<_> = rows.iter().filter(|r| r.1 == "b").cloned().collect();
    let alone = cli_fk(dir.path(), &robot, &joint_csv(&b, true, true), &[]);
    // (the chunks of 32 warm-started rows start elsewhere: 3.5e-9 mm seen)
    let d = max_diff(&both[50..], &alone);
    assert!(d <= 1e-8, "{d:e}");
    // without the run column the file is one run (times made increasing): the second
    // half differs
    let later: Vec<_> = rows
        .iter()
        .map(|&(t, r, q)| (if r == "b" { t + 5.0 } else { t }, r, q))
        .collect();
    let one = cli_fk(dir.path(), &robot, &joint_csv(&later, true, false), &[]);
    assert!(max_diff(&one[50..], &alone) > 1e-3);
    // and the output does not depend on the thread count
    let one_thread = cli_fk(
        dir.path(),
        &robot,
        &joint_csv(&rows, true, true),
        &["--threads", "1"],
    );
    assert_eq!(both, one_thread);
}

/// `--model rigid` overrides the file's kind with the effects kept.
#[test]
fn model_override_keeps_the_effects() {
    let dir = tempfile::tempdir().unwrap();
    let robot = robot_with(dir.path(), "static", STATIC);
    let rows = rows();
    let got = cli_fk(
        dir.path(),
        &robot,
        &joint_csv(&rows, false, false),
        &["--model", "rigid"],
    );
    let mut spec = ModelSpec::from_spec(&RobotSpec::from_path(&robot).unwrap());
    spec.model = Model::Rigid;
    let want = simulated(&spec, &recording(&rows, false, false));
    assert!(max_diff(&got, &want) <= 1e-9);
    // gravity cannot be solved rigid
    let g = robot_with(
        dir.path(),
        "gravity",
        "[model.effects.gravity]\ndirection_W = [-1.0, 0.0, 0.0]\n",
    );
    let j = dir.path().join("j.csv");
    std::fs::write(&j, joint_csv(&rows, false, false)).unwrap();
    let o = cli()
        .args(fk_args(&g, &j, &["--model", "rigid"]))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("model.effects.gravity: the loaded solver models torsion"),
        "{}",
        stderr(&o)
    );
}

/// A fitted model saved with `RobotSpec::to_toml` is just another robot file: it reads
/// back equal, and `fk` on it gives what the model predicts, to the bit what the same
/// tables written by hand give.
#[test]
fn a_fitted_robot_file_round_trips_and_is_used_as_is() {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = RobotSpec::from_path(&repo(LIU)).unwrap();
    spec.effects = Effects {
        joint_offset: Some(JointOffset {
            feed_mm: vec![0.4, -0.3],
            rotation_deg: vec![2.0, -3.0],
        }),
        clearance: Some(Clearance {
            max_deflection_deg: vec![2.5],
            peak_deg: vec![205.0],
            table_deg: vec![],
        }),
        stiffness: Some(Stiffness {
            factor: vec![1.1, 0.9],
        }),
        precurvature: Some(ctr_formats::Precurvature {
            radius_factor: vec![1.05, 0.95],
        }),
        sensor_offset: Some(SensorOffset {
            offset_mm: [0.5, -0.3, -2.0],
        }),
        registration: Some(Registration {
            translation_mm: [3.0, -2.0, 5.0],
            rotation_axis: [0.3, 0.9, 0.3],
            rotation_deg: 2.0,
        }),
        ..Default::default()
    };
    let text = spec.to_toml();
    assert_eq!(
        RobotSpec::from_toml_str(&text, "fitted.toml").unwrap(),
        spec
    );
    let fitted = dir.path().join("fitted.toml");
    std::fs::write(&fitted, &text).unwrap();
    let rows = rows();
    let joints = joint_csv(&rows, false, false);
    let got = cli_fk(dir.path(), &fitted, &joints, &[]);
    let want = simulated(
        &ModelSpec::from_spec(&spec),
        &recording(&rows, false, false),
    );
    assert!(max_diff(&got, &want) <= 1e-9);
    let by_hand = robot_with(dir.path(), "by-hand", STATIC);
    assert_eq!(cli_fk(dir.path(), &by_hand, &joints, &[]), got);
}

/// IK(FK(q)) through the static effects: the targets are the measured tips (in the
/// tracker's frame); the joints found give them back within 1e-3 mm.
#[test]
fn ik_inverts_the_static_effects() {
    let dir = tempfile::tempdir().unwrap();
    let mut tables = String::from(
        "[model.effects.registration]\ntranslation_mm = [3.0, -2.0, 5.0]\n\
         rotation_axis = [0.3, 0.9, 0.3]\nrotation_deg = 4.0\n\
         [model.effects.clearance]\nmax_deflection_deg = [2.5]\npeak_deg = [205.0]\n\
         [model.effects.stiffness]\nfactor = [1.1, 0.9]\n\
         [model.effects.sensor_offset]\noffset_mm = [0.0, 0.5, -1.0]\n\
         [model.effects.joint_offset]\nrotation_deg = [0.0, 3.0]\n",
    );
    for [lo, hi] in [[20.0, 70.0], [25.0, 95.0]] {
        tables += &format!(
            "\n[[limits.tube]]\nincrement_mm = [{lo:?}, {hi:?}]\ntheta_deg = [-180.0, 180.0]\n"
        );
    }
    let robot = robot_with(dir.path(), "ik", &tables);
    let rows = rows();
    let joints = dir.path().join("joints.csv");
    let tips = dir.path().join("tips.csv");
    let found = dir.path().join("found.csv");
    std::fs::write(&joints, joint_csv(&rows, false, false)).unwrap();
    let run = |args: &[&str]| {
        let o = cli().args(args).output().unwrap();
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    };
    run(&fk_args(&robot, &joints, &["-o", arg(&tips)]));
    // the targets: x_mm,y_mm,z_mm (positions only: the label and joints are carried)
    run(&ik_args(
        &robot,
        &tips,
        &["--position-only", "-o", arg(&found)],
    ));
    let mut rdr = csv::Reader::from_path(&found).unwrap();
    let h = rdr.headers().unwrap().clone();
    let status = h.iter().position(|c| c == "status").unwrap();
    let residual = h.iter().position(|c| c == "residual_mm").unwrap();
    for r in rdr.records() {
        let r = r.unwrap();
        assert_eq!(&r[status], "reached");
        assert!(r[residual].parse::<f64>().unwrap() <= 1e-3);
    }
    // the joints found, through fk again: the targets to 1e-3 mm
    let found_text = std::fs::read_to_string(&found).unwrap();
    let mut rdr = csv::Reader::from_reader(found_text.as_bytes());
    let h = rdr.headers().unwrap().clone();
    let cols: Vec<usize> = ["s1_mm", "theta1_deg", "s2_mm", "theta2_deg"]
        .iter()
        .map(|c| h.iter().position(|x| x == *c).unwrap())
        .collect();
    let mut again = String::from("s1_mm,theta1_deg,s2_mm,theta2_deg\n");
    for r in rdr.records() {
        let r = r.unwrap();
        again += &(cols.iter().map(|&i| &r[i]).collect::<Vec<_>>().join(",") + "\n");
    }
    let targets = cli_fk(dir.path(), &robot, &joint_csv(&rows, false, false), &[]);
    let reached = cli_fk(dir.path(), &robot, &again, &[]);
    let d = max_diff(&targets, &reached);
    assert!(d <= 1e-3, "IK(FK(q)) misses by {d:e} mm");
}

/// ik refuses time effects, naming the table; a zero latency is no effect.
#[test]
fn ik_refuses_time_effects() {
    let dir = tempfile::tempdir().unwrap();
    let targets = dir.path().join("targets.csv");
    std::fs::write(&targets, "x_mm,y_mm,z_mm\n-5,0,90\n").unwrap();
    for (name, table, refused) in [
        ("latency", "[model.effects.latency]\ntau_s = 0.1\n", true),
        (
            "friction",
            "[model.effects.friction]\nrotation_play_deg = [3.0]\n",
            true,
        ),
        (
            "latency_zero",
            "[model.effects.latency]\ntau_s = 0.0\n",
            false,
        ),
    ] {
        let robot = robot_with(dir.path(), name, table);
        let o = cli().args(ik_args(&robot, &targets, &[])).output().unwrap();
        if refused {
            assert_eq!(o.status.code(), Some(2), "{name}");
            let effect = name.split('_').next().unwrap();
            assert!(
                stderr(&o).contains(&format!("model.effects.{effect}: a time effect")),
                "{}",
                stderr(&o)
            );
        } else {
            assert!(o.status.success(), "{}", stderr(&o));
        }
    }
}

/// `[model.empirical]`: `ctr-cli fk` adds each term to the model's tip (with friction
/// along the runs, from the commanded joints and `t_s`), refuses a term in time without
/// a `t_s` column, and `ctr-cli ik` refuses the file (it inverts physics only).
#[test]
fn an_empirical_term_is_added_by_fk_and_refused_by_ik() {
    let dir = tempfile::tempdir().unwrap();
    let friction = "[model.effects.friction]\nrotation_play_deg = [4.0]\n";
    let terms = "[model.empirical]\nnote = \"test\"\n\
        [[model.empirical.term]]\nfeature = \"t\"\naxis = \"x\"\nmean = 2.0\nscale = 4.0\ncoefficient_mm = 0.5\n\
        [[model.empirical.term]]\nfeature = \"cos(theta2 - theta1)\"\naxis = \"z\"\ncoefficient_mm = -0.25\n\
        [[model.empirical.term]]\nfeature = \"y\"\naxis = \"y\"\nmean = 1.0\nscale = 10.0\ncoefficient_mm = 2.0\n";
    let plain = robot_with(dir.path(), "plain", friction);
    let with = robot_with(dir.path(), "with", &format!("{friction}{terms}"));
    let rows = rows();
    let joints = joint_csv(&rows, true, true);
    let base = cli_fk(dir.path(), &plain, &joints, &[]);
    let corrected = cli_fk(dir.path(), &with, &joints, &[]);
    for ((b, c), (t, _, q)) in base.iter().zip(&corrected).zip(&rows) {
        let rel = (q[3] - q[1]).to_radians().cos();
        let want = [
            b[0] + 0.5 * (t - 2.0) / 4.0,
            b[1] + 2.0 * (b[1] - 1.0) / 10.0,
            b[2] - 0.25 * rel,
        ];
        for a in 0..3 {
            assert!((c[a] - want[a]).abs() < 1e-12, "{c:?} vs {want:?}");
        }
    }
    // a term in time without t_s: refused, naming the section
    let j = dir.path().join("untimed.csv");
    std::fs::write(&j, joint_csv(&rows, false, true)).unwrap();
    let o = cli().args(fk_args(&with, &j, &[])).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("model.empirical has a term in t: it needs a t_s column"),
        "{}",
        stderr(&o)
    );
    // ik: refused with the reason
    let targets = dir.path().join("targets.csv");
    std::fs::write(&targets, "x_mm,y_mm,z_mm\n0,0,150\n").unwrap();
    let static_only = robot_with(dir.path(), "static", &terms.replace("\"t\"", "\"s1\""));
    let o = cli()
        .args(ik_args(&static_only, &targets, &[]))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o)
            .contains("model.empirical: the inverse kinematics inverts the physical model only"),
        "{}",
        stderr(&o)
    );
}

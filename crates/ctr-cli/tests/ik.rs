//! End-to-end tests of `ctr-cli ik`: IK(FK(q)) through the command line on the shared
//! robots (fk, then ik on its tip file, then fk on the joints found), joint limits,
//! unreachable targets and `--fail-unreachable`, thread-count independence, column
//! carry-through, atomic output.
//!
//! An unoptimized build runs [`ROUND_TRIPS`] targets per robot instead of 1,000
//! (`cargo test --release -p ctr-cli --test ik` runs them all, about a second).

use ctr_formats::{RobotSpec, TubeLimits};

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::analysis::{dist, stable_increments, Rng};
use common::{arg, cli, fk_args, ik_args, repo, run, run_stdin, stderr};

/// Random reachable targets per robot (the 1,000 in release builds).
const ROUND_TRIPS: usize = if cfg!(debug_assertions) { 150 } else { 1000 };

/// The shared robot file with its stable ranges as `[limits]`, written into `dir`.
fn limited_robot(dir: &Path, name: &str) -> PathBuf {
    let mut text = std::fs::read_to_string(repo(&format!("data/robots/{name}.toml"))).unwrap();
    for [lo, hi] in stable_increments(name) {
        text += &format!(
            "\n[[limits.tube]]\nincrement_mm = [{lo:?}, {hi:?}]\ntheta_deg = [-180.0, 180.0]\n"
        );
    }
    let path = dir.join(format!("{name}-limited.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// A joint CSV with a label column: `rows` random configurations inside the stable
/// ranges.
fn random_joint_file(name: &str, rows: usize, seed: u64) -> String {
    let inc = stable_increments(name);
    let n = inc.len();
    let mut rng = Rng(seed);
    let mut text = String::from("label");
    for i in 1..=n {
        text += &format!(",s{i}_mm,theta{i}_deg");
    }
    text += "\n";
    for r in 0..rows {
        text += &format!("\"row {r}, random\"");
        let mut s = 0.0;
        for &[lo, hi] in &inc {
            s += lo + (hi - lo) * rng.uniform();
            text += &format!(",{s},{}", 360.0 * rng.uniform() - 180.0);
        }
        text += "\n";
    }
    text
}

/// A smooth joint path inside the stable ranges (consecutive tips well under 1 mm apart).
fn smooth_joint_file(name: &str, rows: usize) -> String {
    let inc = stable_increments(name);
    let n = inc.len();
    let mut text = String::from("t_s");
    for i in 1..=n {
        text += &format!(",s{i}_mm,theta{i}_deg");
    }
    text += "\n";
    for k in 0..rows {
        let t = k as f64 / rows as f64 * std::f64::consts::TAU;
        text += &format!("{}", k as f64 * 0.01);
        let mut s = 0.0;
        for (i, &[lo, hi]) in inc.iter().enumerate() {
            let f = 1.0 + i as f64;
            s += 0.5 * (lo + hi) + 0.4 * (hi - lo) * (f * t + 0.3 * f).sin();
            text += &format!(",{s},{}", 150.0 * (0.5 * f * t + f).sin());
        }
        text += "\n";
    }
    text
}

/// A CSV file as a header and rows of fields.
struct Csv {
    header: Vec<String>,
    rows: Vec<csv::StringRecord>,
}

impl Csv {
    fn parse(text: &str) -> Csv {
        let mut rdr = csv::Reader::from_reader(text.as_bytes());
        let header = rdr.headers().unwrap().iter().map(String::from).collect();
        let rows = rdr.records().map(Result::unwrap).collect();
        Csv { header, rows }
    }

    fn read(path: &Path) -> Csv {
        Csv::parse(&std::fs::read_to_string(path).unwrap())
    }

    fn col(&self, name: &str) -> usize {
        self.header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name} in {:?}", self.header))
    }

    fn num(&self, row: usize, name: &str) -> f64 {
        self.rows[row][self.col(name)].parse().unwrap()
    }

    fn str(&self, row: usize, name: &str) -> &str {
        &self.rows[row][self.col(name)]
    }
}

fn joint_names(n: usize) -> Vec<String> {
    (1..=n)
        .flat_map(|i| [format!("s{i}_mm"), format!("theta{i}_deg")])
        .collect()
}

/// Checks every row's joints against the core's ranges and the robot file's [limits]
/// (independently of the IK's own limit handling).
fn assert_within_limits(robot: &Path, joints: &Csv) {
    let spec = RobotSpec::from_path(robot).unwrap();
    let limits: Vec<TubeLimits> = spec.limits.clone().unwrap();
    let names = joint_names(limits.len());
    for r in 0..joints.rows.len() {
        let q: Vec<f64> = names.iter().map(|c| joints.num(r, c)).collect();
        spec.robot
            .validate_joints(&q)
            .unwrap_or_else(|e| panic!("row {r}: {q:?}: {e}"));
        let mut prev = 0.0;
        for (i, l) in limits.iter().enumerate() {
            assert_eq!(
                l.violation(q[2 * i], q[2 * i + 1], prev),
                None,
                "row {r}, tube {}: {q:?}",
                i + 1
            );
            prev = q[2 * i];
        }
    }
}

fn tip(c: &Csv, row: usize, prefix: &str) -> [f64; 3] {
    ["x_mm", "y_mm", "z_mm"].map(|k| c.num(row, &format!("{prefix}{k}")))
}

fn ok(o: &Output) {
    assert_eq!(o.status.code(), Some(0), "{}", stderr(o));
}

/// fk on `joints`, ik on its tip file (position targets), fk on the joints found: every
/// tip returns within 1e-3 mm, every joint is within the limits.
fn round_trip(dir: &Path, name: &str, joints: &str, extra: &[&str]) -> (Csv, Csv) {
    let robot = limited_robot(dir, name);
    let joints_file = dir.join(format!("{name}-joints.csv"));
    let tips_file = dir.join(format!("{name}-tips.csv"));
    let ik_file = dir.join(format!("{name}-ik.csv"));
    let back_file = dir.join(format!("{name}-back.csv"));
    std::fs::write(&joints_file, joints).unwrap();
    let fk_command = fk_args(&robot, &joints_file, &["-o", arg(&tips_file)]);
    ok(&run(&fk_command));
    let ik_options = ["-o", arg(&ik_file), "--position-only", "--fail-unreachable"];
    let ik_command = ik_args(&robot, &tips_file, &[&ik_options[..], extra].concat());
    let o = run(&ik_command);
    ok(&o);
    assert!(o.stderr.is_empty(), "{}", stderr(&o));
    ok(&run(&fk_args(&robot, &ik_file, &["-o", arg(&back_file)])));
    let tips = Csv::read(&tips_file);
    let ik = Csv::read(&ik_file);
    let back = Csv::read(&back_file);
    assert_eq!(tips.rows.len(), ik.rows.len());
    assert_eq!(back.rows.len(), ik.rows.len());
    assert_within_limits(&robot, &ik);
    let mut worst: f64 = 0.0;
    for r in 0..tips.rows.len() {
        assert_eq!(ik.str(r, "status"), "reached", "{name} row {r}");
        let d = dist(tip(&tips, r, ""), tip(&back, r, ""));
        assert!(d <= 1e-3, "{name} row {r}: {d} mm");
        // the reached tip the IK reports is the one fk computes
        assert!(dist(tip(&ik, r, "reached_"), tip(&back, r, "")) <= 1e-6);
        assert!((ik.num(r, "residual_mm") - d).abs() <= 1e-6);
        worst = worst.max(d);
    }
    eprintln!(
        "{name}: {} targets round trip, worst {worst:.2e} mm",
        tips.rows.len()
    );
    (tips, ik)
}

#[test]
fn ik_of_fk_returns_to_the_targets_on_every_shared_robot() {
    let dir = tempfile::tempdir().unwrap();
    for (k, name) in ["liu2023", "nitinol2", "nitinol3"].iter().enumerate() {
        let joints = random_joint_file(name, ROUND_TRIPS, 0x1234_5678_9abc_def1 + k as u64);
        let (tips, ik) = round_trip(dir.path(), name, &joints, &["--cold"]);
        // the other columns are carried through, the fk run's joints replaced
        let n = stable_increments(name).len();
        let mut want = vec!["label".to_owned()];
        want.extend(joint_names(n));
        want.extend(
            "reached_x_mm,reached_y_mm,reached_z_mm,residual_mm,status"
                .split(',')
                .map(String::from),
        );
        assert_eq!(ik.header, want);
        for r in 0..tips.rows.len() {
            assert_eq!(ik.str(r, "label"), tips.str(r, "label"));
        }
    }
}

#[test]
fn warm_trajectories_return_to_the_targets() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["liu2023", "nitinol3"] {
        let joints = smooth_joint_file(name, 300);
        let (_, ik) = round_trip(dir.path(), name, &joints, &[]);
        // t_s carried through
        assert_eq!(ik.str(299, "t_s"), "2.99");
    }
}

#[test]
fn pose_targets_from_fk_are_reached() {
    let dir = tempfile::tempdir().unwrap();
    let name = "nitinol3";
    let robot = limited_robot(dir.path(), name);
    let joints = dir.path().join("joints.csv");
    std::fs::write(&joints, smooth_joint_file(name, 100)).unwrap();
    let tips = dir.path().join("tips.csv");
    ok(&run(&fk_args(&robot, &joints, &["-o", arg(&tips)])));
    let o = run(&ik_args(&robot, &tips, &[]));
    ok(&o);
    let ik = Csv::parse(std::str::from_utf8(&o.stdout).unwrap());
    assert!(ik.header.ends_with(
        &"reached_qw,reached_qx,reached_qy,reached_qz,residual_mm,orientation_residual_deg,status"
            .split(',')
            .map(String::from)
            .collect::<Vec<_>>()
    ));
    let tips = Csv::read(&tips);
    for r in 0..ik.rows.len() {
        assert_eq!(ik.str(r, "status"), "reached", "row {r}");
        assert!(ik.num(r, "residual_mm") <= 1e-4);
        assert!(ik.num(r, "orientation_residual_deg") <= 0.0057);
        let dot: f64 = ["qw", "qx", "qy", "qz"]
            .iter()
            .map(|q| ik.num(r, &format!("reached_{q}")) * tips.num(r, q))
            .sum();
        assert!(dot.abs() >= 1.0 - 1e-8, "row {r}: {dot}");
    }
    assert_within_limits(&robot, &ik);
}

#[test]
fn unreachable_targets_get_the_closest_point_and_fail_only_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let robot = limited_robot(dir.path(), "nitinol3");
    let targets = dir.path().join("targets.csv");
    std::fs::write(
        &targets,
        "name,x_mm,y_mm,z_mm\nnear,-4.48,22.3,112.1\nfar,0,0,400\nbehind,0,0,-50\n",
    )
    .unwrap();
    let out = dir.path().join("joints.csv");
    let args = ik_args(&robot, &targets, &["-o", arg(&out)]);
    let o = run(&args);
    ok(&o);
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 2, "{err}");
    assert!(err.contains("targets.csv:3: target unreachable: residual_mm = "));
    assert!(err.contains("targets.csv:4: target unreachable: residual_mm = "));
    let ik = Csv::read(&out);
    assert_eq!(ik.str(0, "status"), "reached");
    for (r, at_least) in [(1, 400.0 - 190.0), (2, 50.0)] {
        assert_eq!(ik.str(r, "status"), "unreachable");
        let d = dist(tip(&ik, r, "reached_"), [0.0, 0.0, [400.0, -50.0][r - 1]]);
        assert!((ik.num(r, "residual_mm") - d).abs() <= 1e-9);
        assert!(d >= at_least, "{d}");
    }
    assert_within_limits(&robot, &ik);
    // the far target's closest point is the robot stretched out: every increment at its
    // maximum
    assert!(
        (ik.num(1, "s3_mm") - 150.0).abs() <= 1e-6,
        "{}",
        ik.num(1, "s3_mm")
    );

    // --fail-unreachable: exit 1, the output is written all the same
    std::fs::remove_file(&out).unwrap();
    let o = run(&[&args[..], &["--fail-unreachable"]].concat());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let last = stderr(&o).lines().last().unwrap().to_owned();
    assert!(
        last.starts_with("error: ") && last.contains("targets.csv:3: 2 of 3 targets not reached"),
        "{last}"
    );
    assert_eq!(Csv::read(&out).rows.len(), 3);
}

#[test]
fn output_does_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let robot = limited_robot(dir.path(), "nitinol3");
    let joints = dir.path().join("joints.csv");
    // a trajectory of several chunks, and scattered targets
    let mut text = smooth_joint_file("nitinol3", 100);
    text += &random_joint_file("nitinol3", 40, 99)
        .lines()
        .skip(1)
        .enumerate()
        .map(|(k, l)| format!("{}{}\n", 10 + k, &l[l.find("\",").unwrap() + 1..]))
        .collect::<String>();
    std::fs::write(&joints, text).unwrap();
    let tips = dir.path().join("tips.csv");
    ok(&run(&fk_args(&robot, &joints, &["-o", arg(&tips)])));
    for mode in [&[][..], &["--cold"], &["--chunk-rows", "7"]] {
        let outputs: Vec<Vec<u8>> = ["1", "2", "3", "8"]
            .iter()
            .map(|n| {
                let options = [&["--position-only", "--threads", n][..], mode].concat();
                let o = run(&ik_args(&robot, &tips, &options));
                ok(&o);
                o.stdout
            })
            .collect();
        for o in &outputs[1..] {
            assert!(o == &outputs[0], "{mode:?}");
        }
        assert_eq!(outputs[0].iter().filter(|b| **b == b'\n').count(), 141);
    }
}

#[test]
fn the_bundled_example_is_reached() {
    let o = cli()
        .args([
            "ik",
            "--robot",
            "data/robots/liu2023.toml",
            "--targets",
            "data/examples/liu2023-targets.csv",
            "--fail-unreachable",
        ])
        .current_dir(repo(""))
        .output()
        .unwrap();
    ok(&o);
    let ik = Csv::parse(std::str::from_utf8(&o.stdout).unwrap());
    assert!(ik.rows.len() >= 20);
    assert!(ik.rows.iter().all(|r| &r[ik.col("status")] == "reached"));
}

#[test]
fn stdin_stdout_header_only_and_atomic_output() {
    let robot = repo("data/robots/nitinol3.toml");
    // header only: an empty table
    let o = run_stdin(
        &ik_args(&robot, Path::new("-"), &[]),
        b"id,x_mm,y_mm,z_mm\n",
    );
    ok(&o);
    assert_eq!(
        String::from_utf8(o.stdout).unwrap(),
        "id,s1_mm,theta1_deg,s2_mm,theta2_deg,s3_mm,theta3_deg,reached_x_mm,reached_y_mm,reached_z_mm,residual_mm,status\n"
    );
    // quoted fields are carried through as the csv crate writes them
    let o = run_stdin(
        &ik_args(&robot, Path::new("-"), &["-o", "-"]),
        b"id,x_mm,note,y_mm,z_mm\n\"a, b\",-4.48,\"say \"\"hi\"\"\",22.3,112.1\n",
    );
    ok(&o);
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(
        out.lines()
            .nth(1)
            .unwrap()
            .starts_with("\"a, b\",\"say \"\"hi\"\"\","),
        "{out}"
    );
    // an existing output is replaced only by a run that succeeds
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("joints.csv");
    std::fs::write(&out, "precious\n").unwrap();
    let targets = dir.path().join("t.csv");
    std::fs::write(&targets, "x_mm,y_mm,z_mm\n0,0,100\n0,0,abc\n").unwrap();
    let o = run(&ik_args(&robot, &targets, &["-o", arg(&out)]));
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("t.csv:3: column z_mm: \"abc\" is not a number"));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "precious\n");
    std::fs::write(&targets, "x_mm,y_mm,z_mm\n-4.48,22.3,112.1\n").unwrap();
    let o = run(&ik_args(&robot, &targets, &["-o", arg(&out)]));
    ok(&o);
    assert!(o.stdout.is_empty());
    assert_eq!(Csv::read(&out).str(0, "status"), "reached");
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 2, "temporary files left: {names:?}");
}

#[test]
fn help_shows_an_example_and_the_options() {
    for args in [&["ik", "--help"][..], &["help", "ik"]] {
        let o = run(args);
        ok(&o);
        let text = String::from_utf8(o.stdout).unwrap();
        assert!(text.contains("Example:"), "{text}");
        assert!(text.contains("ctr-cli ik --robot"), "{text}");
        for opt in [
            "--robot",
            "--targets",
            "--output",
            "--threads",
            "--fail-unreachable",
            "--cold",
            "--chunk-rows",
            "--tolerance-mm",
            "--orientation-weight",
            "--damping-feed",
            "--restarts",
            "--position-only",
            "--min-margin",
            "unreachable_with_margin",
        ] {
            assert!(text.contains(opt), "{opt}");
        }
    }
    let text = String::from_utf8(run(&["--help"]).stdout).unwrap();
    assert!(text.contains("ctr-cli ik --robot"), "{text}");
}

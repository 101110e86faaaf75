//! End-to-end tests of `ctr-cli ik --min-margin`: on the seed's robot with 100 mm longer
//! transmissions (it snaps near the opposed curvatures), feeds pinned so that a target's
//! relative angle, and so its margin, is fixed: fk --margin writes the targets and their margins
//! (one row at a time: solved cold), ik with and without the floor, fk --margin on the
//! joints found.

use std::path::Path;

mod common;
use common::analysis::Rng;
use common::{arg, fk_args, ik_args, repo, run, stderr};

/// The floor of the test (dimensionless).
const MIN_MARGIN: f64 = 0.4;
/// A target made this far above the floor is comfortably within it (dimensionless).
const COMFORT: f64 = 0.1;
/// Rows of the target file.
const ROWS: usize = if cfg!(debug_assertions) { 40 } else { 120 };
/// Pinned feeds, mm.
const FEEDS_MM: [f64; 2] = [55.0, 95.0];

/// `data/robots/liu2023.toml` with 100 mm longer transmissions and pinned feeds.
fn snapping_robot(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo("data/robots/liu2023.toml")).unwrap();
    let mut text = text
        .replace("length_mm = 124.0", "length_mm = 224.0")
        .replace("length_mm = 174.0", "length_mm = 274.0");
    assert_eq!(text.matches("length_mm = 2").count(), 2);
    for s in FEEDS_MM {
        text += &format!("\n[[limits.tube]]\ns_mm = [{s:?}, {s:?}]\n");
    }
    let path = dir.join("snapping.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// The fields of a CSV: header and rows.
fn read(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    common::table(&std::fs::read_to_string(path).unwrap())
}

fn column(path: &Path, name: &str) -> Vec<String> {
    let (header, rows) = read(path);
    let c = header.iter().position(|h| h == name).unwrap();
    rows.into_iter().map(|r| r[c].clone()).collect()
}

fn numbers(path: &Path, name: &str) -> Vec<f64> {
    column(path, name)
        .iter()
        .map(|v| v.parse().unwrap())
        .collect()
}

const JOINTS: [&str; 4] = ["s1_mm", "theta1_deg", "s2_mm", "theta2_deg"];

/// `ctr-cli fk --margin` of one joint row (file units) alone, so solved cold: the tip
/// and the margin.
fn fk_cold(dir: &Path, robot: &Path, joints: &[&str]) -> ([f64; 3], f64) {
    let one = dir.join("one.csv");
    let line = joints.join(",");
    std::fs::write(&one, format!("{}\n{line}\n", JOINTS.join(","))).unwrap();
    let out = dir.join("one-tip.csv");
    let o = run(&fk_args(robot, &one, &["-o", arg(&out), "--margin"]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let tip = ["x_mm", "y_mm", "z_mm"].map(|c| numbers(&out, c)[0]);
    (tip, numbers(&out, "stability_margin")[0])
}

#[test]
fn min_margin_holds_for_every_row_and_names_the_targets_it_holds_back() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let robot = snapping_robot(d);
    // relative angles around the opposed curvatures (0) and anywhere, tube 1 turned
    let mut rng = Rng(0x00c1_1a26_e75b_0001);
    let mut targets = String::from("x_mm,y_mm,z_mm\n");
    let mut made = Vec::new();
    for k in 0..ROWS {
        let rel = if k % 2 == 0 {
            60.0 * rng.uniform() - 30.0
        } else {
            360.0 * rng.uniform() - 180.0
        };
        let theta1 = 180.0 * rng.uniform() - 90.0;
        let theta2 = (theta1 + rel + 180.0).rem_euclid(360.0) - 180.0;
        let q = [FEEDS_MM[0], theta1, FEEDS_MM[1], theta2].map(|v| v.to_string());
        let (tip, m) = fk_cold(d, &robot, &q.each_ref().map(String::as_str));
        targets += &format!("{},{},{}\n", tip[0], tip[1], tip[2]);
        made.push(m);
    }
    let tips = d.join("targets.csv");
    std::fs::write(&tips, targets).unwrap();

    let floor = MIN_MARGIN.to_string();
    let held = d.join("held.csv");
    let ik = ik_args(
        &robot,
        &tips,
        &["-o", arg(&held), "--cold", "--min-margin", &floor],
    );
    let o = run(&ik);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let status = column(&held, "status");
    // fk --margin on the joints found: one row at a time, each solved cold
    let (header, rows) = read(&held);
    let cols: Vec<usize> = JOINTS
        .iter()
        .map(|n| header.iter().position(|h| h == n).unwrap())
        .collect();
    let (mut below, mut comfy, mut smallest) = (0, 0, f64::INFINITY);
    for (k, row) in rows.iter().enumerate() {
        let q: Vec<&str> = cols.iter().map(|&c| row[c].as_str()).collect();
        let m = fk_cold(d, &robot, &q).1;
        assert!(m >= MIN_MARGIN, "row {k}: {q:?}: margin {m}");
        smallest = smallest.min(m);
        if made[k] < MIN_MARGIN {
            below += 1;
            assert_eq!(
                status[k], "unreachable_with_margin",
                "row {k} (made at {})",
                made[k]
            );
        } else if made[k] >= MIN_MARGIN + COMFORT {
            comfy += 1;
            assert_eq!(status[k], "reached", "row {k} (made at {})", made[k]);
        }
    }
    eprintln!(
        "{ROWS} targets: {below} made below the floor, {comfy} comfortably within; \
         smallest margin of the joints found {smallest:.6}"
    );
    assert!(below >= ROWS / 10 && comfy >= ROWS / 3, "{below} {comfy}");
    // each held-back target is named on stderr, and --fail-unreachable fails on them
    let err = stderr(&o);
    assert!(
        err.contains(": target unreachable_with_margin: residual_mm = "),
        "{err}"
    );
    let o = run(&[&ik[..], &["--fail-unreachable"]].concat());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));

    // without the floor the same targets are all reached, some below it
    let free = d.join("free.csv");
    let o = run(&ik_args(&robot, &tips, &["-o", arg(&free), "--cold"]));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(column(&free, "status").iter().all(|s| s == "reached"));
}

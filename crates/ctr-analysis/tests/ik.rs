//! Inverse kinematics on the shared robots: round trips IK(FK(q)), joint limits at every
//! iterate, unreachable targets, warm starts along trajectories.
//!
//! Numeric: run with `cargo test --release -p ctr-analysis --test ik` (about 2 s). An
//! unoptimized build runs [`ROUND_TRIPS`] targets per robot instead of 1,000 and skips
//! the second round of seeds. The timing is `#[ignore]`d (`-- --ignored --nocapture`).

use ctr_analysis::ik::{Ik, IkOptions, IkResult, IkStatus};
use ctr_analysis::model::ModelSpec;
use ctr_formats::IkTarget;
use ctr_formats::{RobotSpec, TubeLimits};
use std::path::{Path, PathBuf};
use std::time::Instant;

mod common;
use common::{dist, stable_increments, Rng};

/// Random reachable targets per robot: the 1,000 in release builds.
const ROUND_TRIPS: usize = if cfg!(debug_assertions) { 150 } else { 1000 };

/// `n` in release builds, a fifth of it in unoptimized ones.
fn scaled(n: usize) -> usize {
    if cfg!(debug_assertions) {
        n / 5
    } else {
        n
    }
}

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../data")
        .join(rel)
}

/// The robot file with the manifest's stable ranges as `[limits]`.
fn spec(name: &str) -> RobotSpec {
    let mut spec = RobotSpec::from_path(&data(&format!("robots/{name}.toml"))).unwrap();
    spec.limits = Some(
        stable_increments(name)
            .into_iter()
            .map(|inc| TubeLimits {
                s_mm: None,
                increment_mm: Some(inc),
                theta_deg: Some([-180.0, 180.0]),
            })
            .collect(),
    );
    spec
}

/// Random joints in file units (mm, degrees) inside the stable ranges.
fn random_joints(rng: &mut Rng, increments: &[[f64; 2]]) -> Vec<f64> {
    let mut s = 0.0;
    let mut q = Vec::new();
    for &[lo, hi] in increments {
        s += lo + (hi - lo) * rng.uniform();
        q.push(s);
        q.push(360.0 * rng.uniform() - 180.0);
    }
    q
}

/// Checks file-unit joints against the core and the robot file's limits, independently
/// of the IK's own `JointLimits`.
fn assert_within_limits(spec: &RobotSpec, joints_file: &[f64]) {
    spec.robot
        .validate_joints(joints_file)
        .unwrap_or_else(|e| panic!("{joints_file:?}: {e}"));
    let limits = spec.limits.as_ref().unwrap();
    let mut prev = 0.0;
    for (i, l) in limits.iter().enumerate() {
        let (s, th) = (joints_file[2 * i], joints_file[2 * i + 1]);
        assert_eq!(
            l.violation(s, th, prev),
            None,
            "tube {} of {joints_file:?}",
            i + 1
        );
        prev = s;
    }
}

/// The tip position of file-unit joints by the plain core FK (default tolerances).
fn fk_position(spec: &RobotSpec, joints_file: &[f64]) -> [f64; 3] {
    ModelSpec::plain(&spec.robot, spec.model)
        .fk(joints_file)
        .unwrap()
        .position
}

/// Solves `target`, checking every iterate against the limits.
fn solve_checked(
    ik: &mut Ik,
    spec: &RobotSpec,
    target: &IkTarget,
    q0: Option<&[f64]>,
) -> (IkResult, usize) {
    let mut iterates = 0;
    let mut bad = None;
    let r = {
        let limits = ik.limits().clone();
        let to_file = |q: &[f64]| limits.to_file_units(q);
        ik.solve_observed(target, q0, &mut |q| {
            iterates += 1;
            if !limits.contains(q) && bad.is_none() {
                bad = Some(q.to_vec());
            }
            if bad.is_none() {
                assert_within_limits(spec, &to_file(q));
            }
        })
    };
    assert_eq!(bad, None, "an iterate left the limits");
    assert!(ik.limits().contains(&r.q));
    assert_within_limits(spec, &ik.to_file_units(&r.q));
    (r, iterates)
}

/// IK(FK(q)) for `count` random joint vectors: every target reached within 1e-3 mm
/// (checked with an independent core FK of the result), every iterate inside the limits.
fn round_trips(name: &str, count: usize, seed: u64) {
    let spec = spec(name);
    let mut ik = Ik::from_spec(&spec, IkOptions::default()).unwrap();
    let increments = stable_increments(name);
    let mut rng = Rng(seed);
    let mut worst: f64 = 0.0;
    let (mut iterations, mut starts, mut max_starts, mut iterates) = (0, 0, 0, 0);
    let t0 = Instant::now();
    for k in 0..count {
        let joints = random_joints(&mut rng, &increments);
        let goal = fk_position(&spec, &joints);
        let (r, n) = solve_checked(&mut ik, &spec, &IkTarget::position(goal), None);
        iterates += n;
        assert_eq!(
            r.status,
            IkStatus::Reached,
            "{name} target {k} {goal:?} from {joints:?}: {r:?}"
        );
        let back = dist(fk_position(&spec, &ik.to_file_units(&r.q)), goal);
        assert!(back <= 1e-3, "{name} target {k}: {back} mm");
        worst = worst.max(back);
        iterations += r.iterations;
        starts += r.starts;
        max_starts = max_starts.max(r.starts);
    }
    eprintln!(
        "{name}: {count} cold targets reached, worst {worst:.2e} mm (independent FK), \
         {:.1} steps and {:.2} starts per target (max {max_starts}), {iterates} iterates checked, \
         {:.2} ms per target",
        iterations as f64 / count as f64,
        starts as f64 / count as f64,
        t0.elapsed().as_secs_f64() * 1e3 / count as f64
    );
}

#[test]
fn round_trips_liu2023() {
    round_trips("liu2023", ROUND_TRIPS, 0x1111_2222_3333_4444);
}

#[test]
fn round_trips_nitinol2() {
    round_trips("nitinol2", ROUND_TRIPS, 0x5555_6666_7777_8888);
}

#[test]
fn round_trips_nitinol3() {
    round_trips("nitinol3", ROUND_TRIPS, 0x9999_aaaa_bbbb_cccc);
}

#[test]
fn round_trips_more_seeds() {
    if cfg!(debug_assertions) {
        eprintln!("round_trips_more_seeds: release builds only");
        return;
    }
    round_trips("liu2023", 1000, 0x0123_4567_89ab_cdef);
    round_trips("nitinol2", 1000, 0x1357_9bdf_0246_8ace);
    round_trips("nitinol3", 1000, 0xfedc_ba98_7654_3210);
}

/// The closest of `count` random FK samples inside the limits to `goal`, mm.
fn brute_force_closest(spec: &RobotSpec, name: &str, goal: [f64; 3], count: usize) -> f64 {
    let mut rng = Rng(0x0bad_5eed_dead_beef);
    let increments = stable_increments(name);
    (0..count)
        .map(|_| {
            dist(
                fk_position(spec, &random_joints(&mut rng, &increments)),
                goal,
            )
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn targets_outside_the_workspace_are_unreachable_with_the_closest_point() {
    for (name, goal) in [
        ("nitinol3", [0.0, 0.0, 400.0]),
        ("nitinol3", [0.0, 0.0, -50.0]),
        ("nitinol3", [200.0, 50.0, 60.0]),
        ("nitinol2", [0.0, 0.0, 300.0]),
        ("nitinol2", [-80.0, 0.0, 20.0]),
        ("liu2023", [0.0, 0.0, 250.0]),
        ("liu2023", [150.0, -150.0, 0.0]),
    ] {
        let spec = spec(name);
        let mut ik = Ik::from_spec(&spec, IkOptions::default()).unwrap();
        let t0 = Instant::now();
        let (r, _) = solve_checked(&mut ik, &spec, &IkTarget::position(goal), None);
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let samples = scaled(20_000);
        let sampled = brute_force_closest(&spec, name, goal, samples);
        eprintln!(
            "{name} {goal:?}: {} at {:.4} mm ({} starts, {} steps, {ms:.1} ms); closest of {samples} samples {sampled:.4} mm",
            r.status.name(),
            r.residual_mm,
            r.starts,
            r.iterations
        );
        assert_eq!(r.status, IkStatus::Unreachable, "{name} {goal:?}");
        assert!(r.residual_mm > 1.0);
        assert!(
            r.residual_mm <= sampled + 1e-6,
            "{name} {goal:?}: {} mm, but a sample is {sampled} mm away",
            r.residual_mm
        );
        // the reported tip is the tip of the reported joints
        let tip = fk_position(&spec, &ik.to_file_units(&r.q));
        assert!((dist(tip, goal) - r.residual_mm).abs() < 1e-6);
    }
}

/// A smooth joint path inside the stable ranges (file units): every joint a slow
/// sinusoid; consecutive tips about 0.1 to 0.5 mm apart.
fn smooth_path(name: &str, points: usize) -> Vec<Vec<f64>> {
    let increments = stable_increments(name);
    (0..points)
        .map(|k| {
            let t = k as f64 / points as f64 * std::f64::consts::TAU;
            let mut s = 0.0;
            let mut q = Vec::new();
            for (i, &[lo, hi]) in increments.iter().enumerate() {
                let f = 1.0 + i as f64;
                let mid = 0.5 * (lo + hi);
                let amp = 0.4 * (hi - lo);
                s += mid + amp * (f * t + 0.3 * f).sin();
                q.push(s);
                q.push(150.0 * (0.5 * f * t + f).sin());
            }
            q
        })
        .collect()
}

fn trajectory_targets(spec: &RobotSpec, path: &[Vec<f64>]) -> Vec<IkTarget> {
    path.iter()
        .map(|q| IkTarget::position(fk_position(spec, q)))
        .collect()
}

#[test]
fn warm_start_along_a_smooth_trajectory_takes_few_steps() {
    for name in ["liu2023", "nitinol2", "nitinol3"] {
        let spec = spec(name);
        let mut ik = Ik::from_spec(&spec, IkOptions::default()).unwrap();
        let path = smooth_path(name, scaled(1000));
        let targets = trajectory_targets(&spec, &path);
        let results = ik.solve_trajectory(&targets, None);
        let mut steps = Vec::new();
        for (k, (r, t)) in results.iter().zip(&targets).enumerate() {
            assert_eq!(r.status, IkStatus::Reached, "{name} point {k}: {r:?}");
            assert!(ik.limits().contains(&r.q));
            assert!((r.tip.position - t.position).norm() <= 1e-4);
            steps.push(r.iterations);
        }
        let warm = &steps[1..];
        let mean = warm.iter().sum::<u32>() as f64 / warm.len() as f64;
        let max = *warm.iter().max().unwrap();
        let starts = results[1..].iter().map(|r| r.starts).max().unwrap();
        eprintln!(
            "{name}: warm trajectory of {} targets: {mean:.2} steps per target, max {max}, max starts {starts}",
            warm.len()
        );
        assert!(mean <= 3.0, "{name}: {mean} steps per warm target");
        assert!(starts == 1, "{name}: a warm target needed a restart");
    }
}

#[test]
fn pose_targets_are_reached_by_the_3_tube_robot() {
    let name = "nitinol3";
    let spec = spec(name);
    let mut ik = Ik::from_spec(&spec, IkOptions::default()).unwrap();
    let increments = stable_increments(name);
    let mut rng = Rng(0x7070_7070_1234_5678);
    let count = scaled(300);
    let (mut reached, mut steps, mut starts) = (0, 0, 0);
    for _ in 0..count {
        let joints = random_joints(&mut rng, &increments);
        let tip = ik.fk(&ik.from_file_units(&joints)).unwrap();
        let target = IkTarget::frame(&tip);
        let (r, _) = solve_checked(&mut ik, &spec, &target, None);
        steps += r.iterations;
        starts += r.starts;
        if r.status == IkStatus::Reached {
            reached += 1;
            assert!(r.residual_mm <= 1e-4 && r.orientation_residual_rad.unwrap() <= 1e-4);
        } else {
            eprintln!(
                "pose not reached: {} mm, {:?} rad, {:?}",
                r.residual_mm, r.orientation_residual_rad, r.status
            );
        }
        // warm from the true joints it is always reached
        let truth = ik.from_file_units(&joints);
        let w = ik.solve(&target, Some(&truth));
        assert_eq!(w.status, IkStatus::Reached);
    }
    eprintln!(
        "nitinol3 pose targets: {reached}/{count} reached cold, {:.1} steps and {:.2} starts per target",
        steps as f64 / count as f64,
        starts as f64 / count as f64
    );
    assert!(reached as f64 >= 0.95 * count as f64, "{reached}/{count}");
}

/// Narrow limits (bounded rotations, feed ranges): the QP holds them at every iterate;
/// targets made inside are reached, targets made outside end on the limits.
#[test]
fn narrow_limits_hold_at_every_iterate() {
    let name = "nitinol3";
    let mut spec = spec(name);
    let narrow = vec![
        TubeLimits {
            s_mm: Some([15.0, 40.0]),
            increment_mm: Some([10.0, 50.0]),
            theta_deg: Some([-60.0, 45.0]),
        },
        TubeLimits {
            s_mm: Some([40.0, 80.0]),
            increment_mm: Some([12.0, 45.0]),
            theta_deg: Some([-30.0, 90.0]),
        },
        TubeLimits {
            s_mm: None,
            increment_mm: Some([15.0, 40.0]),
            theta_deg: Some([0.0, 120.0]),
        },
    ];
    spec.limits = Some(narrow.clone());
    let mut ik = Ik::from_spec(&spec, IkOptions::default()).unwrap();
    let mut rng = Rng(0x4242_4242_4242_4242);
    let (mut inside_reached, mut outside_reached, mut outside_on_limit) = (0, 0, 0);
    let count = scaled(300);
    for _ in 0..count {
        // inside: sample within the narrow limits
        let u: Vec<f64> = (0..6).map(|_| rng.uniform()).collect();
        let q_in = ik.limits().point(&u);
        let goal = ik.fk(&q_in).unwrap().position;
        let (r, _) = solve_checked(&mut ik, &spec, &IkTarget::position(goal.into()), None);
        assert_eq!(r.status, IkStatus::Reached, "{q_in:?}: {r:?}");
        inside_reached += 1;
        // outside: anywhere in the stable ranges
        let joints = random_joints(&mut rng, &stable_increments(name));
        let goal = fk_position(&spec, &joints);
        let (r, _) = solve_checked(&mut ik, &spec, &IkTarget::position(goal), None);
        match r.status {
            IkStatus::Reached => outside_reached += 1,
            IkStatus::Unreachable => outside_on_limit += 1,
            s => panic!("{s:?}"),
        }
    }
    eprintln!(
        "narrow limits: {inside_reached}/{count} inside targets reached; outside targets: \
         {outside_reached} reached within the limits, {outside_on_limit} unreachable"
    );
    assert!(outside_on_limit > 0);
}

#[test]
fn a_solve_depends_only_on_its_arguments() {
    let name = "nitinol3";
    let spec = spec(name);
    let mut a = Ik::from_spec(&spec, IkOptions::default()).unwrap();
    let mut b = a.clone();
    let targets = trajectory_targets(&spec, &smooth_path(name, 40));
    // b has a history, a has none
    let _ = b.solve_trajectory(&targets, None);
    let _ = b.solve(&IkTarget::position([0.0, 0.0, 500.0]), None);
    // (compared as printed: without a margin floor the margin is NaN, not computed)
    let same = |x: IkResult, y: IkResult| assert_eq!(format!("{x:?}"), format!("{y:?}"));
    for t in targets.iter().step_by(7) {
        same(a.solve(t, None), b.solve(t, None));
    }
    let q0 = a.solve(&targets[0], None).q;
    same(
        a.solve(&targets[5], Some(&q0)),
        b.solve(&targets[5], Some(&q0)),
    );
}

#[test]
fn the_papers_plain_damped_step_converges_from_nearby() {
    let name = "nitinol2";
    let spec = spec(name);
    let options = IkOptions {
        adaptive_damping: false,
        damping_feed: 1e-3,
        damping_rotation: 1e-3,
        restarts: 0,
        ..IkOptions::default()
    };
    let mut ik = Ik::from_spec(&spec, options).unwrap();
    let path = smooth_path(name, 200);
    let targets = trajectory_targets(&spec, &path);
    let q0 = ik.from_file_units(&path[0]);
    for r in ik.solve_trajectory(&targets, Some(&q0)) {
        assert_eq!(r.status, IkStatus::Reached, "{r:?}");
    }
}

#[test]
#[ignore = "timing: cargo test --release -p ctr-analysis --test ik -- --ignored --nocapture"]
fn timing_nitinol3() {
    let name = "nitinol3";
    let spec = spec(name);
    let t0 = Instant::now();
    let mut ik = Ik::from_spec(&spec, IkOptions::default()).unwrap();
    let build = t0.elapsed();
    let path = smooth_path(name, 5000);
    let targets = trajectory_targets(&spec, &path);
    let q0 = ik.solve(&targets[0], None).q;
    let t0 = Instant::now();
    let warm = ik.solve_trajectory(&targets[1..], Some(&q0));
    let warm_us = t0.elapsed().as_secs_f64() * 1e6 / warm.len() as f64;
    assert!(warm.iter().all(|r| r.status == IkStatus::Reached));
    let warm_steps = warm.iter().map(|r| r.iterations).sum::<u32>() as f64 / warm.len() as f64;
    let step_mm = path
        .windows(2)
        .map(|w| dist(fk_position(&spec, &w[0]), fk_position(&spec, &w[1])))
        .sum::<f64>()
        / (path.len() - 1) as f64;
    let mut rng = Rng(0x0c01_d0c0_1d0c_01d0);
    let cold_targets: Vec<IkTarget> = (0..2000)
        .map(|_| {
            IkTarget::position(fk_position(
                &spec,
                &random_joints(&mut rng, &stable_increments(name)),
            ))
        })
        .collect();
    let t0 = Instant::now();
    let cold: Vec<IkResult> = cold_targets.iter().map(|t| ik.solve(t, None)).collect();
    let cold_us = t0.elapsed().as_secs_f64() * 1e6 / cold.len() as f64;
    assert!(cold.iter().all(|r| r.status == IkStatus::Reached));
    let cold_steps = cold.iter().map(|r| r.iterations).sum::<u32>() as f64 / cold.len() as f64;
    let t0 = Instant::now();
    let n = 200;
    for _ in 0..n {
        std::hint::black_box(ik.fk(&q0));
    }
    let fk_us = t0.elapsed().as_secs_f64() * 1e6 / n as f64;
    eprintln!(
        "nitinol3 timing: Ik::new {:.2} ms (256-point start table); warm {warm_us:.1} us per target \
         ({warm_steps:.2} steps, tip moves {step_mm:.3} mm per target, {} targets); cold {cold_us:.1} us \
         per target ({cold_steps:.2} steps, {} targets); one tight cold FK {fk_us:.2} us",
        build.as_secs_f64() * 1e3,
        warm.len(),
        cold.len()
    );
}

//! Inverse kinematics with a stability-margin floor (`IkOptions::min_margin`, `ctr-cli ik
//! --min-margin`) on the robot that snaps: the seed's two-tube robot with 100 mm longer
//! transmissions (`sweeps::long_transmissions`). Every result is re-solved
//! independently (the row model's FK, cold, to the core's default tolerance: what a
//! one-row `ctr-cli fk --margin` writes) and its margin checked against the floor.
//!
//! Numeric: `cargo test --release -p ctr-analysis --test ik_margin -- --nocapture`
//! prints what it measured. An unoptimized build runs a fifth of the targets.

mod common;
mod sweeps;

use common::{dist, Rng};
use ctr_analysis::batch::{batch_fk, BatchOptions};
use ctr_analysis::ik::{Ik, IkError, IkOptions, IkResult, IkStatus, MARGIN_SLACK};
use ctr_analysis::model::ModelSpec;
use ctr_core::Status;
use ctr_formats::{IkTarget, RobotSpec, TubeLimits};
use std::collections::BTreeMap;

/// Transmissions this much longer than the seed's make its pair snap, mm.
const EXTRA_TRANSMISSION_MM: f64 = 100.0;
/// The margin floor of the tests (dimensionless: 8 degrees or mm from a snap; a twentieth
/// of the robot's random joints within its ranges are below 0.33, a tenth below 0.7, four
/// fifths at 1).
const MIN_MARGIN: f64 = 0.4;
/// A target made at joints whose margin is this far above the floor is comfortably
/// within it (dimensionless).
const COMFORT: f64 = 0.1;
/// Random targets: the "many" in release builds.
const TARGETS: usize = if cfg!(debug_assertions) { 200 } else { 1000 };
/// Of them, this fraction is drawn at joints of low margin (below [`LOW_MARGIN`]).
const LOW_SHARE: f64 = 0.5;
/// "Low margin" for the targets drawn there (dimensionless).
const LOW_MARGIN: f64 = MIN_MARGIN + 0.2;
/// Feeds of the snapping sweep (`tests/snap.rs`: the tip jumps 50 mm near 200 deg), mm.
const SWEEP_FEEDS_MM: [f64; 2] = [55.0, 95.0];
/// A tip this close to the target, re-solved independently, is at the target, mm.
const AT_TARGET_MM: f64 = 1e-3;

/// The robot within its stated ranges (`data/robots/liu2023.toml`) as `[limits]`.
fn spec() -> RobotSpec {
    let mut spec = sweeps::long_transmissions(EXTRA_TRANSMISSION_MM);
    spec.limits = Some(vec![
        TubeLimits {
            increment_mm: Some([20.0, 70.0]),
            ..Default::default()
        },
        TubeLimits {
            increment_mm: Some([25.0, 95.0]),
            ..Default::default()
        },
    ]);
    spec
}

/// The robot with both feeds pinned at the sweep's: only the rotations move, and a
/// target's relative angle (so its margin) is fixed by the target.
fn pinned_spec() -> RobotSpec {
    let mut spec = sweeps::long_transmissions(EXTRA_TRANSMISSION_MM);
    let pin = |s: f64| TubeLimits {
        s_mm: Some([s, s]),
        ..Default::default()
    };
    spec.limits = Some(vec![pin(SWEEP_FEEDS_MM[0]), pin(SWEEP_FEEDS_MM[1])]);
    spec
}

fn ik(spec: &RobotSpec, min_margin: Option<f64>) -> Ik {
    let options = IkOptions {
        min_margin,
        ..IkOptions::default()
    };
    Ik::from_spec(spec, options).unwrap()
}

fn ik_free(spec: &RobotSpec) -> Ik {
    ik(spec, None)
}

/// Random joints within [`spec`]'s limits (file units).
fn random_joints(rng: &mut Rng) -> Vec<f64> {
    let s1 = 20.0 + 50.0 * rng.uniform();
    let s2 = s1 + 25.0 + 70.0 * rng.uniform();
    vec![
        s1,
        360.0 * rng.uniform() - 180.0,
        s2,
        360.0 * rng.uniform() - 180.0,
    ]
}

/// The independent re-solve: position and margin of the row model's cold FK; `None`
/// where it does not converge (a cold solve of this robot ends at the iteration limit
/// at a few joints, e.g. s = 55, 95 mm 38 degrees apart).
fn try_resolve(model: &ModelSpec, joints: &[f64]) -> Option<([f64; 3], f64)> {
    let r = model
        .rows()
        .unwrap()
        .solver()
        .with_margins()
        .fk(joints)
        .unwrap();
    (r.status == Status::Converged).then_some((r.position, r.stability_margin))
}

/// [`try_resolve`] where it must converge.
fn resolve(model: &ModelSpec, joints: &[f64]) -> ([f64; 3], f64) {
    try_resolve(model, joints).unwrap_or_else(|| panic!("{joints:?}: no cold solve"))
}

/// Checks one result: inside the limits, and its margin (the IK's and re-solved) at
/// least `min_margin`. Returns the re-solved tip and margin.
fn check(ik: &Ik, model: &ModelSpec, r: &IkResult, min_margin: f64) -> ([f64; 3], f64) {
    assert!(ik.limits().contains(&r.q), "{r:?}");
    assert!(
        r.stability_margin >= min_margin + MARGIN_SLACK,
        "the IK's own margin: {r:?}"
    );
    let joints = ik.to_file_units(&r.q);
    let (tip, m) = resolve(model, &joints);
    assert!(
        m >= min_margin,
        "{joints:?}: margin {m} re-solved, {} in the IK",
        r.stability_margin
    );
    (tip, m)
}

/// How the results of one class of targets ended.
#[derive(Default, Debug)]
struct Tally {
    targets: usize,
    statuses: BTreeMap<&'static str, usize>,
    /// re-solved tip within [`AT_TARGET_MM`]
    at_target: usize,
}

impl Tally {
    fn add(&mut self, r: &IkResult, at_target: bool) {
        self.targets += 1;
        *self.statuses.entry(r.status.name()).or_default() += 1;
        self.at_target += usize::from(at_target);
    }
    fn count(&self, status: IkStatus) -> usize {
        self.statuses.get(status.name()).copied().unwrap_or(0)
    }
}

#[test]
fn no_result_is_below_the_margin_over_random_targets() {
    let spec = spec();
    let model = ModelSpec::from_spec(&spec);
    let mut ik = ik(&spec, Some(MIN_MARGIN));
    let mut rng = Rng(0x1d5e_ed01_a2b3_c4d5);
    let (mut comfy, mut near, mut below) = (Tally::default(), Tally::default(), Tally::default());
    let (mut smallest, mut smallest_ik) = (f64::INFINITY, f64::INFINITY);
    let mut iterations = 0;
    let t0 = std::time::Instant::now();
    for k in 0..TARGETS {
        // every other target drawn where the margin is low
        let low = (k as f64 + 0.5) / TARGETS as f64 <= LOW_SHARE;
        // targets where the robot can stand: a converged, stable equilibrium
        let (joints, (goal, margin)) = loop {
            let j = random_joints(&mut rng);
            match try_resolve(&model, &j) {
                Some(solved) if solved.1 > 0.0 && (!low || solved.1 < LOW_MARGIN) => {
                    break (j, solved)
                }
                _ => continue,
            }
        };
        let r = ik.solve(&IkTarget::position(goal), None);
        let (tip, m) = check(&ik, &model, &r, MIN_MARGIN);
        smallest = smallest.min(m);
        smallest_ik = smallest_ik.min(r.stability_margin);
        iterations += r.iterations;
        let class = if margin >= MIN_MARGIN + COMFORT {
            &mut comfy
        } else if margin >= MIN_MARGIN {
            &mut near
        } else {
            &mut below
        };
        class.add(&r, dist(tip, goal) <= AT_TARGET_MM);
        assert!(
            matches!(
                r.status,
                IkStatus::Reached | IkStatus::UnreachableWithMargin
            ),
            "target {k} from {joints:?} (margin {margin}): {r:?}"
        );
    }
    eprintln!(
        "{TARGETS} targets, min_margin {MIN_MARGIN}: {:.2} ms and {:.1} steps per target; \
         smallest margin returned {smallest:.6} re-solved, {smallest_ik:.6} in the IK",
        t0.elapsed().as_secs_f64() * 1e3 / TARGETS as f64,
        iterations as f64 / TARGETS as f64
    );
    for (name, t) in [
        ("made at margin >= floor + comfort", &comfy),
        ("made at margin in [floor, floor + comfort)", &near),
        ("made at margin < floor", &below),
    ] {
        eprintln!(
            "  {name}: {} targets, {:?}, re-solved tip at the target {}",
            t.targets, t.statuses, t.at_target
        );
    }
    // the same targets without the floor (the same number of random draws)
    let mut free = ik_free(&spec);
    let mut rng = Rng(0x1d5e_ed01_a2b3_c4d5);
    let t0 = std::time::Instant::now();
    let (mut free_reached, mut free_at) = (0, 0);
    for k in 0..TARGETS {
        let low = (k as f64 + 0.5) / TARGETS as f64 <= LOW_SHARE;
        let goal = loop {
            match try_resolve(&model, &random_joints(&mut rng)) {
                Some((tip, m)) if m > 0.0 && (!low || m < LOW_MARGIN) => break tip,
                _ => continue,
            }
        };
        let r = free.solve(&IkTarget::position(goal), None);
        free_reached += usize::from(r.status == IkStatus::Reached);
        // (without the floor nothing asks that a cold solve there converge)
        let tip = try_resolve(&model, &free.to_file_units(&r.q)).map(|s| s.0);
        free_at += usize::from(tip.is_some_and(|t| dist(t, goal) <= AT_TARGET_MM));
    }
    eprintln!(
        "  without the floor: {:.2} ms per target (target generation and re-solve included \
         in both), {free_reached} reached, re-solved tip at the target {free_at}",
        t0.elapsed().as_secs_f64() * 1e3 / TARGETS as f64
    );
    // targets comfortably within the floor are reached
    let reached = comfy.count(IkStatus::Reached) as f64 / comfy.targets as f64;
    assert!(comfy.targets >= TARGETS / 3 && reached >= 0.99, "{comfy:?}");
    // below it, the robot is redundant (4 joints, 3 coordinates): a target may be
    // reached on another, stabler configuration; the rest are held back by the margin
    assert!(below.targets >= TARGETS / 10, "{below:?}");
    assert!(below.count(IkStatus::UnreachableWithMargin) >= below.targets / 4);
}

/// Joints of targets at random relative angles, a third of them 13 to 20 degrees from
/// the opposed curvatures (relative angle 0), where the margin falls before the pair
/// snaps (solved cold, below 0.4 from about 16 degrees), tube 1 turned at random.
fn pinned_targets(rng: &mut Rng, count: usize) -> Vec<Vec<f64>> {
    (0..count)
        .map(|k| {
            let rel = if k % 3 == 0 {
                let side = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
                side * (13.0 + 7.0 * rng.uniform())
            } else {
                360.0 * rng.uniform()
            };
            let theta1 = 360.0 * rng.uniform() - 180.0;
            let theta2 = (theta1 + rel + 180.0).rem_euclid(360.0) - 180.0;
            vec![SWEEP_FEEDS_MM[0], theta1, SWEEP_FEEDS_MM[1], theta2]
        })
        .collect()
}

#[test]
fn targets_reachable_only_below_the_margin_are_unreachable_with_margin() {
    let spec = pinned_spec();
    let model = ModelSpec::from_spec(&spec);
    let mut rng = Rng(0x7a26_e75b_e10f_0001);
    let joints = pinned_targets(&mut rng, TARGETS / 2);
    for min_margin in [MIN_MARGIN, 0.8] {
        let mut ik = ik(&spec, Some(min_margin));
        let (mut comfy, mut near, mut below) =
            (Tally::default(), Tally::default(), Tally::default());
        let mut smallest = f64::INFINITY;
        for j in &joints {
            // only where the robot can stand: a converged, stable equilibrium
            let Some((goal, margin)) = try_resolve(&model, j).filter(|s| s.1 > 0.0) else {
                continue;
            };
            let r = ik.solve(&IkTarget::position(goal), None);
            let (tip, m) = check(&ik, &model, &r, min_margin);
            smallest = smallest.min(m);
            let at = dist(tip, goal) <= AT_TARGET_MM;
            if margin >= min_margin + COMFORT {
                comfy.add(&r, at);
                assert_eq!(r.status, IkStatus::Reached, "{j:?} (margin {margin})");
            } else if margin >= min_margin {
                near.add(&r, at);
            } else {
                below.add(&r, at);
                // only this relative angle puts the tip there: it cannot be reached
                assert_eq!(
                    r.status,
                    IkStatus::UnreachableWithMargin,
                    "{j:?} (margin {margin}): {r:?}"
                );
                assert!(r.residual_mm > ik.options().tolerance_mm);
            }
        }
        eprintln!(
            "pinned feeds, min_margin {min_margin}: smallest margin returned {smallest:.6}; \
             comfortable {comfy:?}; near {near:?}; below {below:?}"
        );
        assert!(below.targets >= 10 && comfy.targets >= joints.len() / 2);
    }
}

#[test]
fn a_trajectory_through_a_snap_keeps_the_margin() {
    let spec = pinned_spec();
    let model = ModelSpec::from_spec(&spec);
    // the robot turned a full turn and back at 2 deg a row, solved as it moves
    let params = spec.robot.tube_params();
    let rows = sweeps::full_turn(SWEEP_FEEDS_MM, sweeps::relaxed_deg(&params), 2.0);
    let options = BatchOptions {
        threads: 1,
        chunk_rows: rows.len(),
        margins: true,
    };
    let solved: Vec<_> = batch_fk(
        &model.rows().unwrap(),
        rows.as_flattened(),
        None,
        &options,
        &(),
    )
    .unwrap()
    .into_iter()
    .map(Result::unwrap)
    .collect();
    let targets: Vec<IkTarget> = solved
        .iter()
        .map(|s| IkTarget::position(s.position))
        .collect();
    let mut ik = ik(&spec, Some(MIN_MARGIN));
    let results = ik.solve_trajectory(&targets, None);
    let mut tally = BTreeMap::new();
    for ((r, s), row) in results.iter().zip(&solved).zip(&rows) {
        check(&ik, &model, r, MIN_MARGIN);
        // where the pair is bistable, the robot's branch (the sweep's) and the one a
        // cold solve finds differ; a floor holds for joints only when both clear it
        let cold = resolve(&model, row).1;
        let class = if s.stability_margin < MIN_MARGIN {
            // the robot there is below the floor, and the feeds are pinned
            assert_eq!(r.status, IkStatus::UnreachableWithMargin, "{row:?}: {r:?}");
            "below"
        } else if cold < MIN_MARGIN {
            "within on the sweep's branch, below cold"
        } else if s.stability_margin.min(cold) >= MIN_MARGIN + COMFORT {
            assert_eq!(r.status, IkStatus::Reached, "{row:?}: {r:?}");
            "comfortable"
        } else {
            "near"
        };
        *tally.entry((class, r.status.name())).or_insert(0) += 1;
    }
    eprintln!("full turn and back at s = {SWEEP_FEEDS_MM:?} mm: {tally:?}");
    assert!(tally.keys().any(|(c, _)| *c == "below"), "{tally:?}");
}

#[test]
fn a_start_below_the_margin_is_left_for_one_within_it() {
    let spec = spec();
    let model = ModelSpec::from_spec(&spec);
    let mut rng = Rng(0x0005_7a27_0be1_0001);
    let mut raised = 0;
    let tries = if cfg!(debug_assertions) { 10 } else { 40 };
    for restarts in [0, IkOptions::default().restarts] {
        let options = IkOptions {
            min_margin: Some(MIN_MARGIN),
            restarts,
            ..IkOptions::default()
        };
        let mut ik = Ik::from_spec(&spec, options).unwrap();
        for _ in 0..tries {
            // a start below the floor, a target comfortably within it
            let start = loop {
                let j = random_joints(&mut rng);
                match try_resolve(&model, &j) {
                    Some((_, m)) if m > 0.0 && m < MIN_MARGIN => break j,
                    _ => continue,
                }
            };
            let goal = loop {
                match try_resolve(&model, &random_joints(&mut rng)) {
                    Some((tip, m)) if m >= MIN_MARGIN + COMFORT => break tip,
                    _ => continue,
                }
            };
            let q0 = ik.from_file_units(&start);
            let r = ik.solve(&IkTarget::position(goal), Some(&q0));
            check(&ik, &model, &r, MIN_MARGIN);
            raised += usize::from(r.status == IkStatus::Reached);
        }
    }
    eprintln!("starts below the floor: {raised} of {} reached", 2 * tries);
    assert!(raised >= 2 * tries * 9 / 10);
}

#[test]
fn a_target_outside_the_workspace_stays_unreachable() {
    let spec = spec();
    let model = ModelSpec::from_spec(&spec);
    let mut ik = ik(&spec, Some(MIN_MARGIN));
    let r = ik.solve(&IkTarget::position([500.0, 0.0, 0.0]), None);
    check(&ik, &model, &r, MIN_MARGIN);
    eprintln!("far target: {:?}, margin {}", r.status, r.stability_margin);
    assert!(r.residual_mm > 300.0);
    assert!(matches!(
        r.status,
        IkStatus::Unreachable | IkStatus::UnreachableWithMargin
    ));
}

#[test]
fn the_floor_is_checked_when_the_solver_is_built() {
    let spec = spec();
    let build = |min_margin: f64, seed_samples: usize| {
        let options = IkOptions {
            min_margin: Some(min_margin),
            seed_samples,
            ..IkOptions::default()
        };
        Ik::from_spec(&spec, options).map(|_| ())
    };
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        match build(bad, 16) {
            Err(IkError::Option { name, .. }) => assert_eq!(name, "min_margin"),
            other => panic!("{bad}: {other:?}"),
        }
    }
    // no joints are that stable: a margin is at most 1
    let e = build(100.0, 64).unwrap_err();
    assert!(
        matches!(e, IkError::MinMargin { samples: 64, largest, .. } if largest == 1.0),
        "{e:?}"
    );
    assert!(e.to_string().contains("min_margin = 100"), "{e}");
    // no table to start from
    let e = build(MIN_MARGIN, 0).unwrap_err();
    assert!(matches!(e, IkError::MinMargin { samples: 0, .. }), "{e:?}");
    assert!(e.to_string().contains("seed_samples = 0"), "{e}");
    assert!(build(MIN_MARGIN, 64).is_ok());
}

#[test]
fn without_a_floor_the_result_reports_the_margin_and_may_go_below() {
    // the same low-margin targets without min_margin: reached, some below the floor
    // (what the floor prevents)
    let spec = pinned_spec();
    let model = ModelSpec::from_spec(&spec);
    let mut free = ik(&spec, None);
    let mut rng = Rng(0x7a26_e75b_e10f_0002);
    let mut below = 0;
    for j in pinned_targets(&mut rng, 60) {
        let Some((goal, margin)) = try_resolve(&model, &j).filter(|s| s.1 > 0.0) else {
            continue;
        };
        let r = free.solve(&IkTarget::position(goal), None);
        assert_eq!(r.status, IkStatus::Reached, "{j:?}");
        below += usize::from(margin < MIN_MARGIN && r.stability_margin < MIN_MARGIN);
    }
    assert!(below > 0);
}

//! Property tests of the inverse kinematics over random robots (1 to 4 tubes, as
//! `ctr_suite::props::robot` draws them) and random `[limits]`: FK(IK(FK(q))) = FK(q)
//! for reachable targets, and no joint vector the IK ever evaluates leaves the limits.
//!
//! Case counts (CI; `PROPTEST_CASES=n` runs `n` of each instead):
//!
//! | property | cases |
//! |---|---|
//! | [`ik_of_a_reachable_target_reaches_it`] | 48 |
//! | [`no_iterate_leaves_the_limits`] | 48 |
use ctr_analysis::ik::{Ik, IkOptions, IkStatus};
use ctr_core::{Model, TubeParams};
use ctr_formats::{AnyRobot, IkTarget, TubeLimits};
use ctr_suite::props;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

/// A robot, limits for it (feed increments of 5 to 60 mm from 0 to 30 mm, rotation
/// ranges of 30 to 360 degrees anywhere in [-360, 360]), and `2 n` fractions.
fn case() -> impl Strategy<Value = (Vec<TubeParams<f64>>, Vec<TubeLimits>, Vec<f64>)> {
    (1..=4usize).prop_flat_map(|n| {
        (
            props::robot(n),
            proptest::collection::vec(
                (0.0..30.0f64, 5.0..60.0f64, -360.0..0.0f64, 30.0..360.0f64).prop_map(
                    |(lo, w, t0, tw)| TubeLimits {
                        s_mm: None,
                        increment_mm: Some([lo, lo + w]),
                        theta_deg: Some([t0, t0 + tw]),
                    },
                ),
                n,
            ),
            proptest::collection::vec(0.0..1.0f64, 2 * n),
        )
    })
}

/// The robot with its precurvatures scaled down, if need be, to 0.9 of the uniqueness
/// bound of the twist problem (a strictly convex elastic energy: one equilibrium at
/// every joint value; `ctr-core/tests/properties.rs`, `uniqueness_ratio`, derives it).
/// Where several equilibria exist, FK(IK(x)) solved cold may rightly find another one.
fn unique(params: &[TubeParams<f64>]) -> Vec<TubeParams<f64>> {
    let n = params.len();
    let k: Vec<f64> = params
        .iter()
        .map(|t| t.curvature_radius_mm.map_or(0.0, |r| 1.0 / r))
        .collect();
    let second = |t: &TubeParams<f64>| {
        std::f64::consts::PI * (t.outer_diameter_mm.powi(4) - t.inner_diameter_mm.powi(4)) / 64.0
    };
    let ei: Vec<f64> = params
        .iter()
        .map(|t| t.youngs_modulus_mpa * second(t))
        .collect();
    let gj: Vec<f64> = params
        .iter()
        .map(|t| t.youngs_modulus_mpa / (1.0 + t.poisson_ratio) * second(t))
        .collect();
    let ratio = (0..n)
        .map(|i| {
            let c: f64 = (0..n)
                .filter(|&l| l != i)
                .map(|l| ei[i] * ei[l] * (k[i] * k[l]).abs() / (ei[i] + ei[l]))
                .sum();
            let l = params[i].length_mm;
            2.0 * c / (gj[i] * (std::f64::consts::PI / (2.0 * l)).powi(2))
        })
        .fold(0.0, f64::max);
    let factor = (ratio / 0.9).sqrt().max(1.0);
    params
        .iter()
        .map(|t| TubeParams {
            curvature_radius_mm: t.curvature_radius_mm.map(|r| r * factor),
            ..*t
        })
        .collect()
}

/// Further starts from the table after the first (the IK's default is 8). A kink of
/// the forward kinematics (here a curved part's start at the guide exit, `s_1` equal
/// to its curved length) is a trap for the Levenberg-Marquardt steps: the linear model
/// of one side predicts a decrease across it that the other side's slope undoes, the
/// steps shrink onto it and the start stalls there. In one target of 20,000 (the
/// four-tube case in this property's regression file) the nine starts nearest the
/// target all ended on that kink, 0.063 mm away; the tenth reached it. The property
/// claims the target is reached from the table, so it lets more starts try.
const REACH_RESTARTS: u32 = 32;

/// The IK of a robot within `limits`, with a table of 64 starts and `restarts` further
/// starts; `None` where the limits leave no joints.
fn ik(params: &[TubeParams<f64>], limits: &[TubeLimits], restarts: u32) -> Option<Ik> {
    let robot = AnyRobot::new(params).expect("valid robot");
    let options = IkOptions {
        seed_samples: 64,
        restarts,
        ..Default::default()
    };
    // limits that leave no joint vector within the tube lengths are refused (typed)
    Ik::new(&robot, Model::Torsion, Some(limits), options).ok()
}

/// On a robot with one equilibrium at every joint value (see [`unique`]), a target the
/// robot reaches inside its limits (the tip at random joints there, solved cold) is
/// reached by a cold IK: status `reached`, its tip within the tolerance of the
/// target, the joints inside the limits; where the joints found solve cold, that tip
/// is within the tolerance too.
#[test]
fn ik_of_a_reachable_target_reaches_it() {
    let cold_failures = std::cell::RefCell::new(0usize);
    props::check(
        file!(),
        "ik_of_a_reachable_target_reaches_it",
        48,
        case(),
        |(params, limits, u)| {
            let params = unique(&params);
            let Some(mut ik) = ik(&params, &limits, REACH_RESTARTS) else {
                return Err(TestCaseError::reject("limits leave no joints"));
            };
            let q = ik.limits().point(&u);
            let Some(tip) = ik.fk(&q) else {
                return Err(TestCaseError::reject("FK does not converge there"));
            };
            let target = IkTarget::position(tip.position.into());
            let r = ik.solve(&target, None);
            prop_assert!(ik.limits().contains(&r.q), "{:?} outside the limits", r.q);
            prop_assert_eq!(r.status, IkStatus::Reached, "{:?} from q = {:?}", r, q);
            let d = (r.tip.position - tip.position).norm();
            prop_assert!(
                d <= ik.options().tolerance_mm,
                "IK's tip {d} mm from the target"
            );
            // FK(IK): the joints found, solved again cold; where that does not converge
            // (the solver's limits of `ctr-core/tests/found_by_properties.rs`), counted
            match ik.fk(&r.q) {
                Some(again) => {
                    let d = (again.position - tip.position).norm();
                    prop_assert!(
                        d <= ik.options().tolerance_mm,
                        "FK(IK) {d} mm from the target"
                    );
                }
                None => *cold_failures.borrow_mut() += 1,
            }
            Ok(())
        },
    );
    eprintln!(
        "FK(IK) solved cold did not converge for {} targets",
        cold_failures.borrow()
    );
}

/// For any target, near or far, every joint vector the IK solves the forward kinematics
/// at (iterates and trial steps) is inside the limits and valid for the robot, and so
/// is the result.
#[test]
fn no_iterate_leaves_the_limits() {
    let strategy = (case(), proptest::array::uniform3(-400.0..400.0f64));
    props::check(
        file!(),
        "no_iterate_leaves_the_limits",
        48,
        strategy,
        |((params, limits, u), far)| {
            let Some(mut ik) = ik(&params, &limits, IkOptions::default().restarts) else {
                return Err(TestCaseError::reject("limits leave no joints"));
            };
            let robot = AnyRobot::new(&params).expect("valid robot");
            let q0 = ik.limits().point(&u);
            let mut outside = Vec::new();
            let mut seen = 0usize;
            let target = IkTarget::position(far);
            let r = ik.solve_observed(&target, Some(&q0), &mut |q| {
                seen += 1;
                let file = ik_file_units(q);
                if robot.validate_joints(&file).is_err() {
                    outside.push(q.to_vec());
                }
            });
            prop_assert!(seen > 0);
            prop_assert!(
                outside.is_empty(),
                "iterates outside the core's ranges: {outside:?}"
            );
            prop_assert!(ik.limits().contains(&r.q), "{:?}", r);
            Ok(())
        },
    );
}

/// mm, rad to mm, degrees.
fn ik_file_units(q: &[f64]) -> Vec<f64> {
    q.iter()
        .enumerate()
        .map(|(k, v)| if k % 2 == 1 { v.to_degrees() } else { *v })
        .collect()
}

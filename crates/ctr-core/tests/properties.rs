//! Property tests of the solve over random physical robots (1 to 4 tubes, the ranges of
//! `ctr_suite::props::robot`) and random joints over the whole range, also outside the
//! robot's range and the stable one.
//!
//! Case counts (CI; `PROPTEST_CASES=n` runs `n` of each instead):
//!
//! | property | cases |
//! |---|---|
//! | [`every_solve_is_a_finite_pose_or_a_typed_error`] | 384 |
//! | [`cold_and_warm_starts_agree_where_the_solution_is_unique`] | 256 |
//! | [`the_tip_is_continuous_along_small_steps_away_from_the_snap`] | 128 |
//! | [`joint_jacobian_is_central_differences`] | 192 |
//! | [`torsion_tends_to_the_rigid_closed_form_as_gj_grows`] | 192 |
//!
//! Where a property needs a precondition it is stated with the physics behind it:
//! uniqueness of the twist solution (a strictly convex elastic energy, below), a
//! stability margin away from zero (the snap), no two section cuts within the
//! difference step (the kinks of the forward kinematics).
use ctr_core::nalgebra::{Matrix3, Rotation3, Vector3, Vector6};
use ctr_core::{
    JointError, JointJacobian, Joints, Model, Request, Robot, SolveError, Solver, SolverConfig,
    Status, TubeParams,
};
use ctr_suite::props;
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use std::cell::RefCell;
use std::f64::consts::PI;

/// Fractions of the feed ranges and angles (degrees) for joints on a robot.
type Fractions = (Vec<f64>, Vec<f64>);

/// A robot of `n` tubes and `k` sets of fractions and angles for joints on it.
fn robot_and_draws(
    n: std::ops::RangeInclusive<usize>,
    k: usize,
) -> impl Strategy<Value = (Vec<TubeParams<f64>>, Vec<Fractions>)> {
    n.prop_flat_map(move |n| {
        (
            props::robot(n),
            proptest::collection::vec(
                (
                    proptest::collection::vec(0.0..=1.0f64, n),
                    proptest::collection::vec(-400.0..400.0f64, n),
                ),
                k,
            ),
        )
    })
}

/// Calls `f::<N>` with the tube count of `params` as `N`.
macro_rules! with_n {
    ($params:expr, $f:ident ( $($arg:expr),* )) => {
        match $params.len() {
            1 => $f::<1>($($arg),*),
            2 => $f::<2>($($arg),*),
            3 => $f::<3>($($arg),*),
            4 => $f::<4>($($arg),*),
            n => unreachable!("{n} tubes"),
        }
    };
}

fn robot_of<const N: usize>(params: &[TubeParams<f64>]) -> Robot<f64, N> {
    let p: [TubeParams<f64>; N] = params.try_into().expect("N tubes");
    Robot::new(p).expect("the generator draws valid robots")
}

fn lengths(params: &[TubeParams<f64>]) -> Vec<f64> {
    params.iter().map(|t| t.length_mm).collect()
}

/// Valid joints from fractions and angles (see [`props::valid_joints`]).
fn joints<const N: usize>(params: &[TubeParams<f64>], u: &[f64], theta: &[f64]) -> Joints<f64, N> {
    let (s, t) = props::valid_joints(&lengths(params), u, theta);
    Joints::from_mm_deg(
        s.try_into().expect("N feeds"),
        t.try_into().expect("N angles"),
    )
}

/// A solver converged to machine precision (finite differences of it are exact to ~1e-10).
fn tight<const N: usize>() -> Solver<f64, N> {
    Solver::new(SolverConfig {
        step_tolerance_per_mm: 1e-13,
        residual_tolerance_per_mm: 1e-14,
        ..Default::default()
    })
}

/// Distance between the tips of two solutions: position (mm) and orientation (rad).
fn tip_distance(a: &ctr_core::Frame<f64>, b: &ctr_core::Frame<f64>) -> (f64, f64) {
    (
        (a.position - b.position).norm(),
        a.orientation().angle_to(&b.orientation()),
    )
}

// ---------------------------------------------------------------- finite or typed error

/// One joint value drawn over the whole range: mostly ordinary numbers inside and
/// outside the robot's range, sometimes the edges, sometimes not a number.
fn any_joint_value(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        12 => lo..hi,
        1 => Just(0.0),
        1 => prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY), Just(-0.0), Just(1e300), Just(-1e300), Just(f64::MIN_POSITIVE)],
    ]
}

/// For every robot and joints anywhere: `solve` returns `Err` exactly when the joints
/// are invalid for the robot (the core's own check, a typed [`JointError`]), and
/// otherwise a pose whose every number is finite with a rotation that is a rotation,
/// whatever the status; a converged solve meets its residual tolerance. Solves run
/// warm along the draws (the solver's memory carried), as a controller runs them,
/// under both models, with the default settings or coarse steps and few iterations.
#[test]
fn every_solve_is_a_finite_pose_or_a_typed_error() {
    let stats = RefCell::new([0usize; 4]); // converged, iteration limit, diverged, refused
    let strategy = (1..=4usize).prop_flat_map(|n| {
        props::robot(n).prop_flat_map(move |params| {
            let draws = params
                .iter()
                .map(|t| {
                    (
                        prop_oneof![
                            // valid fractions of the range
                            3 => (0.0..=1.0f64).prop_map(|u| (u, true)),
                            // anything
                            1 => any_joint_value(-30.0, t.length_mm + 30.0).prop_map(|s| (s, false)),
                        ],
                        any_joint_value(-2000.0, 2000.0),
                    )
                })
                .collect::<Vec<_>>();
            (
                Just(params),
                proptest::collection::vec(draws, 1..6),
                any::<bool>(),
                config(),
            )
        })
    });
    props::check(
        file!(),
        "every_solve_is_a_finite_pose_or_a_typed_error",
        384,
        strategy,
        |(params, draws, rigid, config)| {
            with_n!(
                params,
                finite_or_error(&params, &draws, rigid, config, &stats)
            )
        },
    );
    let [c, l, d, r] = *stats.borrow();
    eprintln!("solves: {c} converged, {l} at the iteration limit, {d} diverged, {r} refused");
}

/// Solver settings: the defaults, or a user's coarser steps and tighter iteration
/// bounds (a firmware loop with a fixed budget).
fn config() -> impl Strategy<Value = SolverConfig<f64>> {
    prop_oneof![
        1 => Just(SolverConfig::default()),
        1 => (1u32..=30, 0.05..1.0f64, 1.0..100.0f64).prop_map(|(it, fraction, h)| SolverConfig {
            max_iterations: it,
            step_fraction: fraction,
            max_step_mm: h,
            ..SolverConfig::default()
        }),
    ]
}

type Draw = ((f64, bool), f64);

fn finite_or_error<const N: usize>(
    params: &[TubeParams<f64>],
    draws: &[Vec<Draw>],
    rigid: bool,
    config: SolverConfig<f64>,
    stats: &RefCell<[usize; 4]>,
) -> Result<(), TestCaseError> {
    let robot = robot_of::<N>(params);
    let model = if rigid { Model::Rigid } else { Model::Torsion };
    let mut solver = Solver::<f64, N>::new(config);
    for draw in draws {
        // fractions become valid feeds, in order; the others are taken as drawn
        let mut s = [0.0; N];
        let mut prev = 0.0;
        for i in 0..N {
            let ((v, fraction), _) = draw[i];
            s[i] = if fraction {
                prev + (params[i].length_mm - prev) * v
            } else {
                v
            };
            if s[i].is_finite() {
                prev = s[i].max(prev);
            }
        }
        let theta: [f64; N] = core::array::from_fn(|i| draw[i].1);
        let q = Joints::from_mm_deg(s, theta);
        let valid = q.validate(&robot);
        match (solver.solve(&robot, Request::new(q, model)), valid) {
            (Err(e), Err(v)) => {
                prop_assert_eq!(e, SolveError::Joint(v));
                stats.borrow_mut()[3] += 1;
            }
            (Err(e), Ok(())) => {
                return Err(TestCaseError::fail(format!(
                    "valid joints {q:?} refused: {e}"
                )))
            }
            (Ok(sol), Err(v)) => {
                return Err(TestCaseError::fail(format!(
                    "invalid joints {q:?} ({v}) solved: {sol:?}"
                )))
            }
            (Ok(sol), Ok(())) => {
                let tip = &sol.tip;
                prop_assert!(
                    tip.position
                        .iter()
                        .chain(tip.rotation.iter())
                        .all(|v| v.is_finite()),
                    "{:?} at {:?}: tip not finite: {:?}",
                    sol.status,
                    q,
                    tip
                );
                let orthonormal =
                    (tip.rotation.transpose() * tip.rotation - Matrix3::identity()).norm() < 1e-9
                        && (tip.rotation.determinant() - 1.0).abs() < 1e-9;
                prop_assert!(orthonormal, "not a rotation: {:?}", tip.rotation);
                prop_assert!(sol.residual_per_mm.is_finite(), "{:?}", sol);
                prop_assert!(sol.softest_mode.is_finite(), "{:?}", sol);
                prop_assert!(
                    sol.base_twist_per_mm
                        .iter()
                        .chain(&sol.base_angle_rad)
                        .all(|v| v.is_finite()),
                    "{:?}",
                    sol
                );
                let k = match sol.status {
                    Status::Converged => {
                        // the pose is where the tubes can put it: within the innermost
                        // tube's reach of the guide exit (an unconverged iterate's
                        // pose, with steps too coarse for its twist, need not be)
                        prop_assert!(tip.position.norm() <= s[N - 1] + 1e-9, "{:?}", sol);
                        prop_assert!(
                            sol.residual_per_mm <= solver.config.residual_tolerance_per_mm,
                            "{:?}",
                            sol
                        );
                        0
                    }
                    Status::IterationLimit => 1,
                    Status::Diverged => 2,
                };
                stats.borrow_mut()[k] += 1;
            }
        }
    }
    Ok(())
}

/// The error names what is wrong, with the tube, as the core checks it.
#[test]
fn refused_joints_name_the_tube() {
    let params = [TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33)];
    let robot = Robot::new(params).unwrap();
    let err = Solver::default()
        .solve(
            &robot,
            Request::new(Joints::new([f64::NAN], [0.0]), Model::Torsion),
        )
        .unwrap_err();
    assert_eq!(
        err,
        SolveError::Joint(JointError::NotFinite {
            tube: 1,
            kind: ctr_core::JointKind::Feed
        })
    );
    assert_eq!(err.to_string(), "s1_mm must be a finite number");
}

// ---------------------------------------------------------------- uniqueness

/// How far a robot is from the twist problem's uniqueness bound, as a ratio (< 1: the
/// solution is unique at every joint value).
///
/// The twist problem ([`ctr_core::integrate::twist`]) is the Euler-Lagrange equation of
/// the elastic energy `E[psi] = sum_i int G_i J_i psi_i'^2 / 2 - int sum_{i<l} c_il
/// cos(psi_i - psi_l)`, `c_il = K_i k_i K_l k_l / sum_present K` (K = E I), each
/// `psi_i` held at its actuator and free at its tip. Its second variation is at least
/// `sum_i int (G_i J_i (pi / 2 L_i)^2 - 2 sum_l |c_il|) dpsi_i^2` (Wirtinger's inequality
/// on a clamped-free interval of the tube's whole length `L_i`, and
/// `(a - b)^2 <= 2 a^2 + 2 b^2`). Where every `2 sum_l max |c_il|`, bounded with
/// `sum_present K >= K_i + K_l`, is below `G_i J_i (pi / 2 L_i)^2`, the energy is
/// strictly convex and has one critical point: one solution for every joint value.
fn uniqueness_ratio<const N: usize>(robot: &Robot<f64, N>) -> f64 {
    let t = robot.tubes();
    (0..N)
        .map(|i| {
            let coupling: f64 = (0..N)
                .filter(|&l| l != i)
                .map(|l| {
                    let (ki, kl) = (t[i].bending_stiffness_nmm2(), t[l].bending_stiffness_nmm2());
                    ki * kl * (t[i].curvature_per_mm() * t[l].curvature_per_mm()).abs() / (ki + kl)
                })
                .sum();
            let wirtinger =
                t[i].torsional_stiffness_nmm2() * (PI / (2.0 * t[i].params().length_mm)).powi(2);
            2.0 * coupling / wirtinger
        })
        .fold(0.0, f64::max)
}

/// Where the twist solution is unique (the robot's precurvatures scaled down, if need
/// be, until [`uniqueness_ratio`] is 0.9), a solve reaches the same tip cold and warm
/// started from the solver's memory of other configurations: both converge, and,
/// solved to the tight tolerances (1e-14 rad/mm), their tips agree within 1e-7 mm and
/// 1e-7 rad (distinct equilibria are millimetres and degrees apart). (At the default
/// tolerances they agree to ~2e-6 mm only: the residual bounds twist rates, not
/// torques, and the innermost tube's base twist rate is the outer tubes' residual times
/// their G J ratio, up to 1e4 here.) For the same robots unscaled, where several
/// solutions may exist, the cases where cold and warm starts end on different solutions
/// are counted and printed, not asserted: that is physics, not a fault.
///
/// Any torsional stiffness contrast: where a tube ends with a torque left (a Newton
/// iterate's residual), tube n's twist rate jumps by the G J ratio times it, and the
/// RK4 steps of a coupled section are cut to keep every relative angle's turn per step
/// small at the rates they start with (`MAX_TURN_PER_STEP` in the core). Before that a
/// cold solve of a 0.44 mm wire inside 2 mm nitinol tubes (G J contrast 629) ended
/// `Diverged`, RK4 unstable at the rates of the iterates, and so did a 0.26 mm fibre
/// (4.7e4; `found_by_properties`).
#[test]
fn cold_and_warm_starts_agree_where_the_solution_is_unique() {
    let differ = RefCell::new([0usize; 2]);
    props::check(
        file!(),
        "cold_and_warm_starts_agree_where_the_solution_is_unique",
        256,
        robot_and_draws(2..=4, 3),
        |(params, draws)| with_n!(params, cold_and_warm(&params, &draws, &differ)),
    );
    let [d, n] = *differ.borrow();
    eprintln!("unrestricted robots: cold and warm starts on different solutions in {d} of {n} converged pairs");
}

fn cold_and_warm<const N: usize>(
    params: &[TubeParams<f64>],
    draws: &[(Vec<f64>, Vec<f64>)],
    differ: &RefCell<[usize; 2]>,
) -> Result<(), TestCaseError> {
    let robot = robot_of::<N>(params);
    let ratio = uniqueness_ratio(&robot);
    let factor = (ratio / 0.9).sqrt().max(1.0);
    let unique = robot.scaled([1.0; N], [factor; N]).expect("factor >= 1");
    prop_assert!(uniqueness_ratio(&unique) <= 0.9 + 1e-12);
    let qs: Vec<Joints<f64, N>> = draws
        .iter()
        .map(|(u, t)| joints::<N>(params, u, t))
        .collect();
    let q = qs[2];
    for (r, asserted) in [(&unique, true), (&robot, false)] {
        let mut warm = tight::<N>();
        for p in &qs[..2] {
            warm.solve(r, Request::new(*p, Model::Torsion))
                .expect("valid joints");
        }
        let w = warm
            .solve(r, Request::new(q, Model::Torsion))
            .expect("valid joints");
        let c = tight::<N>()
            .solve(r, Request::new(q, Model::Torsion).cold())
            .expect("valid joints");
        let (dp, dr) = tip_distance(&w.tip, &c.tip);
        if asserted {
            prop_assert_eq!(w.status, Status::Converged, "warm {:?}", w);
            prop_assert_eq!(c.status, Status::Converged, "cold {:?}", c);
            prop_assert!(
                dp <= 1e-7 && dr <= 1e-7,
                "warm and cold differ by {dp:e} mm, {dr:e} rad at {q:?}: warm {w:?}, cold {c:?}"
            );
        } else if w.status == Status::Converged && c.status == Status::Converged {
            let mut d = differ.borrow_mut();
            d[1] += 1;
            d[0] += usize::from(dp > 1e-6);
        }
    }
    Ok(())
}

/// Largest ratio of the tubes' torsional stiffnesses the continuity property is
/// asserted for (see [`the_tip_is_continuous_along_small_steps_away_from_the_snap`]).
const MAX_GJ_CONTRAST: f64 = 1e4;

/// The largest ratio of two tubes' torsional stiffnesses.
fn gj_contrast<const N: usize>(robot: &Robot<f64, N>) -> f64 {
    let gj = robot.tubes().map(|t| t.torsional_stiffness_nmm2());
    gj.iter().fold(0.0, |a: f64, &b| a.max(b)) / gj.iter().fold(f64::MAX, |a, &b| a.min(b))
}

// ---------------------------------------------------------------- continuity

/// Steps ahead within which the path stops when the fold is predicted there.
const FOLD_STEPS_AHEAD: f64 = 2.0;
/// Softest mode below which the path stops: a nearly neutral equilibrium.
const SOFTEST_MODE_FLOOR: f64 = 0.05;

/// Along a path of small joint steps (0.05 mm of feed and 0.05 degrees of rotation at
/// most per joint, 40 steps in a random direction) solved warm, as a controller does,
/// the tip moves by at most twice what the Jacobian at either end predicts (plus 1e-6
/// mm): no jump. The path stops where the joints leave the robot's range or a snap is
/// ahead: at a snap the tip jumps by design.
///
/// Known limit, stated as a precondition: the tubes' torsional stiffnesses within
/// [`MAX_GJ_CONTRAST`] of each other. Beyond it the innermost tube (a 0.2 mm wire inside
/// nitinol tubes, G J contrast 6e4, in this property's regression file) twists at rates
/// the default steps resolve only to about a percent of a turn per step; its many
/// nearly neutral equilibria (softest modes of +-0.07) are then not told apart, and
/// warm solves 0.05 mm and degrees apart land on different ones, the tip jumping
/// 16 to 135 mm (at a fifth of the default step fraction the path is continuous).
///
/// Where the snap is: at a fold the softest mode `sigma` (`Solution::softest_mode`)
/// vanishes as the square root of the joint distance left, so `sigma^2` falls linearly
/// along the path as the fold comes near. The path stops where the fall of `sigma^2`
/// over the last step, carried on, reaches zero within [`FOLD_STEPS_AHEAD`] steps (a
/// floor on `sigma` alone is not a distance: its scale differs from robot to robot, and
/// a path of `sigma` 0.11 then 0.073 crossed the fold in the next step, the tip
/// jumping 17 mm), or where `sigma` is below [`SOFTEST_MODE_FLOOR`]: there the
/// equilibrium is nearly neutral, the tip's sensitivity grows as `1 / sigma`, and a
/// step's motion is no longer what the Jacobians at its ends predict (at `sigma` 5e-4,
/// flat along the path, the tip moved 2.7 mm per step before jumping 150 mm). Both
/// cases are in this property's regression file. The first step only measures the fall
/// of `sigma^2`: it is not checked.
#[test]
fn the_tip_is_continuous_along_small_steps_away_from_the_snap() {
    let steps = RefCell::new([0usize; 2]);
    let strategy = (1..=4usize).prop_flat_map(|n| {
        (
            props::robot(n),
            proptest::collection::vec(0.0..=1.0f64, n),
            proptest::collection::vec(-400.0..400.0f64, n),
            proptest::collection::vec(-1.0..=1.0f64, 2 * n),
        )
    });
    props::check(
        file!(),
        "the_tip_is_continuous_along_small_steps_away_from_the_snap",
        128,
        strategy,
        |(params, u, theta, dir)| with_n!(params, continuity(&params, &u, &theta, &dir, &steps)),
    );
    let [taken, cut] = *steps.borrow();
    eprintln!("continuity: {taken} steps checked; {cut} paths stopped near the snap");
}

/// True when the softest mode, `before` and `now` one step later, says a snap is near:
/// below [`SOFTEST_MODE_FLOOR`], or `sigma^2` falling to zero within
/// [`FOLD_STEPS_AHEAD`] more steps (see the continuity property).
fn snap_ahead(before: f64, now: f64) -> bool {
    let fall = before * before - now * now;
    now < SOFTEST_MODE_FLOOR || (fall > 0.0 && now * now <= FOLD_STEPS_AHEAD * fall)
}

fn continuity<const N: usize>(
    params: &[TubeParams<f64>],
    u: &[f64],
    theta: &[f64],
    dir: &[f64],
    steps: &RefCell<[usize; 2]>,
) -> Result<(), TestCaseError> {
    const STEP: f64 = 0.05;
    let robot = robot_of::<N>(params);
    prop_assume!(gj_contrast(&robot) <= MAX_GJ_CONTRAST);
    let q0 = joints::<N>(params, u, theta);
    let mut solver = Solver::<f64, N>::default();
    let mut prev: Option<(
        ctr_core::Solution<f64, N>,
        JointJacobian<f64, N>,
        Joints<f64, N>,
    )> = None;
    // whether the last step measured the fall of sigma^2 (none before the first)
    let mut fall_known = false;
    for k in 0..=41 {
        let t = k as f64 * STEP;
        let q = Joints::new(
            core::array::from_fn(|i| q0.s_mm[i] + t * dir[i]),
            core::array::from_fn(|i| q0.theta_rad[i] + (t * dir[N + i]).to_radians()),
        );
        if q.validate(&robot).is_err() {
            break;
        }
        let mut jac = JointJacobian::nan();
        let sol = solver
            .solve(
                &robot,
                Request::new(q, Model::Torsion).joint_jacobian(&mut jac),
            )
            .expect("valid joints");
        if sol.status != Status::Converged || sol.softest_mode < SOFTEST_MODE_FLOOR {
            steps.borrow_mut()[1] += 1;
            break;
        }
        if let (Some((p, pj, pq)), true) = (&prev, fall_known) {
            let predicted = |j: &JointJacobian<f64, N>| {
                let mut v = Vector6::zeros();
                for i in 0..N {
                    v += j.feed[i] * (q.s_mm[i] - pq.s_mm[i])
                        + j.rotation[i] * (q.theta_rad[i] - pq.theta_rad[i]);
                }
                v.fixed_rows::<3>(0).norm()
            };
            let bound = 2.0 * predicted(pj).max(predicted(&jac)) + 1e-6;
            let moved = (sol.tip.position - p.tip.position).norm();
            prop_assert!(
                moved <= bound,
                "step {k} from {pq:?} to {q:?}: the tip moved {moved} mm, the Jacobians allow {bound} (softest modes {} and {})",
                p.softest_mode,
                sol.softest_mode
            );
            steps.borrow_mut()[0] += 1;
        }
        if let Some((p, _, _)) = &prev {
            if snap_ahead(p.softest_mode, sol.softest_mode) {
                steps.borrow_mut()[1] += 1;
                break;
            }
            fall_known = true;
        }
        prev = Some((sol, jac, q));
    }
    Ok(())
}

// ---------------------------------------------------------------- Jacobian

/// Central-difference step: mm for feeds, rad for rotations.
const FD_STEP: f64 = 1e-4;
/// Largest accepted relative error of a Jacobian column against its central
/// difference (position and orientation blocks apart).
const FD_RTOL: f64 = 1e-5;
/// ... plus this absolute error (mm or rad per mm or rad): the differences' rounding
/// floor. A tight solve stops at the rounding floor of its integration (residuals of
/// 1e-16 to 1e-14 rad/mm), so neighbouring solves scatter about the smooth tip: by up
/// to ~1e-10 mm and rad where the tip is sensitive to the twist (second differences of
/// 1e-5 mm feed steps of ±8e-11 mm and ±3e-10 rad on a case of this property's
/// regression file, a 20 mm radius tube over 160 mm). Over the step `2 FD_STEP` that
/// is up to ~1e-6, three times it the floor.
const FD_ATOL: f64 = 3e-6;
/// Closest fold (snap) along a column's joint at which the column is compared, in
/// difference steps. Near a fold the tip goes as the square root of the joint distance
/// `d` left, and a central difference of step `h` is off by `(h / d)^2 / 8` of the
/// derivative: 1.4e-6 at 300 steps, well inside [`FD_RTOL`]. `d` is estimated from the
/// softest mode `sigma` (`Solution::softest_mode`), which also goes as `sqrt(d)`:
/// `d = sigma / (2 |d sigma / d q|)`, the derivative from the two differences' own
/// `sigma`. (A floor on `sigma` itself is not a distance: a column at `sigma` 0.17,
/// 0.009 rad from the fold, was off by 1.1e-5: the case in this property's regression
/// file.)
const FOLD_STEPS: f64 = 300.0;

/// The joint Jacobian equals central differences of the solve (both tight, the
/// differences warm-started from the centre's solution so that they stay on its
/// branch), at random valid joints of random robots, under both models. Preconditions:
/// the centre converges on a stable equilibrium, the fold is at least [`FOLD_STEPS`]
/// difference steps away along every column's joint; no two section cuts (the guide
/// exit, each tip, each curved part's start) lie within 100 steps of each other and no
/// feed is within 2 steps of its bounds: there the forward kinematics has a kink and
/// only one-sided derivatives.
#[test]
fn joint_jacobian_is_central_differences() {
    let compared = RefCell::new(0usize);
    props::check(
        file!(),
        "joint_jacobian_is_central_differences",
        192,
        (robot_and_draws(1..=4, 1), any::<bool>()),
        |((params, draws), rigid)| {
            let (u, t) = &draws[0];
            with_n!(params, jacobian_matches(&params, u, t, rigid, &compared))
        },
    );
    eprintln!("jacobian: {} configurations compared", compared.borrow());
}

fn jacobian_matches<const N: usize>(
    params: &[TubeParams<f64>],
    u: &[f64],
    theta: &[f64],
    rigid: bool,
    compared: &RefCell<usize>,
) -> Result<(), TestCaseError> {
    let robot = robot_of::<N>(params);
    let q = joints::<N>(params, u, theta);
    let model = if rigid { Model::Rigid } else { Model::Torsion };
    // the kinks: cuts too close together, feeds at their bounds
    let mut cuts = vec![0.0];
    for (i, t) in robot.tubes().iter().enumerate() {
        cuts.push(q.s_mm[i]);
        if t.curvature_per_mm() != 0.0 && t.params().curved_length_mm > 0.0 {
            cuts.push(q.s_mm[i] - t.params().curved_length_mm);
        }
    }
    let close = cuts.iter().enumerate().any(|(a, x)| {
        cuts[a + 1..]
            .iter()
            .any(|y| (x - y).abs() < 100.0 * FD_STEP)
    });
    let at_bounds = (0..N).any(|i| q.s_mm[i] > params[i].length_mm - 2.0 * FD_STEP);
    prop_assume!(!close && !at_bounds);
    let mut center = tight::<N>();
    let mut jac = JointJacobian::nan();
    let sol = center
        .solve(&robot, Request::new(q, model).joint_jacobian(&mut jac))
        .expect("valid joints");
    prop_assume!(sol.status == Status::Converged && sol.softest_mode > 0.0);
    let r = sol.tip.rotation;
    for j in 0..2 * N {
        let shifted = |sign: f64| {
            let mut p = q;
            if j < N {
                p.s_mm[j] += sign * FD_STEP;
            } else {
                p.theta_rad[j - N] += sign * FD_STEP;
            }
            let mut solver = center;
            let s = solver
                .solve(&robot, Request::new(p, model))
                .expect("valid joints");
            (s.tip, s.status, s.softest_mode)
        };
        let (plus, sp, sigma_plus) = shifted(1.0);
        let (minus, sm, sigma_minus) = shifted(-1.0);
        prop_assume!(sp == Status::Converged && sm == Status::Converged);
        // the joint distance to the fold along this column's joint
        let fold = sol.softest_mode / ((sigma_plus - sigma_minus).abs() / FD_STEP);
        prop_assume!(fold >= FOLD_STEPS * FD_STEP);
        let fd = ctr_suite::difference(&plus, &minus, &r, FD_STEP);
        let got = if j < N {
            jac.feed[j]
        } else {
            jac.rotation[j - N]
        };
        for block in [0, 3] {
            let g = got.fixed_rows::<3>(block);
            let f = fd.fixed_rows::<3>(block);
            let err = (g - f).norm();
            prop_assert!(
                err <= FD_RTOL * f.norm() + FD_ATOL,
                "column {j} ({}) block {block}: analytic {:?} vs difference {:?} (error {err:e}) at {q:?}, softest mode {}, fold {fold} away",
                if j < N { "feed" } else { "rotation" },
                [g[0], g[1], g[2]],
                [f[0], f[1], f[2]],
                sol.softest_mode
            );
        }
    }
    *compared.borrow_mut() += 1;
    Ok(())
}

// ---------------------------------------------------------------- rigid limit

/// The torsionally rigid robot in closed form, written here apart from the core: each
/// section between cuts has the constant curvature `u = sum K_i k_i Rz(theta_i) e_y /
/// sum K` (present tubes; `k_i` where tube i's exposed curved part is), the frame
/// turns by `exp(l [u]x)` and moves by `V(l u) e_z l`-style arcs, and the tip frame is
/// tube n's: the section frame turned by `theta_n` about its tangent.
fn rigid_closed_form<const N: usize>(
    robot: &Robot<f64, N>,
    q: &Joints<f64, N>,
) -> (Vector3<f64>, Matrix3<f64>) {
    let t = robot.tubes();
    let mut cuts: Vec<f64> = vec![0.0];
    for i in 0..N {
        cuts.push(q.s_mm[i]);
        cuts.push((q.s_mm[i] - t[i].params().curved_length_mm).max(0.0));
    }
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    let mut r = Matrix3::identity();
    let mut p = Vector3::zeros();
    for w in cuts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = b - a;
        if len <= 0.0 || a >= q.s_mm[N - 1] {
            continue;
        }
        let mid = 0.5 * (a + b);
        let mut num = Vector3::zeros();
        let mut den = 0.0;
        for i in 0..N {
            if mid < q.s_mm[i] {
                let k = if mid > q.s_mm[i] - t[i].params().curved_length_mm {
                    t[i].curvature_per_mm()
                } else {
                    0.0
                };
                let e = t[i].bending_stiffness_nmm2();
                num += e * k * Vector3::new(-q.theta_rad[i].sin(), q.theta_rad[i].cos(), 0.0);
                den += e;
            }
        }
        let u = num / den;
        let kappa = u.norm();
        let ux = u.cross_matrix();
        // int_0^len exp(s [u]x) ds = I len + [u]x (1 - cos x) / k^2 + [u]x^2 (x - sin x) / k^3,
        // x = k len, without the cancellations of 1 - cos x and x - sin x at small x
        // (written as 1 - cos x they lost 2e-9 mm over 110 mm at x = 5e-5)
        let x = kappa * len;
        let versine = 2.0 * (x / 2.0).sin().powi(2);
        let sin_defect = if x < 1e-2 {
            x.powi(3) / 6.0 * (1.0 - x * x / 20.0 * (1.0 - x * x / 42.0))
        } else {
            x - x.sin()
        };
        let v = if kappa == 0.0 {
            Matrix3::identity() * len
        } else {
            Matrix3::identity() * len
                + ux * (versine / (kappa * kappa))
                + ux * ux * (sin_defect / (kappa * kappa * kappa))
        };
        p += r * v * Vector3::z();
        let turn = if kappa > 0.0 {
            *Rotation3::from_axis_angle(&ctr_core::nalgebra::Unit::new_normalize(u), kappa * len)
                .matrix()
        } else {
            Matrix3::identity()
        };
        r *= turn;
    }
    let roll = Rotation3::from_axis_angle(&Vector3::z_axis(), q.theta_rad[N - 1]);
    (p, r * roll.matrix())
}

/// The rigid model is the closed form above (to 1e-9 mm and rad), and the torsion
/// model tends to it as every tube's G J grows: with G J times `F` the tip is within
/// `2 L_n^2 k_max delta(F) + 1e-7` mm of it, `delta(F) = max_i sum_l c_il L_i^2 /
/// (2 F G_i J_i)` bounding every tube's twist angle (the clamped-free twist equation
/// `F G J psi'' = f` with `|f| <= sum_l c_il`, [`uniqueness_ratio`]'s couplings), and
/// the distance shrinks at least 30-fold from `F = 1e4` to `F = 1e6` (first order in
/// `1 / F`) unless already below 1e-8 mm.
#[test]
fn torsion_tends_to_the_rigid_closed_form_as_gj_grows() {
    props::check(
        file!(),
        "torsion_tends_to_the_rigid_closed_form_as_gj_grows",
        192,
        robot_and_draws(1..=4, 1),
        |(params, draws)| {
            let (u, t) = &draws[0];
            with_n!(params, rigid_limit(&params, u, t))
        },
    );
}

fn rigid_limit<const N: usize>(
    params: &[TubeParams<f64>],
    u: &[f64],
    theta: &[f64],
) -> Result<(), TestCaseError> {
    let robot = robot_of::<N>(params);
    let q = joints::<N>(params, u, theta);
    let (p, r) = rigid_closed_form(&robot, &q);
    let rigid = tight::<N>()
        .solve(&robot, Request::new(q, Model::Rigid))
        .expect("valid joints");
    prop_assert!(
        (rigid.tip.position - p).norm() <= 1e-9 && (rigid.tip.rotation - r).norm() <= 1e-9,
        "rigid model {:?} vs closed form {p:?} {r:?} at {q:?}",
        rigid.tip
    );
    let t = robot.tubes();
    let k_max = t
        .iter()
        .map(|t| t.curvature_per_mm().abs())
        .fold(0.0, f64::max);
    let twist_bound = |factor: f64| {
        (0..N)
            .map(|i| {
                let c: f64 = (0..N)
                    .filter(|&l| l != i)
                    .map(|l| {
                        let (ki, kl) =
                            (t[i].bending_stiffness_nmm2(), t[l].bending_stiffness_nmm2());
                        ki * kl * (t[i].curvature_per_mm() * t[l].curvature_per_mm()).abs()
                            / (ki + kl)
                    })
                    .sum();
                c * t[i].params().length_mm.powi(2)
                    / (2.0 * factor * t[i].torsional_stiffness_nmm2())
            })
            .fold(0.0, f64::max)
    };
    let mut distances = Vec::new();
    for factor in [1e4, 1e6, 1e8] {
        let stiff: [TubeParams<f64>; N] = core::array::from_fn(|i| TubeParams {
            torsional_stiffness_nmm2: Some(factor * t[i].torsional_stiffness_nmm2()),
            ..params[i]
        });
        let stiff = Robot::new(stiff).expect("stiffer tubes are valid");
        let sol = tight::<N>()
            .solve(&stiff, Request::new(q, Model::Torsion))
            .expect("valid joints");
        prop_assert_eq!(sol.status, Status::Converged, "G J x {}: {:?}", factor, sol);
        let d = (sol.tip.position - p).norm();
        let bound = 2.0 * q.s_mm[N - 1].powi(2) * k_max * twist_bound(factor) + 1e-7;
        prop_assert!(
            d <= bound,
            "G J x {factor:e}: {d} mm from the rigid tip, bound {bound}"
        );
        distances.push(d);
    }
    prop_assert!(
        distances[1] <= distances[0] / 30.0 || distances[1] <= 1e-8,
        "no first-order convergence: {distances:?}"
    );
    Ok(())
}

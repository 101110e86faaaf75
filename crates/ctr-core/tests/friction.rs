//! Friction: the seed's boundary friction moment and the play operator on the feed, and
//! the closed-form checks of the effects that should change nothing.
use ctr_core::effects::{ClearanceProfile, Effects, Registration, CLEARANCE_TABLE_CAPACITY};
use ctr_core::friction::{BoundaryMoment, PlayFriction};
use ctr_core::nalgebra::Vector3;
use ctr_core::{Joints, Model, Request, Robot, Solver, Status};
use ctr_suite::*;

/// Feeds of the hysteresis runs (inside nitinol2's stable ranges), mm.
const FEEDS_MM: [f64; 2] = [40.0, 100.0];
/// Step of the rotation sweeps, degrees.
const SWEEP_STEP_DEG: f64 = 5.0;

#[test]
fn zero_boundary_friction_is_the_frictionless_solution() {
    let robot: Robot<f64, 3> = robot::<3>("nitinol3");
    let q = Joints::from_mm_deg([30.0, 60.0, 95.0], [10.0, 100.0, -60.0]);
    let free = Solver::default()
        .solve(&robot, Request::new(q, Model::Torsion))
        .unwrap();
    for direction in [[1.0, -1.0, 0.0], [0.0, 0.0, 0.0]] {
        let none = Solver::default()
            .solve(
                &robot,
                Request::new(q, Model::Torsion).friction([0.0; 3].map(|mu| mu * direction[0])),
            )
            .unwrap();
        assert_eq!(none, free);
    }
    // the friction path itself is continuous at mu = 0: a vanishing coefficient moves
    // the tip by a vanishing amount, and a small one by an amount proportional to it
    let moved = |mu: f64| {
        let sol = Solver::default()
            .solve(
                &robot,
                Request::new(q, Model::Torsion).friction([mu, -mu, 0.0]),
            )
            .unwrap();
        assert_eq!(sol.status, Status::Converged);
        (sol.tip.position - free.tip.position).norm()
    };
    // (1e-10 mm: the solver's own convergence noise)
    let tiny = moved(1e-12);
    assert!(tiny < 1e-10, "{tiny}");
    let (a, b) = (moved(1e-4), moved(2e-4));
    eprintln!("boundary friction: mu 1e-4 moves the tip {a:.3e} mm, 2e-4 {b:.3e} mm");
    assert!(a > 1e-6 && (b / a - 2.0).abs() < 1e-2, "{a} {b}");
}

/// Rotates nitinol2's inner tube forward through a full turn and back under boundary
/// friction `mu`; returns the loop's width: the largest distance between the forward
/// and the backward tip at the same command, mm. Each solve starts cold, so that only
/// the friction memory (not the warm start) tells the branches apart.
fn loop_width(robot: &Robot<f64, 2>, mu: f64) -> f64 {
    let mut friction = BoundaryMoment::new([mu, 0.0]);
    let mut solver = Solver::default();
    let steps = (360.0 / SWEEP_STEP_DEG) as usize;
    let angle = |k: usize| k as f64 * SWEEP_STEP_DEG;
    let mut forward = Vec::new();
    for k in 0..=steps {
        let q = Joints::from_mm_deg(FEEDS_MM, [0.0, angle(k)]);
        solver.reset();
        let sol = friction.step(&mut solver, robot, &q).unwrap();
        assert_eq!(sol.status, Status::Converged);
        forward.push(sol.tip.position);
    }
    let mut width = 0.0_f64;
    for k in (0..=steps).rev() {
        let q = Joints::from_mm_deg(FEEDS_MM, [0.0, angle(k)]);
        solver.reset();
        let sol = friction.step(&mut solver, robot, &q).unwrap();
        assert_eq!(sol.status, Status::Converged);
        width = width.max((sol.tip.position - forward[k]).norm());
    }
    width
}

#[test]
fn boundary_friction_hysteresis_grows_with_mu() {
    let robot: Robot<f64, 2> = robot::<2>("nitinol2");
    assert_eq!(loop_width(&robot, 0.0), 0.0);
    let mus = [0.05, 0.1, 0.2];
    let widths = mus.map(|mu| loop_width(&robot, mu));
    for (mu, w) in mus.iter().zip(&widths) {
        eprintln!("boundary friction mu' = {mu}: loop width {w:.4} mm");
    }
    assert!(widths[0] > 0.05, "{widths:?}");
    assert!(widths[0] < widths[1] && widths[1] < widths[2], "{widths:?}");
    // small moments: the width is nearly proportional to mu'
    let ratio = widths[1] / widths[0];
    assert!(ratio > 1.7 && ratio < 2.3, "{widths:?}");
}

/// Feeding the inner tube forward and back through a play of half-width `w` mm: the
/// actual feed lags the command by `w` against the direction of motion; returns the
/// tip loop's width, mm.
fn feed_loop_width(robot: &Robot<f64, 2>, w: f64) -> f64 {
    let mut play = PlayFriction::new([0.0; 2], [0.0, w]);
    let mut solver = Solver::default();
    let cmd = |k: usize| Joints::from_mm_deg([40.0, 60.0 + k as f64], [0.0, 90.0]);
    play.reset(&cmd(0));
    let mut forward = Vec::new();
    for k in 0..=40 {
        let actual = play.apply(&cmd(k));
        if k as f64 >= 2.0 * w {
            // past the take-up, the feed lags behind the command by the half-width
            assert!((actual.s_mm[1] - (cmd(k).s_mm[1] - w)).abs() < 1e-12);
        }
        forward.push(
            solver
                .solve(robot, Request::new(actual, Model::Torsion).cold())
                .unwrap()
                .tip
                .position,
        );
    }
    let mut width = 0.0_f64;
    for k in (0..=40).rev() {
        let actual = play.apply(&cmd(k));
        if 40.0 - k as f64 >= 2.0 * w {
            // reversed: it now lags the other way
            assert!((actual.s_mm[1] - (cmd(k).s_mm[1] + w)).abs() < 1e-12);
        }
        let p = solver
            .solve(robot, Request::new(actual, Model::Torsion).cold())
            .unwrap()
            .tip
            .position;
        width = width.max((p - forward[k]).norm());
    }
    width
}

#[test]
fn feed_play_lags_against_the_feed_direction() {
    let robot: Robot<f64, 2> = robot::<2>("nitinol2");
    assert_eq!(feed_loop_width(&robot, 0.0), 0.0);
    let widths = [0.25, 0.5, 1.0].map(|w| feed_loop_width(&robot, w));
    eprintln!("feed play 0.25/0.5/1 mm: loop widths {widths:?} mm");
    assert!(widths[0] > 0.1 && widths[0] < widths[1] && widths[1] < widths[2]);
    // the tip moves ~1 mm per mm of feed: the width is about twice the half-width
    for (w, width) in [0.25, 0.5, 1.0].iter().zip(&widths) {
        assert!(*width > 1.0 * w && *width < 3.0 * w, "{w}: {width}");
    }
}

#[test]
fn a_clearance_table_of_zeros_changes_nothing() {
    let robot: Robot<f64, 3> = robot::<3>("nitinol3");
    let zeros = ClearanceProfile::table(&[0.0; CLEARANCE_TABLE_CAPACITY]).unwrap();
    let effects = Effects {
        clearance: [Some(zeros), Some(zeros), None],
        ..Default::default()
    };
    for row in reference::<3>("nitinol3", "torsion").iter().step_by(10) {
        for model in [Model::Rigid, Model::Torsion] {
            let plain = Solver::default()
                .solve(&robot, Request::new(row.q, model))
                .unwrap();
            let with = Solver::default()
                .solve(&robot, Request::new(row.q, model).effects(&effects))
                .unwrap();
            assert_eq!(plain.tip, with.tip);
        }
    }
}

#[test]
fn registration_by_identity_changes_nothing() {
    let robot: Robot<f64, 2> = robot::<2>("liu2023");
    for registration in [
        Registration::identity(),
        Registration::from_axis_angle([0.3, -0.2, 0.9], 0.0, [0.0; 3]),
    ] {
        let effects = Effects {
            registration: Some(registration),
            ..Default::default()
        };
        for row in reference::<2>("liu2023", "torsion").iter().step_by(10) {
            let plain = Solver::default()
                .solve(&robot, Request::new(row.q, Model::Torsion))
                .unwrap();
            let with = Solver::default()
                .solve(
                    &robot,
                    Request::new(row.q, Model::Torsion).effects(&effects),
                )
                .unwrap();
            assert_eq!(plain.tip, with.tip);
        }
    }
    // and a pure translation moves the tip by exactly it
    let t = Vector3::new(1.5, -2.0, 0.25);
    let effects = Effects {
        registration: Some(Registration::from_axis_angle(
            [0.0, 0.0, 1.0],
            0.0,
            t.into(),
        )),
        ..Default::default()
    };
    let q = Joints::from_mm_deg([40.0, 90.0], [0.0, 45.0]);
    let plain = Solver::default()
        .solve(&robot, Request::new(q, Model::Torsion))
        .unwrap();
    let with = Solver::default()
        .solve(&robot, Request::new(q, Model::Torsion).effects(&effects))
        .unwrap();
    assert!((with.tip.position - plain.tip.position - t).norm() < 1e-12);
}

//! The softest mode's gradient (`Solver::softest_mode_gradient`: singular vectors and two
//! sensitivity passes) against central differences of solves, on the shared robots, a
//! four-tube robot and a pair near its snap; and the stretch over which the solver's
//! discrete map stays smooth (`smooth_within_mm`) against `Solver::same_steps`.
use ctr_core::{
    Joints, Loads, Model, Request, Robot, Solution, SolveError, Solver, TubeParams, Unsupported,
};
use ctr_suite::*;

/// A small deterministic generator (xorshift64*), uniform in [0, 1).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Solved twice from a cold start, so that the softest mode is that of the solution's own
/// shooting Jacobian (as the stability margin's probes settle it).
fn settled<const N: usize>(
    robot: &Robot<f64, N>,
    q: Joints<f64, N>,
) -> (Solver<f64, N>, Solution<f64, N>) {
    let mut solver = Solver::default();
    solver
        .solve(robot, Request::new(q, Model::Torsion))
        .unwrap();
    let sol = solver
        .solve(robot, Request::new(q, Model::Torsion))
        .unwrap();
    (solver, sol)
}

/// Central differences of solves settled from `solver` (on its branch): feeds by `h_mm`,
/// rotations by `h_rad`; `None` where a solve did not converge.
fn differences<const N: usize>(
    robot: &Robot<f64, N>,
    solver: &Solver<f64, N>,
    q: Joints<f64, N>,
    h_mm: f64,
    h_rad: f64,
) -> Option<Vec<f64>> {
    let mut out = Vec::new();
    for k in 0..2 * N {
        let at = |sign: f64| {
            let mut p = q;
            if k < N {
                p.s_mm[k] += sign * h_mm;
            } else {
                p.theta_rad[k - N] += sign * h_rad;
            }
            let mut s = *solver;
            s.solve(robot, Request::new(p, Model::Torsion)).unwrap();
            let sol = s.solve(robot, Request::new(p, Model::Torsion)).unwrap();
            (sol.status == ctr_core::Status::Converged).then_some(sol.softest_mode)
        };
        let h = if k < N { h_mm } else { h_rad };
        out.push((at(1.0)? - at(-1.0)?) / (2.0 * h));
    }
    Some(out)
}

/// The largest relative error (2-norm) of the gradient against central differences over
/// `rows` random joint vectors of `robot` (feed increments in `inc`, mm; all
/// rotations), where the differences stay within the smooth stretch; also the number
/// compared.
fn worst_error<const N: usize>(
    robot: &Robot<f64, N>,
    inc: [(f64, f64); N],
    rows: usize,
    seed: u64,
) -> (f64, usize) {
    const H_MM: f64 = 1e-3;
    let h_rad = 1e-3f64.to_radians();
    let mut rng = Rng(seed);
    let (mut worst, mut compared) = (0.0f64, 0);
    for _ in 0..rows {
        let mut s = [0.0; N];
        let mut acc = 0.0;
        for i in 0..N {
            acc += inc[i].0 + (inc[i].1 - inc[i].0) * rng.next();
            s[i] = acc;
        }
        let theta: [f64; N] = core::array::from_fn(|_| 360.0 * rng.next() - 180.0);
        let q = Joints::from_mm_deg(s, theta);
        let (solver, sol) = settled(robot, q);
        let g = solver
            .softest_mode_gradient(robot, Request::new(q, Model::Torsion), &sol)
            .unwrap();
        // the solver's own softest mode: its Newton pass was at the unknowns before the
        // last step, which moved them by ~1e-12 rad/mm, and the shooting Jacobian changes
        // by ~1e3 mm/rad times that
        assert!(
            (g.value - sol.softest_mode).abs() <= 1e-8,
            "{} {}",
            g.value,
            sol.softest_mode
        );
        if g.smooth_within_mm <= H_MM {
            continue;
        }
        let Some(fd) = differences(robot, &solver, q, H_MM, h_rad) else {
            continue;
        };
        let analytic: Vec<f64> = g.feed.iter().chain(&g.rotation).copied().collect();
        let err: f64 = analytic
            .iter()
            .zip(&fd)
            .map(|(a, d)| (a - d).powi(2))
            .sum::<f64>()
            .sqrt();
        let size: f64 = fd.iter().map(|d| d * d).sum::<f64>().sqrt();
        worst = worst.max(err / size);
        compared += 1;
        // only relative angles count
        assert!(g.rotation.iter().sum::<f64>().abs() <= 1e-12 * size.max(1.0));
    }
    (worst, compared)
}

/// Relative error of the gradient's 2-norm against central differences of settled
/// solves (dimensionless): the discretisation error of the twist equations' derivative
/// (about 1e-5) and the differences' own truncation, far below it.
const GRADIENT_TOLERANCE: f64 = 1e-3;

#[test]
fn the_gradient_is_the_difference_of_solves_on_the_shared_robots() {
    let four = {
        let mut p: Vec<TubeParams<f64>> = tube_params("nitinol3");
        p.push(TubeParams {
            curvature_radius_mm: Some(60.0),
            ..TubeParams::new(0.5, 0.3, 340.0, 40.0, 58000.0, 0.33)
        });
        Robot::<f64, 4>::new(p.try_into().unwrap()).unwrap()
    };
    let results = [
        (
            "nitinol3",
            worst_error(&robot::<3>("nitinol3"), [(10.0, 50.0); 3], 150, 1),
        ),
        (
            "nitinol2",
            worst_error(
                &robot::<2>("nitinol2"),
                [(10.0, 60.0), (10.0, 80.0)],
                150,
                2,
            ),
        ),
        (
            "liu2023",
            worst_error(&robot::<2>("liu2023"), [(20.0, 70.0), (25.0, 95.0)], 150, 3),
        ),
        (
            "four tubes",
            worst_error(
                &four,
                [(10.0, 50.0), (10.0, 50.0), (10.0, 50.0), (10.0, 40.0)],
                100,
                4,
            ),
        ),
    ];
    for (name, (worst, compared)) in results {
        eprintln!(
            "{name}: gradient within {worst:.2e} of central differences ({compared} joint vectors)"
        );
        assert!(compared >= 90, "{name}: {compared}");
        assert!(worst < GRADIENT_TOLERANCE, "{name}: {worst}");
    }
}

/// Near a snap (the seed's pair with transmissions 100 mm longer, turned towards the
/// fold of a sweep at s1 = 55 mm, where the softest mode falls towards zero as the
/// square root of the angle left), where the margin's warning is decided.
#[test]
fn the_gradient_is_the_difference_of_solves_near_a_snap() {
    let t = |od, id, len, cl, r, e| TubeParams {
        curvature_radius_mm: Some(r),
        ..TubeParams::<f64>::new(od, id, len, cl, e, 0.41)
    };
    let robot = Robot::new([
        t(6.8, 4.9, 224.0, 74.0, -97.0, 150.0),
        t(4.5, 3.3, 274.0, 114.0, 98.5, 300.0),
    ])
    .unwrap();
    // walk the rotation up warm until the softest mode is small
    let mut solver = Solver::default();
    let (mut smallest, mut worst, mut compared) = (f64::MAX, 0.0f64, 0);
    let mut deg = 340.0;
    let mut last = f64::MAX;
    loop {
        let q = Joints::from_mm_deg([55.0, 95.0], [0.0, deg]);
        solver
            .solve(&robot, Request::new(q, Model::Torsion))
            .unwrap();
        let sol = solver
            .solve(&robot, Request::new(q, Model::Torsion))
            .unwrap();
        // past the fold the robot has snapped to a stiffer branch
        if sol.softest_mode > last || sol.status != ctr_core::Status::Converged {
            break;
        }
        last = sol.softest_mode;
        let g = solver
            .softest_mode_gradient(&robot, Request::new(q, Model::Torsion), &sol)
            .unwrap();
        // central differences from this solver (on this branch), 1e-4 mm or degree
        let (h_mm, h_rad) = (1e-4, 1e-4f64.to_radians());
        let mut fd = [0.0; 4];
        for (k, d) in fd.iter_mut().enumerate() {
            let at = |sign: f64| {
                let mut p = q;
                if k < 2 {
                    p.s_mm[k] += sign * h_mm;
                } else {
                    p.theta_rad[k - 2] += sign * h_rad;
                }
                let mut s = solver;
                s.solve(&robot, Request::new(p, Model::Torsion)).unwrap();
                s.solve(&robot, Request::new(p, Model::Torsion))
                    .unwrap()
                    .softest_mode
            };
            *d = (at(1.0) - at(-1.0)) / (2.0 * if k < 2 { h_mm } else { h_rad });
        }
        let analytic = [g.feed[0], g.feed[1], g.rotation[0], g.rotation[1]];
        let err = analytic
            .iter()
            .zip(&fd)
            .map(|(a, d)| (a - d).powi(2))
            .sum::<f64>()
            .sqrt();
        let size = fd.iter().map(|d| d * d).sum::<f64>().sqrt();
        if g.smooth_within_mm > h_mm {
            worst = worst.max(err / size);
            compared += 1;
        }
        smallest = smallest.min(sol.softest_mode);
        // finer steps near the fold
        deg += if sol.softest_mode > 0.3 { 0.5 } else { 0.02 };
    }
    eprintln!("near the snap (softest mode down to {smallest:.4}): gradient within {worst:.2e} of central differences ({compared} rows)");
    assert!(smallest < 0.05 && compared > 50, "{smallest} {compared}");
    assert!(worst < GRADIENT_TOLERANCE, "{worst}");
}

/// Moving any one feed by less than `smooth_within_mm` keeps the sections and their
/// step counts (`same_steps`); a cut next to another, or a section length next to a
/// change of its step count, leaves almost no room.
#[test]
fn the_smooth_stretch_keeps_the_steps() {
    let robot = robot::<3>("nitinol3");
    let mut rng = Rng(7);
    let mut narrow = 0;
    for _ in 0..300 {
        let mut s = [0.0; 3];
        let mut acc = 0.0;
        for item in s.iter_mut() {
            acc += 10.0 + 40.0 * rng.next();
            *item = acc;
        }
        let q = Joints::from_mm_deg(s, [0.0, 120.0 * rng.next(), -90.0]);
        let (solver, sol) = settled(&robot, q);
        let d = solver
            .softest_mode_gradient(&robot, Request::new(q, Model::Torsion), &sol)
            .unwrap()
            .smooth_within_mm;
        assert!(d > 0.0);
        if d < 0.1 {
            narrow += 1;
        }
        for k in 0..3 {
            for sign in [1.0, -1.0] {
                let mut p = q;
                p.s_mm[k] += sign * 0.999 * d.min(5.0);
                assert!(solver.same_steps(&robot, &q, &p), "{q:?} {k} {sign} {d}");
            }
        }
    }
    eprintln!("{narrow} of 300 joint vectors within 0.1 mm of a change of the sections");
    // the middle tube's curve start (s2 - 70) 1e-4 mm beyond the outer tube's tip
    let q = Joints::from_mm_deg([30.0, 100.0001, 130.0], [0.0, 50.0, 0.0]);
    let (solver, sol) = settled(&robot, q);
    let g = solver
        .softest_mode_gradient(&robot, Request::new(q, Model::Torsion), &sol)
        .unwrap();
    assert!(g.smooth_within_mm <= 1.0001e-4, "{}", g.smooth_within_mm);
    let mut p = q;
    p.s_mm[1] -= 2e-4;
    assert!(!solver.same_steps(&robot, &q, &p));
}

#[test]
fn what_has_no_gradient_says_so() {
    let robot = robot::<3>("nitinol3");
    let q = Joints::from_mm_deg([30.0, 60.0, 90.0], [0.0, 40.0, 80.0]);
    let (solver, sol) = settled(&robot, q);
    let loads = Loads {
        tip_force_n: [0.0, 0.1, 0.0],
        ..Default::default()
    };
    let unsupported = Err(SolveError::Unsupported(Unsupported::SoftestModeGradient));
    let request = Request::new(q, Model::Torsion);
    assert_eq!(
        solver.softest_mode_gradient(&robot, request.loads(loads), &sol),
        unsupported
    );
    let request = Request::new(q, Model::Torsion).friction([0.1, 0.0, 0.0]);
    assert_eq!(
        solver.softest_mode_gradient(&robot, request, &sol),
        unsupported
    );
    // rigid tubes: a constant 1
    let g = solver
        .softest_mode_gradient(&robot, Request::new(q, Model::Rigid), &sol)
        .unwrap();
    assert_eq!((g.value, g.feed, g.rotation), (1.0, [0.0; 3], [0.0; 3]));
}

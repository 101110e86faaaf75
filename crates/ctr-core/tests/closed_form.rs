//! Closed forms and symmetries the solver must reproduce.
use ctr_core::{Joints, Model, Request, Robot, Solver, SolverConfig, Status, TubeParams};
use ctr_suite::*;
use nalgebra::{Matrix3, Rotation3, Vector3};
use std::f64::consts::PI;

fn curved(od: f64, id: f64, len: f64, curved: f64, radius: f64, e: f64) -> TubeParams<f64> {
    TubeParams {
        curvature_radius_mm: Some(radius),
        ..TubeParams::new(od, id, len, curved, e, 0.33)
    }
}

/// Planar arc of curvature `k` over `len`, bending toward the direction at `phi` about z.
fn arc(k: f64, len: f64, phi: f64) -> (Vector3<f64>, Matrix3<f64>) {
    let r = (1.0 - (k * len).cos()) / k;
    let p = Vector3::new(r * phi.cos(), r * phi.sin(), (k * len).sin() / k);
    let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), phi)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), k * len);
    (p, *rot.matrix())
}

#[test]
fn one_tube_is_an_exact_arc() {
    let robot = Robot::new([curved(1.2, 0.9, 260.0, 90.0, 100.0, 58000.0)]).unwrap();
    for model in [Model::Rigid, Model::Torsion] {
        for (s, theta) in [(30.0, 0.0), (90.0, 1.0), (60.0, -2.5)] {
            let sol = Solver::default()
                .solve(
                    &robot,
                    Request::new(Joints::new([s], [theta]), model).cold(),
                )
                .unwrap();
            let (p, r) = arc(0.01, s, theta);
            assert!((sol.tip.position - p).norm() < 1e-12, "{model:?} s={s}");
            // tip frame: tube 1's material frame, Rz(theta) Ry(k s)
            assert!((sol.tip.rotation - r).norm() < 1e-12);
        }
    }
    // a straight part behind the curve: a line of s - curved, then the arc
    let sol = Solver::default()
        .solve(
            &robot,
            Request::new(Joints::new([150.0], [0.0]), Model::Torsion).cold(),
        )
        .unwrap();
    let (p, _) = arc(0.01, 90.0, 0.0);
    assert!((sol.tip.position - (p + Vector3::new(0.0, 0.0, 60.0))).norm() < 1e-12);
}

#[test]
fn two_rigid_tubes_bend_with_the_stiffness_weighted_curvature() {
    let outer = curved(1.8, 1.5, 180.0, 80.0, 200.0, 58000.0);
    let inner = curved(1.2, 0.9, 260.0, 80.0, 100.0, 58000.0);
    let robot = Robot::new([outer, inner]).unwrap();
    let k1 = robot.tubes()[0].bending_stiffness_nmm2();
    let k2 = robot.tubes()[1].bending_stiffness_nmm2();
    for (t1, t2) in [(0.0, 0.0), (0.3, 2.0), (-1.0, 3.0)] {
        let s = 70.0; // both tips together, both curved over all of it
        let sol = Solver::default()
            .solve(
                &robot,
                Request::new(Joints::new([s, s], [t1, t2]), Model::Rigid).cold(),
            )
            .unwrap();
        let u = (Vector3::new(-t1.sin(), t1.cos(), 0.0) * (k1 / 200.0)
            + Vector3::new(-t2.sin(), t2.cos(), 0.0) * (k2 / 100.0))
            / (k1 + k2);
        // curvature about the axis u bends toward u rotated by -90 deg
        let k = u.norm();
        let phi = u.y.atan2(u.x) - PI / 2.0;
        let (p, _) = arc(k, s, phi);
        assert!(
            (sol.tip.position - p).norm() < 1e-11,
            "{t1} {t2}: {} vs {p}",
            sol.tip.position
        );
    }
}

#[test]
fn stiff_torsion_tends_to_rigid() {
    let params = tube_params("nitinol3");
    let q = Joints::from_mm_deg([40.0, 70.0, 100.0], [10.0, 130.0, -100.0]);
    let mut gaps = Vec::new();
    for scale in [1.0, 1e2, 1e4, 1e6] {
        let p: [TubeParams<f64>; 3] = core::array::from_fn(|i| {
            let t = Robot::new([params[i]]).unwrap().tubes()[0].torsional_stiffness_nmm2();
            TubeParams {
                torsional_stiffness_nmm2: Some(t * scale),
                ..params[i]
            }
        });
        let robot = Robot::new(p).unwrap();
        let tors = Solver::default()
            .solve(&robot, Request::new(q, Model::Torsion).cold())
            .unwrap();
        let rig = Solver::default()
            .solve(&robot, Request::new(q, Model::Rigid).cold())
            .unwrap();
        assert_eq!(tors.status, Status::Converged);
        gaps.push((tors.tip.position - rig.tip.position).norm());
    }
    eprintln!("torsion - rigid gap for GJ x 1, 1e2, 1e4, 1e6: {gaps:?}");
    assert!(gaps[0] > 0.1, "the configuration must show torsion at all");
    for w in gaps.windows(2) {
        // the gap falls as 1 / GJ
        let ratio = w[0] / w[1];
        assert!(ratio > 50.0 && ratio < 200.0, "ratio {ratio}");
    }
    assert!(gaps[3] < 1e-5);
}

#[test]
fn common_rotation_rotates_the_tip() {
    let robot = robot::<3>("nitinol3");
    let q = Joints::from_mm_deg([35.0, 60.0, 95.0], [20.0, -70.0, 160.0]);
    for model in [Model::Rigid, Model::Torsion] {
        let base = Solver::default()
            .solve(&robot, Request::new(q, model).cold())
            .unwrap();
        for alpha in [0.7, -2.0, PI] {
            let mut qr = q;
            for t in qr.theta_rad.iter_mut() {
                *t += alpha;
            }
            let rot = Rotation3::from_axis_angle(&Vector3::z_axis(), alpha);
            let sol = Solver::default()
                .solve(&robot, Request::new(qr, model).cold())
                .unwrap();
            assert!((sol.tip.position - rot * base.tip.position).norm() < 1e-10);
            assert!((sol.tip.rotation - rot.matrix() * base.tip.rotation).norm() < 1e-12);
        }
    }
}

/// The seed's two-tube formulation (Liu et al. 2023, eq. 8-10 without friction):
/// `beta'' = c sin(beta)`, `beta(0) = theta_2 - theta_1`, `beta'(L) = 0`, with
/// `c = K1 k1 K2 k2 / (K1 + K2) (1/GJ1 + 1/GJ2)`, which for equal bending stiffness
/// and `GJ = EI / (1 + nu)` is the seed's `(1 + nu) |u1| |u2|`.
#[test]
fn two_tubes_agree_with_the_seed_beta_formulation() {
    let nu = 0.41_f64;
    let ei = 2.0e4_f64;
    let gj = ei / (1.0 + nu);
    let (k1, k2) = (1.0 / 97.0, 1.0 / 98.5);
    let (s1, s2) = (70.0, 110.0);
    // no transmission behind the guide (length = s) so beta(0) is the commanded angle
    let tube = |od: f64, id: f64, len: f64, r: f64| TubeParams {
        curvature_radius_mm: Some(r),
        bending_stiffness_nmm2: Some(ei),
        torsional_stiffness_nmm2: Some(gj),
        ..TubeParams::new(od, id, len, len, 200.0, nu)
    };
    let robot = Robot::new([tube(6.8, 4.9, s1, 97.0), tube(4.5, 3.3, s2, 98.5)]).unwrap();
    let c = (1.0 + nu) * k1 * k2;
    for beta0_deg in [30.0_f64, 90.0, 150.0, 175.0, -120.0] {
        let beta0 = beta0_deg.to_radians();
        let mut fine = Solver::new(SolverConfig {
            step_fraction: 0.005,
            ..Default::default()
        });
        let sol = fine
            .solve(
                &robot,
                Request::new(Joints::new([s1, s2], [0.2, 0.2 + beta0]), Model::Torsion).cold(),
            )
            .unwrap();
        assert_eq!(sol.status, Status::Converged);
        let slope = sol.base_twist_per_mm[1] - sol.base_twist_per_mm[0];
        let expected = seed_shooting(c, beta0, s1);
        eprintln!("beta0 {beta0_deg}: beta'(0) solver {slope:.12e}, seed {expected:.12e}");
        assert!(
            (slope - expected).abs() < 1e-8 * expected.abs(),
            "{slope} vs {expected}"
        );
        assert!((sol.base_angle_rad[1] - sol.base_angle_rad[0] - beta0).abs() < 1e-14);
    }
}

/// Solves `beta'' = c sin beta`, `beta(0) = b0`, `beta'(L) = 0` for `beta'(0)` by
/// bisection on a fine fixed-step RK4 (independent of the library's integrator).
fn seed_shooting(c: f64, b0: f64, len: f64) -> f64 {
    let end_slope = |d0: f64| {
        let n = 20_000;
        let h = len / n as f64;
        let (mut b, mut d) = (b0, d0);
        let f = |b: f64, d: f64| (d, c * b.sin());
        for _ in 0..n {
            let (a1, v1) = f(b, d);
            let (a2, v2) = f(b + 0.5 * h * a1, d + 0.5 * h * v1);
            let (a3, v3) = f(b + 0.5 * h * a2, d + 0.5 * h * v2);
            let (a4, v4) = f(b + h * a3, d + h * v3);
            b += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
            d += h / 6.0 * (v1 + 2.0 * v2 + 2.0 * v3 + v4);
        }
        d
    };
    // beta'(L) is monotone in beta'(0) on the stable branch; bracket and bisect
    let (mut lo, mut hi) = (-0.1, 0.1);
    assert!(end_slope(lo) * end_slope(hi) < 0.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if end_slope(lo) * end_slope(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn f32_reproduces_the_reference_within_five_hundredths_of_a_mm() {
    fn check<const N: usize>(name: &str) -> f64 {
        let robot = robot_f32::<N>(name);
        let mut solver = Solver::<f32, N>::new(SolverConfig::default());
        let mut worst = 0.0_f64;
        for row in reference::<N>(name, "torsion") {
            let q = Joints::new(
                row.q.s_mm.map(|v| v as f32),
                row.q.theta_rad.map(|v| v as f32),
            );
            let sol = solver
                .solve(&robot, Request::new(q, Model::Torsion))
                .unwrap();
            assert_ne!(sol.status, Status::Diverged);
            let p = sol.tip.position.map(|v| v as f64);
            worst = worst.max((p - Vector3::from(row.p)).norm());
        }
        worst
    }
    for (name, e) in [
        ("liu2023", check::<2>("liu2023")),
        ("nitinol2", check::<2>("nitinol2")),
        ("nitinol3", check::<3>("nitinol3")),
    ] {
        eprintln!("f32 {name}: max error {e:.2e} mm");
        assert!(e <= 0.05, "{name}: {e} mm");
    }
}

#[test]
fn four_tubes_solve_and_reduce_to_three_when_one_is_straight_and_short() {
    // a fourth, straight innermost tube flush with tube 3 changes only the stiffness mix
    let p = tube_params("nitinol3");
    let fourth = TubeParams::new(0.5, 0.3, 300.0, 0.0, 58000.0, 0.33);
    let robot4 = Robot::new([p[0], p[1], p[2], fourth]).unwrap();
    let q = Joints::from_mm_deg([30.0, 60.0, 90.0, 90.0], [0.0, 90.0, -45.0, 10.0]);
    let sol = Solver::default()
        .solve(&robot4, Request::new(q, Model::Torsion).cold())
        .unwrap();
    assert_eq!(sol.status, Status::Converged);
    // torque balance at the exit: sum of G J u(0) vanishes
    let total: f64 = (0..4)
        .map(|i| robot4.tubes()[i].torsional_stiffness_nmm2() * sol.base_twist_per_mm[i])
        .sum();
    assert!(total.abs() < 1e-9, "{total}");
    assert!(sol.tip.position.iter().all(|v| v.is_finite()));
}

//! Bad parameters and joints are refused with the tube and field named; solves never
//! panic and never hand back NaN as a converged result.
use ctr_core::{
    Field, JointError, JointKind, Joints, Model, Request, Robot, RobotError, SolveError, Solver,
    Status, TubeParams,
};

use ctr_suite::two_tubes as good;

fn with(i: usize, f: impl Fn(&mut TubeParams<f64>)) -> Result<Robot<f64, 2>, RobotError> {
    let mut p = good();
    f(&mut p[i]);
    Robot::new(p)
}

#[test]
fn every_bad_tube_field_is_named() {
    let cases: Vec<(Result<Robot<f64, 2>, RobotError>, &str)> = vec![
        (
            with(1, |t| t.outer_diameter_mm = f64::NAN),
            "tube 2: outer_diameter_mm must be a finite number",
        ),
        (
            with(0, |t| t.outer_diameter_mm = -1.0),
            "tube 1: outer_diameter_mm = -1 must be > 0",
        ),
        (
            with(0, |t| t.inner_diameter_mm = -0.1),
            "tube 1: inner_diameter_mm = -0.1 must be >= 0",
        ),
        (
            with(1, |t| t.inner_diameter_mm = 1.2),
            "tube 2: outer_diameter_mm = 1.2 must be larger than inner_diameter_mm = 1.2",
        ),
        (
            with(1, |t| t.outer_diameter_mm = 1.5),
            "tube 2: outer_diameter_mm = 1.5 does not fit inside tube 1's inner_diameter_mm = 1.5",
        ),
        (
            with(0, |t| t.length_mm = 0.0),
            "tube 1: length_mm = 0 must be > 0",
        ),
        (
            with(0, |t| t.curved_length_mm = 200.0),
            "tube 1: curved_length_mm = 200 must not exceed length_mm = 180",
        ),
        (
            with(0, |t| t.curved_length_mm = -5.0),
            "tube 1: curved_length_mm = -5 must be >= 0",
        ),
        (
            with(1, |t| t.youngs_modulus_mpa = 0.0),
            "tube 2: youngs_modulus_mpa = 0 must be > 0",
        ),
        (
            with(1, |t| t.poisson_ratio = 0.5),
            "tube 2: poisson_ratio = 0.5 must lie in [0, 0.5)",
        ),
        (
            with(1, |t| t.poisson_ratio = -0.1),
            "tube 2: poisson_ratio = -0.1 must lie in [0, 0.5)",
        ),
        (
            with(0, |t| t.curvature_radius_mm = Some(0.0)),
            "tube 1: curvature_radius_mm must not be 0",
        ),
        (
            with(0, |t| t.curvature_radius_mm = Some(f64::INFINITY)),
            "tube 1: curvature_radius_mm must be a finite number",
        ),
        (
            with(0, |t| t.bending_stiffness_nmm2 = Some(-3.0)),
            "tube 1: bending_stiffness_nmm2 = -3 must be > 0",
        ),
        (
            with(1, |t| t.torsional_stiffness_nmm2 = Some(0.0)),
            "tube 2: torsional_stiffness_nmm2 = 0 must be > 0",
        ),
        (
            with(1, |t| t.density_kg_m3 = Some(-1.0)),
            "tube 2: density_kg_m3 = -1 must be >= 0",
        ),
    ];
    for (result, message) in cases {
        let err = result.expect_err(message);
        assert!(
            err.to_string().starts_with(message),
            "got {err}, wanted {message}"
        );
    }
    assert_eq!(
        with(0, |t| t.youngs_modulus_mpa = f64::NAN).unwrap_err(),
        RobotError::NotFinite {
            tube: 1,
            field: Field::YoungsModulus
        }
    );
    assert!(matches!(
        Robot::<f64, 5>::new([good()[0]; 5]),
        Err(RobotError::TubeCount { count: 5 })
    ));
    assert!(matches!(
        Robot::<f64, 0>::new([]),
        Err(RobotError::TubeCount { count: 0 })
    ));
}

#[test]
fn every_bad_joint_is_named() {
    let robot = Robot::new(good()).unwrap();
    let solve = |s: [f64; 2], t: [f64; 2]| {
        Solver::default().solve(
            &robot,
            Request::new(Joints::from_mm_deg(s, t), Model::Torsion).cold(),
        )
    };
    let cases: Vec<(SolveError, &str)> = vec![
        (
            solve([f64::NAN, 50.0], [0.0, 0.0]).unwrap_err(),
            "s1_mm must be a finite number",
        ),
        (
            solve([10.0, 50.0], [0.0, f64::INFINITY]).unwrap_err(),
            "theta2_deg must be a finite number",
        ),
        (
            solve([-1.0, 50.0], [0.0, 0.0]).unwrap_err(),
            "s1_mm = -1 must be >= 0",
        ),
        (
            solve([60.0, 50.0], [0.0, 0.0]).unwrap_err(),
            "s2_mm = 50 must be >= s1_mm = 60",
        ),
        (
            solve([60.0, 261.0], [0.0, 0.0]).unwrap_err(),
            "s2_mm = 261 exceeds tube 2's length_mm = 260",
        ),
    ];
    for (err, message) in cases {
        assert!(
            err.to_string().starts_with(message),
            "got {err}, wanted {message}"
        );
    }
    assert_eq!(
        solve([10.0, f64::NAN], [0.0, 0.0]).unwrap_err(),
        SolveError::Joint(JointError::NotFinite {
            tube: 2,
            kind: JointKind::Feed
        })
    );
}

#[test]
fn edge_configurations_solve() {
    let robot = Robot::new(good()).unwrap();
    for (s, t) in [
        ([0.0, 0.0], [0.0, 90.0]),
        ([0.0, 50.0], [10.0, 0.0]),
        ([60.0, 60.0], [0.0, 180.0]),
        ([180.0, 260.0], [0.0, 180.0]),
    ] {
        let sol = Solver::default()
            .solve(
                &robot,
                Request::new(Joints::from_mm_deg(s, t), Model::Torsion).cold(),
            )
            .unwrap();
        assert_eq!(sol.status, Status::Converged, "{s:?} {t:?}");
        assert!(sol.tip.position.iter().all(|v| v.is_finite()));
        assert!((sol.tip.position.z - s[1]).abs() <= s[1] * 0.2 + 1e-12);
    }
}

/// The seed's robot with transmissions 100 mm longer snaps when the curved parts overlap
/// far (see tests/data/shared/robots/liu2023.toml). Across a wide sweep that includes the
/// unstable region, a solve either converges to finite numbers or says it did not.
#[test]
fn never_nan_when_converged_even_past_a_snap() {
    let t = |od, id, len, cl, r, e| TubeParams {
        curvature_radius_mm: Some(r),
        ..TubeParams::new(od, id, len, cl, e, 0.41)
    };
    let robot = Robot::new([
        t(6.8, 4.9, 224.0, 74.0, -97.0, 150.0),
        t(4.5, 3.3, 274.0, 114.0, 98.5, 300.0),
    ])
    .unwrap();
    let mut solver = Solver::default();
    let mut counts = [0usize; 3];
    for i in 0..400 {
        let s1 = 10.0 + (i % 20) as f64 * 3.5;
        let theta = (i / 20) as f64 * 18.0;
        for q in [
            Joints::from_mm_deg([s1, s1 + 100.0], [0.0, theta]),
            Joints::from_mm_deg([s1, s1 + 100.0], [0.0, -theta]),
        ] {
            let warm = solver
                .solve(&robot, Request::new(q, Model::Torsion))
                .unwrap();
            let cold = Solver::default()
                .solve(&robot, Request::new(q, Model::Torsion).cold())
                .unwrap();
            for sol in [warm, cold] {
                counts[sol.status as usize] += 1;
                assert!(
                    sol.tip.position.iter().all(|v| v.is_finite())
                        || sol.status == Status::Diverged
                );
                if sol.status == Status::Converged {
                    assert!(sol.residual_per_mm < 1e-9);
                }
            }
        }
    }
    eprintln!("converged / iteration limit / diverged: {counts:?}");
    assert!(counts[0] > 1000);
}

//! Loaded solves against closed forms.
use ctr_core::{
    Gravity, Joints, Loads, Model, Request, Robot, Solution, SolveError, Solver, Status, TubeParams,
};

/// A straight tube (1.2 mm outer, 0.9 mm inner diameter, 300 mm long, nitinol) and its
/// bending stiffness E I, N mm^2.
fn straight_tube() -> (Robot<f64, 1>, f64) {
    let tube = TubeParams::<f64>::new(1.2, 0.9, 300.0, 0.0, 58000.0, 0.33);
    let robot = Robot::new([tube]).unwrap();
    let ei = robot.tubes()[0].bending_stiffness_nmm2();
    (robot, ei)
}

/// The torsion solve of `robot` fed `len` mm at rotation `theta` rad under `loads`.
fn solve_loaded(
    robot: &Robot<f64, 1>,
    len: f64,
    theta: f64,
    loads: Loads<f64>,
) -> Solution<f64, 1> {
    Solver::default()
        .solve(
            robot,
            Request::new(Joints::new([len], [theta]), Model::Torsion).loads(loads),
        )
        .unwrap()
}

/// A straight cantilever under a small tip force bends by `F L^3 / (3 E I)`
/// (Euler-Bernoulli); the large-deflection correction is of relative order
/// `(F L^2 / E I)^2`, below 1e-6 here.
#[test]
fn cantilever_matches_euler_bernoulli() {
    let (robot, ei) = straight_tube();
    for (len, force) in [(100.0, 1e-4), (150.0, -2e-5)] {
        let loads = Loads {
            tip_force_n: [0.0, force, 0.0],
            ..Default::default()
        };
        let sol = solve_loaded(&robot, len, 0.3, loads);
        assert_eq!(sol.status, Status::Converged);
        let expected = force * len * len * len / (3.0 * ei);
        let rel = (sol.tip.position.y - expected).abs() / expected.abs();
        eprintln!(
            "L = {len}: deflection {:.6e} mm, Euler-Bernoulli {expected:.6e} mm",
            sol.tip.position.y
        );
        assert!(rel < 1e-5, "relative error {rel}");
        assert!(sol.tip.position.x.abs() < 1e-12);
    }
}

/// A pure tip moment bends a straight tube into an arc of curvature `M / E I`.
#[test]
fn tip_moment_makes_an_arc() {
    let (robot, ei) = straight_tube();
    let (len, moment) = (120.0, 0.5); // N mm about +y: bends toward +x
    let loads = Loads {
        tip_moment_nmm: [0.0, moment, 0.0],
        ..Default::default()
    };
    let sol = solve_loaded(&robot, len, 0.0, loads);
    let k = moment / ei;
    let expected = [(1.0 - (k * len).cos()) / k, 0.0, (k * len).sin() / k];
    assert!(
        (sol.tip.position - nalgebra::Vector3::from(expected)).norm() < 1e-9,
        "{}",
        sol.tip.position
    );
}

/// Zero loads give the unloaded torsion solution.
#[test]
fn no_load_is_the_unloaded_solution() {
    let p = |od, id, len, cl, r| TubeParams {
        curvature_radius_mm: Some(r),
        density_kg_m3: Some(6450.0),
        ..TubeParams::new(od, id, len, cl, 58000.0, 0.33)
    };
    let robot = Robot::new([
        p(1.9, 1.6, 160.0, 80.0, 300.0),
        p(1.4, 1.1, 220.0, 70.0, 180.0),
        p(0.9, 0.6, 280.0, 50.0, 80.0),
    ])
    .unwrap();
    let q = Joints::from_mm_deg([30.0, 60.0, 95.0], [10.0, 100.0, -60.0]);
    let free = Solver::default()
        .solve(&robot, Request::new(q, ctr_core::Model::Torsion).cold())
        .unwrap();
    let loaded = Solver::default()
        .solve(
            &robot,
            Request::new(q, Model::Torsion).loads(Loads::default()),
        )
        .unwrap();
    assert!((free.tip.position - loaded.tip.position).norm() < 2e-5);
    // weight needs densities
    let bare = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 300.0, 0.0, 58000.0, 0.33)]).unwrap();
    let g = Loads {
        gravity: Some(Gravity::new([0.0, 0.0, -1.0], 9.81)),
        ..Default::default()
    };
    assert_eq!(
        Solver::default().solve(
            &bare,
            Request::new(Joints::new([50.0], [0.0]), Model::Torsion).loads(g)
        ),
        Err(SolveError::MissingDensity { tube: 1 })
    );
}

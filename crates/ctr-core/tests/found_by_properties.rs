//! Regression tests of what the property tests (`properties.rs`) found, one per fix,
//! each on the smallest input the search reduced it to.
use ctr_core::{Joints, Model, Request, Robot, Solver, SolverConfig, Status, TubeParams};

fn tube(
    od: f64,
    id: f64,
    len: f64,
    curved: f64,
    radius: Option<f64>,
    e: f64,
    nu: f64,
) -> TubeParams<f64> {
    TubeParams {
        curvature_radius_mm: radius,
        ..TubeParams::new(od, id, len, curved, e, nu)
    }
}

/// A four-tube robot whose energy is strictly convex in the twist (its precurvatures
/// scaled to 0.9 of the uniqueness bound of `properties.rs`): one solution everywhere.
/// A cold start used to end at the iteration limit (residual 6e-4 rad/mm): its coarse
/// steps were too long for the twist rates of Newton's first iterates (the compliant
/// inner tube turns 0.28 rad/mm), RK4 went unstable and Newton wandered. Now a failed
/// coarse start is retried on the full steps and converges to the answer of fine steps.
#[test]
fn a_cold_start_whose_coarse_steps_fail_is_retried_on_the_full_steps() {
    let robot = Robot::new([
        tube(
            3.154780800527496,
            2.30413441719761,
            114.44227690654037,
            104.25435020742691,
            Some(-30.490896621346234),
            54536.8543281312,
            0.25,
        ),
        tube(
            2.28413441719761,
            2.12413441719761,
            161.26798640244925,
            0.0,
            None,
            1000.0,
            0.25,
        ),
        tube(
            2.10413441719761,
            0.9435073262501894,
            269.87971838533673,
            160.68770917077538,
            Some(90.66998918718399),
            72824.73995007096,
            0.2671646183129621,
        ),
        tube(
            0.6031430443913043,
            0.04094518005802613,
            331.83848227627834,
            195.94616738198928,
            Some(-422.77019419231584),
            27328.058609502317,
            0.4471189410131332,
        ),
    ])
    .unwrap()
    .scaled([1.0; 4], [4.712213763241475; 4])
    .unwrap();
    let q = Joints::from_mm_deg(
        [
            53.56228583508369,
            91.11823695680702,
            124.8430395611574,
            189.2705111774764,
        ],
        [
            359.8737349612341,
            151.66273520787183,
            120.80593420172693,
            212.76014219109052,
        ],
    );
    let cold = Solver::default()
        .solve(&robot, Request::new(q, Model::Torsion).cold())
        .unwrap();
    assert_eq!(cold.status, Status::Converged, "{cold:?}");
    let fine = Solver::new(SolverConfig {
        step_fraction: 0.02,
        ..Default::default()
    })
    .solve(&robot, Request::new(q, Model::Torsion).cold())
    .unwrap();
    assert_eq!(fine.status, Status::Converged);
    let d = (cold.tip.position - fine.tip.position).norm();
    assert!(d < 1e-5, "{d} mm from the fine-step answer");
    assert!(cold.stability_margin > 0.9, "{}", cold.stability_margin);
}

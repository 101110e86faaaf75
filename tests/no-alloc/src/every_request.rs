//! Every kind of solve request (2 and 3 tubes, f64 and f32: torsion, rigid with
//! backbone points, loads with the compliance, joint and parameter Jacobians, effects
//! with clearance kinks and friction moments, the softest mode's gradient), linked into the firmware that has no
//! global allocator: the link is the proof that ctr-core never allocates.

use ctr_core::{
    JointJacobian, Joints, Model, ParameterJacobian, Request, Robot, Solver, TubeParams,
};

fn tube<T: ctr_core::Real>(od: f64, id: f64, len: f64, cl: f64, r: f64) -> TubeParams<T> {
    let c = |v: f64| -> T { nalgebra_convert(v) };
    TubeParams {
        curvature_radius_mm: Some(c(r)),
        ..TubeParams::new(c(od), c(id), c(len), c(cl), c(58000.0), c(0.33))
    }
}

fn nalgebra_convert<T: ctr_core::Real>(v: f64) -> T {
    T::from_subset(&v)
}

fn solve3<T: ctr_core::Real>(x: T) -> T {
    let robot = match Robot::new([
        tube::<T>(1.9, 1.6, 160.0, 80.0, 300.0),
        tube::<T>(1.4, 1.1, 220.0, 70.0, 180.0),
        tube::<T>(0.9, 0.6, 280.0, 50.0, 80.0),
    ]) {
        Ok(r) => r,
        Err(_) => return T::zero(),
    };
    let mut solver = Solver::default();
    let q = Joints::new(
        [
            nalgebra_convert(30.0),
            nalgebra_convert(60.0),
            nalgebra_convert(90.0),
        ],
        [x, x + x, T::zero()],
    );
    let mut pts = [nalgebra_vec(); 32];
    let mut sum = T::zero();
    if let Ok(sol) = solver.solve(&robot, Request::new(q, Model::Torsion)) {
        sum += sol.tip.position.x + sol.tip.orientation().w;
        // the softest mode's gradient at that solution
        let request = Request::new(q, Model::Torsion);
        if let Ok(g) = solver.softest_mode_gradient(&robot, request, &sol) {
            sum += g.feed[0] + g.rotation[1] + g.smooth_within_mm;
        }
    }
    if let Ok(sol) = solver.solve(&robot, Request::new(q, Model::Rigid).backbone(&mut pts)) {
        sum += sol.tip.position.y;
    }
    let loads = ctr_core::Loads {
        tip_force_n: [x, T::zero(), T::zero()],
        ..Default::default()
    };
    let mut compliance = ctr_core::nalgebra::Matrix6::zeros();
    let request = Request::new(q, Model::Torsion).loads(loads);
    if let Ok(sol) = solver.solve(&robot, request.compliance(&mut compliance)) {
        sum += sol.tip.position.z + compliance[(0, 0)];
    }
    let mut jac = JointJacobian::nan();
    if let Ok(sol) = solver.solve(
        &robot,
        Request::new(q, Model::Torsion).joint_jacobian(&mut jac),
    ) {
        sum += sol.tip.position.x + jac.feed[0][0] + jac.rotation[2][5];
    }
    // effects, clearance kinks and friction moments, with the joint Jacobian
    let mut effects = ctr_core::Effects {
        sensor_offset_mm: [T::zero(), T::zero(), T::one()],
        ..Default::default()
    };
    effects.clearance[0] = Some(ctr_core::ClearanceProfile::Cosine {
        max_deflection_rad: nalgebra_convert(0.04),
        peak_rad: nalgebra_convert(3.5),
    });
    let request =
        Request::new(q, Model::Torsion)
            .effects(&effects)
            .friction([x, T::zero(), T::zero()]);
    if solver
        .solve(&robot, request.joint_jacobian(&mut jac))
        .is_ok()
    {
        sum += jac.feed[0][1];
    }
    let mut parameters = ParameterJacobian::nan();
    let request = Request::new(q, Model::Torsion).parameter_jacobian(&mut parameters);
    if solver.solve(&robot, request).is_ok() {
        sum += parameters.curvature[1][1];
    }
    sum
}

fn nalgebra_vec<T: ctr_core::Real>() -> ctr_core::nalgebra::Vector3<T> {
    ctr_core::nalgebra::Vector3::zeros()
}

fn solve2(x: f64) -> f64 {
    let robot = match Robot::new([
        tube::<f64>(1.8, 1.5, 180.0, 60.0, 200.0),
        tube::<f64>(1.2, 0.9, 260.0, 90.0, 100.0),
    ]) {
        Ok(r) => r,
        Err(_) => return 0.0,
    };
    match Solver::default().solve(
        &robot,
        Request::new(Joints::new([40.0, 90.0], [0.0, x]), Model::Torsion).cold(),
    ) {
        Ok(sol) => sol.tip.position.z,
        Err(_) => 0.0,
    }
}

/// Runs every kind of request once at an input the optimiser cannot see, and returns
/// the sum of what they produced (printed, so nothing is optimised away).
pub fn run() -> f64 {
    let x = core::hint::black_box(0.5_f64);
    solve3::<f64>(x) + solve3::<f32>(x as f32) as f64 + solve2(x)
}

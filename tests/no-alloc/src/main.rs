//! Links a full torsion solve (2 and 3 tubes, f64 and f32) into a bare-metal binary
//! without a global allocator: proof that ctr-core never allocates.
#![no_std]
#![no_main]

use core::panic::PanicInfo;
use ctr_core::{Joints, Model, Robot, Solver, TubeParams};

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {}
}

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
    if let Ok(sol) = solver.solve(&robot, &q, Model::Torsion) {
        sum += sol.tip.position.x + sol.tip.orientation().w;
    }
    if let Ok((sol, _)) = solver.solve_backbone(&robot, &q, Model::Rigid, &mut pts) {
        sum += sol.tip.position.y;
    }
    let loads = ctr_core::Loads {
        tip_force_n: [x, T::zero(), T::zero()],
        ..Default::default()
    };
    if let Ok(sol) = solver.solve_loaded(&robot, &q, &loads) {
        sum += sol.tip.position.z;
    }
    if let Ok((sol, jac)) = solver.solve_jacobian(&robot, &q, Model::Torsion) {
        sum += sol.tip.position.x + jac.feed[0][0] + jac.rotation[2][5];
    }
    let effects = ctr_core::effects::Effects {
        sensor_offset_mm: [T::zero(), T::zero(), T::one()],
        ..Default::default()
    };
    if let Ok((_, jac)) = solver.solve_jacobian_with(&robot, &q, Model::Torsion, &effects) {
        sum += jac.feed[0][1];
    }
    if let Ok((_, jac)) = solver.solve_parameter_jacobian(&robot, &q, Model::Torsion) {
        sum += jac.curvature[1][1];
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
    match Solver::default().solve_cold(&robot, &Joints::new([40.0, 90.0], [0.0, x]), Model::Torsion)
    {
        Ok(sol) => sol.tip.position.z,
        Err(_) => 0.0,
    }
}

/// Entry point; the values feed a volatile write so nothing is optimised away.
#[no_mangle]
pub extern "C" fn _start() -> ! {
    let mut sink = 0.0_f64;
    let x = unsafe_free_input();
    sink += solve3::<f64>(x) + solve3::<f32>(x as f32) as f64 + solve2(x);
    let mut cell = [sink];
    core::hint::black_box(&mut cell);
    loop {}
}

fn unsafe_free_input() -> f64 {
    core::hint::black_box(0.5)
}

//! A solve allocates nothing: a counting global allocator sees zero allocations during
//! every kind of request (warm, cold, rigid, backbone, joint and parameter Jacobians,
//! effects with clearance kinks and friction moments, compliance, loads, f32, the
//! softest mode's gradient; the
//! bare-metal build in `tests/no-alloc` proves the same at link time).
#![allow(unsafe_code)] // a GlobalAlloc impl is unsafe by definition

use ctr_core::nalgebra::Matrix6;
use ctr_core::{
    ClearanceProfile, Effects, JointJacobian, Joints, Model, ParameterJacobian, Registration,
    Request, Solver,
};
use ctr_suite::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations_during(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(|c| c.get());
    f();
    ALLOCATIONS.with(|c| c.get()) - before
}

#[test]
fn solves_allocate_nothing() {
    let robot3 = robot::<3>("nitinol3");
    let robot2 = robot::<2>("liu2023");
    let robot_f32 = robot_f32::<3>("nitinol3");
    let rows3 = reference::<3>("nitinol3", "torsion");
    let rows2 = reference::<2>("liu2023", "torsion");
    let mut solver3 = Solver::default();
    let mut solver2 = Solver::default();
    let mut solver_f32 = Solver::<f32, 3>::default();
    let mut points = [ctr_core::nalgebra::Vector3::zeros(); 256];
    let q_f32: Vec<Joints<f32, 3>> = rows3
        .iter()
        .map(|r| Joints::new(r.q.s_mm.map(|v| v as f32), r.q.theta_rad.map(|v| v as f32)))
        .collect();
    let mut checksum = 0.0;
    let gravity = ctr_core::Loads {
        gravity: Some(ctr_core::Gravity::new([-1.0, 0.0, 0.0], 9.81)),
        ..Default::default()
    };
    let effects = Effects::<f64, 3> {
        feed_offset_mm: [0.2, -0.1, 0.3],
        registration: Some(Registration::from_axis_angle(
            [0.0, 1.0, 0.0],
            0.3,
            [1.0, 2.0, 3.0],
        )),
        sensor_offset_mm: [0.0, 0.5, 2.0],
        ..Default::default()
    };
    let mut kinks = effects;
    kinks.clearance[0] = Some(ClearanceProfile::Cosine {
        max_deflection_rad: 0.04,
        peak_rad: 3.5,
    });
    let mut jac = JointJacobian::nan();
    let mut jac2 = JointJacobian::nan();
    let mut parameters = ParameterJacobian::nan();
    let (mut jac3, mut parameters3) = (JointJacobian::nan(), ParameterJacobian::nan());
    let (mut jac4, mut parameters4) = (JointJacobian::nan(), ParameterJacobian::nan());
    let mut compliance = Matrix6::zeros();
    let none = Effects::default();
    let n = allocations_during(|| {
        for (r3, r2) in rows3.iter().zip(&rows2) {
            let (q3, q2) = (r3.q, r2.q);
            let warm = solver3.solve(&robot3, Request::new(q3, Model::Torsion));
            let cold = solver3.solve(&robot3, Request::new(q3, Model::Torsion).cold());
            let rigid = solver3.solve(&robot3, Request::new(q3, Model::Rigid));
            let two = solver2.solve(&robot2, Request::new(q2, Model::Torsion));
            let backbone = Request::new(q3, Model::Torsion).backbone(&mut points);
            let traced = solver3.solve(&robot3, backbone);
            let with_jacobian = Request::new(q3, Model::Torsion).joint_jacobian(&mut jac);
            let jacobian = solver3.solve(&robot3, with_jacobian);
            // effects, clearance kinks and friction moments with the joint Jacobian
            let everything = Request::new(q3, Model::Torsion)
                .effects(&kinks)
                .friction([0.1, -0.05, 0.0])
                .joint_jacobian(&mut jac2);
            let composed = solver3.solve(&robot3, everything);
            let parameter = Request::new(q2, Model::Rigid).parameter_jacobian(&mut parameters);
            let by_parameter = solver2.solve(&robot2, parameter);
            // both Jacobians from one pass, through the kinks
            let both = Request::new(q3, Model::Torsion)
                .effects(&kinks)
                .jacobians(&mut jac3, &mut parameters3);
            let by_both = solver3.solve(&robot3, both);
            let compliant = Request::new(q2, Model::Torsion)
                .effects(&none)
                .compliance(&mut compliance);
            let by_load = solver2.solve(&robot2, compliant);
            let friction = solver2.solve(
                &robot2,
                Request::new(q2, Model::Torsion).friction([0.1, 0.0]),
            );
            let loaded = Request::new(q3, Model::Torsion)
                .effects(&effects)
                .loads(gravity);
            let weighed = solver3.solve(&robot3, loaded);
            // the softest mode's gradient at the warm solution (and at the two-tube one)
            let request = Request::new(q3, Model::Torsion).effects(&kinks);
            let softest = solver3.softest_mode_gradient(&robot3, request, warm.as_ref().unwrap());
            checksum += softest.unwrap().feed[0];
            let request = Request::new(q2, Model::Torsion);
            let softest = solver2.softest_mode_gradient(&robot2, request, two.as_ref().unwrap());
            checksum += softest.unwrap().rotation[0];
            // both Jacobians at the warm solution, without solving again
            let later = Request::new(q3, Model::Torsion).jacobians(&mut jac4, &mut parameters4);
            solver3
                .derivative_at(&robot3, later, warm.as_ref().unwrap())
                .unwrap();
            checksum += jac4.feed[1][2] + parameters4.curvature[2][0];
            for sol in [
                warm, cold, rigid, traced, jacobian, composed, weighed, by_both,
            ] {
                checksum += sol.unwrap().tip.position.x;
            }
            for sol in [two, by_parameter, by_load, friction] {
                checksum += sol.unwrap().tip.orientation().w;
            }
            checksum += jac.feed[2][0] + jac2.rotation[0][1] + parameters.curvature[1][0];
            checksum += jac3.rotation[2][0] + parameters3.bending_stiffness[2][1];
            checksum += compliance[(0, 0)];
        }
        for q in &q_f32 {
            checksum += solver_f32
                .solve(&robot_f32, Request::new(*q, Model::Torsion))
                .unwrap()
                .tip
                .position
                .x as f64;
        }
    });
    assert!(checksum.is_finite());
    assert_eq!(n, 0, "{n} allocations during solves");
    // the counter itself works
    assert!(allocations_during(|| drop(std::hint::black_box(vec![1u8; 10]))) >= 1);
}

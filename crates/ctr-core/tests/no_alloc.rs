//! A solve allocates nothing: a counting global allocator sees zero allocations during
//! warm, cold, backbone, rigid, Jacobian, loaded and f32 solves (the bare-metal build in `tests/no-alloc`
//! proves the same at link time).
#![allow(unsafe_code)] // a GlobalAlloc impl is unsafe by definition

use ctr_core::{Joints, Model, Solver};
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
    let effects = ctr_core::effects::Effects::<f64, 3> {
        feed_offset_mm: [0.2, -0.1, 0.3],
        registration: Some(ctr_core::effects::Registration::from_axis_angle(
            [0.0, 1.0, 0.0],
            0.3,
            [1.0, 2.0, 3.0],
        )),
        sensor_offset_mm: [0.0, 0.5, 2.0],
        ..Default::default()
    };
    let n = allocations_during(|| {
        for (r3, r2) in rows3.iter().zip(&rows2) {
            checksum += solver3
                .solve(&robot3, &r3.q, Model::Torsion)
                .unwrap()
                .tip
                .position
                .x;
            checksum += solver3
                .solve_cold(&robot3, &r3.q, Model::Torsion)
                .unwrap()
                .tip
                .position
                .y;
            checksum += solver3
                .solve(&robot3, &r3.q, Model::Rigid)
                .unwrap()
                .tip
                .position
                .z;
            checksum += solver2
                .solve(&robot2, &r2.q, Model::Torsion)
                .unwrap()
                .tip
                .orientation()
                .w;
            checksum += solver3
                .solve_backbone(&robot3, &r3.q, Model::Torsion, &mut points)
                .unwrap()
                .0
                .tip
                .position
                .x;
            let (sol, jac) = solver3
                .solve_jacobian(&robot3, &r3.q, Model::Torsion)
                .unwrap();
            checksum += sol.tip.position.x + jac.feed[2][0] + jac.rotation[0][1];
            let (_, jac) = solver3
                .solve_jacobian_with(&robot3, &r3.q, Model::Torsion, &effects)
                .unwrap();
            checksum += jac.feed[1][2];
            let (_, pj) = solver2
                .solve_parameter_jacobian(&robot2, &r2.q, Model::Rigid)
                .unwrap();
            checksum += pj.curvature[1][0];
            let (_, compliance) = solver2
                .solve_compliance(&robot2, &r2.q, &ctr_core::Loads::default())
                .unwrap();
            checksum += compliance[(0, 0)];
            checksum += solver2
                .solve_boundary_moment(&robot2, &r2.q, &[0.1, 0.0], &[1.0, 0.0])
                .unwrap()
                .tip
                .position
                .y;
            checksum += solver3
                .solve_loaded(&robot3, &r3.q, &gravity)
                .unwrap()
                .tip
                .position
                .x;
        }
        for q in &q_f32 {
            checksum += solver_f32
                .solve(&robot_f32, q, Model::Torsion)
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

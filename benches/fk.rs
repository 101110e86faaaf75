//! Forward kinematics per configuration, torsion model, default step (<= 3.5e-5 mm from
//! the reference tables; see crates/ctr-core/tests/convergence.rs).
//!
//! - `warm`: consecutive samples of a smooth trajectory (1 kHz sampling of joint sines
//!   across the robot's stable ranges), each warm-started from the previous solves.
//! - `cold`: the 200 scattered configurations of the reference table, no memory.
//!
//! Run: `taskset -c 1 cargo bench --bench fk` (one core; criterion reports the median).
//!
//! Measured 2026-11-21, 2-core AMD EPYC VM (shared, noisy), default solver settings
//! (tip within 1.1e-4 mm of the reference tables), medians, all from one run:
//!
//! | bench                     | nitinol2 | nitinol3 |
//! |---------------------------|----------|----------|
//! | torsion/warm (trajectory) | 0.47 us  | 0.95 us  |
//! | torsion/cold (scattered)  | 0.77 us  | 1.80 us  |
//! | rigid                     | 0.22 us  | 0.36 us  |
//! | gravity/warm (trajectory) | 3.4 us   | 4.9 us   |
//! | torsion+jacobian/warm     | 1.41 us  | 3.45 us  |
//!
//! Targets for 3 tubes: warm <= 1 us, cold <= 2 us, gravity <= 10 us, FK + joint
//! Jacobian <= 4 us.
//!
//! `torsion+jacobian/warm`: the warm solve plus the 6 x 2N joint Jacobian (one pass with
//! the twist in dual numbers and the frame's derivatives as spatial twists,
//! `ctr_core::solve::jacobian`).

use criterion::{criterion_group, criterion_main, Criterion};
use ctr_core::{JointJacobian, Joints, Model, Request, Robot, Solver};
use ctr_suite::*;
use std::hint::black_box;
use std::time::Duration;

/// Samples of a smooth joint trajectory inside the stable ranges of `tests/data/shared/manifest.json`:
/// increments `s_i - s_{i-1}` in `[lo, hi]`, rotations over the full circle.
fn trajectory<const N: usize>(increments: [(f64, f64); N], samples: usize) -> Vec<Joints<f64, N>> {
    (0..samples)
        .map(|k| {
            let t = k as f64 * 1e-3; // 1 kHz
            let mut s = [0.0; N];
            let mut theta = [0.0; N];
            let mut acc = 0.0;
            for i in 0..N {
                let (lo, hi) = increments[i];
                let phase = 0.7 * i as f64;
                acc += lo + (hi - lo) * 0.5 * (1.0 + (0.9 * t + phase).sin());
                s[i] = acc;
                theta[i] = 2.5 * (0.6 * t * (i as f64 + 1.0) + phase).sin();
            }
            Joints::new(s, theta)
        })
        .collect()
}

fn bench_robot<const N: usize>(c: &mut Criterion, name: &str, increments: [(f64, f64); N]) {
    let robot: Robot<f64, N> = robot::<N>(name);
    let path = trajectory(increments, 20_000);
    let scattered: Vec<Joints<f64, N>> = reference::<N>(name, "torsion")
        .into_iter()
        .map(|r| r.q)
        .collect();
    let mut group = c.benchmark_group(format!("fk/{name}"));
    group
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30);
    let mut solver = Solver::default();
    let mut k = 0;
    group.bench_function("torsion/warm", |b| {
        b.iter(|| {
            k = (k + 1) % path.len();
            if k == 0 {
                solver.reset();
            }
            black_box(
                solver
                    .solve(&robot, Request::new(path[k], Model::Torsion))
                    .unwrap()
                    .tip
                    .position,
            )
        })
    });
    let mut with_jacobian = Solver::default();
    let mut kj = 0;
    group.bench_function("torsion+jacobian/warm", |b| {
        let mut jac = JointJacobian::nan();
        b.iter(|| {
            kj = (kj + 1) % path.len();
            if kj == 0 {
                with_jacobian.reset();
            }
            let sol = with_jacobian
                .solve(
                    &robot,
                    Request::new(path[kj], Model::Torsion).joint_jacobian(&mut jac),
                )
                .unwrap();
            black_box((sol.tip.position, jac.feed[0]))
        })
    });
    let mut cold = Solver::default();
    let mut j = 0;
    for (bench, model) in [("torsion/cold", Model::Torsion), ("rigid", Model::Rigid)] {
        group.bench_function(bench, |b| {
            b.iter(|| {
                j = (j + 1) % scattered.len();
                black_box(
                    cold.solve(&robot, Request::new(scattered[j], model).cold())
                        .unwrap()
                        .tip
                        .position,
                )
            })
        });
    }
    let gravity = ctr_core::Loads {
        gravity: Some(ctr_core::Gravity::new([-1.0, 0.0, 0.0], 9.81)),
        ..Default::default()
    };
    let mut loaded = Solver::default();
    group.bench_function("gravity/warm", |b| {
        b.iter(|| {
            k = (k + 1) % path.len();
            black_box(
                loaded
                    .solve(&robot, Request::new(path[k], Model::Torsion).loads(gravity))
                    .unwrap()
                    .tip
                    .position,
            )
        })
    });
    group.finish();
}

fn fk(c: &mut Criterion) {
    bench_robot::<2>(c, "nitinol2", [(10.0, 60.0), (10.0, 80.0)]);
    bench_robot::<3>(c, "nitinol3", [(10.0, 50.0), (10.0, 50.0), (10.0, 50.0)]);
}

criterion_group!(benches, fk);
criterion_main!(benches);

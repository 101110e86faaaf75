//! scratch probe (not committed)
use ctr_core::*;
use ctr_suite::*;
#[inline(never)]
fn run(robot: &Robot<f64, 3>, qs: &[Joints<f64, 3>]) -> f64 {
    let mut solver = Solver::default();
    let mut acc = 0.0;
    for q in qs {
        acc += solver
            .solve(robot, q, Model::Torsion)
            .unwrap()
            .tip
            .position
            .x;
    }
    acc
}
fn main() {
    let robot = robot::<3>("nitinol3");
    let mut qs = vec![];
    for k in 0..20000 {
        let t = k as f64 * 1e-3;
        let mut s = [0.0; 3];
        let mut th = [0.0; 3];
        let mut acc = 0.0;
        for i in 0..3 {
            let ph = 0.7 * i as f64;
            acc += 10.0 + 40.0 * 0.5 * (1.0 + (0.9 * t + ph).sin());
            s[i] = acc;
            th[i] = 2.5 * (0.6 * t * (i as f64 + 1.0) + ph).sin();
        }
        qs.push(Joints::new(s, th));
    }
    let t0 = std::time::Instant::now();
    let a = run(&robot, &qs);
    println!("{a} warm {:?} per solve", t0.elapsed() / 20000);
    let rows = reference::<3>("nitinol3", "torsion");
    let t0 = std::time::Instant::now();
    let mut acc = 0.0;
    let mut it = [0usize; 12];
    for _ in 0..100 {
        for r in &rows {
            let s = Solver::default()
                .solve_cold(&robot, &r.q, Model::Torsion)
                .unwrap();
            acc += s.tip.position.x;
            it[s.iterations as usize] += 1;
        }
    }
    println!(
        "{acc} cold {:?} per solve, iterations {:?}",
        t0.elapsed() / 20000,
        it
    );
}
#[allow(dead_code)]
fn cold_probe() {}

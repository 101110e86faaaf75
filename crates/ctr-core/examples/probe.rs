//! scratch probe (not committed)
use ctr_core::*;
use ctr_suite::*;
fn main() {
    let robot = robot::<3>("nitinol3");
    let rows = reference::<3>("nitinol3", "torsion");
    let mut hist = [0usize; 40];
    for r in &rows { let s = Solver::default().solve_cold(&robot, &r.q, Model::Torsion).unwrap(); hist[s.iterations as usize] += 1; }
    println!("cold iterations histogram {:?}", &hist[..10]);
    let mut hist = [0usize; 40];
    let mut solver = Solver::default();
    for k in 0..2000 {
        let t = k as f64 * 1e-3;
        let mut s = [0.0; 3]; let mut th = [0.0; 3]; let mut acc = 0.0;
        for i in 0..3 { let ph = 0.7 * i as f64; acc += 10.0 + 40.0 * 0.5 * (1.0 + (0.9 * t + ph).sin()); s[i] = acc; th[i] = 2.5 * (0.6 * t * (i as f64 + 1.0) + ph).sin(); }
        let sol = solver.solve(&robot, &Joints::new(s, th), Model::Torsion).unwrap();
        hist[sol.iterations as usize] += 1;
    }
    println!("warm iterations histogram {:?}", &hist[..10]);
}

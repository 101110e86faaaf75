//! The stability margin falls to zero at a snap and stays positive over the shared
//! robots' stated stable ranges.
use ctr_core::{Joints, Model, Request, Robot, Solver, TubeParams};
use ctr_suite::*;

/// The seed's robot with transmissions 100 mm longer (tests/data/shared/robots/liu2023.toml
/// notes it snaps when the curved parts overlap far): at opposed curvatures the margin
/// falls linearly to zero where the symmetric solution loses stability (past it the
/// solver takes a stable twisted equilibrium, never the unstable symmetric one); just
/// off the symmetric angle, a warm-started rotation jumps there (a snap).
#[test]
fn margin_vanishes_at_the_snap_of_a_long_transmission_pair() {
    let t = |od, id, len, cl, r, e| TubeParams {
        curvature_radius_mm: Some(r),
        ..TubeParams::<f64>::new(od, id, len, cl, e, 0.41)
    };
    let robot = Robot::new([
        t(6.8, 4.9, 224.0, 74.0, -97.0, 150.0),
        t(4.5, 3.3, 274.0, 114.0, 98.5, 300.0),
    ])
    .unwrap();
    let solve = |s1: f64, rel: f64| {
        Solver::default()
            .solve(
                &robot,
                Request::new(
                    Joints::from_mm_deg([s1, s1 + 40.0], [0.0, rel]),
                    Model::Torsion,
                )
                .cold(),
            )
            .unwrap()
    };
    let margin = |s1: f64, rel: f64| solve(s1, rel).softest_mode;
    // the opposed configuration, untwisted, is an equilibrium at every feed; past the
    // crossing it is unstable and a cold solve takes a stable twisted one instead
    let symmetric = |s1: f64| {
        let sol = solve(s1, 0.0);
        sol.base_twist_per_mm[0].abs() < 1e-9 && sol.softest_mode > 0.0
    };
    // find the crossing by bisection
    let (mut lo, mut hi) = (20.0, 40.0);
    assert!(margin(lo, 0.0) > 0.3 && symmetric(lo) && !symmetric(hi));
    assert!(
        margin(hi, 0.0) > 0.0,
        "a stable twisted equilibrium past it"
    );
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if symmetric(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    eprintln!("margin crosses zero at s1 = {lo:.4} mm");
    assert!(margin(lo, 0.0).abs() < 1e-3);
    assert!(margin(lo - 2.0, 0.0) > 0.02 && margin(lo - 2.0, 0.0) < 0.1);
    // rotating through the opposed configuration: smooth before the crossing, a snap
    // (a jump of the warm-started solution) past it
    let sweep = |s1: f64| {
        let mut solver = Solver::default();
        let mut prev: Option<ctr_core::nalgebra::Vector3<f64>> = None;
        let mut biggest = 0.0_f64;
        for k in 0..=240 {
            let rel = -60.0 + 0.5 * k as f64;
            let sol = solver
                .solve(
                    &robot,
                    Request::new(
                        Joints::from_mm_deg([s1, s1 + 40.0], [0.0, rel]),
                        Model::Torsion,
                    ),
                )
                .unwrap();
            if let Some(p) = prev {
                biggest = biggest.max((sol.tip.position - p).norm());
            }
            prev = Some(sol.tip.position);
        }
        biggest
    };
    let (before, after) = (sweep(lo - 6.0), sweep(lo + 8.0));
    eprintln!("largest tip step per 0.5 deg of rotation: {before:.3} mm before the crossing, {after:.3} mm past it");
    assert!(after > 10.0 * before, "no snap past the crossing");
}

fn min_margin<const N: usize>(name: &str, inc: [(f64, f64); N], steps: usize) -> f64 {
    let robot = robot::<N>(name);
    let mut min = f64::MAX;
    let total = (steps + 1).pow(N as u32) * 12usize.pow((N - 1) as u32);
    for k in 0..total {
        let mut r = k;
        let (mut s, mut th, mut acc) = ([0.0; N], [0.0; N], 0.0);
        for i in 0..N {
            acc += inc[i].0 + (inc[i].1 - inc[i].0) * (r % (steps + 1)) as f64 / steps as f64;
            r /= steps + 1;
            s[i] = acc;
        }
        for item in th.iter_mut().skip(1) {
            *item = (r % 12) as f64 * 30.0;
            r /= 12;
        }
        let sol = Solver::default()
            .solve(
                &robot,
                Request::new(Joints::from_mm_deg(s, th), Model::Torsion).cold(),
            )
            .unwrap();
        min = min.min(sol.softest_mode);
    }
    min
}

#[test]
fn margin_stays_positive_over_the_stated_ranges() {
    let m = [
        (
            "liu2023",
            min_margin::<2>("liu2023", [(20.0, 70.0), (25.0, 95.0)], 10),
        ),
        (
            "nitinol2",
            min_margin::<2>("nitinol2", [(10.0, 60.0), (10.0, 80.0)], 10),
        ),
        (
            "nitinol3",
            min_margin::<3>("nitinol3", [(10.0, 50.0), (10.0, 50.0), (10.0, 50.0)], 4),
        ),
    ];
    eprintln!("smallest margins over the stated ranges: {m:?}");
    // liu2023's stated range reaches within 1e-3 of a bifurcation at its corner
    // (s1 = 70, s2 - s1 = 25, opposed curvatures); the nitinol robots keep far from one
    assert!(m.iter().all(|(_, v)| *v > 0.0));
    assert!(m[1].1 > 0.15 && m[2].1 > 0.04);
}

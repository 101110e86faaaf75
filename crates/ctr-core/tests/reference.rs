//! The core reproduces the independent simulator's tables in `tests/data/shared/reference`.

use ctr_core::{Model, Request, Solution, Solver, Status};
use ctr_suite::*;

/// Contract: tip position within 1e-3 mm, orientation within 1e-4 rad.
const POS_TOL_MM: f64 = 1e-3;
const ROT_TOL_RAD: f64 = 1e-4;

/// Checks the solves `solve` makes of every row of the table `name-table` against it:
/// each converges, and the worst tip position and orientation errors are within the
/// contract.
fn check_rows<const N: usize>(
    name: &str,
    table: &str,
    rows: &[RefRow<N>],
    mut solve: impl FnMut(&RefRow<N>) -> Solution<f64, N>,
) {
    let (mut worst_p, mut worst_r) = (0.0_f64, 0.0_f64);
    for row in rows {
        let sol = solve(row);
        assert_eq!(sol.status, Status::Converged, "{name} {:?}", row.q);
        worst_p = worst_p.max((sol.tip.position - nalgebra::Vector3::from(row.p)).norm());
        worst_r = worst_r.max(angle_between(&sol.tip.orientation(), row.quat));
    }
    eprintln!("{name}-{table}: max position error {worst_p:.3e} mm, orientation {worst_r:.3e} rad");
    assert!(worst_p <= POS_TOL_MM, "{name}-{table}: {worst_p} mm");
    assert!(worst_r <= ROT_TOL_RAD, "{name}-{table}: {worst_r} rad");
}

fn check<const N: usize>(name: &str, table: &str, model: Model) {
    let robot = robot::<N>(name);
    let rows = reference::<N>(name, table);
    assert_eq!(rows.len(), 200);
    let mut solver = Solver::default();
    check_rows(name, table, &rows, |row| {
        let sol = solver
            .solve(&robot, Request::new(row.q, model).cold())
            .unwrap();
        // warm start along the table must give the same answer
        let warm = solver.solve(&robot, Request::new(row.q, model)).unwrap();
        assert!((warm.tip.position - sol.tip.position).norm() < 1e-6);
        sol
    });
}

fn check_gravity<const N: usize>(name: &str) {
    use ctr_core::{Gravity, Loads};
    let robot = robot::<N>(name);
    let loads = Loads {
        gravity: Some(Gravity::new([-1.0, 0.0, 0.0], 9.81)),
        ..Default::default()
    };
    let mut solver = Solver::default();
    check_rows(name, "gravity", &reference::<N>(name, "gravity"), |row| {
        solver
            .solve(&robot, Request::new(row.q, Model::Torsion).loads(loads))
            .unwrap()
    });
}

/// One `#[test]` a robot and table: `test_name => the check it runs;`.
macro_rules! reference_tests {
    ($($test:ident => $check:expr;)*) => {
        $(
            #[test]
            fn $test() {
                $check;
            }
        )*
    };
}

reference_tests! {
    liu2023_rigid => check::<2>("liu2023", "rigid", Model::Rigid);
    nitinol2_rigid => check::<2>("nitinol2", "rigid", Model::Rigid);
    nitinol3_rigid => check::<3>("nitinol3", "rigid", Model::Rigid);
    liu2023_torsion => check::<2>("liu2023", "torsion", Model::Torsion);
    nitinol2_torsion => check::<2>("nitinol2", "torsion", Model::Torsion);
    nitinol3_torsion => check::<3>("nitinol3", "torsion", Model::Torsion);
    liu2023_gravity => check_gravity::<2>("liu2023");
    nitinol2_gravity => check_gravity::<2>("nitinol2");
    nitinol3_gravity => check_gravity::<3>("nitinol3");
}

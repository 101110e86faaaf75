//! scratch probe (not committed)
use ctr_core::*;
use ctr_suite::*;
fn main() {
    let robot = robot::<2>("liu2023");
    for s1 in [20.0, 45.0, 70.0] {
        let mut line = format!("liu2023 rel 0, s1 {s1}:");
        for inc in [25.0, 40.0, 55.0, 70.0, 85.0, 95.0] {
            let sol = Solver::default()
                .solve_cold(
                    &robot,
                    &Joints::from_mm_deg([s1, s1 + inc], [0.0, 0.0]),
                    Model::Torsion,
                )
                .unwrap();
            line += &format!(" {:.3}", sol.stability_margin);
        }
        println!("{line}");
    }
    let t = |od, id, len, cl, r, e| TubeParams {
        curvature_radius_mm: Some(r),
        ..TubeParams::<f64>::new(od, id, len, cl, e, 0.41)
    };
    let long = Robot::new([
        t(6.8, 4.9, 224.0, 74.0, -97.0, 150.0),
        t(4.5, 3.3, 274.0, 114.0, 98.5, 300.0),
    ])
    .unwrap();
    let mut line = String::from("long, rel 0, s2 = s1 + 40:");
    for s1 in [20.0, 25.0, 30.0, 32.0, 33.0, 35.0, 40.0] {
        let sol = Solver::default()
            .solve_cold(
                &long,
                &Joints::from_mm_deg([s1, s1 + 40.0], [0.0, 0.0]),
                Model::Torsion,
            )
            .unwrap();
        line += &format!(" {s1}:{:.3}", sol.stability_margin);
    }
    println!("{line}");
}

//! Jacobians from integrated sensitivities against central finite differences of the
//! solver itself, on the shared robots at random configurations inside the manifest's
//! ranges, and the compliance against Euler-Bernoulli.
use ctr_core::nalgebra::Vector6;
use ctr_core::{Joints, Model, Request, Robot, Solver, SolverConfig, Status, TubeParams};
use ctr_suite::*;

/// Largest accepted relative error of a Jacobian column (norm of the difference over the
/// norm of the finite difference, position and orientation blocks apart).
const REL_TOL: f64 = 1e-6;
/// Central-difference step: mm for feeds, rad for rotations, unitless for scale factors.
/// Truncation error ~ h^2/6 f''' (< 1e-9 relative here); the solver's own noise at the
/// tight tolerances below (~1e-13 mm) over 2h stays below 1e-9 too.
const FD_STEP: f64 = 1e-4;
/// Configurations per robot and model.
const CONFIGS: usize = 6;

/// A solver converged to machine precision, so that finite differences of it are exact
/// to ~1e-10.
fn tight_solver<const N: usize>() -> Solver<f64, N> {
    Solver::new(SolverConfig {
        step_tolerance_per_mm: 1e-13,
        residual_tolerance_per_mm: 1e-14,
        ..Default::default()
    })
}

/// xorshift64*: deterministic pseudo-random numbers in [0, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Random joints inside the manifest's valid ranges for `name`.
fn random_joints<const N: usize>(name: &str, rng: &mut Rng) -> Joints<f64, N> {
    let text = std::fs::read_to_string(shared_data().join("manifest.json")).unwrap();
    let m: serde_json::Value = serde_json::from_str(&text).unwrap();
    let ranges = &m["robots"][name]["valid_ranges"];
    let mut s = [0.0; N];
    let mut theta = [0.0; N];
    let mut acc = 0.0;
    for i in 0..N {
        let lo = ranges["increments"][i][0].as_f64().unwrap();
        let hi = ranges["increments"][i][1].as_f64().unwrap();
        acc += lo + (hi - lo) * rng.next();
        s[i] = acc;
        let tlo = ranges["theta_deg"][0].as_f64().unwrap();
        let thi = ranges["theta_deg"][1].as_f64().unwrap();
        theta[i] = tlo + (thi - tlo) * rng.next();
    }
    Joints::from_mm_deg(s, theta)
}

/// Relative error of a column, position and orientation blocks apart; returns the worse.
fn relative_error(got: &Vector6<f64>, fd: &Vector6<f64>) -> f64 {
    let block = |a: usize| {
        let g = got.fixed_rows::<3>(a);
        let f = fd.fixed_rows::<3>(a);
        // an absolute floor for blocks that vanish (e.g. a straight tube's orientation)
        (g - f).norm() / f.norm().max(1e-9)
    };
    block(0).max(block(3))
}

/// The largest relative error of the columns checked so far.
struct Worst(f64);

impl Worst {
    /// Checks a column's relative error `rel` against [`REL_TOL`] (`column` is the
    /// failure message) and keeps it if it is the largest.
    fn check(&mut self, rel: f64, column: std::fmt::Arguments) {
        assert!(rel <= REL_TOL, "{column}");
        self.0 = self.0.max(rel);
    }

    /// Prints the largest error, `what` saying of what, and returns it.
    fn report(self, what: std::fmt::Arguments) -> f64 {
        eprintln!("{what} max relative error {:.3e}", self.0);
        self.0
    }
}

/// Worst relative error of the joint Jacobian against central differences at random
/// configurations: of the plain tip, or with `effects` of the measured tip, against
/// differences of the same request without the Jacobian.
fn joint_columns<const N: usize>(
    name: &str,
    model: Model,
    seed: u64,
    effects: Option<&ctr_core::effects::Effects<f64, N>>,
) -> f64 {
    let robot: Robot<f64, N> = robot::<N>(name);
    let mut rng = Rng(seed);
    let mut worst = Worst(0.0);
    for _ in 0..CONFIGS {
        let q = random_joints::<N>(name, &mut rng);
        let mut solver = tight_solver::<N>();
        let (sol, jac) = match effects {
            None => {
                let mut d = ctr_core::JointJacobian::nan();
                solver
                    .solve(&robot, Request::new(q, model).joint_jacobian(&mut d))
                    .map(|sol| (sol, d))
            }
            Some(e) => {
                let mut d = ctr_core::JointJacobian::nan();
                solver
                    .solve(
                        &robot,
                        Request::new(q, model).effects(e).joint_jacobian(&mut d),
                    )
                    .map(|sol| (sol, d))
            }
        }
        .unwrap();
        assert_eq!(sol.status, Status::Converged, "{name} {q:?}");
        for col in 0..2 * N {
            let shifted = |d: f64| {
                let mut p = q;
                if col < N {
                    p.s_mm[col] += d;
                } else {
                    p.theta_rad[col - N] += d;
                }
                let mut cold = tight_solver::<N>();
                let s = match effects {
                    None => cold.solve(&robot, Request::new(p, model)),
                    Some(e) => cold.solve(&robot, Request::new(p, model).effects(e)),
                }
                .unwrap();
                assert_eq!(s.status, Status::Converged);
                s.tip
            };
            let fd = difference(
                &shifted(FD_STEP),
                &shifted(-FD_STEP),
                &sol.tip.rotation,
                FD_STEP,
            );
            let got = jac.column(col).unwrap();
            let rel = relative_error(&got, &fd);
            worst.check(
                rel,
                format_args!(
                    "{name} {model:?} column {col} at {q:?}: relative error {rel:.3e}\n got {got}\n fd {fd}"
                ),
            );
        }
    }
    let with = if effects.is_some() {
        " with static effects"
    } else {
        ""
    };
    worst.report(format_args!("{name} {model:?}: joint Jacobian{with}"))
}

#[test]
fn joint_jacobian_matches_finite_differences() {
    for model in [Model::Torsion, Model::Rigid] {
        joint_columns::<2>("liu2023", model, 0x9E37_79B9_7F4A_7C15, None);
        joint_columns::<2>("nitinol2", model, 0xD1B5_4A32_D192_ED03, None);
        joint_columns::<3>("nitinol3", model, 0x8CB9_2BA7_2F3D_8DD7, None);
    }
}

/// A robot with tube i's E I, G J or precurvature scaled (as explicit overrides).
fn scaled_robot<const N: usize>(name: &str, which: usize, tube: usize, f: f64) -> Robot<f64, N> {
    let base: Robot<f64, N> = robot::<N>(name);
    let mut p: Vec<TubeParams<f64>> = tube_params(name);
    for (i, t) in p.iter_mut().enumerate() {
        let b = &base.tubes()[i];
        t.bending_stiffness_nmm2 = Some(b.bending_stiffness_nmm2());
        t.torsional_stiffness_nmm2 = Some(b.torsional_stiffness_nmm2());
    }
    let t = &mut p[tube];
    match which {
        0 => t.bending_stiffness_nmm2 = t.bending_stiffness_nmm2.map(|v| v * f),
        1 => t.torsional_stiffness_nmm2 = t.torsional_stiffness_nmm2.map(|v| v * f),
        _ => t.curvature_radius_mm = t.curvature_radius_mm.map(|r| r / f),
    }
    Robot::new(p.try_into().unwrap()).unwrap()
}

fn parameter_columns<const N: usize>(name: &str, model: Model, seed: u64) -> f64 {
    let robot: Robot<f64, N> = robot::<N>(name);
    let mut rng = Rng(seed);
    let mut worst = Worst(0.0);
    for _ in 0..CONFIGS / 2 {
        let q = random_joints::<N>(name, &mut rng);
        let mut solver = tight_solver::<N>();
        let (sol, jac) = {
            let mut d = ctr_core::ParameterJacobian::nan();
            solver
                .solve(&robot, Request::new(q, model).parameter_jacobian(&mut d))
                .map(|sol| (sol, d))
        }
        .unwrap();
        assert_eq!(sol.status, Status::Converged);
        for which in 0..3 {
            for tube in 0..N {
                let got = [
                    jac.bending_stiffness,
                    jac.torsional_stiffness,
                    jac.curvature,
                ][which][tube];
                let mut tip = |f: f64| {
                    let r = scaled_robot::<N>(name, which, tube, f);
                    let s = solver.solve(&r, Request::new(q, model).cold()).unwrap();
                    assert_eq!(s.status, Status::Converged);
                    s.tip
                };
                let fd = difference(
                    &tip(1.0 + FD_STEP),
                    &tip(1.0 - FD_STEP),
                    &sol.tip.rotation,
                    FD_STEP,
                );
                // columns that vanish (a common stiffness scale of the rigid model,
                // a straight tube's curvature) are compared absolutely
                let rel = if fd.norm() < 1e-9 {
                    (got - fd).norm()
                } else {
                    relative_error(&got, &fd)
                };
                worst.check(
                    rel,
                    format_args!(
                        "{name} {model:?} parameter {which} tube {tube} at {q:?}: {rel:.3e}\n got {got}\n fd {fd}"
                    ),
                );
            }
        }
    }
    worst.report(format_args!("{name} {model:?}: parameter Jacobian"))
}

#[test]
fn parameter_jacobian_matches_finite_differences() {
    for model in [Model::Torsion, Model::Rigid] {
        parameter_columns::<2>("liu2023", model, 0x1234_5678_9ABC_DEF1);
        parameter_columns::<2>("nitinol2", model, 0x0FED_CBA9_8765_4321);
        parameter_columns::<3>("nitinol3", model, 0x5555_AAAA_3333_CCCC);
    }
}

/// Compliance from sensitivities against central differences of the loaded solver in
/// small tip forces and moments, at zero load.
fn compliance_columns<const N: usize>(name: &str, seed: u64) -> f64 {
    let robot: Robot<f64, N> = robot::<N>(name);
    let mut rng = Rng(seed);
    let mut worst = Worst(0.0);
    // steps: small enough that the response is linear to 1e-9 relative, large enough
    // that the tip moves ~1e-3 mm (mm/N compliances here are 1-1e3)
    let (force_step, moment_step) = (1e-6, 1e-4);
    for _ in 0..2 {
        let q = random_joints::<N>(name, &mut rng);
        let (sol, c) = {
            let mut d = ctr_core::nalgebra::Matrix6::from_element(f64::NAN);
            tight_solver::<N>()
                .solve(
                    &robot,
                    Request::new(q, Model::Torsion)
                        .loads(ctr_core::Loads::default())
                        .compliance(&mut d),
                )
                .map(|sol| (sol, d))
        }
        .unwrap();
        assert_eq!(sol.status, Status::Converged);
        for col in 0..6 {
            let h = if col < 3 { force_step } else { moment_step };
            let tip = |d: f64| {
                let mut loads = ctr_core::Loads::default();
                if col < 3 {
                    loads.tip_force_n[col] = d;
                } else {
                    loads.tip_moment_nmm[col - 3] = d;
                }
                let s = tight_solver::<N>()
                    .solve(&robot, Request::new(q, Model::Torsion).loads(loads))
                    .unwrap();
                assert_eq!(s.status, Status::Converged, "{name} {loads:?}");
                s.tip
            };
            let fd = difference(&tip(h), &tip(-h), &sol.tip.rotation, h);
            let got: Vector6<f64> = c.column(col).into_owned();
            let rel = relative_error(&got, &fd);
            worst.check(
                rel,
                format_args!(
                    "{name} compliance column {col} at {q:?}: {rel:.3e}\n got {got}\n fd {fd}"
                ),
            );
        }
    }
    worst.report(format_args!("{name}: compliance"))
}

#[test]
fn compliance_matches_finite_differences_of_the_loaded_solver() {
    compliance_columns::<2>("liu2023", 0xA5A5_5A5A_F00D_BEEF);
    compliance_columns::<2>("nitinol2", 0x0123_4567_89AB_CDEF);
    compliance_columns::<3>("nitinol3", 0xFEDC_BA98_7654_3210);
}

/// A straight cantilever of length L (exposed) and transmission `length - L`:
/// Euler-Bernoulli `dx/dF = L^3/(3EI)`, `dx/dM = dphi/dF = L^2/(2EI)`,
/// `dphi/dM = L/EI`; twist `dphi_z/dM_z = length/(GJ)` (the transmission twists too);
/// no stretch along z; nothing couples the two bending planes.
#[test]
fn straight_cantilever_compliance_is_euler_bernoulli() {
    let tube = TubeParams::<f64>::new(1.2, 0.9, 300.0, 0.0, 58000.0, 0.33);
    let robot = Robot::new([tube]).unwrap();
    let ei = robot.tubes()[0].bending_stiffness_nmm2();
    let gj = robot.tubes()[0].torsional_stiffness_nmm2();
    for (l, theta) in [(100.0, 0.0), (170.0, 0.7)] {
        let (_, c) = {
            let mut d = ctr_core::nalgebra::Matrix6::from_element(f64::NAN);
            Solver::default()
                .solve(
                    &robot,
                    Request::new(Joints::new([l], [theta]), Model::Torsion)
                        .loads(ctr_core::Loads::default())
                        .compliance(&mut d),
                )
                .map(|sol| (sol, d))
        }
        .unwrap();
        let mut expected = ctr_core::nalgebra::Matrix6::<f64>::zeros();
        let (bend, couple, rot) = (l * l * l / (3.0 * ei), l * l / (2.0 * ei), l / ei);
        // x displaces under F_x and M_y, y under F_y and -M_x
        expected[(0, 0)] = bend;
        expected[(1, 1)] = bend;
        expected[(0, 4)] = couple;
        expected[(1, 3)] = -couple;
        expected[(3, 1)] = -couple;
        expected[(4, 0)] = couple;
        expected[(3, 3)] = rot;
        expected[(4, 4)] = rot;
        expected[(5, 5)] = 300.0 / gj;
        let err = (c - expected).abs().max() / expected.abs().max();
        eprintln!("cantilever L = {l}: max error {err:.2e} of the largest entry");
        assert!(err < 1e-10, "{c}\nexpected {expected}");
    }
}

/// The f32 joint Jacobian against the f64 one: single precision carries the same
/// sensitivities (measured 2.0e-6 relative on nitinol3; f32 itself resolves 6e-8).
const F32_REL_TOL: f64 = 1e-4;

#[test]
fn f32_joint_jacobian_matches_f64() {
    let robot: Robot<f64, 3> = robot::<3>("nitinol3");
    let robot32 = robot_f32::<3>("nitinol3");
    let mut rng = Rng(0x5851_F42D_4C95_7F2D);
    let mut worst = 0.0_f64;
    for _ in 0..CONFIGS {
        let q = random_joints::<3>("nitinol3", &mut rng);
        let q32 = Joints::new(q.s_mm.map(|v| v as f32), q.theta_rad.map(|v| v as f32));
        let (sol, jac) = {
            let mut d = ctr_core::JointJacobian::nan();
            Solver::default()
                .solve(
                    &robot,
                    Request::new(q, Model::Torsion).joint_jacobian(&mut d),
                )
                .map(|sol| (sol, d))
        }
        .unwrap();
        let (sol32, jac32) = {
            let mut d = ctr_core::JointJacobian::nan();
            Solver::<f32, 3>::default()
                .solve(
                    &robot32,
                    Request::new(q32, Model::Torsion).joint_jacobian(&mut d),
                )
                .map(|sol| (sol, d))
        }
        .unwrap();
        assert_eq!(sol.status, Status::Converged);
        assert_eq!(sol32.status, Status::Converged);
        for col in 0..6 {
            let want = jac.column(col).unwrap();
            let got = jac32.column(col).unwrap().map(|v| v as f64);
            let rel = relative_error(&got, &want);
            assert!(
                rel <= F32_REL_TOL,
                "column {col} at {q:?}: {rel:.3e}\n got {got}\n want {want}"
            );
            worst = worst.max(rel);
        }
    }
    eprintln!("nitinol3: f32 joint Jacobian max relative error against f64 {worst:.3e}");
}

/// Static effects of a recording: joint offsets, a sensor offset and a registration.
fn static_effects<const N: usize>() -> ctr_core::effects::Effects<f64, N> {
    use ctr_core::effects::{Effects, Registration};
    Effects {
        feed_offset_mm: core::array::from_fn(|i| 0.7 - 0.4 * i as f64),
        rotation_offset_rad: core::array::from_fn(|i| 0.05 * (i as f64 + 1.0)),
        registration: Some(Registration::from_axis_angle(
            [0.3, -1.0, 0.4],
            0.6,
            [12.0, -4.0, 30.0],
        )),
        sensor_offset_mm: [1.5, -0.8, 4.0],
        ..Default::default()
    }
}

#[test]
fn joint_jacobian_through_offsets_sensor_and_registration_matches_finite_differences() {
    let (e2, e3) = (static_effects::<2>(), static_effects::<3>());
    joint_columns::<2>("liu2023", Model::Torsion, 0x1234_5678_9ABC_DEF1, Some(&e2));
    joint_columns::<3>("nitinol3", Model::Torsion, 0x0FED_CBA9_8765_4321, Some(&e3));
}

/// The clearance kinks are differentiated too (through the relative angle they
/// depend on): the Jacobian of the measured tip with a cosine profile or a table, on
/// top of offsets, sensor offset and registration, matches central differences.
#[test]
fn joint_jacobian_through_clearance_kinks_matches_finite_differences() {
    use ctr_core::effects::ClearanceProfile;
    let mut cosine = static_effects::<2>();
    cosine.clearance[0] = Some(ClearanceProfile::Cosine {
        max_deflection_rad: 0.04,
        peak_rad: 205f64.to_radians(),
    });
    joint_columns::<2>(
        "liu2023",
        Model::Torsion,
        0x5151_2323_4545_6767,
        Some(&cosine),
    );
    joint_columns::<2>(
        "liu2023",
        Model::Rigid,
        0x5151_2323_4545_6768,
        Some(&cosine),
    );
    // a table of 36 values: piecewise linear in the relative angle (away from its corners)
    let mut table = static_effects::<3>();
    let values: Vec<f64> = (0..36)
        .map(|k| 0.03 * (1.0 + (k as f64 * 10f64.to_radians() - 3.5).cos()) / 2.0)
        .collect();
    table.clearance[0] = ClearanceProfile::table(&values);
    table.clearance[1] = ClearanceProfile::table(&values[..24]);
    joint_columns::<3>(
        "nitinol3",
        Model::Torsion,
        0x0F0F_1E1E_2D2D_3C3C,
        Some(&table),
    );
}

/// The boundary friction moments are part of the residuals the Jacobian eliminates: the
/// joint Jacobian of a solve with friction matches central differences of that solve.
#[test]
fn joint_jacobian_with_boundary_friction_matches_finite_differences() {
    let robot: Robot<f64, 3> = robot::<3>("nitinol3");
    let mut rng = Rng(0x7777_1111_2222_3333);
    let friction = [0.15, -0.1, 0.0];
    for _ in 0..3 {
        let q = random_joints::<3>("nitinol3", &mut rng);
        let request = |p: Joints<f64, 3>| Request::new(p, Model::Torsion).friction(friction);
        let mut jac = ctr_core::JointJacobian::nan();
        let sol = tight_solver::<3>()
            .solve(&robot, request(q).joint_jacobian(&mut jac))
            .unwrap();
        assert_eq!(sol.status, Status::Converged);
        for col in 0..6 {
            let tip = |d: f64| {
                let mut p = q;
                if col < 3 {
                    p.s_mm[col] += d;
                } else {
                    p.theta_rad[col - 3] += d;
                }
                tight_solver::<3>().solve(&robot, request(p)).unwrap().tip
            };
            let fd = difference(&tip(FD_STEP), &tip(-FD_STEP), &sol.tip.rotation, FD_STEP);
            let rel = relative_error(&jac.column(col).unwrap(), &fd);
            assert!(rel <= REL_TOL, "column {col} at {q:?}: {rel:.3e}");
        }
    }
}

/// The joint and parameter Jacobians from one pass ([`Request::jacobians`]) against
/// each from its own pass: the same derivative, so equal to rounding.
fn both_at_once<const N: usize>(robot: &Robot<f64, N>, name: &str, model: Model, seed: u64) {
    let mut rng = Rng(seed);
    for _ in 0..CONFIGS {
        let q = random_joints::<N>(name, &mut rng);
        let (mut j, mut p) = (
            ctr_core::JointJacobian::nan(),
            ctr_core::ParameterJacobian::nan(),
        );
        let (mut j1, mut p1) = (j, p);
        let mut solver = tight_solver::<N>();
        solver
            .solve(
                robot,
                Request::new(q, model).cold().jacobians(&mut j, &mut p),
            )
            .unwrap();
        solver
            .solve(robot, Request::new(q, model).cold().joint_jacobian(&mut j1))
            .unwrap();
        solver
            .solve(
                robot,
                Request::new(q, model).cold().parameter_jacobian(&mut p1),
            )
            .unwrap();
        let together = j.feed.iter().chain(&j.rotation).chain(&p.bending_stiffness);
        let together = together.chain(&p.torsional_stiffness).chain(&p.curvature);
        let alone = j1
            .feed
            .iter()
            .chain(&j1.rotation)
            .chain(&p1.bending_stiffness);
        let alone = alone.chain(&p1.torsional_stiffness).chain(&p1.curvature);
        for (k, (a, b)) in together.zip(alone).enumerate() {
            let gap = (a - b).norm();
            assert!(
                gap <= 1e-9 * (1.0 + b.norm()),
                "{name} {model:?} column {k} at {q:?}: {gap:.3e}\n together {a}\n alone {b}"
            );
        }
    }
}

#[test]
fn joint_and_parameter_jacobians_at_once_are_each_alone() {
    for model in [Model::Torsion, Model::Rigid] {
        both_at_once::<2>(
            &robot::<2>("liu2023"),
            "liu2023",
            model,
            0x2468_ACE0_1357_9BDF,
        );
        both_at_once::<3>(
            &robot::<3>("nitinol3"),
            "nitinol3",
            model,
            0x1357_9BDF_2468_ACE0,
        );
    }
}

/// The derivatives at a solution found before ([`Solver::derivative_at`]) against
/// asking for them in the solve: the same numbers, bit for bit (joint, parameter and
/// both), through joint offsets, clearance kinks and a registration; a sensor offset,
/// whose lever arm needs the tip before the measurement, is refused.
fn at_a_solution<const N: usize>(name: &str, model: Model, seed: u64) {
    use ctr_core::effects::ClearanceProfile;
    let robot: Robot<f64, N> = robot::<N>(name);
    let mut effects = static_effects::<N>();
    effects.sensor_offset_mm = [0.0; 3];
    effects.clearance[0] = Some(ClearanceProfile::Cosine {
        max_deflection_rad: 0.04,
        peak_rad: 205f64.to_radians(),
    });
    let mut rng = Rng(seed);
    let mut chain = Solver::<f64, N>::default();
    for _ in 0..CONFIGS {
        let q = random_joints::<N>(name, &mut rng);
        let request = || Request::new(q, model).effects(&effects);
        // the solver as it found the row: each derivative asked in a solve from it
        let state = chain;
        let plain = chain.solve(&robot, request()).unwrap();
        let other = Solver::<f64, N>::default();
        let nan = || {
            (
                ctr_core::JointJacobian::<f64, N>::nan(),
                ctr_core::ParameterJacobian::<f64, N>::nan(),
            )
        };
        let ((mut j, mut p), (mut j1, mut p1)) = (nan(), nan());
        let mut asked = state;
        let within = asked
            .solve(&robot, request().jacobians(&mut j, &mut p))
            .unwrap();
        assert_eq!(within.tip, plain.tip, "{name} {model:?}: the same solve");
        other
            .derivative_at(&robot, request().jacobians(&mut j1, &mut p1), &plain)
            .unwrap();
        assert_eq!((j1, p1), (j, p), "{name} {model:?} at {q:?}: both");
        let ((mut j, mut p), (mut j1, mut p1)) = (nan(), nan());
        asked = state;
        asked
            .solve(&robot, request().joint_jacobian(&mut j))
            .unwrap();
        other
            .derivative_at(&robot, request().joint_jacobian(&mut j1), &plain)
            .unwrap();
        assert_eq!(j1, j, "{name} {model:?} at {q:?}: the joints");
        asked = state;
        asked
            .solve(&robot, request().parameter_jacobian(&mut p))
            .unwrap();
        other
            .derivative_at(&robot, request().parameter_jacobian(&mut p1), &plain)
            .unwrap();
        assert_eq!(p1, p, "{name} {model:?} at {q:?}: the parameters");
    }
    let mut offset = effects;
    offset.sensor_offset_mm = [0.0, 0.0, 2.0];
    let q = random_joints::<N>(name, &mut rng);
    let sol = chain
        .solve(&robot, Request::new(q, model).effects(&offset))
        .unwrap();
    let mut j = ctr_core::JointJacobian::nan();
    let refused = chain.derivative_at(
        &robot,
        Request::new(q, model)
            .effects(&offset)
            .joint_jacobian(&mut j),
        &sol,
    );
    assert!(refused.is_err(), "a sensor offset");
}

#[test]
fn derivatives_at_a_solution_are_those_of_the_solve() {
    for model in [Model::Torsion, Model::Rigid] {
        at_a_solution::<2>("liu2023", model, 0x0BAD_CAFE_1234_5678);
        at_a_solution::<3>("nitinol3", model, 0x0DEA_DBEE_F123_4567);
    }
}

//! Regression tests of what the property tests (`properties.rs`) found, one per fix,
//! each on the smallest input the search reduced it to.
use ctr_core::{Joints, Model, Request, Robot, Solver, SolverConfig, Status, TubeParams};

fn tube(
    od: f64,
    id: f64,
    len: f64,
    curved: f64,
    radius: Option<f64>,
    e: f64,
    nu: f64,
) -> TubeParams<f64> {
    TubeParams {
        curvature_radius_mm: radius,
        ..TubeParams::new(od, id, len, curved, e, nu)
    }
}

/// A four-tube robot whose energy is strictly convex in the twist (its precurvatures
/// scaled to 0.9 of the uniqueness bound of `properties.rs`): one solution everywhere.
/// A cold start used to end at the iteration limit (residual 6e-4 rad/mm): its coarse
/// steps were too long for the twist rates of Newton's first iterates (the compliant
/// inner tube turns 0.28 rad/mm), RK4 went unstable and Newton wandered. Now a failed
/// coarse start is retried on the full steps and converges to the answer of fine steps.
#[test]
fn a_cold_start_whose_coarse_steps_fail_is_retried_on_the_full_steps() {
    let robot = Robot::new([
        tube(
            3.154780800527496,
            2.30413441719761,
            114.44227690654037,
            104.25435020742691,
            Some(-30.490896621346234),
            54536.8543281312,
            0.25,
        ),
        tube(
            2.28413441719761,
            2.12413441719761,
            161.26798640244925,
            0.0,
            None,
            1000.0,
            0.25,
        ),
        tube(
            2.10413441719761,
            0.9435073262501894,
            269.87971838533673,
            160.68770917077538,
            Some(90.66998918718399),
            72824.73995007096,
            0.2671646183129621,
        ),
        tube(
            0.6031430443913043,
            0.04094518005802613,
            331.83848227627834,
            195.94616738198928,
            Some(-422.77019419231584),
            27328.058609502317,
            0.4471189410131332,
        ),
    ])
    .unwrap()
    .scaled([1.0; 4], [4.712213763241475; 4])
    .unwrap();
    let q = Joints::from_mm_deg(
        [
            53.56228583508369,
            91.11823695680702,
            124.8430395611574,
            189.2705111774764,
        ],
        [
            359.8737349612341,
            151.66273520787183,
            120.80593420172693,
            212.76014219109052,
        ],
    );
    let cold = Solver::default()
        .solve(&robot, Request::new(q, Model::Torsion).cold())
        .unwrap();
    assert_eq!(cold.status, Status::Converged, "{cold:?}");
    let fine = Solver::new(SolverConfig {
        step_fraction: 0.02,
        ..Default::default()
    })
    .solve(&robot, Request::new(q, Model::Torsion).cold())
    .unwrap();
    assert_eq!(fine.status, Status::Converged);
    let d = (cold.tip.position - fine.tip.position).norm();
    assert!(d < 1e-5, "{d} mm from the fine-step answer");
    assert!(cold.softest_mode > 0.9, "{}", cold.softest_mode);
}

/// One Newton iteration on steps of 0.75 of the length scale: the iterate's pose
/// overflowed (RK4 unstable at its twist) and the solve returned a NaN tip with
/// `Status::Diverged`, where the documentation promised the best finite iterate. The
/// rigid model's pose (closed form) was then reported for a pose that overflows; since
/// the steps of a coupled section follow the twist rates (`MAX_TURN_PER_STEP`), this
/// iterate's own pose no longer overflows and is the one reported: finite, and the
/// solve not converged.
#[test]
fn a_diverged_solve_reports_a_finite_pose() {
    let robot = Robot::new([
        tube(
            3.6448880547391886,
            3.4848880547391885,
            281.8184050590474,
            148.02416170846215,
            Some(145.76586404320025),
            70626.61713169861,
            0.34154647395412946,
        ),
        tube(
            3.4648880547391885,
            2.71030499540259,
            429.6243386902862,
            180.3478132259301,
            Some(25.85855009950234),
            60303.92314691568,
            0.40421115892223825,
        ),
        tube(
            2.392575591886588,
            1.3856182252713731,
            446.98514748259487,
            172.19931716450301,
            Some(-1522.3020316445657),
            71206.9519688576,
            0.36415456988710526,
        ),
        tube(
            1.1343210943730568,
            0.7086254130850937,
            489.07820828043276,
            117.16936137953198,
            Some(-912.440807336691),
            67394.48420015041,
            0.4251729685308327,
        ),
    ])
    .unwrap();
    let s1 = 281.8184050590474 * 0.7853960495933318;
    let s2 = s1 + (429.6243386902862 - s1) * 0.43337499420883774;
    let q = Joints::from_mm_deg([s1, s2, s2, s2], [34.742008555995426, 0.0, 0.0, 0.0]);
    let mut solver = Solver::new(SolverConfig {
        max_step_mm: 71.92407258382028,
        step_fraction: 0.7541952990131027,
        max_iterations: 1,
        ..Default::default()
    });
    let sol = solver
        .solve(&robot, Request::new(q, Model::Torsion))
        .unwrap();
    assert_ne!(sol.status, Status::Converged);
    let tip = &sol.tip;
    assert!(
        tip.position
            .iter()
            .chain(tip.rotation.iter())
            .all(|v| v.is_finite()),
        "{sol:?}"
    );
    assert!(
        sol.residual_per_mm.is_finite() && sol.base_twist_per_mm.iter().all(|v| v.is_finite()),
        "{sol:?}"
    );
    // the iterate is no further from the guide exit than the innermost tube reaches
    assert!(sol.tip.position.norm() <= q.s_mm[3], "{sol:?}");
}

/// A 0.26 mm plastic fibre (G J 4.7e4 times smaller) inside nitinol tubes,
/// precurvatures scaled to 0.9 of the uniqueness bound (one solution): the fibre's base
/// twist is the outer tubes' residual times their G J ratio, Newton's iterates turned
/// it by radians per millimetre, the fixed RK4 steps went unstable at those rates, and
/// every start ended `Diverged` (with a tip 1e49 mm away). Now a coupled section takes
/// the steps its starting twist rates need (`MAX_TURN_PER_STEP`): the cold solve
/// converges, to the tip of fine steps.
#[test]
fn a_fibre_inside_a_stiff_tube_is_solved_cold() {
    let robot = Robot::new([
        tube(
            2.136489361525203,
            1.4728365713784461,
            153.36913699218536,
            41.85175543173896,
            Some(19.999999999999996),
            30025.074367217105,
            0.25,
        ),
        tube(
            1.4528365713784461,
            0.4607746763160665,
            173.14553788179447,
            83.87804776320353,
            Some(684.9488109076444),
            74174.78323989651,
            0.28657689894805277,
        ),
        tube(
            0.4407746763160665,
            0.28077467631606645,
            240.56491817963496,
            67.86705356070179,
            Some(-1678.1926687022642),
            46933.614860795766,
            0.3107408540713759,
        ),
        tube(
            0.26077467631606643,
            0.06652733388841453,
            348.0929042169265,
            133.19546001343753,
            Some(-676.5035899156123),
            2352.365380174903,
            0.3220915464470149,
        ),
    ])
    .unwrap();
    let t = robot.tubes();
    let gj: Vec<f64> = t.iter().map(|t| t.torsional_stiffness_nmm2()).collect();
    assert!(gj[0] / gj[3] > 4e4, "{}", gj[0] / gj[3]);
    // scaled to 0.9 of the uniqueness bound, as the property scales it
    let ratio = (0..4)
        .map(|i| {
            let c: f64 = (0..4)
                .filter(|&l| l != i)
                .map(|l| {
                    let (a, b) = (t[i].bending_stiffness_nmm2(), t[l].bending_stiffness_nmm2());
                    a * b * (t[i].curvature_per_mm() * t[l].curvature_per_mm()).abs() / (a + b)
                })
                .sum();
            2.0 * c / (gj[i] * (std::f64::consts::PI / (2.0 * t[i].params().length_mm)).powi(2))
        })
        .fold(0.0, f64::max);
    let robot = robot.scaled([1.0; 4], [(ratio / 0.9).sqrt(); 4]).unwrap();
    let lengths = [
        153.36913699218536,
        173.14553788179447,
        240.56491817963496,
        348.0929042169265,
    ];
    let u = [
        0.8330816579520958,
        0.11460711143956613,
        0.332335635537957,
        0.3350667688230968,
    ];
    let mut s = [0.0; 4];
    let mut prev = 0.0;
    for i in 0..4 {
        s[i] = prev + (lengths[i] - prev) * u[i];
        prev = s[i];
    }
    let q = Joints::from_mm_deg(
        s,
        [
            347.60064675431124,
            299.39318019664927,
            -198.67901949774335,
            -324.1372176402329,
        ],
    );
    let sol = Solver::default()
        .solve(&robot, Request::new(q, Model::Torsion).cold())
        .unwrap();
    assert_eq!(sol.status, Status::Converged, "{sol:?}");
    let fine = fine()
        .solve(&robot, Request::new(q, Model::Torsion))
        .unwrap();
    let d = (sol.tip.position - fine.tip.position).norm();
    assert!(d <= DEFAULT_STEPS_MM, "{d} mm from the tip of fine steps");
}

/// How close the default steps' tip is to that of fine steps on these robots, mm (the
/// default steps keep the shared robots' tips within 1.1e-4 mm of the references).
const DEFAULT_STEPS_MM: f64 = 1e-4;

/// A solver on fine steps (a hundredth of each section's length scale, at most 2 mm)
/// converged tightly: the equations' answer, to compare the default steps with.
fn fine<const N: usize>() -> Solver<f64, N> {
    Solver::new(SolverConfig {
        step_fraction: 0.01,
        max_step_mm: 2.0,
        max_iterations: 100,
        step_tolerance_per_mm: 1e-13,
        residual_tolerance_per_mm: 1e-14,
    })
}

/// A 0.44 mm wire inside 2 mm nitinol tubes (G J contrast 629), precurvatures scaled to
/// 0.9 of the uniqueness bound (one solution), its middle tubes ending 0.46 mm apart:
/// a cold solve (and a warm one) ended `Diverged` with the rigid model's tip, where
/// a fifth of the default step converged. At the start `x = 0` the outer tubes end with
/// a torque left, which passes to the wire: its twist rate jumps by 629 times theirs,
/// and RK4 on the default 25 mm steps turned the relative angles by radians per step
/// (residual 5e5 rad/mm, then overflow). A coupled section now takes at least the steps
/// that keep each turn per step below `MAX_TURN_PER_STEP` at the rates it starts with.
/// (Found as `cold_and_warm_starts_agree_where_the_solution_is_unique` failing: the
/// solution was unique, the solver wrong.)
#[test]
fn a_wire_inside_stiff_tubes_is_solved_cold() {
    let robot = Robot::new([
        tube(
            2.3206599611835825,
            2.1606599611835824,
            119.01640538692841,
            73.04978242365178,
            Some(19.999999999999996),
            75326.6015580379,
            0.25,
        ),
        tube(
            2.1406599611835824,
            1.1325925204662899,
            262.1383085696404,
            138.46841825959572,
            Some(19.999999999999996),
            75957.64644822756,
            0.25,
        ),
        tube(
            1.1125925204662899,
            0.6352133966543548,
            310.41775559668685,
            161.16067422139173,
            Some(1204.3257360236437),
            55986.30356321323,
            0.2956073690395483,
        ),
        tube(
            0.441314872525705,
            0.2573115729925359,
            345.79059192132763,
            86.50062288833547,
            Some(882.6193803859323),
            78465.99104719018,
            0.4081861925666881,
        ),
    ])
    .unwrap()
    .scaled([1.0; 4], [7.234410414478549; 4])
    .unwrap();
    let q = Joints::new(
        [
            100.2338085039637,
            198.4992537577163,
            198.9566578654398,
            228.5024664548221,
        ],
        [
            -3.2515680463320407,
            -5.320004516834913,
            -4.425460112660052,
            -0.09507834159490045,
        ],
    );
    let cold = Solver::default()
        .solve(&robot, Request::new(q, Model::Torsion).cold())
        .unwrap();
    assert_eq!(cold.status, Status::Converged, "{cold:?}");
    let fine = fine()
        .solve(&robot, Request::new(q, Model::Torsion))
        .unwrap();
    let d = (cold.tip.position - fine.tip.position).norm();
    // 1.4e-6 mm measured
    assert!(d <= DEFAULT_STEPS_MM, "{d} mm from the tip of fine steps");
}

/// A user's coarse steps (0.46 of the length scale, up to 89 mm, 8 iterations), a warm
/// start 71 mm of feed and 1500 degrees away: the solve "converged" (residual 2e-14)
/// with a base twist of -10 rad/mm and the tip 2752 mm from the guide exit of a robot
/// 30 mm out, a root of the discretisation (RK4 at 10 rad/mm on 10 mm steps), not of
/// the equations. With the steps following the twist rates that root is gone: the warm
/// start converges where the cold one does (the tip of fine steps within 2e-7 mm).
#[test]
fn coarse_steps_do_not_converge_to_a_root_of_the_discretisation() {
    let robot = Robot::new([
        tube(
            1.2482464925602783,
            0.6948332656872487,
            101.45041626262334,
            3.4887792309682237,
            Some(23.293998211832616),
            53110.84994741359,
            0.44597226758799086,
        ),
        tube(
            0.4148842149786546,
            0.2196944837991156,
            230.55943363242045,
            93.16182499170552,
            Some(38.975038994930536),
            48036.43494908387,
            0.4340264845748976,
        ),
    ])
    .unwrap();
    let config = SolverConfig {
        max_step_mm: 88.7756814813208,
        step_fraction: 0.4582371024933365,
        max_iterations: 8,
        ..Default::default()
    };
    let before = Joints::from_mm_deg(
        [100.71289007409224, 100.71289007409224],
        [-28.716120001047422, -1760.280725897108],
    );
    let q = Joints::from_mm_deg(
        [29.6827541914923, 29.6827541914923],
        [1495.8139849928602, 282.4700008404803],
    );
    let mut solver = Solver::new(config);
    solver
        .solve(&robot, Request::new(before, Model::Torsion))
        .unwrap();
    let warm = solver
        .solve(&robot, Request::new(q, Model::Torsion))
        .unwrap();
    assert_eq!(warm.status, Status::Converged, "{warm:?}");
    assert!(warm.tip.position.norm() <= q.s_mm[1], "{warm:?}");
    let cold = Solver::new(config)
        .solve(&robot, Request::new(q, Model::Torsion).cold())
        .unwrap();
    assert!(
        (warm.tip.position - cold.tip.position).norm() <= 1e-9,
        "{warm:?} {cold:?}"
    );
    let fine = fine()
        .solve(&robot, Request::new(q, Model::Torsion))
        .unwrap();
    let d = (warm.tip.position - fine.tip.position).norm();
    assert!(d <= DEFAULT_STEPS_MM, "{d} mm from the tip of fine steps");
}

/// A multistable three-tube robot along steps of 0.05 mm and degrees, solved warm: the
/// first solve lands on an unstable equilibrium, the second snaps to a stable one
/// (softest mode 5.4), and the third, extrapolated along the line through those two
/// solutions of different branches, was sent into a third equilibrium's basin: the tip
/// jumped 208 mm where the Jacobians allow 0.04. The solver now extrapolates only
/// along one branch (after a snap or a retry it starts from the last solution alone):
/// the third solve continues the second's branch. (Today the first solve is already
/// stable: see the note in the body.)
#[test]
fn a_warm_start_does_not_extrapolate_across_a_snap() {
    let robot = Robot::new([
        tube(
            3.3350426230512973,
            2.8670192823323615,
            242.2280077708932,
            177.52337933037288,
            Some(33.969965372200456),
            9386.798871738809,
            0.3867565417351732,
        ),
        tube(
            2.560092817889612,
            1.8723799757312904,
            281.46529729649285,
            157.73002957693808,
            Some(139.13149132612716),
            65484.11431393781,
            0.43923237567730217,
        ),
        tube(
            1.8523799757312904,
            1.0196955554462317,
            331.81739172697064,
            113.75274063637167,
            Some(43.37332946699747),
            43035.81173304449,
            0.414351525866247,
        ),
    ])
    .unwrap();
    let path = [
        Joints::new(
            [229.2040382978194, 251.99813399128936, 273.0105955968339],
            [-4.67026715071575, -1.756299278400498, -3.2706094708129623],
        ),
        Joints::new(
            [229.20236053256178, 252.0097158195753, 273.0093082453248],
            [-4.670287482866285, -1.7561411077314169, -3.2711251416275657],
        ),
        Joints::new(
            [229.20068276730413, 252.02129764786122, 273.0080208938157],
            [-4.67030781501682, -1.7559829370623354, -3.271640812442169],
        ),
    ];
    let mut solver = Solver::default();
    let sols = path.map(|q| {
        solver
            .solve(&robot, Request::new(q, Model::Torsion))
            .unwrap()
    });
    // Since the core solves along the softest direction of the full block (a 2 x 2
    // block padded by its own norm, not 1e30), the first solve lands on the stable
    // branch at once (softest mode 1.1): no snap happens on this path any more, and
    // what is left to hold is the property itself, every step continuing one branch.
    // The one-branch rule is still what keeps the third solve there when the first is
    // unstable (the solver's memory after a snap).
    assert!(sols[1].softest_mode > 1.0, "{sols:?}");
    for k in 1..sols.len() {
        let moved = (sols[k].tip.position - sols[k - 1].tip.position).norm();
        assert!(
            moved < 0.1,
            "the tip jumped {moved} mm at step {k}: {sols:?}"
        );
    }
    assert!(
        (sols[2].softest_mode - sols[1].softest_mode).abs() < 1e-3,
        "{sols:?}"
    );
}

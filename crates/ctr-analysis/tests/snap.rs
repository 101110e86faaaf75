//! Snap-through along joint sweeps of the seed's robot with 100 mm longer transmissions,
//! solved as `ctr-cli fk --threads 1` solves a joint file, checked against an independent
//! continuation (`sweeps::continuation`) and the closed-form two-tube criterion.
mod sweeps;

use ctr_analysis::batch::{batch_fk, BatchOptions, WARM_CHUNK_ROWS};
use ctr_analysis::margin::DEFAULT_WARN_MARGIN;
use ctr_analysis::model::ModelSpec;
use ctr_core::{Joints, Model, Request, Robot, Solver, Status, TubeParams};
use ctr_formats::FkResult;
use sweeps::continuation::{follow, Followed, TwoTubes};

/// Transmissions this much longer than the seed's make its pair snap, mm.
const EXTRA_TRANSMISSION_MM: f64 = 100.0;
/// Feed of tube 2 beyond tube 1 in the sweeps, mm.
const INNER_AHEAD_MM: f64 = 40.0;
/// Step of the relative angle along a sweep, degrees.
const STEP_DEG: f64 = 2.0;
/// A tip within this of the continuation's is on its branch, mm.
const ON_BRANCH_MM: f64 = 0.5;

fn params() -> Vec<TubeParams<f64>> {
    sweeps::long_transmissions(EXTRA_TRANSMISSION_MM)
        .robot
        .tube_params()
}

/// The closed-form softest mode of the symmetric configuration (the tubes' curvatures opposed,
/// untwisted: an equilibrium at every feed): with the overlap of the curved parts `l`,
/// the straight length behind it (transmissions, compliance-weighted, and the common
/// straight part) `L` and `lambda = l sqrt|C|`, the twist perturbation
/// `db'' = -|C| db` with `db(0) = L db'(0)` gives
/// `db'(l) / db'(0) = cos(lambda) - (L / l) lambda sin(lambda)`, zero at the critical
/// feed `(L / l) lambda tan(lambda) = 1` (Gilbert, Hendrick & Webster 2016; for
/// `L = 0`, `lambda = pi / 2`, Dupont et al. 2010).
fn closed_form_margin(params: &[TubeParams<f64>], s1: f64) -> f64 {
    let two = TwoTubes::new(params, [s1, s1 + INNER_AHEAD_MM]);
    let (start, end) = two.overlap().expect("the curved parts overlap");
    let l = end - start;
    let straight = two.transmission() + start;
    let lambda = l * two.coupling().abs().sqrt();
    lambda.cos() - straight / l * lambda * lambda.sin()
}

/// The relative angle of the symmetric configuration, degrees.
fn symmetric_deg(params: &[TubeParams<f64>]) -> f64 {
    sweeps::relaxed_deg(params) + 180.0
}

fn cold(robot: &Robot<f64, 2>, s1: f64, rel_deg: f64) -> ctr_core::Solution<f64, 2> {
    Solver::default()
        .solve(
            robot,
            Request::new(
                Joints::from_mm_deg([s1, s1 + INNER_AHEAD_MM], [0.0, rel_deg]),
                Model::Torsion,
            )
            .cold(),
        )
        .unwrap()
}

#[test]
fn the_softest_mode_at_the_symmetric_configuration_is_the_closed_form_and_vanishes_at_the_critical_feed(
) {
    let params = params();
    let robot: Robot<f64, 2> = Robot::new([params[0], params[1]]).unwrap();
    let sym = symmetric_deg(&params);
    for s1 in [15.0, 20.0, 25.0, 28.0, 30.0, 31.5] {
        let sol = cold(&robot, s1, sym);
        let want = closed_form_margin(&params, s1);
        eprintln!(
            "s1 = {s1}: softest mode {:.6}, closed form {want:.6}",
            sol.softest_mode
        );
        assert!(
            (sol.softest_mode - want).abs() < 1e-5,
            "s1 = {s1}: {} vs {want}",
            sol.softest_mode
        );
    }
    // the critical feed: the closed form's zero, and where the core stops returning the
    // symmetric equilibrium (past it that one is unstable and the solver takes a stable
    // twisted one)
    let bisect = |below: &dyn Fn(f64) -> bool| {
        let (mut lo, mut hi) = (20.0, 45.0);
        assert!(below(lo) && !below(hi));
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if below(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    };
    let closed = bisect(&|s1| closed_form_margin(&params, s1) > 0.0);
    let core = bisect(&|s1| {
        let sol = cold(&robot, s1, sym);
        sol.base_twist_per_mm[0].abs() < 1e-9 && sol.softest_mode > 0.0
    });
    eprintln!("critical feed s1: closed form {closed:.4} mm, core {core:.4} mm");
    assert!((closed - core).abs() < 0.01, "{closed} vs {core}");
    let past = cold(&robot, core + 1.0, sym);
    eprintln!(
        "1 mm past it: margin {:.4}, base twist {:.2e} rad/mm",
        past.softest_mode, past.base_twist_per_mm[0]
    );
    assert!(past.softest_mode > 0.0 && past.base_twist_per_mm[0].abs() > 1e-6);
}

/// One sweep: the rows, the continuation along them and the rows as solved.
struct Sweep {
    s1: f64,
    followed: Vec<Followed>,
    solved: Vec<FkResult>,
}

fn sweep(params: &[TubeParams<f64>], s1: f64) -> Sweep {
    let s = [s1, s1 + INNER_AHEAD_MM];
    let rows = sweeps::full_turn(s, sweeps::relaxed_deg(params), STEP_DEG);
    let angles: Vec<[f64; 2]> = rows
        .iter()
        .map(|r| [r[1].to_radians(), r[3].to_radians()])
        .collect();
    let followed = follow(params, s, &angles);
    let spec = sweeps::long_transmissions(EXTRA_TRANSMISSION_MM);
    let model = ModelSpec::from_spec(&spec).rows().unwrap();
    // as `ctr-cli fk --threads 1` solves a joint file
    let options = BatchOptions {
        threads: 1,
        chunk_rows: WARM_CHUNK_ROWS,
        margins: true,
    };
    let solved = batch_fk(&model, rows.as_flattened(), None, &options, &())
        .unwrap()
        .into_iter()
        .map(Result::unwrap)
        .collect();
    Sweep {
        s1,
        followed,
        solved,
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

#[test]
fn sweeps_follow_the_branch_of_the_continuation_and_the_margin_foretells_each_snap() {
    let params = params();
    // two feeds below the critical one (no snap) and three past it
    let sweeps: Vec<Sweep> = [20.0, 28.0, 40.0, 55.0, 70.0]
        .iter()
        .map(|&s1| sweep(&params, s1))
        .collect();
    let mut lowest_calm = f64::MAX;
    let mut highest_before_snap = f64::MIN;
    for sw in &sweeps {
        let jumps: Vec<usize> = (0..sw.followed.len())
            .filter(|&i| sw.followed[i].jumped)
            .collect();
        // on the continuation's branch, the rows right after a jump aside
        let judged: Vec<usize> = (0..sw.solved.len())
            .filter(|i| !jumps.contains(i))
            .collect();
        let on = judged
            .iter()
            .filter(|&&i| distance(sw.solved[i].position, sw.followed[i].eq.tip) <= ON_BRANCH_MM)
            .count();
        let not_converged = sw
            .solved
            .iter()
            .filter(|f| f.status != Status::Converged)
            .count();
        let margin_error = judged
            .iter()
            .map(|&i| (sw.solved[i].softest_mode - sw.followed[i].eq.slope).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "s1 = {}: {} rows, snaps at rows {jumps:?}, {on} of {} on the branch, {not_converged} not converged, softest mode vs continuation {margin_error:.1e}",
            sw.s1,
            sw.solved.len(),
            judged.len()
        );
        assert!(on as f64 >= 0.98 * judged.len() as f64, "s1 = {}", sw.s1);
        assert_eq!(not_converged, 0, "s1 = {}", sw.s1);
        assert!(margin_error < 1e-3, "s1 = {}", sw.s1);
        let margins: Vec<f64> = sw.solved.iter().map(|f| f.stability_margin).collect();
        let lowest = margins.iter().copied().fold(f64::MAX, f64::min);
        if jumps.is_empty() {
            lowest_calm = lowest_calm.min(lowest);
            continue;
        }
        // hysteresis: it snaps once each way, at two different angles of the turn
        let n = (sw.solved.len() - 1) / 2;
        assert_eq!(jumps.len(), 2, "s1 = {}", sw.s1);
        assert!(jumps[0] <= n && jumps[1] > n);
        assert_ne!(jumps[0], 2 * n + 1 - jumps[1], "no hysteresis");
        for &j in &jumps {
            let fold = sw.followed[j].fold.expect("a jump ends a branch");
            let before = &margins[j - 3..j];
            highest_before_snap = highest_before_snap.max(before[2]);
            // falls in the last steps, to the sweep's lowest and below the warning margin
            assert!(before[0] > before[1] && before[1] > before[2], "{before:?}");
            let at = margins.iter().position(|&m| m == lowest).unwrap();
            eprintln!(
                "  lowest {lowest:.4} at row {at} (softest {:.3}), before {before:.4?}",
                sw.solved[at].softest_mode
            );
            // (the two snaps of a sweep mirror each other: their last rows' margins, from
            // forward differences, agree to the differences' truncation)
            assert!(before[2] <= lowest + 1e-4, "{} vs {lowest}", before[2]);
            assert!(before[2] <= DEFAULT_WARN_MARGIN, "{before:?}");
            // the margin is a distance to the fold, linear in the angle left: extrapolated
            // from the last two rows it reaches zero where the continuation's branch ends
            let (a, b) = (before[1], before[2]);
            let predicted = b / (a - b);
            eprintln!(
                "  snap at row {j}: margins {before:.3?}, fold predicted {predicted:.2} of a step after the last row, continuation {fold:.2}"
            );
            assert!((predicted - fold).abs() < 0.25, "{predicted} vs {fold}");
        }
    }
    eprintln!(
        "lowest margin of a sweep that does not snap {lowest_calm:.3}; margin one step before a snap up to {highest_before_snap:.3}"
    );
    // a margin that ranks danger: every snap is announced lower than any calm sweep goes
    assert!(highest_before_snap < lowest_calm);
}

#[test]
fn the_softest_mode_is_the_stiffness_of_the_softest_twist_mode_relative_to_uncoupled_tubes() {
    let params = params();
    let spec = sweeps::long_transmissions(EXTRA_TRANSMISSION_MM);
    let model = ModelSpec::from_spec(&spec).rows().unwrap();
    let mut worst: f64 = 0.0;
    for s1 in [20.0, 30.0, 45.0] {
        let two = TwoTubes::new(&params, [s1, s1 + INNER_AHEAD_MM]);
        for rel in [150.0, 200.0, 250.0, 300.0] {
            let theta = [0.0, f64::to_radians(rel)];
            let x = two
                .roots(theta)
                .into_iter()
                .filter(|&x| two.residual(theta, x).1 > 0.0)
                .min_by(|a, b| a.abs().total_cmp(&b.abs()))
                .unwrap();
            let want = two.stiffness_ratio(theta, x);
            let fk = model
                .solver()
                .fk(&[s1, 0.0, s1 + INNER_AHEAD_MM, rel])
                .unwrap();
            worst = worst.max((fk.softest_mode / want - 1.0).abs());
        }
    }
    eprintln!("softest mode / stiffness ratio of the softest twist mode: within {worst:.3}");
    assert!(worst < 0.1);
}

/// `ctr-cli fk`'s warnings without `--margin` probe only the rows whose softest mode
/// allows a margin below the warning (`Margins::Below`): they are the warnings the exact
/// margins give, row for row, for the default and a wider warning margin.
#[test]
fn the_warnings_without_the_margin_column_are_those_of_the_exact_margins() {
    use ctr_analysis::job::{run_fk, FkJob, Input, OnError, Output};
    let dir = tempfile::tempdir().unwrap();
    let robot = dir.path().join("robot.toml");
    std::fs::write(&robot, sweeps::long_transmissions(100.0).to_toml()).unwrap();
    let joints = dir.path().join("joints.csv");
    let mut text = String::from("s1_mm,theta1_deg,s2_mm,theta2_deg\n");
    for s1 in [40.0, 55.0] {
        for r in sweeps::full_turn([s1, s1 + 40.0], sweeps::relaxed_deg(&params()), 2.0) {
            text += &format!("{},{},{},{}\n", r[0], r[1], r[2], r[3]);
        }
    }
    std::fs::write(&joints, text).unwrap();
    for warn in [DEFAULT_WARN_MARGIN, 0.3] {
        let job = |margin| FkJob {
            robot: Input::Path(robot.clone()),
            joints: Input::Path(joints.clone()),
            output: Output::Path(dir.path().join("tips.csv")),
            model: None,
            on_error: OnError::Fail,
            threads: 2,
            margin,
            warn_margin: Some(warn),
        };
        let screened = run_fk(&job(false), &()).unwrap().low_margin;
        let exact = run_fk(&job(true), &()).unwrap().low_margin;
        eprintln!("warning margin {warn}: {} runs of rows below", exact.len());
        // one snap each way at each of the two feeds
        assert_eq!(exact.len(), 4, "{exact:?}");
        assert_eq!(screened, exact);
    }
}

/// Row for row, the margins `Margins::Below(x)` gives (the screen of `ctr-cli fk`'s
/// warnings: the fade's bound, then the margin from the softest mode's analytic
/// gradient, then the probes) against `Margins::Exact`: a row below `x` has its exact
/// margin bit for bit, a row at or above it a lower bound of it that is at least `x`;
/// where the analytic gradient cleared a row, its margin (the bound times
/// `SCREEN_FACTOR`) is within `ANALYTIC_AGREEMENT` of the exact one, far inside the
/// factor. On sweeps of the snapping pair (2 deg, and 0.05 deg towards two folds),
/// random nitinol3 rows and a nitinol3 trajectory, for the default and wider warnings.
#[test]
fn the_screened_margins_are_the_exact_ones_below_the_warning_and_lower_bounds_above() {
    use ctr_analysis::batch::{solve_rows, Rows};
    use ctr_analysis::margin::{Margin, Margins, SCREEN_FACTOR};
    /// The analytic margin against the exact one (relative, dimensionless): the
    /// probes' truncation and the twist equations' discretisation (module doc of
    /// `ctr_analysis::margin`, "Screening").
    const ANALYTIC_AGREEMENT: f64 = 1e-3;
    let snapping = ModelSpec::from_spec(&sweeps::long_transmissions(EXTRA_TRANSMISSION_MM))
        .rows()
        .unwrap();
    let mut pair: Vec<f64> = Vec::new();
    let relaxed = sweeps::relaxed_deg(&params());
    for s1 in [28.0, 40.0, 55.0] {
        let s = [s1, s1 + INNER_AHEAD_MM];
        pair.extend(sweeps::full_turn(s, relaxed, STEP_DEG).as_flattened());
    }
    // towards the folds of s1 = 40 and 55 mm (forward, about 180-200 deg past relaxed)
    for s1 in [40.0, 55.0] {
        for k in 0..=600 {
            let deg = relaxed + 170.0 + 0.05 * k as f64;
            pair.extend([s1, 0.0, s1 + INNER_AHEAD_MM, deg]);
        }
    }
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../data/robots/nitinol3.toml"
    );
    let spec = ctr_formats::RobotSpec::from_bytes(std::fs::read(path).unwrap(), path).unwrap();
    let nitinol3 = ModelSpec::from_spec(&spec).rows().unwrap();
    // random rows (feed increments 10-50 mm, all rotations) and a smooth trajectory
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut three: Vec<f64> = Vec::new();
    for _ in 0..3000 {
        let mut s = 0.0;
        for _ in 0..3 {
            s += 10.0 + 40.0 * uniform();
            three.extend([s, 360.0 * uniform() - 180.0]);
        }
    }
    for k in 0..6000 {
        let t = 2.0 * std::f64::consts::PI * k as f64 / 6000.0;
        let mut s = 0.0;
        for i in 0..3 {
            let f = 1.0 + i as f64;
            s += 30.0 + 16.0 * (f * t + 0.3 * f).sin();
            three.extend([s, 170.0 * (0.5 * f * t + f).sin()]);
        }
    }
    for (name, model, joints) in [("pair", &snapping, &pair), ("nitinol3", &nitinol3, &three)] {
        let rows = joints.len() / (2 * model.robot().n_tubes());
        let solve = |margins| {
            let mut out = Vec::with_capacity(rows);
            solve_rows(
                model,
                Rows::Commanded(joints),
                0..rows,
                WARM_CHUNK_ROWS,
                margins,
                None,
                |_, r| {
                    out.push(r.unwrap());
                    true
                },
            );
            out
        };
        let exact = solve(Margins::Exact);
        for warn in [DEFAULT_WARN_MARGIN, 0.1, 0.3] {
            let screened = solve(Margins::Below(warn));
            let (mut below, mut probed, mut analytic, mut worst) = (0, 0, 0, 0.0f64);
            for (row, (e, s)) in exact.iter().zip(&screened).enumerate() {
                assert_eq!(e.position, s.position, "{name} row {row}: the same solve");
                let (e, s) = (e.stability_margin, s.stability_margin);
                if e.is_nan() || e < warn {
                    assert_eq!(e.to_bits(), s.to_bits(), "{name} {warn} row {row}");
                    below += 1;
                    continue;
                }
                assert!(
                    s >= warn && s <= e + 1e-12,
                    "{name} {warn} row {row}: {s} vs {e}"
                );
                if Margin::at_least(exact[row].softest_mode).value >= warn {
                    // cleared by the softest mode alone
                } else if s.to_bits() == e.to_bits() {
                    probed += 1;
                } else {
                    analytic += 1;
                    worst = worst.max((s * SCREEN_FACTOR / e - 1.0).abs());
                }
            }
            eprintln!(
                "{name}, warning {warn}: {below} of {rows} rows below (exact), {analytic} cleared by the analytic gradient (within {worst:.1e} of the exact margin), {probed} above it probed"
            );
            assert!(worst < ANALYTIC_AGREEMENT, "{name} {warn}: {worst}");
            assert!(
                analytic > 100,
                "{name} {warn}: the screen cleared {analytic} rows"
            );
            // the pair snaps; nitinol3 comes within 0.3 (of 1) of a snap
            if name == "pair" || warn >= 0.3 {
                assert!(below > 0, "{name} {warn}: no row below the warning");
            }
        }
    }
}

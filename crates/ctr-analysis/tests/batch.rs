//! Batch forward kinematics: the same numbers as the core, whatever the thread count.

use ctr_analysis::batch::{batch_fk, BatchOptions, WARM_CHUNK_ROWS};
use ctr_analysis::job::{run_fk, FkJob, Input, OnError, Output};
use ctr_analysis::model::{ModelSpec, RowModel};
use ctr_core::{Model, Status};
use ctr_formats::parallel::Progress;
use ctr_formats::RobotSpec;
use ctr_formats::{AnyRobot, ErrorKind, FkResult};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

mod common;
use common::core_rows;

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../data")
        .join(rel)
}

fn spec(name: &str) -> RobotSpec {
    RobotSpec::from_path(&data(&format!("robots/{name}.toml"))).unwrap()
}

/// A deterministic walk through the valid joint space of an `n`-tube robot with
/// increments in `[lo, hi]` mm: smooth runs with jumps, as a recording would have.
fn joint_rows(n: usize, rows: usize, lo: f64, hi: f64) -> Vec<f64> {
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(rows * 2 * n);
    let mut inc: Vec<f64> = (0..n).map(|_| lo + (hi - lo) * uniform()).collect();
    let mut theta: Vec<f64> = (0..n).map(|_| 360.0 * uniform() - 180.0).collect();
    for r in 0..rows {
        if r % 17 == 0 {
            inc = (0..n).map(|_| lo + (hi - lo) * uniform()).collect();
            theta = (0..n).map(|_| 360.0 * uniform() - 180.0).collect();
        }
        let mut s = 0.0;
        for i in 0..n {
            inc[i] = (inc[i] + (uniform() - 0.5)).clamp(lo, hi);
            theta[i] = (theta[i] + 10.0 * (uniform() - 0.5)).clamp(-180.0, 180.0);
            s += inc[i];
            out.push(s);
            out.push(theta[i]);
        }
    }
    out
}

/// The row model of `robot` under `model`, without effects.
fn rows(robot: &AnyRobot, model: Model) -> RowModel {
    ModelSpec::plain(robot, model).rows().unwrap()
}

/// The results with the stability margin (not asked for: NaN, never equal to itself)
/// set to zero, so that whole results compare.
fn comparable(v: Vec<FkResult>) -> Vec<FkResult> {
    v.into_iter()
        .map(|f| {
            assert!(f.stability_margin.is_nan(), "a margin nobody asked for");
            FkResult {
                stability_margin: 0.0,
                ..f
            }
        })
        .collect()
}

fn batch(robot: &AnyRobot, joints: &[f64], model: Model, threads: usize) -> Vec<FkResult> {
    let options = BatchOptions {
        threads,
        chunk_rows: WARM_CHUNK_ROWS,
        margins: false,
    };
    batch_fk(&rows(robot, model), joints, None, &options, &())
        .unwrap()
        .into_iter()
        .map(Result::unwrap)
        .collect()
}

#[test]
fn batch_equals_core_row_by_row_bit_for_bit() {
    for model in [Model::Torsion, Model::Rigid] {
        let s = spec("liu2023");
        let joints = joint_rows(2, 150, 25.0, 45.0);
        let AnyRobot::Two(r) = s.robot else {
            panic!("liu2023 has two tubes")
        };
        let expect = core_rows(&r, &joints, model, WARM_CHUNK_ROWS);
        let got = batch(&s.robot, &joints, model, 2);
        assert_eq!(comparable(got.clone()), comparable(expect), "{model:?}");
        assert!(got.iter().all(|f| f.status == Status::Converged));

        let s = spec("nitinol3");
        let joints = joint_rows(3, 100, 10.0, 50.0);
        let AnyRobot::Three(r) = s.robot else {
            panic!("nitinol3 has three tubes")
        };
        assert_eq!(
            comparable(batch(&s.robot, &joints, model, 3)),
            comparable(core_rows(&r, &joints, model, WARM_CHUNK_ROWS)),
            "{model:?}"
        );
    }
}

#[test]
fn output_does_not_depend_on_thread_count() {
    let s = spec("nitinol2");
    let joints = joint_rows(2, 203, 10.0, 60.0);
    let one = batch(&s.robot, &joints, Model::Torsion, 1);
    for threads in [2, 3, 8, 64] {
        let many = batch(&s.robot, &joints, Model::Torsion, threads);
        // compare bits, not just values
        let bits = |v: &[FkResult]| -> Vec<u64> {
            v.iter()
                .flat_map(|f| f.position.iter().chain(f.quaternion.iter()))
                .map(|x| x.to_bits())
                .collect()
        };
        assert_eq!(bits(&many), bits(&one), "{threads} threads");
        assert_eq!(comparable(many), comparable(one.clone()));
    }
}

#[test]
fn chunk_of_one_row_is_cold_solves() {
    let s = spec("liu2023");
    let joints = joint_rows(2, 40, 25.0, 45.0);
    let options = BatchOptions {
        threads: 2,
        chunk_rows: 1,
        margins: false,
    };
    let got: Vec<FkResult> = batch_fk(
        &rows(&s.robot, Model::Torsion),
        &joints,
        None,
        &options,
        &(),
    )
    .unwrap()
    .into_iter()
    .map(Result::unwrap)
    .collect();
    let cold: Vec<FkResult> = joints
        .chunks(4)
        .map(|q| ModelSpec::plain(&s.robot, Model::Torsion).fk(q).unwrap())
        .collect();
    assert_eq!(comparable(got), comparable(cold.clone()));
    // warm and cold agree to well below a micrometre
    let warm = batch(&s.robot, &joints, Model::Torsion, 1);
    for (w, c) in warm.iter().zip(&cold) {
        for k in 0..3 {
            assert!((w.position[k] - c.position[k]).abs() < 1e-6);
        }
    }
}

#[test]
fn invalid_rows_are_errors_in_place() {
    let s = spec("liu2023");
    let joints = [
        30.0, 0.0, 80.0, 0.0, 40.0, 0.0, 30.0, 0.0, 30.0, 0.0, 90.0, 0.0,
    ];
    let out = batch_fk(
        &rows(&s.robot, Model::Torsion),
        &joints,
        None,
        &BatchOptions::default(),
        &(),
    )
    .unwrap();
    assert!(out[0].is_ok() && out[2].is_ok());
    assert_eq!(
        out[1].unwrap_err().to_string(),
        "s2_mm = 30 must be >= s1_mm = 40 (inner tubes reach at least as far as outer ones)"
    );
}

#[derive(Default)]
struct Count {
    started: AtomicUsize,
    advanced: AtomicUsize,
    finished: AtomicUsize,
}

impl Progress for Count {
    fn start(&self, rows: usize) {
        self.started.store(rows, Ordering::SeqCst);
    }
    fn advance(&self, rows: usize) {
        self.advanced.fetch_add(rows, Ordering::SeqCst);
    }
    fn finish(&self) {
        self.finished.fetch_add(1, Ordering::SeqCst);
    }
}

#[test]
fn progress_sees_every_row() {
    let s = spec("liu2023");
    let joints = joint_rows(2, 77, 25.0, 45.0);
    let count = Count::default();
    let options = BatchOptions {
        threads: 2,
        ..Default::default()
    };
    let model = rows(&s.robot, Model::Torsion);
    batch_fk(&model, &joints, None, &options, &count).unwrap();
    assert_eq!(count.started.load(Ordering::SeqCst), 77);
    assert_eq!(count.advanced.load(Ordering::SeqCst), 77);
    assert_eq!(count.finished.load(Ordering::SeqCst), 1);
    // and an empty batch is fine
    assert!(batch_fk(&model, &[], None, &options, &())
        .unwrap()
        .is_empty());
}

/// A robot that snaps (long transmissions) and rows where the torsion solve fails.
fn snap_case(dir: &Path) -> (PathBuf, PathBuf) {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/cli/snap");
    let robot = dir.join("robot.toml");
    let joints = dir.join("joints.csv");
    std::fs::copy(fixtures.join("robot.toml"), &robot).unwrap();
    std::fs::copy(fixtures.join("joints.csv"), &joints).unwrap();
    (robot, joints)
}

#[test]
fn job_policies_for_rows_that_do_not_converge() {
    let dir = tempfile::tempdir().unwrap();
    let (robot, joints) = snap_case(dir.path());
    let out = dir.path().join("tips.csv");
    std::fs::write(&out, "previous\n").unwrap();
    let mut job = FkJob {
        robot: Input::Path(robot),
        joints: Input::Path(joints.clone()),
        output: Output::Path(out.clone()),
        model: None,
        on_error: OnError::Fail,
        threads: 2,
        margin: false,
        warn_margin: None,
    };
    let e = run_fk(&job, &()).unwrap_err();
    assert!(e.is_solver_failure());
    assert!(
        matches!(
            e.kind(),
            ErrorKind::SolverFailed {
                failed: 1,
                rows: 6,
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(e.location().line, Some(5), "{e}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous\n");

    job.on_error = OnError::Skip;
    let summary = run_fk(&job, &()).unwrap();
    assert_eq!((summary.rows, summary.written), (6, 5));
    assert_eq!(summary.failures.len(), 1);
    assert_eq!(summary.failures[0].line, 5);
    assert_eq!(summary.failures[0].status, Status::IterationLimit);
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().count(), 6);

    job.on_error = OnError::Mark;
    run_fk(&job, &()).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().count(), 7);
    assert!(text
        .lines()
        .next()
        .unwrap()
        .ends_with(",status,residual_per_mm"));
    assert!(text.lines().nth(4).unwrap().contains(",iteration_limit,"));

    // the rigid model has nothing to converge
    job.on_error = OnError::Fail;
    job.model = Some(Model::Rigid);
    assert_eq!(run_fk(&job, &()).unwrap().failures, []);
}

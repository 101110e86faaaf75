//! Forward kinematics over many rows, in parallel, with results independent of the
//! thread count; and the chunked parallel runner that the file jobs (`ctr-cli fk`,
//! `ctr-cli ik`) are built on.
//!
//! The rows are cut into chunks of [`BatchOptions::chunk_rows`] consecutive rows
//! (boundaries at multiples of `chunk_rows`, whatever the thread count). Each chunk is
//! solved by one worker with a fresh core [`Solver`](ctr_core::Solver) that warm-starts
//! every row from the previous rows of the same chunk, exactly as calling
//! `Solver::solve` row by row over that chunk would. Workers take chunks from a shared
//! counter; the results are handed back in input order ([`for_each_chunk`](ctr_formats::parallel::for_each_chunk)), so the
//! output is bit for bit the same for 1 or 64 threads. Warm start changes a converged
//! result only below the Newton tolerance (`SolverConfig::step_tolerance_per_mm`), but
//! the fixed chunking makes even those last bits reproducible.

use crate::ik::{Ik, IkResult};
use crate::model::{FkModel, ModelError};
use crate::robot::Kinematics;
use ctr_core::{JointError, Model, SolveError};
use ctr_formats::parallel::{for_each_chunk, Progress};
use ctr_formats::{AnyRobot, FkResult, IkTarget};
use std::ops::Range;

/// Default rows per warm-started chunk.
pub const WARM_CHUNK_ROWS: usize = 32;

/// How to run a batch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BatchOptions {
    /// The mechanics.
    pub model: Model,
    /// Worker threads; 0 = all available cores.
    pub threads: usize,
    /// Rows per warm-started chunk (at least 1; 1 means every row is solved cold).
    /// The results depend on this, never on `threads`.
    pub chunk_rows: usize,
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            model: Model::Torsion,
            threads: 0,
            chunk_rows: WARM_CHUNK_ROWS,
        }
    }
}

/// Solves every row of `joints` (row after row, `2 * robot.n_tubes()` values each in
/// file order `s1_mm, theta1_deg, ...`) and returns one result per row, in order.
///
/// # Panics
/// If `joints.len()` is not a multiple of `2 * robot.n_tubes()`.
///
/// ```
/// use ctr_analysis::batch::{batch_fk, BatchOptions};
/// use ctr_formats::AnyRobot;
/// let t = ctr_core::TubeParams { curvature_radius_mm: Some(100.0), ..ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
/// let robot = AnyRobot::new(&[t]).unwrap();
/// let rows = [10.0, 0.0, 20.0, 0.0, 30.0, 90.0];
/// let one = batch_fk(&robot, &rows, &BatchOptions { threads: 1, ..Default::default() }, &());
/// let two = batch_fk(&robot, &rows, &BatchOptions { threads: 2, ..Default::default() }, &());
/// assert_eq!(one, two);
/// ```
pub fn batch_fk(
    robot: &AnyRobot,
    joints: &[f64],
    options: &BatchOptions,
    progress: &dyn Progress,
) -> Vec<Result<FkResult, JointError>> {
    let width = 2 * robot.n_tubes();
    assert!(
        joints.len().is_multiple_of(width),
        "{} joint values do not make rows of {width}",
        joints.len()
    );
    let rows = joints.len() / width;
    let mut out = Vec::with_capacity(rows);
    for_each_chunk(
        rows,
        options.chunk_rows,
        options.threads,
        progress,
        || (),
        |(), range| {
            let mut solver = robot.solver();
            range
                .map(|row| solver.fk(&joints[row * width..(row + 1) * width], options.model))
                .collect::<Vec<_>>()
        },
        |_, results| {
            out.extend(results);
            true
        },
    );
    out
}

/// As [`batch_fk`], for a robot file's whole model (its effects included; see
/// [`crate::model`]): `options.model` is not used (the model has its own). With time
/// effects ([`FkModel::needs_time`]) the rows are one run in order: `t_s` gives their
/// times (non-decreasing; the caller checks), without them the row index stands for
/// time (latency is then refused). The actual joints of the run are found first, then
/// the rows are solved in the same fixed chunks as [`batch_fk`]. The error of a row is
/// `SolveError::Joint` when its (actual) joints are out of the robot's ranges.
///
/// # Panics
/// If `joints.len()` is not a multiple of `2 * n_tubes`, or `t_s` does not have one
/// time per row.
///
/// ```
/// use ctr_analysis::{batch::{batch_fk, batch_fk_model, BatchOptions}, model::FkModel};
/// use ctr_formats::AnyRobot;
/// use ctr_formats::Effects;
/// let t = ctr_core::TubeParams { curvature_radius_mm: Some(100.0), ..ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
/// let robot = AnyRobot::new(&[t]).unwrap();
/// let rows = [10.0, 0.0, 20.0, 0.0, 30.0, 90.0];
/// let model = FkModel::new(&robot, ctr_core::Model::Torsion, &Effects::default()).unwrap();
/// let with = batch_fk_model(&model, &rows, None, &BatchOptions::default(), &()).unwrap();
/// let plain = batch_fk(&robot, &rows, &BatchOptions::default(), &());
/// assert_eq!(with[2].unwrap(), plain[2].unwrap());
/// ```
pub fn batch_fk_model(
    model: &FkModel,
    joints: &[f64],
    t_s: Option<&[f64]>,
    options: &BatchOptions,
    progress: &dyn Progress,
) -> Result<Vec<Result<FkResult, SolveError>>, ModelError> {
    let width = 2 * model.robot().n_tubes();
    assert!(
        joints.len().is_multiple_of(width),
        "{} joint values do not make rows of {width}",
        joints.len()
    );
    let rows = joints.len() / width;
    if let Some(t) = t_s {
        assert_eq!(t.len(), rows, "one time per row");
    }
    let actual = if model.needs_time() {
        Some(model.actual_joints(joints, t_s, std::slice::from_ref(&(0..rows)))?)
    } else {
        None
    };
    let mut out = Vec::with_capacity(rows);
    for_each_chunk(
        rows,
        options.chunk_rows,
        options.threads,
        progress,
        || (),
        |(), range| {
            let mut solver = model.solver();
            range
                .map(|row| {
                    let r = row * width..(row + 1) * width;
                    match &actual {
                        Some(a) => solver.fk_actual(&a[r]),
                        None => solver.fk(&joints[r]),
                    }
                })
                .collect::<Vec<_>>()
        },
        |_, results| {
            out.extend(results);
            true
        },
    );
    Ok(out)
}

/// Rows per chunk of [`batch_ik`].
pub const IK_CHUNK_ROWS: usize = 32;

/// How to run a batch of inverse-kinematics targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IkBatchOptions {
    /// Worker threads; 0 = all available cores. The results do not depend on it.
    pub threads: usize,
    /// Rows per chunk (at least 1). The results depend on this, never on `threads`.
    pub chunk_rows: usize,
    /// Warm start along the rows (a trajectory); `false`: every target is solved cold
    /// from the start table, independently (scattered targets).
    pub warm: bool,
}

impl Default for IkBatchOptions {
    fn default() -> Self {
        IkBatchOptions {
            threads: 0,
            chunk_rows: IK_CHUNK_ROWS,
            warm: true,
        }
    }
}

/// Solves every target with `ik` (cloned for each worker) and hands the results to
/// `consume` chunk by chunk, in order, on the calling thread (as [`for_each_chunk`](ctr_formats::parallel::for_each_chunk);
/// `consume` returning `false` stops the batch).
///
/// Warm (`options.warm`), the rows are a trajectory: each row starts from the
/// previous row's result. To run in parallel with results independent of the thread
/// count, the rows are cut into chunks of `chunk_rows` (boundaries at multiples of it)
/// and solved in two passes:
///
/// 1. in order, on the calling thread: the first row of every chunk, each started from
///    the first row of the chunk before (the very first row cold); these rows are a
///    coarse trajectory, `chunk_rows` rows a step, so they stay on one branch of
///    solutions when the trajectory is smooth;
/// 2. in parallel: the other rows of each chunk, each from the row before it.
///
/// Every row thus starts from a joint vector fixed by the rows before it and the chunk
/// size alone, and an [`Ik`] solve depends only on its arguments: the same results, bit
/// for bit, on any number of threads. Across a chunk boundary the joints come from two
/// different warm-start paths (both from the previous chunk's first row); they agree
/// to the solver's tolerance in tip position, not necessarily in joints when the robot
/// is redundant for the target (e.g. 6 joints for a position).
///
/// Cold, every row is solved from the start table on its own (pass 2 only).
///
/// ```
/// use ctr_analysis::batch::{batch_ik, IkBatchOptions};
/// use ctr_formats::RobotSpec;
/// use ctr_analysis::ik::{Ik, IkOptions};
/// use ctr_formats::IkTarget;
/// let spec = RobotSpec::from_toml_str(r#"
/// [[tube]]
/// outer_diameter_mm = 1.2
/// inner_diameter_mm = 0.9
/// length_mm = 260.0
/// curved_length_mm = 90.0
/// curvature_radius_mm = 100.0
/// youngs_modulus_mpa = 58000.0
/// poisson_ratio = 0.33
/// "#, "robot.toml")?;
/// let ik = Ik::from_spec(&spec, IkOptions::default())?;
/// let targets: Vec<IkTarget> = (0..40)
///     .map(|k| IkTarget::position(ik.fk(&[40.0 + k as f64, 0.1]).unwrap().position.into()))
///     .collect();
/// let solve = |threads| {
///     let mut all = Vec::new();
///     let options = IkBatchOptions { threads, ..Default::default() };
///     batch_ik(&ik, &targets, &options, &(), |_, r| { all.extend(r); true });
///     all
/// };
/// assert_eq!(solve(1), solve(3));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn batch_ik(
    ik: &Ik,
    targets: &[IkTarget],
    options: &IkBatchOptions,
    progress: &dyn Progress,
    consume: impl FnMut(Range<usize>, Vec<IkResult>) -> bool,
) {
    let rows = targets.len();
    let chunk = options.chunk_rows.max(1);
    let chunks = rows.div_ceil(chunk);
    progress.start(rows);
    // pass 1: the first row of every chunk, in order
    let mut firsts: Vec<Option<IkResult>> = Vec::new();
    if options.warm {
        let mut solver = ik.clone();
        let mut prev: Option<Vec<f64>> = None;
        for k in 0..chunks {
            let r = solver.solve(&targets[k * chunk], prev.as_deref());
            prev = Some(r.q.clone());
            firsts.push(Some(r));
            progress.advance(1);
        }
    }
    let firsts: Vec<std::sync::Mutex<Option<IkResult>>> =
        firsts.into_iter().map(std::sync::Mutex::new).collect();
    // pass 2: the chunks, in parallel
    for_each_chunk(
        rows,
        chunk,
        options.threads,
        &(),
        || ik.clone(),
        |solver, range| {
            let mut out = Vec::with_capacity(range.len());
            let mut done = 0;
            for row in range {
                let r = if !options.warm {
                    solver.solve(&targets[row], None)
                } else if row % chunk == 0 {
                    let first = firsts[row / chunk].lock().map(|mut f| f.take());
                    match first {
                        Ok(Some(r)) => r,
                        // unreachable: each chunk is taken once
                        _ => solver.solve(&targets[row], None),
                    }
                } else {
                    let prev: &IkResult = out.last().expect("the chunk's first row is solved");
                    solver.solve(&targets[row], Some(&prev.q))
                };
                if !(options.warm && row % chunk == 0) {
                    done += 1;
                }
                out.push(r);
            }
            progress.advance(done);
            out
        },
        consume,
    );
    progress.finish();
}

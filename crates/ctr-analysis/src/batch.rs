//! Forward and inverse kinematics over many rows, in parallel on the one thread pool
//! ([`ctr_formats::parallel`]), with results independent of the thread count.
//!
//! The rows are cut into chunks of [`BatchOptions::chunk_rows`] consecutive rows
//! (boundaries at multiples of `chunk_rows`, whatever the thread count). Each chunk is
//! solved by one worker with a fresh row solver that warm-starts every row from the
//! previous rows of the same chunk ([`solve_rows`]). Workers take chunks from a shared
//! counter; the results are handed back in input order, so the output is bit for bit
//! the same for 1 or 64 threads. Warm start changes a converged result only below the
//! Newton tolerance (`SolverConfig::step_tolerance_per_mm`), but the fixed chunking
//! makes even those last bits reproducible.

use crate::ik::{Ik, IkResult};
use crate::learned::along_commands;
use crate::margin::Margins;
use crate::model::{ModelError, RowModel, RowSolver};
use ctr_core::SolveError;
use ctr_formats::parallel::{for_each_chunk, Progress};
use ctr_formats::{FkResult, IkTarget};
use std::ops::Range;

/// Default rows per warm-started chunk.
pub const WARM_CHUNK_ROWS: usize = 32;

/// How to run a batch of forward kinematics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BatchOptions {
    /// Worker threads; 0 = all available cores.
    pub threads: usize,
    /// Rows per warm-started chunk (at least 1; 1 means every row is solved cold).
    /// The results depend on this, never on `threads`.
    pub chunk_rows: usize,
    /// Compute every row's stability margin ([`crate::margin`]; else
    /// [`FkResult::stability_margin`] is NaN).
    pub margins: bool,
}

impl BatchOptions {
    /// The margins [`Self::margins`] asks for.
    fn margins(&self) -> Margins {
        if self.margins {
            Margins::Exact
        } else {
            Margins::Off
        }
    }
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            threads: 0,
            chunk_rows: WARM_CHUNK_ROWS,
            margins: false,
        }
    }
}

/// The joints of a batch, row after row (`2 n` values a row, file order and units).
#[derive(Clone, Copy, Debug)]
pub enum Rows<'a> {
    /// Commanded joints: the row model adds the joint offsets.
    Commanded(&'a [f64]),
    /// Actual joints ([`RowModel::actual_joints`]: offsets and time effects applied),
    /// with the commanded ones and the rows' times (s) they came from (for the
    /// `[model.empirical]` correction; `None`: no times).
    Actual {
        /// The actual joints.
        actual: &'a [f64],
        /// The commanded joints.
        commanded: &'a [f64],
        /// Each row's time, s.
        t_s: Option<&'a [f64]>,
    },
}

/// Two solutions of one row farther apart than this at the tip, mm, are on two branches
/// of equilibria (the same root found twice differs by the Newton tolerance, ~1e-9 mm).
pub const BRANCH_TOLERANCE_MM: f64 = 1e-6;

/// Solves one row with `solver`, warm-started from its memory.
fn solve_row(
    solver: &mut RowSolver<'_>,
    rows: Rows<'_>,
    row: usize,
    width: usize,
) -> Result<FkResult, SolveError> {
    let r = row * width..(row + 1) * width;
    match rows {
        Rows::Commanded(j) => solver.fk(&j[r]),
        Rows::Actual {
            actual,
            commanded,
            t_s,
        } => solver.fk_timed(
            &commanded[r.clone()],
            &actual[r],
            t_s.map_or(f64::NAN, |t| t[row]),
            [0.0; 3],
        ),
    }
}

/// True when two solutions of one row lie on one branch (or either failed).
fn same_branch(a: &Result<FkResult, SolveError>, b: &Result<FkResult, SolveError>) -> bool {
    match (a, b) {
        (Ok(a), Ok(b)) => {
            let d2: f64 = (0..3)
                .map(|k| (a.position[k] - b.position[k]).powi(2))
                .sum();
            d2.sqrt() <= BRANCH_TOLERANCE_MM
        }
        _ => true,
    }
}

/// Solves the rows `range` of `rows` in order, each warm-started from the rows before
/// it in its chunk of `chunk_rows` consecutive rows (boundaries at multiples of
/// `chunk_rows`; at least 1), handing each result to `each` (which returns `false` to
/// stop), and returns the solver as the last row left it. Every forward-kinematics
/// batch solves its rows this way (the CLI's file job, `ctr_py`, [`batch_fk`]), so the
/// results depend on the chunk size and never on how the rows are shared out between
/// threads.
///
/// A chunk starts from a fresh solver, unless the robot would be on another branch of
/// equilibria there (a snapping robot between its folds): the first row is also solved
/// warm from the chunk before (`after`, the solver the previous range ended with, for
/// the range's first chunk), and where the two differ by more than
/// [`BRANCH_TOLERANCE_MM`] the warm one is kept, with its memory, so that a trajectory
/// follows one branch as the robot does. (With `chunk_rows` 1 every row is cold.) The
/// caller that handed a range out without `after` checks it with [`branch_changed`].
/// With `margins` every row's stability margin is computed
/// ([`RowSolver::with_margins`]).
///
/// # Panics
/// If a row is not `2 n` values or `range` is beyond the rows.
pub fn solve_rows<'m>(
    model: &'m RowModel,
    rows: Rows<'_>,
    range: Range<usize>,
    chunk_rows: usize,
    margins: Margins,
    after: Option<&RowSolver<'m>>,
    mut each: impl FnMut(usize, Result<FkResult, SolveError>) -> bool,
) -> RowSolver<'m> {
    let width = 2 * model.robot().n_tubes();
    let chunk = chunk_rows.max(1);
    let fresh = || model.solver().margins(margins);
    let mut solver = fresh();
    for row in range.clone() {
        let tip = if row % chunk == 0 || row == range.start {
            let before = if row == range.start {
                after.cloned()
            } else {
                Some(solver.clone())
            };
            solver = fresh();
            let cold = solve_row(&mut solver, rows, row, width);
            match before.filter(|_| chunk > 1) {
                Some(mut warm) => {
                    let tip = solve_row(&mut warm, rows, row, width);
                    if same_branch(&cold, &tip) {
                        cold
                    } else {
                        solver = warm;
                        tip
                    }
                }
                None => cold,
            }
        } else {
            solve_row(&mut solver, rows, row, width)
        };
        if !each(row, tip) {
            break;
        }
    }
    solver
}

/// For the caller of [`solve_rows`] without `after`: true when the range's first row,
/// solved from `after` (the solver the range before ended with), lies on another branch
/// than `first` (its result from a fresh start): the range must be solved again with
/// `after`.
pub fn branch_changed(
    model: &RowModel,
    rows: Rows<'_>,
    row: usize,
    chunk_rows: usize,
    after: &RowSolver<'_>,
    first: &Result<FkResult, SolveError>,
) -> bool {
    // (a first row that failed to solve is no branch to compare)
    if chunk_rows <= 1 {
        return false;
    }
    let width = 2 * model.robot().n_tubes();
    let warm = solve_row(&mut after.clone(), rows, row, width);
    !same_branch(&warm, first)
}

/// Solves every row of `joints` (row after row, `2 n` values each in file order
/// `s1_mm, theta1_deg, ...`) with the row model (its effects included; see
/// [`crate::model`]) in parallel, and returns one result per row, in order. With time
/// effects ([`RowModel::needs_time`]) the rows are one run in order: `t_s` gives their
/// times (non-decreasing; the caller checks), without them the row index stands for
/// time (latency is then refused). The error of a row is `SolveError::Joint` when its
/// (actual) joints are out of the robot's ranges.
///
/// # Panics
/// If `joints.len()` is not a multiple of `2 n`, or `t_s` does not have one time per
/// row.
///
/// ```
/// use ctr_analysis::batch::{batch_fk, BatchOptions};
/// use ctr_analysis::model::ModelSpec;
/// use ctr_formats::AnyRobot;
/// let t = ctr_core::TubeParams { curvature_radius_mm: Some(100.0), ..ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
/// let model = ModelSpec::plain(&AnyRobot::new(&[t]).unwrap(), ctr_core::Model::Torsion).rows().unwrap();
/// let rows = [10.0, 0.0, 20.0, 0.0, 30.0, 90.0];
/// // with margins: without, each row's `stability_margin` is NaN (and NaN != NaN)
/// let options = |threads| BatchOptions { threads, margins: true, ..Default::default() };
/// let one = batch_fk(&model, &rows, None, &options(1), &()).unwrap();
/// let two = batch_fk(&model, &rows, None, &options(2), &()).unwrap();
/// assert_eq!(one, two);
/// ```
pub fn batch_fk(
    model: &RowModel,
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
    let n_rows = joints.len() / width;
    if let Some(t) = t_s {
        assert_eq!(t.len(), n_rows, "one time per row");
    }
    let actual = if model.needs_time() {
        Some(model.actual_joints(joints, t_s, std::slice::from_ref(&(0..n_rows)))?)
    } else {
        None
    };
    let rows = match &actual {
        Some(a) => Rows::Actual {
            actual: a,
            commanded: joints,
            t_s,
        },
        None => Rows::Commanded(joints),
    };
    let mut out = Vec::with_capacity(n_rows);
    let mut last: Option<RowSolver<'_>> = None;
    for_each_chunk(
        n_rows,
        options.chunk_rows,
        options.threads,
        progress,
        || (),
        |(), range| {
            let mut results = Vec::with_capacity(range.len());
            let end = solve_rows(
                model,
                rows,
                range,
                options.chunk_rows,
                options.margins(),
                None,
                |_, r| {
                    results.push(r);
                    true
                },
            );
            (results, end)
        },
        |range, (mut results, mut end)| {
            if let Some(after) = &last {
                if branch_changed(
                    model,
                    rows,
                    range.start,
                    options.chunk_rows,
                    after,
                    &results[0],
                ) {
                    results.clear();
                    end = solve_rows(
                        model,
                        rows,
                        range,
                        options.chunk_rows,
                        options.margins(),
                        Some(after),
                        |_, r| {
                            results.push(r);
                            true
                        },
                    );
                }
            }
            last = Some(end);
            out.extend(results);
            true
        },
    );
    // the learned discrepancy along the rows, one run in their order
    if let Some(d) = along_commands(model.spec(), joints, t_s) {
        for (r, (correction, _)) in out.iter_mut().zip(d) {
            if let Ok(fk) = r {
                for a in 0..3 {
                    fk.position[a] += correction[a];
                }
            }
        }
    }
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
/// `consume` chunk by chunk, in order, on the calling thread (as
/// [`for_each_chunk`]; `consume` returning `false` stops the batch).
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

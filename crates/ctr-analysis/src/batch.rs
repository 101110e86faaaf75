//! Forward kinematics over many rows, in parallel, with results independent of the
//! thread count.
//!
//! The rows are cut into chunks of [`BatchOptions::chunk_rows`] consecutive rows
//! (boundaries at multiples of `chunk_rows`, whatever the thread count). Each chunk is
//! solved by one worker with a fresh core [`Solver`](ctr_core::Solver) that warm-starts
//! every row from the previous rows of the same chunk, exactly as calling
//! `Solver::solve` row by row over that chunk would. Workers take chunks from a shared
//! queue and write into the chunk's own slots, so the output is in input order and bit
//! for bit the same for 1 or 64 threads. Warm start changes a converged result only below
//! the Newton tolerance (`SolverConfig::step_tolerance_per_mm`), but the fixed chunking
//! makes even those last bits reproducible.

use crate::robot::{AnyRobot, FkResult};
use ctr_core::{JointError, Model};
use std::sync::Mutex;

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

/// Receives progress from a batch; called from worker threads.
pub trait Progress: Sync {
    /// The batch starts with `rows` rows.
    fn start(&self, rows: usize) {
        let _ = rows;
    }
    /// `rows` more rows are done.
    fn advance(&self, rows: usize) {
        let _ = rows;
    }
    /// The batch is done.
    fn finish(&self) {}
}

/// No progress reporting.
impl Progress for () {}

/// The number of worker threads `threads` stands for (0 = all available cores).
pub fn resolve_threads(threads: usize) -> usize {
    if threads > 0 {
        threads
    } else {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    }
}

/// Solves every row of `joints` (row after row, `2 * robot.n_tubes()` values each in
/// file order `s1_mm, theta1_deg, ...`) and returns one result per row, in order.
///
/// # Panics
/// If `joints.len()` is not a multiple of `2 * robot.n_tubes()`.
///
/// ```
/// use ctr_analysis::{batch::{batch_fk, BatchOptions}, AnyRobot};
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
    let chunk = options.chunk_rows.max(1);
    let mut out: Vec<Option<Result<FkResult, JointError>>> = vec![None; rows];
    progress.start(rows);
    let solve_chunk = |input: &[f64], slots: &mut [Option<Result<FkResult, JointError>>]| {
        let mut solver = robot.solver();
        for (q, slot) in input.chunks_exact(width).zip(slots.iter_mut()) {
            *slot = Some(solver.fk(q, options.model));
        }
        progress.advance(slots.len());
    };
    let chunks = rows.div_ceil(chunk);
    let threads = resolve_threads(options.threads).min(chunks).max(1);
    let queue = Mutex::new(joints.chunks(chunk * width).zip(out.chunks_mut(chunk)));
    let work = || loop {
        let next = queue.lock().map(|mut q| q.next());
        match next {
            Ok(Some((input, slots))) => solve_chunk(input, slots),
            // a poisoned queue means another worker panicked; the scope re-raises it
            Ok(None) | Err(_) => break,
        }
    };
    if threads == 1 {
        work();
    } else {
        std::thread::scope(|s| {
            for _ in 1..threads {
                s.spawn(work);
            }
            work();
        });
    }
    progress.finish();
    out.into_iter()
        .map(|r| r.expect("every chunk is solved"))
        .collect()
}

//! The project's one thread pool: work cut into chunks of consecutive rows (or items),
//! run on a number of scoped worker threads, results handed back in order.
//!
//! Every parallel path goes through it: the readers' number parsing, batch forward and
//! inverse kinematics, the diagnosis's candidate fits and Jacobian columns, the Python
//! wheel's maps. Results never depend on the thread count: chunk boundaries are fixed by
//! the chunk size alone, and each chunk's work must depend only on the chunk.
//!
//! ```
//! use ctr_formats::parallel::map;
//! let squares = map(&[1, 2, 3, 4], 2, |x| x * x);
//! assert_eq!(squares, vec![1, 4, 9, 16]);
//! ```

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

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
///
/// ```
/// assert_eq!(ctr_formats::parallel::resolve_threads(3), 3);
/// assert!(ctr_formats::parallel::resolve_threads(0) >= 1);
/// ```
pub fn resolve_threads(threads: usize) -> usize {
    if threads > 0 {
        threads
    } else {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    }
}

/// `f` of every item, in item order, on `threads` workers (0 = all cores), one item per
/// chunk. A panic in `f` is raised again here.
pub fn map<J: Sync, R: Send>(items: &[J], threads: usize, f: impl Fn(&J) -> R + Sync) -> Vec<R> {
    map_rows(items.len(), 1, threads, || (), |(), i| f(&items[i]))
}

/// `f(state, i)` for every row `i` in `0..rows`, in order, on `threads` workers (0 = all
/// cores) taking `block` rows at a time, each worker with its own `state` from `init`
/// (scratch space, a solver to clone once). The results do not depend on the thread
/// count as long as `f`'s result depends only on `i`.
///
/// ```
/// use ctr_formats::parallel::map_rows;
/// let one = map_rows(103, 4, 1, || 0u32, |calls, i| { *calls += 1; i * i });
/// assert_eq!(one, map_rows(103, 4, 3, || 0u32, |_, i| i * i));
/// assert_eq!(one[10], 100);
/// ```
pub fn map_rows<S, R: Send>(
    rows: usize,
    block: usize,
    threads: usize,
    init: impl Fn() -> S + Sync,
    f: impl Fn(&mut S, usize) -> R + Sync,
) -> Vec<R> {
    let mut out = Vec::with_capacity(rows);
    for_each_chunk(
        rows,
        block,
        threads,
        &(),
        init,
        |state, range| range.map(|i| f(state, i)).collect::<Vec<R>>(),
        |_, results| {
            out.extend(results);
            true
        },
    );
    out
}

/// Runs `work` over the rows `0..rows` in chunks of `chunk_rows` consecutive rows
/// (boundaries at multiples of `chunk_rows`; at least 1) on `threads` workers (0 = all
/// cores), and hands every chunk's result to `consume` on the calling thread, in chunk
/// order, as soon as it and all chunks before it are done.
///
/// Each worker builds its own state with `init` and passes it to `work` for every
/// chunk it takes; for results independent of the thread count, `work`'s result must
/// depend only on the chunk (not on the state's history). When `consume` returns
/// `false`, no further chunks are started and none are consumed. `progress` hears of
/// every chunk done.
pub fn for_each_chunk<S, T, I, W, C>(
    rows: usize,
    chunk_rows: usize,
    threads: usize,
    progress: &dyn Progress,
    init: I,
    work: W,
    mut consume: C,
) where
    T: Send,
    I: Fn() -> S + Sync,
    W: Fn(&mut S, Range<usize>) -> T + Sync,
    C: FnMut(Range<usize>, T) -> bool,
{
    let chunk = chunk_rows.max(1);
    let chunks = rows.div_ceil(chunk);
    let range = |k: usize| k * chunk..((k + 1) * chunk).min(rows);
    let threads = resolve_threads(threads).min(chunks).max(1);
    progress.start(rows);
    if threads == 1 {
        let mut state = init();
        for k in 0..chunks {
            let r = range(k);
            let t = work(&mut state, r.clone());
            progress.advance(r.len());
            if !consume(r, t) {
                break;
            }
        }
        progress.finish();
        return;
    }
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    std::thread::scope(|s| {
        let (tx, rx) = mpsc::channel::<(usize, T)>();
        for _ in 0..threads {
            let tx = tx.clone();
            let (next, stop, init, work) = (&next, &stop, &init, &work);
            s.spawn(move || {
                let mut state = init();
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    if k >= chunks || stop.load(Ordering::Relaxed) {
                        break;
                    }
                    let r = range(k);
                    let len = r.len();
                    let t = work(&mut state, r);
                    progress.advance(len);
                    if tx.send((k, t)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(tx);
        let mut pending = BTreeMap::new();
        let mut want = 0;
        // a worker that panics drops its sender: `recv` fails once all are gone and
        // the scope re-raises the panic
        while want < chunks {
            let t = match pending.remove(&want) {
                Some(t) => t,
                None => match rx.recv() {
                    Ok((k, t)) => {
                        pending.insert(k, t);
                        continue;
                    }
                    Err(_) => break,
                },
            };
            if !consume(range(want), t) {
                stop.store(true, Ordering::Relaxed);
                break;
            }
            want += 1;
        }
        // unblock the workers and let them finish
        drop(rx);
    });
    progress.finish();
}

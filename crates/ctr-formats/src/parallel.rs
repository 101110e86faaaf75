//! The project's one thread pool: work cut into chunks of consecutive rows (or items),
//! run on a number of scoped worker threads, results handed back in order.
//!
//! [`stream`] is the same for items that arrive one after the other (pieces of a file
//! being read): a producer thread, the workers, and the calling thread consuming the
//! results in order, with a bounded number of items in between (bounded memory).
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
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{mpsc, Mutex};
use std::time::Duration;

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
    /// Where to add the time of a streamed job's stages, if it is to be timed.
    fn stages(&self) -> Option<&Stages> {
        None
    }
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

/// Runs `work` over the items `source` gives, in order, on `threads` workers (0 = all
/// cores), and hands every result to `consume` on the calling thread in the items'
/// order. At most `in_flight` items (at least 1) are between `source` and `consume` at
/// any time: memory stays bounded however many items there are.
///
/// With more than one thread, `source` runs on a thread of its own, so reading the
/// next items, working on items and consuming results overlap. With one thread all
/// three run in turn on the calling thread. Each worker builds its own state with
/// `init`; for results independent of the thread count, `work`'s result must depend only
/// on its item. When `consume` returns `false`, no further items are asked for or
/// consumed. A panic in `source`, `work` or `consume` is raised again here. With
/// `stages`, the time of each stage is added to it.
///
/// ```
/// use ctr_formats::parallel::stream;
/// let mut next = 0;
/// let mut squares = Vec::new();
/// stream(3, 4, None, || { next += 1; (next <= 5).then_some(next) }, || (), |(), x| x * x,
///        |y| { squares.push(y); true });
/// assert_eq!(squares, [1, 4, 9, 16, 25]);
/// ```
pub fn stream<I, S, T>(
    threads: usize,
    in_flight: usize,
    stages: Option<&Stages>,
    source: impl FnMut() -> Option<I> + Send,
    init: impl Fn() -> S + Sync,
    work: impl Fn(&mut S, I) -> T + Sync,
    consume: impl FnMut(T) -> bool,
) where
    I: Send,
    T: Send,
{
    let off = Stages::default();
    let stages = stages.unwrap_or(&off);
    let threads = resolve_threads(threads);
    if threads == 1 {
        stream_here(stages, source, init, work, consume);
    } else {
        let writer_cpu = stages.on().then(thread_cpu_ns).flatten();
        let pipeline = Pipeline {
            threads,
            in_flight: in_flight.max(1),
            stages,
        };
        pipeline.run(source, init, work, consume);
        if let (Some(t0), Some(t1)) = (writer_cpu, thread_cpu_ns()) {
            let used = t1.saturating_sub(t0);
            stages.writer_cpu_ns.fetch_add(used, Ordering::Relaxed);
        }
    }
}

/// [`stream`] on the calling thread alone: each item read, worked on and consumed in
/// turn.
fn stream_here<I, S, T>(
    stages: &Stages,
    mut source: impl FnMut() -> Option<I>,
    init: impl Fn() -> S,
    work: impl Fn(&mut S, I) -> T,
    mut consume: impl FnMut(T) -> bool,
) {
    let on = stages.on();
    let mut state = init();
    while let Some(item) = timed(on, &stages.read_ns, &mut source) {
        let result = timed(on, &stages.work_ns, || work(&mut state, item));
        if !timed(on, &stages.write_ns, || consume(result)) {
            break;
        }
    }
}

/// [`stream`] on threads: a producer, `threads` workers, the calling thread consuming.
struct Pipeline<'s> {
    threads: usize,
    in_flight: usize,
    stages: &'s Stages,
}

impl Pipeline<'_> {
    fn run<I: Send, S, T: Send>(
        &self,
        mut source: impl FnMut() -> Option<I> + Send,
        init: impl Fn() -> S + Sync,
        work: impl Fn(&mut S, I) -> T + Sync,
        consume: impl FnMut(T) -> bool,
    ) {
        let stop = AtomicBool::new(false);
        // the producer takes a token for every item; the consumer gives one back for
        // every result it consumed: at most `in_flight` items in between
        let (token_tx, token_rx) = mpsc::channel::<()>();
        for _ in 0..self.in_flight {
            let _ = token_tx.send(());
        }
        let (item_tx, item_rx) = mpsc::sync_channel::<(usize, I)>(self.in_flight);
        let item_rx = Mutex::new(item_rx);
        let (result_tx, result_rx) = mpsc::channel::<Option<(usize, T)>>();
        std::thread::scope(|s| {
            let (stop, init, work) = (&stop, &init, &work);
            let mut handles = Vec::with_capacity(self.threads + 1);
            handles.push(s.spawn(move || self.produce(&mut source, token_rx, item_tx, stop)));
            for _ in 0..self.threads {
                let (result_tx, item_rx) = (result_tx.clone(), &item_rx);
                handles.push(s.spawn(move || self.work(item_rx, result_tx, stop, init, work)));
            }
            drop(result_tx);
            self.consume_in_order(result_rx, token_tx, consume);
            // unblock the producer and the workers and let them finish
            stop.store(true, Ordering::Relaxed);
            for h in handles {
                if let Err(panic) = h.join() {
                    std::panic::resume_unwind(panic);
                }
            }
        });
    }

    /// The producer: an item from `source` for every token, numbered, until the source
    /// ends or the consumer stops.
    fn produce<I>(
        &self,
        source: &mut impl FnMut() -> Option<I>,
        tokens: mpsc::Receiver<()>,
        items: mpsc::SyncSender<(usize, I)>,
        stop: &AtomicBool,
    ) {
        let stages = self.stages;
        let _cpu = ThreadCpu::start(stages, &stages.reader_cpu_ns);
        for k in 0.. {
            if tokens.recv().is_err() || stop.load(Ordering::Relaxed) {
                break;
            }
            let Some(item) = timed(stages.on(), &stages.read_ns, &mut *source) else {
                break;
            };
            if items.send((k, item)).is_err() {
                break;
            }
        }
    }

    /// A worker: takes items until there are none, sends each result with its number.
    fn work<I, S, T>(
        &self,
        items: &Mutex<mpsc::Receiver<(usize, I)>>,
        results: mpsc::Sender<Option<(usize, T)>>,
        stop: &AtomicBool,
        init: impl Fn() -> S,
        work: impl Fn(&mut S, I) -> T,
    ) {
        let stages = self.stages;
        // a worker that panics says so, so that the consumer stops waiting
        let guard = PanicNotice(&results);
        let _cpu = ThreadCpu::start(stages, &stages.workers_cpu_ns);
        let mut state = init();
        loop {
            let next = items.lock().map(|rx| rx.recv());
            let Ok(Ok((k, item))) = next else { break };
            if stop.load(Ordering::Relaxed) {
                break;
            }
            let t = timed(stages.on(), &stages.work_ns, || work(&mut state, item));
            if guard.0.send(Some((k, t))).is_err() {
                break;
            }
        }
    }

    /// The calling thread: the results in their items' order to `consume` (a token back
    /// for each), until the workers are done, one panicked or `consume` says stop.
    fn consume_in_order<T>(
        &self,
        results: mpsc::Receiver<Option<(usize, T)>>,
        tokens: mpsc::Sender<()>,
        mut consume: impl FnMut(T) -> bool,
    ) {
        let stages = self.stages;
        let mut pending = BTreeMap::new();
        let mut want = 0;
        loop {
            let t = match pending.remove(&want) {
                Some(t) => t,
                None => match results.recv() {
                    Ok(Some((k, t))) => {
                        pending.insert(k, t);
                        continue;
                    }
                    // all workers done, or one panicked (raised again by the caller)
                    Ok(None) | Err(_) => break,
                },
            };
            want += 1;
            if !timed(stages.on(), &stages.write_ns, || consume(t)) {
                break;
            }
            let _ = tokens.send(());
        }
    }
}

/// `f()`, its wall time added to `stage` when `on`.
fn timed<R>(on: bool, stage: &AtomicU64, f: impl FnOnce() -> R) -> R {
    if !on {
        return f();
    }
    let t0 = std::time::Instant::now();
    let r = f();
    stage.fetch_add(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
    r
}

/// Where the time of a [`stream`] went, stage by stage, when asked (`Stages::new(true)`).
///
/// Wall times are summed over the threads that ran a stage: reading the next item
/// (`source`), working on items (`work`, on the workers) and consuming results in order
/// (`consume`, on the calling thread). With more than one thread the CPU time of each
/// kind of thread is kept too (from the kernel's per-thread accounting, Linux; zero
/// elsewhere), which load on the machine does not inflate.
///
/// ```
/// use ctr_formats::parallel::{stream, Stages};
/// let stages = Stages::new(true);
/// let mut n = 0;
/// stream(2, 4, Some(&stages), || { n += 1; (n <= 100).then_some(n) }, || (), |(), x| x + 1, |_| true);
/// assert!(stages.work().as_nanos() > 0);
/// ```
#[derive(Debug, Default)]
pub struct Stages {
    on: bool,
    read_ns: AtomicU64,
    work_ns: AtomicU64,
    write_ns: AtomicU64,
    reader_cpu_ns: AtomicU64,
    workers_cpu_ns: AtomicU64,
    writer_cpu_ns: AtomicU64,
    before_ns: AtomicU64,
    after_ns: AtomicU64,
}

impl Stages {
    /// Stages that are timed (`on`) or not.
    pub fn new(on: bool) -> Self {
        Stages {
            on,
            ..Default::default()
        }
    }

    /// Whether the stages are timed.
    pub fn on(&self) -> bool {
        self.on
    }

    fn get(a: &AtomicU64) -> Duration {
        Duration::from_nanos(a.load(Ordering::Relaxed))
    }

    /// Wall time in `source` (reading the next item).
    pub fn read(&self) -> Duration {
        Self::get(&self.read_ns)
    }

    /// Wall time in `work`, summed over the workers.
    pub fn work(&self) -> Duration {
        Self::get(&self.work_ns)
    }

    /// Wall time in `consume`.
    pub fn write(&self) -> Duration {
        Self::get(&self.write_ns)
    }

    /// Adds to the wall time a job spends before its stream (setting up) or after it
    /// (finishing): the parts that no thread count shortens.
    pub fn add_around(&self, before: Duration, after: Duration) {
        self.before_ns
            .fetch_add(before.as_nanos() as u64, Ordering::Relaxed);
        self.after_ns
            .fetch_add(after.as_nanos() as u64, Ordering::Relaxed);
    }

    /// Wall time before the stream and after it ([`Stages::add_around`]).
    pub fn around(&self) -> [Duration; 2] {
        [Self::get(&self.before_ns), Self::get(&self.after_ns)]
    }

    /// CPU time of the reading thread, the workers (summed) and the consuming thread,
    /// with more than one thread (zero where the kernel does not tell).
    pub fn cpu(&self) -> [Duration; 3] {
        [
            Self::get(&self.reader_cpu_ns),
            Self::get(&self.workers_cpu_ns),
            Self::get(&self.writer_cpu_ns),
        ]
    }
}

/// A thread's CPU time so far, ns (Linux: the first field of
/// `/proc/thread-self/schedstat`); `None` where it cannot be read.
fn thread_cpu_ns() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    text.split_whitespace().next()?.parse().ok()
}

/// Adds the CPU time of the thread it lives on, from its start to its drop, to a
/// counter of [`Stages`] (when they are timed).
struct ThreadCpu<'a> {
    start: Option<u64>,
    to: &'a AtomicU64,
}

impl<'a> ThreadCpu<'a> {
    fn start(stages: &Stages, to: &'a AtomicU64) -> Self {
        ThreadCpu {
            start: stages.on().then(thread_cpu_ns).flatten(),
            to,
        }
    }
}

impl Drop for ThreadCpu<'_> {
    fn drop(&mut self) {
        if let (Some(t0), Some(t1)) = (self.start, thread_cpu_ns()) {
            self.to.fetch_add(t1.saturating_sub(t0), Ordering::Relaxed);
        }
    }
}

/// Sends `None` when dropped during a panic (a worker of [`stream`] that panicked).
struct PanicNotice<'a, T>(&'a mpsc::Sender<Option<T>>);

impl<T> Drop for PanicNotice<'_, T> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            let _ = self.0.send(None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_in_order_with_bounded_items_in_flight() {
        for threads in [1, 2, 5] {
            let produced = AtomicUsize::new(0);
            let mut next = 0;
            let mut out = Vec::new();
            let mut most_ahead = 0;
            stream(
                threads,
                3,
                None,
                || {
                    next += 1;
                    produced.fetch_add(1, Ordering::SeqCst);
                    (next <= 200).then_some(next)
                },
                || (),
                |(), x: usize| {
                    // uneven work, so that results come back out of order
                    std::thread::sleep(std::time::Duration::from_micros((x % 7) as u64 * 50));
                    x * 10
                },
                |y| {
                    out.push(y);
                    most_ahead = most_ahead.max(produced.load(Ordering::SeqCst) - out.len());
                    true
                },
            );
            assert_eq!(out, (1..=200).map(|x| x * 10).collect::<Vec<_>>());
            // the producer is at most `in_flight` items ahead of the consumer (plus the
            // call that found the end)
            assert!(most_ahead <= 3 + 1, "{threads} threads: {most_ahead} ahead");
        }
    }

    #[test]
    fn a_consumer_that_stops_ends_the_stream() {
        for threads in [1, 3] {
            let mut next = 0;
            let mut seen = Vec::new();
            stream(
                threads,
                4,
                None,
                || {
                    next += 1;
                    Some(next)
                },
                || (),
                |(), x: u64| x,
                |y| {
                    seen.push(y);
                    y < 10
                },
            );
            assert_eq!(seen, (1..=10).collect::<Vec<_>>());
        }
    }

    #[test]
    #[should_panic(expected = "bad item")]
    fn a_panicking_worker_is_raised_again() {
        let mut next = 0;
        stream(
            2,
            2,
            None,
            || {
                next += 1;
                (next < 50).then_some(next)
            },
            || (),
            |(), x: u32| {
                assert!(x != 7, "bad item");
                x
            },
            |_| true,
        );
    }
}

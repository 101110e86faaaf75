//! A parallel map over independent rows, for calls whose rows do not share a solver
//! (IK targets, Jacobians). Batch FK does not use it: it goes through
//! `ctr_analysis::batch::batch_fk`, whose warm-started chunks make it equal `ctr-cli fk`.

use std::sync::atomic::{AtomicUsize, Ordering};

/// Rows a worker takes at a time.
const BLOCK: usize = 4;

/// `f(state, i)` for `i` in `0..n`, in order, on `threads` workers (0 = all cores),
/// each with its own `state` from `init`. The results are independent of the thread
/// count as long as `f`'s result depends only on `i`.
pub fn map<S, T, I, F>(n: usize, threads: usize, init: I, f: F) -> Vec<T>
where
    T: Send,
    I: Fn() -> S + Sync,
    F: Fn(&mut S, usize) -> T + Sync,
{
    let threads = ctr_analysis::batch::resolve_threads(threads)
        .min(n.div_ceil(BLOCK))
        .max(1);
    if threads == 1 {
        let mut state = init();
        return (0..n).map(|i| f(&mut state, i)).collect();
    }
    let next = AtomicUsize::new(0);
    let work = || {
        let mut state = init();
        let mut done = Vec::new();
        loop {
            let start = next.fetch_add(BLOCK, Ordering::Relaxed);
            if start >= n {
                break done;
            }
            for i in start..(start + BLOCK).min(n) {
                done.push((i, f(&mut state, i)));
            }
        }
    };
    let mut all: Vec<(usize, T)> = std::thread::scope(|s| {
        let handles: Vec<_> = (1..threads).map(|_| s.spawn(work)).collect();
        let mut all = work();
        for h in handles {
            // a worker's panic is re-raised here (pyo3 turns it into PanicException)
            all.extend(h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)));
        }
        all
    });
    all.sort_unstable_by_key(|(i, _)| *i);
    all.into_iter().map(|(_, t)| t).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn order_and_thread_count_do_not_matter() {
        let one = super::map(
            103,
            1,
            || 0u32,
            |calls, i| {
                *calls += 1;
                i * i
            },
        );
        let four = super::map(103, 4, || 0u32, |_, i| i * i);
        assert_eq!(one, four);
        assert_eq!(one[10], 100);
        assert!(super::map(0, 3, || (), |_, i| i).is_empty());
    }
}

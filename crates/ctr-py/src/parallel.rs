//! A parallel map over independent rows, for calls whose rows do not share a solver
//! (IK targets, Jacobians). Batch FK does not use it: it goes through
//! `ctr_analysis::batch::batch_fk`, whose warm-started chunks make it equal `ctr-cli fk`.

/// Rows a worker takes at a time.
const BLOCK: usize = 4;

/// `f(state, i)` for `i` in `0..n`, in order, on `threads` workers (0 = all cores),
/// each with its own `state` from `init` (`ctr_formats::parallel::for_each_chunk` over
/// blocks of rows). The results are independent of the thread count as long as `f`'s
/// result depends only on `i`.
pub fn map<S, T, I, F>(n: usize, threads: usize, init: I, f: F) -> Vec<T>
where
    T: Send,
    I: Fn() -> S + Sync,
    F: Fn(&mut S, usize) -> T + Sync,
{
    let mut out = Vec::with_capacity(n);
    ctr_formats::parallel::for_each_chunk(
        n,
        BLOCK,
        threads,
        &(),
        init,
        |state, rows| rows.map(|i| f(state, i)).collect::<Vec<T>>(),
        |_, block| {
            out.extend(block);
            true
        },
    );
    out
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

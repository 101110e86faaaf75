//! A progress bar on stderr, shown only on a terminal and only once a job has run for
//! a while.

use ctr_formats::parallel::Progress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// The bar appears when a job is still running after this long.
const SHOW_AFTER: Duration = Duration::from_secs(1);

/// A bar that stays hidden unless stderr is a terminal and the job is long.
#[derive(Default)]
pub struct Bar {
    bar: OnceLock<(ProgressBar, Instant)>,
    shown: AtomicBool,
}

impl Progress for Bar {
    fn start(&self, rows: usize) {
        if rows == 0 || !std::io::stderr().is_terminal() {
            return;
        }
        let bar = ProgressBar::with_draw_target(Some(rows as u64), ProgressDrawTarget::hidden());
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {pos}/{len} rows, {per_sec}, eta {eta}")
        {
            bar.set_style(style);
        }
        let _ = self.bar.set((bar, Instant::now()));
    }

    fn advance(&self, rows: usize) {
        if let Some((bar, started)) = self.bar.get() {
            bar.inc(rows as u64);
            if started.elapsed() >= SHOW_AFTER && !self.shown.swap(true, Ordering::Relaxed) {
                bar.set_draw_target(ProgressDrawTarget::stderr());
            }
        }
    }

    fn finish(&self) {
        if let Some((bar, _)) = self.bar.get() {
            bar.finish_and_clear();
        }
    }
}

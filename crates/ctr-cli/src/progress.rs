//! A progress bar on stderr, shown only on a terminal and only once a job has run for
//! a while.

use ctr_formats::parallel::{Progress, Stages};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// The bar appears when a job is still running after this long.
const SHOW_AFTER: Duration = Duration::from_secs(1);

/// A bar that stays hidden unless stderr is a terminal and the job is long; it also
/// carries the stages' times of a job that is profiled ([`Bar::profiled`]).
#[derive(Default)]
pub struct Bar {
    bar: OnceLock<(ProgressBar, Instant)>,
    shown: AtomicBool,
    stages: Stages,
}

impl Bar {
    /// A bar whose job times its stages (`on`).
    pub fn profiled(on: bool) -> Self {
        Bar {
            stages: Stages::new(on),
            ..Bar::default()
        }
    }

    /// The stages' times as lines for stderr: what no thread count shortens (setting
    /// up, finishing), the reader, the workers and the writer, wall and CPU seconds
    /// (CPU with more than one thread, from the kernel's accounting of each thread).
    pub fn profile(&self, rows: usize, threads: usize, wall: Duration) -> String {
        let s = &self.stages;
        let [before, after] = s.around();
        let [reader, workers, writer] = s.cpu();
        let line = |what: &str, w: Duration, cpu: Option<Duration>| {
            let cpu = cpu
                .filter(|_| threads > 1)
                .map_or("-".to_owned(), |c| format!("{:.3}", c.as_secs_f64()));
            format!("profile: {what:<50} {:>8.3} {cpu:>8}\n", w.as_secs_f64())
        };
        let mut out = format!(
            "profile: {rows} rows, {threads} thread{}, wall {:.3} s; per stage: wall s, cpu s\n",
            if threads == 1 { "" } else { "s" },
            wall.as_secs_f64()
        );
        out += &line("setting up (robot, model, header, output)", before, None);
        out += &line(
            "reading and cutting the joint file (reader)",
            s.read(),
            Some(reader),
        );
        out += &line(
            "parsing, solving, formatting (workers, summed)",
            s.work(),
            Some(workers),
        );
        out += &line(
            "taking pieces in order, writing (writer)",
            s.write(),
            Some(writer),
        );
        out += &line("finishing (flush, fsync, rename)", after, None);
        out
    }
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

    fn stages(&self) -> Option<&Stages> {
        self.stages.on().then_some(&self.stages)
    }
}

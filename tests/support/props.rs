//! Property tests: how they run and the random robots and joints they draw.
//!
//! # The same cases every run
//!
//! Every property draws its cases from the fixed seed `SEED`, or from
//! `PROPTEST_RNG_SEED` when that is set: two runs of one commit (CI's included) run the
//! same cases and print the same lines. The case count is the test's own (the count CI
//! runs), or `PROPTEST_CASES` when that is set. Fresh seeds and large counts are
//! `scripts/explore_properties.sh`'s job, not CI's.
//!
//! # Regression files
//!
//! Each property keeps the cases that ever failed in its own file,
//! `proptest-regressions/<test file>/<property>.txt` beside its test file, one line
//! each: `cc <seed> # shrinks to <the shrunk case>`. Every run replays them before it
//! draws new cases; a run that finds a failure appends it (commit the file). The seed
//! regenerates the original failing case, which shrinks again to the one named.
//!
//! # A failure
//!
//! `check` panics at the test's line with the property's reason, the seed and count
//! of the run, the regression file and one line to paste into it: the `cc` line of the
//! shrunk case (already appended when the run found it).

use ctr_core::TubeParams;
use proptest::prelude::*;
use proptest::test_runner::{
    Config, FailurePersistence, PersistedSeed, RngSeed, TestCaseError, TestError, TestRunner,
};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// The seed every property draws from unless `PROPTEST_RNG_SEED` names another.
pub const SEED: u64 = 0x000c_7a11_5eed;

/// Largest number of shrink steps of a failing case (it is shrunk, but not for longer).
const MAX_SHRINK_ITERS: u32 = 2048;

/// `var` parsed as a `T`, `None` when unset; a value that does not parse is an error
/// that names it (a typo must not quietly run the defaults).
fn env_number<T: std::str::FromStr>(var: &str) -> Option<T> {
    let v = std::env::var(var).ok()?;
    match v.trim().parse() {
        Ok(x) => Some(x),
        Err(_) => panic!(
            "{var}={v:?} is not a number ({})",
            std::any::type_name::<T>()
        ),
    }
}

/// The seed of this run: `PROPTEST_RNG_SEED` when set, [`SEED`] otherwise.
pub fn seed() -> u64 {
    env_number("PROPTEST_RNG_SEED").unwrap_or(SEED)
}

/// A proptest configuration of `cases` cases (the count CI runs), or of
/// `PROPTEST_CASES` cases when that is set, drawn from [`seed`]:
/// `PROPTEST_CASES=5000 cargo test --release -p ctr-core --test properties`.
/// (proptest reads `PROPTEST_CASES` only for its default configuration, which a
/// count of our own would override.)
pub fn config(cases: u32) -> Config {
    Config {
        cases: env_number("PROPTEST_CASES").unwrap_or(cases),
        rng_seed: RngSeed::Fixed(seed()),
        max_shrink_iters: MAX_SHRINK_ITERS,
        ..Config::default()
    }
}

/// The regression file of property `test` of the test file `source_file` (a
/// `file!()`: relative to the workspace root, where the crates are built from):
/// `<its folder>/proptest-regressions/<its stem>/<test>.txt`.
pub fn regression_file(source_file: &str, test: &str) -> PathBuf {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join(source_file);
    let stem = source
        .file_stem()
        .unwrap_or_else(|| panic!("{source_file}: not a file name"));
    source
        .with_file_name("proptest-regressions")
        .join(stem)
        .join(format!("{test}.txt"))
}

/// The regression file of one property: replayed before new cases, a new failure's
/// `cc` line appended (and kept for the failure's message).
#[derive(Clone, Debug)]
struct Regressions {
    path: PathBuf,
    /// the line appended by this run
    appended: Arc<Mutex<Option<String>>>,
}

const REGRESSIONS_HEADER: &str = "\
# Cases this property failed on, replayed by every run (CI's included) before it draws
# new ones: `cc <seed> # shrinks to <case>`, the seed regenerating the original case,
# which shrinks to the one named. Written by the runs that find them
# (scripts/explore_properties.sh, tests/support/props.rs); keep them committed.
";

impl FailurePersistence for Regressions {
    fn load_persisted_failures2(&self, _: Option<&'static str>) -> Vec<PersistedSeed> {
        let Ok(text) = std::fs::read_to_string(&self.path) else {
            return Vec::new();
        };
        text.lines()
            .enumerate()
            .filter_map(|(k, line)| {
                let seed = line.split('#').next().unwrap_or("").trim();
                (!seed.is_empty()).then(|| {
                    seed.parse().unwrap_or_else(|()| {
                        panic!(
                            "{}:{}: not a proptest seed line: {line}",
                            self.path.display(),
                            k + 1
                        )
                    })
                })
            })
            .collect()
    }

    fn save_persisted_failure2(
        &mut self,
        _: Option<&'static str>,
        seed: PersistedSeed,
        shrunk: &dyn std::fmt::Debug,
    ) {
        let line = format!("{seed} # shrinks to {shrunk:?}");
        let mut text =
            std::fs::read_to_string(&self.path).unwrap_or_else(|_| REGRESSIONS_HEADER.to_string());
        text.push_str(&line);
        text.push('\n');
        let written = self
            .path
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .and_then(|()| std::fs::write(&self.path, text));
        if let Err(e) = written {
            eprintln!("could not append to {}: {e}", self.path.display());
        }
        *self.appended.lock().unwrap_or_else(|e| e.into_inner()) = Some(line);
    }

    fn box_clone(&self) -> Box<dyn FailurePersistence> {
        Box::new(self.clone())
    }

    fn eq(&self, other: &dyn FailurePersistence) -> bool {
        other
            .as_any()
            .downcast_ref::<Self>()
            .is_some_and(|o| o.path == self.path)
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

/// Runs the property `test` (its function's name) of the test file `source_file`
/// (the caller's `file!()`) on [`config`]`(cases)` draws of `strategy`, after the cases
/// of its [`regression_file`]. On a failure it panics at the caller's line with the
/// reason, the seed, and the shrunk case as one `cc` line of the regression file.
#[track_caller]
pub fn check<S: Strategy>(
    source_file: &'static str,
    test: &'static str,
    cases: u32,
    strategy: S,
    property: impl Fn(S::Value) -> Result<(), TestCaseError>,
) where
    S::Value: std::fmt::Debug,
{
    // a name that is not the test's would file its cases under another property
    if let Some(thread) = std::thread::current().name() {
        assert!(
            thread == "main" || thread.rsplit("::").next() == Some(test),
            "props::check called from test {thread} with the name {test}"
        );
    }
    let regressions = Regressions {
        path: regression_file(source_file, test),
        appended: Arc::default(),
    };
    let config = Config {
        source_file: Some(source_file),
        failure_persistence: Some(Box::new(regressions.clone())),
        ..config(cases)
    };
    let (seed, cases) = (seed(), config.cases);
    let Err(e) = TestRunner::new(config).run(&strategy, property) else {
        return;
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let file = regressions
        .path
        .strip_prefix(root)
        .unwrap_or(&regressions.path)
        .display();
    let run = format!("seed {seed}, {cases} cases");
    match e {
        TestError::Abort(why) => panic!("property {test} gave up ({run}): {why}"),
        TestError::Fail(why, case) => {
            match regressions
                .appended
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .take()
            {
                Some(line) => panic!(
                    "property {test} failed ({run}): {why}\n\
                     the shrunk case, appended to {file} (replayed by every run; commit it):\n\
                     {line}"
                ),
                None => panic!(
                    "property {test} failed again on a case of {file}: {why}\n\
                     the shrunk case: {case:?}"
                ),
            }
        }
    }
}

/// A random tube of a physical robot, built from the inside out: its inner diameter
/// is the next tube's outer diameter plus a clearance (`inner_od` is `None` for
/// the innermost tube). Ranges: walls 0.08 to 0.6 mm, clearances 0.02 to 0.4 mm,
/// curved parts 0 to 200 mm (at most the tube), radii 20 to 2000 mm either sign
/// (one tube in five straight), E 1 GPa (plastics) to 80 GPa (nitinol), Poisson
/// ratio 0.25 to 0.45.
fn tube(inner_od: Option<f64>, length_mm: f64) -> impl Strategy<Value = TubeParams<f64>> {
    (
        match inner_od {
            None => (0.0..1.2f64).boxed(),
            Some(od) => (0.02..0.4f64).prop_map(move |c| od + c).boxed(),
        },
        0.08..0.6f64,
        0.0..1.0f64,
        prop_oneof![
            1 => Just(None),
            // log-uniform: as many strongly curved tubes (those that snap) as mild ones
            4 => ((20.0f64).ln()..(2000.0f64).ln(), any::<bool>())
                .prop_map(|(r, neg)| Some(if neg { -r.exp() } else { r.exp() })),
        ],
        1000.0..80000.0f64,
        0.25..0.45f64,
    )
        .prop_map(move |(id, wall, curved, radius, e, nu)| TubeParams {
            curvature_radius_mm: radius,
            ..TubeParams::new(
                id + 2.0 * wall,
                id,
                length_mm,
                curved * length_mm.min(200.0),
                e,
                nu,
            )
        })
}

/// A random valid robot of `n` tubes (1 to 4), outermost first: tube lengths from
/// 60 to 300 mm for tube 1, each inner tube 10 to 150 mm longer than the one around
/// it (it must reach beyond it), tubes as `tube` draws them.
pub fn robot(n: usize) -> BoxedStrategy<Vec<TubeParams<f64>>> {
    assert!((1..=ctr_core::MAX_TUBES).contains(&n));
    (
        60.0..300.0f64,
        proptest::collection::vec(10.0..150.0f64, n - 1),
    )
        .prop_flat_map(move |(first, extra)| {
            // lengths outermost first
            let mut lengths = vec![first];
            for e in &extra {
                lengths.push(lengths.last().copied().unwrap_or(0.0) + e);
            }
            // build from the innermost tube out: each tube's inner diameter
            // depends on the outer diameter of the tube inside it
            let innermost = tube(None, lengths[n - 1]).prop_map(|t| vec![t]).boxed();
            (1..n).rev().fold(innermost, |inner, i| {
                let length = lengths[i - 1];
                inner
                    .prop_flat_map(move |tubes: Vec<TubeParams<f64>>| {
                        let od = tubes[0].outer_diameter_mm;
                        tube(Some(od), length).prop_map(move |t| {
                            let mut all = vec![t];
                            all.extend(tubes.iter().copied());
                            all
                        })
                    })
                    .boxed()
            })
        })
        .boxed()
}

/// Random valid joints for tubes of `lengths` (outermost first), as fractions:
/// `s_1 <= ... <= s_n`, each `s_i <= length_i`, rotations -400 to 400 degrees;
/// returned in file units, `(s_mm, theta_deg)`.
pub fn valid_joints(lengths: &[f64], u: &[f64], theta_deg: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut s = Vec::with_capacity(lengths.len());
    let mut prev = 0.0;
    for (i, &len) in lengths.iter().enumerate() {
        let v = prev + (len - prev) * u[i];
        s.push(v);
        prev = v;
    }
    (s, theta_deg.to_vec())
}

//! One candidate fitted on a ~1,000-row recording: `calibrate` with one effect (the
//! split, the user model's error, one robust Levenberg-Marquardt fit of the effect's
//! parameters from its start, the intervals and the report), on one thread.
//!
//! - `clearance/liu2023`: the bundled example (`data/examples/liu2023-recording.csv`, 984
//!   rows), the clearance's two parameters (unloaded solves).
//! - `latency/liu2023`: the same recording, the latency (a time effect: the actual
//!   joints recomputed along every run for each prediction).
//! - `gravity/dev-gravity`: the shared `dev-gravity` recording (984 rows), gravity's
//!   three parameters (every prediction a loaded solve: the costly candidate).
//!
//! Run: `cargo bench -p ctr-diagnosis --bench candidate_fit` (criterion reports the
//! median); `scripts/bench_diagnose.sh` times whole diagnoses.

use criterion::{criterion_group, criterion_main, Criterion};
use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::{calibrate, EffectId, Options};
use ctr_formats::{Recording, RobotSpec};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn case(robot: &str, recording: &str) -> (ModelSpec, Recording) {
    let spec = RobotSpec::from_path(&root().join(robot)).expect("the robot file reads");
    let rec = Recording::from_path(&root().join(recording), spec.robot.n_tubes())
        .expect("the recording reads");
    (ModelSpec::from_spec(&spec), rec)
}

fn candidate_fit(c: &mut Criterion) {
    let example = case(
        "data/robots/liu2023.toml",
        "data/examples/liu2023-recording.csv",
    );
    let gravity = case(
        "tests/data/shared/robots/liu2023.toml",
        "tests/data/shared/recordings/dev-gravity.csv",
    );
    let one_thread = Options {
        threads: 1,
        ..Options::default()
    };
    let mut group = c.benchmark_group("candidate_fit");
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    for (name, (model, rec), effect) in [
        ("clearance/liu2023", &example, EffectId::Clearance),
        ("latency/liu2023", &example, EffectId::Latency),
        ("gravity/dev-gravity", &gravity, EffectId::Gravity),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| calibrate(black_box(model), black_box(rec), &[effect], &one_thread).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, candidate_fit);
criterion_main!(benches);

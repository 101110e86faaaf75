//! The intervals' coverage on replicas of the public recordings: the same commands,
//! the same robot and the same concealed effects, measured again with fresh tracker
//! noise.
//!
//! A public recording is one draw of its noise. `ctr-analysis`'s
//! `true_effects_reach_the_noise_floor` and the replicas' own check below show that the
//! project's simulator, given the truth, reproduces the independent simulator's clean
//! tips to far below the noise (the RMS at the truth equals the RMS of the noise the
//! truth file says was added to 1e-6 in its square): what separates a public fit from
//! the truth is the noise alone. Its 20 scalar parameters then hold the truth in their
//! 95 % intervals about 19 times in 20 on average, but on the one draw of each
//! recording the count is a random number; whether the intervals are honest is a
//! question about many draws. Here each recording is replayed with
//! [`REPLICAS`] fresh draws (`CTR_REPLICAS` overrides), its clean tips the truth's
//! prediction (a tracker drift added as the truth file states it) plus Gaussian noise
//! of the truth's `sigma_mm_per_axis`, diagnosed blind, and the truth must lie inside
//! `ci95` for at least [`MIN_COVERAGE`] of the scalars over all replicas together.
//! Run in release: `cargo test -p ctr-diagnosis --release --test replicas -- --nocapture`.

mod common;

use common::coverage::Tally;
use common::{public_ids, public_truth};

use ctr_analysis::model::ModelSpec;
use ctr_analysis::rng::Rng;
use ctr_analysis::simulate::predict;
use ctr_diagnosis::{diagnose, Options};
use ctr_formats::{Clearance, Effects, Friction, Gravity, Latency, Registration};
use serde_json::Value;

/// Fresh noise draws per public recording.
const REPLICAS: u64 = 2;
/// Least share of the scalars whose interval holds the truth (the 85 %).
const MIN_COVERAGE: f64 = 0.85;
/// The RMS at the truth may exceed the noise actually added by this factor.
const FLOOR_TOLERANCE: f64 = 1.02;

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

fn v3(v: &Value) -> [f64; 3] {
    std::array::from_fn(|i| f(&v[i]))
}

/// The truth file's effects of the vocabulary in the robot file's terms.
fn truth_effects(world: &Value, n: usize) -> Effects {
    let mut out = Effects::default();
    if let Some(c) = world.get("clearance") {
        out.clearance = Some(Clearance {
            max_deflection_deg: vec![f(&c["delta_max_deg"]); n - 1],
            peak_deg: vec![f(&c["phi0_deg"]); n - 1],
            table_deg: vec![],
        });
    }
    if let Some(c) = world.get("friction") {
        out.friction = Some(Friction {
            rotation_friction_coefficient: vec![],
            rotation_play_deg: vec![f(&c["rotation_play_half_width_deg"]); n - 1],
            feed_play_mm: vec![],
        });
    }
    if let Some(c) = world.get("latency") {
        out.latency = Some(Latency {
            tau_s: f(&c["tau_s"]),
        });
    }
    if let Some(c) = world.get("gravity") {
        out.gravity = Some(Gravity {
            direction_w: v3(&c["direction_W"]),
            g_m_s2: f(&c["g_m_s2"]),
        });
    }
    if let Some(c) = world.get("registration") {
        out.registration = Some(Registration {
            translation_mm: v3(&c["translation_mm"]),
            rotation_axis: v3(&c["rotation_axis"]),
            rotation_deg: f(&c["rotation_deg"]),
        });
    }
    out
}

#[test]
fn intervals_hold_the_truth_on_replicas_of_the_public_recordings() {
    let replicas = std::env::var("CTR_REPLICAS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(REPLICAS);
    let mut all = Tally::default();
    let mut per_draw = vec![(0, 0); replicas as usize];
    for id in &public_ids() {
        let (spec, rec, truth) = common::recording(id);
        let world = &truth["world"]["effects"];
        let n = spec.robot.n_tubes();
        let user = ModelSpec::from_spec(&spec);
        let mut model = user.clone();
        model.effects = truth_effects(world, n);
        // only the vocabulary's effects and a tracker drift are replayed
        let graded = model.effects.present().len();
        let known = graded + usize::from(world.get("tracker_drift").is_some());
        if known != world.as_object().map_or(0, |m| m.len()) || graded == 0 {
            continue;
        }
        let drift = world
            .get("tracker_drift")
            .map_or([0.0; 3], |d| v3(&d["velocity_mm_s"]));
        let sigma = f(&truth["noise"]["sigma_mm_per_axis"]);
        let runs: Vec<usize> = (0..rec.runs.len()).collect();
        let clean: Vec<[f64; 3]> = predict(&model, &rec, &runs)
            .unwrap()
            .p
            .iter()
            .zip(&rec.rows)
            .map(|(p, r)| std::array::from_fn(|a| p[a] + drift[a] * r.t_s))
            .collect();
        // the replay's clean tips are the recording's but for its noise
        let sum: f64 = clean
            .iter()
            .zip(&rec.rows)
            .map(|(c, r)| (0..3).map(|a| (r.p[a] - c[a]).powi(2)).sum::<f64>())
            .sum();
        let rms = (sum / rec.rows.len() as f64).sqrt();
        let floor = f(&truth["noise_floor_rms_mm"]);
        assert!(rms <= FLOOR_TOLERANCE * floor, "{id}: {rms} vs {floor}");
        for (k, draw) in per_draw.iter_mut().enumerate() {
            let mut rng = Rng::new(9000 + k as u64);
            let mut replay = rec.clone();
            for (row, c) in replay.rows.iter_mut().zip(&clean) {
                for a in 0..3 {
                    row.p[a] = c[a] + sigma * rng.normal();
                }
            }
            let d = diagnose(&user, &replay, &Options::default()).unwrap();
            let before = (all.inside, all.total);
            for fd in &d.report.findings {
                if let Some(t) = public_truth(world, fd.effect.as_str(), n) {
                    all.finding(&format!("{id} replica {k}"), fd, &t, |_| None);
                }
            }
            draw.0 += all.inside - before.0;
            draw.1 += all.total - before.1;
        }
    }
    let Tally {
        inside,
        total,
        misses,
        ..
    } = all;
    let coverage = inside as f64 / total.max(1) as f64;
    eprintln!(
        "replicas of the public recordings: {inside} of {total} scalars hold the truth \
         ({:.1} %); per draw of all recordings {per_draw:?}; misses: {misses:#?}",
        100.0 * coverage
    );
    assert!(total >= 10 * replicas as usize, "{total} compared");
    assert!(coverage >= MIN_COVERAGE, "coverage {coverage:.3}");
}

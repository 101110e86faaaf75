//! The diagnosis, run blind on the shared recordings: each must give exactly its
//! `expected_findings` as established findings (and, where every effect is in the
//! vocabulary, nothing predictive); where every effect is in the vocabulary, `explained: true` and a
//! held-out RMS after fitting within 1.25 x its noise floor; where the truth names
//! effects `outside_vocabulary`, `explained: false`. Tracker outliers only where
//! planted, plus at most 2% of the rows.

mod common;

use common::{print_trials, recording};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_diagnosis::{diagnose, split, Options};
use ctr_formats::RobotSpec;

fn check(id: &str) {
    let (spec, rec, truth) = recording(id);
    let d = diagnose(&ModelSpec::from_spec(&spec), &rec, &Options::default()).unwrap();
    let r = &d.report;
    let found: Vec<&str> = r.established().map(|f| f.effect.as_str()).collect();
    let expected: Vec<&str> = truth["expected_findings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    let floor = truth["noise_floor_rms_mm"].as_f64().unwrap();
    eprintln!(
        "{id}: found {found:?} (expected {expected:?}); baseline {:.3}/{:.3} -> final {:.3}/{:.3} held out, floor {floor:.3}, noise est {:.3}",
        r.baseline.rms_mm, r.baseline.heldout_rms_mm, r.final_.rms_mm, r.final_.heldout_rms_mm, r.noise.rms_mm
    );
    print_trials(r);
    for f in &r.findings {
        eprintln!("   {} | {} | {}", f.explanation, f.where_, f.parameters);
    }
    eprintln!("   {}", r.unexplained);
    assert_eq!(found, expected, "{id}");
    // the public recordings stay far from a snap: no row marked, nothing said
    assert!(
        r.stability.nominal.is_empty() && r.stability.fitted.is_empty(),
        "{id}: {:?}",
        r.stability
    );
    let outside = truth
        .get("outside_vocabulary")
        .and_then(|v| v.as_object())
        .is_some_and(|o| !o.is_empty());
    assert_eq!(r.explained, !outside, "{id}: explained");
    if !outside {
        assert_eq!(r.findings.len(), found.len(), "{id}: predictive findings");
    }
    if !outside {
        assert!(r.final_.heldout_rms_mm <= 1.25 * floor, "{id}");
        assert!(
            r.empirical.is_none() && d.empirical.is_none(),
            "{id}: no empirical term"
        );
    } else {
        // the empirical term (the learned discrepancy), written as [model.discrepancy]
        // and read back as a robot file does, gives the report's figures when the
        // recording is simulated with it
        let emp = r
            .empirical
            .as_ref()
            .expect("an empirical term when not explained");
        let text = d.fitted_spec_with_empirical(&spec).to_toml();
        let back = RobotSpec::from_toml_str(&text, "fitted.toml").unwrap();
        assert!(
            back.discrepancy.is_some(),
            "{id}: [model.discrepancy] written"
        );
        let all: Vec<usize> = (0..rec.runs.len()).collect();
        let p = predict(&ModelSpec::from_spec(&back), &rec, &all).unwrap().p;
        let (held, _) = split(&rec, &Options::default().holdout).unwrap();
        let (mut fit_sse, mut fit_n, mut held_sse, mut held_n) = (0.0, 0, 0.0, 0);
        for (k, row) in rec.rows.iter().enumerate() {
            let e2: f64 = (0..3).map(|a| (p[k][a] - row.p[a]).powi(2)).sum();
            if held[k] {
                held_sse += e2;
                held_n += 1;
            } else {
                fit_sse += e2;
                fit_n += 1;
            }
        }
        let (fit_rms, held_rms) = (
            (fit_sse / fit_n as f64).sqrt(),
            (held_sse / held_n as f64).sqrt(),
        );
        eprintln!(
            "   with [model.empirical]: {fit_rms:.6}/{held_rms:.6} (report {:.6}/{:.6})",
            emp.rms_mm, emp.heldout_rms_mm
        );
        assert!(
            (fit_rms - emp.rms_mm).abs() < 1e-6 && (held_rms - emp.heldout_rms_mm).abs() < 1e-6,
            "{id}"
        );
        assert!(
            emp.heldout_rms_mm < r.final_.heldout_rms_mm,
            "{id}: the term helps on held-out rows"
        );
    }
    let planted: Vec<usize> = truth["noise"]["outlier_rows"]
        .as_array()
        .map(|a| a.iter().map(|v| v.as_u64().unwrap() as usize).collect())
        .unwrap_or_default();
    let extra = r
        .outlier_lines
        .iter()
        .filter(|line| !planted.iter().any(|&row| rec.rows[row].line == **line))
        .count();
    eprintln!(
        "   outliers: {} flagged, {} planted, {extra} not planted",
        r.outlier_lines.len(),
        planted.len()
    );
    assert!(
        extra as f64 <= MAX_FALSE_OUTLIER_SHARE * rec.rows.len() as f64,
        "{id}: {extra} rows flagged as outliers that were not planted"
    );
}

/// Largest share of rows without a planted outlier that may be flagged as outliers.
const MAX_FALSE_OUTLIER_SHARE: f64 = 0.02;

#[test]
fn dev_unexplained_feed_gain() {
    check("dev-unexplained-feed-gain");
}

#[test]
fn dev_unexplained_drift() {
    check("dev-unexplained-drift");
}

#[test]
fn dev_clean() {
    check("dev-clean");
}

#[test]
fn dev_clearance() {
    check("dev-clearance");
}

#[test]
fn dev_friction() {
    check("dev-friction");
}

#[test]
fn dev_gravity() {
    check("dev-gravity");
}

#[test]
fn dev_latency() {
    check("dev-latency");
}

#[test]
fn dev_registration() {
    check("dev-registration");
}

/// Where two effects explain the same residual equally, the report says so instead of
/// naming one alone: on a one-tube robot turned about its own axis, a registration's
/// rotation about that axis and the tube's rotation offset move the tip alike.
#[test]
fn equal_explanations_are_said() {
    use ctr_diagnosis::synth::{record, CommandedRun, SynthSpec};
    use ctr_formats::Registration;
    let spec = RobotSpec::from_toml_str(
        "[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\nlength_mm = 200.0\n\
         curved_length_mm = 80.0\ncurvature_radius_mm = 100.0\nyoungs_modulus_mpa = 58000.0\n\
         poisson_ratio = 0.33\n",
        "one.toml",
    )
    .unwrap();
    let user = ModelSpec::from_spec(&spec);
    let mut world = user.clone();
    world.effects.registration = Some(Registration::from_rotation_vector(
        [0.0, 0.0, 4.0],
        [0.0, 0.0, 0.0],
    ));
    let turn: Vec<Vec<f64>> = (0..240)
        .map(|i| vec![120.0 + 10.0 * f64::from(i / 60), 6.0 * f64::from(i % 60)])
        .collect();
    let feed: Vec<Vec<f64>> = (0..160)
        .map(|i| vec![100.0 + 1.0 * f64::from(i % 40), 90.0 * f64::from(i / 40)])
        .collect();
    let runs = [
        CommandedRun {
            label: "turn".into(),
            joints: turn,
        },
        CommandedRun {
            label: "feed".into(),
            joints: feed,
        },
    ];
    let synth = SynthSpec {
        noise_sigma_mm: 0.2,
        seed: 5,
        ..SynthSpec::default()
    };
    let rec = record(&world, &runs, &synth).unwrap().recording;
    let d = diagnose(&user, &rec, &Options::default()).unwrap();
    let r = &d.report;
    print_trials(r);
    let summary = r.summary("one.csv");
    eprintln!("{summary}");
    // one finding, and the report says which other effect does as well: the world's
    // registration or the rotation offset, whichever the search took first
    assert_eq!(r.findings.len(), 1, "{summary}");
    let f = &r.findings[0];
    let mut named: Vec<&str> = std::iter::once(f.effect.as_str())
        .chain(f.equally_explained_by.iter().map(|a| a.effect.as_str()))
        .collect();
    named.sort_unstable();
    assert!(
        named.contains(&"registration") && named.contains(&"joint_offset"),
        "{named:?}"
    );
    assert!(summary.contains("  equally: "), "{summary}");
    let json = serde_json::to_value(r).unwrap();
    assert!(
        json["findings"][0]["equally_explained_by"]
            .as_array()
            .is_some_and(|a| !a.is_empty()),
        "{json}"
    );
    let page = ctr_diagnosis::Page::new(r, &rec, &spec, &d.fitted_spec(&spec))
        .unwrap()
        .to_html()
        .unwrap();
    assert!(page.contains("<p class=\"equally\">Equally: "));
}

//! Helpers shared by the tests of ctr-diagnosis: the shared data (ctr-analysis's test
//! set-up), the report's trials printed for a failing case, the public recordings and
//! their truth in the report's form, and intervals held against a truth (`coverage`).
#![allow(dead_code)]

use ctr_diagnosis::Report;

pub mod angular;
pub mod coverage;

#[path = "../../../ctr-analysis/tests/common/mod.rs"]
mod analysis;
pub use analysis::*;

/// Every candidate the diagnosis fitted, round by round, on stderr.
pub fn print_trials(r: &Report) {
    for t in &r.tried {
        eprintln!(
            "   round {} {:>13}: fit {:.4} held {:.4} bic {:>9.1} {}{}",
            t.round,
            t.effect.as_str(),
            t.rms_mm,
            t.heldout_rms_mm,
            t.bic_change,
            if t.added { "ADDED " } else { "" },
            t.note
        );
    }
}

/// A public recording's truth (`world.effects` of its truth file, in the contract's
/// names) in the report's form of `effect`, or `None` for an effect it does not name.
pub fn public_truth(
    world: &serde_json::Value,
    effect: &str,
    n: usize,
) -> Option<serde_json::Value> {
    use serde_json::json;
    let e = world.get(effect)?;
    Some(match effect {
        "clearance" => json!({
            "max_deflection_deg": vec![e["delta_max_deg"].clone(); n - 1],
            "peak_deg": vec![e["phi0_deg"].clone(); n - 1],
        }),
        "friction" => json!({
            "rotation_play_deg": vec![e["rotation_play_half_width_deg"].clone(); n - 1],
            "feed_play_mm": vec![0.0; n],
        }),
        "registration" => {
            let mut r = e.clone();
            let a: Vec<f64> = serde_json::from_value(e["rotation_axis"].clone()).unwrap();
            let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            r["rotation_axis"] = json!(a.iter().map(|v| v / norm).collect::<Vec<_>>());
            r
        }
        _ => e.clone(),
    })
}

/// The ids of the public recordings (`<id>.truth.json` in the shared data), sorted.
pub fn public_ids() -> Vec<String> {
    let mut ids: Vec<String> = std::fs::read_dir(shared().join("recordings"))
        .unwrap()
        .filter_map(|e| {
            let name = e.ok()?.file_name().into_string().ok()?;
            Some(name.strip_suffix(".truth.json")?.to_owned())
        })
        .collect();
    ids.sort();
    ids
}

//! Helpers shared by the tests of ctr-diagnosis: the shared data (ctr-analysis's test
//! set-up) and the report's trials printed for a failing case.
#![allow(dead_code)]

use ctr_diagnosis::Report;

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

//! The second answer of a diagnosis: the best predictive model.
//!
//! The checks ([`crate::verify`]) keep only the findings whose form the data establish;
//! the others are taken out, and on a real robot, where almost every constant parameter
//! fits a little better when it may vary with something, that throws away physics that
//! predicts. So the model the search ended with, every finding in it, is the predictive
//! model; the findings the checks took out stay in it, graded **predictive**, where
//! they help prediction: the fitted model without one (the others as fitted, or
//! refitted) does worse on the held-out rows by at least [`MIN_HELDOUT_GAIN`]. That is
//! the gain the search asks of every effect to enter and to keep its place in the
//! revisit, where the information criterion too has accepted it; one rule, so that a
//! finding the search kept is not dropped here on a stricter test whose verdict a
//! re-framing of the data can flip (a paired test at its threshold: on the real
//! recording a friction 16 % better held out fell on either side of it when only
//! the rows' rounding changed). Those that do not help are dropped and the rest
//! refitted together. The established findings are exactly those the checks keep: a
//! predictive finding never makes one.

use crate::candidates::EffectId;
use crate::found::{simulate, Found};
use crate::report::Grade;
use crate::report::REMOVED;
use crate::scored::Scored;
use crate::search::MIN_HELDOUT_GAIN;
use crate::start::Start;
use crate::verify::Removed;

/// The predictive model: `searched` (the search's model) with `removed` (the findings
/// the checks took out of it, leaving `established`) graded predictive where they help
/// prediction; `established` itself when the checks took nothing out or nothing of it
/// helps. Whether it is `established`.
pub(crate) fn readmit(
    start: &Start,
    searched: Found,
    established: Found,
    removed: Vec<Removed>,
) -> (Found, bool) {
    let helping: Vec<(&Removed, Help)> = removed
        .iter()
        .filter_map(|r| Some((r, helps(start, &searched, r.finding.effect)?)))
        .collect();
    if helping.is_empty() {
        return (established, true);
    }
    let searched_findings = searched.findings.len();
    let mut found = Found {
        tried: established.tried.clone(),
        ..searched
    };
    for r in &removed {
        let Some(&(_, help)) = helping
            .iter()
            .find(|(h, _)| h.finding.effect == r.finding.effect)
        else {
            found.findings.retain(|f| f.effect != r.finding.effect);
            continue;
        };
        if let Some(f) = found
            .findings
            .iter_mut()
            .find(|f| f.effect == r.finding.effect)
        {
            f.grade = Grade::Predictive;
            f.grade_reason = format!(
                "{}, but its form is not established: {}; it may stand in for something \
                 outside the vocabulary",
                help.words(),
                r.why
            );
            mark_kept(&mut found.tried, r.finding.effect);
        }
    }
    for f in found.findings.iter_mut() {
        if let Some(e) = established.findings.iter().find(|e| e.effect == f.effect) {
            f.grade = e.grade;
            f.grade_reason = e.grade_reason.clone();
            f.empirical_heldout_rms_mm = e.empirical_heldout_rms_mm;
        }
    }
    if found.findings.len() < searched_findings {
        found.refit(start);
    }
    (found, false)
}

/// How a removed finding helps the predictive model.
#[derive(Clone, Copy, Debug)]
enum Help {
    /// Without it the held-out rows do worse by at least [`MIN_HELDOUT_GAIN`].
    Predicts,
    /// Without it the model (the others as fitted) cannot be simulated.
    HoldsUp,
}

impl Help {
    /// Why it is kept, in words.
    fn words(self) -> &'static str {
        match self {
            Help::Predicts => {
                "it helps prediction (without it the fitted model does worse on the \
                 held-out rows by at least the gain the search asks of every effect)"
            }
            Help::HoldsUp => {
                "it is kept for prediction (without it the other findings, as fitted, \
                 cannot be simulated)"
            }
        }
    }
}

/// How `c` helps `found`'s prediction, if it does: without it the held-out rows do
/// worse, the others as fitted, or else refitted (what dropping it would leave: an
/// effect that helps the fit rows but not the held-out ones, taken out, has the
/// others take its place on the fit rows, and they may predict worse for it).
fn helps(start: &Start, found: &Found, c: EffectId) -> Option<Help> {
    let mut without = found.clone();
    without.findings.retain(|f| f.effect != c);
    c.remove(&mut without.model);
    let Some(e) = simulate(start, &without.model) else {
        return Some(Help::HoldsUp);
    };
    let scored = Scored::from(&found.e, &start.held);
    let worse_without = |e: &[crate::residual::RowError]| {
        scored.score(start.rec, &found.e) < (1.0 - MIN_HELDOUT_GAIN) * scored.score(start.rec, e)
    };
    if worse_without(&e) {
        return Some(Help::Predicts);
    }
    (without.refit(start) && worse_without(&without.e)).then_some(Help::Predicts)
}

/// The trial that took `c` out now says it is kept as predictive.
fn mark_kept(tried: &mut [crate::report::Trial], c: EffectId) {
    if let Some(t) = tried
        .iter_mut()
        .rev()
        .find(|t| t.effect == c && t.note.starts_with(REMOVED))
    {
        t.note = format!(
            "kept as predictive, not established: {}",
            &t.note[REMOVED.len()..]
        );
    }
}

//! The search (the method's step 4): forward selection over the effects the model leaves out. Each round
//! every remaining candidate is screened (fitted alone beside the effects found so far,
//! [`crate::search::screen`]), then the most promising are fitted in full with the effects
//! found so far free, and of those the information criterion and the held-out rows
//! both accept, the best on the held-out rows is added.
//!
//! Each round ([`round`]) ends with the best candidate that both tests accept, or with
//! none. The pick is added, every effect found is refitted together (a first effect
//! that soaked up part of another gives it back), and the finding records where it
//! shows: the change it makes to the predictions, located. Candidates that explain the
//! same residual as well are listed beside it ([`Alternative`]).

pub(crate) mod round;
pub(crate) mod screen;

use crate::candidates::EffectId;
use crate::error::DiagnoseError;
use crate::fit::MAX_FIT_ITERATIONS;
use crate::found::{simulate, Found};
use crate::locate;
use crate::paired::clearly_lower;
use crate::report::prose::{explain, parameters};
use crate::report::Grade;
use crate::report::{Alternative, Finding};
use crate::residual::{tips, RowError};
use crate::start::Start;
use ctr_analysis::model::ModelSpec;
use round::{Outcome, Passing};

/// Smallest relative drop of the held-out RMS for an effect to be added.
pub const MIN_HELDOUT_GAIN: f64 = 0.02;

/// Forward selection over `candidates` from the user's model of `start`: round after
/// round the best candidate both tests accept is added and every effect found
/// refitted together, until no candidate passes.
pub(crate) fn forward_selection(
    start: &Start,
    candidates: &[EffectId],
) -> Result<Found, DiagnoseError> {
    let mut found = Found::user(start)
        .ok_or_else(|| DiagnoseError::Model("the user model fails on the fit rows".into()))?;
    let mut number = 1;
    loop {
        let mut outcome = round::run(start, &found, number, candidates);
        found.tried.append(&mut outcome.not_applicable);
        let Some(best) = outcome.best().cloned() else {
            found.tried.extend(outcome.trials);
            return Ok(found);
        };
        add(start, &mut found, best, outcome);
        number += 1;
    }
}

/// Adds the round's pick `best` to `found`: its trial marked added, those of the
/// candidates that explain the same residual as well marked so, every effect found
/// refitted together, and the finding with where it shows.
fn add(start: &Start, found: &mut Found, best: Passing, outcome: Outcome) {
    let c = best.effect;
    let equally = equally(&best, &outcome.passing, &start.held);
    for mut t in outcome.trials {
        if t.effect == c {
            t.added = true;
        } else if equally.iter().any(|a| a.effect == t.effect) {
            t.note = "not added: it explains the same residual as well as the candidate \
                      added (the data do not tell them apart)"
                .into();
        } else if t.note.is_empty() {
            t.note = "another candidate explained more".into();
        }
        found.tried.push(t);
    }
    let effects: Vec<EffectId> = found.effects().into_iter().chain([c]).collect();
    let (m, cost, e) = refit_together(start, &effects, best);
    // where: the change the effect makes to the predictions
    let change: Vec<[f64; 3]> = e
        .iter()
        .zip(&found.e)
        .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
        .collect();
    let all_mask = vec![true; start.rec.rows.len()];
    let where_ = locate::summary(&locate::locate(
        start.rec,
        &change,
        &all_mask,
        &tips(start.rec, &e),
    ));
    let before = found.fig;
    found.findings.push(Finding {
        effect: c,
        // graded by the checks (`crate::verify::settle`)
        grade: Grade::Established,
        grade_reason: String::new(),
        explanation: explain(c, &m),
        where_,
        parameters: parameters(c, &m),
        rms_mm_before: before.rms_mm,
        rms_mm_after: f64::NAN,
        heldout_rms_mm_before: before.heldout_rms_mm,
        heldout_rms_mm_after: f64::NAN,
        heldout_rms_deg: None,
        empirical_heldout_rms_mm: f64::NAN,
        ci95: serde_json::Value::Null,
        equally_explained_by: equally,
    });
    found.take(start, m, e);
    found.cost = cost;
    if let Some(f) = found.findings.last_mut() {
        f.rms_mm_after = found.fig.rms_mm;
        f.heldout_rms_mm_after = found.fig.heldout_rms_mm;
    }
}

/// `effects` (the last being `best`'s) refitted together from `best`'s fit, on the
/// user's model: the model, its robust cost and its error vectors; `best`'s own when
/// the joint fit does not lower the cost.
fn refit_together(
    start: &Start,
    effects: &[EffectId],
    best: Passing,
) -> (ModelSpec, f64, Vec<RowError>) {
    let mut joint_base = start.user.clone();
    let x0: Vec<f64> = effects.iter().flat_map(|b| b.read(&best.model)).collect();
    if let EffectId::Torsion = best.effect {
        joint_base.model = ctr_core::Model::Torsion;
    }
    let p = start.problem(joint_base, effects.to_vec());
    if let Some(f) = p
        .fit(&x0, MAX_FIT_ITERATIONS)
        .filter(|f| f.cost < best.cost)
    {
        let m = p.model(&f.x);
        if let Some(e) = simulate(start, &m) {
            return (m, f.cost, e);
        }
    }
    (best.model, best.cost, best.e)
}

/// The candidates of `passing` other than `best` that explain the residual as well:
/// held out within [`MIN_HELDOUT_GAIN`] of it (the gain the search asks of any effect)
/// and not higher beyond chance ([`clearly_lower`]).
fn equally(best: &Passing, passing: &[Passing], held: &[bool]) -> Vec<Alternative> {
    passing
        .iter()
        .filter(|p| {
            p.effect != best.effect
                && p.fig.heldout_score() * (1.0 - MIN_HELDOUT_GAIN) <= best.fig.heldout_score()
                && !clearly_lower(&best.e, &p.e, held)
        })
        .map(|p| Alternative {
            effect: p.effect,
            heldout_rms_mm: p.fig.heldout_rms_mm,
        })
        .collect()
}

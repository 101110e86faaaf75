//! The search (the method's step 4): forward selection over the effects the model leaves
//! out. The tracker's frame comes first, and no candidate: it is in the model from the
//! start and solved in every fit ([`frame`]). Each round every remaining candidate is
//! screened (fitted alone beside the effects found so far, [`crate::search::screen`]),
//! then the most promising are fitted in full with the effects found so far free, and
//! of those the information criterion and the held-out rows both accept, the best on the
//! held-out rows is added (the held-out rows a glitch of the model so far would decide
//! set aside, [`crate::scored`]).
//!
//! Each round ([`round`]) ends with the best candidate that both tests accept, or with
//! none. The pick is added, every effect found is refitted together (a first effect
//! that soaked up part of another gives it back), and the finding records where it
//! shows: the change it makes to the predictions, located. Candidates that explain the
//! same residual as well are listed beside it ([`Alternative`]). Where none passes
//! both tests, the one the information criterion likes best goes in for a look-ahead
//! ([`LOOK_AHEAD_ROUNDS`]): two effects may pay where each alone does not; it is kept
//! only if the model the look-ahead leads to pays over where it began. When nothing
//! enters, the effects found are revisited ([`backward`]): each must still pay its way
//! against the model without it, refitted. Where candidates are left out then, a second
//! path starts from that end with all of them added and revisits ([`together`]):
//! effects that pay only together (which one at a time never adds) are not lost to the
//! order the first path took, and the criteria choose between the two ends.

pub(crate) mod backward;
pub(crate) mod frame;
pub(crate) mod round;
pub(crate) mod screen;
pub(crate) mod together;

use crate::candidates::EffectId;
use crate::error::DiagnoseError;
use crate::fit::MAX_FIT_ITERATIONS;
use crate::found::{simulate, Found};
use crate::locate;
use crate::paired::clearly_lower;
use crate::report::prose::{explain, parameters};
use crate::report::Grade;
use crate::report::{Alternative, Finding};
use crate::residual::{components, tips, RowError};
use crate::scored::Scored;
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
    if frame::profiled(&start.user, candidates) {
        frame::enter(start, &mut found, candidates);
    }
    let mut number = 1;
    // where a look-ahead began, and the rounds it has taken
    let mut ahead: Option<(Found, usize)> = None;
    loop {
        let mut outcome = round::run(start, &found, number, candidates);
        found.tried.append(&mut outcome.not_applicable);
        number += 1;
        if let Some(best) = outcome.best().cloned() {
            add(start, &mut found, best, outcome);
            if let Some((from, taken)) = ahead.take() {
                if !pays_over(start, &found, &from) {
                    ahead = Some((from, taken + 1));
                }
            }
        } else if let Some(pick) = outcome
            .best_ahead()
            .cloned()
            .filter(|_| ahead.as_ref().map_or(0, |a| a.1) < LOOK_AHEAD_ROUNDS)
        {
            // no candidate gains on the held-out rows alone: the one the criterion
            // likes best goes in for a look-ahead (two effects may pay where each
            // alone does not), kept only if the model it leads to pays
            let (from, taken) = ahead.take().unwrap_or_else(|| (found.clone(), 0));
            add(start, &mut found, pick, outcome);
            ahead = Some((from, taken + 1));
        } else {
            found.tried.extend(outcome.trials);
            if let Some((from, _)) = ahead.take() {
                found = looked_ahead(found, from);
            }
            return Ok(ended(start, found, number, candidates));
        }
        if ahead.as_ref().is_some_and(|a| a.1 > LOOK_AHEAD_ROUNDS) {
            let (from, _) = ahead.take().expect("a look-ahead");
            found = looked_ahead(found, from);
            return Ok(ended(start, found, number, candidates));
        }
    }
}

/// The search's end from `found`, where no candidate enters after round `number`: the
/// effects found revisited ([`backward`]), then the second path ([`together`]).
fn ended(start: &Start, mut found: Found, number: usize, candidates: &[EffectId]) -> Found {
    backward::revisit(start, &mut found, number);
    together::second_path(start, found, number + 1, candidates)
}

/// Rounds a look-ahead may add effects that do not pay alone before the model it
/// leads to must pay over where it began.
const LOOK_AHEAD_ROUNDS: usize = 2;

/// Whether `now` pays over `from` (the model where a look-ahead began) as one effect
/// must to enter: the information criterion on the fit rows and the held-out gain.
fn pays_over(start: &Start, now: &Found, from: &Found) -> bool {
    let n_obs = (components(start.rec) * start.fit_rows.len()) as f64;
    let n = start.user.robot.n_tubes();
    let k: usize = now
        .effects()
        .iter()
        .filter(|c| !from.has(**c))
        .map(|c| c.n_params(n))
        .sum();
    let bic = n_obs * (now.cost / from.cost).ln() + k as f64 * n_obs.ln();
    let scored = Scored::from(&from.e, &start.held);
    bic < 0.0
        && scored.score(start.rec, &now.e)
            < (1.0 - MIN_HELDOUT_GAIN) * scored.score(start.rec, &from.e)
}

/// The model a look-ahead began at (`from`), with the trials `ended` went through
/// and those it added said to be tried ahead.
fn looked_ahead(ended: Found, mut from: Found) -> Found {
    let kept = from.effects();
    from.tried = ended.tried;
    for t in from
        .tried
        .iter_mut()
        .filter(|t| t.added && !kept.contains(&t.effect))
    {
        t.added = false;
        t.note = "not kept: added for a look-ahead (the information criterion accepts it, the \
                  held-out rows alone do not), and the model it led to did not pay over where \
                  the look-ahead began"
            .into();
    }
    from
}

/// Adds the round's pick `best` to `found`: its trial marked added, those of the
/// candidates that explain the same residual as well marked so, every effect found
/// refitted together, and the finding with where it shows.
fn add(start: &Start, found: &mut Found, best: Passing, outcome: Outcome) {
    let c = best.effect;
    let equally = equally(
        &best,
        &outcome.passing,
        &Scored::from(&found.e, &start.held),
    );
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
    let f = finding(start, found, c, &m, &e, equally);
    found.findings.push(f);
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

/// The finding of `c` entering `found` as the model `m` (error vectors `e`): where it
/// shows (the change it makes to the predictions, located) and `found`'s figures as
/// its figures before; its figures after are left to the caller (`NaN`), its grade to
/// the checks (`crate::verify::settle`).
pub(crate) fn finding(
    start: &Start,
    found: &Found,
    c: EffectId,
    m: &ModelSpec,
    e: &[RowError],
    equally_explained_by: Vec<Alternative>,
) -> Finding {
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
        &tips(start.rec, e),
    ));
    let before = found.fig;
    Finding {
        effect: c,
        grade: Grade::Established,
        grade_reason: String::new(),
        explanation: explain(c, m),
        where_,
        parameters: parameters(c, m),
        rms_mm_before: before.rms_mm,
        rms_mm_after: f64::NAN,
        heldout_rms_mm_before: before.heldout_rms_mm,
        heldout_rms_mm_after: f64::NAN,
        heldout_rms_deg: None,
        empirical_heldout_rms_mm: f64::NAN,
        ci95: serde_json::Value::Null,
        equally_explained_by,
    }
}

/// The candidates of `passing` other than `best` that explain the residual as well:
/// held out within [`MIN_HELDOUT_GAIN`] of it (the gain the search asks of any effect)
/// and not higher beyond chance ([`clearly_lower`]).
pub(crate) fn equally(best: &Passing, passing: &[Passing], scored: &Scored) -> Vec<Alternative> {
    passing
        .iter()
        .filter(|p| {
            p.effect != best.effect
                && p.score * (1.0 - MIN_HELDOUT_GAIN) <= best.score
                && !clearly_lower(&best.e, &p.e, scored.mask())
        })
        .map(|p| Alternative {
            effect: p.effect,
            heldout_rms_mm: p.fig.heldout_rms_mm,
        })
        .collect()
}

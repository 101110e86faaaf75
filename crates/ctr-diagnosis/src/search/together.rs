//! The search's second path: every candidate forward selection left out, fitted
//! together with the effects it found, then revisited ([`super::backward`]).
//!
//! Forward selection adds one effect at a time, so effects that pay only together (on
//! the real three-tube recording a stiffness, a sensor offset and the joint offsets:
//! each alone trades with the precurvature already found) enter or not depending on
//! the path: the order the rows or the frame happen to favour. Backward elimination
//! from the model with everything does not have that blind spot: it takes out one
//! effect at a time from a model where the groups are already together. So where the
//! forward path ends with candidates left out, the second path starts from its end with
//! all of them added (each from its screen beside the effects found, as a round would
//! start it), fits them all together and revisits. Of the two ends, the model is the
//! one the information criterion prefers, where the held-out rows do not say the other
//! is better beyond chance ([`crate::paired::clearly_lower`]): the same two tests every
//! effect passes to enter, applied to the two paths' ends.

use super::{backward, finding, round};
use crate::candidates::EffectId;
use crate::fit::MAX_FIT_ITERATIONS;
use crate::found::{simulate, Found};
use crate::paired::clearly_lower;
use crate::report::Trial;
use crate::residual::components;
use crate::scored::Scored;
use crate::search::screen::Screen;
use crate::start::{sample_period, Start};

/// What a candidate's trial of the second path says when it stays.
const ADDED: &str = "added by the search's second path: every candidate left fitted \
                     together with the effects found, then each effect revisited";

/// `found` (the forward path's end, revisited, round `round` next) or the second
/// path's end, whichever the criteria prefer (module doc), with the trials of both.
pub(crate) fn second_path(
    start: &Start,
    found: Found,
    round: usize,
    candidates: &[EffectId],
) -> Found {
    let Some(mut other) = all_in(start, &found, round, candidates) else {
        return found;
    };
    backward::revisit(start, &mut other, round + 1);
    let same = {
        let (mut a, mut b) = (found.effects(), other.effects());
        a.sort_by_key(|c| c.as_str());
        b.sort_by_key(|c| c.as_str());
        a == b
    };
    if !same && prefers(start, &other, &found) {
        return other;
    }
    let mut found = found;
    let ended: Vec<&str> = other.effects().iter().map(|c| c.as_str()).collect();
    for c in round::left(start, &found, round, candidates).0 {
        found.tried.push(Trial {
            round,
            effect: c,
            rms_mm: other.fig.rms_mm,
            heldout_rms_mm: other.fig.heldout_rms_mm,
            bic_change: f64::NAN,
            added: false,
            note: format!(
                "not added: the search's second path (every candidate left fitted together \
                 with the effects found, then revisited) ended at [{}], which the criteria \
                 do not prefer",
                ended.join(", ")
            ),
        });
    }
    found
}

/// Whether `b` is preferred to `a` (two ends of the search): a lower information
/// criterion on the fit rows, and `a` not lower on the held-out rows beyond chance.
fn prefers(start: &Start, b: &Found, a: &Found) -> bool {
    let n_obs = (components(start.rec) * start.fit_rows.len()) as f64;
    let n = start.user.robot.n_tubes();
    let k = |f: &Found| -> f64 { f.effects().iter().map(|c| c.n_params(n) as f64).sum() };
    let bic = n_obs * (b.cost / a.cost).ln() + (k(b) - k(a)) * n_obs.ln();
    let scored = Scored::from(&a.e, &start.held);
    bic < 0.0 && !clearly_lower(&a.e, &b.e, scored.mask())
}

/// `found` with every candidate left (of `candidates`, round `round`) added, each from
/// its screen beside the effects found, all fitted together; `None` where none is left
/// or the fit fails.
fn all_in(start: &Start, found: &Found, round: usize, candidates: &[EffectId]) -> Option<Found> {
    let (todo, _) = round::left(start, found, round, candidates);
    // torsion changes the base model rather than adding parameters: the forward path
    // alone decides it
    let todo: Vec<EffectId> = todo
        .into_iter()
        .filter(|&c| c != EffectId::Torsion)
        .collect();
    if todo.is_empty() {
        return None;
    }
    let n = start.user.robot.n_tubes();
    let held = found.effects();
    let screen = Screen::beside(start, found);
    let screened = screen.fit_all(&todo, n, sample_period(start.rec), start.threads);
    let mut x0 = found.parameters_in(&found.model);
    for (c, s) in todo.iter().zip(&screened) {
        match s {
            Some(f) => x0.extend_from_slice(&f.x),
            None => x0.extend(c.read(&found.model)),
        }
    }
    let blocks: Vec<EffectId> = held.iter().chain(&todo).copied().collect();
    let p = start.problem(start.user.clone(), blocks);
    let fitted = p.fit(&x0, MAX_FIT_ITERATIONS)?;
    let m = p.model(&fitted.x);
    let e = simulate(start, &m)?;
    let mut other = found.clone();
    for &c in &todo {
        let f = finding(start, found, c, &m, &e, Vec::new());
        other.findings.push(f);
    }
    // the frame, where it is no finding, stays the last of the model's effects
    other.take(start, m, e);
    other.cost = fitted.cost;
    for f in other
        .findings
        .iter_mut()
        .filter(|f| todo.contains(&f.effect))
    {
        f.rms_mm_after = other.fig.rms_mm;
        f.heldout_rms_mm_after = other.fig.heldout_rms_mm;
    }
    for &c in &todo {
        other.tried.push(Trial {
            round,
            effect: c,
            rms_mm: other.fig.rms_mm,
            heldout_rms_mm: other.fig.heldout_rms_mm,
            bic_change: f64::NAN,
            added: true,
            note: ADDED.into(),
        });
    }
    Some(other)
}

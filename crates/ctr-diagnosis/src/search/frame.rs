//! The tracker's frame as a nuisance: in the model from the start, never searched.
//!
//! A registration (`p -> R p + t` of every measured tip, `R` of every measured angle)
//! says nothing of the robot; re-registering a tracker must not change the account of
//! it. So where the registration is a candidate (the user's model has none, and the
//! candidates hold it), it enters the model before the first round, solved in closed
//! form on the user's model ([`crate::measurement`]), and every fit after solves it
//! again at every point it tries (variable projection): no candidate is ever judged
//! against a frame held where another candidate left it, and the order effects enter
//! no longer depends on how the tracker was set up.
//!
//! When the search ends, the frame passes the tests every effect passes to enter, as
//! every effect found does again ([`super::backward`]): against the model without it,
//! refitted. Where it fails, it is taken out; where it passes, it is a finding like the
//! others, checked and graded by them (and never taken out by the checks: the others
//! are checked with it in place, `crate::verify::settle`).

use super::round::{self, Passing};
use crate::candidates::EffectId;
use crate::fit::MAX_FIT_ITERATIONS;
use crate::found::{simulate, Found};
use crate::report::Trial;
use crate::residual::{components, figures};
use crate::scored::Scored;
use crate::start::Start;
use ctr_analysis::model::ModelSpec;

/// What the frame's trial says when it enters.
const ENTERS: &str = "the tracker's frame: in the model from the start, solved in every \
                      fit (profiled), never searched";

/// Whether the frame is a nuisance of a diagnosis of the user's model `user`: the
/// registration is among the `candidates` and `user` has none (it applies to every
/// recording).
pub(crate) fn profiled(user: &ModelSpec, candidates: &[EffectId]) -> bool {
    let c = EffectId::Registration;
    candidates.contains(&c) && !c.present_in(user)
}

/// `found` (the user's model, nothing found yet) with the frame fitted on the fit
/// rows: the registration its first finding, of round 0, with the candidates that
/// explain as much of the user's error in its place (a first round of the search
/// without it, [`round::run`]: on a robot turned about its own axis, the outer tube's
/// rotation offset moves the tip as the frame's turn about that axis does). `found` as
/// it was where the frame cannot be fitted, or where one of those explains as much
/// for less (by the information criterion): then the registration stays a candidate
/// of the search, as any effect.
pub(crate) fn enter(start: &Start, found: &mut Found, candidates: &[EffectId]) {
    let c = EffectId::Registration;
    let p = start.problem(found.model.clone(), vec![c]);
    let Some(fitted) = p.fit(&c.read(&found.model), MAX_FIT_ITERATIONS) else {
        return;
    };
    let m = p.model(&fitted.x);
    let Some(e) = simulate(start, &m) else {
        return;
    };
    let others: Vec<EffectId> = candidates.iter().copied().filter(|&o| o != c).collect();
    let instead = round::run(start, found, 0, &others);
    let framed = Passing {
        effect: c,
        model: m.clone(),
        fig: figures(start.rec, &e, &start.held),
        score: f64::NAN,
        cost: fitted.cost,
        e: e.clone(),
    };
    let scored = Scored::from(&found.e, &start.held);
    let framed = Passing {
        score: scored.score(start.rec, &framed.e),
        ..framed
    };
    let equally = super::equally(&framed, &instead.passing, &scored);
    // an effect of the robot that explains the user's error for less than the frame
    // (the criterion's cost and parameters), beside which the frame would not pay, is
    // what the frame stood for: the account's, not the tracker's. Then the frame does
    // not enter and stays a candidate like the others (a robot turned about its own
    // axis, one sweep whose offset the frame can follow).
    if let Some(best) = cheapest_beside(start, found, &instead.passing, fitted.cost) {
        if !frame_pays_beside(start, &best) {
            return;
        }
    }
    let f = super::finding(start, found, c, &m, &e, equally);
    found.findings.push(f);
    found.take(start, m, e);
    found.cost = fitted.cost;
    found.frame_profiled = true;
    found.tried.push(Trial {
        round: 0,
        effect: c,
        rms_mm: found.fig.rms_mm,
        heldout_rms_mm: found.fig.heldout_rms_mm,
        bic_change: f64::NAN,
        added: true,
        note: ENTERS.into(),
    });
}

/// Of `passing` (candidates fitted alone on the user's model `found`), the one of least
/// information criterion, if it is below the frame's (robust cost `frame_cost`).
fn cheapest_beside(
    start: &Start,
    found: &Found,
    passing: &[Passing],
    frame_cost: f64,
) -> Option<Passing> {
    let n_obs = (components(start.rec) * start.fit_rows.len()) as f64;
    let n = start.user.robot.n_tubes();
    let criterion = |cost: f64, k: usize| n_obs * (cost / found.cost).ln() + k as f64 * n_obs.ln();
    let frame = criterion(frame_cost, EffectId::Registration.n_params(n));
    passing
        .iter()
        .map(|p| (criterion(p.cost, p.effect.n_params(n)), p))
        .filter(|(c, _)| *c < frame)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, p)| p.clone())
}

/// Whether the frame, fitted beside the candidate `p`, passes the tests an effect
/// passes to enter against `p` alone.
fn frame_pays_beside(start: &Start, p: &Passing) -> bool {
    let c = EffectId::Registration;
    let problem = start.problem(start.user.clone(), vec![p.effect, c]);
    let x0: Vec<f64> = p
        .effect
        .read(&p.model)
        .into_iter()
        .chain(c.read(&p.model))
        .collect();
    let Some(fitted) = problem.fit(&x0, MAX_FIT_ITERATIONS) else {
        return true;
    };
    let Some(e) = simulate(start, &problem.model(&fitted.x)) else {
        return true;
    };
    let n_obs = (components(start.rec) * start.fit_rows.len()) as f64;
    let k = c.n_params(start.user.robot.n_tubes()) as f64;
    let bic = n_obs * (fitted.cost / p.cost).ln() + k * n_obs.ln();
    let scored = Scored::from(&p.e, &start.held);
    bic < 0.0
        && scored.score(start.rec, &e)
            < (1.0 - super::MIN_HELDOUT_GAIN) * scored.score(start.rec, &p.e)
}

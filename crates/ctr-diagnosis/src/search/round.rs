//! One round of the search: every candidate left is screened ([`Screen`]) beside the
//! effects found so far, the most promising are fitted in full with those effects free,
//! and each is judged by the information criterion and the held-out rows. The best that
//! both accept is the round's pick; the others are its trials.

use super::MIN_HELDOUT_GAIN;
use crate::candidates::{not_applicable, EffectId};
use crate::fit::MAX_FIT_ITERATIONS;
use crate::found::{simulate, Found};
use crate::report::{Figures, Trial};
use crate::residual::{components, figures, RowError};
use crate::scored::Scored;
use crate::search::screen::{Screen, Screened, FULL_FITS};
use crate::start::{sample_period, Start};
use ctr_analysis::model::ModelSpec;

/// Why a candidate the information criterion accepts is not added.
pub(crate) const NO_HELDOUT_GAIN: &str = "not added: no gain on held-out rows";

/// Why a candidate has no figures.
const CANNOT_SIMULATE: &str = "the model cannot be simulated with this effect";

/// A candidate fitted in full and accepted by both tests.
#[derive(Clone, Debug)]
pub(crate) struct Passing {
    pub effect: EffectId,
    /// The model found so far with it, fitted.
    pub model: ModelSpec,
    pub fig: Figures,
    /// Its held-out score over the rows the round counts ([`Scored`]).
    pub score: f64,
    /// Robust cost on the fit rows, mm^2.
    pub cost: f64,
    /// Error vectors, every row.
    pub e: Vec<RowError>,
}

/// What a round found.
pub(crate) struct Outcome {
    /// Candidates that do not apply to this model or recording (listed in round 1).
    pub not_applicable: Vec<Trial>,
    /// The trials of the candidates fitted or screened, in the candidates' order.
    pub trials: Vec<Trial>,
    /// Every candidate both tests accept, in the order fitted.
    pub passing: Vec<Passing>,
    /// The candidates fitted in full that the information criterion accepts but the
    /// held-out rows do not (what a look-ahead may add, [`super`]), in the order fitted.
    pub ahead: Vec<Passing>,
}

impl Outcome {
    /// The candidate of lowest held-out score that both tests accept (the first of
    /// equals).
    pub(crate) fn best(&self) -> Option<&Passing> {
        lowest_heldout(&self.passing)
    }

    /// The candidate of lowest robust cost that the information criterion alone
    /// accepts (a look-ahead's pick).
    pub(crate) fn best_ahead(&self) -> Option<&Passing> {
        self.ahead
            .iter()
            .fold(None, |best: Option<&Passing>, p| match best {
                Some(b) if b.cost <= p.cost => Some(b),
                _ => Some(p),
            })
    }
}

/// The candidate of lowest held-out RMS of `passing` (the first of equals).
fn lowest_heldout(passing: &[Passing]) -> Option<&Passing> {
    passing
        .iter()
        .fold(None, |best: Option<&Passing>, p| match best {
            Some(b) if b.score <= p.score => Some(b),
            _ => Some(p),
        })
}

/// The trial of a candidate that was not fitted, and why.
pub(crate) fn not_fitted(round: usize, effect: EffectId, note: String) -> Trial {
    Trial {
        round,
        effect,
        rms_mm: f64::NAN,
        heldout_rms_mm: f64::NAN,
        bic_change: f64::NAN,
        added: false,
        note,
    }
}

/// Round `round` of the search from `found`, over `candidates`.
pub(crate) fn run(start: &Start, found: &Found, round: usize, candidates: &[EffectId]) -> Outcome {
    let (todo, not_applicable) = left(start, found, round, candidates);
    // the held-out rows every candidate of the round is judged on: a glitch of the
    // model found so far set aside for all alike
    let scored = Scored::from(&found.e, &start.held);
    let n = start.user.robot.n_tubes();
    // the screen: every candidate fitted from its starts on a sample of the fit rows
    // with the effects found so far held, side by side on the pool
    let screen = Screen::beside(start, found);
    let screened = screen.fit_all(&todo, n, sample_period(start.rec), start.threads);
    let ranked = screen.rank(&todo, &screened, start.threads);
    // which are fitted in full depends on the screen alone: they are fitted side by
    // side (the results do not depend on the threads)
    let mut on_screen = Vec::new();
    let mut to_fit = Vec::new();
    for r in &ranked {
        match screen_note(&screen, r, to_fit.len(), n) {
            Some(note) => on_screen.push((r, note)),
            None => to_fit.push(r),
        }
    }
    // each with every thread for its Jacobian's columns: the fits differ in cost (one
    // under gravity solves loaded rows), and a long one left alone keeps the cores
    // busy instead of one (measured: 9 % faster than splitting the threads)
    let fitted = ctr_formats::parallel::map(&to_fit, start.threads, |r| {
        full_fit(start, found, &scored, round, r)
    });
    let mut verdicts = Vec::new();
    let mut passing = Vec::new();
    let mut ahead = Vec::new();
    for (trial, pass) in fitted {
        match pass {
            Some((p, true)) => passing.push(p),
            Some((p, false)) => ahead.push(p),
            None => {}
        }
        verdicts.push(trial);
    }
    verdicts.extend(judged_on_screen(start, &screen, round, on_screen));
    // the trials in the candidates' order
    let trials = todo
        .iter()
        .map(|&c| match verdicts.iter().position(|t| t.effect == c) {
            Some(i) => verdicts.remove(i),
            None => not_fitted(round, c, CANNOT_SIMULATE.into()),
        })
        .collect();
    Outcome {
        not_applicable,
        trials,
        passing,
        ahead,
    }
}

/// The candidates left to try in `round` (neither in the user's model nor found), and
/// the trials of those that do not apply here (listed in round 1 only).
pub(crate) fn left(
    start: &Start,
    found: &Found,
    round: usize,
    candidates: &[EffectId],
) -> (Vec<EffectId>, Vec<Trial>) {
    let mut todo = Vec::new();
    let mut skipped = Vec::new();
    for &c in candidates {
        if c.present_in(&start.user) || found.has(c) {
            continue;
        }
        if let Some(note) = not_applicable(c, &found.model, start.rec) {
            if round == 1 {
                skipped.push(not_fitted(round, c, note));
            }
            continue;
        }
        todo.push(c);
    }
    (todo, skipped)
}

/// Why the screened candidate `r` is judged on its screen rather than fitted in full
/// (`full_fits` made so far this round), or `None` to fit it in full: only the
/// [`FULL_FITS`] best that the screen projects below the held model's cost are.
fn screen_note(screen: &Screen, r: &Screened, full_fits: usize, n: usize) -> Option<String> {
    if full_fits < FULL_FITS && r.projected < screen.cost0 {
        None
    } else if screen.bic(r.cost, r.effect.n_params(n)) >= 0.0 {
        Some(format!(
            "not added: the information criterion rejects it (fitted with the effects \
             found so far held, {})",
            screen.rows_in_words()
        ))
    } else {
        Some(format!(
            "not fitted in full: the screen ranked {FULL_FITS} candidates higher"
        ))
    }
}

/// Candidate `r` fitted in full from where its screen ended, with the effects found so
/// far free (a first effect that soaked up part of another must be able to give it
/// back), on every thread, and judged: its trial, and the candidate when the
/// information criterion accepts it, with whether the held-out rows do too.
fn full_fit(
    start: &Start,
    found: &Found,
    scored: &Scored,
    round: usize,
    r: &Screened,
) -> (Trial, Option<(Passing, bool)>) {
    let c = r.effect;
    let k = c.n_params(start.user.robot.n_tubes());
    let blocks: Vec<EffectId> = found.effects().into_iter().chain([c]).collect();
    let p = start.problem(found.model.clone(), blocks);
    let x: Vec<f64> = found
        .parameters_in(&found.model)
        .into_iter()
        .chain(r.x.iter().copied())
        .collect();
    let n_obs = (components(start.rec) * start.fit_rows.len()) as f64;
    // the cost the information criterion asks for: a fit that cannot reach it stops
    // early
    let bic_cost = found.cost * (-(k as f64) * n_obs.ln() / n_obs).exp();
    let fitted = p
        .fit_until(&x, MAX_FIT_ITERATIONS, Some(bic_cost))
        .and_then(|f| {
            let m = p.model(&f.x);
            let e = simulate(start, &m)?;
            Some((f, m, e))
        });
    let Some((fitted, m, e)) = fitted else {
        return (not_fitted(round, c, CANNOT_SIMULATE.into()), None);
    };
    let fig = figures(start.rec, &e, &start.held);
    let score = scored.score(start.rec, &e);
    let bic = n_obs * (fitted.cost / found.cost).ln() + k as f64 * n_obs.ln();
    let criterion = !fitted.gave_up && bic < 0.0;
    let note = if fitted.gave_up {
        "not added: the information criterion rejects it (its fit stopped where the gain \
         left, linearised, could not pay for its parameters)"
    } else if bic >= 0.0 {
        "not added: the information criterion rejects it"
    } else if score >= scored.score(start.rec, &found.e) * (1.0 - MIN_HELDOUT_GAIN) {
        NO_HELDOUT_GAIN
    } else {
        ""
    };
    let trial = Trial {
        round,
        effect: c,
        rms_mm: fig.rms_mm,
        heldout_rms_mm: fig.heldout_rms_mm,
        bic_change: bic,
        added: false,
        note: note.to_string(),
    };
    let both = note.is_empty();
    let pass = criterion.then_some((
        Passing {
            effect: c,
            model: m,
            fig,
            score,
            cost: fitted.cost,
            e,
        },
        both,
    ));
    (trial, pass)
}

/// The trials of the candidates judged on their screen: the model with its screened
/// parameters, simulated on every row (in parallel).
fn judged_on_screen(
    start: &Start,
    screen: &Screen,
    round: usize,
    on_screen: Vec<(&Screened, String)>,
) -> Vec<Trial> {
    let n = start.user.robot.n_tubes();
    let screen_errors = ctr_formats::parallel::map(&on_screen, start.threads, |(r, _)| {
        simulate(start, &screen.model(r.effect, &r.x))
    });
    on_screen
        .into_iter()
        .zip(screen_errors)
        .map(|((r, note), e)| {
            let Some(e) = e else {
                return not_fitted(round, r.effect, CANNOT_SIMULATE.into());
            };
            let fig = figures(start.rec, &e, &start.held);
            Trial {
                round,
                effect: r.effect,
                rms_mm: fig.rms_mm,
                heldout_rms_mm: fig.heldout_rms_mm,
                bic_change: screen.bic(r.cost, r.effect.n_params(n)),
                added: false,
                note,
            }
        })
        .collect()
}

//! The search: forward selection over the effects the model leaves out. Each round
//! every remaining candidate is screened (fitted alone beside the effects found so far,
//! [`crate::search::screen`]), then the most promising are fitted in full with the effects
//! found so far free, and of those the information criterion and the held-out rows
//! both accept, the best on the held-out rows is added.

pub(crate) mod screen;

use crate::candidates::{not_applicable, EffectId};
use crate::error::DiagnoseError;
use crate::fit::{Problem, MAX_FIT_ITERATIONS};
use crate::locate;
use crate::options::Options;
use crate::report::prose::{explain, parameters};
use crate::report::{Alternative, Diagnosis, Figures, Finding, Trial, REMOVED};
use crate::residual::{components, errors, figures, positions, tips, RowError};
use crate::search::screen::{Screen, Screened, FULL_FITS};
use crate::start::{sample_period, Start};
use crate::verify;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::{predict, predict_with_margins};
use ctr_formats::Recording;

/// Smallest relative drop of the held-out RMS for an effect to be added.
pub const MIN_HELDOUT_GAIN: f64 = 0.02;

/// Why a candidate has no figures.
const CANNOT_SIMULATE: &str = "the model cannot be simulated with this effect";

/// The candidate of a round that is added.
struct Best {
    effect: EffectId,
    model: ModelSpec,
    fig: Figures,
    cost: f64,
    e: Vec<RowError>,
}

/// The trial of a candidate that was not fitted, and why.
fn not_fitted(round: usize, effect: EffectId, note: String) -> Trial {
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

/// Diagnoses `model` against `rec`.
///
/// ```no_run
/// use ctr_diagnosis::{diagnose, Options};
/// use ctr_analysis::model::ModelSpec;
/// use ctr_formats::{Recording, RobotSpec};
/// use std::path::Path;
/// let spec = RobotSpec::from_path(Path::new("robot.toml"))?;
/// let rec = Recording::from_path(Path::new("rec.csv"), spec.robot.n_tubes())?;
/// let d = diagnose(&ModelSpec::from_spec(&spec), &rec, &Options::default())?;
/// for f in &d.report.findings {
///     println!("{}: {}", f.effect.as_str(), f.explanation);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn diagnose(
    model: &ModelSpec,
    rec: &Recording,
    opt: &Options,
) -> Result<Diagnosis, DiagnoseError> {
    // the angular columns weighted by their noise: the one residual of every step
    let (weighted, base) = crate::start::simulated(model, rec)?;
    let rec: &Recording = &weighted;
    let start = Start::new(model, rec, base, &opt.holdout, opt.threads, opt.warn_margin)?;
    let (held, all_runs, fit_rows) = (&start.held, &start.all_runs, &start.fit_rows);
    let (e0, baseline) = (&start.e0, start.baseline);
    let n = model.robot.n_tubes();
    let huber = start.huber_mm();
    let threads = ctr_formats::parallel::resolve_threads(opt.threads);
    let period = sample_period(rec);
    let n_obs = (components(rec) * fit_rows.len()) as f64;

    let mut current = model.clone();
    let mut current_fig = baseline;
    let mut current_e = e0.clone();
    let mut accepted: Vec<EffectId> = Vec::new();
    let mut findings = Vec::new();
    let mut tried = Vec::new();
    let problem = |base: ModelSpec, blocks: Vec<EffectId>| Problem {
        base,
        blocks,
        rec,
        rows: fit_rows.clone(),
        huber_mm: huber,
        threads,
        clearance_table: None,
    };
    let mut current_cost = problem(current.clone(), vec![])
        .cost_at(&[])
        .ok_or_else(|| DiagnoseError::Model("the user model fails on the fit rows".into()))?;
    for round in 1.. {
        let mut best: Option<Best> = None;
        let mut round_trials = Vec::new();
        let mut todo = Vec::new();
        for &c in &opt.candidates {
            if c.present_in(model) || accepted.contains(&c) {
                continue;
            }
            if let Some(note) = not_applicable(c, &current, rec) {
                if round == 1 {
                    tried.push(not_fitted(round, c, note));
                }
                continue;
            }
            todo.push(c);
        }
        // the screen: every (candidate, start) fitted on a sample of the fit rows with
        // the effects found so far held, each on its own thread of the pool
        let jobs: Vec<(EffectId, Vec<f64>)> = todo
            .iter()
            .flat_map(|&c| c.starts(n, period).into_iter().map(move |x0| (c, x0)))
            .collect();
        let screen = Screen::new(&current, &accepted, rec, fit_rows, huber, threads);
        let screened = ctr_formats::parallel::map(&jobs, threads, |(c, x0)| screen.fit(*c, x0));
        let ranked = screen.rank(&todo, &jobs, screened, threads);
        // the best of them fitted in full from where their screen ended, with the
        // effects found so far free (a first effect that soaked up part of another must
        // be able to give it back); one fit after the other, each Jacobian's columns on
        // the pool
        let held_x: Vec<f64> = accepted.iter().flat_map(|b| b.read(&current)).collect();
        let with = |c: EffectId| -> Vec<EffectId> { accepted.iter().copied().chain([c]).collect() };
        let mut verdicts: Vec<Trial> = Vec::new();
        // every candidate both tests accept, for what explains the residual equally
        let mut passing: Vec<(EffectId, f64, Vec<RowError>)> = Vec::new();
        let mut on_screen: Vec<(&Screened, String)> = Vec::new();
        let mut full_fits = 0;
        for r in &ranked {
            let c = r.effect;
            let k = c.n_params(n);
            let not_full = if full_fits < FULL_FITS && r.projected < screen.cost0 {
                None
            } else if screen.bic(r.cost, k) >= 0.0 {
                Some(format!(
                    "not added: the information criterion rejects it (fitted with the \
                     effects found so far held, {})",
                    screen.rows_in_words()
                ))
            } else {
                Some(format!(
                    "not fitted in full: the screen ranked {FULL_FITS} candidates higher"
                ))
            };
            if let Some(note) = not_full {
                on_screen.push((r, note));
                continue;
            }
            full_fits += 1;
            let p = problem(current.clone(), with(c));
            let x: Vec<f64> = held_x.iter().chain(&r.x).copied().collect();
            // the cost the information criterion asks for: a fit that cannot reach it
            // stops early
            let bic_cost = current_cost * (-(k as f64) * n_obs.ln() / n_obs).exp();
            let fitted = p
                .fit_until(&x, MAX_FIT_ITERATIONS, Some(bic_cost))
                .and_then(|f| {
                    let m = p.model(&f.x);
                    let pred = predict(&m, rec, all_runs).ok()?;
                    Some((f, m, errors(rec, &pred)))
                });
            let Some((fitted, m, e)) = fitted else {
                verdicts.push(not_fitted(round, c, CANNOT_SIMULATE.into()));
                continue;
            };
            let fig = figures(&e, held);
            let bic = n_obs * (fitted.cost / current_cost).ln() + k as f64 * n_obs.ln();
            let note = if fitted.gave_up {
                "not added: the information criterion rejects it (its fit stopped where \
                 the gain left, linearised, could not pay for its parameters)"
                    .to_string()
            } else if bic >= 0.0 {
                "not added: the information criterion rejects it".to_string()
            } else if fig.heldout_rms_mm >= current_fig.heldout_rms_mm * (1.0 - MIN_HELDOUT_GAIN) {
                "not added: no gain on held-out rows".to_string()
            } else {
                String::new()
            };
            let passes = note.is_empty();
            verdicts.push(Trial {
                round,
                effect: c,
                rms_mm: fig.rms_mm,
                heldout_rms_mm: fig.heldout_rms_mm,
                bic_change: bic,
                added: false,
                note,
            });
            if passes {
                passing.push((c, fig.heldout_rms_mm, e.clone()));
            }
            if passes
                && best
                    .as_ref()
                    .is_none_or(|b| fig.heldout_rms_mm < b.fig.heldout_rms_mm)
            {
                best = Some(Best {
                    effect: c,
                    model: m,
                    fig,
                    cost: fitted.cost,
                    e,
                });
            }
        }
        // the others judged on their screen: the model with its screened parameters
        let screen_errors = ctr_formats::parallel::map(&on_screen, threads, |(r, _)| {
            let pred = predict(&screen.model(r.effect, &r.x), rec, all_runs).ok()?;
            Some(errors(rec, &pred))
        });
        for ((r, note), e) in on_screen.into_iter().zip(screen_errors) {
            let Some(e) = e else {
                verdicts.push(not_fitted(round, r.effect, CANNOT_SIMULATE.into()));
                continue;
            };
            let fig = figures(&e, held);
            verdicts.push(Trial {
                round,
                effect: r.effect,
                rms_mm: fig.rms_mm,
                heldout_rms_mm: fig.heldout_rms_mm,
                bic_change: screen.bic(r.cost, r.effect.n_params(n)),
                added: false,
                note,
            });
        }
        // the trials in the candidates' order
        for &c in &todo {
            round_trials.push(match verdicts.iter().position(|t| t.effect == c) {
                Some(i) => verdicts.remove(i),
                None => not_fitted(round, c, CANNOT_SIMULATE.into()),
            });
        }
        let Some(Best {
            effect: c,
            model: m,
            fig,
            cost,
            e,
        }) = best
        else {
            tried.extend(round_trials);
            break;
        };
        let equally = equally(c, fig.heldout_rms_mm, &e, &passing, held);
        for t in &mut round_trials {
            if t.effect == c {
                t.added = true;
            } else if equally.iter().any(|a| a.effect == t.effect) {
                t.note = "not added: it explains the same residual as well as the candidate \
                          added (the data do not tell them apart)"
                    .into();
            } else if t.note.is_empty() {
                t.note = "another candidate explained more".into();
            }
        }
        tried.extend(round_trials);
        // refit everything found so far together
        accepted.push(c);
        let mut joint_base = model.clone();
        let x0: Vec<f64> = accepted.iter().flat_map(|b| b.read(&m)).collect();
        if let EffectId::Torsion = c {
            joint_base.model = ctr_core::Model::Torsion;
        }
        let p = problem(joint_base, accepted.clone());
        let (m, fig, cost, e) = match p.fit(&x0, MAX_FIT_ITERATIONS) {
            Some(f) if f.cost < cost => {
                let mj = p.model(&f.x);
                match predict(&mj, rec, all_runs) {
                    Ok(pred) => {
                        let ej = errors(rec, &pred);
                        (mj, figures(&ej, held), f.cost, ej)
                    }
                    Err(_) => (m, fig, cost, e),
                }
            }
            _ => (m, fig, cost, e),
        };
        // where: the change the effect makes to the predictions
        let change: Vec<[f64; 3]> = e
            .iter()
            .zip(&current_e)
            .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
            .collect();
        let tips = tips(rec, &e);
        let all_mask = vec![true; rec.rows.len()];
        let where_ = locate::summary(&locate::locate(rec, &change, &all_mask, &tips));
        findings.push(Finding {
            effect: c,
            explanation: explain(c, &m),
            where_,
            parameters: parameters(c, &m),
            rms_mm_before: current_fig.rms_mm,
            rms_mm_after: fig.rms_mm,
            heldout_rms_mm_before: current_fig.heldout_rms_mm,
            heldout_rms_mm_after: fig.heldout_rms_mm,
            empirical_heldout_rms_mm: f64::NAN,
            ci95: serde_json::Value::Null,
            equally_explained_by: equally,
        });
        // the earlier findings' parameters moved in the joint refit
        for f in &mut findings {
            f.parameters = parameters(f.effect, &m);
            f.explanation = explain(f.effect, &m);
        }
        current = m;
        current_fig = fig;
        current_cost = cost;
        current_e = e;
    }
    // every finding checked with the others in place; those that fail are taken out
    // and the rest refitted together, until all pass
    let ctx = verify::Context::new(rec, held, huber, threads, start.noise.rms_mm, opt.checks);
    let last_round = tried.iter().map(|t| t.round).max().unwrap_or(0) + 1;
    // the joint fit's assessment of check 3, when the loop ends on it: the report's
    let mut assessed = None;
    loop {
        let mut checks: Vec<verify::Checked> = accepted
            .iter()
            .map(|&c| ctx.check(&current, &current_e, c))
            .collect();
        for ch in &checks {
            if let Some(f) = findings.iter_mut().find(|f| f.effect == ch.effect) {
                f.empirical_heldout_rms_mm = ch.empirical_heldout_rms_mm;
            }
        }
        let mut assessment = None;
        if checks.iter().all(|c| c.failure.is_none()) && !accepted.is_empty() {
            // 3. identified: only once the other checks pass (it needs the joint fit's
            // covariance, and a finding taken out changes everyone's)
            let (failures, a) = ctx.identified(&current, model, &accepted, fit_rows);
            for (c, failure) in failures {
                if let Some(ch) = checks.iter_mut().find(|ch| ch.effect == c) {
                    ch.failure = Some(failure);
                }
            }
            assessment = a;
        }
        let failed: Vec<&verify::Checked> = checks.iter().filter(|c| c.failure.is_some()).collect();
        if failed.is_empty() {
            assessed = assessment;
            break;
        }
        for ch in &failed {
            tried.push(Trial {
                round: last_round,
                effect: ch.effect,
                rms_mm: current_fig.rms_mm,
                heldout_rms_mm: current_fig.heldout_rms_mm,
                bic_change: f64::NAN,
                added: false,
                note: removed_note(ch),
            });
        }
        accepted.retain(|c| failed.iter().all(|f| f.effect != *c));
        findings.retain(|f| accepted.contains(&f.effect));
        let x0: Vec<f64> = accepted.iter().flat_map(|b| b.read(&current)).collect();
        let p = problem(model.clone(), accepted.clone());
        let refit = if accepted.is_empty() {
            Some(model.clone())
        } else {
            p.fit(&x0, MAX_FIT_ITERATIONS).map(|f| p.model(&f.x))
        };
        let Some(m) = refit else { break };
        let Ok(pred) = predict(&m, rec, all_runs) else {
            break;
        };
        current_e = errors(rec, &pred);
        current_fig = figures(&current_e, held);
        for f in &mut findings {
            f.parameters = parameters(f.effect, &m);
            f.explanation = explain(f.effect, &m);
        }
        current = m;
    }
    // an alternative that is itself a finding is no alternative
    for f in &mut findings {
        f.equally_explained_by
            .retain(|a| !accepted.contains(&a.effect));
    }
    let final_pred = predict_with_margins(&current, rec, all_runs)
        .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
    Ok(start.finish(
        rec,
        current,
        findings,
        current_fig,
        &current_e,
        &final_pred.margin,
        tried,
        final_pred.failed,
        assessed,
        |fit_mask| {
            let statements = locate::locate(rec, &positions(&current_e), fit_mask, &final_pred.p);
            let mut out = locate::summary(&statements);
            if let Some(c) = statements
                .iter()
                .find(|s| s.kind != "run")
                .and_then(locate::causes)
            {
                out += &format!(". Outside the vocabulary, this pattern comes from {c}");
            }
            out
        },
    ))
}

/// The candidates of `passing` (effect, held-out RMS, errors) other than the one
/// added, `added` (held-out RMS `h`, errors `e`), that explain the residual as well: held
/// out within [`MIN_HELDOUT_GAIN`] of it (the gain the search asks of any effect) and not
/// higher beyond chance (`verify::clearly_lower`).
fn equally(
    added: EffectId,
    h: f64,
    e: &[RowError],
    passing: &[(EffectId, f64, Vec<RowError>)],
    held: &[bool],
) -> Vec<Alternative> {
    passing
        .iter()
        .filter(|(c, h_c, e_c)| {
            *c != added
                && h_c * (1.0 - MIN_HELDOUT_GAIN) <= h
                && !verify::clearly_lower(e, e_c, held)
        })
        .map(|(c, h_c, _)| Alternative {
            effect: *c,
            heldout_rms_mm: *h_c,
        })
        .collect()
}

/// Why a finding was taken out after the search, for its trial.
fn removed_note(ch: &verify::Checked) -> String {
    match &ch.failure {
        Some(verify::Failure::Empirical {
            heldout_rms_mm,
            tip: false,
        }) => format!(
            "{REMOVED}a generic empirical correction of as many parameters, \
             in its place, does as well on held-out rows ({heldout_rms_mm:.3} mm)"
        ),
        Some(verify::Failure::Empirical {
            heldout_rms_mm,
            tip: true,
        }) => format!(
            "{REMOVED}a generic empirical correction of as many parameters, in the \
             joints, time and the stretches and shears of the tip position, in its place, \
             explains the data as well ({heldout_rms_mm:.3} mm held out): the data cannot \
             tell it from an error outside the vocabulary such as a tracker's scale error"
        ),
        Some(verify::Failure::Varying {
            feature,
            constant_heldout_rms_mm,
            heldout_rms_mm,
        }) => format!(
            "{REMOVED}its parameters fit the data better proportional to \
             {feature} than constant ({heldout_rms_mm:.3} against {constant_heldout_rms_mm:.3} \
             mm held out, linearised): it stands in for a gain or drift outside the vocabulary"
        ),
        Some(verify::Failure::NotIdentified {
            statistic,
            threshold,
        }) => format!(
            "{REMOVED}with every finding fitted together, its parameters are not told \
             from the nominal (Wald statistic {statistic:.2} against the 95 % threshold \
             {threshold:.2}: the nominal lies inside their 95 % region)"
        ),
        None => String::new(),
    }
}

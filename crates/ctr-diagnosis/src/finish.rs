//! How a diagnosis and a calibration finish (the method's steps 6 to 8): the verdict on
//! what the fitted model leaves ([`Verdict`]), the intervals of every finding and the
//! run to record next ([`crate::uncertainty`]), the rows near a snap, and the report.

use crate::candidates::EffectId;
use crate::fit::{Problem, MAX_FIT_ITERATIONS};
use crate::found::{simulate, Found};
use crate::grade;
use crate::locate;
use crate::report::Grade;
use crate::report::{Diagnosis, Figures, Finding, Report, Split};
use crate::residual::{figures, positions, RowError};
use crate::start::noise::outlier_rule;
use crate::start::{sample_period, Start};
use crate::uncertainty::{self, suggest, Assessment};
use crate::verdict::Verdict;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::Prediction;
use ctr_formats::Recording;

/// Where the report says what is left sits.
pub(crate) enum WhereLeft {
    /// Located on the fit rows, with what outside the vocabulary makes such a pattern.
    Located,
    /// In these words.
    Said(&'static str),
}

/// The run the report suggests recording next for `findings` of `problem` (none
/// without an assessment), and its joints.
fn next_run(
    start: &Start,
    problem: &Problem,
    assessment: Option<Assessment>,
    findings: &[Finding],
) -> (
    Option<crate::report::SuggestedRun>,
    Option<crate::report::JointRun>,
) {
    let rec = start.rec;
    let fit_share = start.fit_rows.len() as f64 / rec.rows.len().max(1) as f64;
    let named: Vec<EffectId> = findings.iter().map(|f| f.effect).collect();
    assessment
        .and_then(|a| suggest::next_run(problem, &a, &named, fit_share, sample_period(rec)))
        .unzip()
}

/// `findings` graded by their intervals and bounds at `fitted` (`problem`'s model) and
/// by the lab's tolerances, as the checks of `start` say.
fn graded(
    start: &Start,
    findings: &mut [Finding],
    problem: &Problem,
    fitted: &ModelSpec,
    assessment: Option<&Assessment>,
) {
    if start.checks.present {
        grade::by_evidence(findings, problem, fitted, assessment);
    }
    if start.checks.within_tolerance {
        crate::tolerance::by_tolerance(findings);
    }
}

/// The report of `found`, `pred` its prediction of every run with stability margins.
/// `assessed`: the uncertainty of exactly these findings on the fit rows, when the
/// checks computed it (not computed again).
pub(crate) fn finish(
    start: Start,
    found: Found,
    pred: &Prediction,
    assessed: Option<Assessment>,
    where_left: WhereLeft,
) -> Diagnosis {
    let rec = start.rec;
    let mut found = found;
    without_each(&start, &mut found);
    let predictive: Vec<_> = found
        .findings
        .iter()
        .filter(|f| f.grade == Grade::Predictive)
        .map(|f| f.effect)
        .collect();
    let verdict = Verdict::new(&start, &found.model, &found.e, &pred.margin, &predictive);
    // every effect in the model (the tracker's frame too, where it is no finding)
    let effects = found.effects();
    let Found {
        model,
        mut findings,
        fig,
        tried,
        e,
        ..
    } = found;
    // intervals at the fitted model; what the data cannot pin set to the nominal; an
    // unexplained remainder widens them by what it can move them by
    let problem = uncertainty::attach::problem_of(
        rec,
        &model,
        &effects,
        &start.fit_rows,
        start.huber_mm(),
        start.threads,
    );
    let (fitted, overall, assessment) = uncertainty::attach::attach(
        &problem,
        &start.user,
        &mut findings,
        assessed,
        (!verdict.explained).then_some(&verdict.correction),
    );
    graded(
        &start,
        &mut findings,
        &problem,
        &fitted,
        assessment.as_ref(),
    );
    let established = established_alone(&start, &problem, &fitted, &findings);
    // a finding its intervals lowered to predictive no longer explains anything
    let mut verdict = verdict;
    verdict.lean_on(
        findings
            .iter()
            .filter(|f| f.grade == Grade::Predictive)
            .map(|f| f.effect),
    );
    let (suggested_run, suggested_joints) = next_run(&start, &problem, assessment, &findings);
    let unexplained = verdict.in_words(&start, &fig, || match where_left {
        WhereLeft::Located => located_left(rec, &e, &start.fit_mask(), &pred.p),
        WhereLeft::Said(words) => words.into(),
    });
    Diagnosis {
        report: Report {
            baseline: start.baseline,
            findings,
            final_: fig,
            explained: verdict.explained,
            unexplained,
            empirical: (!verdict.explained).then_some(verdict.empirical),
            sessions: crate::sessions::disagreeing(rec, &verdict.noise),
            noise: verdict.noise,
            split: Split {
                method: start.split_method,
                fit_rows: start.fit_rows.len(),
                heldout_rows: rec.rows.len() - start.fit_rows.len(),
            },
            located: start.located,
            tried,
            failed_rows: pred.failed,
            outlier_lines: verdict.outliers.iter().map(|&r| rec.rows[r].line).collect(),
            outlier_rule: outlier_rule(rec),
            outlier_threshold_mm: verdict.outlier_threshold_mm,
            final_inliers: verdict.inliers,
            uncertainty_method: overall.method,
            identifiability: overall.identifiability,
            correlated: overall.correlated,
            suggested_run,
            stability: verdict.stability,
        },
        fitted,
        established,
        empirical: (!verdict.explained).then_some(verdict.correction),
        discrepancy: verdict.discrepancy,
        suggested_joints,
    }
}

/// The model of the established findings alone: the user's model with them, refitted
/// on the fit rows from their values in `fitted` without the predictive findings
/// (whose values the others leaned on: a sensor offset fitted beside a feed offset of
/// 8 mm does not predict without it). `fitted` itself when every finding is
/// established; the predictive ones merely taken out when the refit fails.
fn established_alone(
    start: &Start,
    problem: &Problem,
    fitted: &ModelSpec,
    findings: &[Finding],
) -> ModelSpec {
    let of = |g: Grade| -> Vec<EffectId> {
        findings
            .iter()
            .filter(|f| f.grade == g)
            .map(|f| f.effect)
            .collect()
    };
    let predictive = of(Grade::Predictive);
    if predictive.is_empty() {
        return fitted.clone();
    }
    let mut m = fitted.clone();
    for c in &predictive {
        c.remove(&mut m);
    }
    let kept = of(Grade::Established);
    if kept.is_empty() {
        return m;
    }
    let mut p = start.problem(start.user.clone(), kept);
    p.clearance_table = problem.clearance_table;
    let x0 = p.read(&m);
    match p.fit(&x0, MAX_FIT_ITERATIONS) {
        Some(f) => p.model(&f.x),
        None => m,
    }
}

/// Where the error vectors `e` sit on the fit rows (`fit`), `tips` the modelled tips,
/// and what outside the vocabulary makes the strongest pattern that is not a run.
fn located_left(rec: &Recording, e: &[RowError], fit: &[bool], tips: &[[f64; 3]]) -> String {
    let statements = locate::locate(rec, &positions(e), fit, tips);
    let mut out = locate::summary(&statements);
    if let Some(c) = statements
        .iter()
        .find(|s| s.kind != "run")
        .and_then(locate::causes)
    {
        out += &format!(". Outside the vocabulary, this pattern comes from {c}");
    }
    out
}

/// Each finding's figures before and after it on one basis, the final model's: before
/// is the final model without it (the others as fitted), after the final model; what
/// the fitted model loses without each.
fn without_each(start: &Start, found: &mut Found) {
    let without: Vec<ModelSpec> = found
        .findings
        .iter()
        .map(|f| {
            let mut m = found.model.clone();
            f.effect.remove(&mut m);
            m
        })
        .collect();
    let errors = ctr_formats::parallel::map(&without, start.threads, |m| simulate(start, m));
    let after = found.fig;
    for (f, e) in found.findings.iter_mut().zip(errors) {
        let before = e.map_or(UNKNOWN, |e| figures(start.rec, &e, &start.held));
        f.rms_mm_before = before.rms_mm;
        f.rms_mm_after = after.rms_mm;
        f.heldout_rms_mm_before = before.heldout_rms_mm;
        f.heldout_rms_mm_after = after.heldout_rms_mm;
        f.heldout_rms_deg = before
            .angular
            .zip(after.angular)
            .map(|(a, b)| [a.heldout_rms_deg, b.heldout_rms_deg]);
    }
}

/// The figures of a model that cannot be simulated.
const UNKNOWN: Figures = Figures {
    rms_mm: f64::NAN,
    max_mm: f64::NAN,
    heldout_rms_mm: f64::NAN,
    angular: None,
};

//! What a diagnosis and a calibration both start from: the split, the user model's
//! error on it, the noise estimate and where the error sits; and how both finish: the
//! report of the fitted model.

pub(crate) mod angular;
pub(crate) mod noise;
pub(crate) mod split;
pub(crate) mod weighting;

use crate::empirical::hybrid;
use crate::error::DiagnoseError;
use crate::locate::stability::{checked_warn_margin, Stability};
use crate::locate::{self, Statement};
use crate::report::prose::leftover;
use crate::report::{Diagnosis, Figures, Finding, Noise, Report, Split, Trial};
use crate::residual::{errors, figures, inlier_figures, positions, RowError};
use crate::start::noise::{estimate_noise, median, outlier_rows, outlier_rule, NOISE_TOLERANCE};
use crate::start::split::{split, Holdout};
use crate::uncertainty::suggest;
use crate::uncertainty::{self, Assessment};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::{predict_with_margins, Prediction};
use ctr_formats::Recording;
use std::borrow::Cow;

/// Huber threshold of the robust cost, in estimated noise standard deviations per
/// axis (a 3-D noise vector is below 4 sigma 99.9 % of the time).
const HUBER_SIGMAS: f64 = 4.0;

/// What a diagnosis and a calibration both start from: the split and the user model's
/// error on it.
pub(crate) struct Start {
    /// Whether each row is held out.
    pub(crate) held: Vec<bool>,
    /// The split, in words.
    pub(crate) split_method: String,
    /// Every run (all are simulated, whatever is held out).
    pub(crate) all_runs: Vec<usize>,
    /// The rows fitted.
    pub(crate) fit_rows: Vec<usize>,
    /// The user model's error vectors, every row.
    pub(crate) e0: Vec<RowError>,
    /// The user model's figures.
    pub(crate) baseline: Figures,
    /// The noise estimated on the user model's error.
    pub(crate) noise: Noise,
    /// Where the user model's error sits.
    pub(crate) located: Vec<Statement>,
    /// The user's model (the nominal of every fitted parameter).
    pub(crate) user: ModelSpec,
    /// Worker threads (resolved).
    pub(crate) threads: usize,
    /// The user model's stability margin per row, along the recording.
    pub(crate) margin0: Vec<f64>,
    /// Rows whose margin is below this are near a snap.
    pub(crate) warn_margin: f64,
}

/// `model`'s prediction of every run of `rec`, and `rec` with its angular columns
/// weighted from it (`crate::start::weighting`): what [`Start::new`] starts from.
pub(crate) fn simulated<'a>(
    model: &ModelSpec,
    rec: &'a Recording,
) -> Result<(Cow<'a, Recording>, Prediction), DiagnoseError> {
    let all_runs: Vec<usize> = (0..rec.runs.len()).collect();
    let base = predict_with_margins(model, rec, &all_runs)
        .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
    Ok((weighting::weighted(rec, &base), base))
}

impl Start {
    /// The split of `rec` by `holdout` and `model`'s error on it, `base` its prediction
    /// of every run ([`simulated`]).
    pub(crate) fn new(
        model: &ModelSpec,
        rec: &Recording,
        base: Prediction,
        holdout: &Holdout,
        threads: usize,
        warn_margin: f64,
    ) -> Result<Self, DiagnoseError> {
        let warn_margin = checked_warn_margin(warn_margin)
            .map_err(|m| DiagnoseError::Option(format!("warn_margin: {m}")))?;
        let (held, split_method) = split(rec, holdout)?;
        let all_runs: Vec<usize> = (0..rec.runs.len()).collect();
        let fit_rows: Vec<usize> = (0..rec.rows.len()).filter(|&r| !held[r]).collect();
        let e0 = errors(rec, &base);
        let fit_mask: Vec<bool> = held.iter().map(|h| !h).collect();
        Ok(Start {
            baseline: figures(&e0, &held),
            noise: estimate_noise(rec, &positions(&e0)),
            located: locate::locate(rec, &positions(&e0), &fit_mask, &base.p),
            held,
            split_method,
            all_runs,
            fit_rows,
            e0,
            user: model.clone(),
            threads: ctr_formats::parallel::resolve_threads(threads),
            margin0: base.margin,
            warn_margin,
        })
    }

    /// Huber threshold of the fits, mm (none without a noise estimate).
    pub(crate) fn huber_mm(&self) -> f64 {
        let sigma = self.noise.sigma_mm_per_axis;
        if sigma.is_finite() && sigma > 0.0 {
            HUBER_SIGMAS * sigma
        } else {
            f64::INFINITY
        }
    }

    /// The report of the model `fitted`, whose error vectors are `e` and stability margins
    /// `margin` (per row, from the same simulation): the noise estimated again on what it
    /// leaves (closer to white), tracker outliers set aside, the rows near a snap, and
    /// what is left in words (`where_left` says where, given the fit rows' mask).
    /// `assessed`: the uncertainty of exactly these findings of `fitted` on the fit
    /// rows, when the search's last check computed it (not computed again).
    pub(crate) fn finish(
        self,
        rec: &Recording,
        fitted: ModelSpec,
        mut findings: Vec<Finding>,
        final_: Figures,
        e: &[RowError],
        margin: &[f64],
        tried: Vec<Trial>,
        failed_rows: usize,
        assessed: Option<Assessment>,
        where_left: impl FnOnce(&[bool]) -> String,
    ) -> Diagnosis {
        let huber_mm = self.huber_mm();
        // intervals at the fitted model; what the data cannot pin set to the nominal
        let effects: Vec<_> = findings.iter().map(|f| f.effect).collect();
        let problem = uncertainty::problem_of(
            rec,
            &fitted,
            &effects,
            &self.fit_rows,
            huber_mm,
            self.threads,
        );
        let again = estimate_noise(rec, &positions(e));
        let noise = if again.sigma_mm_per_axis < self.noise.sigma_mm_per_axis
            || !self.noise.sigma_mm_per_axis.is_finite()
        {
            again
        } else {
            self.noise
        };
        // outliers judged on what is left after the physics and the empirical term: a
        // structured residual is spread, not outlying
        let (empirical, correction, left) = hybrid::fit(rec, e, &self.held, huber_mm);
        let (outliers, outlier_threshold_mm) = outlier_rows(rec, &left);
        let stability = Stability::new(rec, self.warn_margin, &self.margin0, margin, &outliers);
        let inliers = inlier_figures(e, &self.held, &outliers);
        let explained = inliers.heldout_rms_mm <= NOISE_TOLERANCE * noise.rms_mm;
        // an unexplained remainder widens the intervals by what it can move them by
        let (fitted, overall, assessment) = uncertainty::attach(
            &problem,
            &self.user,
            &mut findings,
            assessed,
            (!explained).then_some(&correction),
        );
        let fit_share = self.fit_rows.len() as f64 / rec.rows.len().max(1) as f64;
        let next =
            assessment.and_then(|a| suggest::next_run(&problem, &a, fit_share, sample_period(rec)));
        let (suggested_run, suggested_joints) = next.unzip();
        let fit_mask: Vec<bool> = self.held.iter().map(|h| !h).collect();
        let unexplained = leftover(
            rec,
            &final_,
            &inliers,
            &outliers,
            &stability.outlier_lines_near_snap,
            outlier_threshold_mm,
            &noise,
            explained,
            || where_left(&fit_mask),
        );
        Diagnosis {
            report: Report {
                baseline: self.baseline,
                findings,
                final_,
                explained,
                unexplained,
                empirical: (!explained).then_some(empirical),
                noise,
                split: Split {
                    method: self.split_method,
                    fit_rows: self.fit_rows.len(),
                    heldout_rows: rec.rows.len() - self.fit_rows.len(),
                },
                located: self.located,
                tried,
                failed_rows,
                outlier_lines: outliers.iter().map(|&r| rec.rows[r].line).collect(),
                outlier_rule: outlier_rule(),
                outlier_threshold_mm,
                final_inliers: inliers,
                uncertainty_method: overall.method,
                identifiability: overall.identifiability,
                correlated: overall.correlated,
                suggested_run,
                stability,
            },
            fitted,
            empirical: (!explained).then_some(correction),
            suggested_joints,
        }
    }
}

/// Median time step between a run's rows (s).
pub(crate) fn sample_period(rec: &Recording) -> f64 {
    let mut dt: Vec<f64> = rec
        .runs
        .iter()
        .flat_map(|r| {
            let rows = &rec.rows[r.rows.clone()];
            rows.windows(2)
                .map(|w| w[1].t_s - w[0].t_s)
                .filter(|d| *d > 0.0)
                .collect::<Vec<_>>()
        })
        .collect();
    if dt.is_empty() {
        f64::NAN
    } else {
        median(&mut dt)
    }
}

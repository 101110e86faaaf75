//! What a diagnosis and a calibration both start from (the method's steps 1 to 3):
//! the recording's angular columns weighted by their noise, the split, the user
//! model's error on it, the noise estimate and where the error sits.

pub(crate) mod angular;
pub(crate) mod noise;
pub(crate) mod split;
pub(crate) mod weighting;

use crate::candidates::EffectId;
use crate::error::DiagnoseError;
use crate::fit::Problem;
use crate::locate::stability::checked_warn_margin;
use crate::locate::{self, Statement};
use crate::options::{Checks, Options};
use crate::report::{Figures, Noise};
use crate::residual::{errors, figures, positions, RowError};
use crate::start::noise::{estimate_noise, median};
use crate::start::split::split;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::{predict_with_margins, Prediction};
use ctr_formats::Recording;
use std::borrow::Cow;

/// Huber threshold of the robust cost, in estimated noise standard deviations per
/// axis (a 3-D noise vector is below 4 sigma 99.9 % of the time).
const HUBER_SIGMAS: f64 = 4.0;

/// What a diagnosis and a calibration both start from: the recording, the split and
/// the user model's error on it.
pub(crate) struct Start<'a> {
    /// The recording, its angular columns weighted ([`simulated`]).
    pub(crate) rec: &'a Recording,
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
    /// The acceptance checks that run (the grades' too).
    pub(crate) checks: Checks,
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

impl<'a> Start<'a> {
    /// The split of `rec` by `opt.holdout` and `model`'s error on it, `base` its
    /// prediction of every run ([`simulated`]).
    pub(crate) fn new(
        model: &ModelSpec,
        rec: &'a Recording,
        base: Prediction,
        opt: &Options,
    ) -> Result<Self, DiagnoseError> {
        let warn_margin = checked_warn_margin(opt.warn_margin)
            .map_err(|m| DiagnoseError::Option(format!("warn_margin: {m}")))?;
        let (held, split_method) = split(rec, &opt.holdout)?;
        let all_runs: Vec<usize> = (0..rec.runs.len()).collect();
        let fit_rows: Vec<usize> = (0..rec.rows.len()).filter(|&r| !held[r]).collect();
        let e0 = errors(rec, &base);
        let fit_mask: Vec<bool> = held.iter().map(|h| !h).collect();
        Ok(Start {
            rec,
            baseline: figures(rec, &e0, &held),
            noise: estimate_noise(rec, &positions(&e0)),
            located: locate::locate(rec, &positions(&e0), &fit_mask, &base.p),
            held,
            split_method,
            all_runs,
            fit_rows,
            e0,
            user: model.clone(),
            threads: ctr_formats::parallel::resolve_threads(opt.threads),
            margin0: base.margin,
            warn_margin,
            checks: opt.checks,
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

    /// The fit of `blocks`' parameters added to `base` on the fit rows.
    pub(crate) fn problem(&self, base: ModelSpec, blocks: Vec<EffectId>) -> Problem<'a> {
        Problem {
            base,
            blocks,
            rec: self.rec,
            rows: self.fit_rows.clone(),
            huber_mm: self.huber_mm(),
            threads: self.threads,
            clearance_table: None,
        }
    }

    /// Whether each row is fitted.
    pub(crate) fn fit_mask(&self) -> Vec<bool> {
        self.held.iter().map(|h| !h).collect()
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

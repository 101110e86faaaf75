//! What a diagnosis and a calibration both start from (the method's steps 1 to 3):
//! the recording's angular columns weighted by their noise, the split, the user
//! model's error on it, the noise estimate and where the error sits.

pub(crate) mod angular;
pub(crate) mod noise;
pub(crate) mod repeats;
pub(crate) mod split;
pub(crate) mod weighting;

use crate::candidates::EffectId;
use crate::error::DiagnoseError;
use crate::fit::Problem;
use crate::locate::stability::checked_warn_margin;
use crate::locate::{self, Statement};
use crate::measurement::{self, Free, Measurement, Tips};
use crate::options::{Checks, Options};
use crate::report::{Figures, Noise};
use crate::residual::{errors, figures, positions, RowError};
use crate::start::noise::{estimate_noise, median};
use crate::start::split::split;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::{predict, predict_with_margins_on, Prediction};
use ctr_formats::Recording;
use nalgebra::Rotation3;
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
/// weighted from it (`crate::start::weighting`): what [`Start::new`] starts from. With
/// `framed`, the tracker's frame is fitted first (least squares of the tip positions,
/// closed form: [`crate::measurement`]) and the weights (and the noise, [`Start::new`])
/// are taken on the model's error in it, the third value: the same whatever frame the
/// tracker was registered in. The runs are simulated on `threads` workers (0: every
/// core; the same prediction at any count).
pub(crate) fn simulated<'a>(
    model: &ModelSpec,
    rec: &'a Recording,
    framed: bool,
    threads: usize,
) -> Result<(Cow<'a, Recording>, Prediction, Option<Seen>), DiagnoseError> {
    let all_runs: Vec<usize> = (0..rec.runs.len()).collect();
    let cannot = |e| DiagnoseError::Model(format!("the model cannot be simulated: {e}"));
    let threads = ctr_formats::parallel::resolve_threads(threads);
    let base = predict_with_margins_on(model, rec, &all_runs, threads).map_err(cannot)?;
    let seen = if framed {
        in_its_frame(model, rec, &base)
    } else {
        None
    };
    let weighted = weighting::weighted(rec, seen.as_ref().map_or(&base, |s| &s.pred));
    Ok((weighted, base, seen))
}

/// A user model's prediction in the tracker's frame fitted to it ([`simulated`]).
pub(crate) struct Seen {
    /// The prediction of every run, in the fitted frame.
    pred: Prediction,
    /// The fitted frame's rotation (the tracker's frame from the model's W).
    turn: Rotation3<f64>,
}

impl Seen {
    /// The position errors of the prediction on `rec`'s rows, turned back into the
    /// model's W (so that a noise estimate per axis is the same in any frame).
    fn errors_in_w(&self, rec: &Recording) -> Vec<[f64; 3]> {
        let back = self.turn.inverse();
        positions(&errors(rec, &self.pred))
            .into_iter()
            .map(|v| (back * nalgebra::Vector3::from(v)).into())
            .collect()
    }
}

/// `base` (`model`'s prediction of every row of `rec`) with the tracker's frame fitted
/// to the positions by least squares (`None` where it cannot be).
fn in_its_frame(model: &ModelSpec, rec: &Recording, base: &Prediction) -> Option<Seen> {
    let all_rows: Vec<usize> = (0..rec.rows.len()).collect();
    let all_runs: Vec<usize> = (0..rec.runs.len()).collect();
    let bare = predict(&measurement::without(model), rec, &all_runs).ok()?;
    let mut positions = rec.clone();
    positions.angular = None;
    let tips = Tips::new(&positions, &all_rows, &bare, f64::INFINITY)?;
    let free = Free {
        registration: Some(0),
        ..Free::default()
    };
    let (m, _) = measurement::profile(&tips, Measurement::of(model), &free);
    let mut pred = tips.measured(&m, &bare);
    pred.margin.clone_from(&base.margin);
    Some(Seen {
        pred,
        turn: m.turn(),
    })
}

impl<'a> Start<'a> {
    /// The split of `rec` by `opt.holdout` and `model`'s error on it, `base` its
    /// prediction of every run and `seen` the same in the tracker's frame fitted, if it
    /// was ([`simulated`]): the noise is estimated on that one.
    pub(crate) fn new(
        model: &ModelSpec,
        rec: &'a Recording,
        base: Prediction,
        seen: Option<Seen>,
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
            noise: estimate_noise(
                rec,
                &seen.map_or_else(|| positions(&e0), |s| s.errors_in_w(rec)),
            ),
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

//! The report: the types a diagnosis returns (written as the mismatch report JSON of
//! `docs/formats.md`) and its plain-language summary.

mod fitted;
mod grade;
pub(crate) mod html;
pub(crate) mod numbers;
pub(crate) mod plots;
pub(crate) mod prose;
mod summary;

use crate::candidates::EffectId;
use crate::locate::stability::{MarginRange, Stability};
use crate::locate::Statement;
use ctr_analysis::model::ModelSpec;
use ctr_formats::{Correction, Discrepancy};
pub use fitted::fitted_file;
pub use grade::Grade;
use serde::Serialize;

/// Error figures of a model on a recording: of the tip positions in mm, and of the tip
/// angles in degrees beside them when the recording has angular columns.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Figures {
    /// RMS tip position error over the fit rows, mm.
    pub rms_mm: f64,
    /// Largest tip position error over the fit rows, mm.
    pub max_mm: f64,
    /// RMS tip position error over the held-out rows, mm.
    pub heldout_rms_mm: f64,
    /// The tip angles' figures and the weighted whole's (only for a recording whose
    /// angular columns enter the residual; written beside the keys above).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub angular: Option<AngularFigures>,
}

/// The angular part of [`Figures`]: the tip angle's error (the small rotation from the
/// measured to the predicted orientation or tangent) in degrees, and the whole row's
/// error as the fits weigh it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AngularFigures {
    /// RMS tip angle error over the fit rows, degrees.
    pub rms_deg: f64,
    /// Largest tip angle error over the fit rows, degrees.
    pub max_deg: f64,
    /// RMS tip angle error over the held-out rows, degrees.
    pub heldout_rms_deg: f64,
    /// RMS over the fit rows of the whole weighted error, the fits' cost basis: the
    /// position in mm and the angles at `noise.angular.mm_per_deg`, mm-equivalent (not a
    /// distance a tracker measures).
    pub weighted_rms_mm_eq: f64,
    /// The same over the held-out rows: what the search and the checks compare.
    pub weighted_heldout_rms_mm_eq: f64,
}

impl Noise {
    /// What the held-out RMS is compared with: [`Figures::heldout_score`]'s basis.
    pub(crate) fn weighted_rms(&self) -> f64 {
        self.weighted_rms
    }
}

impl Figures {
    /// The held-out RMS the search, the checks and the verdict decide on: the weighted
    /// whole's with angular columns, the positions' without.
    pub(crate) fn heldout_score(&self) -> f64 {
        self.angular
            .map_or(self.heldout_rms_mm, |a| a.weighted_heldout_rms_mm_eq)
    }
}

/// One term of the empirical correction, as the report lists it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Term {
    /// The basis function (`t`, `s2`, `cos(theta1)`, `x`, ... standardised over the
    /// fit rows).
    pub feature: String,
    /// The tip coordinate it corrects (`x`, `y` or `z`).
    pub axis: String,
    /// What it adds to the modelled tip, mm per standard deviation of the feature
    /// (as `[model.empirical]` writes it).
    pub coefficient_mm: f64,
    /// RMS of its contribution over the rows, mm.
    pub rms_mm: f64,
}

/// An input of the learned discrepancy and its length scale.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GpInput {
    /// Its name (`s3`, `theta3 - theta2`, `play(theta3 - theta2, 2)`).
    pub input: String,
    /// Its length scale in standardised units: the shorter, the more the discrepancy
    /// changes with it (100: it does not matter).
    pub length_scale: f64,
}

/// The learned discrepancy's band: how sure it is, row by row.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Band {
    /// The median over the rows of a measurement's standard deviation about the
    /// corrected tip, mm per axis (the band is +/- 1.96 of it).
    pub median_sd_mm: f64,
    /// The discrepancy's prior standard deviation, mm.
    pub signal_mm: f64,
    /// The measurements' noise about it, mm.
    pub noise_mm: f64,
    /// Share of the held-out rows' coordinates inside their 95 % band.
    pub heldout_coverage_95: f64,
}

/// The empirical correction fitted on top of the physical model.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Empirical {
    /// What it is, in words.
    pub method: String,
    /// Number of terms chosen by cross-validation on the fit rows.
    pub terms: usize,
    /// RMS over the fit rows with the correction, mm.
    pub rms_mm: f64,
    /// RMS over the held-out rows with the correction, mm.
    pub heldout_rms_mm: f64,
    /// The largest terms by contribution, largest first (a linear correction's).
    pub dominant: Vec<Term>,
    /// A learned discrepancy's inputs, shortest length scale first.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<GpInput>,
    /// A learned discrepancy's band.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub band: Option<Band>,
}

/// One effect the diagnosis found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    /// The contract's id.
    pub effect: EffectId,
    /// How sure the report is of it (`crate::grade`): `established` physics the data
    /// show, or `predictive`: it helps prediction, its form is not established.
    pub grade: Grade,
    /// Why this grade, in words.
    pub grade_reason: String,
    /// What the model leaves out, in words, with the fitted values.
    pub explanation: String,
    /// Where the effect shows: the runs and the pattern of the error it removes.
    #[serde(rename = "where")]
    pub where_: String,
    /// The fitted parameters, as the robot file writes them.
    pub parameters: serde_json::Value,
    /// Fit-row RMS of the tip positions without it, mm: the final model with this effect
    /// taken out, the others as fitted (what the fitted model loses without it).
    pub rms_mm_before: f64,
    /// Fit-row RMS with it, mm: the final model's (`final.rms_mm`).
    pub rms_mm_after: f64,
    /// Held-out RMS without it, mm (as `rms_mm_before`).
    pub heldout_rms_mm_before: f64,
    /// Held-out RMS with it, mm: the final model's.
    pub heldout_rms_mm_after: f64,
    /// Held-out RMS of the tip angles without and with it, degrees (only with angular
    /// columns in the residual).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heldout_rms_deg: Option<[f64; 2]>,
    /// Held-out RMS of the tip positions of the final model with this effect replaced by
    /// the generic empirical correction of as many parameters, mm (NaN for torsion): the
    /// yardstick of its first check (see `verify`).
    pub empirical_heldout_rms_mm: f64,
    /// 95 % intervals of `parameters`: the same keys and shapes, each number replaced
    /// by `[lo, hi]` in its unit (`[null, null]` where the data set no bound); with
    /// `identified`, the combinations the data pin where the parameters alone are not
    /// (see `uncertainty_method`).
    pub ci95: serde_json::Value,
    /// Other effects that explained the same residual as well when this one was added
    /// (held out within [`MIN_HELDOUT_GAIN`](crate::MIN_HELDOUT_GAIN) of it and not
    /// lower beyond chance): the data do not tell them from this one, which the search
    /// named only because it came first. Empty when the choice was clear.
    pub equally_explained_by: Vec<Alternative>,
}

/// An effect that explains a finding's residual as well as the finding does.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Alternative {
    /// The contract's id.
    pub effect: EffectId,
    /// Held-out RMS of the tip positions with it in the finding's place (fitted with
    /// the findings before, when the finding was added), mm.
    pub heldout_rms_mm: f64,
}

/// Two parameters the data hardly tell apart.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Correlated {
    /// The first parameter, in words.
    pub a: String,
    /// The second.
    pub b: String,
    /// Their correlation in the fit, -1..1.
    pub r: f64,
}

/// A parameter's interval now and after the suggested run, as the fit expects it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ExpectedInterval {
    /// The parameter, in words (a factor, not its log).
    pub parameter: String,
    /// Its fitted value.
    pub value: f64,
    /// Its 95 % interval now (`[null, null]`: not identified).
    pub ci95_now: [Option<f64>; 2],
    /// Its 95 % interval expected once the run is recorded and diagnosed with the rest.
    pub ci95_expected: [Option<f64>; 2],
}

/// The run to record next, when the data leave parameters poorly identified.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SuggestedRun {
    /// What to do, in words.
    pub run: String,
    /// Its rows.
    pub rows: usize,
    /// Time between its rows, s (the recording's).
    pub sample_period_s: f64,
    /// Why: the uncertain parameters with their intervals now and expected.
    pub why: String,
    /// The same, one entry per parameter.
    pub expected: Vec<ExpectedInterval>,
}

/// The noise estimate.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Noise {
    /// Estimated standard deviation per axis, mm.
    pub sigma_mm_per_axis: f64,
    /// RMS of a row's position noise, mm: `sqrt(3) sigma` (the angular columns' is
    /// `angular.rms_deg`).
    pub rms_mm: f64,
    /// RMS of a row's whole weighted noise, positions and angles (mm-equivalent, the
    /// fits' basis: what the verdict compares [`AngularFigures::weighted_heldout_rms_mm_eq`]
    /// with); `rms_mm` without angular columns.
    #[serde(skip)]
    pub weighted_rms: f64,
    /// How it was estimated.
    pub method: String,
    /// The angular columns of the recording, when it has some: their noise and weight.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angular: Option<AngularNoise>,
}

/// The angular columns of a recording in the residual (`crate::start::angular`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AngularNoise {
    /// The column set used (`qw,qx,qy,qz` or `tx,ty,tz`).
    pub columns: String,
    /// Angular components per row in the residual (3 for an orientation, 2 for a
    /// tangent; 0 when not used).
    pub components: usize,
    /// Estimated standard deviation per angular component, degrees.
    pub sigma_deg: f64,
    /// RMS of a row's angular noise, degrees: `sqrt(components) sigma_deg`.
    pub rms_deg: f64,
    /// mm of tip error one degree of angular error counts as (position noise over
    /// angular noise).
    pub mm_per_deg: f64,
    /// How it was estimated and weighted, or why the columns are not used.
    pub method: String,
}

/// One candidate tried in one round.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Trial {
    /// Round, from 1.
    pub round: usize,
    /// The candidate.
    pub effect: EffectId,
    /// Fit-row RMS with it, mm.
    pub rms_mm: f64,
    /// Held-out RMS with it, mm.
    pub heldout_rms_mm: f64,
    /// Change of the information criterion (negative: better).
    pub bic_change: f64,
    /// Whether it was added.
    pub added: bool,
    /// Why not tried or not added, if so.
    pub note: String,
}

/// The split used.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Split {
    /// In words.
    pub method: String,
    /// Rows fitted.
    pub fit_rows: usize,
    /// Rows held out.
    pub heldout_rows: usize,
}

/// The mismatch report (`docs/formats.md`) with this project's additions.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// The user's model.
    pub baseline: Figures,
    /// Effects found, in the order added.
    pub findings: Vec<Finding>,
    /// The fitted model, every row counted (outliers too).
    #[serde(rename = "final")]
    pub final_: Figures,
    /// The verdict: true when the held-out residual of the fitted model (tracker
    /// outliers set aside) is consistent with the noise estimate, at most
    /// [`NOISE_TOLERANCE`](crate::NOISE_TOLERANCE) times its RMS; false when a part is
    /// left that no effect of the vocabulary accounts for (`unexplained` says where).
    pub explained: bool,
    /// What is left, in words.
    pub unexplained: String,
    /// The labelled empirical correction fitted on top of the found physics for what
    /// is left, apart from `findings` (absent when the physics explains the recording).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub empirical: Option<Empirical>,
    /// Noise estimated from the data.
    pub noise: Noise,
    /// The split.
    pub split: Split,
    /// Where the user model's error sits, strongest pattern first.
    pub located: Vec<Statement>,
    /// Every candidate fitted, round by round.
    pub tried: Vec<Trial>,
    /// Rows whose solve did not converge under the final model.
    pub failed_rows: usize,
    /// File lines of the rows whose final error lies more than `outlier_threshold_mm`
    /// from the residual's median: tracker outliers, kept out of the fit by the robust
    /// loss (and still counted in `final`).
    pub outlier_lines: Vec<usize>,
    /// The rule that set the outliers apart, in words.
    pub outlier_rule: String,
    /// The rule's threshold on a row's distance from the residual's median, mm.
    pub outlier_threshold_mm: f64,
    /// The final model's figures without those rows.
    pub final_inliers: Figures,
    /// How the findings' `ci95` were computed.
    pub uncertainty_method: String,
    /// What the data do not identify, in words (empty when every parameter is).
    pub identifiability: Vec<String>,
    /// Pairs of fitted parameters correlated above 0.9: the data tell them apart only
    /// weakly.
    pub correlated: Vec<Correlated>,
    /// The run to record next to pin what is poorly identified (`null` when every
    /// parameter is pinned well or no simple run would help).
    pub suggested_run: Option<SuggestedRun>,
    /// The rows where the user's or the fitted model, solved along the recording, is
    /// within the warning margin of a snap or on an unstable branch (a jump in the data
    /// there is physics, not a tracker glitch).
    pub stability: Stability,
    /// Pairs of runs that measured the same commanded joints farther apart than the
    /// noise allows (`crate::sessions`); absent from the JSON when there are none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sessions: Vec<SessionChange>,
}

/// Two runs that disagree at the joints both commanded (`crate::sessions`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SessionChange {
    /// The runs' labels, in file order.
    pub runs: [String; 2],
    /// Commanded joint vectors both ran.
    pub configurations: usize,
    /// RMS distance between their mean measured tips there, mm.
    pub rms_mm: f64,
    /// What the noise alone would give, mm.
    pub noise_rms_mm: f64,
    /// In words.
    pub statement: String,
}

/// Held-out figures in words: `0.350 mm` of tip position, with `, 1.20 deg` of tip
/// angle beside them when the recording's angular columns enter the residual.
pub(crate) fn held_words(fig: &Figures) -> String {
    match fig.angular {
        Some(a) => format!("{:.3} mm, {:.2} deg", fig.heldout_rms_mm, a.heldout_rms_deg),
        None => format!("{:.3} mm", fig.heldout_rms_mm),
    }
}

/// How the note of a finding taken out after the search starts.
pub(crate) const REMOVED: &str = "removed after the search: ";

/// The joints of a suggested run, as `ctr-cli hw run` plays them.
#[derive(Clone, Debug, PartialEq)]
pub struct JointRun {
    /// Time of each row from the run's start, s.
    pub t_s: Vec<f64>,
    /// Commanded joints of each row, file order and units.
    pub q: Vec<Vec<f64>>,
}

impl JointRun {
    /// The run as a joint file: `t_s` then the joint columns, one row per line.
    ///
    /// ```
    /// let run = ctr_diagnosis::JointRun { t_s: vec![0.0, 0.5], q: vec![vec![10.0, 0.0], vec![10.0, 5.0]] };
    /// assert_eq!(run.to_csv(), "t_s,s1_mm,theta1_deg\n0,10,0\n0.5,10,5\n");
    /// ```
    pub fn to_csv(&self) -> String {
        let n = self.q.first().map_or(0, |q| q.len() / 2);
        let mut out = String::from("t_s");
        for c in ctr_formats::joint_columns(n) {
            out += ",";
            out += &c;
        }
        out += "\n";
        for (t, q) in self.t_s.iter().zip(&self.q) {
            out += &t.to_string();
            for v in q {
                out += ",";
                out += &v.to_string();
            }
            out += "\n";
        }
        out
    }
}

/// A diagnosis: the report and the fitted model.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The report.
    pub report: Report,
    /// The user's model with the effects found, fitted.
    pub fitted: ModelSpec,
    /// The user's model with the established findings alone, refitted without the
    /// predictive ones (`fitted` when every finding is established).
    pub established: ModelSpec,
    /// The linear empirical correction as the robot file's `[model.empirical]` (only
    /// when the recording is not explained).
    pub empirical: Option<Correction>,
    /// The report's `empirical` term, the learned discrepancy, as the robot file's
    /// `[model.discrepancy]` (only when the recording is not explained and it could be
    /// fitted).
    pub discrepancy: Option<Discrepancy>,
    /// The joints of the report's `suggested_run`.
    pub suggested_joints: Option<JointRun>,
}

/// Tip errors of one run under several models (the seed paper's Table 2).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunErrors {
    /// The run's label (`all` for the whole recording).
    pub run: String,
    /// Rows in the run.
    pub rows: usize,
    /// Mean tip error per model, mm.
    pub mean_mm: Vec<f64>,
    /// Largest tip error per model, mm.
    pub max_mm: Vec<f64>,
    /// Smallest stability margin per model over the run's rows, along the recording
    /// (`NaN` when no row converged).
    pub lowest_margin: Vec<f64>,
    /// Per model, the ranges of the run's rows within the warning margin of a snap
    /// ([`Marks::near_snap`](crate::Marks::near_snap); every run's for `all`).
    pub near_snap: Vec<Vec<MarginRange>>,
    /// Per model, the ranges of the run's rows on an unstable branch
    /// ([`Marks::unstable`](crate::Marks::unstable)).
    pub unstable: Vec<Vec<MarginRange>>,
}

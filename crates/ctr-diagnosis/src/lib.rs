//! Diagnosis: where a model and a recording disagree, which left-out physics explains
//! it, fitted, and the gain shown on rows the fit did not see.
//!
//! 1. **Split** ([`Holdout`]): each run is cut into contiguous blocks and every
//!    `every`-th block (staggered between runs) is held out; or whole runs are held out
//!    by label. Never random rows: neighbouring samples share their errors. Time effects
//!    need whole runs, so every run is always simulated; only the residuals of the
//!    held-out rows are kept from the fit.
//! 2. **Noise**: estimated from the data, not from the model: the second differences
//!    of the user model's residual along each run remove any error that varies smoothly
//!    with the motion, leaving `6 sigma^2` of white tracker noise per axis (a robust
//!    median-absolute-deviation estimate, so jumps at reversals and outliers do not
//!    count). Rows repeated at rest give a second estimate where there are enough.
//! 3. **Locate** ([`locate`]): regressions of the residual on runs, joints, exposed
//!    lengths, relative angles (periodic), direction of motion and workspace position.
//! 4. **Explain**: forward selection over the contract's effects the model leaves out
//!    ([`EffectId`]). Each round fits every remaining candidate's parameters
//!    ([`fit`]: robust Levenberg-Marquardt, bounded) with the effects found so far held,
//!    and the candidate with the lowest held-out error is added if it passes both
//!    tests: the Bayesian information criterion on the fit rows,
//!    `N ln(C_new / C_old) + k ln N < 0` (N residual components, k parameters, C the
//!    robust cost), and a held-out RMS at least [`MIN_HELDOUT_GAIN`] lower. The effects
//!    found are then refitted together. It stops when no candidate passes, and says
//!    whether what is left is consistent with the noise estimate.

mod candidates;
mod fit;
pub mod locate;
#[cfg(feature = "synth")]
pub mod synth;

pub use candidates::EffectId;
pub use locate::Statement;

use ctr_analysis::simulate::{predict, ModelSpec};
use ctr_formats::{Recording, RobotSpec};
use fit::Problem;
use serde::Serialize;
use std::collections::BTreeMap;

/// Smallest relative drop of the held-out RMS for an effect to be added.
pub const MIN_HELDOUT_GAIN: f64 = 0.02;
/// Huber threshold of the robust cost, in estimated noise standard deviations per
/// axis (a 3-D noise vector is below 4 sigma 99.9 % of the time).
const HUBER_SIGMAS: f64 = 4.0;
/// What is left counts as noise when its RMS is at most this many times the noise
/// estimate's.
const NOISE_TOLERANCE: f64 = 1.15;
/// A row the final model misses by more than this many noise standard deviations (per
/// axis) is a tracker outlier (a 3-D Gaussian error exceeds 6 sigma once in 10^7).
pub const OUTLIER_SIGMAS: f64 = 6.0;
/// Robust standard deviation from a median absolute deviation.
const MAD_TO_SIGMA: f64 = 1.4826;
/// Fewest rows in a block of the split.
const MIN_BLOCK_ROWS: usize = 10;
/// Blocks per run (at most) in the split.
const BLOCKS_PER_RUN: usize = 8;
/// Start of every value of a clearance table fit, deg.
const TABLE_START_DEG: f64 = 0.5;
/// Jacobians per fit.
const MAX_FIT_ITERATIONS: usize = 25;

/// How the rows are split into fit and held-out parts.
#[derive(Clone, Debug, PartialEq)]
pub enum Holdout {
    /// Each run in contiguous blocks (up to 8, at least 10 rows each); every `every`-th
    /// block is held out, staggered from run to run. Runs too short for two blocks are
    /// fitted whole.
    Blocks {
        /// one block in `every` is held out (>= 2)
        every: usize,
    },
    /// These runs (labels) are held out whole.
    Runs(Vec<String>),
}

impl std::str::FromStr for Holdout {
    type Err = String;

    /// `blocks:K` (K >= 2) or `runs:LABEL[,LABEL...]`, as `--holdout` takes it.
    ///
    /// ```
    /// use ctr_diagnosis::Holdout;
    /// assert_eq!("blocks:3".parse(), Ok(Holdout::Blocks { every: 3 }));
    /// assert_eq!("runs: a ,b".parse(), Ok(Holdout::Runs(vec!["a".into(), "b".into()])));
    /// assert!("blocks:1".parse::<Holdout>().is_err());
    /// ```
    fn from_str(s: &str) -> Result<Self, String> {
        let want = "wanted blocks:K (K >= 2) or runs:LABEL[,LABEL...]";
        match s.split_once(':') {
            Some(("blocks", k)) => match k.parse::<usize>() {
                Ok(every) if every >= 2 => Ok(Holdout::Blocks { every }),
                _ => Err(format!("{s:?}: {want}")),
            },
            Some(("runs", labels)) if !labels.trim().is_empty() => Ok(Holdout::Runs(
                labels.split(',').map(|l| l.trim().to_owned()).collect(),
            )),
            _ => Err(format!("{s:?}: {want}")),
        }
    }
}

impl Default for Holdout {
    fn default() -> Self {
        Holdout::Blocks { every: 4 }
    }
}

/// Options of a diagnosis.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The split.
    pub holdout: Holdout,
    /// The effects tried (default: all ten).
    pub candidates: Vec<EffectId>,
    /// Threads for the fits (0: all cores).
    pub threads: usize,
    /// `calibrate` only: fit the clearance as a smooth table of this many values per
    /// pair over one turn (the seed's measured "database") instead of a cosine profile.
    pub clearance_table: Option<usize>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            holdout: Holdout::default(),
            candidates: EffectId::ALL.to_vec(),
            threads: 0,
            clearance_table: None,
        }
    }
}

/// Error figures of a model on a recording, mm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Figures {
    /// RMS tip error over the fit rows.
    pub rms_mm: f64,
    /// Largest tip error over the fit rows.
    pub max_mm: f64,
    /// RMS tip error over the held-out rows.
    pub heldout_rms_mm: f64,
}

/// One effect the diagnosis found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Finding {
    /// The contract's id.
    pub effect: EffectId,
    /// What the model leaves out, in words, with the fitted values.
    pub explanation: String,
    /// Where the effect shows: the runs and the pattern of the error it removes.
    #[serde(rename = "where")]
    pub where_: String,
    /// The fitted parameters, as the robot file writes them.
    pub parameters: serde_json::Value,
    /// Fit-row RMS before adding it, mm.
    pub rms_mm_before: f64,
    /// Fit-row RMS after, mm.
    pub rms_mm_after: f64,
    /// Held-out RMS before, mm.
    pub heldout_rms_mm_before: f64,
    /// Held-out RMS after, mm.
    pub heldout_rms_mm_after: f64,
}

/// The noise estimate.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Noise {
    /// Estimated standard deviation per axis, mm.
    pub sigma_mm_per_axis: f64,
    /// RMS of 3-D noise, `sqrt(3) sigma`, mm.
    pub rms_mm: f64,
    /// How it was estimated.
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

/// The mismatch report (`shared/spec/formats.md`) with this project's additions.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// The user's model.
    pub baseline: Figures,
    /// Effects found, in the order added.
    pub findings: Vec<Finding>,
    /// The fitted model.
    #[serde(rename = "final")]
    pub final_: Figures,
    /// What is left, in words.
    pub unexplained: String,
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
    /// File lines of the rows the final model misses by more than
    /// [`OUTLIER_SIGMAS`] noise standard deviations: tracker outliers, kept out of the
    /// fit by the robust loss.
    pub outlier_lines: Vec<usize>,
    /// The final model's figures without those rows.
    pub final_inliers: Figures,
}

/// A diagnosis: the report and the fitted model.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The report.
    pub report: Report,
    /// The user's model with the effects found, fitted.
    pub fitted: ModelSpec,
}

impl Report {
    /// The plain-language summary (`ctr-cli diagnose` prints it; `ctr_py` returns it):
    /// the error, where it sits, each finding with its gain, and what is left.
    pub fn summary(&self, recording: &str) -> String {
        let mut s = format!(
            "{recording}: the model misses the measured tip by {:.3} mm RMS ({:.3} mm on \
             held-out rows, largest {:.3} mm).\n",
            self.baseline.rms_mm, self.baseline.heldout_rms_mm, self.baseline.max_mm
        );
        let patterns: Vec<&str> = self
            .located
            .iter()
            .filter(|l| l.kind != "run")
            .take(3)
            .map(|l| l.text.as_str())
            .collect();
        if !patterns.is_empty() {
            s += &format!("Where: the error {}.\n", patterns.join("; "));
        }
        if self.findings.is_empty() {
            s += "No left-out effect explains part of it.\n";
        }
        for f in &self.findings {
            s += &format!(
                "{}\n  where: {}\n  held-out RMS {:.3} -> {:.3} mm (fit rows {:.3} -> {:.3} mm)\n",
                f.explanation,
                f.where_,
                f.heldout_rms_mm_before,
                f.heldout_rms_mm_after,
                f.rms_mm_before,
                f.rms_mm_after
            );
        }
        s += &format!(
            "After fitting: {:.3} mm RMS, {:.3} mm held out. The {}.\n",
            self.final_.rms_mm, self.final_.heldout_rms_mm, self.unexplained
        );
        s
    }
}

impl Diagnosis {
    /// The fitted model as a robot file: `spec` (the user's) with the fitted `[model]`.
    pub fn fitted_spec(&self, spec: &RobotSpec) -> RobotSpec {
        RobotSpec {
            model: self.fitted.model,
            effects: self.fitted.effects.clone(),
            ..spec.clone()
        }
    }
}

/// Why a diagnosis could not run.
#[derive(Clone, Debug, PartialEq)]
pub enum DiagnoseError {
    /// The user's model cannot be simulated on the recording.
    Model(String),
    /// The split leaves no fit rows or no held-out rows.
    Split(String),
}

impl std::fmt::Display for DiagnoseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DiagnoseError::Model(m) => write!(f, "{m}"),
            DiagnoseError::Split(m) => write!(f, "{m}"),
        }
    }
}

impl std::error::Error for DiagnoseError {}

/// Which rows are held out.
pub fn split(rec: &Recording, holdout: &Holdout) -> Result<(Vec<bool>, String), DiagnoseError> {
    let mut held = vec![false; rec.rows.len()];
    let method = match holdout {
        Holdout::Blocks { every } => {
            let every = (*every).max(2);
            for (i, run) in rec.runs.iter().enumerate() {
                let len = run.rows.len();
                let blocks = (len / MIN_BLOCK_ROWS).min(BLOCKS_PER_RUN);
                if blocks < 2 {
                    continue;
                }
                for b in 0..blocks {
                    if (b + i) % every == every - 1 {
                        let start = run.rows.start + b * len / blocks;
                        let end = run.rows.start + (b + 1) * len / blocks;
                        held[start..end].iter_mut().for_each(|h| *h = true);
                    }
                }
            }
            format!(
                "each run in up to {BLOCKS_PER_RUN} contiguous blocks of at least \
                 {MIN_BLOCK_ROWS} rows; one block in {every} held out, staggered between runs"
            )
        }
        Holdout::Runs(labels) => {
            for l in labels {
                if !rec.runs.iter().any(|r| &r.label == l) {
                    return Err(DiagnoseError::Split(format!(
                        "--holdout: no run labelled {l} in {} (runs: {})",
                        rec.file,
                        rec.runs
                            .iter()
                            .map(|r| r.label.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )));
                }
            }
            for run in &rec.runs {
                if labels.contains(&run.label) {
                    held[run.rows.clone()].iter_mut().for_each(|h| *h = true);
                }
            }
            format!("runs {} held out whole", labels.join(", "))
        }
    };
    let n_held = held.iter().filter(|h| **h).count();
    if n_held == 0 || n_held == held.len() {
        return Err(DiagnoseError::Split(format!(
            "the split ({method}) leaves {} fit rows and {n_held} held-out rows; both must \
             be non-empty (--holdout chooses another)",
            held.len() - n_held,
        )));
    }
    Ok((held, method))
}

/// Noise per axis from the second differences of `e` along each run.
pub fn estimate_noise(rec: &Recording, e: &[[f64; 3]]) -> Noise {
    let mut d2 = Vec::new();
    for run in &rec.runs {
        for k in run.rows.start + 1..run.rows.end.saturating_sub(1) {
            for a in 0..3 {
                d2.push(e[k - 1][a] - 2.0 * e[k][a] + e[k + 1][a]);
            }
        }
    }
    let sigma = if d2.len() >= 9 {
        let med = median(&mut d2.clone());
        let mut dev: Vec<f64> = d2.iter().map(|v| (v - med).abs()).collect();
        MAD_TO_SIGMA * median(&mut dev) / 6f64.sqrt()
    } else {
        f64::NAN
    };
    Noise {
        sigma_mm_per_axis: sigma,
        rms_mm: 3f64.sqrt() * sigma,
        method: format!(
            "median absolute deviation of the residual's second differences along the runs \
             ({} triples of rows)",
            d2.len() / 3
        ),
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Error vectors (predicted - measured) of every row.
fn errors(rec: &Recording, p: &[[f64; 3]]) -> Vec<[f64; 3]> {
    rec.rows
        .iter()
        .zip(p)
        .map(|(r, p)| [p[0] - r.p[0], p[1] - r.p[1], p[2] - r.p[2]])
        .collect()
}

fn figures(e: &[[f64; 3]], held: &[bool]) -> Figures {
    let (mut sf, mut nf, mut sh, mut nh, mut max) = (0.0, 0usize, 0.0, 0usize, 0.0f64);
    for (v, h) in e.iter().zip(held) {
        let d2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
        if *h {
            sh += d2;
            nh += 1;
        } else {
            sf += d2;
            nf += 1;
            max = max.max(d2.sqrt());
        }
    }
    Figures {
        rms_mm: (sf / nf.max(1) as f64).sqrt(),
        max_mm: max,
        heldout_rms_mm: (sh / nh.max(1) as f64).sqrt(),
    }
}

/// Median time step between a run's rows (s).
fn sample_period(rec: &Recording) -> f64 {
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

/// Why a candidate cannot be tried on this model and recording, if so.
fn not_applicable(effect: EffectId, model: &ModelSpec, rec: &Recording) -> Option<String> {
    let densities = model
        .robot
        .tube_params()
        .iter()
        .all(|p| p.density_kg_m3.is_some());
    match effect {
        EffectId::Latency if !rec.has_time => {
            Some("the recording has no t_s column: latency cannot be seen".into())
        }
        EffectId::Gravity if !densities => {
            Some("not tried: the robot file gives no density_kg_m3 for every tube".into())
        }
        EffectId::Gravity if model.model == ctr_core::Model::Rigid => Some(
            "not tried on a rigid model: the loaded solver models torsion too, so a gravity \
             fit would also bring torsion in (torsion is tried first)"
                .into(),
        ),
        EffectId::Gravity if model.effects.clearance.is_some() => {
            Some("not tried: gravity together with clearance is not modelled".into())
        }
        EffectId::Clearance if model.effects.gravity.is_some() => {
            Some("not tried: clearance together with gravity is not modelled".into())
        }
        EffectId::Clearance | EffectId::Friction if model.robot.n_tubes() < 2 => {
            Some("not tried: one tube has no neighbour".into())
        }
        _ => None,
    }
}

/// Rows whose error exceeds [`OUTLIER_SIGMAS`] noise standard deviations.
fn outlier_rows(e: &[[f64; 3]], noise: &Noise) -> Vec<usize> {
    if noise.sigma_mm_per_axis.is_nan() || noise.sigma_mm_per_axis <= 0.0 {
        return Vec::new();
    }
    let limit = OUTLIER_SIGMAS * noise.sigma_mm_per_axis;
    e.iter()
        .enumerate()
        .filter(|(_, v)| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() > limit)
        .map(|(r, _)| r)
        .collect()
}

/// Figures without the outlier rows.
fn inlier_figures(e: &[[f64; 3]], held: &[bool], outliers: &[usize]) -> Figures {
    let keep: Vec<usize> = (0..e.len())
        .filter(|r| outliers.binary_search(r).is_err())
        .collect();
    let e: Vec<[f64; 3]> = keep.iter().map(|&r| e[r]).collect();
    let held: Vec<bool> = keep.iter().map(|&r| held[r]).collect();
    figures(&e, &held)
}

/// What is left, in words.
fn leftover(
    rec: &Recording,
    fig: &Figures,
    inliers: &Figures,
    outliers: &[usize],
    noise: &Noise,
    where_: impl FnOnce() -> String,
) -> String {
    let outlier_note = if outliers.is_empty() {
        String::new()
    } else {
        format!(
            " once {} row{} the model misses by more than {OUTLIER_SIGMAS} noise deviations \
             (tracker outliers: lines {}) are set aside",
            outliers.len(),
            if outliers.len() == 1 { "" } else { "s" },
            outliers
                .iter()
                .take(10)
                .map(|&r| rec.rows[r].line.to_string())
                .collect::<Vec<_>>()
                .join(", ")
                + if outliers.len() > 10 { ", ..." } else { "" }
        )
    };
    if inliers.rms_mm <= NOISE_TOLERANCE * noise.rms_mm {
        format!(
            "residual is consistent with measurement noise{outlier_note}: {:.3} mm RMS on the \
             fit rows, {:.3} mm held out, against {:.3} mm of noise estimated from the data",
            inliers.rms_mm, inliers.heldout_rms_mm, noise.rms_mm
        )
    } else {
        format!(
            "{:.3} mm RMS is left ({:.3} mm held out{}), above the {:.3} mm of noise \
             estimated from the data, and no effect of the vocabulary reduces it further; it \
             sits in {}",
            fig.rms_mm,
            fig.heldout_rms_mm,
            if outliers.is_empty() {
                String::new()
            } else {
                format!(
                    "; {:.3} mm without {} outlier rows",
                    inliers.rms_mm,
                    outliers.len()
                )
            },
            noise.rms_mm,
            where_()
        )
    }
}

/// What a diagnosis and a calibration both start from: the split and the user model's
/// error on it.
struct Start {
    held: Vec<bool>,
    split_method: String,
    all_runs: Vec<usize>,
    fit_rows: Vec<usize>,
    /// The user model's error vectors, every row.
    e0: Vec<[f64; 3]>,
    baseline: Figures,
    noise: Noise,
    located: Vec<Statement>,
}

impl Start {
    fn new(model: &ModelSpec, rec: &Recording, holdout: &Holdout) -> Result<Self, DiagnoseError> {
        let (held, split_method) = split(rec, holdout)?;
        let all_runs: Vec<usize> = (0..rec.runs.len()).collect();
        let fit_rows: Vec<usize> = (0..rec.rows.len()).filter(|&r| !held[r]).collect();
        let base = predict(model, rec, &all_runs)
            .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
        let e0 = errors(rec, &base.p);
        let fit_mask: Vec<bool> = held.iter().map(|h| !h).collect();
        Ok(Start {
            baseline: figures(&e0, &held),
            noise: estimate_noise(rec, &e0),
            located: locate::locate(rec, &e0, &fit_mask, &base.p),
            held,
            split_method,
            all_runs,
            fit_rows,
            e0,
        })
    }

    /// Huber threshold of the fits, mm (none without a noise estimate).
    fn huber_mm(&self) -> f64 {
        let sigma = self.noise.sigma_mm_per_axis;
        if sigma.is_finite() && sigma > 0.0 {
            HUBER_SIGMAS * sigma
        } else {
            f64::INFINITY
        }
    }

    /// The report of the model `fitted`, whose error vectors are `e`: the noise estimated
    /// again on what it leaves (closer to white), tracker outliers set aside, and what is
    /// left in words (`where_left` says where, given the fit rows' mask).
    fn finish(
        self,
        rec: &Recording,
        fitted: ModelSpec,
        findings: Vec<Finding>,
        final_: Figures,
        e: &[[f64; 3]],
        tried: Vec<Trial>,
        failed_rows: usize,
        where_left: impl FnOnce(&[bool]) -> String,
    ) -> Diagnosis {
        let again = estimate_noise(rec, e);
        let noise = if again.sigma_mm_per_axis < self.noise.sigma_mm_per_axis
            || !self.noise.sigma_mm_per_axis.is_finite()
        {
            again
        } else {
            self.noise
        };
        let outliers = outlier_rows(e, &noise);
        let inliers = inlier_figures(e, &self.held, &outliers);
        let fit_mask: Vec<bool> = self.held.iter().map(|h| !h).collect();
        let unexplained = leftover(rec, &final_, &inliers, &outliers, &noise, || {
            where_left(&fit_mask)
        });
        Diagnosis {
            report: Report {
                baseline: self.baseline,
                findings,
                final_,
                unexplained,
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
                final_inliers: inliers,
            },
            fitted,
        }
    }
}

/// The best candidate of a round so far.
struct Best {
    effect: EffectId,
    model: ModelSpec,
    fig: Figures,
    cost: f64,
    e: Vec<[f64; 3]>,
}

/// Diagnoses `model` against `rec`.
///
/// ```no_run
/// use ctr_diagnosis::{diagnose, Options};
/// use ctr_analysis::simulate::ModelSpec;
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
    let start = Start::new(model, rec, &opt.holdout)?;
    let (held, all_runs, fit_rows) = (&start.held, &start.all_runs, &start.fit_rows);
    let (e0, baseline) = (&start.e0, start.baseline);
    let n = model.robot.n_tubes();
    let huber = start.huber_mm();
    let threads = ctr_formats::parallel::resolve_threads(opt.threads);
    let period = sample_period(rec);
    let n_obs = (3 * fit_rows.len()) as f64;

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
        runs: all_runs.clone(),
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
                    tried.push(Trial {
                        round,
                        effect: c,
                        rms_mm: f64::NAN,
                        heldout_rms_mm: f64::NAN,
                        bic_change: f64::NAN,
                        added: false,
                        note,
                    });
                }
                continue;
            }
            todo.push(c);
        }
        // every (candidate, start) fit on its own thread of a pool; the fits then use
        // one thread each
        let jobs: Vec<(EffectId, Vec<f64>)> = todo
            .iter()
            .flat_map(|&c| c.starts(n, period).into_iter().map(move |x0| (c, x0)))
            .collect();
        // each candidate is fitted together with the effects found so far, which stay
        // free: a first effect that soaked up part of another must be able to give it back
        let held_x: Vec<f64> = accepted.iter().flat_map(|b| b.read(&current)).collect();
        let with = |c: EffectId| -> Vec<EffectId> { accepted.iter().copied().chain([c]).collect() };
        let results = ctr_formats::parallel::map(&jobs, threads, |(c, x0)| {
            let mut p = problem(current.clone(), with(*c));
            p.threads = 1;
            let x: Vec<f64> = held_x.iter().chain(x0).copied().collect();
            p.fit(&x, MAX_FIT_ITERATIONS)
        });
        for &c in &todo {
            let p = problem(current.clone(), with(c));
            let fitted = jobs
                .iter()
                .zip(&results)
                .filter(|((jc, _), _)| *jc == c)
                .filter_map(|(_, r)| r.clone())
                .min_by(|a, b| a.cost.total_cmp(&b.cost));
            let Some(fitted) = fitted else {
                round_trials.push(Trial {
                    round,
                    effect: c,
                    rms_mm: f64::NAN,
                    heldout_rms_mm: f64::NAN,
                    bic_change: f64::NAN,
                    added: false,
                    note: "the model cannot be simulated with this effect".into(),
                });
                continue;
            };
            let m = p.model(&fitted.x);
            let Ok(pred) = predict(&m, rec, all_runs) else {
                continue;
            };
            let e = errors(rec, &pred.p);
            let fig = figures(&e, held);
            let k = c.n_params(n) as f64;
            let bic = n_obs * (fitted.cost / current_cost).ln() + k * n_obs.ln();
            round_trials.push(Trial {
                round,
                effect: c,
                rms_mm: fig.rms_mm,
                heldout_rms_mm: fig.heldout_rms_mm,
                bic_change: bic,
                added: false,
                note: String::new(),
            });
            let passes = bic < 0.0
                && fig.heldout_rms_mm < current_fig.heldout_rms_mm * (1.0 - MIN_HELDOUT_GAIN);
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
        let Some(Best {
            effect: c,
            model: m,
            fig,
            cost,
            e,
        }) = best
        else {
            for t in &mut round_trials {
                if t.note.is_empty() {
                    t.note = "not added: no gain on held-out rows or the information \
                              criterion rejects it"
                        .into();
                }
            }
            tried.extend(round_trials);
            break;
        };
        for t in &mut round_trials {
            if t.effect == c {
                t.added = true;
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
                        let ej = errors(rec, &pred.p);
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
        let tips: Vec<[f64; 3]> = rec
            .rows
            .iter()
            .zip(&e)
            .map(|(r, v)| [r.p[0] + v[0], r.p[1] + v[1], r.p[2] + v[2]])
            .collect();
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
    let final_pred = predict(&current, rec, all_runs)
        .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
    Ok(start.finish(
        rec,
        current,
        findings,
        current_fig,
        &current_e,
        tried,
        final_pred.failed,
        |fit_mask| locate::summary(&locate::locate(rec, &current_e, fit_mask, &final_pred.p)),
    ))
}

/// The effect's table of the robot file, as JSON.
fn parameters(c: EffectId, m: &ModelSpec) -> serde_json::Value {
    let e = &m.effects;
    let v = match c {
        EffectId::Torsion => serde_json::to_value(BTreeMap::from([("kind", "torsion")])),
        EffectId::Friction => serde_json::to_value(&e.friction),
        EffectId::Clearance => serde_json::to_value(&e.clearance),
        EffectId::Gravity => serde_json::to_value(&e.gravity),
        EffectId::Registration => serde_json::to_value(e.registration),
        EffectId::JointOffset => serde_json::to_value(&e.joint_offset),
        EffectId::Stiffness => serde_json::to_value(&e.stiffness),
        EffectId::Precurvature => serde_json::to_value(&e.precurvature),
        EffectId::Latency => serde_json::to_value(e.latency),
        EffectId::SensorOffset => serde_json::to_value(e.sensor_offset),
    };
    v.unwrap_or(serde_json::Value::Null)
}

fn list(v: &[f64], unit: &str) -> String {
    v.iter()
        .map(|x| format!("{x:.3}{unit}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The finding in words.
fn explain(c: EffectId, m: &ModelSpec) -> String {
    let e = &m.effects;
    match c {
        EffectId::Torsion => "The model leaves out torsion: the tubes twist along their \
            length, so the relative angles at the tips differ from the commanded ones."
            .into(),
        EffectId::Friction => {
            let f = e.friction.as_ref().expect("written by the fit");
            let mut s = String::from(
                "The model leaves out friction between the tubes: the tip depends on the \
                 direction of motion (hysteresis)",
            );
            for (i, w) in f.rotation_play_deg.iter().enumerate() {
                s += &format!(
                    "; the rotation of tube {} relative to tube {} lags by a play of \
                     +/-{w:.2} deg",
                    i + 2,
                    i + 1
                );
            }
            if f.feed_play_mm.iter().any(|w| *w > 0.0) {
                s += &format!("; feed play per tube {}", list(&f.feed_play_mm, " mm"));
            }
            s + "."
        }
        EffectId::Clearance => {
            let c = e.clearance.as_ref().expect("written by the fit");
            let mut parts = Vec::new();
            for (i, t) in c.table_deg.iter().enumerate() {
                let (k, max) = t
                    .iter()
                    .enumerate()
                    .fold(
                        (0, f64::NEG_INFINITY),
                        |a, (k, v)| if *v > a.1 { (k, *v) } else { a },
                    );
                parts.push(format!(
                    "tube {} leaves tube {}'s tip deflected by up to {max:.2} deg, largest at a \
                     relative angle of {:.0} deg (a table of {} values over one turn)",
                    i + 2,
                    i + 1,
                    360.0 * k as f64 / t.len() as f64,
                    t.len()
                ));
            }
            for i in 0..c.max_deflection_deg.len() {
                parts.push(format!(
                    "tube {} leaves tube {}'s tip deflected by up to {:.2} deg, largest at a \
                     relative angle of {:.0} deg",
                    i + 2,
                    i + 1,
                    c.max_deflection_deg[i],
                    c.peak_deg[i]
                ));
            }
            format!(
                "The model leaves out the clearance between the tubes: {}.",
                parts.join("; ")
            )
        }
        EffectId::Gravity => {
            let g = e.gravity.as_ref().expect("written by the fit");
            format!(
                "The model leaves out the tubes' weight: gravity of {:.2} m/s^2 along \
                 ({:.3}, {:.3}, {:.3}) in W bends the robot.",
                g.g_m_s2, g.direction_w[0], g.direction_w[1], g.direction_w[2]
            )
        }
        EffectId::Registration => {
            let r = e.registration.expect("written by the fit");
            format!(
                "The measuring frame is not W: it is shifted by ({}) mm and rotated by \
                 {:.3} deg about ({:.3}, {:.3}, {:.3}).",
                list(&r.translation_mm, ""),
                r.rotation_deg,
                r.rotation_axis[0],
                r.rotation_axis[1],
                r.rotation_axis[2]
            )
        }
        EffectId::JointOffset => {
            let o = e.joint_offset.as_ref().expect("written by the fit");
            format!(
                "The actuators' zeros differ from the nominal ones: feed offsets ({}) mm, \
                 rotation offsets ({}) deg, tube 1 first.",
                list(&o.feed_mm, ""),
                list(&o.rotation_deg, "")
            )
        }
        EffectId::Stiffness => {
            let s = e.stiffness.as_ref().expect("written by the fit");
            format!(
                "The tubes' stiffness differs from the description: E times ({}), tube 1 \
                 first.",
                list(&s.factor, "")
            )
        }
        EffectId::Precurvature => {
            let p = e.precurvature.as_ref().expect("written by the fit");
            format!(
                "The tubes' precurvature differs from the description: curvature radius \
                 times ({}), tube 1 first.",
                list(&p.radius_factor, "")
            )
        }
        EffectId::Latency => {
            let l = e.latency.expect("written by the fit");
            if l.tau_s >= 0.0 {
                format!(
                    "The measured tip lags the commanded joints by {:.3} s (actuator \
                     tracking or tracker delay).",
                    l.tau_s
                )
            } else {
                format!(
                    "The measured tip leads the commanded joints by {:.3} s (the time \
                     stamps are shifted).",
                    -l.tau_s
                )
            }
        }
        EffectId::SensorOffset => {
            let s = e.sensor_offset.expect("written by the fit");
            format!(
                "The tracked point is not the tube's tip: it sits at ({}) mm in the tip \
                 frame.",
                list(&s.offset_mm, "")
            )
        }
    }
}

/// Fits the parameters of the named effects together, without the search: the
/// `calibrate` of a lab that knows what to identify (a clearance profile, the stiffness
/// from tip deflections under known hung weights recorded as `fx_n,fy_n,fz_n`, ...).
/// Effects the model already has are refitted from their values. The report has one
/// finding per effect (before: the user model; after: all fitted).
///
/// ```no_run
/// use ctr_diagnosis::{calibrate, EffectId, Options};
/// use ctr_analysis::simulate::ModelSpec;
/// use ctr_formats::{Recording, RobotSpec};
/// use std::path::Path;
/// let spec = RobotSpec::from_path(Path::new("robot.toml"))?;
/// let rec = Recording::from_path(Path::new("weights.csv"), spec.robot.n_tubes())?;
/// let d = calibrate(&ModelSpec::from_spec(&spec), &rec, &[EffectId::Stiffness], &Options::default())?;
/// println!("{}", d.report.findings[0].explanation);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn calibrate(
    model: &ModelSpec,
    rec: &Recording,
    effects: &[EffectId],
    opt: &Options,
) -> Result<Diagnosis, DiagnoseError> {
    for &c in effects {
        if let Some(note) = not_applicable(c, model, rec) {
            return Err(DiagnoseError::Model(format!("{}: {note}", c.as_str())));
        }
    }
    let start = Start::new(model, rec, &opt.holdout)?;
    let n = model.robot.n_tubes();
    let mut blocks: Vec<EffectId> = Vec::new();
    for &c in effects {
        if !blocks.contains(&c) {
            blocks.push(c);
        }
    }
    let problem = Problem {
        base: model.clone(),
        blocks: blocks.clone(),
        rec,
        runs: start.all_runs.clone(),
        rows: start.fit_rows.clone(),
        huber_mm: start.huber_mm(),
        threads: ctr_formats::parallel::resolve_threads(opt.threads),
        clearance_table: opt.clearance_table,
    };
    let period = sample_period(rec);
    // start every block from the model's values (or its first start when absent); a
    // block with several starts tries each, the others held at their first
    let table_start = |b: EffectId| -> Option<Vec<f64>> {
        let k = problem
            .clearance_table
            .filter(|_| b == EffectId::Clearance)?;
        Some(vec![TABLE_START_DEG; k * n.saturating_sub(1)])
    };
    let first: Vec<Vec<f64>> = blocks
        .iter()
        .map(|b| {
            if let Some(t) = table_start(*b) {
                t
            } else if b.present_in(model) {
                b.read(model)
            } else {
                b.starts(n, period).swap_remove(0)
            }
        })
        .collect();
    let mut starts = vec![first.concat()];
    for (i, b) in blocks.iter().enumerate() {
        if b.present_in(model) || table_start(*b).is_some() {
            continue;
        }
        for alt in b.starts(n, period).into_iter().skip(1) {
            let mut x = first.clone();
            x[i] = alt;
            starts.push(x.concat());
        }
    }
    let fitted = starts
        .iter()
        .filter_map(|x0| problem.fit(x0, MAX_FIT_ITERATIONS))
        .min_by(|a, b| a.cost.total_cmp(&b.cost))
        .ok_or_else(|| {
            DiagnoseError::Model("the model cannot be simulated with these effects".into())
        })?;
    let m = problem.model(&fitted.x);
    let pred = predict(&m, rec, &start.all_runs)
        .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
    let e = errors(rec, &pred.p);
    let fig = figures(&e, &start.held);
    let change: Vec<[f64; 3]> = e
        .iter()
        .zip(&start.e0)
        .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
        .collect();
    let all_mask = vec![true; rec.rows.len()];
    let where_ = locate::summary(&locate::locate(rec, &change, &all_mask, &pred.p));
    let findings = blocks
        .iter()
        .map(|&c| Finding {
            effect: c,
            explanation: explain(c, &m),
            where_: where_.clone(),
            parameters: parameters(c, &m),
            rms_mm_before: start.baseline.rms_mm,
            rms_mm_after: fig.rms_mm,
            heldout_rms_mm_before: start.baseline.heldout_rms_mm,
            heldout_rms_mm_after: fig.heldout_rms_mm,
        })
        .collect();
    Ok(
        start.finish(rec, m, findings, fig, &e, Vec::new(), pred.failed, |_| {
            "`ctr-cli diagnose` searches the other effects".into()
        }),
    )
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
}

/// Mean and largest tip error per run (and over all rows, last) for each model.
///
/// ```
/// use ctr_analysis::simulate::ModelSpec;
/// use ctr_diagnosis::evaluate;
/// use ctr_formats::{Recording, RobotSpec};
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\nyoungs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let rec = Recording::read("run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\na,50,0,0,0,51\n".as_bytes(), "rec.csv", 1)?;
/// let table = evaluate(&[ModelSpec::from_spec(&spec)], &rec).unwrap();
/// assert_eq!(table[0].run, "a");
/// assert!((table[0].mean_mm[0] - 1.0).abs() < 1e-12);
/// assert_eq!(table.last().unwrap().run, "all");
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn evaluate(models: &[ModelSpec], rec: &Recording) -> Result<Vec<RunErrors>, DiagnoseError> {
    let all_runs: Vec<usize> = (0..rec.runs.len()).collect();
    let mut sizes = Vec::with_capacity(models.len());
    for m in models {
        let p = predict(m, rec, &all_runs)
            .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
        sizes.push(
            errors(rec, &p.p)
                .iter()
                .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
                .collect::<Vec<f64>>(),
        );
    }
    let row = |label: &str, range: std::ops::Range<usize>| RunErrors {
        run: label.to_owned(),
        rows: range.len(),
        mean_mm: sizes
            .iter()
            .map(|s| s[range.clone()].iter().sum::<f64>() / range.len() as f64)
            .collect(),
        max_mm: sizes
            .iter()
            .map(|s| s[range.clone()].iter().copied().fold(0.0, f64::max))
            .collect(),
    };
    let mut out: Vec<RunErrors> = rec
        .runs
        .iter()
        .map(|r| row(&r.label, r.rows.clone()))
        .collect();
    out.push(row("all", 0..rec.rows.len()));
    Ok(out)
}

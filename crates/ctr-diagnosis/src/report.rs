//! The report: the types a diagnosis returns (written as the mismatch report JSON of
//! `shared/spec/formats.md`) and its plain-language summary.

use crate::candidates::EffectId;
use crate::locate::Statement;
use ctr_analysis::model::ModelSpec;
use ctr_formats::{Correction, RobotSpec};
use serde::Serialize;

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
    /// The largest terms by contribution, largest first.
    pub dominant: Vec<Term>,
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
    /// Held-out RMS of the final model with this effect replaced by the generic
    /// empirical correction of as many parameters, mm (NaN for torsion): the yardstick
    /// it beat (see `verify`).
    pub empirical_heldout_rms_mm: f64,
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
}

/// How the note of a finding taken out after the search starts.
pub(crate) const REMOVED: &str = "removed after the search: ";

/// A diagnosis: the report and the fitted model.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The report.
    pub report: Report,
    /// The user's model with the effects found, fitted.
    pub fitted: ModelSpec,
    /// The report's `empirical` term as the robot file's `[model.empirical]` (only when
    /// the recording is not explained).
    pub empirical: Option<Correction>,
}

impl Report {
    /// The plain-language summary (`ctr-cli diagnose` prints it; `ctr_py` returns it):
    /// the error, where it sits, each finding with its gain, and what is left.
    pub fn summary(&self, recording: &str) -> String {
        let mut s = format!(
            "{recording}: explained: {}: after fitting, {:.3} mm RMS is left on held-out rows \
             (all rows counted) against {:.3} mm of noise estimated from the data.\n",
            if self.explained { "yes" } else { "no" },
            self.final_.heldout_rms_mm,
            self.noise.rms_mm
        );
        s += &format!(
            "The model misses the measured tip by {:.3} mm RMS ({:.3} mm on held-out rows, \
             largest {:.3} mm).\n",
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
        for t in self.tried.iter().filter(|t| t.note.starts_with(REMOVED)) {
            s += &format!(
                "Not physics: {} ({}).\n",
                t.effect.as_str(),
                &t.note[REMOVED.len()..]
            );
        }
        s += &format!(
            "After fitting: {:.3} mm RMS, {:.3} mm held out. The {}.\n",
            self.final_.rms_mm, self.final_.heldout_rms_mm, self.unexplained
        );
        if let Some(emp) = &self.empirical {
            let terms: Vec<String> = self
                .dominant_terms()
                .map(|t| format!("{} on {} ({:.2} mm)", t.feature, t.axis, t.rms_mm))
                .collect();
            s += &format!(
                "An empirical term (not physics, {} terms chosen by cross-validation on the \
                 fit rows) leaves {:.3} mm held out; its largest terms: {}.\n",
                emp.terms,
                emp.heldout_rms_mm,
                terms.join(", ")
            );
        }
        s
    }

    fn dominant_terms(&self) -> impl Iterator<Item = &Term> {
        self.empirical.iter().flat_map(|e| e.dominant.iter())
    }
}

impl Diagnosis {
    /// The fitted model as a robot file: `spec` (the user's) with the fitted `[model]`.
    pub fn fitted_spec(&self, spec: &RobotSpec) -> RobotSpec {
        RobotSpec {
            model: self.fitted.model,
            effects: self.fitted.effects.clone(),
            empirical: self.fitted.empirical.clone(),
            ..spec.clone()
        }
    }

    /// [`fitted_spec`](Self::fitted_spec) with the empirical term as `[model.empirical]`
    /// (its terms after any the user's file had): what `ctr-cli diagnose
    /// --with-empirical` writes. The same as `fitted_spec` when the recording is
    /// explained.
    pub fn fitted_spec_with_empirical(&self, spec: &RobotSpec) -> RobotSpec {
        let mut out = self.fitted_spec(spec);
        if let Some(c) = &self.empirical {
            let mut all = out.empirical.take().unwrap_or_default();
            all.note = c.note.clone();
            all.terms.extend(c.terms.iter().copied());
            out.empirical = Some(all);
        }
        out
    }
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

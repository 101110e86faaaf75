//! The verdict (the method's step 6): is what the fitted model leaves consistent with
//! the noise? The noise is estimated again on what it leaves (closer to white, so the
//! lower estimate is kept), the labelled empirical term is fitted on top of the physics
//! ([`crate::empirical::hybrid`]; where the recording is not explained, the learned
//! discrepancy of [`crate::empirical::gp`] is fitted too and reported in its place when
//! its cross-validation on the fit rows beats the physics, else it is not offered and
//! the linear correction says why),
//! tracker outliers are judged on what is left after
//! both, and `explained` holds when the held-out RMS without them is at most
//! [`NOISE_TOLERANCE`] times the noise's RMS and no predictive finding (`crate::grade`)
//! was needed to get there.

use crate::candidates::EffectId;
use crate::empirical::{gp, hybrid};
use crate::locate::stability::Stability;
use crate::report::prose::leftover;
use crate::report::{Empirical, Figures, Noise};
use crate::residual::{inlier_figures, positions, RowError};
use crate::start::noise::{estimate_noise, outlier_rows, NOISE_TOLERANCE};
use crate::start::Start;
use ctr_analysis::model::ModelSpec;
use ctr_formats::{Correction, Discrepancy};

/// The verdict on a fitted model's error (see the module docs).
pub(crate) struct Verdict {
    /// The noise estimate the verdict compares with.
    pub noise: Noise,
    /// The empirical term fitted on top of the physics, as the report lists it: the
    /// learned discrepancy where the recording is not explained and it can be fitted,
    /// else the linear correction.
    pub empirical: Empirical,
    /// The linear correction, as the robot file's `[model.empirical]` (what the
    /// outliers are judged after, and the intervals' remainder is refitted with).
    pub correction: Correction,
    /// The learned discrepancy, as the robot file's `[model.discrepancy]` (only where
    /// the recording is not explained).
    pub discrepancy: Option<Discrepancy>,
    /// Rows set aside as tracker outliers, ascending.
    pub outliers: Vec<usize>,
    /// The outlier rule's threshold, mm.
    pub outlier_threshold_mm: f64,
    /// The rows near a snap, and the outliers among them.
    pub stability: Stability,
    /// The figures without the outlier rows.
    pub inliers: Figures,
    /// Whether the held-out residual is consistent with the noise with established
    /// physics alone: at the noise, and no predictive finding needed to get there.
    pub explained: bool,
    /// The predictive findings the residual needs to reach the noise, if it does (then
    /// not explained: something outside the vocabulary may act like them).
    pub leaning_on: Vec<EffectId>,
}

impl Verdict {
    /// The verdict on the fitted model `model` whose error vectors are `e` and stability
    /// margins `margin` (per row, from the same simulation), `predictive` its findings
    /// graded predictive.
    pub(crate) fn new(
        start: &Start,
        model: &ModelSpec,
        e: &[RowError],
        margin: &[f64],
        predictive: &[EffectId],
    ) -> Self {
        let rec = start.rec;
        let again = estimate_noise(rec, &positions(e));
        let noise = if again.sigma_mm_per_axis < start.noise.sigma_mm_per_axis
            || !start.noise.sigma_mm_per_axis.is_finite()
        {
            again
        } else {
            start.noise.clone()
        };
        // outliers judged on what is left after the physics and the empirical term: a
        // structured residual is spread, not outlying
        let (empirical, correction, left) =
            hybrid::fit(rec, e, &start.held, start.huber_mm(), start.threads);
        let (outliers, outlier_threshold_mm) = outlier_rows(rec, &left);
        let stability = Stability::new(rec, start.warn_margin, &start.margin0, margin, &outliers);
        let inliers = inlier_figures(rec, e, &start.held, &outliers);
        let at_noise = inliers.heldout_score() <= NOISE_TOLERANCE * noise.weighted_rms();
        // the noise reached with findings whose form the data do not establish is no
        // explanation: something outside the vocabulary may act like them
        let explained = at_noise && predictive.is_empty();
        let leaning_on = if at_noise {
            predictive.to_vec()
        } else {
            Vec::new()
        };
        // what no physics explains, learned over the joints and their history
        let learned = (!at_noise).then(|| gp::fit(start, model, e)).flatten();
        let (empirical, discrepancy) = match learned {
            Some((account, d, _, cv)) if cv.helps() => (account, Some(d)),
            Some((_, _, _, cv)) => {
                let mut empirical = empirical;
                empirical.method += &format!(
                    "; the learned discrepancy (a Gaussian process over the joints and their \
                     history) is not offered: cross-validated over {} folds of the fit rows it \
                     leaves {:.3} mm against the physics' {:.3} mm",
                    gp::CV_FOLDS,
                    cv.learned_mm,
                    cv.physics_mm
                );
                (empirical, None)
            }
            None => (empirical, None),
        };
        Verdict {
            noise,
            empirical,
            correction,
            discrepancy,
            outliers,
            outlier_threshold_mm,
            stability,
            inliers,
            explained,
            leaning_on,
        }
    }

    /// Where the residual is at the noise, `predictive` (the findings graded predictive
    /// in the end) are what it leans on: not explained when there are any.
    pub(crate) fn lean_on(&mut self, predictive: impl Iterator<Item = EffectId>) {
        if self.explained || !self.leaning_on.is_empty() {
            self.leaning_on = predictive.collect();
            self.explained = self.leaning_on.is_empty();
        }
    }

    /// What is left, in words, the fitted model's figures being `fig` (`where_left`
    /// says where).
    pub(crate) fn in_words(
        &self,
        start: &Start,
        fig: &Figures,
        where_left: impl FnOnce() -> String,
    ) -> String {
        if !self.noise.sigma_mm_per_axis.is_finite() {
            return format!(
                "cannot tell whether what is left ({:.3} mm held out) is noise: the noise is {}",
                self.inliers.heldout_rms_mm, self.noise.method
            );
        }
        if !self.leaning_on.is_empty() {
            let names: Vec<&str> = self.leaning_on.iter().map(|c| c.as_str()).collect();
            return format!(
                "residual reaches the noise ({:.3} mm held out against {:.3} mm) only with \
                 findings whose form the data do not establish ({}): something outside the \
                 vocabulary may act like them, so the recording is not called explained",
                self.inliers.heldout_rms_mm,
                self.noise.rms_mm,
                names.join(", ")
            );
        }
        leftover(
            start.rec,
            fig,
            &self.inliers,
            &self.outliers,
            &self.stability.outlier_lines_near_snap,
            self.outlier_threshold_mm,
            &self.noise,
            self.explained,
            where_left,
        )
    }
}

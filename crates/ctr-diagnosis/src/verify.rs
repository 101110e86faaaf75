//! The checks every finding of the search must pass, with all the other findings in
//! place, before the report calls it physics. A wrong confident finding is the worst
//! output of a diagnosis; these checks trade a little sensitivity for that.
//!
//! Let `M` be the fitted model with its findings, `e` its error on every row and `h`
//! its held-out RMS; `sigma_n` the noise estimate's RMS. For a finding `c` with `k`
//! parameters:
//!
//! 1. **It beats a generic correction of its size** ([`empirical`]). Take `c` out of
//!    `M` (the others stay as fitted); fit the best `k`-term empirical correction to
//!    that model's error on the fit rows; its held-out RMS `h_emp` must be clearly
//!    above `h`: `h < (1 - MIN_GAIN_OVER_EMPIRICAL) h_emp`. Where `M` leaves nothing
//!    but noise on the held-out rows (`h <= NOISE_TOLERANCE sigma_n`) the check passes:
//!    both then explain everything, and the physics is the hypothesis.
//! 2. **Its signature is gone from what it leaves.** An effect claims a fixed set of
//!    parameters: its error is `J_c(q) dx` with `J_c` the derivative of the tip
//!    with respect to its parameters and `dx` constant over the rows. If the residual
//!    still holds `J_c(q) dx(q)` with `dx` varying with a feature of the rows (a joint,
//!    time, the tip position: [`empirical::Basis`]), the effect stands in for something
//!    else (a feed *offset* where the feed *gain* is wrong). The `k` most useful
//!    fields `J_c,j(q) phi_m(q)` are picked on the fit rows; the check fails when,
//!    on the held-out rows, they remove at least [`MAX_SIGNATURE_SHARE`] of what `M`
//!    leaves above the noise and clearly more than the generic correction of as many
//!    terms does on the same residual.
//!
//! A finding that fails is taken out, the others are refitted together, and the checks
//! run again until every finding passes.

use crate::candidates::EffectId;
use crate::empirical::{self, Basis, Field};
use crate::fit::Problem;
use crate::noise::NOISE_TOLERANCE;
use crate::residual::{errors, figures};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_formats::Recording;

/// Smallest relative margin by which the model's held-out RMS must undercut that of
/// the generic empirical correction with as many free parameters, with the finding
/// taken out, for the finding to count as physics.
pub const MIN_GAIN_OVER_EMPIRICAL: f64 = 0.02;
/// Largest share of the residual's excess over the noise (held-out, squared) that the
/// finding's own signature with varying parameters may still explain.
pub const MAX_SIGNATURE_SHARE: f64 = 0.5;

/// What the checks run on.
pub(crate) struct Context<'a> {
    pub(crate) rec: &'a Recording,
    /// Whether each row is held out.
    pub(crate) held: &'a [bool],
    /// Huber threshold of the fits, mm.
    pub(crate) huber_mm: f64,
    /// Worker threads.
    pub(crate) threads: usize,
    /// The noise estimate's RMS, mm.
    pub(crate) noise_rms_mm: f64,
}

/// Why a finding failed its checks.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Failure {
    /// A generic correction of as many parameters does as well.
    Empirical {
        /// Its held-out RMS, mm.
        heldout_rms_mm: f64,
    },
    /// The effect's parameters vary with a feature of the rows.
    Varying {
        /// The feature they vary with most.
        feature: String,
        /// Held-out RMS with the varying parameters, mm.
        heldout_rms_mm: f64,
    },
}

/// A finding's checks.
#[derive(Clone, Debug)]
pub(crate) struct Checked {
    pub(crate) effect: EffectId,
    /// Held-out RMS of the generic correction of the finding's size, the finding taken
    /// out (NaN for torsion, which has no parameter), mm.
    pub(crate) empirical_heldout_rms_mm: f64,
    pub(crate) failure: Option<Failure>,
}

impl Context<'_> {
    fn fit_mask(&self) -> Vec<bool> {
        self.held.iter().map(|h| !h).collect()
    }

    fn errors_of(&self, m: &ModelSpec) -> Option<Vec<[f64; 3]>> {
        let all: Vec<usize> = (0..self.rec.runs.len()).collect();
        predict(m, self.rec, &all)
            .ok()
            .map(|p| errors(self.rec, &p.p))
    }

    fn tips(&self, e: &[[f64; 3]]) -> Vec<[f64; 3]> {
        self.rec
            .rows
            .iter()
            .zip(e)
            .map(|(r, v)| [r.p[0] + v[0], r.p[1] + v[1], r.p[2] + v[2]])
            .collect()
    }

    /// Held-out RMS of `e` after the best `k`-term generic correction fitted to it.
    fn empirical_heldout(&self, e: &[[f64; 3]], k: usize) -> f64 {
        let fit = self.fit_mask();
        let basis = Basis::new(self.rec, &self.tips(e), &fit);
        let w = empirical::weights(e, &fit, self.huber_mm);
        let left = empirical::greedy(&basis, e, &w, k).apply(&basis, e);
        figures(&left, self.held).heldout_rms_mm
    }

    /// Checks finding `c` of `m` (whose error is `e`, held-out RMS `h`).
    pub(crate) fn check(&self, m: &ModelSpec, e: &[[f64; 3]], c: EffectId) -> Checked {
        let n = m.robot.n_tubes();
        let k = c.n_params(n);
        let h = figures(e, self.held).heldout_rms_mm;
        let at_noise = h <= NOISE_TOLERANCE * self.noise_rms_mm;
        let mut out = Checked {
            effect: c,
            empirical_heldout_rms_mm: f64::NAN,
            failure: None,
        };
        if k == 0 {
            return out;
        }
        // 1. against a generic correction of its size, the finding taken out
        let mut without = m.clone();
        c.remove(&mut without);
        if let Some(e_without) = self.errors_of(&without) {
            let h_emp = self.empirical_heldout(&e_without, k);
            out.empirical_heldout_rms_mm = h_emp;
            if !at_noise && h >= (1.0 - MIN_GAIN_OVER_EMPIRICAL) * h_emp {
                out.failure = Some(Failure::Empirical {
                    heldout_rms_mm: h_emp,
                });
                return out;
            }
        }
        if at_noise {
            return out;
        }
        // 2. its own signature, with parameters that vary over the rows
        if let Some((feature, h_vc)) = self.varying_signature(m, e, c) {
            let excess = h * h - self.noise_rms_mm * self.noise_rms_mm;
            let share = (h * h - h_vc * h_vc) / excess.max(f64::MIN_POSITIVE);
            let h_gen = self.empirical_heldout(e, k);
            if share >= MAX_SIGNATURE_SHARE && h_vc < (1.0 - MIN_GAIN_OVER_EMPIRICAL) * h_gen {
                out.failure = Some(Failure::Varying {
                    feature,
                    heldout_rms_mm: h_vc,
                });
            }
        }
        out
    }

    /// The held-out RMS of `e` after the best `k` fields `J_c,j phi_m` (the effect's
    /// parameter directions times a varying feature), and the feature chosen first.
    fn varying_signature(
        &self,
        m: &ModelSpec,
        e: &[[f64; 3]],
        c: EffectId,
    ) -> Option<(String, f64)> {
        let rows = self.rec.rows.len();
        let problem = Problem {
            base: m.clone(),
            blocks: vec![c],
            rec: self.rec,
            runs: (0..self.rec.runs.len()).collect(),
            rows: (0..rows).collect(),
            huber_mm: self.huber_mm,
            threads: self.threads,
            clearance_table: None,
        };
        let x = c.read(m);
        let p0 = problem.predictions(&x)?;
        let jac = problem.jacobian(&x, &p0)?;
        let fit = self.fit_mask();
        let basis = Basis::new(self.rec, &self.tips(e), &fit);
        let mut fields: Vec<Field> = Vec::new();
        let mut names = Vec::new();
        for j in 0..jac.ncols() {
            for (feature, col) in basis.varying() {
                fields.push(
                    (0..rows)
                        .map(|r| {
                            let d = |a: usize| jac[(3 * r + a, j)] * col[r];
                            [d(0), d(1), d(2)]
                        })
                        .collect(),
                );
                names.push(feature.name());
            }
        }
        let w = empirical::weights(e, &fit, self.huber_mm);
        let terms = empirical::pursue(&fields, e, &w, c.n_params(m.robot.n_tubes()));
        let first = terms.first().map(|&(i, _)| names[i].clone())?;
        let left = empirical::subtract(&fields, &terms, e);
        Some((first, figures(&left, self.held).heldout_rms_mm))
    }
}

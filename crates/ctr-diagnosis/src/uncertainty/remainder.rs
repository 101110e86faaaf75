//! The findings' parameters with the unexplained remainder modelled: when the report
//! says `explained: false`, something outside the vocabulary is in the residual, and
//! the physical parameters may have soaked part of it up (a feed play taking a tracker's
//! drift). Intervals that cover only the noise would then be too sure.
//!
//! The remainder is modelled by the labelled empirical correction the diagnosis fits
//! on the same rows (its chosen terms `B`, each a standardised feature on one axis, see
//! [`crate::empirical`]). The parameters and the terms' coefficients are fitted
//! together, linearised at `x`: with `A = [J B]`,
//!
//! ```text
//! (delta, gamma) = -(A^T W A)^+ A^T W e,   x' = x + delta,
//! Sigma' = s'^2 (A^T W A)^+_xx (scaled by each parameter's sandwich inflation),
//! ```
//!
//! `s'^2` the weighted residual variance left by both. `x' - x` is the parameters'
//! sensitivity to the remainder (the omitted-variable shift), `Sigma'` their
//! uncertainty once the terms compete for the same residual (larger where the terms can
//! mimic a finding). The reported interval is the union of the interval at `x` and the
//! one at `x'`: honest whichever of the two explanations of the remainder holds.

use super::{pseudo_inverse, Assessment};
use crate::fit::Problem;
use ctr_formats::Correction;
use nalgebra::{DMatrix, DVector};

/// The findings refitted with the remainder's empirical terms.
#[derive(Clone, Debug)]
pub(crate) struct WithRemainder {
    /// The parameters (within the fit's bounds).
    pub x: Vec<f64>,
    /// Their covariance.
    pub cov: DMatrix<f64>,
    /// The empirical terms used.
    pub terms: usize,
}

/// Most Gauss-Newton steps of the joint refit (each one simulation; the Jacobian of the
/// findings stays the one at `x`).
const MAX_STEPS: usize = 8;

impl Assessment {
    /// The parameters refitted together with the terms of `correction` (`None` when it
    /// has none or the model cannot be simulated at `x`).
    pub(crate) fn with_remainder(
        &self,
        problem: &Problem,
        correction: &Correction,
    ) -> Option<WithRemainder> {
        let m = correction.terms.len();
        if m == 0 {
            return None;
        }
        let np = self.x.len();
        let p = problem.predictions(&self.x)?;
        let e = problem.errors(&p);
        let (_, w) = problem.cost(&e);
        let mut a = DMatrix::<f64>::zeros(e.len(), np + m);
        a.view_mut((0, 0), (e.len(), np)).copy_from(&self.jac);
        for (k, &r) in problem.rows.iter().enumerate() {
            let row = &problem.rec.rows[r];
            let tip = [p[3 * k], p[3 * k + 1], p[3 * k + 2]];
            for (i, t) in correction.terms.iter().enumerate() {
                let v = (t.feature.value(&row.q, row.t_s, &tip) - t.mean) / t.scale;
                a[(3 * k + t.axis, np + i)] = v;
            }
        }
        let weight = |i: usize| w.get(i / 3).copied().unwrap_or(1.0);
        let mut n = DMatrix::<f64>::zeros(np + m, np + m);
        for i in 0..e.len() {
            let ai = a.row(i);
            n += (ai.transpose() * ai) * weight(i);
        }
        let (n_pinv, null, _) = pseudo_inverse(&n);
        let rank = np + m - null.len();
        // the joint weighted squared error left at `x` (the terms at their best), the
        // step towards the joint minimum
        let joint = |e: &[f64]| -> (f64, DVector<f64>) {
            let mut g = DVector::<f64>::zeros(np + m);
            for (i, v) in e.iter().enumerate() {
                g += a.row(i).transpose() * (weight(i) * v);
            }
            let step = -(&n_pinv * g);
            let mut left = DVector::from_column_slice(e);
            left += a.view((0, np), (e.len(), m)) * step.rows(np, m);
            let sse = (0..e.len()).map(|i| weight(i) * left[i] * left[i]).sum();
            (sse, step)
        };
        let (mut sse, mut step) = joint(&e);
        let mut x = self.x.clone();
        for _ in 0..MAX_STEPS {
            let next = self.clamped((0..np).map(|j| x[j] + step[j]).collect());
            let Some(p) = problem.predictions(&next) else {
                break;
            };
            let (s, st) = joint(&problem.errors(&p));
            if s >= sse {
                break;
            }
            (x, sse, step) = (next, s, st);
        }
        let s2 = sse / (e.len().saturating_sub(rank)).max(1) as f64;
        // each parameter's sandwich inflation of the classical variance, kept
        let inflation: Vec<f64> = (0..np)
            .map(|j| {
                let c = self.classic[(j, j)];
                if c > 0.0 {
                    (self.cov[(j, j)] / c).max(1.0).sqrt()
                } else {
                    1.0
                }
            })
            .collect();
        let cov = DMatrix::from_fn(np, np, |i, j| {
            s2 * n_pinv[(i, j)] * inflation[i] * inflation[j]
        });
        Some(WithRemainder { x, cov, terms: m })
    }
}

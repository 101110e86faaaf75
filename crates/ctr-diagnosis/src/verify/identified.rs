//! Check 3 of a finding: its parameters are identified, told from the nominal by the
//! data (see the module docs of [`crate::verify`]).

use super::{Context, Failure};
use crate::candidates::EffectId;
use crate::quantiles::{chi2_95, Z975};
use crate::uncertainty::{self, Assessment};
use ctr_analysis::model::ModelSpec;
use nalgebra::{DMatrix, DVector};

/// Eigenvalue of a finding's correlation block, relative to its largest, below which
/// its direction counts as not identified in the Wald test (a parameter pinned only
/// with others).
const WALD_RANK_CUTOFF: f64 = 1e-8;

impl Context<'_> {
    /// Check 3 on the findings `accepted` of `m`, fitted together on `fit_rows`
    /// against the user's model `user`: the failure of each finding whose parameters
    /// the data do not tell from the nominal, and the assessment they were judged on
    /// (the report's intervals, when nothing fails). No failure when the covariance
    /// cannot be computed (the other checks stand alone then).
    pub(crate) fn identified(
        &self,
        m: &ModelSpec,
        user: &ModelSpec,
        accepted: &[EffectId],
        fit_rows: &[usize],
    ) -> (Vec<(EffectId, Failure)>, Option<Assessment>) {
        if !self.checks.identified {
            return (Vec::new(), None);
        }
        let problem = uncertainty::attach::problem_of(
            self.rec,
            m,
            accepted,
            fit_rows,
            self.huber_mm,
            self.threads,
        );
        let x = problem.read(m);
        let nominal = problem.read(user);
        let Some(a) = Assessment::new(&problem, &x, &nominal) else {
            return (Vec::new(), None);
        };
        let failures = problem
            .blocks
            .iter()
            .filter_map(|&c| {
                let (statistic, threshold) = wald(&a, c)?;
                if statistic <= threshold {
                    Some((
                        c,
                        Failure::NotIdentified {
                            statistic,
                            threshold,
                        },
                    ))
                } else {
                    let absent = self.checks.present && !present_beyond_doubt(&a, c);
                    absent.then_some((c, Failure::MaybeAbsent))
                }
            })
            .collect();
        (failures, Some(a))
    }
}

/// Whether at least one of `c`'s parameters that has a "not there" value (its
/// [`EffectId::absence_of`]) has a 95 % interval `x_j +/- t sd_j` that excludes its
/// nominal, the user's model having no such effect. Where some of its parameters are
/// not identified alone (stiffness factors, of which kinematics see only ratios) the
/// Wald test of the block, on the directions identified, has decided: present.
fn present_beyond_doubt(a: &Assessment, c: EffectId) -> bool {
    let idx: Vec<usize> = (0..a.x.len()).filter(|&j| a.effects[j] == c).collect();
    if idx.iter().any(|&j| a.unidentified[j]) {
        return true;
    }
    idx.iter().enumerate().any(|(i, &j)| {
        let sd = a.cov[(j, j)].max(0.0).sqrt();
        c.absence_of(i)
            && !a.unidentified[j]
            && sd.is_finite()
            && (a.x[j] - a.nominal[j]).abs() > a.t * sd
    })
}

/// The Wald test of `c`'s parameters against the nominal: `d^T Sigma_cc^+ d` (`d`
/// fitted less nominal, `Sigma_cc` their covariance block, inverted on the
/// directions identified) and the 95 % threshold it must exceed: the chi-square
/// quantile of the block's rank x `(t / z)^2` for the clusters' few degrees of
/// freedom. `None` when `c` has no parameter here.
fn wald(a: &Assessment, c: EffectId) -> Option<(f64, f64)> {
    let idx: Vec<usize> = (0..a.x.len()).filter(|&j| a.effects[j] == c).collect();
    if idx.is_empty() {
        return None;
    }
    let k = idx.len();
    let sd: Vec<f64> = idx.iter().map(|&j| a.cov[(j, j)].max(0.0).sqrt()).collect();
    // the block scaled to a unit diagonal, so the cut-off is relative
    let scaled = DMatrix::from_fn(k, k, |i, j| {
        let s = sd[i] * sd[j];
        if s > 0.0 {
            a.cov[(idx[i], idx[j])] / s
        } else {
            0.0
        }
    });
    let d = DVector::from_fn(k, |i, _| {
        if sd[i] > 0.0 {
            (a.x[idx[i]] - a.nominal[idx[i]]) / sd[i]
        } else {
            0.0
        }
    });
    let eig = scaled.symmetric_eigen();
    let top = eig.eigenvalues.amax();
    let mut stat = 0.0;
    let mut rank = 0;
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        if l > WALD_RANK_CUTOFF * top {
            stat += eig.eigenvectors.column(i).dot(&d).powi(2) / l;
            rank += 1;
        }
    }
    if rank == 0 {
        return Some((0.0, f64::INFINITY));
    }
    Some((stat, chi2_95(rank) * (a.t / Z975).powi(2)))
}

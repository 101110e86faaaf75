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
                let test = wald(&a, c)?;
                if test.statistic <= test.threshold {
                    Some((c, Failure::NotIdentified(test)))
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

/// A finding's joint test against the nominal ([`wald`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Wald {
    /// `d^T Sigma^+ d` over the parameters counted.
    pub(crate) statistic: f64,
    /// The 95 % threshold it must exceed.
    pub(crate) threshold: f64,
    /// Parameters fitted on a bound of the fit where their nominal sits (a play or a
    /// deflection of 0, at least 0): not counted, the test conditional on them.
    pub(crate) at_edge: usize,
}

/// The Wald test of `c`'s parameters against the nominal: `d^T Sigma_cc^+ d` (`d`
/// fitted less nominal, `Sigma_cc` their covariance block, inverted on the
/// directions identified) and the 95 % threshold it must exceed: the chi-square
/// quantile of the block's rank, x `(t / z)^2` for the clusters' few degrees of
/// freedom.
///
/// A test a bound cannot dilute. Where a parameter's nominal sits on a bound of the
/// fit (a play or a deflection of 0: at least 0), its estimate falls on that bound
/// about half the time when the nominal is true, and the chi-square of the whole
/// block is not the statistic's distribution there. The parameters fitted on such a
/// bound sit at their nominal; they are left out, and the test is conditional on
/// where they are: given which parameters are on the bound, the others' statistic is
/// chi-square of their rank (exact for parameters estimated independently: each one
/// off its bound is a squared normal given its side). The unconditional alternative,
/// the chi-bar-squared mixture over every parameter that may fall on its bound (Self
/// and Liang 1987; Kodde and Palm 1986), spends its size on the parameters the data
/// cannot move; this one counts only what they do move. `None` when `c` has no
/// parameter here.
fn wald(a: &Assessment, c: EffectId) -> Option<Wald> {
    let all: Vec<usize> = (0..a.x.len()).filter(|&j| a.effects[j] == c).collect();
    if all.is_empty() {
        return None;
    }
    let pick = |v: &[f64]| all.iter().map(|&j| v[j]).collect::<Vec<f64>>();
    let cov = DMatrix::from_fn(all.len(), all.len(), |i, j| a.cov[(all[i], all[j])]);
    let on_edge: Vec<bool> = all.iter().map(|&j| a.on_edge(j) == Some(true)).collect();
    Some(wald_on(&pick(&a.x), &pick(&a.nominal), &cov, &on_edge, a.t))
}

/// [`wald`] of parameters `x` against `nominal` with covariance `cov`, those with
/// `on_edge` (fitted on the bound where their nominal sits) not counted, `t` the
/// 97.5 % quantile the intervals use.
fn wald_on(x: &[f64], nominal: &[f64], cov: &DMatrix<f64>, on_edge: &[bool], t: f64) -> Wald {
    let idx: Vec<usize> = (0..x.len()).filter(|&j| !on_edge[j]).collect();
    let at_edge = x.len() - idx.len();
    let k = idx.len();
    let sd: Vec<f64> = idx.iter().map(|&j| cov[(j, j)].max(0.0).sqrt()).collect();
    // the block scaled to a unit diagonal, so the cut-off is relative
    let scaled = DMatrix::from_fn(k, k, |i, j| {
        let s = sd[i] * sd[j];
        if s > 0.0 {
            cov[(idx[i], idx[j])] / s
        } else {
            0.0
        }
    });
    let d = DVector::from_fn(k, |i, _| {
        if sd[i] > 0.0 {
            (x[idx[i]] - nominal[idx[i]]) / sd[i]
        } else {
            0.0
        }
    });
    let mut stat = 0.0;
    let mut rank: usize = 0;
    if k > 0 {
        let eig = scaled.symmetric_eigen();
        let top = eig.eigenvalues.amax();
        for (i, &l) in eig.eigenvalues.iter().enumerate() {
            if l > WALD_RANK_CUTOFF * top {
                stat += eig.eigenvectors.column(i).dot(&d).powi(2) / l;
                rank += 1;
            }
        }
    }
    let threshold = if rank == 0 {
        f64::INFINITY
    } else {
        chi2_95(rank) * (t / Z975).powi(2)
    };
    Wald {
        statistic: stat,
        threshold,
        at_edge,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ctr_analysis::rng::Rng;

    /// Draws of the size and power tests.
    const DRAWS: usize = 4_000;

    /// Parameters at least 0 with nominal 0, estimated independently with unit
    /// variance: the estimate is `max(0, theta + z)`, on the bound when it clips.
    fn clipped(theta: &[f64], rng: &mut Rng) -> (Vec<f64>, Vec<bool>) {
        let x: Vec<f64> = theta.iter().map(|t| (t + rng.normal()).max(0.0)).collect();
        let on_edge = x.iter().map(|&v| v == 0.0).collect();
        (x, on_edge)
    }

    fn rejects(theta: &[f64], seed: u64, conditional: bool) -> f64 {
        let mut rng = Rng::new(seed);
        let k = theta.len();
        let cov = DMatrix::identity(k, k);
        let nominal = vec![0.0; k];
        let hits = (0..DRAWS)
            .filter(|_| {
                let (x, on_edge) = clipped(theta, &mut rng);
                let counted = if conditional { on_edge } else { vec![false; k] };
                let w = wald_on(&x, &nominal, &cov, &counted, Z975);
                w.statistic > w.threshold
            })
            .count();
        hits as f64 / DRAWS as f64
    }

    #[test]
    fn the_test_keeps_its_size_at_a_bound() {
        // four plays of 0: the estimates clip at the bound half the time; the test
        // conditional on them rejects about 5 % of the draws (it may be conservative
        // where all clip: nothing is tested then)
        let size = rejects(&[0.0; 4], 5, true);
        assert!((0.03..=0.065).contains(&size), "size {size}");
    }

    #[test]
    fn a_bound_does_not_dilute_the_parameter_the_data_move() {
        // one play 3 standard deviations from 0 beside three the data leave at 0: the
        // whole block's chi-square (4 degrees of freedom) misses it far more often
        // than the test that leaves out the ones on the bound
        let theta = [3.0, 0.0, 0.0, 0.0];
        let (conditional, whole) = (rejects(&theta, 7, true), rejects(&theta, 7, false));
        assert!(conditional > whole + 0.15, "{conditional} against {whole}");
        // about 0.73: chi-square(1) of the play when the others clip, more degrees of
        // freedom when some do not
        assert!(conditional > 0.65, "{conditional}");
    }
}

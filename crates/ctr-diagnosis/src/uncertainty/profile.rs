//! The interval of one output `g(x)` (a file-form value) checked against the cost, and
//! profiled where the Wald interval misreads it.
//!
//! With `C = s^2 H^+` the classical covariance, `Sigma` the reported one (the larger
//! variances) and `a = grad g`, the linearised profile of `g` is the path
//! `x(d) = x + d C a / (a^T C a)`: where the other parameters go, to first order, when
//! `g` is moved by `d` and they follow at their best. Along it the robust cost rises by
//! `d^2 s^2 / (a^T C a)` if the problem is linear, so the profile deviance
//!
//! ```text
//! D(d) = (cost(x(d)) - cost(x)) / (s^2 kappa),   kappa = a^T Sigma a / a^T C a
//! ```
//!
//! reaches `t^2` exactly at the Wald end `d = t sqrt(a^T Sigma a)` (kappa carries the
//! sandwich's inflation into the cost's scale). Each point of the path is moved to its
//! constrained best by one Gauss-Newton step with the Jacobian at `x`, `g` held
//! (`delta = -H^+ (r - a lambda)`, `r = J^T W e`, `lambda = a^T H^+ r / a^T H^+ a`), so a
//! curved valley (a registration's rotation and translation) is followed, not cut.
//!
//! At each end the deviance is evaluated first at the Wald end. Where `sqrt(D) / t` lies
//! within [`AGREES_WITHIN`] of 1 the Wald end stands (the problem is linear enough there);
//! elsewhere the end moves to where the deviance crosses `t^2`, found by the one-sided
//! quadratic step `d <- d t / sqrt(D)` (exact for a quadratic, at most [`MAX_GROWTH`]
//! per step, [`MAX_STEPS`] cost evaluations, within [`CONVERGED_WITHIN`]). The path stops
//! at the first bound of a parameter that moves `g` along it: an end reaching a bound with the
//! deviance still below `t^2` is the bound (the data cannot exclude it), the boundary
//! case a Wald interval clipped there only approximates. The end's value is `g` at the
//! point reached, so a non-linear output map (an axis normalised, a factor `exp`) is
//! followed too.

use super::Assessment;
use crate::fit::Problem;
use nalgebra::DVector;

/// Wald's end stands where `sqrt(D) / t` at it is within this factor of 1 (its
/// half-width then within the factor of the profile's).
pub const AGREES_WITHIN: f64 = 1.25;
/// The search stops where `sqrt(D) / t` is within this of 1.
const CONVERGED_WITHIN: f64 = 0.05;
/// Most growth (or shrinking) of `d` per step of the search.
const MAX_GROWTH: f64 = 4.0;
/// Most cost evaluations of one end's search after the first.
const MAX_STEPS: usize = 6;
/// Share of the output's change along the path (`a_k dir_k`, summing to 1) from which
/// a parameter's bound stops the path.
const MOVES_OUTPUT: f64 = 0.01;
/// Farthest an end may go, in Wald half-widths.
const MAX_WIDEN: f64 = 16.0;

/// One end of an output's interval.
pub(crate) struct End {
    /// Where the output is there (`None`: the Wald end stands).
    pub value: Option<f64>,
}

impl Assessment {
    /// `J^T W e` of errors `e` with weights `w`.
    fn gradient(&self, e: &[f64], w: &[f64]) -> DVector<f64> {
        let mut r = DVector::<f64>::zeros(self.x.len());
        for (i, wi) in w.iter().enumerate() {
            for ax in 0..3 {
                r += self.jac.row(3 * i + ax).transpose() * (wi * e[3 * i + ax]);
            }
        }
        r
    }

    /// The cost the profiles' deviances are measured from: the lower of the cost at
    /// `x` and after one free Gauss-Newton step from it (so that a fit stopped short of
    /// its minimum does not read as a flat profile).
    fn reference(&self, problem: &Problem) -> f64 {
        *self.reference.get_or_init(|| {
            let stepped = problem.predictions(&self.x).and_then(|p| {
                let e = problem.errors(&p);
                let (_, w) = problem.cost(&e);
                let step = -(&self.classic / self.s2) * self.gradient(&e, &w);
                let x = self.clamped((0..self.x.len()).map(|k| self.x[k] + step[k]).collect());
                problem.cost_at(&x)
            });
            stepped.map_or(self.cost, |c| c.min(self.cost))
        })
    }

    /// The end of the interval of output `o` of `out` (gradient `a` over all parameters,
    /// `deps` the parameters it depends on) on side `sign` (`-1` low, `+1` high).
    pub(crate) fn profile_end(
        &self,
        problem: &Problem,
        out: &(dyn Fn(&[f64]) -> Vec<f64> + Sync),
        o: usize,
        a: &DVector<f64>,
        deps: &[usize],
        sign: f64,
    ) -> End {
        let np = self.x.len();
        let ca = &self.classic * a;
        let var_c = a.dot(&ca);
        let var_r = (a.transpose() * &self.cov * a)[(0, 0)];
        let none = End { value: None };
        if !(var_c > 0.0 && var_r > 0.0 && self.s2 > 0.0) {
            return none;
        }
        let kappa = var_r / var_c;
        let dir = ca * (sign / var_c);
        let wald = self.t * var_r.sqrt();
        // the path stops at the first bound of a parameter that moves the output along it
        // (`stop`: that parameter and its bound)
        let (limit, stop) = deps
            .iter()
            .filter(|&&k| (a[k] * dir[k]).abs() >= MOVES_OUTPUT)
            .filter_map(|&k| {
                let (lo, hi) = self.bounds[k];
                match dir[k] {
                    v if v > 0.0 => Some(((hi - self.x[k]) / v, Some((k, hi)))),
                    v if v < 0.0 => Some(((lo - self.x[k]) / v, Some((k, lo)))),
                    _ => None,
                }
            })
            .fold(
                (MAX_WIDEN * wald, None),
                |m, c| if c.0 < m.0 { c } else { m },
            );
        let limit = limit.max(0.0);
        let h_pinv = &self.classic / self.s2;
        let ha = &h_pinv * a;
        let a_ha = a.dot(&ha);
        let reference = self.reference(problem);
        // the deviance at `d` and the point reached
        let deviance = |d: f64| -> Option<(f64, Vec<f64>)> {
            // at the limit the bound itself, not the rounding of `x + d dir` next to it
            let at_limit = |mut x: Vec<f64>| {
                if let (true, Some((k, bound))) = (d >= limit, stop) {
                    x[k] = bound;
                }
                x
            };
            let x1 = at_limit(self.clamped((0..np).map(|k| self.x[k] + d * dir[k]).collect()));
            let e = problem.errors(&problem.predictions(&x1)?);
            let (c1, w) = problem.cost(&e);
            // one Gauss-Newton step of the others, g held, with the Jacobian at x
            let r = self.gradient(&e, &w);
            let lambda = if a_ha > 0.0 { ha.dot(&r) / a_ha } else { 0.0 };
            let step = -(&h_pinv * (r - a * lambda));
            let x2 = at_limit(self.clamped((0..np).map(|k| x1[k] + step[k]).collect()));
            let (c, x) = match problem.cost_at(&x2) {
                Some(c2) if c2 < c1 => (c2, x2),
                _ => (c1, x1),
            };
            Some(((c - reference) / (self.s2 * kappa), x))
        };
        let t2 = self.t * self.t;
        let mut d = wald.min(limit);
        let Some((mut dev, mut at)) = deviance(d) else {
            return none;
        };
        let ratio = |dev: f64| dev.max(0.0).sqrt() / self.t;
        if d == wald && (ratio(dev).ln().abs() <= AGREES_WITHIN.ln()) {
            return none;
        }
        for _ in 0..MAX_STEPS {
            if (ratio(dev) - 1.0).abs() <= CONVERGED_WITHIN || (d >= limit && dev <= t2) {
                break;
            }
            let grow = (1.0 / ratio(dev).max(1e-12)).clamp(1.0 / MAX_GROWTH, MAX_GROWTH);
            let next = (d * grow).min(limit);
            if next == d {
                break;
            }
            let Some((v, x)) = deviance(next) else {
                break;
            };
            (d, dev, at) = (next, v, x);
        }
        End {
            value: out(&at).get(o).copied(),
        }
    }
}

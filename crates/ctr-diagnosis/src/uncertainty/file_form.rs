//! The `ci95` of a finding in the robot file's form (see the parent module for the
//! statistics).

use super::remainder::WithRemainder;
use super::{Assessment, OUTPUT_STEP};
use crate::candidates::EffectId;
use crate::fit::Problem;
use crate::report::numbers::{leaves, replace};
use crate::report::prose::parameters;
use nalgebra::{DMatrix, DVector};
use serde_json::Value;

impl Assessment {
    /// The `ci95` of block `b` (its parameters from `at`): the file form of
    /// [`parameters`] with each number replaced by `[lo, hi]` (`null` where unbounded).
    /// `alt`: the parameters refitted with the unexplained remainder's terms, whose
    /// intervals are joined to these.
    pub fn ci95(
        &self,
        problem: &Problem,
        b: EffectId,
        at: usize,
        len: usize,
        alt: Option<&WithRemainder>,
    ) -> Value {
        let model = problem.model(&self.x);
        let template = parameters(b, &model);
        let mut v0 = Vec::new();
        leaves(&template, "", &mut v0);
        let out = |x: &[f64]| -> Vec<f64> {
            let mut v = Vec::new();
            leaves(&parameters(b, &problem.model(x)), "", &mut v);
            v.into_iter().map(|(_, v)| v).collect()
        };
        let base: Vec<f64> = v0.iter().map(|(_, v)| *v).collect();
        let degrees: Vec<bool> = v0.iter().map(|(k, _)| k.contains("_deg")).collect();
        let unwrap = |o: usize, v: f64| -> f64 {
            if degrees[o] {
                base[o] + (v - base[o] + 180.0).rem_euclid(360.0) - 180.0
            } else {
                v
            }
        };
        // derivatives of the file values with respect to the block's parameters
        let mut g = DMatrix::<f64>::zeros(base.len(), len);
        for j in 0..len {
            let h = OUTPUT_STEP * self.steps[at + j];
            let mut x = self.x.clone();
            x[at + j] += h;
            for (o, v) in out(&x).into_iter().enumerate().take(base.len()) {
                g[(o, j)] = (unwrap(o, v) - base[o]) / h;
            }
        }
        let deps_of = |o: usize| -> Vec<usize> {
            let row = g.row(o);
            let big = row.amax();
            (0..len)
                .filter(|&j| big > 0.0 && row[j].abs() > 1e-9 * big)
                .collect()
        };
        let unwrapped = |x: &[f64]| -> Vec<f64> {
            out(x)
                .into_iter()
                .enumerate()
                .map(|(o, v)| unwrap(o, v))
                .collect()
        };
        // each identified output's ends checked against the cost (profiled where the
        // Wald interval misreads it), both sides of every output in parallel
        let tasks: Vec<(usize, f64)> = (0..base.len())
            .filter(|&o| {
                let deps = deps_of(o);
                !deps.is_empty() && deps.iter().all(|&j| !self.unidentified[at + j])
            })
            .flat_map(|o| [(o, -1.0), (o, 1.0)])
            .collect();
        let ends = ctr_formats::parallel::map(&tasks, problem.threads.max(1), |&(o, sign)| {
            let mut a = DVector::<f64>::zeros(self.x.len());
            for j in 0..len {
                a[at + j] = g[(o, j)];
            }
            let deps: Vec<usize> = deps_of(o).into_iter().map(|j| at + j).collect();
            self.profile_end(problem, &unwrapped, o, &a, &deps, sign)
                .value
        });
        let profiled = |o: usize, sign: f64| -> Option<f64> {
            tasks
                .iter()
                .position(|&(p, s)| p == o && s == sign)
                .and_then(|k| ends[k])
        };
        let mut ints: Vec<[Option<f64>; 2]> = Vec::with_capacity(base.len());
        for o in 0..base.len() {
            let row = g.row(o);
            let deps = deps_of(o);
            let finite = |v: f64| v.is_finite().then_some(v);
            let mut int = match deps.as_slice() {
                [] => [Some(base[o]), Some(base[o])],
                [j] => {
                    let (lo, hi) = self.interval(at + j);
                    let mut ends = vec![base[o]];
                    let mut open = false;
                    for end in [lo, hi] {
                        if end.is_finite() {
                            let mut x = self.x.clone();
                            x[at + j] = end;
                            ends.push(unwrap(o, out(&x)[o]));
                        } else {
                            open = true;
                        }
                    }
                    if open {
                        [None, None]
                    } else {
                        let lo = ends.iter().copied().fold(f64::INFINITY, f64::min);
                        let hi = ends.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                        [finite(lo), finite(hi)]
                    }
                }
                _ if deps.iter().any(|&j| self.unidentified[at + j]) => [None, None],
                _ => {
                    let gr = row.transpose();
                    let sub = self.cov.view((at, at), (len, len));
                    let half = self.t * (gr.transpose() * sub * &gr)[(0, 0)].max(0.0).sqrt();
                    [finite(base[o] - half), finite(base[o] + half)]
                }
            };
            if let Some(v) = profiled(o, -1.0) {
                int[0] = finite(v.min(base[o]));
            }
            if let Some(v) = profiled(o, 1.0) {
                int[1] = finite(v.max(base[o]));
            }
            // joined with the interval of the parameters refitted with the remainder
            if let (Some(alt), [lo, hi]) = (alt, &mut int) {
                let joined = match deps.as_slice() {
                    [] => None,
                    _ if deps.iter().any(|&j| self.unidentified[at + j]) => None,
                    [j] => {
                        let (blo, bhi) = self.bounds[at + j];
                        let half = self.t * alt.cov[(at + j, at + j)].max(0.0).sqrt();
                        let mut ends = Vec::new();
                        for end in [alt.x[at + j] - half, alt.x[at + j] + half] {
                            let mut x = self.x.clone();
                            x[at + j] = end.clamp(blo, bhi);
                            ends.push(unwrap(o, out(&x)[o]));
                        }
                        Some((
                            ends.iter().copied().fold(f64::INFINITY, f64::min),
                            ends.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                        ))
                    }
                    _ => {
                        let gr = row.transpose();
                        let sub = alt.cov.view((at, at), (len, len));
                        let half = self.t * (gr.transpose() * sub * &gr)[(0, 0)].max(0.0).sqrt();
                        let centre = unwrap(o, out(&alt.x)[o]);
                        Some((centre - half, centre + half))
                    }
                };
                if let Some((l, h)) = joined {
                    *lo = lo.and_then(|v| finite(v.min(l)));
                    *hi = hi.and_then(|v| finite(v.max(h)));
                }
            }
            ints.push(int);
        }
        let mut it = ints.into_iter();
        replace(&template, &mut it)
    }
}

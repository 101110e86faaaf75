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

/// Half a turn, deg: an angle's interval reaching this far from its value on a side
/// holds every angle (open).
const HALF_TURN_DEG: f64 = 180.0;
/// Relative slack on [`HALF_TURN_DEG`] for the forward-difference derivative of an angle
/// that is the parameter itself (1 to rounding).
const TURN_TOLERANCE: f64 = 1e-6;

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
        let template = parameters(b, &problem.model(&self.x));
        let form = FileForm::new(self, problem, b, at, len, &template);
        let profiled = self.profiled_ends(&form);
        let mut ints: Vec<[Option<f64>; 2]> = Vec::with_capacity(form.base.len());
        for o in 0..form.base.len() {
            let base = form.base[o];
            let deps = form.deps(o);
            let mut int = self.mapped_interval(&form, o, &deps);
            if let Some(v) = profiled.end(o, -1.0) {
                int[0] = finite(v.min(base));
            }
            if let Some(v) = profiled.end(o, 1.0) {
                int[1] = finite(v.max(base));
            }
            // joined with the interval of the parameters refitted with the remainder
            if let (Some(alt), [lo, hi]) = (alt, &mut int) {
                if let Some((l, h)) = self.remainder_interval(&form, alt, o, &deps) {
                    *lo = lo.and_then(|v| finite(v.min(l)));
                    *hi = hi.and_then(|v| finite(v.max(h)));
                }
            }
            ints.push(int);
        }
        let mut it = ints.into_iter();
        replace(&template, &mut it)
    }

    /// Each identified output's ends checked against the cost (profiled where the Wald
    /// interval misreads it), both sides of every output in parallel.
    fn profiled_ends(&self, form: &FileForm) -> Profiled {
        let at = form.at;
        let tasks: Vec<(usize, f64)> = (0..form.base.len())
            .filter(|&o| {
                let deps = form.deps(o);
                !deps.is_empty() && deps.iter().all(|&j| !self.unidentified[at + j])
            })
            .flat_map(|o| [(o, -1.0), (o, 1.0)])
            .collect();
        let unwrapped = |x: &[f64]| form.unwrapped(x);
        let threads = form.problem.threads.max(1);
        let ends = ctr_formats::parallel::map(&tasks, threads, |&(o, sign)| {
            let mut a = DVector::<f64>::zeros(self.x.len());
            for j in 0..form.len() {
                a[at + j] = form.g[(o, j)];
            }
            let deps: Vec<usize> = form.deps(o).into_iter().map(|j| at + j).collect();
            self.profile_end(form.problem, &unwrapped, o, &a, &deps, sign)
                .value
        });
        Profiled { tasks, ends }
    }

    /// The Wald interval of output `o` (depending on the block's parameters `deps`):
    /// one parameter's interval mapped through the output (its end points), the delta
    /// method where it depends on several, open where one of them is not identified.
    fn mapped_interval(&self, form: &FileForm, o: usize, deps: &[usize]) -> [Option<f64>; 2] {
        let (at, base) = (form.at, form.base[o]);
        match deps {
            [] => [Some(base), Some(base)],
            // an angle with an end half a turn or more from its value: unwrapped to
            // within half a turn, that end would fold onto the other side of the circle
            // and print an interval from there to the value (a rotation offset free over
            // a whole turn, or a very wide one): every angle is possible, open
            [j] if form.degrees[o] && self.reaches_half_turn(form, o, at + j) => [None, None],
            [j] => {
                let (lo, hi) = self.interval(at + j);
                let mut ends = vec![base];
                let mut open = false;
                for end in [lo, hi] {
                    if end.is_finite() {
                        let mut x = self.x.clone();
                        x[at + j] = end;
                        ends.push(form.unwrap(o, form.raw(&x)[o]));
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
                let half = self.t * delta_variance(&self.cov, form, o).max(0.0).sqrt();
                [finite(base - half), finite(base + half)]
            }
        }
    }

    /// Whether output `o`, an angle depending on parameter `j` alone, has an end of
    /// `j`'s interval half a turn or more from its value (to first order).
    fn reaches_half_turn(&self, form: &FileForm, o: usize, j: usize) -> bool {
        let (lo, hi) = self.interval(j);
        let reach = (self.x[j] - lo).max(hi - self.x[j]) * form.g[(o, j - form.at)].abs();
        reach >= HALF_TURN_DEG * (1.0 - TURN_TOLERANCE)
    }

    /// The interval of output `o` (depending on the block's parameters `deps`) with
    /// the parameters `alt` refitted with the unexplained remainder's terms (`None`
    /// where it depends on none or on one not identified).
    fn remainder_interval(
        &self,
        form: &FileForm,
        alt: &WithRemainder,
        o: usize,
        deps: &[usize],
    ) -> Option<(f64, f64)> {
        let at = form.at;
        match deps {
            [] => None,
            _ if deps.iter().any(|&j| self.unidentified[at + j]) => None,
            [j] => {
                let (blo, bhi) = self.bounds[at + j];
                let half = self.t * alt.cov[(at + j, at + j)].max(0.0).sqrt();
                let mut ends = Vec::new();
                for end in [alt.x[at + j] - half, alt.x[at + j] + half] {
                    let mut x = self.x.clone();
                    x[at + j] = end.clamp(blo, bhi);
                    ends.push(form.unwrap(o, form.raw(&x)[o]));
                }
                Some((
                    ends.iter().copied().fold(f64::INFINITY, f64::min),
                    ends.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                ))
            }
            _ => {
                let half = self.t * delta_variance(&alt.cov, form, o).max(0.0).sqrt();
                let centre = form.unwrap(o, form.raw(&alt.x)[o]);
                Some((centre - half, centre + half))
            }
        }
    }
}

/// One block in the robot file's form as a function of the fitted parameters: the
/// numbers of its table (in [`leaves`] order), angles in degrees unwrapped to within
/// 180 deg of their value at the fit, and their derivatives there.
struct FileForm<'a> {
    problem: &'a Problem<'a>,
    b: EffectId,
    /// The block's first parameter.
    at: usize,
    /// The file values' paths in the table ([`leaves`]' names), at the fit.
    keys: Vec<String>,
    /// The file values at the fit.
    base: Vec<f64>,
    /// Whether each file value is an angle in degrees.
    degrees: Vec<bool>,
    /// The derivatives of the file values (rows) with respect to the block's
    /// parameters (columns).
    g: DMatrix<f64>,
}

impl<'a> FileForm<'a> {
    /// Block `b` of `problem` (parameters `at..at + len`) about `fit`, where its table
    /// is `template`.
    fn new(
        fit: &Assessment,
        problem: &'a Problem<'a>,
        b: EffectId,
        at: usize,
        len: usize,
        template: &Value,
    ) -> Self {
        let mut v0 = Vec::new();
        leaves(template, "", &mut v0);
        let mut form = FileForm {
            problem,
            b,
            at,
            keys: v0.iter().map(|(k, _)| k.clone()).collect(),
            base: v0.iter().map(|(_, v)| *v).collect(),
            degrees: v0.iter().map(|(k, _)| k.contains("_deg")).collect(),
            g: DMatrix::zeros(0, 0),
        };
        form.g = form.derivatives(fit, len);
        form
    }

    /// The block's parameters.
    fn len(&self) -> usize {
        self.g.ncols()
    }

    /// The file values at parameters `x`, as the file writes them, each by its path at
    /// the fit: a value the file leaves out at `x` is 0 (friction's coefficients are
    /// not written where all are 0), so that no value stands in another's place (the
    /// coefficient's interval once ended at the play's value, the next in the table).
    fn raw(&self, x: &[f64]) -> Vec<f64> {
        let mut v = Vec::new();
        leaves(&parameters(self.b, &self.problem.model(x)), "", &mut v);
        self.keys
            .iter()
            .map(|k| {
                v.iter()
                    .find(|(name, _)| name == k)
                    .map_or(0.0, |(_, x)| *x)
            })
            .collect()
    }

    /// File value `o` equal to `v`, an angle unwrapped to within 180 deg of its value
    /// at the fit.
    fn unwrap(&self, o: usize, v: f64) -> f64 {
        let base = &self.base;
        if self.degrees[o] {
            // the turn's difference first: `base + d - 180` would round `base + d` and
            // give a value that moved nothing a rounding error's derivative
            base[o] + ((v - base[o] + 180.0).rem_euclid(360.0) - 180.0)
        } else {
            v
        }
    }

    /// The file values at parameters `x`, angles unwrapped.
    fn unwrapped(&self, x: &[f64]) -> Vec<f64> {
        self.raw(x)
            .into_iter()
            .enumerate()
            .map(|(o, v)| self.unwrap(o, v))
            .collect()
    }

    /// The derivatives of the file values with respect to the block's parameters, by
    /// forward differences at [`OUTPUT_STEP`] of each parameter's scale.
    fn derivatives(&self, fit: &Assessment, len: usize) -> DMatrix<f64> {
        let base = &self.base;
        let mut g = DMatrix::<f64>::zeros(base.len(), len);
        for j in 0..len {
            let h = OUTPUT_STEP * fit.steps[self.at + j];
            let mut x = fit.x.clone();
            x[self.at + j] += h;
            for (o, v) in self.raw(&x).into_iter().enumerate().take(base.len()) {
                g[(o, j)] = (self.unwrap(o, v) - base[o]) / h;
            }
        }
        g
    }

    /// The block's parameters (from 0) file value `o` depends on.
    fn deps(&self, o: usize) -> Vec<usize> {
        let row = self.g.row(o);
        let big = row.amax();
        (0..self.len())
            .filter(|&j| big > 0.0 && row[j].abs() > 1e-9 * big)
            .collect()
    }
}

/// The ends of the outputs' intervals found along their profiles.
struct Profiled {
    /// The output and side (`-1` low, `+1` high) of each end profiled.
    tasks: Vec<(usize, f64)>,
    /// Where each end is (`None`: the Wald end stands).
    ends: Vec<Option<f64>>,
}

impl Profiled {
    /// The end of output `o` on side `sign`, where profiled and moved.
    fn end(&self, o: usize, sign: f64) -> Option<f64> {
        self.tasks
            .iter()
            .position(|&(p, s)| p == o && s == sign)
            .and_then(|k| self.ends[k])
    }
}

/// The delta method's variance `g^T Sigma g` of file value `o`, `Sigma` the block's
/// part of the covariance `cov`.
fn delta_variance(cov: &DMatrix<f64>, form: &FileForm, o: usize) -> f64 {
    let gr = form.g.row(o).transpose();
    let sub = cov.view((form.at, form.at), (form.len(), form.len()));
    (gr.transpose() * sub * &gr)[(0, 0)]
}

/// `v` where finite.
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

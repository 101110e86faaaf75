//! The next experiment: when the data leave parameters poorly identified, the simple
//! run to record that would pin them best.
//!
//! A parameter is **uncertain** when the data do not identify it alone, when it is
//! correlated above [`CORRELATED_ABOVE`] with a parameter of another effect (two effects
//! explaining the same residual), or when its 95 % interval is wider than [`WIDE`]
//! times its size (its distance from the nominal, or the RMS distance of its effect's
//! parameters of the same unit, whichever is larger). For those, every candidate
//! run on the ranges the recording visited (reachable, and stable as recorded) is
//! simulated with the fitted model at the recording's sample period:
//!
//! - each tube turned alone over its recorded range and back;
//! - each tube's feed increment swept alone over its range and back;
//! - the innermost tube turned at full extension (the most extended row's feeds);
//! - a reversal: the innermost tube turned back and forth over a quarter of its range,
//!   four times (friction and latency show at reversals);
//! - a rest: the middle configuration held (time effects).
//!
//! Its information `H_c = J_c^T J_c` (the Jacobian of its predicted tips with respect
//! to the fitted parameters) is added to the fit's, `H' = H + f H_c` with `f` the share
//! of a recording's rows a diagnosis fits, and each uncertain parameter's variance is
//! expected to become `var_j [H'^+]_jj / [H^+]_jj` (the robust covariance scaled as the
//! classical one shrinks). The run chosen minimises `sum_j ln(var'_j / var_j)` over the
//! uncertain parameters (the D-optimal choice for their variances, each alone; a
//! parameter a run makes identifiable counts as a gain of [`NEWLY_IDENTIFIED`]). It is
//! proposed only when it shrinks their intervals by [`MIN_SHRINK`] on average.

use crate::fit::Problem;
use crate::report::numbers::sig_beside;
use crate::report::{ExpectedInterval, JointRun, SuggestedRun};
use crate::uncertainty::{parts, pseudo_inverse, Assessment, CORRELATED_ABOVE};
use ctr_formats::{RecordedRow, Recording, Run};
use nalgebra::DMatrix;

/// An interval wider than this many times the parameter's distance from its nominal
/// makes it uncertain.
pub const WIDE: f64 = 0.25;
/// Smallest average shrink of the uncertain parameters' half-widths (new / now) for a
/// run to be proposed.
pub const MIN_SHRINK: f64 = 0.8;
/// Variance ratio counted for a parameter a run makes identifiable.
const NEWLY_IDENTIFIED: f64 = 1e-4;
/// Rows of a suggested run.
pub const SUGGESTED_ROWS: usize = 120;
/// Times the reversal run turns back.
const REVERSALS: usize = 4;
/// Sample period used when the recording has no time, s.
const DEFAULT_PERIOD_S: f64 = 0.1;

/// The joint a candidate run moves: a tube's feed increment or its rotation.
#[derive(Clone, Copy)]
enum Slot {
    Feed(usize),
    Turn(usize),
}

/// A candidate run in words and its joints.
struct Candidate {
    name: String,
    q: Vec<Vec<f64>>,
}

/// From `a` to `b` and back in `rows` rows.
fn out_and_back(a: f64, b: f64, rows: usize) -> Vec<f64> {
    let half = rows / 2;
    (0..rows)
        .map(|i| {
            let u = if i <= half {
                i as f64 / half.max(1) as f64
            } else {
                (rows - 1 - i) as f64 / (rows - 1 - half).max(1) as f64
            };
            a + (b - a) * u
        })
        .collect()
}

/// Joints (file order) from feed increments and rotations.
fn joints(inc: &[f64], theta: &[f64]) -> Vec<f64> {
    let mut s = 0.0;
    inc.iter()
        .zip(theta)
        .flat_map(|(d, t)| {
            s += d;
            [s, *t]
        })
        .collect()
}

/// The ranges a recording visited: each tube's feed increment (its extension beyond
/// the next outer tube) and rotation, lowest, highest and middle.
struct Ranges {
    lo_inc: Vec<f64>,
    hi_inc: Vec<f64>,
    lo_th: Vec<f64>,
    hi_th: Vec<f64>,
    mid_inc: Vec<f64>,
    mid_th: Vec<f64>,
    /// The increments of the most extended row recorded (the innermost feed at its
    /// largest): each increment at its own largest could reach past what was recorded.
    full_inc: Vec<f64>,
}

impl Ranges {
    /// The ranges `rec` visited.
    fn of(rec: &Recording) -> Self {
        let n = rec.n_tubes;
        let inc_of = |q: &[f64]| -> Vec<f64> {
            (0..n)
                .map(|k| q[2 * k] - if k == 0 { 0.0 } else { q[2 * k - 2] })
                .collect()
        };
        let mut lo_inc = vec![f64::INFINITY; n];
        let mut hi_inc = vec![f64::NEG_INFINITY; n];
        let mut lo_th = vec![f64::INFINITY; n];
        let mut hi_th = vec![f64::NEG_INFINITY; n];
        let mut full_inc = vec![0.0; n];
        let mut fullest = f64::NEG_INFINITY;
        for r in &rec.rows {
            let inc = inc_of(&r.q);
            if r.q[2 * n - 2] > fullest {
                fullest = r.q[2 * n - 2];
                full_inc.clone_from(&inc);
            }
            for k in 0..n {
                lo_inc[k] = lo_inc[k].min(inc[k]);
                hi_inc[k] = hi_inc[k].max(inc[k]);
                lo_th[k] = lo_th[k].min(r.q[2 * k + 1]);
                hi_th[k] = hi_th[k].max(r.q[2 * k + 1]);
            }
        }
        let mid_inc: Vec<f64> = (0..n).map(|k| 0.5 * (lo_inc[k] + hi_inc[k])).collect();
        let mid_th: Vec<f64> = (0..n).map(|k| 0.5 * (lo_th[k] + hi_th[k])).collect();
        Ranges {
            lo_inc,
            hi_inc,
            lo_th,
            hi_th,
            mid_inc,
            mid_th,
            full_inc,
        }
    }

    /// The configuration with feed increments `inc` and the middle rotations, with one
    /// feed increment or rotation set to each value.
    fn sweep(&self, inc: &[f64], slot: Slot, values: Vec<f64>) -> Vec<Vec<f64>> {
        values
            .into_iter()
            .map(|v| {
                let (mut inc, mut th) = (inc.to_vec(), self.mid_th.clone());
                match slot {
                    Slot::Feed(k) => inc[k] = v,
                    Slot::Turn(k) => th[k] = v,
                }
                joints(&inc, &th)
            })
            .collect()
    }
}

/// The candidate runs on the ranges `rec` visited.
fn candidates(rec: &Recording) -> Vec<Candidate> {
    let ranges = Ranges::of(rec);
    let mut out = one_joint_alone(&ranges);
    out.extend(innermost_turns(&ranges));
    out.push(Candidate {
        name: "rest at the middle configuration".into(),
        q: vec![joints(&ranges.mid_inc, &ranges.mid_th); SUGGESTED_ROWS],
    });
    out
}

/// Each tube turned alone over its recorded range and back, and its feed increment
/// swept alone (the other joints at the middle of their ranges).
fn one_joint_alone(r: &Ranges) -> Vec<Candidate> {
    let rows = SUGGESTED_ROWS;
    let mut out = Vec::new();
    for k in 0..r.mid_inc.len() {
        if r.hi_th[k] > r.lo_th[k] {
            out.push(Candidate {
                name: format!(
                    "turn tube {} alone from {:.0} to {:.0} deg and back (the others at the \
                     middle of their recorded ranges)",
                    k + 1,
                    r.lo_th[k],
                    r.hi_th[k]
                ),
                q: r.sweep(
                    &r.mid_inc,
                    Slot::Turn(k),
                    out_and_back(r.lo_th[k], r.hi_th[k], rows),
                ),
            });
        }
        if r.hi_inc[k] > r.lo_inc[k] {
            out.push(Candidate {
                name: format!(
                    "feed tube {} alone, its increment from {:.1} to {:.1} mm and back",
                    k + 1,
                    r.lo_inc[k],
                    r.hi_inc[k]
                ),
                q: r.sweep(
                    &r.mid_inc,
                    Slot::Feed(k),
                    out_and_back(r.lo_inc[k], r.hi_inc[k], rows),
                ),
            });
        }
    }
    out
}

/// The innermost tube turned over its range at full extension, and turned back and
/// forth over a quarter of its range [`REVERSALS`] times (none when it was not turned).
fn innermost_turns(r: &Ranges) -> Vec<Candidate> {
    let rows = SUGGESTED_ROWS;
    let n = r.mid_inc.len();
    let last = n - 1;
    let turned = r.hi_th[last] > r.lo_th[last];
    if !turned {
        return Vec::new();
    }
    let full_extension = Candidate {
        name: format!(
            "turn tube {n} from {:.0} to {:.0} deg and back at full extension (the \
             feeds of the most extended row recorded)",
            r.lo_th[last], r.hi_th[last]
        ),
        q: r.sweep(
            &r.full_inc,
            Slot::Turn(last),
            out_and_back(r.lo_th[last], r.hi_th[last], rows),
        ),
    };
    let quarter = 0.25 * (r.hi_th[last] - r.lo_th[last]);
    let leg = rows / (2 * REVERSALS);
    let back_and_forth = (0..rows)
        .map(|i| {
            let phase = (i % (2 * leg)) as f64 / leg as f64;
            let u = if phase <= 1.0 { phase } else { 2.0 - phase };
            r.mid_th[last] + quarter * (u - 0.5)
        })
        .collect();
    let reversals = Candidate {
        name: format!(
            "reverse tube {n}'s rotation {REVERSALS} times over {quarter:.0} deg about \
             {:.0} deg",
            r.mid_th[last]
        ),
        q: r.sweep(&r.mid_inc, Slot::Turn(last), back_and_forth),
    };
    vec![full_extension, reversals]
}

/// A recording of the run `q` sampled every `period_s` (tips unknown: zeros).
fn as_recording(rec: &Recording, name: &str, q: &[Vec<f64>], period_s: f64) -> Recording {
    Recording {
        file: format!("suggested run ({name})"),
        n_tubes: rec.n_tubes,
        rows: q
            .iter()
            .enumerate()
            .map(|(i, q)| RecordedRow {
                line: i + 2,
                t_s: i as f64 * period_s,
                run: 0,
                q: q.clone(),
                p: [0.0; 3],
                quaternion: None,
                tangent: None,
                force_n: [0.0; 3],
                frames: None,
            })
            .collect(),
        runs: vec![Run {
            label: "suggested".into(),
            rows: 0..q.len(),
        }],
        has_time: rec.has_time,
        has_force: false,
        poses: None,
        angular: None,
    }
}

/// The parameters of `a` that are uncertain (see the module doc).
fn uncertain(a: &Assessment) -> Vec<usize> {
    let (np, nominal) = (a.x.len(), &a.nominal);
    // a parameter's size: its distance from the nominal, or the RMS distance of its
    // effect's parameters of the same unit (a gravity component near zero is small
    // beside the gravity, not poorly identified)
    let size = |j: usize| -> f64 {
        let same: Vec<f64> = (0..np)
            .filter(|&i| a.effects[i] == a.effects[j] && a.labels[i].unit == a.labels[j].unit)
            .map(|i| (a.x[i] - nominal[i]).powi(2))
            .collect();
        let rms = (same.iter().sum::<f64>() / same.len().max(1) as f64).sqrt();
        (a.x[j] - nominal[j]).abs().max(rms)
    };
    (0..np)
        .filter(|&j| {
            if a.unidentified[j] {
                return true;
            }
            // two effects explaining the same residual
            let confused = (0..np).any(|i| {
                a.effects[i] != a.effects[j]
                    && !a.unidentified[i]
                    && a.correlation(i, j).abs() > CORRELATED_ABOVE
            });
            confused || a.t * a.cov[(j, j)].sqrt() > WIDE * size(j)
        })
        .collect()
}

/// The run that would pin `problem`'s uncertain parameters of the effects `findings`
/// best (a nuisance in the model beside them, the tracker's frame where it is no
/// finding, is no target), with the intervals expected after recording it (`None`
/// when none is uncertain or no candidate run helps enough). `fit_share` is the share
/// of rows a diagnosis fits.
pub(crate) fn next_run(
    problem: &Problem,
    a: &Assessment,
    findings: &[crate::candidates::EffectId],
    fit_share: f64,
    period_s: f64,
) -> Option<(SuggestedRun, JointRun)> {
    let targets: Vec<usize> = uncertain(a)
        .into_iter()
        .filter(|&j| findings.contains(&a.effects[j]))
        .collect();
    if targets.is_empty() {
        return None;
    }
    let period = if period_s.is_finite() && period_s > 0.0 {
        period_s
    } else {
        DEFAULT_PERIOD_S
    };
    let design = Design::new(problem, a, &targets, fit_share, period);
    let (score, c, var) = design.best()?;
    if score > targets.len() as f64 * (MIN_SHRINK * MIN_SHRINK).ln() {
        return None;
    }
    let expected = expected_intervals(a, &targets, &var);
    let why = why(&expected);
    let t_s = (0..c.q.len()).map(|i| i as f64 * period).collect();
    Some((
        SuggestedRun {
            run: c.name,
            rows: c.q.len(),
            sample_period_s: period,
            why,
            expected,
        },
        JointRun { t_s, q: c.q },
    ))
}

/// What a candidate run is judged by: the fit's information and covariance, the
/// uncertain parameters, and how a run is sampled and how much of it a diagnosis fits.
struct Design<'a> {
    problem: &'a Problem<'a>,
    a: &'a Assessment,
    /// The uncertain parameters.
    targets: &'a [usize],
    /// The share of a recording's rows a diagnosis fits.
    fit_share: f64,
    /// The sample period of a run, s.
    period: f64,
    /// The pseudo-inverse of the fit's information `H^+`.
    h_pinv: DMatrix<f64>,
    /// The covariance's scale over the classical one (for parameters identified anew):
    /// the median over the identified parameters.
    scale: f64,
}

impl<'a> Design<'a> {
    /// The design for `a`'s uncertain parameters `targets`.
    fn new(
        problem: &'a Problem<'a>,
        a: &'a Assessment,
        targets: &'a [usize],
        fit_share: f64,
        period: f64,
    ) -> Self {
        let np = a.x.len();
        let (h_pinv, _, _) = pseudo_inverse(&a.information);
        let mut scales: Vec<f64> = (0..np)
            .filter(|&j| !a.unidentified[j] && h_pinv[(j, j)] > 0.0)
            .map(|j| a.cov[(j, j)] / h_pinv[(j, j)])
            .collect();
        scales.sort_by(f64::total_cmp);
        let scale = scales.get(scales.len() / 2).copied().unwrap_or(0.0);
        Design {
            problem,
            a,
            targets,
            fit_share,
            period,
            h_pinv,
            scale,
        }
    }

    /// The candidate run with the lowest score, its score and the uncertain
    /// parameters' expected variances (`None` when no candidate can be simulated).
    fn best(&self) -> Option<(f64, Candidate, Vec<f64>)> {
        let mut best: Option<(f64, Candidate, Vec<f64>)> = None;
        for c in candidates(self.problem.rec) {
            let Some(h_new) = self.information_with(&c) else {
                continue;
            };
            let (score, var) = self.expected_variances(&h_new);
            if best.as_ref().is_none_or(|b| score < b.0) {
                best = Some((score, c, var));
            }
        }
        best
    }

    /// The information after recording run `c`, `H + f H_c` (`None` when the run
    /// cannot be simulated with the fitted model).
    fn information_with(&self, c: &Candidate) -> Option<DMatrix<f64>> {
        let (problem, a) = (self.problem, self.a);
        let rec = as_recording(problem.rec, &c.name, &c.q, self.period);
        let p = Problem {
            base: problem.base.clone(),
            blocks: problem.blocks.clone(),
            rec: &rec,
            rows: (0..rec.rows.len()).collect(),
            huber_mm: f64::INFINITY,
            threads: problem.threads,
            clearance_table: problem.clearance_table,
        };
        let p0 = p.predictions(&a.x)?;
        let jac = p.jacobian(&a.x, &p0)?;
        let rows = 3 * rec.rows.len();
        let jr = jac.rows(0, rows);
        Some(&a.information + (jr.transpose() * jr) * self.fit_share)
    }

    /// The uncertain parameters' variances expected with information `h_new`, and the
    /// run's score: the sum of their log variance ratios (a parameter identified anew
    /// counting [`NEWLY_IDENTIFIED`]).
    fn expected_variances(&self, h_new: &DMatrix<f64>) -> (f64, Vec<f64>) {
        let a = self.a;
        let (pinv_new, null_new, _) = pseudo_inverse(h_new);
        let mut still = vec![false; a.x.len()];
        for j in null_new.iter().flat_map(parts) {
            still[j] = true;
        }
        let mut score = 0.0;
        let mut var = Vec::with_capacity(self.targets.len());
        for &j in self.targets {
            let v = if still[j] {
                f64::INFINITY
            } else if a.unidentified[j] {
                self.scale * pinv_new[(j, j)]
            } else {
                a.cov[(j, j)] * pinv_new[(j, j)] / self.h_pinv[(j, j)]
            };
            score += match (a.unidentified[j], still[j]) {
                (true, true) => 0.0,
                (true, false) => NEWLY_IDENTIFIED.ln(),
                _ => (v / a.cov[(j, j)]).ln(),
            };
            var.push(v);
        }
        (score, var)
    }
}

/// The 95 % interval of parameter `j` of `a` were its variance `v` (clipped to the
/// fit's bounds, in the file's units; open where `v` is not finite).
fn interval(a: &Assessment, j: usize, v: f64) -> [Option<f64>; 2] {
    if !v.is_finite() {
        return [None, None];
    }
    let half = a.t * v.sqrt();
    let (lo, hi) = a.bounds[j];
    let (lo, hi) = ((a.x[j] - half).max(lo), (a.x[j] + half).min(hi));
    if a.labels[j].log {
        [Some(lo.exp()), Some(hi.exp())]
    } else {
        [Some(lo), Some(hi)]
    }
}

/// The uncertain parameters `targets`' intervals now and with the expected variances
/// `var`.
fn expected_intervals(a: &Assessment, targets: &[usize], var: &[f64]) -> Vec<ExpectedInterval> {
    targets
        .iter()
        .zip(var)
        .map(|(&j, &v)| {
            let now = if a.unidentified[j] {
                [None, None]
            } else {
                interval(a, j, a.cov[(j, j)])
            };
            let value = if a.labels[j].log {
                a.x[j].exp()
            } else {
                a.x[j]
            };
            ExpectedInterval {
                parameter: a.labels[j].name.clone(),
                value,
                ci95_now: now,
                ci95_expected: interval(a, j, v),
            }
        })
        .collect()
}

/// Why the run is suggested: each uncertain parameter with its interval now and the
/// one expected; those not identified now nor after it (a feed play of a tube that
/// never moves, a common factor of every stiffness) named once at the end, without
/// their values.
fn why(expected: &[ExpectedInterval]) -> String {
    let unidentified = |ci: &[Option<f64>; 2]| ci.iter().any(Option::is_none);
    let (still, informed): (Vec<&ExpectedInterval>, Vec<&ExpectedInterval>) = expected
        .iter()
        .partition(|e| unidentified(&e.ci95_now) && unidentified(&e.ci95_expected));
    let mut parts: Vec<String> = informed
        .iter()
        .map(|e| {
            let all: Vec<f64> = e
                .ci95_now
                .iter()
                .chain(&e.ci95_expected)
                .flatten()
                .copied()
                .collect();
            let show = |ci: [Option<f64>; 2]| match ci {
                [Some(lo), Some(hi)] => {
                    format!("{} to {}", sig_beside(lo, &all), sig_beside(hi, &all))
                }
                _ => "not identified".into(),
            };
            format!(
                "{} {} ({} now, {} expected)",
                e.parameter,
                sig_beside(e.value, &all),
                show(e.ci95_now),
                show(e.ci95_expected)
            )
        })
        .collect();
    if !still.is_empty() {
        let names: Vec<&str> = still.iter().map(|e| e.parameter.as_str()).collect();
        parts.push(format!(
            "not identified now nor after it: {}",
            names.join(", ")
        ));
    }
    parts.join("; ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reasons give each parameter the run informs with its intervals, and name the
    /// ones it leaves unidentified once, at the end, without values.
    #[test]
    fn parameters_the_run_leaves_unseen_are_named_once() {
        let e = |name: &str, now: [Option<f64>; 2], after: [Option<f64>; 2]| ExpectedInterval {
            parameter: name.into(),
            value: 0.5,
            ci95_now: now,
            ci95_expected: after,
        };
        let reasons = why(&[
            e("a", [Some(0.0), Some(1.0)], [Some(0.25), Some(0.75)]),
            e("b", [None, None], [None, None]),
            e("c", [None, None], [Some(0.1), Some(0.9)]),
            e("d", [None, None], [None, None]),
        ]);
        assert_eq!(
            reasons,
            "a 0.5000 (0 to 1.000 now, 0.2500 to 0.7500 expected); \
             c 0.5000 (not identified now, 0.1000 to 0.9000 expected); \
             not identified now nor after it: b, d"
        );
    }

    #[test]
    fn out_and_back_returns_to_its_start() {
        let v = out_and_back(0.0, 10.0, 11);
        assert_eq!(v.first(), Some(&0.0));
        assert_eq!(v[5], 10.0);
        assert_eq!(v.last(), Some(&0.0));
    }

    #[test]
    fn joints_sum_the_increments() {
        assert_eq!(
            joints(&[10.0, 5.0], &[1.0, 2.0]),
            vec![10.0, 1.0, 15.0, 2.0]
        );
    }
}

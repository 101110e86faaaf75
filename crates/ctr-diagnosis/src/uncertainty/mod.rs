//! How sure a diagnosis is: a 95 % interval for every fitted parameter, the directions
//! the data cannot pin, and the pairs they hardly tell apart.
//!
//! At the fitted parameters `x` (every finding's block together, on the fit rows), let
//! `J` be the Jacobian of the predictions (3 per row), `w` the robust fit's weights
//! and `e` the errors. The information matrix is the robust cost's own curvature,
//! `H = sum_i J_i^T W_i J_i` with `W_i = I` for a row within the Huber threshold and
//! `w_i (I - u_i u_i^T)` beyond it (`u_i` its error's direction, along which the cost
//! grows only linearly: [`robust_information`], the fit's curvature too); scaled to a unit
//! diagonal, `S = D H D` with `D = diag(H_jj)^(-1/2)`, its eigenvalues say what the
//! data identify:
//!
//! - an eigenvector `v` with eigenvalue below [`UNIDENTIFIED_EIGEN`] x the largest is
//!   a direction `u = D v` along which the tips do not change: the parameters taking
//!   part in it are **not identified** (a common factor of every tube's stiffness, seen
//!   by kinematics alone). The basis of these directions is put in reduced echelon
//!   form, so that parameters unseen each on its own are stated so and directions of
//!   disjoint parameters come apart ([`unseen`]); their values are set to the nominal
//!   along them where the tips do not move (the fit's value would be arbitrary), their
//!   intervals are the fit's bounds, and the combinations orthogonal to every such
//!   direction are reported as what is identified (the ratio of two stiffness factors);
//! - on the identified directions two covariances are computed and the larger variance
//!   of each parameter kept (correlations from the first):
//!   - the classical `s^2 H^+`, `s^2 = sum_i w_i |e_i|^2 / (N - p)` (so a residual that
//!     is more than noise widens the intervals);
//!   - a cluster-robust sandwich `H^+ (G/(G-1) sum_g u_g u_g^T) H^+`, `u_g = sum_(i in g)
//!     J_i^T w_i e_i`, over `G` clusters of consecutive fit rows of one run, each
//!     twice as long as the residual's correlation length (the first lag where its
//!     autocorrelation along the run falls below [`INDEPENDENT_BELOW`]): errors that
//!     are not white along a run (a tracker's slow wander, a leftover structure) count
//!     with their real weight (Liang & Zeger 1986; Cameron & Miller 2015 for the
//!     `G/(G-1)` correction).
//! - the interval is `x_j +/- t_(0.975, G-1) sd_j`, clipped to the fit's bounds, and
//!   written in the robot file's form: an output that depends on one parameter maps
//!   that parameter's end points (a stiffness factor `exp(ln f +/- ...)`, not
//!   symmetric), one that depends on several (a gravity direction, a registration
//!   axis) gets the delta method, `+/- t sqrt(g^T Sigma g)`;
//! - each end is then checked against the robust cost along the output's linearised
//!   profile and moved to where the profile deviance reaches `t^2` where the Wald end
//!   misreads it (a non-linear direction, a bound): [`profile`];
//! - when the report does not explain the residual, each interval is joined with the
//!   one of the parameters refitted together with the empirical correction's terms
//!   (what the unexplained remainder can move them by): [`remainder`].
//!
//! Pairs correlated above [`CORRELATED_ABOVE`] are listed: the data tell them apart
//! only by their difference.

pub(crate) mod attach;
pub(crate) mod suggest;

use crate::candidates::{EffectId, Label};
use crate::fit::Problem;
use crate::levenberg::robust_information;
use crate::quantiles::t975;
use crate::report::numbers::sig_interval;
use crate::report::Correlated;
use ctr_formats::Recording;
use nalgebra::{DMatrix, DVector};
use serde_json::Value;

mod file_form;
mod profile;
mod remainder;
mod unseen;

pub(crate) use unseen::Tie;
use unseen::Unseen;

/// Eigenvalue of the scaled information matrix, relative to its largest, below which
/// a direction is not identified (a singular value ratio of 1e-4 of the scaled
/// Jacobian: what finite differences of an exactly invariant direction leave).
pub const UNIDENTIFIED_EIGEN: f64 = 1e-8;

/// Correlation above which a pair of parameters is listed as hard to tell apart.
pub const CORRELATED_ABOVE: f64 = 0.9;

/// Autocorrelation of the residual along a run below which rows count as independent
/// (sets the clusters' length).
pub const INDEPENDENT_BELOW: f64 = 0.1;

/// Cosine between a combination and a direction not identified below which the
/// combination counts as orthogonal to it (identified).
const ORTHOGONAL_WITHIN: f64 = 1e-3;
/// Fewest rows in a cluster.
const MIN_CLUSTER_ROWS: usize = 5;
/// Longest correlation length looked for, rows.
const MAX_LAG_ROWS: usize = 100;
/// Share of a not-identified direction (of its largest component) above which a
/// parameter takes part in it.
const PART_OF_DIRECTION: f64 = 0.05;
/// Finite-difference step of the map from fitted to file parameters, relative to a
/// parameter's natural scale.
const OUTPUT_STEP: f64 = 1e-4;

/// A combination of parameters the data identify where the parameters alone are not.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Combination {
    /// The finding whose `ci95` lists it (that of its first parameter).
    pub effect: EffectId,
    /// In words (`stiffness factor of tube 2 / stiffness factor of tube 1`).
    pub name: String,
    pub value: f64,
    pub ci95: [f64; 2],
    /// Its value at the nominal (the user's model, where the effect is not there) when
    /// both its parameters are of one effect; `None` across effects (it then says
    /// nothing of either effect alone).
    pub not_there: Option<f64>,
    /// The direction not identified it is orthogonal to (index into the null
    /// directions): the statement of that direction lists it.
    direction: usize,
}

impl Combination {
    /// Its entry in a finding's `ci95.identified` (`not_there` where it has one).
    fn to_json(&self) -> Value {
        let mut v =
            serde_json::json!({"combination": self.name, "value": self.value, "ci95": self.ci95});
        if let (Some(n), Value::Object(m)) = (self.not_there, &mut v) {
            m.insert("not_there".into(), n.into());
        }
        v
    }

    /// `name = value (lo to hi)`.
    fn words(&self) -> String {
        let [v, lo, hi] = sig_interval(self.value, Some(self.ci95[0]), Some(self.ci95[1]))
            .map(Option::unwrap_or_default);
        format!("{} = {v} ({lo} to {hi})", self.name)
    }
}

/// How close to a bound of its fit a parameter counts as on it, in its natural steps
/// ([`Problem::scale`]): the QP's interior-point steps stop
/// just inside a bound.
pub(crate) const ON_BOUND_STEPS: f64 = 1e-3;

/// The uncertainty of a fit: covariance, intervals, what is not identified.
#[derive(Clone, Debug)]
pub(crate) struct Assessment {
    /// The fitted parameters (set to the nominal along directions not identified).
    pub x: Vec<f64>,
    /// The parameters' nominal values (the user's model).
    pub nominal: Vec<f64>,
    pub labels: Vec<Label>,
    /// The effect each parameter belongs to.
    pub effects: Vec<EffectId>,
    pub bounds: Vec<(f64, f64)>,
    steps: Vec<f64>,
    /// Covariance on the identified directions.
    pub cov: DMatrix<f64>,
    /// The information (the robust cost's curvature) of the fit rows.
    pub information: DMatrix<f64>,
    /// Whether each parameter takes part in a direction not identified.
    pub unidentified: Vec<bool>,
    /// Directions not identified (in the parameters' units, reduced echelon form) and
    /// their groups.
    unseen: Unseen,
    /// The classical covariance `s^2 H^+` (the profiles' directions).
    classic: DMatrix<f64>,
    /// The weighted residual variance per component `s^2`.
    s2: f64,
    /// The robust cost at `x`, mm^2.
    cost: f64,
    /// The Jacobian of the predictions at `x` (the profiles' Gauss-Newton steps).
    jac: DMatrix<f64>,
    /// The profiles' reference cost (computed once, when first profiled).
    reference: std::sync::OnceLock<f64>,
    /// The 97.5 % quantile used.
    pub t: f64,
    /// The method, in words.
    pub method: String,
}

/// The pseudo-inverse of the information `h` on its identified directions, computed
/// scaled to a unit diagonal (`D h D`, `D = diag(h_jj)^(-1/2)`; a parameter that moves
/// nothing keeps `d_j = 1` and is not identified), with the directions not identified
/// (scaled) and the scale `d`.
pub(crate) fn pseudo_inverse(h: &DMatrix<f64>) -> (DMatrix<f64>, Vec<DVector<f64>>, Vec<f64>) {
    let np = h.nrows();
    let d: Vec<f64> = (0..np)
        .map(|j| {
            if h[(j, j)] > 0.0 {
                1.0 / h[(j, j)].sqrt()
            } else {
                1.0
            }
        })
        .collect();
    let dm = DMatrix::from_diagonal(&DVector::from_column_slice(&d));
    let s = &dm * h * &dm;
    let eig = s.symmetric_eigen();
    let lmax = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
    let mut s_pinv = DMatrix::<f64>::zeros(np, np);
    let mut null = Vec::new();
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        let v = eig.eigenvectors.column(k).into_owned();
        if lmax > 0.0 && l > UNIDENTIFIED_EIGEN * lmax {
            s_pinv += &v * v.transpose() / l;
        } else {
            null.push(v);
        }
    }
    (&dm * s_pinv * &dm, null, d)
}

/// A parameter whose natural step ([`Problem::scale`]) moves the predictions by less
/// than this RMS, mm, moves nothing: its Jacobian column is rounding (a straight tube's
/// rotation, which turns nothing), and scaled to a unit diagonal it would pass for a
/// direction of its own.
pub const NEGLIGIBLE_MOVE_MM: f64 = 1e-9;

/// `jac` with the columns of parameters that move nothing ([`NEGLIGIBLE_MOVE_MM`])
/// set to zero: not identified, whether the column came out as rounding or as zeros.
fn without_negligible_columns(mut jac: DMatrix<f64>, problem: &Problem) -> DMatrix<f64> {
    let rows = jac.nrows().max(1) as f64;
    for j in 0..jac.ncols() {
        let step = problem.scale(j).0;
        let rms = jac.column(j).norm() / rows.sqrt() * step;
        if rms < NEGLIGIBLE_MOVE_MM {
            jac.column_mut(j).fill(0.0);
        }
    }
    jac
}

/// The parameters taking part in a direction `u` not identified: components of at
/// least [`PART_OF_DIRECTION`] of its largest.
pub(crate) fn parts(u: &DVector<f64>) -> Vec<usize> {
    let big = u.amax();
    (0..u.len())
        .filter(|&j| big > 0.0 && u[j].abs() >= PART_OF_DIRECTION * big)
        .collect()
}

/// Consecutive fit rows of one run, in order (`rows` sorted).
fn segments(rec: &Recording, rows: &[usize]) -> Vec<std::ops::Range<usize>> {
    let run_of = |r: usize| rec.runs.iter().position(|run| run.rows.contains(&r));
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=rows.len() {
        let breaks =
            k == rows.len() || rows[k] != rows[k - 1] + 1 || run_of(rows[k]) != run_of(rows[k - 1]);
        if breaks {
            out.push(start..k);
            start = k;
        }
    }
    out
}

/// The first lag (rows) at which the residual's autocorrelation along the segments
/// falls below [`INDEPENDENT_BELOW`]; `r[k]` is row k's weighted error.
fn correlation_length(r: &[[f64; 3]], segs: &[std::ops::Range<usize>]) -> usize {
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let var: f64 = r.iter().map(|v| dot(v, v)).sum::<f64>() / r.len().max(1) as f64;
    if var <= 0.0 {
        return 1;
    }
    for lag in 1..MAX_LAG_ROWS {
        let (mut s, mut n) = (0.0, 0usize);
        for seg in segs {
            for k in seg.start..seg.end.saturating_sub(lag) {
                s += dot(&r[k], &r[k + lag]);
                n += 1;
            }
        }
        if n == 0 || s / n as f64 / var < INDEPENDENT_BELOW {
            return lag;
        }
    }
    MAX_LAG_ROWS
}

/// The classical weighted residual variance per component of the `rows` fit rows,
/// `s^2 = sum_i w_i |e_i|^2 / (N - p)` (`p` the identified directions).
fn residual_variance(e: &[f64], w: &[f64], rows: usize, identified: usize) -> f64 {
    let data = 3 * rows;
    (0..rows)
        .map(|k| w[k] * (0..3).map(|a| e[3 * k + a].powi(2)).sum::<f64>())
        .sum::<f64>()
        / (data.saturating_sub(identified)).max(1) as f64
}

/// The cluster-robust sandwich covariance over blocks of consecutive fit rows.
struct Sandwich {
    /// `H^+ (G/(G-1) sum_g u_g u_g^T) H^+` (the classical covariance when there are
    /// fewer than two clusters).
    cov: DMatrix<f64>,
    /// The clusters `G`.
    clusters: usize,
    /// The rows of a cluster (twice the residual's correlation length).
    cluster_rows: usize,
}

impl Sandwich {
    /// The sandwich of `problem`'s fit: Jacobian `jac`, errors `e`, weights `w`,
    /// `h_pinv` the pseudo-inverse of the information and `classic` the classical
    /// covariance.
    fn new(
        problem: &Problem,
        jac: &DMatrix<f64>,
        e: &[f64],
        w: &[f64],
        h_pinv: &DMatrix<f64>,
        classic: &DMatrix<f64>,
    ) -> Self {
        let (np, rows) = (jac.ncols(), problem.rows.len());
        let segs = segments(problem.rec, &problem.rows);
        let weighted: Vec<[f64; 3]> = (0..rows)
            .map(|k| [w[k] * e[3 * k], w[k] * e[3 * k + 1], w[k] * e[3 * k + 2]])
            .collect();
        let len = (2 * correlation_length(&weighted, &segs)).max(MIN_CLUSTER_ROWS);
        let mut meat = DMatrix::<f64>::zeros(np, np);
        let mut clusters = 0usize;
        for seg in &segs {
            let n = seg.len();
            let pieces = (n / len).max(1);
            for c in 0..pieces {
                let from = seg.start + c * n / pieces;
                let to = seg.start + (c + 1) * n / pieces;
                let mut u = DVector::<f64>::zeros(np);
                for k in from..to {
                    for a in 0..3 {
                        u += jac.row(3 * k + a).transpose() * weighted[k][a];
                    }
                }
                meat += &u * u.transpose();
                clusters += 1;
            }
        }
        let g = clusters as f64;
        let cov = if clusters >= 2 {
            h_pinv * (meat * (g / (g - 1.0))) * h_pinv
        } else {
            classic.clone()
        };
        Sandwich {
            cov,
            clusters,
            cluster_rows: len,
        }
    }
}

/// The covariance kept: each parameter's larger variance of the classical and the
/// sandwich, with the classical correlations.
fn larger_variance(classic: &DMatrix<f64>, sandwich: &DMatrix<f64>) -> DMatrix<f64> {
    let np = classic.nrows();
    let sd: Vec<f64> = (0..np)
        .map(|j| classic[(j, j)].max(sandwich[(j, j)]).max(0.0).sqrt())
        .collect();
    let mut cov = DMatrix::<f64>::zeros(np, np);
    for i in 0..np {
        for j in 0..np {
            let denom = (classic[(i, i)] * classic[(j, j)]).sqrt();
            let r = if denom > 0.0 {
                classic[(i, j)] / denom
            } else {
                f64::from(u8::from(i == j))
            };
            cov[(i, j)] = r * sd[i] * sd[j];
        }
    }
    cov
}

/// The method, in words: `clusters` blocks of `len` consecutive fit rows.
fn method_words(clusters: usize, len: usize) -> String {
    format!(
        "95 % intervals x +/- t(0.975, {dof}) sd, sd the larger of the classical \
         (weighted residual variance x pseudo-inverse of the robust cost's curvature J^T W J, \
         W = w (I - u u^T) for a row beyond the Huber threshold, u its error's direction) and the cluster-robust \
         sandwich over {clusters} blocks of {len} consecutive fit rows (twice the \
         residual's correlation length), J the Jacobian of the robust fit on the fit \
         rows; clipped to the fit's bounds; file-form values by their parameter's end \
         points, or the delta method where they depend on several; each end checked \
         against the robust cost along its linearised profile (the other parameters \
         following by a Gauss-Newton step) and, where sqrt(deviance)/t there is off \
         by more than a factor {agrees}, moved to where the profile deviance reaches \
         t^2 (or to the bound it reaches first); directions whose \
         scaled information is below {UNIDENTIFIED_EIGEN:e} of the largest are not \
         identified (their intervals are the fit's bounds)",
        dof = clusters.saturating_sub(1),
        agrees = profile::AGREES_WITHIN
    )
}

impl Assessment {
    /// `x` with each parameter clipped to the fit's bounds.
    pub(crate) fn clamped(&self, mut x: Vec<f64>) -> Vec<f64> {
        for (v, &(lo, hi)) in x.iter_mut().zip(&self.bounds) {
            *v = v.clamp(lo, hi);
        }
        x
    }

    /// The uncertainty of `problem`'s fit at `x` (`None` when it cannot be simulated
    /// there or has no parameter); `nominal` is what the parameters are without the
    /// findings (the user's model).
    pub fn new(problem: &Problem, x: &[f64], nominal: &[f64]) -> Option<Self> {
        let np = x.len();
        if np == 0 {
            return None;
        }
        let p0 = problem.predictions(x)?;
        let e = problem.errors(&p0);
        let (cost, w) = problem.cost(&e);
        let jac = without_negligible_columns(problem.jacobian(x, &p0)?, problem);
        let h = robust_information(&jac, &w, &e, np);
        let (h_pinv, null_scaled, d) = pseudo_inverse(&h);
        let identified = np - null_scaled.len();
        let s2 = residual_variance(&e, &w, problem.rows.len(), identified);
        let classic = &h_pinv * s2;
        let robust = Sandwich::new(problem, &jac, &e, &w, &h_pinv, &classic);
        let cov = larger_variance(&classic, &robust.cov);
        // directions not identified, in the parameters' units; set to the nominal
        let mut unseen = Unseen::new(&null_scaled, &d);
        let mut unidentified: Vec<bool> = (0..np).map(|j| h[(j, j)] <= 0.0).collect();
        for j in unseen.directions.iter().flat_map(parts) {
            unidentified[j] = true;
        }
        let xs = unseen.tie(problem, x, nominal, cost);
        let clusters = robust.clusters;
        Some(Assessment {
            x: xs,
            nominal: nominal.to_vec(),
            labels: (0..np).map(|j| problem.label(j)).collect(),
            effects: (0..np).map(|j| problem.effect_of(j)).collect(),
            bounds: (0..np).map(|j| problem.scale(j).1).collect(),
            steps: (0..np).map(|j| problem.scale(j).0).collect(),
            cov,
            information: h,
            unidentified,
            unseen,
            classic,
            s2,
            cost,
            jac,
            reference: std::sync::OnceLock::new(),
            t: t975(clusters.saturating_sub(1)),
            method: method_words(clusters, robust.cluster_rows),
        })
    }

    /// Where parameter `j`'s nominal sits on a bound of its fit (a play, a deflection,
    /// a lag: at least 0), whether its fitted value is on that bound too (within
    /// [`ON_BOUND_STEPS`] of its natural step); `None`
    /// where the nominal is inside the bounds.
    pub(crate) fn on_edge(&self, j: usize) -> Option<bool> {
        let within = ON_BOUND_STEPS * self.steps[j];
        let (lo, hi) = self.bounds[j];
        [lo, hi]
            .into_iter()
            .find(|b| b.is_finite() && (self.nominal[j] - b).abs() <= within)
            .map(|b| (self.x[j] - b).abs() <= within)
    }

    /// Whether parameter `j`, at `bound` of its fit at `x`, can leave it by more than
    /// `within` along a direction the data do not see while every parameter stays within
    /// the fit's bounds: then its place on the bound is the fit's arbitrary choice, not
    /// the data's push. An identified parameter cannot.
    pub(crate) fn free_to_leave(&self, j: usize, x: &[f64], bound: f64, within: f64) -> bool {
        if !self.unidentified[j] {
            return false;
        }
        let (lo, hi) = self.bounds[j];
        let inward = if (bound - hi).abs() < (bound - lo).abs() {
            -1.0
        } else {
            1.0
        };
        self.unseen.directions.iter().any(|u| {
            // along `sign u`, parameter j moves inward
            let sign = inward * u[j].signum();
            let d: Vec<f64> = u.iter().map(|uk| sign * uk).collect();
            u[j] != 0.0 && unseen::reach(x, &d, &self.bounds) * u[j].abs() > within
        })
    }

    /// The 95 % interval of fitted parameter `j` (the fit's bounds when not identified).
    pub fn interval(&self, j: usize) -> (f64, f64) {
        let (lo, hi) = self.bounds[j];
        if self.unidentified[j] {
            return (lo, hi);
        }
        let half = self.t * self.cov[(j, j)].sqrt();
        ((self.x[j] - half).max(lo), (self.x[j] + half).min(hi))
    }

    /// The correlation of fitted parameters `i` and `j`.
    pub fn correlation(&self, i: usize, j: usize) -> f64 {
        self.cov[(i, j)] / (self.cov[(i, i)] * self.cov[(j, j)]).sqrt()
    }

    /// Pairs of identified parameters correlated above [`CORRELATED_ABOVE`].
    pub fn correlated(&self) -> Vec<Correlated> {
        let np = self.x.len();
        let mut out = Vec::new();
        for i in 0..np {
            for j in i + 1..np {
                if self.unidentified[i] || self.unidentified[j] {
                    continue;
                }
                let r = self.correlation(i, j);
                if r.abs() > CORRELATED_ABOVE {
                    out.push(Correlated {
                        a: self.labels[i].name.clone(),
                        b: self.labels[j].name.clone(),
                        r,
                    });
                }
            }
        }
        out
    }

    /// The combinations the data identify across each direction they do not, each with
    /// the finding of its first parameter.
    pub fn combinations(&self) -> Vec<Combination> {
        let mut out = Vec::new();
        for (direction, u) in self.unseen.directions.iter().enumerate() {
            let part = parts(u);
            let Some(&r) = part.iter().find(|&&j| u[j].abs() >= 0.5 * u.amax()) else {
                continue;
            };
            for &j in part.iter().filter(|&&j| j != r) {
                // a = e_j - (u_j / u_r) e_r is orthogonal to u: identified
                let ratio = u[j] / u[r];
                let mut a = DVector::<f64>::zeros(u.len());
                a[j] = 1.0;
                a[r] = -ratio;
                if !self.identifies(&a) {
                    // it moves along another direction the data do not see: not identified
                    continue;
                }
                let value = a.dot(&DVector::from_column_slice(&self.x));
                let at_nominal = a.dot(&DVector::from_column_slice(&self.nominal));
                let one_effect = self.effects[j] == self.effects[r];
                let half = self.t * (a.transpose() * &self.cov * &a)[(0, 0)].max(0.0).sqrt();
                let (lj, lr) = (&self.labels[j], &self.labels[r]);
                let same = (ratio - 1.0).abs() < 0.05;
                let (name, value, ci95, at_nominal) = if lj.log && lr.log {
                    let name = if same {
                        format!("{} / {}", lj.name, lr.name)
                    } else {
                        format!("{} / {}^{ratio:.3}", lj.name, lr.name)
                    };
                    (
                        name,
                        value.exp(),
                        [(value - half).exp(), (value + half).exp()],
                        at_nominal.exp(),
                    )
                } else {
                    let unit = if lj.unit.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", lj.unit)
                    };
                    let name = if same {
                        format!("{} - {}{unit}", lj.name, lr.name)
                    } else if (ratio + 1.0).abs() < 0.05 {
                        format!("{} + {}{unit}", lj.name, lr.name)
                    } else if ratio < 0.0 {
                        format!("{} + {:.3} x {}{unit}", lj.name, -ratio, lr.name)
                    } else {
                        format!("{} - {ratio:.3} x {}{unit}", lj.name, lr.name)
                    };
                    (name, value, [value - half, value + half], at_nominal)
                };
                // two directions that share parameters give the same pair twice: once
                if out.iter().any(|c: &Combination| c.name == name) {
                    continue;
                }
                out.push(Combination {
                    effect: self.effects[j],
                    name,
                    value,
                    ci95,
                    not_there: one_effect.then_some(at_nominal),
                    direction,
                });
            }
        }
        out
    }

    /// Whether the data identify the combination `a . x`: `a` orthogonal (within
    /// [`ORTHOGONAL_WITHIN`] of its and the direction's sizes) to every direction the
    /// data do not see. One built across a direction can still lie along another that
    /// shares its parameters; its variance there is the pseudo-inverse's zero, not a
    /// measurement.
    fn identifies(&self, a: &DVector<f64>) -> bool {
        self.unseen
            .directions
            .iter()
            .all(|u| a.dot(u).abs() <= ORTHOGONAL_WITHIN * a.norm() * u.norm())
    }

    /// What the data do not identify, in words: one sentence for the parameters unseen
    /// each on its own (per how far they went toward the nominal), then one per group
    /// of directions that share parameters, with the combinations across it listed
    /// before.
    pub fn statements(&self, combos: &[Combination]) -> Vec<String> {
        let mut out = Vec::new();
        // parameters unseen each on its own, by how far they went toward the nominal:
        // one sentence for all of them
        for tie in [Tie::Nominal, Tie::TowardNominal, Tie::Fitted] {
            let mut alone: Vec<usize> = self
                .unseen
                .groups
                .iter()
                .filter(|g| g.tie == tie && g.directions.len() == g.parameters.len())
                .flat_map(|g| g.parameters.iter().copied())
                .collect();
            alone.sort_unstable();
            let alone: Vec<String> = alone.iter().map(|&j| self.labels[j].name.clone()).collect();
            if !alone.is_empty() {
                let one = alone.len() == 1;
                out.push(format!(
                    "not identified: {} (the tips do not change when {} moves); {} {}",
                    alone.join(", "),
                    if one { "it" } else { "any of them" },
                    if one { "it is" } else { "they are" },
                    tie.words()
                ));
            }
        }
        for group in &self.unseen.groups {
            if group.directions.len() == group.parameters.len() {
                continue;
            }
            let names: Vec<String> = group
                .parameters
                .iter()
                .map(|&j| self.labels[j].name.clone())
                .collect();
            let ids: Vec<String> = combos
                .iter()
                .filter(|c| group.directions.contains(&c.direction))
                .map(Combination::words)
                .collect();
            let mut s = format!(
                "not identified alone: {} (the tips do not change when they move \
                 together{}); they are {}",
                names.join(", "),
                match group.directions.len() {
                    1 => String::new(),
                    k => format!(", in {k} independent ways"),
                },
                group.tie.words()
            );
            if !ids.is_empty() {
                s += &format!(
                    "; only {} identified: {}",
                    if ids.len() == 1 {
                        "this is"
                    } else {
                        "these are"
                    },
                    ids.join("; ")
                );
            }
            out.push(s);
        }
        out
    }

    /// How far the values went toward the nominal along direction `k` not identified.
    pub(crate) fn tie_along(&self, k: usize) -> Tie {
        self.unseen.group_of(k).map_or(Tie::Fitted, |g| g.tie)
    }
}

#[cfg(test)]
mod tests;

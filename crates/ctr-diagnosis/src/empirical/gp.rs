//! The learned discrepancy (Kennedy and O'Hagan's model discrepancy): what the fitted
//! physics leaves, learned as a Gaussian process over the joints the model takes and
//! their history, on the fit rows; reported apart as not physics, with its held-out RMS
//! and band, and written as `[model.discrepancy]` (`ctr_formats::discrepancy` has the
//! equations, `ctr_analysis::discrepancy` evaluates it, here it is fitted).
//!
//! - **Inputs**: every feed, rotation and relative rotation of the commanded joints,
//!   delayed by the fitted model's latency, and for each relative
//!   rotation the state of a play operator of half-width `w` along each run: what tells
//!   the same joints reached forwards from the same joints reached backwards (on a real
//!   robot's recording, where a run driven backwards repeats another, history
//!   dominates what physics leaves). Inputs constant on the training rows, or exact
//!   copies of another, are left out; each is standardised on the training rows.
//! - **Training rows**: the fit rows, every `k`-th along each run so that at most
//!   [`MAX_TRAIN_ROWS`] remain (consecutive rows of a recording carry little new
//!   information and the cost is cubic in their number).
//! - **Hyperparameters** (a length scale per input, the signal and the noise, shared by
//!   the three coordinates) maximise the log marginal likelihood of the training rows,
//!   `sum_o -1/2 y_o^T K^-1 y_o - 3/2 log|K| - 3n/2 log 2 pi`, by L-BFGS (argmin) over
//!   their logs mapped into bounds, with its analytic gradient
//!   `1/2 tr((K^-1 Y Y^T K^-1 - 3 K^-1) dK)`; the play width by the same likelihood
//!   over [`PLAY_WIDTHS_DEG`]. No held-out row takes part.
//! - **Offered only where it helps** (`crate::verdict`): [`CV_FOLDS`]-fold
//!   cross-validation over the training rows (folds like the split's blocks: each run's
//!   rows in `2 K` contiguous blocks, block `b` in fold `b mod K`; a static set's by
//!   pose, so that no frame of a pose predicts another), the process with the fitted
//!   hyperparameters conditioned on the other folds: its RMS against the physics' on the
//!   same rows ([`Cv`]).
//!
//! Why by hand on nalgebra rather than a GP crate (egobox-gp): the fitted process must
//! be written into the robot file as numbers (its inputs by name, training rows,
//! hyperparameters) that `ctr-cli fk` evaluates row by row along a run with the play
//! operators; egobox-gp brings a second linear algebra stack (ndarray, linfa) and keeps
//! its model as an opaque serialised object. The algebra is a Cholesky factor and a few
//! products on nalgebra, which the workspace already builds; the optimiser is argmin's.

use crate::report::{Band, Empirical, GpInput};
use crate::residual::{figures, positions, with_angles, RowError};
use crate::start::Start;
use argmin::core::{CostFunction, Executor, Gradient, State};
use argmin::solver::linesearch::MoreThuenteLineSearch;
use argmin::solver::quasinewton::LBFGS;
use ctr_analysis::discrepancy::{kernel, Gp};
use ctr_analysis::learned::delayed_commands;
use ctr_analysis::model::ModelSpec;
use ctr_formats::{inputs_along_run, Discrepancy, Input};
use nalgebra::DMatrix;

/// Most training rows of the process.
pub const MAX_TRAIN_ROWS: usize = 250;
/// Half-widths of the play operators tried, deg: from a gear's backlash to the twist a
/// tube pair stores before it slips.
pub const PLAY_WIDTHS_DEG: [f64; 4] = [2.0, 5.0, 10.0, 20.0];
/// Bounds of the length scales, standardised units: from a tenth of an input's spread
/// to an input that does not matter.
const LENGTH_SCALE_BOUNDS: (f64, f64) = (0.05, 100.0);
/// Bounds of the signal, as shares of the targets' standard deviation.
const SIGNAL_BOUNDS: (f64, f64) = (0.01, 10.0);
/// Upper bound of the noise, as a share of the targets' standard deviation (its lower
/// bound is half the tracker's noise estimate: the measurements scatter at least that).
const MAX_NOISE_SHARE: f64 = 2.0;
/// Iterations of one L-BFGS run.
const MAX_ITERATIONS: u64 = 60;
/// An L-BFGS run ends when an iteration changes the negative log marginal likelihood by
/// less than this, nats: hyperparameters a hundredth of a nat apart are equally
/// supported by the data (a likelihood ratio of 1.01), and the last iterations of a
/// run crawl along such a flat valley (measured on a generated ~1,000-row recording:
/// 37 % fewer likelihood evaluations, the held-out RMS with the discrepancy the same to
/// 0.06 %).
const LIKELIHOOD_TOLERANCE_NATS: f64 = 1e-2;
/// Folds of the cross-validation that decides whether the discrepancy is offered.
pub const CV_FOLDS: usize = 5;

/// The discrepancy's cross-validation on the fit rows: what it leaves on the training
/// rows, each predicted by the process conditioned on the other folds, against what the
/// physics leaves there (RMS of the tip positions, mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Cv {
    /// with the discrepancy, mm
    pub learned_mm: f64,
    /// the physics alone, mm
    pub physics_mm: f64,
}

impl Cv {
    /// Whether the discrepancy beats the physics (and so is offered).
    pub(crate) fn helps(&self) -> bool {
        self.learned_mm < self.physics_mm
    }
}

/// The z value of a two-sided 95 % band.
const Z95: f64 = 1.959_963_984_540_054;

/// The discrepancy fitted to the fitted model `model`'s errors `e` (positions), with
/// what it leaves on every row, the report's account of it and its per-row standard
/// deviation; `None` when it cannot be fitted (no input varies, too few rows).
#[allow(clippy::type_complexity)]
pub(crate) fn fit(
    start: &Start,
    model: &ModelSpec,
    e: &[RowError],
) -> Option<(Empirical, Discrepancy, Vec<RowError>, Cv)> {
    let rec = start.rec;
    let mut joints = vec![Vec::new(); rec.rows.len()];
    for run in 0..rec.runs.len() {
        for (r, q) in rec.runs[run]
            .rows
            .clone()
            .zip(delayed_commands(model, rec, run))
        {
            joints[r] = q;
        }
    }
    let train = training_rows(start);
    if train.len() < 2 * MIN_INPUT_ROWS {
        return None;
    }
    let target: Vec<[f64; 3]> = train
        .iter()
        .map(|&r| [-e[r][0], -e[r][1], -e[r][2]])
        .collect();
    let spread = (target.iter().flatten().map(|v| v * v).sum::<f64>() / (3 * target.len()) as f64)
        .sqrt()
        .max(f64::MIN_POSITIVE);
    let noise_floor = 0.5 * start.noise.sigma_mm_per_axis;
    let noise_floor = if noise_floor.is_finite() && noise_floor > 0.0 {
        noise_floor
    } else {
        1e-3 * spread
    };
    let n = model.robot.n_tubes();
    let widths: Vec<f64> = if n > 1 {
        PLAY_WIDTHS_DEG.to_vec()
    } else {
        vec![f64::NAN]
    };
    // each play width from the first start, then the likeliest from the others too
    let candidates = ctr_formats::parallel::map(&widths, start.threads, |&w| {
        let inputs = candidate_inputs(n, w);
        let values = values(rec, &joints, &inputs);
        let (inputs, mean, scale) = kept_inputs(&inputs, &values, &train)?;
        let kept = project(&values, &inputs.1);
        let problem = Likelihood::new(&kept, &train, &mean, &scale, &target, spread, noise_floor);
        let first = problem.best(&problem.starts()[..1])?;
        Some((first, problem, inputs.0, mean, scale, kept))
    });
    let (first, problem, inputs, mean, scale, kept) = candidates
        .into_iter()
        .flatten()
        .min_by(|a, b| a.0 .1.total_cmp(&b.0 .1))?;
    let others = problem.starts()[1..].to_vec();
    let more = ctr_formats::parallel::map(&others, start.threads, |h| problem.optimise(h));
    let best = more
        .into_iter()
        .flatten()
        .chain([first])
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let (theta, _) = best;
    let d = inputs.len();
    let discrepancy = Discrepancy {
        note: format!(
            "not physics: a Gaussian process over the joints and their history, fitted by \
             ctr-cli diagnose on {} ({} training rows)",
            rec.file,
            train.len()
        ),
        inputs,
        mean,
        scale,
        length_scales: theta[..d].to_vec(),
        signal_mm: theta[d],
        noise_mm: theta[d + 1],
        train: train.iter().map(|&r| kept[r].clone()).collect(),
        target_mm: target,
    };
    let gp = Gp::new(&discrepancy).ok()?;
    let at: Vec<([f64; 3], f64)> = kept.iter().map(|u| gp.at(u)).collect();
    let left: Vec<[f64; 3]> = positions(e)
        .iter()
        .zip(&at)
        .map(|(v, (m, _))| [v[0] + m[0], v[1] + m[1], v[2] + m[2]])
        .collect();
    let left = with_angles(&left, e);
    let cv = cross_validated(start, &discrepancy, &kept, &train, e)?;
    let mut report = account(start, &discrepancy, &left, &at, train.len());
    report.method += &format!(
        "; cross-validated over {CV_FOLDS} folds of those rows it leaves {:.3} mm against the \
         physics' {:.3} mm",
        cv.learned_mm, cv.physics_mm
    );
    Some((report, discrepancy, left, cv))
}

/// [`Cv`] of `d` (fitted on the rows `train`, whose inputs are `kept`) on `e` (the
/// physics' errors): [`CV_FOLDS`] folds of blocks of each run's training rows (of a
/// static set, of its poses), each predicted by `d`'s process conditioned on the others.
fn cross_validated(
    start: &Start,
    d: &Discrepancy,
    kept: &[Vec<f64>],
    train: &[usize],
    e: &[RowError],
) -> Option<Cv> {
    // the unit a fold keeps together: a static set's pose, else the row
    let mut unit = vec![0; start.rec.rows.len()];
    match &start.rec.poses {
        Some(poses) => {
            for (j, p) in poses.iter().enumerate() {
                unit[p.rows.clone()].iter_mut().for_each(|u| *u = j);
            }
        }
        None => unit.iter_mut().enumerate().for_each(|(r, u)| *u = r),
    }
    let units: Vec<usize> = train.iter().map(|&r| unit[r]).collect();
    // folds like the split's blocks: each run's training units in 2 K contiguous
    // blocks, block b in fold b mod K (every fold spans every run, as held-out blocks do)
    let mut fold = vec![0; train.len()];
    let mut distinct = 0;
    for run in &start.rec.runs {
        let mine: Vec<usize> = (0..train.len())
            .filter(|&i| run.rows.contains(&train[i]))
            .collect();
        let mut ranks: Vec<usize> = mine.iter().map(|&i| units[i]).collect();
        ranks.dedup();
        distinct += ranks.len();
        for &i in &mine {
            let rank = ranks.partition_point(|&u| u < units[i]);
            let block = if ranks.len() >= 2 * CV_FOLDS {
                rank * 2 * CV_FOLDS / ranks.len()
            } else {
                rank
            };
            fold[i] = block % CV_FOLDS;
        }
    }
    if distinct < CV_FOLDS {
        return None;
    }
    let fold_of = |i: usize| fold[i];
    let (mut learned, mut physics, mut n) = (0.0, 0.0, 0usize);
    for f in 0..CV_FOLDS {
        let (inside, outside): (Vec<usize>, Vec<usize>) =
            (0..train.len()).partition(|&i| fold_of(i) == f);
        let rest = Discrepancy {
            train: outside.iter().map(|&i| d.train[i].clone()).collect(),
            target_mm: outside.iter().map(|&i| d.target_mm[i]).collect(),
            ..d.clone()
        };
        let gp = Gp::new(&rest).ok()?;
        for &i in &inside {
            let r = train[i];
            let (m, _) = gp.at(&kept[r]);
            for a in 0..3 {
                learned += (e[r][a] + m[a]).powi(2);
                physics += e[r][a].powi(2);
            }
            n += 1;
        }
    }
    let rms = |s: f64| (s / n.max(1) as f64).sqrt();
    Some(Cv {
        learned_mm: rms(learned),
        physics_mm: rms(physics),
    })
}

/// Fewest training rows per input worth a process.
const MIN_INPUT_ROWS: usize = 5;

/// The fit rows, every `k`-th along each run, at most [`MAX_TRAIN_ROWS`].
fn training_rows(start: &Start) -> Vec<usize> {
    let every = start.fit_rows.len().div_ceil(MAX_TRAIN_ROWS).max(1);
    let mut out = Vec::new();
    for run in &start.rec.runs {
        let fit: Vec<usize> = run.rows.clone().filter(|&r| !start.held[r]).collect();
        out.extend(fit.into_iter().step_by(every));
    }
    out
}

/// Every input of `n` tubes, the relative rotations' plays of half-width `w` (none for
/// one tube).
fn candidate_inputs(n: usize, w: f64) -> Vec<Input> {
    let mut out: Vec<Input> = (0..n)
        .flat_map(|i| [Input::Feed(i), Input::Rotation(i)])
        .collect();
    out.extend((0..n.saturating_sub(1)).map(Input::Relative));
    if w.is_finite() {
        out.extend((0..n.saturating_sub(1)).map(|i| Input::Play(i, w)));
    }
    out
}

/// The inputs' values on every row, run by run along the joints the model takes.
fn values(rec: &ctr_formats::Recording, joints: &[Vec<f64>], inputs: &[Input]) -> Vec<Vec<f64>> {
    let mut out = vec![Vec::new(); rec.rows.len()];
    for run in &rec.runs {
        let rows: Vec<&[f64]> = run.rows.clone().map(|r| &joints[r][..]).collect();
        for (r, v) in run.rows.clone().zip(inputs_along_run(inputs, &rows)) {
            out[r] = v;
        }
    }
    out
}

/// The inputs kept (and their columns): those that vary on the training rows and are
/// no exact copy of one kept before (up to a constant); with each one's mean and spread
/// there.
#[allow(clippy::type_complexity)]
fn kept_inputs(
    inputs: &[Input],
    values: &[Vec<f64>],
    train: &[usize],
) -> Option<((Vec<Input>, Vec<usize>), Vec<f64>, Vec<f64>)> {
    let mut kept: Vec<(usize, Vec<f64>)> = Vec::new();
    let (mut mean, mut scale) = (Vec::new(), Vec::new());
    for j in 0..inputs.len() {
        let c: Vec<f64> = train.iter().map(|&r| values[r][j]).collect();
        let m = c.iter().sum::<f64>() / c.len() as f64;
        let centred: Vec<f64> = c.iter().map(|v| v - m).collect();
        let s = (centred.iter().map(|v| v * v).sum::<f64>() / c.len() as f64).sqrt();
        let varies = s > CONSTANT_SPREAD * (1.0 + m.abs());
        let copy = kept.iter().any(|(_, other)| {
            other
                .iter()
                .zip(&centred)
                .all(|(a, b)| (a - b).abs() <= CONSTANT_SPREAD * (1.0 + b.abs()))
        });
        if varies && !copy {
            kept.push((j, centred));
            mean.push(m);
            scale.push(s);
        }
    }
    let columns: Vec<usize> = kept.iter().map(|(j, _)| *j).collect();
    (!columns.is_empty()).then(|| {
        (
            (columns.iter().map(|&j| inputs[j]).collect(), columns),
            mean,
            scale,
        )
    })
}

/// Spread, relative to an input's size, below which it counts as constant (and the
/// difference below which two inputs count as one).
const CONSTANT_SPREAD: f64 = 1e-9;

/// Every row's values of the columns `kept`.
fn project(values: &[Vec<f64>], kept: &[usize]) -> Vec<Vec<f64>> {
    values
        .iter()
        .map(|v| kept.iter().map(|&j| v[j]).collect())
        .collect()
}

/// The report's account of the discrepancy: its figures (tip positions), inputs by
/// length scale, and its band's coverage of the held-out rows.
fn account(
    start: &Start,
    d: &Discrepancy,
    left: &[RowError],
    at: &[([f64; 3], f64)],
    train_rows: usize,
) -> Empirical {
    let fig = figures(start.rec, left, &start.held);
    let held: Vec<usize> = (0..left.len()).filter(|&r| start.held[r]).collect();
    let inside = held
        .iter()
        .flat_map(|&r| (0..3).map(move |a| (r, a)))
        .filter(|&(r, a)| left[r][a].abs() <= Z95 * at[r].1)
        .count();
    let mut sd: Vec<f64> = at.iter().map(|a| a.1).collect();
    sd.sort_by(f64::total_cmp);
    let mut inputs: Vec<GpInput> = d
        .inputs
        .iter()
        .zip(&d.length_scales)
        .map(|(i, l)| GpInput {
            input: i.name(),
            length_scale: *l,
        })
        .collect();
    inputs.sort_by(|a, b| a.length_scale.total_cmp(&b.length_scale));
    Empirical {
        method: format!(
            "a Gaussian process over the joints the model takes and the play operators of \
             their relative rotations (history), one squared exponential kernel over the \
             standardised inputs shared by x, y and z, its length scales, signal and noise \
             by the largest marginal likelihood of {train_rows} fit rows; not physics"
        ),
        terms: d.inputs.len(),
        rms_mm: fig.rms_mm,
        heldout_rms_mm: fig.heldout_rms_mm,
        dominant: Vec::new(),
        inputs,
        band: Some(Band {
            median_sd_mm: sd.get(sd.len() / 2).copied().unwrap_or(f64::NAN),
            signal_mm: d.signal_mm,
            noise_mm: d.noise_mm,
            heldout_coverage_95: inside as f64 / (3 * held.len()).max(1) as f64,
        }),
    }
}

/// The log marginal likelihood of the training rows as a function of the
/// hyperparameters (mapped from unbounded `p` into their bounds).
struct Likelihood {
    /// Training inputs, standardised (rows).
    u: DMatrix<f64>,
    /// Targets (rows, x y z).
    y: DMatrix<f64>,
    /// Bounds of each hyperparameter: length scales, signal, noise.
    bounds: Vec<(f64, f64)>,
    /// The targets' standard deviation, mm.
    spread: f64,
}

/// The negative log marginal likelihood and its gradient in the free parameters.
type Value = (f64, Vec<f64>);

/// A fitted start: the hyperparameters (length scales, signal, noise) and the negative
/// log marginal likelihood.
type Hyper = (Vec<f64>, f64);

impl Likelihood {
    fn new(
        values: &[Vec<f64>],
        train: &[usize],
        mean: &[f64],
        scale: &[f64],
        target: &[[f64; 3]],
        spread: f64,
        noise_floor: f64,
    ) -> Self {
        let d = mean.len();
        let u = DMatrix::from_fn(train.len(), d, |k, j| {
            (values[train[k]][j] - mean[j]) / scale[j]
        });
        let y = DMatrix::from_fn(train.len(), 3, |k, a| target[k][a]);
        let mut bounds = vec![LENGTH_SCALE_BOUNDS; d];
        bounds.push((SIGNAL_BOUNDS.0 * spread, SIGNAL_BOUNDS.1 * spread));
        let noise_hi = (MAX_NOISE_SHARE * spread).max(2.0 * noise_floor);
        bounds.push((noise_floor, noise_hi));
        Likelihood {
            u,
            y,
            bounds,
            spread,
        }
    }

    /// Starting hyperparameters: length scales 1, 3, 0.5 and 10, the signal the
    /// targets' spread, the noise a third, a tenth, a half and a fifth of it.
    fn starts(&self) -> Vec<Vec<f64>> {
        let d = self.u.ncols();
        [(1.0, 0.3), (3.0, 0.1), (0.5, 0.5), (10.0, 0.2)]
            .iter()
            .map(|&(l, noise)| {
                let mut h = vec![l; d];
                h.push(self.spread);
                h.push(noise * self.spread);
                h
            })
            .collect()
    }

    /// The best of the L-BFGS runs from `starts`.
    fn best(&self, starts: &[Vec<f64>]) -> Option<Hyper> {
        starts
            .iter()
            .filter_map(|h| self.optimise(h))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// One L-BFGS run from the hyperparameters `h0`.
    fn optimise(&self, h0: &[f64]) -> Option<Hyper> {
        let p0: Vec<f64> = h0
            .iter()
            .zip(&self.bounds)
            .map(|(h, b)| to_free(*h, *b))
            .collect();
        let solver = LBFGS::new(MoreThuenteLineSearch::new(), 7)
            .with_tolerance_cost(LIKELIHOOD_TOLERANCE_NATS)
            .ok()?;
        let run = Executor::new(Run::new(self), solver)
            .configure(|s| s.param(p0).max_iters(MAX_ITERATIONS))
            .run()
            .ok()?;
        let state = run.state();
        let p = state.get_best_param()?.clone();
        let cost = state.get_best_cost();
        cost.is_finite().then(|| (self.hyper(&p), cost))
    }

    /// The hyperparameters of the free parameters `p`.
    fn hyper(&self, p: &[f64]) -> Vec<f64> {
        p.iter()
            .zip(&self.bounds)
            .map(|(v, b)| from_free(*v, *b))
            .collect()
    }

    /// The negative log marginal likelihood at `p` and its gradient in `p`.
    fn value(&self, p: &[f64]) -> Option<Value> {
        let h = self.hyper(p);
        let (n, d) = (self.u.nrows(), self.u.ncols());
        let (s2, noise2) = (h[d] * h[d], h[d + 1] * h[d + 1]);
        // one column per training row (contiguous)
        let scaled = DMatrix::from_fn(d, n, |j, k| self.u[(k, j)] / h[j]);
        // symmetric: each pair's kernel once
        let mut kse = DMatrix::<f64>::zeros(n, n);
        for b in 0..n {
            for a in 0..=b {
                let v = kernel(scaled.column(a).as_slice(), scaled.column(b).as_slice(), s2);
                kse[(a, b)] = v;
                kse[(b, a)] = v;
            }
        }
        let k = &kse + DMatrix::identity(n, n) * noise2;
        let chol = k.cholesky()?;
        let alpha = chol.solve(&self.y);
        let log_det: f64 = 2.0
            * chol
                .l_dirty()
                .diagonal()
                .iter()
                .map(|v| v.ln())
                .sum::<f64>();
        let nlml = 0.5 * self.y.dot(&alpha)
            + 1.5 * log_det
            + 1.5 * n as f64 * (2.0 * std::f64::consts::PI).ln();
        // W = 3 K^-1 - alpha alpha^T: dNLML = 1/2 tr(W dK)
        let w = inverse_of_factor(chol.l_dirty()) * 3.0 - &alpha * alpha.transpose();
        let mut grad_h = vec![0.0; d + 2];
        // dk/dl_j = k (s_aj - s_bj)^2 / l_j (s the scaled inputs), so with the symmetric
        // V = W o K_se and its row sums r: sum_ab V_ab (s_a - s_b)^2 = 2 (s^2 . r - s^T V s),
        // every length scale's at once from one product S V
        let v = w.component_mul(&kse);
        let r = v.column_sum();
        let sv = &scaled * &v;
        for (j, g) in grad_h.iter_mut().enumerate().take(d) {
            let s_j = scaled.row(j);
            let squares: f64 = s_j.iter().zip(r.iter()).map(|(x, r)| x * x * r).sum();
            let quadratic = sv.row(j).dot(&s_j);
            *g = (squares - quadratic) / h[j];
        }
        grad_h[d] = 0.5 * v.sum() * 2.0 / h[d];
        grad_h[d + 1] = 0.5 * w.trace() * 2.0 * h[d + 1];
        // chain rule through the bounded map
        let grad: Vec<f64> = grad_h
            .iter()
            .zip(p)
            .zip(&self.bounds)
            .map(|((g, v), b)| g * free_derivative(*v, *b))
            .collect();
        Some((nlml, grad))
    }
}

/// `K^-1` from the lower triangle of `K`'s Cholesky factor `l` (its upper triangle
/// ignored): `M = L^-1` by forward substitution on contiguous columns (only the lower
/// triangle of each, `n^3 / 6` multiply-adds), then `K^-1 = M^T M`, each entry once for
/// both triangles and over the rows where both columns of `M` are not zero
/// (`K^-1_ij = sum_{k >= max(i, j)} M_ki M_kj`: another `n^3 / 6`, a sixth of the full
/// product). The same numbers as solving `K X = I`, in a fraction of its time (the
/// likelihood's gradient needs the whole inverse at every evaluation).
fn inverse_of_factor(l: &DMatrix<f64>) -> DMatrix<f64> {
    let n = l.nrows();
    let mut m = DMatrix::<f64>::zeros(n, n);
    for c in 0..n {
        let x = m.column_mut(c);
        let x = x.data.into_slice_mut();
        x[c] = 1.0;
        for k in c..n {
            let col = l.column(k);
            let col = col.as_slice();
            x[k] /= col[k];
            let xk = x[k];
            for (xi, li) in x[k + 1..].iter_mut().zip(&col[k + 1..]) {
                *xi -= li * xk;
            }
        }
    }
    let mut inverse = DMatrix::<f64>::zeros(n, n);
    // column-major: column c is m[c n .. (c + 1) n]
    let m = m.as_slice();
    for i in 0..n {
        let ci = &m[i * n + i..(i + 1) * n];
        for j in 0..=i {
            let v = dot(ci, &m[j * n + i..(j + 1) * n]);
            inverse[(i, j)] = v;
            inverse[(j, i)] = v;
        }
    }
    inverse
}

/// `a . b` over four running sums (which the compiler keeps in vector registers).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut sums = [0.0; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            sums[k] += x[k] * y[k];
        }
    }
    (sums[0] + sums[1]) + (sums[2] + sums[3]) + tail
}

/// One L-BFGS run over a [`Likelihood`]: argmin asks for the cost and the gradient at
/// the same point one after the other, so the run remembers its last value. Each run
/// has its own memory, so runs from several starts go side by side without waiting on
/// each other.
struct Run<'a> {
    likelihood: &'a Likelihood,
    /// The last value computed, at its free parameters.
    last: std::cell::RefCell<Option<(Vec<f64>, Value)>>,
}

impl<'a> Run<'a> {
    fn new(likelihood: &'a Likelihood) -> Self {
        Run {
            likelihood,
            last: std::cell::RefCell::new(None),
        }
    }

    /// [`Likelihood::value`], remembered for the last `p`.
    fn cached(&self, p: &[f64]) -> Option<Value> {
        let mut last = self.last.borrow_mut();
        if let Some((at, v)) = last.as_ref() {
            if at.as_slice() == p {
                return Some(v.clone());
            }
        }
        let v = self.likelihood.value(p)?;
        *last = Some((p.to_vec(), v.clone()));
        Some(v)
    }
}

impl CostFunction for Run<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, p: &Vec<f64>) -> Result<f64, argmin::core::Error> {
        Ok(self.cached(p).map_or(f64::INFINITY, |v| v.0))
    }
}

impl Gradient for Run<'_> {
    type Param = Vec<f64>;
    type Gradient = Vec<f64>;
    fn gradient(&self, p: &Vec<f64>) -> Result<Vec<f64>, argmin::core::Error> {
        self.cached(p)
            .map(|v| v.1)
            .ok_or_else(|| argmin::core::Error::msg("the kernel is not positive definite"))
    }
}

/// A hyperparameter in bounds `(lo, hi)` as a free parameter: the logit of its log's
/// place between the bounds' logs.
fn to_free(h: f64, (lo, hi): (f64, f64)) -> f64 {
    let t = ((h.clamp(lo, hi).ln() - lo.ln()) / (hi.ln() - lo.ln())).clamp(1e-6, 1.0 - 1e-6);
    (t / (1.0 - t)).ln()
}

/// The hyperparameter of free parameter `p` (see [`to_free`]).
fn from_free(p: f64, (lo, hi): (f64, f64)) -> f64 {
    let t = 1.0 / (1.0 + (-p).exp());
    (lo.ln() + t * (hi.ln() - lo.ln())).exp()
}

/// `d from_free / d p` at `p`.
fn free_derivative(p: f64, b: (f64, f64)) -> f64 {
    let t = 1.0 / (1.0 + (-p).exp());
    from_free(p, b) * (b.1.ln() - b.0.ln()) * t * (1.0 - t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bounded_map_round_trips_and_its_derivative_is_the_difference_quotient() {
        let b = (0.05, 100.0);
        for h in [0.06, 1.0, 42.0] {
            assert!((from_free(to_free(h, b), b) - h).abs() < 1e-9 * h);
        }
        let (p, dp) = (0.3, 1e-6);
        let fd = (from_free(p + dp, b) - from_free(p - dp, b)) / (2.0 * dp);
        assert!((free_derivative(p, b) - fd).abs() < 1e-6 * fd.abs());
    }

    #[test]
    fn the_inverse_from_the_factor_is_the_inverse() {
        let n = 7;
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 5) as f64 - 2.0);
        let k = &a * a.transpose() + DMatrix::identity(n, n) * 0.5;
        let chol = k.clone().cholesky().unwrap();
        let inv = super::inverse_of_factor(chol.l_dirty());
        let eye = &k * &inv;
        assert!((eye - DMatrix::identity(n, n)).amax() < 1e-12);
        assert!((inv - chol.inverse()).amax() < 1e-12);
    }

    #[test]
    fn the_likelihood_gradient_is_the_difference_quotient() {
        // a smooth function of two inputs with noise-free targets
        let values: Vec<Vec<f64>> = (0..30)
            .map(|i| vec![f64::from(i) * 0.3, (f64::from(i) * 0.7).sin()])
            .collect();
        let train: Vec<usize> = (0..30).collect();
        let target: Vec<[f64; 3]> = values
            .iter()
            .map(|v| [v[0].sin(), v[1] * 0.5, v[0] * v[1] * 0.1])
            .collect();
        let l = Likelihood::new(
            &values,
            &train,
            &[4.5, 0.0],
            &[2.6, 0.7],
            &target,
            0.5,
            0.01,
        );
        let p: Vec<f64> = vec![0.2, -0.4, 0.1, -1.0];
        let (_, g) = l.value(&p).unwrap();
        for j in 0..p.len() {
            let mut a = p.clone();
            let mut b = p.clone();
            a[j] += 1e-6;
            b[j] -= 1e-6;
            let fd = (l.value(&a).unwrap().0 - l.value(&b).unwrap().0) / 2e-6;
            assert!(
                (g[j] - fd).abs() <= 1e-4 * (1.0 + fd.abs()),
                "parameter {j}: analytic {} against {fd}",
                g[j]
            );
        }
    }
}

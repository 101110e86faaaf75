//! The screen: which candidates of a search round are worth a full fit.
//!
//! A full fit of a candidate frees the effects found so far beside it, so its cost per
//! Levenberg-Marquardt iteration grows with every effect found (two finite-difference
//! predictions per parameter), and under gravity each prediction is a loaded solve.
//! Fitting every candidate that way in every round is what made a diagnosis slow when
//! the cause lies outside the vocabulary (every round fits every candidate). The screen
//! fits each candidate with only its own parameters free, the effects found so far held
//! at their values, on a sample of at most [`SCREEN_ROWS`] evenly spread fit rows (a
//! candidate with several starts fits each on a coarser sample first, [`COARSE_ROWS`],
//! and goes on from the best). A held screen cannot see a candidate that only pays once a
//! held effect moves with it (a stiffness beside the precurvature found first: the
//! kinematics pin their ratio), so each is ranked by its projected cost: the screened
//! cost less the Gauss-Newton decrease `g^T H^-1 g` of the held effects' parameters and
//! its own together, the held ones' Jacobian taken once per round at the held model.
//! Then only the [`FULL_FITS`] candidates of the lowest projected cost are fitted in full, from where their screen ended (a full fit
//! stops early when the information criterion's cost is out of its linearised reach,
//! [`crate::fit::Problem::fit_until`]), and the one of them that does best on the
//! held-out rows is added if it passes.
//!
//! The others are judged on their screen in the report's trials: the information
//! criterion of their screened cost against the held model's on the same rows,
//! `n ln(cost / cost0) + k ln n` with `n` the sample's observations.
//!
//! Measured with `scripts/bench_diagnose.sh` (issue 16): the same findings on every
//! public recording and the generated ones, the parameters within the fits' stopping
//! tolerance, at a fraction of the time.

use crate::candidates::EffectId;
use crate::fit::{Problem, MAX_FIT_ITERATIONS};
use crate::found::Found;
use crate::levenberg::{projected_gain, Fitted};
use crate::residual::components;
use crate::start::Start;
use ctr_analysis::model::ModelSpec;
use ctr_formats::Recording;
use nalgebra::{DMatrix, DVector};

/// Most fit rows a screen counts (evenly spread; every fit row below it).
pub(crate) const SCREEN_ROWS: usize = 400;
/// Candidates fitted in full per round: those whose screen lowered the cost most.
pub(crate) const FULL_FITS: usize = 3;
/// Most sample rows a candidate's start is first fitted on, when it has several
/// (clearance's peak angles, latency's signs): the starts only pick a basin, and the
/// best one goes on from where it ended on the whole sample.
pub(crate) const COARSE_ROWS: usize = 100;

/// A round's screen: the model found so far and the sample of rows.
pub(crate) struct Screen<'a> {
    base: ModelSpec,
    rec: &'a Recording,
    rows: Vec<usize>,
    /// One sampled row in this many fit rows.
    every: usize,
    huber_mm: f64,
    /// The held model's robust cost on the sample, mm^2 (infinite if it cannot be
    /// simulated there).
    pub cost0: f64,
    /// The Jacobian of the sample's predictions in the held effects' parameters, at
    /// the held model (none before the first effect is found).
    held_jacobian: Option<DMatrix<f64>>,
}

/// A candidate's screen: its best start's parameters and robust cost on the sample.
#[derive(Clone, Debug)]
pub(crate) struct Screened {
    pub effect: EffectId,
    pub x: Vec<f64>,
    pub cost: f64,
    /// Where the cost would go with the held effects freed too: the screened cost
    /// less the Gauss-Newton decrease of the held and the candidate's parameters
    /// together (what ranks the candidates: a candidate that needs a held effect to
    /// move shows it here, e.g. a stiffness beside a precurvature found first).
    pub projected: f64,
}

/// Every `every`-th of `rows` (ascending) counted from each run's first of them: a
/// run's sample is the same rows wherever the run stands in the file (a screen that
/// ends in another basin when the runs are reordered would change the account).
fn every_in_runs(rec: &Recording, rows: &[usize], every: usize) -> Vec<usize> {
    let mut out = Vec::with_capacity(rows.len() / every.max(1) + rec.runs.len());
    let (mut run, mut k) = (usize::MAX, 0);
    for &r in rows {
        if rec.rows[r].run != run {
            (run, k) = (rec.rows[r].run, 0);
        }
        if k % every.max(1) == 0 {
            out.push(r);
        }
        k += 1;
    }
    out
}

impl<'a> Screen<'a> {
    /// The screen of candidates added to `current`, which holds the effects `held`,
    /// on a sample of `fit_rows` (`threads` for the held effects' Jacobian).
    pub fn new(
        current: &ModelSpec,
        held: &[EffectId],
        rec: &'a Recording,
        fit_rows: &[usize],
        huber_mm: f64,
        threads: usize,
    ) -> Self {
        let every = fit_rows.len().div_ceil(SCREEN_ROWS).max(1);
        let mut screen = Screen {
            base: current.clone(),
            rec,
            rows: every_in_runs(rec, fit_rows, every),
            every,
            huber_mm,
            cost0: f64::INFINITY,
            held_jacobian: None,
        };
        screen.cost0 = screen.problem(vec![]).cost_at(&[]).unwrap_or(f64::INFINITY);
        if !held.is_empty() {
            let mut p = screen.problem(held.to_vec());
            p.threads = threads;
            let x = p.read(current);
            screen.held_jacobian = p.predictions(&x).and_then(|p0| p.jacobian(&x, &p0));
        }
        screen
    }

    /// The screen of a search round from `found`: candidates added to its model, the
    /// effects it holds held, on a sample of `start`'s fit rows.
    pub(crate) fn beside(start: &Start<'a>, found: &Found) -> Self {
        Screen::new(
            &found.model,
            &found.effects(),
            start.rec,
            &start.fit_rows,
            start.huber_mm(),
            start.threads,
        )
    }

    fn problem(&self, blocks: Vec<EffectId>) -> Problem<'a> {
        Problem {
            base: self.base.clone(),
            blocks,
            rec: self.rec,
            rows: self.rows.clone(),
            huber_mm: self.huber_mm,
            threads: 1,
            clearance_table: None,
        }
    }

    /// Candidate `c` fitted alone from `x0` on the sample (one thread).
    pub fn fit(&self, c: EffectId, x0: &[f64]) -> Option<Fitted> {
        self.problem(vec![c]).fit(x0, MAX_FIT_ITERATIONS)
    }

    /// Candidate `c` fitted alone from `x0` on every k-th row of the sample, at most
    /// [`COARSE_ROWS`] (one thread): a start's first look.
    fn fit_coarse(&self, c: EffectId, x0: &[f64]) -> Option<Fitted> {
        let mut p = self.problem(vec![c]);
        let every = p.rows.len().div_ceil(COARSE_ROWS).max(1);
        p.rows = every_in_runs(self.rec, &p.rows, every);
        p.fit(x0, MAX_FIT_ITERATIONS)
    }

    /// Every candidate of `todo` fitted alone on the sample from its starts
    /// ([`EffectId::starts`], `sample_period_s` for latency's), on `threads`: one
    /// start on the whole sample; several each on a coarse sample first
    /// ([`COARSE_ROWS`]), the best of them (the first where none could be simulated)
    /// then on the whole sample from where it ended. One result per candidate, in
    /// `todo`'s order; the result does not depend on the thread count.
    pub fn fit_all(
        &self,
        todo: &[EffectId],
        n: usize,
        sample_period_s: f64,
        threads: usize,
    ) -> Vec<Option<Fitted>> {
        let starts: Vec<Vec<Vec<f64>>> =
            todo.iter().map(|c| c.starts(n, sample_period_s)).collect();
        // the single starts in full and the several on the coarse sample, side by side
        let jobs: Vec<(usize, &Vec<f64>)> = starts
            .iter()
            .enumerate()
            .flat_map(|(i, s)| s.iter().map(move |x0| (i, x0)))
            .collect();
        let first = ctr_formats::parallel::map(&jobs, threads, |&(i, x0)| {
            if starts[i].len() == 1 {
                self.fit(todo[i], x0)
            } else {
                self.fit_coarse(todo[i], x0)
            }
        });
        let mut out: Vec<Option<Fitted>> = vec![None; todo.len()];
        let mut again: Vec<(usize, Vec<f64>)> = Vec::new();
        for (i, s) in starts.iter().enumerate() {
            let mine = jobs.iter().zip(&first).filter(|((j, _), _)| *j == i);
            if s.len() == 1 {
                out[i] = mine.map(|(_, f)| f.clone()).next().flatten();
                continue;
            }
            let best = mine
                .filter_map(|(_, f)| f.as_ref())
                .min_by(|a, b| a.cost.total_cmp(&b.cost))
                .map_or_else(|| s[0].clone(), |f| f.x.clone());
            again.push((i, best));
        }
        let finals = ctr_formats::parallel::map(&again, threads, |(i, x0)| self.fit(todo[*i], x0));
        for ((i, _), f) in again.iter().zip(finals) {
            out[*i] = f;
        }
        out
    }

    /// The candidates `todo` by their screen (`screened` holds one result per
    /// candidate, [`fit_all`](Self::fit_all)), lowest projected cost first; those that
    /// could not be simulated left out. The projections on `threads`.
    pub fn rank(
        &self,
        todo: &[EffectId],
        screened: &[Option<Fitted>],
        threads: usize,
    ) -> Vec<Screened> {
        let best: Vec<(EffectId, &Fitted)> = todo
            .iter()
            .zip(screened)
            .filter_map(|(&c, f)| Some((c, f.as_ref()?)))
            .collect();
        let mut ranked = ctr_formats::parallel::map(&best, threads, |&(c, f)| Screened {
            effect: c,
            x: f.x.clone(),
            cost: f.cost,
            projected: self.projected(c, &f.x).unwrap_or(f.cost),
        });
        ranked.sort_by(|a, b| a.projected.total_cmp(&b.projected));
        ranked
    }

    /// The screened candidate `c` at `x` with the held effects freed beside it, in the
    /// Gauss-Newton model: its cost less `g^T H^-1 g` over the held effects' columns
    /// (at the held model) and the candidate's (at `x`). `None` where it cannot be
    /// simulated.
    fn projected(&self, c: EffectId, x: &[f64]) -> Option<f64> {
        let p = self.problem(vec![c]);
        let pred = p.predictions(x)?;
        let e = p.errors(&pred);
        let (cost, w) = p.cost(&e);
        let Some(held) = &self.held_jacobian else {
            return Some(cost);
        };
        let jc = p.jacobian(x, &pred)?;
        let (na, nc) = (held.ncols(), jc.ncols());
        let mut h = DMatrix::<f64>::zeros(na + nc, na + nc);
        let mut g = DVector::<f64>::zeros(na + nc);
        let mut row = DVector::<f64>::zeros(na + nc);
        for i in 0..e.len().min(held.nrows()) {
            for j in 0..na {
                row[j] = held[(i, j)];
            }
            for j in 0..nc {
                row[na + j] = jc[(i, j)];
            }
            let wi = w[i / 3];
            g.axpy(wi * e[i], &row, 1.0);
            h.ger(wi, &row, &row, 1.0);
        }
        let dmax = (0..na + nc).map(|j| h[(j, j)]).fold(0.0, f64::max);
        if dmax <= 0.0 {
            return Some(cost);
        }
        Some(cost - projected_gain(&h, &g, dmax))
    }

    /// The held model with candidate `c`'s parameters `x`.
    pub fn model(&self, c: EffectId, x: &[f64]) -> ModelSpec {
        self.problem(vec![c]).model(x)
    }

    /// Change of the information criterion for a screened `cost` with `k` parameters.
    pub fn bic(&self, cost: f64, k: usize) -> f64 {
        let n_obs = (components(self.rec) * self.rows.len()) as f64;
        n_obs * (cost / self.cost0).ln() + k as f64 * n_obs.ln()
    }

    /// The sample in words: "every fit row" or "one in K fit rows".
    pub fn rows_in_words(&self) -> String {
        if self.every == 1 {
            "on every fit row".into()
        } else {
            format!("on one fit row in {}", self.every)
        }
    }
}

//! The checks every finding of the search must pass, with all the other findings in
//! place, before the report calls it physics. A wrong confident finding is the worst
//! output of a diagnosis; these checks trade a little sensitivity for that.
//!
//! Let `M` be the fitted model with its findings, `e` its error on every row and `h`
//! its held-out RMS; `sigma_n` the noise estimate's RMS. For a finding `c` with `k`
//! parameters:
//!
//! 1. **It beats a generic correction of its size** ([`empirical`]: in the joints and
//!    time, so that the registration, itself a map of the tip position, is not measured
//!    against its own form), within the hybrid model. Let `K` be the size of generic
//!    correction that cross-validation on the fit rows gives what `M` leaves. Take `c`
//!    out of `M` (the others stay as fitted) and give that model `K + k` generic terms;
//!    `M` with `K` terms must do clearly better on the held-out rows:
//!    `h_K < (1 - MIN_GAIN_OVER_EMPIRICAL) h_emp`. So `c` must explain something a
//!    generic term cannot, and something else that is left (a drift) neither saves a
//!    proxy nor sinks a true effect. Where `M` leaves nothing but noise on the held-out
//!    rows (`h <= NOISE_TOLERANCE sigma_n`, then `K = 0`), the generic correction in
//!    `c`'s place may also hold the linear maps of the modelled tip position that no
//!    rigid motion makes ([`non_rigid`]: stretches and symmetric shears; rotations
//!    and translations are the registration's, in the vocabulary): what a tracker's
//!    scale or calibration error makes, and what an effect that reaches the noise
//!    through the tip's pose (a sensor offset along the tip, which turns with it) can
//!    mimic. `c` must then beat that correction of `k` terms by the same margin and,
//!    where that correction too leaves only noise, beyond chance ([`clearly_lower`]: a
//!    paired test of the held-out squared errors over blocks of consecutive rows).
//!    An effect whose own form is a map of the tip position ([`affine_in_tip`]: every
//!    parameter direction affine in the tip position, as a registration's) is not
//!    measured against itself: it passes at the noise, the physics the hypothesis.
//! 2. **Its parameters are constant, not proportional to something.** An effect
//!    claims a fixed set of parameters: its error is `J_c(q) dx` with `J_c` the
//!    derivative of the tip with respect to its parameters and `dx` constant over the
//!    rows. With `c` taken out of `M`, compare two linear fits of that error on the
//!    fit rows, each with `k` terms: the constant `J_c,j(q)` columns, and the best `k`
//!    of the fields `J_c,j(q) f(q)` with `f` a feature of the rows in its own units
//!    (a feed, a rotation's cosine, the time, the tip position: [`Basis::raw`]), which
//!    vanish where the feature does, as a gain's error does. If the proportional
//!    fields do clearly better on the held-out rows, the effect is the shadow of a gain
//!    or a drift on its own directions (a feed *offset* where the feed *gain* is
//!    wrong, a registration where the tracker's scale is): outside the vocabulary.
//!
//! 3. **Its parameters are identified.** With every finding fitted together, the
//!    covariance of [`uncertainty`] (the larger of the classical and the
//!    cluster-robust variances, so a structured residual widens it) must put the
//!    user's nominal values outside the finding's joint 95 % region: the Wald
//!    statistic `d^T Sigma^+ d` of its parameters' distance `d` from the nominal
//!    exceeds the chi-square quantile of their rank ([`wald`]). A finding
//!    whose values the data cannot tell from the nominal is no finding, however much
//!    it lowered the cost on the way.
//!
//! Checks 1 and 2 run first on every finding; check 3 once they all pass (it needs the
//! joint fit's covariance, which a finding taken out changes). The findings that fail
//! are taken out, the others are refitted together, and the checks run again until
//! every finding passes. [`Checks`] turns one off, to show what it is for.

use crate::candidates::EffectId;
use crate::empirical::hybrid;
use crate::empirical::{self, Basis, Field};
use crate::fit::Problem;
use crate::options::Checks;
use crate::quantiles::{chi2_95, Z975};
use crate::residual::{errors, figures, positions, size2, tips, with_angles, RowError};
use crate::start::noise::NOISE_TOLERANCE;
use crate::uncertainty::{self, Assessment};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_formats::Recording;
use nalgebra::{DMatrix, DVector};

/// Smallest relative margin by which the model's held-out RMS must undercut that of
/// the generic empirical correction with as many free parameters, with the finding
/// taken out, for the finding to count as physics.
pub const MIN_GAIN_OVER_EMPIRICAL: f64 = 0.02;

/// Eigenvalue of a finding's correlation block, relative to its largest, below which
/// its direction counts as not identified in the Wald test (a parameter pinned only
/// with others).
const WALD_RANK_CUTOFF: f64 = 1e-8;

/// What the checks run on.
pub(crate) struct Context<'a> {
    rec: &'a Recording,
    /// Whether each row is held out.
    held: &'a [bool],
    /// Whether each row is fitted.
    fit: Vec<bool>,
    /// The generic correction's terms in the joints and time, as fields over the rows
    /// (the same for every check of a diagnosis: built once).
    yardstick: Vec<Field>,
    /// Huber threshold of the fits, mm.
    huber_mm: f64,
    /// Worker threads.
    threads: usize,
    /// The noise estimate's RMS, mm.
    noise_rms_mm: f64,
    /// Which checks run.
    checks: Checks,
}

/// Why a finding failed its checks.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Failure {
    /// A generic correction of as many parameters does as well.
    Empirical {
        /// Its held-out RMS, mm.
        heldout_rms_mm: f64,
        /// Whether the correction was also linear in the tip position (the yardstick
        /// where the model leaves only noise).
        tip: bool,
    },
    /// The effect's parameters are better proportional to a feature of the rows.
    Varying {
        /// The feature they are proportional to (the first chosen).
        feature: String,
        /// Held-out RMS of the constant parameters (linearised), mm.
        constant_heldout_rms_mm: f64,
        /// Held-out RMS of the proportional ones, mm.
        heldout_rms_mm: f64,
    },
    /// The data cannot tell its parameters from the nominal.
    NotIdentified {
        /// The Wald statistic of its parameters against the nominal.
        statistic: f64,
        /// The 95 % threshold it had to exceed.
        threshold: f64,
    },
}

/// A finding's checks.
#[derive(Clone, Debug)]
pub(crate) struct Checked {
    pub(crate) effect: EffectId,
    /// Held-out RMS of the generic correction of the finding's size, the finding taken
    /// out (NaN for torsion, which has no parameter), mm.
    pub(crate) empirical_heldout_rms_mm: f64,
    pub(crate) failure: Option<Failure>,
}

impl<'a> Context<'a> {
    /// The checks of a diagnosis of `rec` split by `held`, with the fits' Huber
    /// threshold, threads and the noise estimate's RMS (mm).
    pub(crate) fn new(
        rec: &'a Recording,
        held: &'a [bool],
        huber_mm: f64,
        threads: usize,
        noise_rms_mm: f64,
        checks: Checks,
    ) -> Self {
        let fit: Vec<bool> = held.iter().map(|h| !h).collect();
        let yardstick = Basis::joints_and_time(rec, &fit).fields();
        Context {
            rec,
            held,
            fit,
            yardstick,
            huber_mm,
            threads,
            noise_rms_mm,
            checks,
        }
    }

    fn errors_of(&self, m: &ModelSpec) -> Option<Vec<RowError>> {
        let all: Vec<usize> = (0..self.rec.runs.len()).collect();
        predict(m, self.rec, &all)
            .ok()
            .map(|p| errors(self.rec, &p))
    }

    /// Held-out RMS of `e` after the best `k`-term generic correction in the joints
    /// and time fitted to its positions (the angular errors stay).
    fn empirical_heldout(&self, e_row: &[RowError], k: usize) -> f64 {
        let e = &positions(e_row);
        let w = empirical::weights(e, &self.fit, self.huber_mm);
        let terms = empirical::pursue(&self.yardstick, e, &w, k);
        let left = empirical::subtract(&self.yardstick, &terms, e);
        figures(&with_angles(&left, e_row), self.held).heldout_rms_mm
    }

    /// What `e` leaves after the best `k`-term generic correction in the joints, time
    /// and the non-rigid linear maps of the modelled tip position, every row.
    fn empirical_with_tip(&self, e_row: &[RowError], k: usize) -> Vec<RowError> {
        let e = &positions(e_row);
        let mut fields = self.yardstick.clone();
        fields.extend(non_rigid(&tips(self.rec, e_row), &self.fit));
        let w = empirical::weights(e, &self.fit, self.huber_mm);
        let terms = empirical::pursue(&fields, e, &w, k);
        with_angles(&empirical::subtract(&fields, &terms, e), e_row)
    }

    /// The size of the generic correction (joints and time) that cross-validation on
    /// the fit rows gives `e`: what is left that a generic term takes, whatever it is.
    fn generic_size(&self, e_row: &[RowError]) -> usize {
        let e = &positions(e_row);
        let w = empirical::weights(e, &self.fit, self.huber_mm);
        hybrid::choose_size(&self.yardstick, e, &w)
    }

    /// Checks finding `c` of `m` (whose error is `e`, held-out RMS `h`).
    pub(crate) fn check(&self, m: &ModelSpec, e: &[RowError], c: EffectId) -> Checked {
        let n = m.robot.n_tubes();
        let k = c.n_params(n);
        let h = figures(e, self.held).heldout_rms_mm;
        let at_noise = h <= NOISE_TOLERANCE * self.noise_rms_mm;
        let mut out = Checked {
            effect: c,
            empirical_heldout_rms_mm: f64::NAN,
            failure: None,
        };
        if k == 0 {
            return out;
        }
        // 1. against a generic correction of its size, the finding taken out
        let mut without = m.clone();
        c.remove(&mut without);
        if let Some(e_without) = self.errors_of(&without) {
            // both sides get the generic term that what `M` leaves asks for (size by
            // cross-validation), the side without `c` k terms more: `c` must explain
            // something a generic term cannot, not just something else that is left
            let size = if at_noise { 0 } else { self.generic_size(e) };
            let h_with = if size == 0 {
                h
            } else {
                self.empirical_heldout(e, size)
            };
            // where `M` leaves only noise, the correction in `c`'s place may also be
            // linear in the tip position (what a tracker's scale or calibration error
            // makes, and what an effect that reaches the noise through the tip's pose,
            // a sensor offset along the tip, can mimic), unless `c`'s own form is such
            // a map (a registration): it is not measured against itself
            let directions = if at_noise {
                self.directions(m, c)
            } else {
                None
            };
            let tip = directions
                .as_ref()
                .is_some_and(|d| !affine_in_tip(d, &tips(self.rec, e)));
            let (h_emp, left_emp) = if tip {
                let left = self.empirical_with_tip(&e_without, k);
                (figures(&left, self.held).heldout_rms_mm, Some(left))
            } else {
                (self.empirical_heldout(&e_without, size + k), None)
            };
            out.empirical_heldout_rms_mm = h_emp;
            // where the generic correction too leaves only noise, both explain the
            // data and clearly also means beyond chance
            let both_at_noise = h_emp <= NOISE_TOLERANCE * self.noise_rms_mm;
            let beaten = h_with >= (1.0 - MIN_GAIN_OVER_EMPIRICAL) * h_emp
                || (both_at_noise
                    && left_emp
                        .as_ref()
                        .is_some_and(|l| !clearly_lower(e, l, self.held)));
            if self.checks.beats_generic && (!at_noise || tip) && beaten {
                out.failure = Some(Failure::Empirical {
                    heldout_rms_mm: h_emp,
                    tip,
                });
                return out;
            }
            if at_noise {
                return out;
            }
            // 2. constant parameters against parameters proportional to a feature
            if !self.checks.constant {
                return out;
            }
            if let Some((feature, h_const, h_prop)) = self.proportional(m, &e_without, c) {
                if h_prop < (1.0 - MIN_GAIN_OVER_EMPIRICAL) * h_const {
                    out.failure = Some(Failure::Varying {
                        feature,
                        constant_heldout_rms_mm: h_const,
                        heldout_rms_mm: h_prop,
                    });
                }
            }
        }
        out
    }

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
        let problem =
            uncertainty::problem_of(self.rec, m, accepted, fit_rows, self.huber_mm, self.threads);
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
                (statistic <= threshold).then_some((
                    c,
                    Failure::NotIdentified {
                        statistic,
                        threshold,
                    },
                ))
            })
            .collect();
        (failures, Some(a))
    }

    /// The tip directions of `c`'s parameters in `m` at every row: column `j` of the
    /// Jacobian of the tip positions with respect to its parameters, `J_c,j(q)`.
    fn directions(&self, m: &ModelSpec, c: EffectId) -> Option<Vec<Field>> {
        let rows = self.rec.rows.len();
        let problem = Problem {
            base: m.clone(),
            blocks: vec![c],
            rec: self.rec,
            rows: (0..rows).collect(),
            huber_mm: self.huber_mm,
            threads: self.threads,
            clearance_table: None,
        };
        let x = c.read(m);
        let p0 = problem.predictions(&x)?;
        let jac = problem.jacobian(&x, &p0)?;
        Some(
            (0..jac.ncols())
                .map(|j| {
                    (0..rows)
                        .map(|r| [jac[(3 * r, j)], jac[(3 * r + 1, j)], jac[(3 * r + 2, j)]])
                        .collect()
                })
                .collect(),
        )
    }

    /// With `c` taken out (its error `e`): the held-out RMS of the linear fit of the
    /// `k` constant parameter directions `J_c,j`, and of the best `k` proportional
    /// fields `J_c,j f`, with the feature chosen first.
    fn proportional(
        &self,
        m: &ModelSpec,
        e_row: &[RowError],
        c: EffectId,
    ) -> Option<(String, f64, f64)> {
        // fitted to the positions (the tip directions `J_c`); the angular errors stay
        let e = &positions(e_row);
        let rows = self.rec.rows.len();
        let constant = self.directions(m, c)?;
        let k = constant.len();
        let direction = |j: usize, r: usize| constant[j][r];
        let basis = Basis::raw(self.rec, &tips(self.rec, e_row));
        let mut fields: Vec<Field> = Vec::new();
        let mut names = Vec::new();
        for j in 0..k {
            for (feature, col) in basis.varying() {
                fields.push(
                    (0..rows)
                        .map(|r| direction(j, r).map(|d| d * col[r]))
                        .collect(),
                );
                names.push(feature.name());
            }
        }
        let w = empirical::weights(e, &self.fit, self.huber_mm);
        let heldout = |fields: &[Field], terms: &[(usize, f64)]| {
            let left = empirical::subtract(fields, terms, e);
            figures(&with_angles(&left, e_row), self.held).heldout_rms_mm
        };
        let all: Vec<usize> = (0..k).collect();
        let h_const = heldout(&constant, &empirical::coefficients(&constant, &all, e, &w));
        let terms = empirical::pursue(&fields, e, &w, k);
        let first = terms.first().map(|&(i, _)| names[i].clone())?;
        Some((first, h_const, heldout(&fields, &terms)))
    }
}

/// Held-out rows of one block of the paired comparison of [`clearly_lower`]
/// (consecutive rows share their errors; the cross-validation's blocks are as long).
const PAIRED_BLOCK_ROWS: usize = 10;

/// Whether the held-out squared errors of `a` are lower than those of `b` beyond
/// chance: the mean paired difference `|b|^2 - |a|^2` over the held-out rows exceeds
/// [`Z975`] times its standard error, taken over blocks of up to
/// [`PAIRED_BLOCK_ROWS`] consecutive held-out rows (so errors correlated along a run
/// count once per block).
pub(crate) fn clearly_lower(a: &[RowError], b: &[RowError], held: &[bool]) -> bool {
    let mut blocks: Vec<(f64, usize)> = Vec::new();
    let mut open = false;
    for (r, h) in held.iter().enumerate() {
        if !h {
            open = false;
            continue;
        }
        let d = size2(&b[r]) - size2(&a[r]);
        match blocks.last_mut() {
            Some((sum, n)) if open && *n < PAIRED_BLOCK_ROWS => {
                *sum += d;
                *n += 1;
            }
            _ => blocks.push((d, 1)),
        }
        open = true;
    }
    let g = blocks.len();
    let rows: usize = blocks.iter().map(|b| b.1).sum();
    if g < 2 {
        return false;
    }
    let mean = blocks.iter().map(|b| b.0).sum::<f64>() / rows as f64;
    let var = blocks
        .iter()
        .map(|&(sum, n)| (sum - n as f64 * mean).powi(2))
        .sum::<f64>()
        * g as f64
        / (g - 1) as f64;
    mean > Z975 * var.sqrt() / rows as f64
}

/// The linear maps of the tip position `p` that no rigid motion makes, as fields over
/// the rows (each coordinate centred and scaled on the `fit` rows, `u`): the three
/// stretches along an axis (`u_a` on axis `a`) and the three symmetric shears (`u_b` on
/// `a` and `u_a` on `b`). A tracker's scale or calibration error is a sum of them; a
/// rotation (antisymmetric) or a translation, a registration's, is not: that belongs to
/// the vocabulary.
fn non_rigid(p: &[[f64; 3]], fit: &[bool]) -> Vec<Field> {
    let n = fit.iter().filter(|f| **f).count().max(1) as f64;
    let u: Vec<[f64; 3]> = {
        let mut centre = [0.0; 3];
        let mut spread = [0.0; 3];
        for a in 0..3 {
            centre[a] = p
                .iter()
                .zip(fit)
                .filter(|(_, f)| **f)
                .map(|(v, _)| v[a])
                .sum::<f64>()
                / n;
            let var = p
                .iter()
                .zip(fit)
                .filter(|(_, f)| **f)
                .map(|(v, _)| (v[a] - centre[a]).powi(2))
                .sum::<f64>()
                / n;
            spread[a] = if var > 0.0 { var.sqrt() } else { 1.0 };
        }
        p.iter()
            .map(|v| [0, 1, 2].map(|a| (v[a] - centre[a]) / spread[a]))
            .collect()
    };
    let mut fields: Vec<Field> = (0..3)
        .map(|a| {
            u.iter()
                .map(|v| {
                    let mut f = [0.0; 3];
                    f[a] = v[a];
                    f
                })
                .collect()
        })
        .collect();
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        fields.push(
            u.iter()
                .map(|v| {
                    let mut f = [0.0; 3];
                    f[a] = v[b];
                    f[b] = v[a];
                    f
                })
                .collect(),
        );
    }
    fields
}

/// Share of a parameter direction's squared size an affine map of the tip position
/// may leave for the effect to count as itself such a map.
const AFFINE_LEFT: f64 = 1e-2;

/// Whether every parameter direction `J_c,j` of an effect (over the rows, modelled tips
/// `tips`) is, axis by axis, an affine function of the tip position to within
/// [`AFFINE_LEFT`] of its squared size: a registration's are (a translation and a
/// rotation of the tip positions), a sensor offset's, which turn with the tip, are not.
/// Directions that move no tip count as affine.
fn affine_in_tip(directions: &[Field], tips: &[[f64; 3]]) -> bool {
    let rows = tips.len();
    let a = DMatrix::from_fn(rows, 4, |r, j| if j == 0 { 1.0 } else { tips[r][j - 1] });
    let svd = a.clone().svd(true, true);
    directions.iter().all(|d| {
        let (mut total, mut left) = (0.0, 0.0);
        for axis in 0..3 {
            let b = DVector::from_fn(rows, |r, _| d[r][axis]);
            let Ok(coef) = svd.solve(&b, 1e-12) else {
                return false;
            };
            let res = &b - &a * coef;
            total += b.norm_squared();
            left += res.norm_squared();
        }
        left <= AFFINE_LEFT * total
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{record, CommandedRun, SynthSpec};
    use ctr_formats::{Latency, RobotSpec};

    /// Tracker noise of the test recordings, mm per axis.
    const SIGMA_MM: f64 = 0.2;

    fn user() -> ModelSpec {
        let spec = RobotSpec::from_toml_str(
            "[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\nlength_mm = 200.0\n\
             curved_length_mm = 80.0\ncurvature_radius_mm = 100.0\nyoungs_modulus_mpa = 58000.0\n\
             poisson_ratio = 0.33\n",
            "one.toml",
        )
        .unwrap();
        ModelSpec::from_spec(&spec)
    }

    fn with_latency(tau_s: f64) -> ModelSpec {
        let mut m = user();
        m.effects.latency = Some(Latency { tau_s });
        m
    }

    /// A one-tube recording of `world`: turned and fed back and forth, 2 samples a second.
    fn recording(world: &ModelSpec) -> Recording {
        let turn: Vec<Vec<f64>> = (0..120)
            .map(|i| vec![120.0, 12.0 * f64::from(i % 60) - 30.0 * f64::from(i / 60)])
            .collect();
        let feed: Vec<Vec<f64>> = (0..80)
            .map(|i| vec![100.0 + 1.5 * f64::from(i % 40), 45.0])
            .collect();
        let runs = [
            CommandedRun {
                label: "turn".into(),
                joints: turn,
            },
            CommandedRun {
                label: "feed".into(),
                joints: feed,
            },
        ];
        let spec = SynthSpec {
            noise_sigma_mm: SIGMA_MM,
            seed: 11,
            ..SynthSpec::default()
        };
        record(world, &runs, &spec).unwrap().recording
    }

    fn identified(world: &ModelSpec, fitted: &ModelSpec) -> Vec<(EffectId, Failure)> {
        let rec = recording(world);
        let held: Vec<bool> = (0..rec.rows.len()).map(|r| r % 4 == 3).collect();
        let fit_rows: Vec<usize> = (0..rec.rows.len()).filter(|&r| !held[r]).collect();
        let noise_rms_mm = 3f64.sqrt() * SIGMA_MM;
        let ctx = Context::new(
            &rec,
            &held,
            3.0 * SIGMA_MM,
            1,
            noise_rms_mm,
            Checks::default(),
        );
        ctx.identified(fitted, &user(), &[EffectId::Latency], &fit_rows)
            .0
    }

    #[test]
    fn a_finding_the_data_cannot_tell_from_the_nominal_fails_the_identification_check() {
        // no latency in the world; a finding of 10 ms (what noise might leave a search
        // with) is inside its own 95 % region around zero
        let failures = identified(&user(), &with_latency(0.01));
        assert!(
            matches!(
                failures.as_slice(),
                [(EffectId::Latency, Failure::NotIdentified { statistic, threshold })]
                    if statistic < threshold
            ),
            "{failures:?}"
        );
        // the same check off: nothing
        let rec = recording(&user());
        let held = vec![false; rec.rows.len()];
        let off = Checks {
            identified: false,
            ..Checks::default()
        };
        let ctx = Context::new(&rec, &held, 0.6, 1, 0.35, off);
        let rows: Vec<usize> = (0..rec.rows.len()).collect();
        assert!(ctx
            .identified(&with_latency(0.01), &user(), &[EffectId::Latency], &rows)
            .0
            .is_empty());
    }

    /// Tips spread over a box, as a workspace's.
    fn box_tips() -> Vec<[f64; 3]> {
        (0..200)
            .map(|i| {
                let f = f64::from(i);
                [
                    20.0 * (0.37 * f).sin(),
                    15.0 * (0.23 * f).cos(),
                    100.0 + 30.0 * (0.11 * f).sin(),
                ]
            })
            .collect()
    }

    /// Squared error left by the best `k` of `fields` fitted to `e`, as a share.
    fn left_share(fields: &[Field], e: &[[f64; 3]], k: usize) -> f64 {
        let w = vec![1.0; e.len()];
        let terms = empirical::pursue(fields, e, &w, k);
        let left = empirical::subtract(fields, &terms, e);
        let sq = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x * x).sum::<f64>();
        sq(&left) / sq(e)
    }

    #[test]
    fn the_non_rigid_maps_take_a_scale_error_not_a_rotation() {
        let p = box_tips();
        let fit = vec![true; p.len()];
        let fields = non_rigid(&p, &fit);
        let mean: Vec<f64> = (0..3)
            .map(|a| p.iter().map(|v| v[a]).sum::<f64>() / p.len() as f64)
            .collect();
        // a tracker's scale error about the workspace's centre: all of it
        let scale: Vec<[f64; 3]> = p
            .iter()
            .map(|v| {
                [
                    0.01 * (v[0] - mean[0]),
                    -0.008 * (v[1] - mean[1]),
                    0.006 * (v[2] - mean[2]),
                ]
            })
            .collect();
        assert!(left_share(&fields, &scale, 3) < 1e-20);
        // a rotation of 2 deg about z (a registration's): half of it stays, whatever
        // the terms
        let w = 2f64.to_radians();
        let rotation: Vec<[f64; 3]> = p
            .iter()
            .map(|v| [-w * (v[1] - mean[1]), w * (v[0] - mean[0]), 0.0])
            .collect();
        assert!(left_share(&fields, &rotation, 6) > 0.3);
        // a registration's directions are affine in the tip; a direction that turns with
        // a joint is not
        let translation: Vec<[f64; 3]> = p.iter().map(|_| [1.0, 0.0, 0.0]).collect();
        assert!(affine_in_tip(&[rotation.clone(), translation], &p));
        let turning: Vec<[f64; 3]> = (0..p.len())
            .map(|i| [(0.5 * i as f64).cos(), (0.5 * i as f64).sin(), 0.0])
            .collect();
        assert!(!affine_in_tip(&[rotation, turning], &p));
    }

    #[test]
    fn clearly_lower_needs_more_than_chance() {
        let mut rng = ctr_analysis::rng::Rng::new(3);
        let noise: Vec<RowError> = (0..400)
            .map(|_| [0, 1, 2, 3, 4, 5].map(|a| if a < 3 { 0.2 * rng.normal() } else { 0.0 }))
            .collect();
        let held: Vec<bool> = (0..400).map(|r| (r / 20) % 4 == 3).collect();
        let shifted = |d: f64| -> Vec<RowError> {
            noise
                .iter()
                .map(|v| [v[0] + d, v[1], v[2], 0.0, 0.0, 0.0])
                .collect()
        };
        // the same errors: not lower; a clear shift on top: lower
        assert!(!clearly_lower(&noise, &noise, &held));
        assert!(clearly_lower(&noise, &shifted(0.3), &held));
        assert!(!clearly_lower(&shifted(0.3), &noise, &held));
    }

    #[test]
    fn a_real_latency_passes_the_identification_check() {
        let world = with_latency(0.4);
        assert_eq!(identified(&world, &world), Vec::new());
    }
}

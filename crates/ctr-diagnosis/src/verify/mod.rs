//! The checks every finding of the search must pass, with all the other findings in
//! place, before the report calls it physics. A wrong confident finding is the worst
//! output of a diagnosis; these checks trade a little sensitivity for that.
//!
//! Let `M` be the fitted model with its findings, `e` its error on every row and `h`
//! its held-out RMS; `sigma_n` the noise estimate's RMS. For a finding `c` with `k`
//! parameters:
//!
//! 1. **It beats a generic correction of its size** ([`empirical`](crate::empirical): in the joints and
//!    time, so that the registration, itself a map of the tip position, is not measured
//!    against its own form), within the hybrid model. Let `K` be the size of generic
//!    correction that cross-validation on the fit rows gives what `M` leaves. Take `c`
//!    out of `M` (the others stay as fitted) and give that model `K + k` generic terms;
//!    `M` with `K` terms must do clearly better on the held-out rows:
//!    `h_K < (1 - MIN_GAIN_OVER_EMPIRICAL) h_emp`. So `c` must explain something a
//!    generic term cannot, and something else that is left (a drift) neither saves a
//!    proxy nor sinks a true effect (where `M` leaves nothing but noise on the held-out
//!    rows, `h <= NOISE_TOLERANCE sigma_n`, `K = 0`). The generic terms, on both sides,
//!    also hold the linear maps of the modelled tip position that no rigid motion
//!    makes (`generic::non_rigid`: stretches, the same stretch on every axis, and
//!    symmetric shears; rotations and translations are the registration's, in the
//!    vocabulary), whether or not `M` leaves only noise: what a tracker's scale or
//!    calibration error makes, and what an effect that reaches through the tip's pose
//!    (a sensor offset along the tip, a precurvature, a clearance) can mimic. Where
//!    that correction too leaves only noise, `c` must also beat it beyond chance ([`clearly_lower`](crate::paired::clearly_lower): a
//!    paired test of the held-out squared errors over blocks of consecutive rows).
//!    An effect whose own form is a map of the tip position (`generic::affine_in_tip`: every
//!    parameter direction affine in the tip position, as a registration's) is not
//!    measured against itself: it passes at the noise, the physics the hypothesis.
//! 2. **Its parameters are constant, not proportional to something.** An effect
//!    claims a fixed set of parameters: its error is `J_c(q) dx` with `J_c` the
//!    derivative of the tip with respect to its parameters and `dx` constant over the
//!    rows. With `c` taken out of `M` to first order (`e - J_c x`, `x` its parameters:
//!    both fits stand on one linearisation, so that a large effect, a frame turned by
//!    degrees, is not judged on the curvature of its rotation), compare two linear fits
//!    of that error on the fit rows with `M`'s robust weights, each with `k` terms: the
//!    constant `J_c,j(q)` columns, which give `M`'s own error back, and the best `k`
//!    of the fields `J_c,j(q) f(q)` with `f` a feature of the rows in its own units
//!    (a feed, a rotation's cosine, the time, the tip position: [`Basis::raw`]), which
//!    vanish where the feature does, as a gain's error does. If the proportional
//!    fields do clearly better on the held-out rows, the effect is the shadow of a gain
//!    or a drift on its own directions (a feed *offset* where the feed *gain* is
//!    wrong, a registration where the tracker's scale is): outside the vocabulary.
//!
//!    Checks 1 and 2 run in the model's own frame (`ModelFrame`: the errors, the tip
//!    directions and the tip coordinates turned back by `M`'s registration), so that a
//!    generic term on an axis of the tip, or in a coordinate of it, does not depend on
//!    how the tracker was registered.
//!
//! 3. **Its parameters are identified.** With every finding fitted together, the
//!    covariance of [`uncertainty`](crate::uncertainty) (the larger of the classical and the
//!    cluster-robust variances, so a structured residual widens it) must put the
//!    user's nominal values outside the finding's joint 95 % region: the Wald
//!    statistic `d^T Sigma^+ d` of its parameters' distance `d` from the nominal
//!    exceeds the chi-square quantile of their rank (`identified::wald`). Where a
//!    parameter's nominal sits on a bound of the fit (a play, a deflection: at least
//!    0) and it is fitted there, it is not counted: the test is conditional on where
//!    such parameters are, so a bound cannot dilute what the data do move (the report
//!    says so). A finding
//!    whose values the data cannot tell from the nominal is no finding, however much
//!    it lowered the cost on the way.
//!
//! A finding without which the model cannot be simulated (another finding's values
//! put a row out of reach) cannot be checked, and so is not established.
//!
//! Checks 1 and 2 run first on every finding; check 3 once they all pass (it needs the
//! joint fit's covariance, which a finding taken out changes). The findings that fail
//! are taken out, the others are refitted together, and the checks run again until
//! every finding passes. The tracker's frame, in the model from the start
//! (`crate::search::frame`), is graded by them but never taken out: the others are
//! checked with it in place. The held-out figures they compare count the rows of
//! `crate::scored` (a glitch of the searched model set aside). [`Checks`] turns one
//! off, to show what it is for.

mod form;
mod generic;
mod identified;

use crate::candidates::EffectId;
use crate::empirical::{Basis, Field};
use crate::found::Found;
use crate::options::Checks;
use crate::report::Grade;
use crate::report::{held_words, Figures, Trial, REMOVED};
use crate::residual::{errors, figures, RowError};
use crate::scored::Scored;
use crate::start::noise::NOISE_TOLERANCE;
use crate::start::Start;
use crate::uncertainty::Assessment;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_formats::Recording;

/// Smallest relative margin by which the model's held-out RMS must undercut that of
/// the generic empirical correction with as many free parameters, with the finding
/// taken out, for the finding to count as physics.
pub const MIN_GAIN_OVER_EMPIRICAL: f64 = 0.02;

/// What the checks run on.
pub(crate) struct Context<'a> {
    rec: &'a Recording,
    /// Whether each row is held out and counted by the checks' held-out figures (a
    /// glitch set aside, [`crate::scored`]).
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
    /// The noise estimate's RMS on the checks' basis
    /// ([`Noise::weighted_rms`](crate::report::Noise)), mm(-equivalent).
    noise_rms: f64,
    /// Which checks run.
    checks: Checks,
}

/// A check a finding failed.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Failure {
    /// A generic correction of as many parameters does as well.
    Empirical {
        /// Its figures.
        fig: Figures,
        /// Whether the correction was also linear in the tip position (always, unless
        /// the effect is itself such a map).
        tip: bool,
    },
    /// The effect's parameters are better proportional to a feature of the rows.
    Varying {
        /// The feature they are proportional to (the first chosen).
        feature: String,
        /// Figures of the constant parameters (linearised).
        constant: Figures,
        /// Figures of the proportional ones.
        proportional: Figures,
    },
    /// Its parameters are told from the nominal together, but each one's 95 % interval
    /// holds the value that means the effect is not there.
    MaybeAbsent,
    /// The model without it cannot be simulated, so checks 1 and 2 cannot weigh it.
    Untestable {
        /// Why the model without it cannot be simulated.
        why: String,
    },
    /// The data cannot tell its parameters from the nominal.
    NotIdentified(identified::Wald),
}

/// A finding's checks.
#[derive(Clone, Debug)]
pub(crate) struct Checked {
    pub(crate) effect: EffectId,
    /// Figures of the generic correction of the finding's size in its place (none for
    /// torsion, which has no parameter).
    pub(crate) generic: Option<Figures>,
    /// The first check it fails.
    pub(crate) failure: Option<Failure>,
}

/// Why an established finding is: the words of its grade.
pub(crate) const PASSES_EVERY_CHECK: &str = "it passes every check: it beats a generic \
    correction of its size, its parameters are constant rather than proportional to a \
    feature of the rows, they are told from the nominal together, and at least one of \
    their 95 % intervals excludes the value that means it is not there";

impl<'a> Context<'a> {
    /// The checks of a diagnosis of `rec` whose fit rows are `fit`, judged on the
    /// held-out rows `held` (of those not fitted, the ones counted), with the fits'
    /// Huber threshold, threads and the noise estimate's RMS on the checks' basis.
    pub(crate) fn new(
        rec: &'a Recording,
        fit: Vec<bool>,
        held: &'a [bool],
        huber_mm: f64,
        threads: usize,
        noise_rms: f64,
        checks: Checks,
    ) -> Self {
        let yardstick = Basis::joints_and_time(rec, &fit).fields();
        Context {
            rec,
            held,
            fit,
            yardstick,
            huber_mm,
            threads,
            noise_rms,
            checks,
        }
    }

    /// `m`'s errors on every row, or why it cannot be simulated.
    fn errors_of(&self, m: &ModelSpec) -> Result<Vec<RowError>, String> {
        let all: Vec<usize> = (0..self.rec.runs.len()).collect();
        predict(m, self.rec, &all)
            .map(|p| errors(self.rec, &p))
            .map_err(|e| e.to_string())
    }

    fn figures(&self, e: &[RowError]) -> Figures {
        figures(self.rec, e, self.held)
    }

    /// Checks 1 and 2 of finding `c` of `m`, whose error vectors are `e` (check 3 is
    /// [`Context::identified`], on every finding together).
    pub(crate) fn check(&self, m: &ModelSpec, e: &[RowError], c: EffectId) -> Checked {
        let mut out = Checked {
            effect: c,
            generic: None,
            failure: None,
        };
        if c.n_params(m.robot.n_tubes()) == 0 {
            return out;
        }
        let mut without = m.clone();
        c.remove(&mut without);
        // a check that cannot run does not pass: without `c` the other findings'
        // values may leave the model unable to simulate a row (joint offsets fitted
        // beside a feed play can put an inner tube behind an outer one)
        let e_without = match self.errors_of(&without) {
            Ok(e) => e,
            Err(why) => {
                if self.checks.beats_generic || self.checks.constant {
                    out.failure = Some(Failure::Untestable { why });
                }
                return out;
            }
        };
        let at_noise = self.figures(e).heldout_score() <= NOISE_TOLERANCE * self.noise_rms;
        // in the model's frame: the checks' generic terms (on an axis of the tip, in a
        // coordinate of the tip) then do not depend on how the tracker was registered
        let frame = ModelFrame::of(m);
        let (e, e_without) = (frame.errors(e), frame.errors(&e_without));
        // the tip directions of `c`'s parameters, which both checks read: one Jacobian
        let directions = self.directions(m, &frame, c);
        let (generic, failure) = self.against_generic(
            m,
            &frame,
            directions.as_deref(),
            &e,
            &e_without,
            c,
            at_noise,
        );
        out.generic = Some(generic);
        out.failure = failure;
        // 2. where the model leaves more than noise: constant parameters against
        // parameters proportional to a feature
        if out.failure.is_none() && !at_noise && self.checks.constant {
            out.failure = directions
                .as_deref()
                .and_then(|d| self.against_proportional(m, &frame, d, &e, c));
        }
        out
    }
}

/// The frame of a model's W in the tracker's (its registration, `p -> R p + t`): what
/// the checks turn the errors and tips back by.
pub(crate) struct ModelFrame {
    r: nalgebra::Rotation3<f64>,
    t: nalgebra::Vector3<f64>,
}

impl ModelFrame {
    /// `m`'s frame (the identity without a registration).
    pub(crate) fn of(m: &ModelSpec) -> Self {
        let reg = m.effects.registration;
        ModelFrame {
            r: reg.map_or(nalgebra::Rotation3::identity(), |r| {
                nalgebra::Rotation3::new(
                    nalgebra::Vector3::from(r.rotation_vector_deg()).map(f64::to_radians),
                )
            }),
            t: nalgebra::Vector3::from(reg.map_or([0.0; 3], |r| r.translation_mm)),
        }
    }

    /// A vector of the tracker's frame in W.
    fn back(&self, v: [f64; 3]) -> [f64; 3] {
        (self.r.inverse() * nalgebra::Vector3::from(v)).into()
    }

    /// Error vectors (positions and angles) turned into W.
    pub(crate) fn errors(&self, e: &[RowError]) -> Vec<RowError> {
        e.iter()
            .map(|v| {
                let p = self.back([v[0], v[1], v[2]]);
                let a = self.back([v[3], v[4], v[5]]);
                [p[0], p[1], p[2], a[0], a[1], a[2]]
            })
            .collect()
    }

    /// A field of tip directions turned into W.
    pub(crate) fn field(&self, f: Field) -> Field {
        f.into_iter().map(|v| self.back(v)).collect()
    }

    /// The modelled tips in W of `rec`'s rows whose errors in W are `e`.
    pub(crate) fn tips(&self, rec: &Recording, e: &[RowError]) -> Vec<[f64; 3]> {
        rec.rows
            .iter()
            .zip(e)
            .map(|(row, v)| {
                let m = self.r.inverse() * (nalgebra::Vector3::from(row.p) - self.t);
                [m.x + v[0], m.y + v[1], m.z + v[2]]
            })
            .collect()
    }
}

/// Every finding of `found` checked with the others in place: those that fail are taken
/// out (their trials say why, and [`Removed`] keeps them for `crate::predictive`) and
/// the rest refitted together, until all pass: the established findings. Also the
/// assessment check 3 judged them on, when the loop ends on it (the report's
/// intervals).
pub(crate) fn settle(
    start: &Start,
    mut found: Found,
    checks: Checks,
) -> (Found, Vec<Removed>, Option<Assessment>) {
    // a glitch of the searched model set aside from the checks' held-out figures
    let scored = Scored::from(&found.e, &start.held);
    let ctx = Context::new(
        start.rec,
        start.fit_mask(),
        scored.mask(),
        start.huber_mm(),
        start.threads,
        start.noise.weighted_rms(),
        checks,
    );
    let last_round = found.tried.iter().map(|t| t.round).max().unwrap_or(0) + 1;
    let mut removed = Vec::new();
    // the tracker's frame, a nuisance in the model from the start: graded, never taken
    // out (the others are checked with it in place, whatever it is graded)
    let kept = found.frame_profiled.then_some(EffectId::Registration);
    loop {
        let (checked, assessment) = ctx.check_all(start, &found, kept);
        for ch in &checked {
            if let Some(f) = found.findings.iter_mut().find(|f| f.effect == ch.effect) {
                f.empirical_heldout_rms_mm = ch.generic.map_or(f64::NAN, |g| g.heldout_rms_mm);
                f.grade = Grade::Established;
                f.grade_reason = PASSES_EVERY_CHECK.into();
            }
        }
        let mut failed: Vec<(EffectId, String)> = checked
            .iter()
            .filter_map(|c| Some((c.effect, failure_words(c.failure.as_ref()?))))
            .collect();
        if let Some(i) = failed.iter().position(|(c, _)| Some(*c) == kept) {
            let (c, why) = failed.remove(i);
            if let Some(f) = found.findings.iter_mut().find(|f| f.effect == c) {
                f.grade = Grade::Predictive;
                f.grade_reason = format!(
                    "the tracker's frame, kept in the model (solved in every fit, a nuisance), \
                     but not established: {why}"
                );
            }
        }
        if failed.is_empty() {
            return (found, removed, assessment);
        }
        for (c, why) in failed {
            found.tried.push(Trial {
                round: last_round,
                effect: c,
                rms_mm: found.fig.rms_mm,
                heldout_rms_mm: found.fig.heldout_rms_mm,
                bic_change: f64::NAN,
                added: false,
                note: format!("{REMOVED}{why}"),
            });
            if let Some(i) = found.findings.iter().position(|f| f.effect == c) {
                let finding = found.findings.remove(i);
                removed.push(Removed { finding, why });
            }
        }
        if !found.refit(start) {
            return (found, removed, None);
        }
    }
}

/// A finding the checks took out: as it was when taken out, and why.
#[derive(Clone, Debug)]
pub(crate) struct Removed {
    pub finding: crate::report::Finding,
    /// The check it failed, in words.
    pub why: String,
}

impl Context<'_> {
    /// Checks 1 and 2 of every finding of `found`, then, once they all pass, check 3 on
    /// them together (it needs the joint fit's covariance, and a finding taken out
    /// changes everyone's), with the assessment it judged them on.
    /// A failure of `kept` (a finding graded but never taken out) does not hold check
    /// 3 back.
    fn check_all(
        &self,
        start: &Start,
        found: &Found,
        kept: Option<EffectId>,
    ) -> (Vec<Checked>, Option<Assessment>) {
        // the findings checked; the tracker's frame, in the model without being one,
        // counted in the joint fit's covariance of check 3
        let effects = found.effects();
        let findings: Vec<EffectId> = found.findings.iter().map(|f| f.effect).collect();
        // each finding's checks are independent of the others': side by side
        let mut checked: Vec<Checked> = ctr_formats::parallel::map(&findings, self.threads, |&c| {
            self.check(&found.model, &found.e, c)
        });
        let held_back = checked
            .iter()
            .any(|c| c.failure.is_some() && Some(c.effect) != kept);
        if effects.is_empty() || held_back {
            return (checked, None);
        }
        let (failures, assessment) =
            self.identified(&found.model, &start.user, &effects, &start.fit_rows);
        for (c, failure) in failures {
            if let Some(ch) = checked.iter_mut().find(|ch| ch.effect == c) {
                ch.failure.get_or_insert(failure);
            }
        }
        (checked, assessment)
    }
}

/// A failed check, in words.
fn failure_words(failure: &Failure) -> String {
    match failure {
        Failure::Empirical { fig, tip: false } => format!(
            "a generic empirical correction of as many parameters, in its place, does as \
             well on held-out rows ({})",
            held_words(fig)
        ),
        Failure::Empirical { fig, tip: true } => format!(
            "a generic empirical correction of as many parameters, in the joints, time and \
             the stretches and shears of the tip position, in its place, explains the data \
             as well ({} held out): the data cannot tell it from an error outside the \
             vocabulary such as a tracker's scale error",
            held_words(fig)
        ),
        Failure::Varying {
            feature,
            constant,
            proportional,
        } => format!(
            "its parameters fit the data better proportional to {feature} than constant \
             ({} against {} held out, linearised): it may stand in for a gain or drift \
             outside the vocabulary",
            held_words(proportional),
            held_words(constant)
        ),
        Failure::Untestable { why } => format!(
            "the checks cannot weigh it: with it taken out (the other findings as fitted) \
             the model cannot be simulated ({why})"
        ),
        Failure::MaybeAbsent => "with every finding fitted together, each of its \
                                 parameters' 95 % intervals holds the value that means it is \
                                 not there: the data do not rule its absence out"
            .into(),
        Failure::NotIdentified(w) => {
            let edge = if w.at_edge == 0 {
                String::new()
            } else {
                format!(
                    "; {} of its parameters fitted on the bound where the nominal sits (a \
                     play or a deflection of 0) not counted, the test conditional on them",
                    w.at_edge
                )
            };
            format!(
                "with every finding fitted together, its parameters are not told from the \
                 nominal (Wald statistic {:.2} against the 95 % threshold {:.2}{edge}: \
                 the nominal lies inside their 95 % region)",
                w.statistic, w.threshold
            )
        }
    }
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
        let fit: Vec<bool> = held.iter().map(|h| !h).collect();
        let ctx = Context::new(
            &rec,
            fit,
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
                [(EffectId::Latency, Failure::NotIdentified(w))]
                    if w.statistic < w.threshold
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
        let ctx = Context::new(&rec, vec![true; held.len()], &held, 0.6, 1, 0.35, off);
        let rows: Vec<usize> = (0..rec.rows.len()).collect();
        assert!(ctx
            .identified(&with_latency(0.01), &user(), &[EffectId::Latency], &rows)
            .0
            .is_empty());
    }

    #[test]
    fn a_real_latency_passes_the_identification_check() {
        let world = with_latency(0.4);
        assert_eq!(identified(&world, &world), Vec::new());
    }
}

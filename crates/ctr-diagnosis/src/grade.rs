//! How sure the report is of each finding: its grade.
//!
//! A diagnosis gives two answers from one search: the best predictive model (every
//! finding, whatever its grade, is in the fitted robot) and an account that grades each
//! effect by the evidence on the held-out rows:
//!
//! - **established**: it passes every check of [`crate::verify`] (it beats a generic
//!   correction of its size, its parameters are constant rather than proportional to a
//!   feature of the rows, and their joint 95 % region excludes the nominal), and at least
//!   one of its parameters' 95 % intervals (`ci95`, as the report prints them) excludes
//!   the value that means "not there" ([`absent_value`]: a play, a deflection, a lag, an
//!   offset of 0; a factor of 1), and none sits on a bound of its fit ([`on_bounds`]:
//!   pushed as far as the fit allows, its interval cut by the bound). This is physics
//!   the data show;
//! - **predictive**: it fails a check (or no interval excludes "not there"), but the
//!   fitted model without it does worse on the held-out rows by at least
//!   [`crate::MIN_HELDOUT_GAIN`], the gain the search asks of every effect
//!   ([`crate::predictive`]): it helps prediction, its form is not
//!   established, and it may stand in for something outside the vocabulary.
//!
//! A finding that fails a check and does not help prediction is taken out (a trial
//! says why). On a real robot almost every constant parameter fits a little better when
//! it may vary with something, so a failed form check alone no longer throws physics
//! away: it lowers the grade.

use crate::candidates::EffectId;
use crate::fit::Problem;
use crate::report::numbers::intervals;
use crate::report::{Finding, Grade};
use crate::uncertainty::{Assessment, ON_BOUND_STEPS};
use ctr_analysis::model::ModelSpec;

/// The value of a parameter of an effect's table in the robot file (its key) that means
/// the effect is not there; `None` for a parameter without one (a clearance's peak
/// angle, a registration's axis, a gravity's direction).
///
/// ```
/// use ctr_diagnosis::absent_value;
/// assert_eq!(absent_value("radius_factor"), Some(1.0));
/// assert_eq!(absent_value("tau_s"), Some(0.0));
/// assert_eq!(absent_value("peak_deg"), None);
/// ```
pub fn absent_value(key: &str) -> Option<f64> {
    match key {
        "factor" | "radius_factor" => Some(1.0),
        "rotation_play_deg"
        | "feed_play_mm"
        | "rotation_friction_coefficient"
        | "max_deflection_deg"
        | "tau_s"
        | "translation_mm"
        | "rotation_deg"
        | "feed_mm"
        | "offset_mm"
        | "g_m_s2"
        | "rotation_vector_deg" => Some(0.0),
        _ => None,
    }
}

/// How near its "not there" value an interval's end counts as on it, relative to the
/// interval's width: rounding in an end cut at the bound where the absence sits.
const END_AT_ABSENCE: f64 = 1e-9;

/// Whether at least one of `finding`'s parameters has a 95 % interval that excludes its
/// "not there" value, or one of the combinations of its own parameters the data
/// identify (`ci95.identified`, with its `not_there` value: a ratio of stiffness
/// factors against 1) excludes it (a finding without parameters, torsion, has nothing
/// to exclude and counts as excluding). A combination across effects counts for
/// neither: it cannot say which of the two is there.
pub(crate) fn present_beyond_doubt(finding: &Finding) -> bool {
    let (parameters, _) = intervals(&finding.parameters, &finding.ci95);
    if parameters.is_empty() {
        return true;
    }
    // an end within rounding of "not there" is that value: the interval cut at the
    // bound where the absence sits (a deflection's interval ending at 4.7e-15 deg,
    // printed as 0) holds it
    let excludes = |lo: Option<f64>, hi: Option<f64>, absent: f64| {
        let at = |end: f64| {
            let width = match (lo, hi) {
                (Some(lo), Some(hi)) => hi - lo,
                _ => end.abs(),
            };
            (end - absent).abs() <= END_AT_ABSENCE * width.abs().max(absent.abs())
        };
        lo.is_some_and(|lo| lo > absent && !at(lo)) || hi.is_some_and(|hi| hi < absent && !at(hi))
    };
    let own = parameters.iter().any(|p| {
        let key = p.name.split('[').next().unwrap_or("");
        absent_value(key).is_some_and(|absent| excludes(p.lo, p.hi, absent))
    });
    let combined = finding
        .ci95
        .get("identified")
        .and_then(serde_json::Value::as_array)
        .into_iter()
        .flatten()
        .any(|c| {
            c["not_there"]
                .as_f64()
                .is_some_and(|n| excludes(c["ci95"][0].as_f64(), c["ci95"][1].as_f64(), n))
        });
    own || combined
}

/// Lowers to predictive every established finding none of whose 95 % intervals
/// excludes its "not there" value (its checks passed, but the data leave it possibly
/// absent).
pub(crate) fn by_intervals(findings: &mut [Finding]) {
    for f in findings
        .iter_mut()
        .filter(|f| f.grade == Grade::Established && !present_beyond_doubt(f))
    {
        f.grade = Grade::Predictive;
        f.grade_reason = "each of its parameters' 95 % intervals holds the value that means \
                          it is not there: the data do not rule its absence out"
            .into();
    }
}

/// The effects of `problem` with a parameter at `x` on a bound of its fit other than
/// the value that means "not there" (0 in every fitted parameter: an offset, a play, a
/// lag, the log of a factor): the data pushed it as far as the fit lets it go (a
/// stiffness a seventh of the catalogue's, gravity at five times the earth's). Not
/// counted: an angle whose bounds are where it wraps (a rotation offset at +/-180 deg
/// is a place on the circle, not a limit), and a parameter that directions the data do
/// not see can move off the bound within the fit's bounds (`free(j, bound, within)`:
/// its place there is the fit's arbitrary choice, not the data's push).
/// A parameter not identified alone still counts where no such move frees it: every
/// stiffness factor may scale together, but with tube 1's at its upper bound and tube
/// 3's at its lower one their ratio is as far as the bounds let it go.
fn on_bounds(
    problem: &Problem,
    x: &[f64],
    free: impl Fn(usize, f64, f64) -> bool,
) -> Vec<EffectId> {
    let n = problem.n_tubes();
    let mut out = Vec::new();
    let mut at = 0;
    for &b in &problem.blocks {
        let len = problem.block_len(b);
        let on_bound = (at..at + len).any(|j| {
            let (step, (lo, hi)) = problem.scale(j);
            let within = ON_BOUND_STEPS * step;
            let on = |bound: f64| {
                bound != 0.0
                    && bound.is_finite()
                    && (x[j] - bound).abs() <= within
                    && !free(j, bound, within)
            };
            !b.wraps(n, j - at) && (on(lo) || on(hi))
        });
        if on_bound {
            out.push(b);
        }
        at += len;
    }
    out
}

/// Grades the established `findings` by their intervals ([`by_intervals`]), then lowers
/// to predictive every one whose effect has a parameter on a bound of its fit at
/// `fitted`, `problem`'s model ([`on_bounds`]; left out, when `assessment` was
/// computed, the parameters its directions not seen move off their bound): the fit's
/// value is not a minimum the data place inside the plausible range, its interval is
/// cut by the bound, and an effect pushed that far most likely stands in for something
/// else.
pub(crate) fn by_evidence(
    findings: &mut [Finding],
    problem: &Problem,
    fitted: &ModelSpec,
    assessment: Option<&Assessment>,
) {
    by_intervals(findings);
    let x = problem.read(fitted);
    let on_bound = on_bounds(problem, &x, |j, bound, within| {
        assessment.is_some_and(|a| a.free_to_leave(j, &x, bound, within))
    });
    lower_on_bound(findings, &on_bound);
}

/// Lowers to predictive the established findings of the effects `on_bound` (see
/// [`by_evidence`]).
fn lower_on_bound(findings: &mut [Finding], on_bound: &[EffectId]) {
    for f in findings
        .iter_mut()
        .filter(|f| f.grade == Grade::Established && on_bound.contains(&f.effect))
    {
        f.grade = Grade::Predictive;
        f.grade_reason = "a parameter sits on the bound of its fit: the data push it beyond \
                          any plausible value, so it may stand in for something outside the \
                          vocabulary"
            .into();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::candidates::EffectId;
    use serde_json::json;

    fn finding(parameters: serde_json::Value, ci95: serde_json::Value) -> Finding {
        Finding {
            effect: EffectId::Precurvature,
            grade: Grade::Established,
            grade_reason: String::new(),
            explanation: String::new(),
            where_: String::new(),
            parameters,
            rms_mm_before: 0.0,
            rms_mm_after: 0.0,
            heldout_rms_mm_before: 0.0,
            heldout_rms_mm_after: 0.0,
            heldout_rms_deg: None,
            empirical_heldout_rms_mm: f64::NAN,
            ci95,
            equally_explained_by: Vec::new(),
        }
    }

    #[test]
    fn an_end_cut_at_the_absence_by_rounding_holds_it() {
        // a clearance whose deflection interval ends at 4.7e-15 deg (cut at its bound
        // 0, printed as 0) does not exclude "not there"; one ending at 0.05 deg does
        let clearance = |lo: f64| Finding {
            effect: EffectId::Clearance,
            ..finding(
                json!({"max_deflection_deg": [0.71], "peak_deg": [348.0]}),
                json!({"max_deflection_deg": [[lo, 0.959]], "peak_deg": [[317.4, 358.8]]}),
            )
        };
        assert!(!present_beyond_doubt(&clearance(4.66e-15)));
        assert!(present_beyond_doubt(&clearance(0.05)));
    }

    #[test]
    fn a_finding_whose_intervals_all_hold_not_there_is_only_predictive() {
        // the issue's tracker-scale example: factors 0.98 and 1.06, both intervals
        // holding 1
        let mut f = vec![finding(
            json!({"radius_factor": [0.98, 1.06]}),
            json!({"radius_factor": [[0.95, 1.01], [0.99, 1.12]]}),
        )];
        by_intervals(&mut f);
        assert_eq!(f[0].grade, Grade::Predictive);
        // one interval excluding 1 keeps it established; a peak angle, which has no
        // "not there", counts for nothing
        let mut f = vec![finding(
            json!({"radius_factor": [0.98, 1.06]}),
            json!({"radius_factor": [[0.95, 1.01], [1.02, 1.12]]}),
        )];
        by_intervals(&mut f);
        assert_eq!(f[0].grade, Grade::Established);
        let mut f = vec![finding(
            json!({"max_deflection_deg": [2.1], "peak_deg": [200.0]}),
            json!({"max_deflection_deg": [[-0.17, 3.04]], "peak_deg": [[150.0, 250.0]]}),
        )];
        by_intervals(&mut f);
        assert_eq!(f[0].grade, Grade::Predictive);
        // parameters identified only in a combination of its own: that combination's
        // interval against its value where the effect is not there (a ratio of 1)
        let ratio = |ci95: [f64; 2], not_there: Option<f64>| {
            let mut c = json!({"combination": "stiffness factor of tube 2 / stiffness factor of tube 1",
                 "value": 1.3, "ci95": ci95});
            if let Some(n) = not_there {
                c["not_there"] = json!(n);
            }
            let mut f = vec![finding(
                json!({"factor": [1.0, 1.3]}),
                json!({"factor": [[0.135, 7.389], [0.135, 7.389]], "identified": [c]}),
            )];
            by_intervals(&mut f);
            f[0].grade
        };
        assert_eq!(ratio([1.29, 1.31], Some(1.0)), Grade::Established);
        assert_eq!(ratio([0.95, 1.31], Some(1.0)), Grade::Predictive);
        // a combination across effects (no not_there) says nothing of this one
        assert_eq!(ratio([1.29, 1.31], None), Grade::Predictive);
    }

    #[test]
    fn a_finding_on_a_bound_of_its_fit_is_only_predictive() {
        let f = || {
            finding(
                json!({"factor": [0.151, 0.135]}),
                json!({"factor": [[0.139, 0.163], [0.135, 0.146]]}),
            )
        };
        let mut on = vec![f()];
        by_intervals(&mut on);
        assert_eq!(on[0].grade, Grade::Established, "its intervals exclude 1");
        lower_on_bound(&mut on, &[EffectId::Precurvature]);
        assert_eq!(on[0].grade, Grade::Predictive);
        assert!(on[0].grade_reason.contains("bound"));
        let mut off = vec![f()];
        lower_on_bound(&mut off, &[EffectId::Stiffness]);
        assert_eq!(
            off[0].grade,
            Grade::Established,
            "another effect on a bound"
        );
    }

    #[test]
    fn on_a_bound_counts_limits_not_wraps_nor_what_unseen_directions_free() {
        use crate::synth::{record, CommandedRun, SynthSpec};
        let spec = ctr_formats::RobotSpec::from_toml_str(
            "[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\nlength_mm = 200.0\n\
             curved_length_mm = 80.0\ncurvature_radius_mm = 100.0\n\
             youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n",
            "one.toml",
        )
        .unwrap();
        let model = ModelSpec::from_spec(&spec);
        let run = CommandedRun {
            label: "turn".into(),
            joints: vec![vec![100.0, 0.0], vec![100.0, 10.0]],
        };
        let rec = record(&model, &[run], &SynthSpec::default())
            .unwrap()
            .recording;
        let problem = Problem {
            base: model,
            blocks: vec![EffectId::Stiffness, EffectId::JointOffset],
            rec: &rec,
            rows: vec![0, 1],
            huber_mm: 1.0,
            threads: 1,
            clearance_table: None,
        };
        let (_, (ln_lo, _)) = problem.scale(0);
        let (_, (_, feed_hi)) = problem.scale(1);
        // x: ln stiffness factor, feed offset, rotation offset; nothing freed by
        // directions not seen unless said
        let held = |_: usize, _: f64, _: f64| false;
        let on =
            |x: [f64; 3], free: &dyn Fn(usize, f64, f64) -> bool| on_bounds(&problem, &x, free);
        assert_eq!(on([0.1, 0.2, 30.0], &held), vec![]);
        assert_eq!(on([ln_lo, 0.2, 30.0], &held), vec![EffectId::Stiffness]);
        assert_eq!(
            on([ln_lo + 1e-6, 0.2, 30.0], &held),
            vec![EffectId::Stiffness],
            "just inside"
        );
        assert_eq!(on([ln_lo + 0.1, 0.2, 30.0], &held), vec![]);
        assert_eq!(on([0.1, feed_hi, 30.0], &held), vec![EffectId::JointOffset]);
        assert_eq!(
            on([0.1, 0.2, 180.0], &held),
            vec![],
            "a rotation wraps there"
        );
        // the stiffness factor free to leave its bound along a direction not seen
        let free = |j: usize, _: f64, _: f64| j == 0;
        assert_eq!(on([ln_lo, 0.2, 30.0], &free), vec![]);
        // held there: it counts
        assert_eq!(on([ln_lo, 0.2, 30.0], &held), vec![EffectId::Stiffness]);
    }
}

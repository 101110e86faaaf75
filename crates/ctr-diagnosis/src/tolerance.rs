//! What the lab knows of its robot: the tolerances of the physical parameters, and the
//! grade of a finding that leaves them.
//!
//! A lab measures its tubes: curvature radii to about 10 %, Young's modulus from the
//! datasheet to about 15 %, the density (what a gravity finding's size absorbs) to
//! about 10 %. A fit that puts a tube five times softer than its datasheet, or gravity
//! at four times the earth's, has found a stand-in for something the vocabulary does
//! not hold, or a robot file that is wrong; it is not physics on that evidence. So an
//! established finding with a parameter more than [`TOLERANCE_SIGMAS`] tolerances from its
//! nominal is graded predictive, and the report says so.
//!
//! | parameter | nominal | tolerance (1 sigma, relative) |
//! |---|---|---|
//! | `precurvature.radius_factor` | 1 | [`CURVATURE_RADIUS_TOLERANCE`] |
//! | `stiffness.factor` | 1 | [`YOUNGS_MODULUS_TOLERANCE`] |
//! | `gravity.g_m_s2` | [`STANDARD_GRAVITY_M_S2`] | [`DENSITY_TOLERANCE`] |
//!
//! The other effects (a tracker's frame, an encoder's zero, a latency, a play, a
//! clearance, a sensor's place) are what calibration finds: no default tolerance.

use crate::candidates::EffectId;
use crate::report::{Finding, Grade};

/// A parameter further than this many tolerances from its nominal is outside it.
pub const TOLERANCE_SIGMAS: f64 = 3.0;
/// Tolerance of a tube's curvature radius, relative (1 sigma): measured radii.
pub const CURVATURE_RADIUS_TOLERANCE: f64 = 0.10;
/// Tolerance of a tube's Young's modulus, relative (1 sigma): a datasheet's.
pub const YOUNGS_MODULUS_TOLERANCE: f64 = 0.15;
/// Tolerance of a tube's density, relative (1 sigma): what a gravity finding's size
/// stands for.
pub const DENSITY_TOLERANCE: f64 = 0.10;
/// Standard gravity, m/s^2: a gravity finding's nominal size.
pub const STANDARD_GRAVITY_M_S2: f64 = 9.80665;

/// The first parameter of `f` outside its tolerance, in words; `None` where every one
/// is within it (or its effect has no tolerance).
pub(crate) fn outside(f: &Finding) -> Option<String> {
    let p = &f.parameters;
    let check = |name: &str, values: &[f64], nominal: f64, tol: f64, what: &str| {
        values.iter().enumerate().find_map(|(i, &v)| {
            ((v - nominal).abs() > TOLERANCE_SIGMAS * tol * nominal).then(|| {
                let which = if values.len() > 1 {
                    format!(" of tube {}", i + 1)
                } else {
                    String::new()
                };
                format!(
                    "its {name}{which} is {v:.3}, more than {TOLERANCE_SIGMAS} x {:.0} % from {nominal} \
                     ({what})",
                    100.0 * tol
                )
            })
        })
    };
    let numbers = |key: &str| -> Vec<f64> {
        match &p[key] {
            serde_json::Value::Array(a) => a.iter().filter_map(serde_json::Value::as_f64).collect(),
            v => v.as_f64().into_iter().collect(),
        }
    };
    match f.effect {
        EffectId::Precurvature => check(
            "curvature radius factor",
            &numbers("radius_factor"),
            1.0,
            CURVATURE_RADIUS_TOLERANCE,
            "the tolerance of a measured radius",
        ),
        EffectId::Stiffness => check(
            "stiffness factor",
            &numbers("factor"),
            1.0,
            YOUNGS_MODULUS_TOLERANCE,
            "the tolerance of a datasheet's Young's modulus",
        ),
        EffectId::Gravity => check(
            "gravity",
            &numbers("g_m_s2"),
            STANDARD_GRAVITY_M_S2,
            DENSITY_TOLERANCE,
            "standard gravity and the tolerance of a tube's density",
        ),
        _ => None,
    }
}

/// Lowers to predictive every established finding with a parameter outside its
/// tolerance (module doc).
pub(crate) fn by_tolerance(findings: &mut [Finding]) {
    for f in findings
        .iter_mut()
        .filter(|f| f.grade == Grade::Established)
    {
        if let Some(why) = outside(f) {
            f.grade = Grade::Predictive;
            f.grade_reason = format!(
                "outside the stated tolerance: {why}; it may stand in for something outside \
                 the vocabulary, or the robot file is wrong"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn finding(effect: EffectId, parameters: serde_json::Value) -> Finding {
        Finding {
            effect,
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
            ci95: serde_json::Value::Null,
            equally_explained_by: Vec::new(),
        }
    }

    #[test]
    fn a_finding_outside_its_tolerance_is_only_predictive() {
        let mut f = vec![
            // a tube five times softer than its datasheet
            finding(EffectId::Stiffness, json!({"factor": [0.206, 0.181]})),
            // within 3 x 15 %
            finding(EffectId::Stiffness, json!({"factor": [1.35, 0.75]})),
            finding(
                EffectId::Precurvature,
                json!({"radius_factor": [1.12, 0.88]}),
            ),
            finding(
                EffectId::Precurvature,
                json!({"radius_factor": [2.55, 0.52, 1.05]}),
            ),
            finding(
                EffectId::Gravity,
                json!({"direction_W": [0.0, 0.0, -1.0], "g_m_s2": 42.5}),
            ),
            finding(
                EffectId::Gravity,
                json!({"direction_W": [0.0, 0.0, -1.0], "g_m_s2": 9.9}),
            ),
            // no tolerance: an encoder zero is what calibration finds
            finding(
                EffectId::JointOffset,
                json!({"feed_mm": [5.0], "rotation_deg": [40.0]}),
            ),
        ];
        by_tolerance(&mut f);
        let grades: Vec<Grade> = f.iter().map(|f| f.grade).collect();
        use Grade::{Established as E, Predictive as P};
        assert_eq!(grades, [P, E, E, P, P, E, E]);
        assert!(f[0]
            .grade_reason
            .contains("stiffness factor of tube 1 is 0.206"));
        assert!(f[3]
            .grade_reason
            .starts_with("outside the stated tolerance"));
    }
}

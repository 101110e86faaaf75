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
//!   offset of 0; a factor of 1). This is physics the data show;
//! - **predictive**: it fails a check (or no interval excludes "not there"), but the
//!   fitted model without it does worse on the held-out rows beyond chance
//!   ([`crate::paired::clearly_lower`]): it helps prediction, its form is not
//!   established, and it may stand in for something outside the vocabulary.
//!
//! A finding that fails a check and does not help prediction is taken out (a trial
//! says why). On a real robot almost every constant parameter fits a little better when
//! it may vary with something, so a failed form check alone no longer throws physics
//! away: it lowers the grade.

use crate::report::numbers::intervals;
use crate::report::Finding;
use serde::Serialize;

/// How sure the report is of a finding (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Grade {
    /// Physics the data show: every check passed and an interval excludes "not there".
    Established,
    /// Helps prediction on held-out rows; its form is not established.
    Predictive,
}

impl Grade {
    /// The grade's name in the report (`established`, `predictive`).
    ///
    /// ```
    /// assert_eq!(ctr_diagnosis::Grade::Predictive.as_str(), "predictive");
    /// ```
    pub fn as_str(self) -> &'static str {
        match self {
            Grade::Established => "established",
            Grade::Predictive => "predictive",
        }
    }

    /// The grade named `name` (`None` for another word).
    ///
    /// ```
    /// use ctr_diagnosis::Grade;
    /// assert_eq!(Grade::parse("established"), Some(Grade::Established));
    /// assert_eq!(Grade::parse("sure"), None);
    /// ```
    pub fn parse(name: &str) -> Option<Grade> {
        [Grade::Established, Grade::Predictive]
            .into_iter()
            .find(|g| g.as_str() == name)
    }
}

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

/// Whether at least one of `finding`'s parameters has a 95 % interval that excludes its
/// "not there" value (a finding without parameters, torsion, has nothing to exclude and
/// counts as excluding).
pub(crate) fn present_beyond_doubt(finding: &Finding) -> bool {
    let (parameters, _) = intervals(&finding.parameters, &finding.ci95);
    if parameters.is_empty() {
        return true;
    }
    parameters.iter().any(|p| {
        let key = p.name.split('[').next().unwrap_or("");
        let Some(absent) = absent_value(key) else {
            return false;
        };
        p.lo.is_some_and(|lo| lo > absent) || p.hi.is_some_and(|hi| hi < absent)
    })
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
        f.grade_reason = "it passes every check, but each of its parameters' 95 % intervals \
                          holds the value that means it is not there: the data do not rule \
                          its absence out"
            .into();
    }
}

//! A finding's grade, as the report writes it (what it means: `crate::grade`).

use serde::Serialize;

/// How sure the report is of a finding (see `crate::grade`).
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

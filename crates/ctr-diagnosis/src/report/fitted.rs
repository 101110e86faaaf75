//! The fitted robot: the model a diagnosis hands back, as a robot file ([`fitted_file`])
//! and as specs (the fitted model, with its empirical term, with its established
//! findings alone).

use super::{Diagnosis, Grade};
use ctr_formats::RobotSpec;

impl Diagnosis {
    /// The fitted model as a robot file: `spec` (the user's) with the fitted `[model]`.
    pub fn fitted_spec(&self, spec: &RobotSpec) -> RobotSpec {
        RobotSpec {
            model: self.fitted.model,
            effects: self.fitted.effects.clone(),
            empirical: self.fitted.empirical.clone(),
            ..spec.clone()
        }
    }

    /// [`fitted_spec`](Self::fitted_spec) with the established findings alone,
    /// refitted without the predictive ones ([`Diagnosis::established`]). What
    /// `ctr-cli diagnose --established-only` writes.
    pub fn established_spec(&self, spec: &RobotSpec) -> RobotSpec {
        let mut out = self.fitted_spec(spec);
        out.model = self.established.model;
        out.effects = self.established.effects.clone();
        out
    }

    /// The report's findings as [`fitted_file`] lists them: contract id and grade,
    /// only the established ones with `established_only`.
    pub fn graded(&self, established_only: bool) -> Vec<(&'static str, Grade)> {
        self.report
            .findings
            .iter()
            .filter(|f| !established_only || f.grade == Grade::Established)
            .map(|f| (f.effect.as_str(), f.grade))
            .collect()
    }

    /// [`fitted_spec`](Self::fitted_spec) with the empirical term as `[model.empirical]`
    /// (its terms after any the user's file had): what `ctr-cli diagnose
    /// --with-empirical` writes. The same as `fitted_spec` when the recording is
    /// explained.
    pub fn fitted_spec_with_empirical(&self, spec: &RobotSpec) -> RobotSpec {
        let mut out = self.fitted_spec(spec);
        if let Some(d) = &self.discrepancy {
            out.discrepancy = Some(d.clone());
            return out;
        }
        if let Some(c) = &self.empirical {
            let mut all = out.empirical.take().unwrap_or_default();
            all.note = c.note.clone();
            all.terms.extend(c.terms.iter().copied());
            out.empirical = Some(all);
        }
        out
    }
}

/// The fitted robot file as `ctr-cli diagnose --out` writes it: a comment line naming
/// the robot and the effects added (`findings`: contract ids with their grades, in the
/// report's order; and, with
/// `with_empirical`, the empirical term in `[model.empirical]`), a comment line per
/// grade saying which are established and which only predictive, then `fitted`'s TOML,
/// which `ctr-cli fk` reads as is.
///
/// ```
/// let spec = ctr_formats::RobotSpec::from_path(std::path::Path::new("../../data/robots/liu2023.toml"))?;
/// let text = ctr_diagnosis::fitted_file(&spec, &[], false);
/// assert!(text.starts_with("# Fitted by ctr-cli from liu2023: no effect added\nname = \"liu2023\"\n"));
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn fitted_file(fitted: &RobotSpec, findings: &[(&str, Grade)], with_empirical: bool) -> String {
    let of =
        |g: Grade| -> Vec<&str> { findings.iter().filter(|f| f.1 == g).map(|f| f.0).collect() };
    let all: Vec<&str> = findings.iter().map(|f| f.0).collect();
    let mut grades = String::new();
    let established = of(Grade::Established);
    if !established.is_empty() {
        grades += &format!(
            "# established (physics the data show): {}\n",
            established.join(", ")
        );
    }
    let predictive = of(Grade::Predictive);
    if !predictive.is_empty() {
        grades += &format!(
            "# predictive (helps prediction; its form is not established; it may stand in for \
             something outside the vocabulary): {}\n",
            predictive.join(", ")
        );
    }
    format!(
        "# Fitted by ctr-cli from {}: {}{}\n{grades}{}",
        fitted.name.as_deref().unwrap_or("the robot file"),
        if all.is_empty() {
            "no effect added".to_owned()
        } else {
            all.join(", ")
        },
        match (with_empirical, fitted.discrepancy.is_some()) {
            (false, _) => "",
            (true, true) => "; and a learned discrepancy (not physics) in [model.discrepancy]",
            (true, false) => "; and an empirical term (not physics) in [model.empirical]",
        },
        fitted.to_toml()
    )
}

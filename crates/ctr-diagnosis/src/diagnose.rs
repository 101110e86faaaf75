//! The diagnosis, step by step: the method of the crate docs as it runs.

use crate::error::DiagnoseError;
use crate::finish::{finish, WhereLeft};
use crate::found::Found;
use crate::options::Options;
use crate::predictive::readmit;
use crate::report::Diagnosis;
use crate::search::forward_selection;
use crate::start::{simulated, Start};
use crate::verify::settle;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::{predict_with_margins_on, Prediction};
use ctr_formats::Recording;

/// Diagnoses `model` against `rec`: the split, the noise and where the error sits; the
/// effects the model leaves out, found by forward selection and each checked with the
/// others in place; the verdict, the intervals and the rows near a snap.
///
/// ```no_run
/// use ctr_diagnosis::{diagnose, Options};
/// use ctr_analysis::model::ModelSpec;
/// use ctr_formats::{Recording, RobotSpec};
/// use std::path::Path;
/// let spec = RobotSpec::from_path(Path::new("robot.toml"))?;
/// let rec = Recording::from_path(Path::new("rec.csv"), spec.robot.n_tubes())?;
/// let d = diagnose(&ModelSpec::from_spec(&spec), &rec, &Options::default())?;
/// for f in &d.report.findings {
///     println!("{}: {}", f.effect.as_str(), f.explanation);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn diagnose(
    model: &ModelSpec,
    rec: &Recording,
    opt: &Options,
) -> Result<Diagnosis, DiagnoseError> {
    let framed = crate::search::frame::profiled(model, &opt.candidates);
    let (weighted, base, seen) = simulated(model, rec, framed, opt.threads)?;
    let start = Start::new(model, &weighted, base, seen, opt)?;
    let found = forward_selection(&start, &opt.candidates)?;
    let (established, removed, assessed) = settled(&start, &found);
    let (found, only_established) = readmit(&start, found, established, removed);
    // the checks' assessment is of the established findings alone
    let assessed = assessed.filter(|_| only_established);
    let found = without_alternatives_found(found);
    let pred = with_margins(&start, &found)?;
    Ok(finish(start, found, &pred, assessed, WhereLeft::Located))
}

/// The established findings of the searched `found` ([`settle`]), revisited as the
/// search revisits (`crate::search::backward`): a finding the checks kept only because
/// a finding they took out held it up (a soft tube beside a strong gravity, standing in
/// for something else) no longer pays without it, and goes too; then the rest is
/// checked again. With the findings taken out, and the assessment of the last checks
/// (none when the revisit took something out after them).
fn settled(
    start: &Start,
    found: &Found,
) -> (
    Found,
    Vec<crate::verify::Removed>,
    Option<crate::uncertainty::Assessment>,
) {
    let mut all_removed = Vec::new();
    let mut from = found.clone();
    loop {
        let (mut established, removed, assessed) = settle(start, from, start.checks);
        all_removed.extend(removed);
        let round = established.tried.iter().map(|t| t.round).max().unwrap_or(0) + 1;
        let dropped = crate::search::backward::revisit(start, &mut established, round);
        if dropped.is_empty() {
            return (established, all_removed, assessed);
        }
        all_removed.extend(dropped);
        from = established;
    }
}

/// `found` without the alternatives that are themselves findings (no alternative).
fn without_alternatives_found(mut found: Found) -> Found {
    let effects = found.effects();
    for f in &mut found.findings {
        f.equally_explained_by
            .retain(|a| !effects.contains(&a.effect));
    }
    found
}

/// The prediction of `found`'s model along every run, with stability margins.
pub(crate) fn with_margins(start: &Start, found: &Found) -> Result<Prediction, DiagnoseError> {
    predict_with_margins_on(&found.model, start.rec, &start.all_runs, start.threads)
        .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))
}

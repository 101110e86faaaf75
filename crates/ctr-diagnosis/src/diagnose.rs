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
use ctr_analysis::simulate::{predict_with_margins, Prediction};
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
    let (weighted, base) = simulated(model, rec)?;
    let start = Start::new(model, &weighted, base, opt)?;
    let found = forward_selection(&start, &opt.candidates)?;
    let (established, removed, assessed) = settle(&start, found.clone(), start.checks);
    let (found, only_established) = readmit(&start, found, established, removed);
    // the checks' assessment is of the established findings alone
    let assessed = assessed.filter(|_| only_established);
    let found = without_alternatives_found(found);
    let pred = with_margins(&start, &found)?;
    Ok(finish(start, found, &pred, assessed, WhereLeft::Located))
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
    predict_with_margins(&found.model, start.rec, &start.all_runs)
        .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))
}

//! `ctr_py.diagnose`, `ctr_py.calibrate`, `ctr_py.evaluate` and `ctr_py.Report`: the
//! calls of `ctr-cli diagnose`, `calibrate` and `evaluate` on a `Robot` and a
//! `Recording`, with the CLI's options (the same strings for `holdout` and the
//! effects) and messages.
//!
//! A `Report` keeps the report as the compact JSON text `serde_json` writes of it, that
//! text parsed once by Python's `json` into a [`Json`] tree (so `to_dict()` and the
//! attributes equal the parsed CLI file exactly, `NaN` written as `null` included, and
//! the indented text is `serde_json`'s, as `ctr-cli diagnose --report` writes it), the
//! CLI's summary text and the fitted model as a `Robot` (the robot file `--out` writes,
//! without its comment line), and the user's robot and the recording it was made from,
//! from which `to_html()` draws the page `ctr-cli diagnose --html` writes
//! (`ctr_diagnosis::Page`, from the same JSON text: the same bytes).

use crate::errors;
use crate::json::Json;
use crate::recording::{self, Recording};
use crate::robot::{check_threads, Robot, MAX_THREADS};
use ctr_analysis::margin::DEFAULT_WARN_MARGIN;
use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::{DiagnoseError, Diagnosis, EffectId, Holdout, MarginRange, Options, Page};
use ctr_formats::CLEARANCE_FIT_TABLE_SIZES;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use std::path::PathBuf;

/// `holdout=`: `None` (the default split, blocks:4) or the CLI's string.
fn holdout_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Holdout> {
    let Some(obj) = obj else {
        return Ok(Holdout::default());
    };
    let s = obj.cast::<PyString>().map_err(|_| {
        errors::input_type(format!(
            "holdout: a {} is not a split (wanted a str, blocks:K or runs:LABEL[,LABEL...])",
            type_name(obj)
        ))
    })?;
    s.to_cow()?
        .parse::<Holdout>()
        .map_err(|m| errors::input(format!("holdout: {m}")))
}

/// `warn_margin=`: `None` (the CLI's default, `ctr-cli fk --warn-margin`'s) or a number,
/// finite and not negative.
fn warn_margin_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<f64> {
    let Some(obj) = obj else {
        return Ok(DEFAULT_WARN_MARGIN);
    };
    let x: f64 = if obj.is_instance_of::<pyo3::types::PyBool>() {
        None
    } else {
        obj.extract().ok()
    }
    .ok_or_else(|| {
        errors::input_type(format!(
            "warn_margin: a {} is not a number (a stability margin, e.g. 0.05)",
            type_name(obj)
        ))
    })?;
    ctr_diagnosis::checked_warn_margin(x).map_err(|m| errors::input(format!("warn_margin: {m}")))
}

/// A list of effect ids: a comma-separated str or a sequence of str.
fn effects_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<EffectId>> {
    let ids: Vec<String> = if let Ok(s) = obj.cast::<PyString>() {
        s.to_cow()?.split(',').map(str::to_owned).collect()
    } else {
        let not_ids = || {
            errors::input_type(format!(
                "{name}: a {} is not a list of effect ids (str)",
                type_name(obj)
            ))
        };
        let mut ids = Vec::new();
        for item in obj.try_iter().map_err(|_| not_ids())? {
            let item = item?;
            let s = item.cast::<PyString>().map_err(|_| {
                errors::input_type(format!(
                    "{name}: a {} is not an effect id (a str such as \"clearance\")",
                    type_name(&item)
                ))
            })?;
            ids.push(s.to_cow()?.into_owned());
        }
        ids
    };
    ids.iter()
        .map(|s| EffectId::from_id(s).map_err(|m| errors::input(format!("{name}: {m}"))))
        .collect()
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_default()
}

/// `threads=`: `None` or 0 for all cores.
fn threads_opt(threads: Option<i64>) -> PyResult<usize> {
    match threads {
        None => Ok(0),
        Some(t) if t >= 0 => check_threads(usize::try_from(t).unwrap_or(usize::MAX)),
        Some(t) => Err(errors::input(format!(
            "threads: {t} is not in 0..={} (0 = all cores)",
            MAX_THREADS
        ))),
    }
}

/// The recording argument: a `Recording` of the robot's tube count (the same object), or
/// a path read with the robot's joint columns.
fn recording_arg(py: Python<'_>, obj: &Bound<'_, PyAny>, robot: &Robot) -> PyResult<Py<Recording>> {
    let n = robot.spec().robot.n_tubes();
    if let Ok(r) = obj.cast::<Recording>() {
        let rec = &r.get().rec;
        if rec.n_tubes != n {
            return Err(errors::input(format!(
                "{}: {n} tubes, but the recording {} was read for {} (read_recording(path, \
                 robot) reads the joint columns of the robot's tubes)",
                robot.source_name(),
                rec.file,
                rec.n_tubes
            )));
        }
        return Ok(r.clone().unbind());
    }
    let path: PathBuf = obj.extract().map_err(|_| {
        errors::input_type(format!(
            "recording: a {} is not a ctr_py.Recording or a path",
            type_name(obj)
        ))
    })?;
    let rec = recording::read(py, &path, n)?;
    Py::new(py, Recording { rec })
}

/// A diagnosis's or calibration's report; see `_ctr.pyi`.
#[pyclass(frozen, module = "ctr_py", name = "Report")]
pub struct Report {
    /// The report's JSON text, compact (as pickled).
    json: String,
    /// The same, parsed once.
    value: Json,
    /// The CLI's summary text.
    summary: String,
    /// The fitted model.
    fitted: Py<Robot>,
    /// The fitted model with the empirical correction (`--with-empirical`); `None`
    /// when explained (then the same as `fitted`).
    fitted_empirical: Option<Py<Robot>>,
    /// The fitted model with the established findings alone; `None` in a report
    /// pickled before grades (then `fitted`).
    fitted_established: Option<Py<Robot>>,
    /// The recording's file name.
    recording: String,
    /// The user's robot.
    user: Py<Robot>,
    /// The recording the report was made from.
    rec: Py<Recording>,
}

/// What a pickled `Report` holds: the JSON text, the summary, the fitted robot, the
/// recording's file name, the user's robot, the recording and (last, so that the earlier
/// fields keep their places) the fitted robot with the empirical correction, then the
/// fitted robot with the established findings alone.
type State = (
    String,
    String,
    Py<Robot>,
    String,
    Py<Robot>,
    Py<Recording>,
    Option<Py<Robot>>,
    Option<Py<Robot>>,
);

impl Report {
    fn new(
        py: Python<'_>,
        d: &Diagnosis,
        robot: &Bound<'_, Robot>,
        rec: Py<Recording>,
    ) -> PyResult<Self> {
        let json = serde_json::to_string(&d.report)
            .map_err(|e| errors::input(format!("internal: the report does not serialize: {e}")))?;
        let user = robot.get();
        let fitted = d.fitted_spec(user.spec());
        let fitted = Robot::new(fitted, format!("{} (fitted)", user.source_name()));
        let fitted_empirical = match &d.empirical {
            Some(_) => Some(Py::new(
                py,
                Robot::new(
                    d.fitted_spec_with_empirical(user.spec()),
                    format!("{} (fitted, with empirical)", user.source_name()),
                ),
            )?),
            None => None,
        };
        let fitted_established = Some(Py::new(
            py,
            Robot::new(
                d.established_spec(user.spec()),
                format!("{} (fitted, established findings)", user.source_name()),
            ),
        )?);
        let file = rec.get().rec.file.clone();
        Report::_from_state(
            py,
            json,
            d.report.summary(&file),
            Py::new(py, fitted)?,
            file,
            robot.clone().unbind(),
            rec,
            fitted_empirical,
            fitted_established,
        )
    }

    fn item<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        self.value.item(py, key)
    }
}

#[pymethods]
impl Report {
    /// Rebuilds a pickled report (and builds every report): its JSON text, a JSON
    /// object, parsed here once.
    #[staticmethod]
    #[pyo3(signature = (json, summary, fitted, recording, user, rec, fitted_empirical = None, fitted_established = None))]
    #[allow(clippy::too_many_arguments)]
    fn _from_state(
        py: Python<'_>,
        json: String,
        summary: String,
        fitted: Py<Robot>,
        recording: String,
        user: Py<Robot>,
        rec: Py<Recording>,
        fitted_empirical: Option<Py<Robot>>,
        fitted_established: Option<Py<Robot>>,
    ) -> PyResult<Self> {
        let parsed = py
            .import("json")?
            .call_method1("loads", (&json,))
            .ok()
            .filter(|v| v.is_instance_of::<PyDict>())
            .ok_or_else(|| errors::input("Report state: the report is not a JSON object".into()))?;
        let value =
            Json::from_py(&parsed).map_err(|m| errors::input(format!("Report state: {m}")))?;
        Ok(Report {
            json,
            value,
            summary,
            fitted,
            fitted_empirical,
            fitted_established,
            recording,
            user,
            rec,
        })
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, State)> {
        let r = slf.get();
        let py = slf.py();
        Ok((
            slf.get_type().getattr("_from_state")?,
            (
                r.json.clone(),
                r.summary.clone(),
                r.fitted.clone_ref(py),
                r.recording.clone(),
                r.user.clone_ref(py),
                r.rec.clone_ref(py),
                r.fitted_empirical.as_ref().map(|f| f.clone_ref(py)),
                r.fitted_established.as_ref().map(|f| f.clone_ref(py)),
            ),
        ))
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other.cast::<Report>().is_ok_and(|o| {
            let o = o.get();
            o.json == self.json
                && o.recording == self.recording
                && o.fitted.get().spec() == self.fitted.get().spec()
        })
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let effects: Vec<String> = self.effects(py)?.iter().map(|e| format!("'{e}'")).collect();
        Ok(format!(
            "Report(recording='{}', findings=[{}])",
            self.recording,
            effects.join(", ")
        ))
    }

    /// The report as plain dicts, lists, str, int and float (`None` for `null`), new on
    /// every call.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.value.to_py(py)
    }

    /// The report's JSON text, as `ctr-cli --report` writes it (`serde_json`'s
    /// two-space indents, a final newline) or compact.
    #[pyo3(signature = (indent = true))]
    fn to_json(&self, indent: bool) -> PyResult<String> {
        if indent {
            serde_json::to_string_pretty(&self.value)
                .map(|text| text + "\n")
                .map_err(|e| errors::input(format!("internal: the report does not serialize: {e}")))
        } else {
            Ok(self.json.clone())
        }
    }

    /// The plain-language summary `ctr-cli` prints.
    fn summary(&self) -> &str {
        &self.summary
    }

    /// The report as one self-contained HTML page, the bytes `ctr-cli diagnose --html`
    /// writes for the same robot, recording and options.
    fn to_html(&self, py: Python<'_>) -> PyResult<String> {
        let (rec, user, fitted) = (&self.rec.get().rec, self.user.get(), self.fitted.get());
        let json = &self.json;
        py.detach(|| {
            Page::from_json(json, rec, user.spec(), fitted.spec()).and_then(|p| p.to_html())
        })
        .map_err(|e| errors::input(format!("{}: {e}", rec.file)))
    }

    /// The fitted model: the robot with its `[model]` and the effects found, fitted.
    #[getter]
    fn fitted(&self, py: Python<'_>) -> Py<Robot> {
        self.fitted.clone_ref(py)
    }

    /// The fitted model with the report's empirical correction in `[model.empirical]`
    /// (after any terms the user's file had): the robot file `ctr-cli diagnose
    /// --with-empirical --out` writes. The same as `fitted` when the recording is
    /// explained (no empirical term).
    #[getter]
    fn fitted_with_empirical(&self, py: Python<'_>) -> Py<Robot> {
        self.fitted_empirical
            .as_ref()
            .unwrap_or(&self.fitted)
            .clone_ref(py)
    }

    /// The fitted model with the established findings alone (refitted on the fit rows
    /// without the predictive ones): the robot file `ctr-cli diagnose
    /// --established-only --out` writes. `fitted` for a report pickled before grades.
    #[getter]
    fn fitted_established(&self, py: Python<'_>) -> Py<Robot> {
        self.fitted_established
            .as_ref()
            .unwrap_or(&self.fitted)
            .clone_ref(py)
    }

    /// The recording's file name.
    #[getter]
    fn recording(&self) -> &str {
        &self.recording
    }

    /// The ids of the effects found, in the order added.
    #[getter]
    fn effects(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        let findings = self.item(py, "findings")?;
        findings
            .try_iter()?
            .map(|f| f?.get_item("effect")?.extract())
            .collect()
    }

    /// `baseline`: the user model's figures.
    #[getter]
    fn baseline<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "baseline")
    }

    /// `findings`: the effects found, in the order added.
    #[getter]
    fn findings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "findings")
    }

    /// `final`: the fitted model's figures.
    #[getter(r#final)]
    fn final_<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "final")
    }

    /// `unexplained`: what is left, in words.
    #[getter]
    fn unexplained<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "unexplained")
    }

    /// `noise`: the noise estimated from the data.
    #[getter]
    fn noise<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "noise")
    }

    /// `split`: the split used.
    #[getter]
    fn split<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "split")
    }

    /// `located`: where the user model's error sits.
    #[getter]
    fn located<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "located")
    }

    /// `tried`: every candidate fitted, round by round.
    #[getter]
    fn tried<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "tried")
    }

    /// `failed_rows`: rows whose solve did not converge under the fitted model.
    #[getter]
    fn failed_rows<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "failed_rows")
    }

    /// `explained`: the verdict, true when what is left is consistent with the noise.
    #[getter]
    fn explained<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "explained")
    }

    /// `uncertainty_method`: how the findings' `ci95` were computed.
    #[getter]
    fn uncertainty_method<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "uncertainty_method")
    }

    /// `identifiability`: what the data do not identify, in words.
    #[getter]
    fn identifiability<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "identifiability")
    }

    /// `correlated`: pairs of fitted parameters correlated above 0.9.
    #[getter]
    fn correlated<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "correlated")
    }

    /// `suggested_run`: the run to record next, or `None`.
    #[getter]
    fn suggested_run<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "suggested_run")
    }

    /// `stability`: the rows where the user's or the fitted model is near a snap.
    #[getter]
    fn stability<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.item(py, "stability")
    }

    /// `empirical`: the labelled empirical correction, or `None` when explained.
    #[getter]
    fn empirical<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match self.item(py, "empirical") {
            Err(e) if e.is_instance_of::<pyo3::exceptions::PyKeyError>(py) => {
                Ok(py.None().into_bound(py))
            }
            other => other,
        }
    }
}

/// Runs `fit` (a diagnosis or calibration) on the robot's model and the recording with
/// the GIL released: the report, or the error located at the recording as `ctr-cli`
/// prints it.
fn fit_report(
    py: Python<'_>,
    robot: &Bound<'_, Robot>,
    recording: &Bound<'_, PyAny>,
    fit: impl FnOnce(&ModelSpec, &ctr_formats::Recording) -> Result<Diagnosis, DiagnoseError> + Send,
) -> PyResult<Report> {
    let rec_obj = recording_arg(py, recording, robot.get())?;
    let rec = &rec_obj.get().rec;
    let model = ModelSpec::from_spec(robot.get().spec());
    let d = py
        .detach(|| fit(&model, rec))
        .map_err(|e| errors::input(format!("{}: {e}", rec.file)))?;
    Report::new(py, &d, robot, rec_obj)
}

/// Diagnoses a robot's model against a recording; see `_ctr.pyi`.
#[pyfunction]
#[pyo3(signature = (robot, recording, *, holdout = None, effects = None, threads = None, warn_margin = None))]
pub fn diagnose(
    py: Python<'_>,
    robot: &Bound<'_, Robot>,
    recording: &Bound<'_, PyAny>,
    holdout: Option<&Bound<'_, PyAny>>,
    effects: Option<&Bound<'_, PyAny>>,
    threads: Option<i64>,
    warn_margin: Option<&Bound<'_, PyAny>>,
) -> PyResult<Report> {
    let options = Options {
        holdout: holdout_arg(holdout)?,
        candidates: match effects {
            None => EffectId::ALL.to_vec(),
            Some(e) => effects_arg("effects", e)?,
        },
        threads: threads_opt(threads)?,
        clearance_table: None,
        warn_margin: warn_margin_arg(warn_margin)?,
        ..Default::default()
    };
    fit_report(py, robot, recording, |model, rec| {
        ctr_diagnosis::diagnose(model, rec, &options)
    })
}

/// Fits the named effects' parameters; see `_ctr.pyi`.
#[pyfunction]
#[pyo3(signature = (robot, recording, fit, *, table = None, holdout = None, threads = None, warn_margin = None))]
pub fn calibrate(
    py: Python<'_>,
    robot: &Bound<'_, Robot>,
    recording: &Bound<'_, PyAny>,
    fit: &Bound<'_, PyAny>,
    table: Option<i64>,
    holdout: Option<&Bound<'_, PyAny>>,
    threads: Option<i64>,
    warn_margin: Option<&Bound<'_, PyAny>>,
) -> PyResult<Report> {
    let fit = effects_arg("fit", fit)?;
    if fit.is_empty() {
        return Err(errors::input(
            "fit: no effect ids; name the effects whose parameters are fitted (e.g. \
             [\"clearance\"])"
                .into(),
        ));
    }
    let table = match table {
        None => None,
        Some(k) if k >= 0 && CLEARANCE_FIT_TABLE_SIZES.contains(&(k as usize)) => Some(k as usize),
        Some(k) => {
            return Err(errors::input(format!(
                "table: {k} is not in {}..={}",
                CLEARANCE_FIT_TABLE_SIZES.start(),
                CLEARANCE_FIT_TABLE_SIZES.end()
            )))
        }
    };
    let options = Options {
        holdout: holdout_arg(holdout)?,
        threads: threads_opt(threads)?,
        clearance_table: table,
        warn_margin: warn_margin_arg(warn_margin)?,
        ..Options::default()
    };
    fit_report(py, robot, recording, |model, rec| {
        ctr_diagnosis::calibrate(model, rec, &fit, &options)
    })
}

/// Per model, its ranges as dicts (the report's `stability` keys).
fn ranges_per_model<'py>(
    py: Python<'py>,
    per_model: &[Vec<MarginRange>],
) -> PyResult<Bound<'py, PyList>> {
    let out = PyList::empty(py);
    for ranges in per_model {
        let list = PyList::empty(py);
        for r in ranges {
            let d = PyDict::new(py);
            d.set_item("run", &r.run)?;
            d.set_item("lines", r.lines.to_vec())?;
            d.set_item("rows", r.rows)?;
            d.set_item("lowest_margin", r.lowest_margin)?;
            d.set_item("lowest_line", r.lowest_line)?;
            list.append(d)?;
        }
        out.append(list)?;
    }
    Ok(out)
}

/// Mean and largest tip error per run for several models; see `_ctr.pyi`.
#[pyfunction]
#[pyo3(signature = (robots, recording, *, warn_margin = None))]
pub fn evaluate<'py>(
    py: Python<'py>,
    robots: &Bound<'py, PyAny>,
    recording: &Bound<'py, PyAny>,
    warn_margin: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyList>> {
    let warn_margin = warn_margin_arg(warn_margin)?;
    let list: Vec<Bound<'py, Robot>> = if let Ok(r) = robots.cast::<Robot>() {
        vec![r.clone()]
    } else {
        let not_robots = || {
            errors::input_type(format!(
                "robots: a {} is not a list of ctr_py.Robot",
                type_name(robots)
            ))
        };
        let mut v = Vec::new();
        for item in robots.try_iter().map_err(|_| not_robots())? {
            let item = item?;
            let r = item.cast::<Robot>().map_err(|_| {
                errors::input_type(format!(
                    "robots: a {} is not a ctr_py.Robot",
                    type_name(&item)
                ))
            })?;
            v.push(r.clone());
        }
        v
    };
    let Some(first) = list.first() else {
        return Err(errors::input(
            "robots: no robots; give at least one model to evaluate".into(),
        ));
    };
    let first = first.get();
    let n_first = first.spec().robot.n_tubes();
    for r in &list[1..] {
        let r = r.get();
        let n = r.spec().robot.n_tubes();
        if n != n_first {
            // `ctr-cli evaluate`'s message
            return Err(errors::input(format!(
                "{}: {n} tubes, but the first robot has {n_first}; models compared on one \
                 recording must have the same tubes",
                r.source_name()
            )));
        }
    }
    let rec_obj = recording_arg(py, recording, first)?;
    let rec = &rec_obj.get().rec;
    let models: Vec<ModelSpec> = list
        .iter()
        .map(|r| ModelSpec::from_spec(r.get().spec()))
        .collect();
    let table = py
        .detach(|| ctr_diagnosis::evaluate(&models, rec, warn_margin))
        .map_err(|e| errors::input(format!("{}: {e}", rec.file)))?;
    let out = PyList::empty(py);
    for r in table {
        let d = PyDict::new(py);
        d.set_item("run", r.run)?;
        d.set_item("rows", r.rows)?;
        d.set_item("mean_mm", r.mean_mm)?;
        d.set_item("max_mm", r.max_mm)?;
        // no converged row: no margin (None, as the report's JSON writes NaN)
        let lowest: Vec<Option<f64>> = r
            .lowest_margin
            .iter()
            .map(|m| (!m.is_nan()).then_some(*m))
            .collect();
        d.set_item("lowest_margin", lowest)?;
        d.set_item("near_snap", ranges_per_model(py, &r.near_snap)?)?;
        d.set_item("unstable", ranges_per_model(py, &r.unstable)?)?;
        out.append(d)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holdout_and_effect_strings_as_the_cli() {
        assert_eq!("blocks:3".parse(), Ok(Holdout::Blocks { every: 3 }));
        assert_eq!(
            "runs: a ,b".parse(),
            Ok(Holdout::Runs(vec!["a".into(), "b".into()]))
        );
        assert!("blocks:1".parse::<Holdout>().is_err());
        assert!("runs:".parse::<Holdout>().is_err());
        assert_eq!(EffectId::from_id(" latency"), Ok(EffectId::Latency));
        assert!(EffectId::from_id("lag")
            .unwrap_err()
            .starts_with("unknown effect \"lag\""));
    }
}

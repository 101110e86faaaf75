//! Calibration: the named effects fitted together, without the search.

use crate::candidates::{not_applicable, EffectId};
use crate::error::DiagnoseError;
use crate::finish::{finish, WhereLeft};
use crate::fit::{Problem, MAX_FIT_ITERATIONS};
use crate::found::Found;
use crate::locate;
use crate::options::Options;
use crate::report::prose::{explain, parameters};
use crate::report::{Diagnosis, Finding};
use crate::residual::{errors, figures};
use crate::start::{sample_period, Start};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict_with_margins;
use ctr_formats::Recording;

/// Start of every value of a clearance table fit, deg.
const TABLE_START_DEG: f64 = 0.5;

/// Fits the parameters of the named effects together, without the search: the
/// `calibrate` of a lab that knows what to identify (a clearance profile, the stiffness
/// from tip deflections under known hung weights recorded as `fx_n,fy_n,fz_n`, ...).
/// Effects the model already has are refitted from their values. The report has one
/// finding per effect (before: the user model; after: all fitted).
///
/// ```no_run
/// use ctr_diagnosis::{calibrate, EffectId, Options};
/// use ctr_analysis::model::ModelSpec;
/// use ctr_formats::{Recording, RobotSpec};
/// use std::path::Path;
/// let spec = RobotSpec::from_path(Path::new("robot.toml"))?;
/// let rec = Recording::from_path(Path::new("weights.csv"), spec.robot.n_tubes())?;
/// let d = calibrate(&ModelSpec::from_spec(&spec), &rec, &[EffectId::Stiffness], &Options::default())?;
/// println!("{}", d.report.findings[0].explanation);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn calibrate(
    model: &ModelSpec,
    rec: &Recording,
    effects: &[EffectId],
    opt: &Options,
) -> Result<Diagnosis, DiagnoseError> {
    for &c in effects {
        if let Some(note) = not_applicable(c, model, rec) {
            return Err(DiagnoseError::Model(format!("{}: {note}", c.as_str())));
        }
    }
    // the angular columns weighted by their noise: the one residual of the fits
    let (weighted, base) = crate::start::simulated(model, rec)?;
    let rec: &Recording = &weighted;
    let start = Start::new(model, rec, base, opt)?;
    let n = model.robot.n_tubes();
    let mut blocks: Vec<EffectId> = Vec::new();
    for &c in effects {
        if !blocks.contains(&c) {
            blocks.push(c);
        }
    }
    let problem = Problem {
        clearance_table: opt.clearance_table,
        ..start.problem(model.clone(), blocks.clone())
    };
    let period = sample_period(rec);
    // start every block from the model's values (or its first start when absent); a
    // block with several starts tries each, the others held at their first
    let table_start = |b: EffectId| -> Option<Vec<f64>> {
        let k = problem
            .clearance_table
            .filter(|_| b == EffectId::Clearance)?;
        Some(vec![TABLE_START_DEG; k * n.saturating_sub(1)])
    };
    let first: Vec<Vec<f64>> = blocks
        .iter()
        .map(|b| {
            if let Some(t) = table_start(*b) {
                t
            } else if b.present_in(model) {
                b.read(model)
            } else {
                b.starts(n, period).swap_remove(0)
            }
        })
        .collect();
    let mut starts = vec![first.concat()];
    for (i, b) in blocks.iter().enumerate() {
        if b.present_in(model) || table_start(*b).is_some() {
            continue;
        }
        for alt in b.starts(n, period).into_iter().skip(1) {
            let mut x = first.clone();
            x[i] = alt;
            starts.push(x.concat());
        }
    }
    let fitted = starts
        .iter()
        .filter_map(|x0| problem.fit(x0, MAX_FIT_ITERATIONS))
        .min_by(|a, b| a.cost.total_cmp(&b.cost))
        .ok_or_else(|| {
            DiagnoseError::Model("the model cannot be simulated with these effects".into())
        })?;
    let m = problem.model(&fitted.x);
    let pred = predict_with_margins(&m, rec, &start.all_runs)
        .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
    let e = errors(rec, &pred);
    let fig = figures(&e, &start.held);
    let change: Vec<[f64; 3]> = e
        .iter()
        .zip(&start.e0)
        .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
        .collect();
    let all_mask = vec![true; rec.rows.len()];
    let where_ = locate::summary(&locate::locate(rec, &change, &all_mask, &pred.p));
    let findings = blocks
        .iter()
        .map(|&c| Finding {
            effect: c,
            explanation: explain(c, &m),
            where_: where_.clone(),
            parameters: parameters(c, &m),
            rms_mm_before: start.baseline.rms_mm,
            rms_mm_after: fig.rms_mm,
            heldout_rms_mm_before: start.baseline.heldout_rms_mm,
            heldout_rms_mm_after: fig.heldout_rms_mm,
            // the user named these effects: no search, so no check against the generic
            empirical_heldout_rms_mm: f64::NAN,
            ci95: serde_json::Value::Null,
            equally_explained_by: Vec::new(),
        })
        .collect();
    let found = Found {
        model: m,
        findings,
        fig,
        cost: fitted.cost,
        e,
        tried: Vec::new(),
    };
    Ok(finish(
        start,
        found,
        &pred,
        None,
        WhereLeft::Said("`ctr-cli diagnose` searches the other effects"),
    ))
}

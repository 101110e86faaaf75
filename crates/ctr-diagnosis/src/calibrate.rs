//! Calibration: the named effects fitted together, without the search.

use crate::candidates::{not_applicable, EffectId};
use crate::error::DiagnoseError;
use crate::finish::{finish, WhereLeft};
use crate::fit::{Problem, MAX_FIT_ITERATIONS};
use crate::found::Found;
use crate::levenberg::Fitted;
use crate::locate;
use crate::options::Options;
use crate::report::prose::{explain, parameters};
use crate::report::Grade;
use crate::report::{Diagnosis, Finding};
use crate::residual::{errors, figures, RowError};
use crate::start::{sample_period, Start};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict_with_margins_on;
use ctr_formats::Recording;

/// Start of every value of a clearance table fit, deg.
const TABLE_START_DEG: f64 = 0.5;

/// Fits the parameters of the named effects together, without the search: the
/// `calibrate` of a lab that knows what to identify (a clearance profile, the stiffness
/// from tip deflections under known hung weights recorded as `fx_n,fy_n,fz_n`, ...).
/// Effects the model already has are refitted from their values. The fit starts from
/// every combination of the effects' starts (`starts`) and, with several effects, also
/// from the staged fit that adds them one at a time; the lowest cost wins. A fit that
/// cannot lower the cost from its start although the linearised problem says it could
/// is an error ([`DiagnoseError::NotFitted`]): a start value is never reported as a fit.
/// The report has one finding per effect; its before figures are the fitted model's
/// without it.
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
    // the angular columns weighted by their noise: the one residual of the fits (and
    // what says whether the sensor's rotation can be seen at all)
    let framed = effects.contains(&EffectId::Registration);
    let (weighted, base, seen) = crate::start::simulated(model, rec, framed, opt.threads)?;
    for &c in effects {
        if let Some(note) = not_applicable(c, model, &weighted) {
            return Err(DiagnoseError::Model(format!("{}: {note}", c.as_str())));
        }
    }
    let start = Start::new(model, &weighted, base, seen, opt)?;
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
    let fitted = best_fit(&problem, &starts(&problem, model, &start))?;
    let m = problem.model(&fitted.x);
    let pred = predict_with_margins_on(&m, start.rec, &start.all_runs, start.threads)
        .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
    let e = errors(start.rec, &pred);
    let findings = named_findings(&start, &blocks, &m, &e, &pred.p);
    let found = Found {
        fig: figures(start.rec, &e, &start.held),
        model: m,
        findings,
        cost: fitted.cost,
        e,
        tried: Vec::new(),
        frame_profiled: false,
    };
    Ok(finish(
        start,
        found,
        &pred,
        None,
        WhereLeft::Said("`ctr-cli diagnose` searches the other effects"),
    ))
}

/// The starts of `problem`'s fit: every block from `model`'s values (its first start
/// when absent, a table's [`TABLE_START_DEG`]), then each further start of a block with
/// the others at their first, then (with several blocks) the staged start: the blocks
/// fitted one after the other, each from the last stage's fit.
fn starts(problem: &Problem, model: &ModelSpec, start: &Start) -> Vec<Vec<f64>> {
    let n = model.robot.n_tubes();
    let period = sample_period(start.rec);
    let table_start = |b: EffectId| -> Option<Vec<f64>> {
        let k = problem
            .clearance_table
            .filter(|_| b == EffectId::Clearance)?;
        Some(vec![TABLE_START_DEG; k * n.saturating_sub(1)])
    };
    let first: Vec<Vec<f64>> = problem
        .blocks
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
    let mut out = vec![first.concat()];
    for (i, b) in problem.blocks.iter().enumerate() {
        if b.present_in(model) || table_start(*b).is_some() {
            continue;
        }
        for alt in b.starts(n, period).into_iter().skip(1) {
            let mut x = first.clone();
            x[i] = alt;
            out.push(x.concat());
        }
    }
    // feed offsets from the file that take rows out of the feeds' ranges (friction's
    // plays would simulate them, a fit does not: Problem::feeds_in_range) start from
    // zero as well
    let offsets = problem
        .blocks
        .iter()
        .position(|&b| b == EffectId::JointOffset);
    if let Some(i) = offsets.filter(|_| !problem.feeds_in_range(&out[0])) {
        let mut x = first.clone();
        x[i][..n].fill(0.0);
        out.push(x.concat());
    }
    if problem.blocks.len() > 1 {
        out.extend(staged(problem, &first));
    }
    out
}

/// The blocks of `problem` fitted one after the other from their `first` starts, each
/// stage freeing one more block from the last stage's fit: where fitting every block
/// at once from the starts stalls, effects that are large alone lead the way.
fn staged(problem: &Problem, first: &[Vec<f64>]) -> Option<Vec<f64>> {
    let mut base = problem.base.clone();
    for i in 0..problem.blocks.len() {
        let stage = Problem {
            base: base.clone(),
            blocks: problem.blocks[..=i].to_vec(),
            ..problem.clone()
        };
        let x0: Vec<f64> = problem.blocks[..i]
            .iter()
            .flat_map(|c| c.read(&base))
            .chain(first[i].iter().copied())
            .collect();
        base = stage.model(&stage.fit(&x0, MAX_FIT_ITERATIONS)?.x);
    }
    Some(problem.read(&base))
}

/// The fit of lowest cost over `starts`; an error when none can be simulated, or when
/// the best did not move from its start though it could have (stuck).
fn best_fit(problem: &Problem, starts: &[Vec<f64>]) -> Result<Fitted, DiagnoseError> {
    let best = starts
        .iter()
        .filter_map(|x0| problem.fit(x0, MAX_FIT_ITERATIONS))
        .min_by(|a, b| a.cost.total_cmp(&b.cost))
        .ok_or_else(|| {
            DiagnoseError::Model("the model cannot be simulated with these effects".into())
        })?;
    if best.stuck {
        let names: Vec<&str> = problem.blocks.iter().map(|b| b.as_str()).collect();
        return Err(DiagnoseError::NotFitted(format!(
            "the fit of {} did not move from its start values over {} starts although \
             the linearised problem says the cost can fall: no step the model can be \
             simulated at lowers it (fit fewer effects, or give starting values in the \
             robot file)",
            names.join(", "),
            starts.len()
        )));
    }
    Ok(best)
}

/// One finding per effect named to calibrate, of the fitted model `m` (its error
/// vectors `e`, modelled tips `tips`): where its change shows, its parameters, graded
/// by its intervals and bounds alone (no checks run).
fn named_findings(
    start: &Start,
    blocks: &[EffectId],
    m: &ModelSpec,
    e: &[RowError],
    tips: &[[f64; 3]],
) -> Vec<Finding> {
    let change: Vec<[f64; 3]> = e
        .iter()
        .zip(&start.e0)
        .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
        .collect();
    let all_mask = vec![true; start.rec.rows.len()];
    let where_ = locate::summary(&locate::locate(start.rec, &change, &all_mask, tips));
    blocks
        .iter()
        .map(|&c| Finding {
            effect: c,
            // no checks: graded by its intervals and bounds alone (`crate::grade::by_evidence`)
            grade: Grade::Established,
            grade_reason: "named to calibrate (no checks run); at least one of its 95 % \
                           intervals excludes the value that means it is not there, and no \
                           parameter sits on a bound of its fit"
                .into(),
            explanation: explain(c, m),
            where_: where_.clone(),
            parameters: parameters(c, m),
            // figures without it: `crate::finish`
            rms_mm_before: f64::NAN,
            rms_mm_after: f64::NAN,
            heldout_rms_mm_before: f64::NAN,
            heldout_rms_mm_after: f64::NAN,
            heldout_rms_deg: None,
            // the user named these effects: no search, so no check against the generic
            empirical_heldout_rms_mm: f64::NAN,
            ci95: serde_json::Value::Null,
            equally_explained_by: Vec::new(),
        })
        .collect()
}

//! Evaluation: the tip errors of several models, run by run (the seed paper's Table 2),
//! and where each model is near a snap along the recording.

use crate::error::DiagnoseError;
use crate::locate::stability::{checked_warn_margin, MarginRange, Marks};
use crate::report::RunErrors;
use crate::residual::errors;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict_with_margins;
use ctr_formats::Recording;

/// Mean and largest tip error per run (and over all rows, last) for each model, with
/// its smallest stability margin and the rows within `warn_margin` of a snap or on an
/// unstable branch (the margins of the same simulation: no extra solve).
///
/// ```
/// use ctr_analysis::model::ModelSpec;
/// use ctr_diagnosis::evaluate;
/// use ctr_formats::{Recording, RobotSpec};
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\nyoungs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let rec = Recording::read("run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\na,50,0,0,0,51\n".as_bytes(), "rec.csv", 1)?;
/// let table = evaluate(&[ModelSpec::from_spec(&spec)], &rec, 0.05).unwrap();
/// assert_eq!(table[0].run, "a");
/// assert!((table[0].mean_mm[0] - 1.0).abs() < 1e-12);
/// // one tube: nothing to snap against, the margin of uncoupled tubes
/// assert!((table[0].lowest_margin[0] - 1.0).abs() < 1e-9);
/// assert!(table[0].near_snap[0].is_empty());
/// assert_eq!(table.last().unwrap().run, "all");
/// assert!(evaluate(&[ModelSpec::from_spec(&spec)], &rec, f64::NAN).is_err());
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn evaluate(
    models: &[ModelSpec],
    rec: &Recording,
    warn_margin: f64,
) -> Result<Vec<RunErrors>, DiagnoseError> {
    let warn_margin = checked_warn_margin(warn_margin)
        .map_err(|m| DiagnoseError::Option(format!("warn_margin: {m}")))?;
    let all_runs: Vec<usize> = (0..rec.runs.len()).collect();
    let mut sizes = Vec::with_capacity(models.len());
    let mut margins = Vec::with_capacity(models.len());
    let mut marks = Vec::with_capacity(models.len());
    for m in models {
        let p = predict_with_margins(m, rec, &all_runs)
            .map_err(|e| DiagnoseError::Model(format!("the model cannot be simulated: {e}")))?;
        sizes.push(
            errors(rec, &p)
                .iter()
                .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
                .collect::<Vec<f64>>(),
        );
        marks.push(Marks::of(rec, &p.margin, warn_margin));
        margins.push(p.margin);
    }
    // the ranges among the rows `range` (lines grow with the rows)
    let within = |ranges: &[MarginRange], range: &std::ops::Range<usize>| -> Vec<MarginRange> {
        let lines = match (
            rec.rows.get(range.start),
            rec.rows.get(range.end.wrapping_sub(1)),
        ) {
            (Some(a), Some(b)) => a.line..=b.line,
            _ => return Vec::new(),
        };
        ranges
            .iter()
            .filter(|r| lines.contains(&r.lines[0]))
            .cloned()
            .collect()
    };
    let row = |label: &str, range: std::ops::Range<usize>| RunErrors {
        run: label.to_owned(),
        rows: range.len(),
        mean_mm: sizes
            .iter()
            .map(|s| s[range.clone()].iter().sum::<f64>() / range.len() as f64)
            .collect(),
        max_mm: sizes
            .iter()
            .map(|s| s[range.clone()].iter().copied().fold(0.0, f64::max))
            .collect(),
        // NaN (no margin) is skipped by f64::min
        lowest_margin: margins
            .iter()
            .map(|m| m[range.clone()].iter().copied().fold(f64::NAN, f64::min))
            .collect(),
        near_snap: marks.iter().map(|m| within(&m.near_snap, &range)).collect(),
        unstable: marks.iter().map(|m| within(&m.unstable, &range)).collect(),
    };
    let mut out: Vec<RunErrors> = rec
        .runs
        .iter()
        .map(|r| row(&r.label, r.rows.clone()))
        .collect();
    out.push(row("all", 0..rec.rows.len()));
    Ok(out)
}

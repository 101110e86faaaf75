//! Before/after plots of a diagnosis, as SVG (plotters; no fonts needed):
//!
//! - `residual-vs-<feature>.svg`: the tip error's size against the feature that located
//!   the user model's error best (a joint, an exposed length or a relative angle), for
//!   the user model and the fitted one;
//! - `run-<label>.svg`: per run, the measured tip path and both models' paths, projected
//!   on the plane of W in which the measured path spreads most.

use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_diagnosis::Diagnosis;
use ctr_formats::Recording;
use plotters::prelude::*;
use std::path::Path;

/// Size of each plot, pixels.
const SIZE: (u32, u32) = (900, 600);
/// Radius of a measured point, pixels.
const POINT_PX: i32 = 2;
const BEFORE: RGBColor = RGBColor(214, 39, 40);
const AFTER: RGBColor = RGBColor(31, 119, 180);
const MEASURED: RGBColor = RGBColor(60, 60, 60);

fn file_safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Writes every plot into `dir` (created if missing).
pub fn write_all(
    dir: &Path,
    rec: &Recording,
    user: &ModelSpec,
    d: &Diagnosis,
) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    let runs: Vec<usize> = (0..rec.runs.len()).collect();
    let before = predict(user, rec, &runs).map_err(|e| e.to_string())?.p;
    let after = predict(&d.fitted, rec, &runs).map_err(|e| e.to_string())?.p;
    let size = |p: &[[f64; 3]]| -> Vec<f64> {
        rec.rows
            .iter()
            .zip(p)
            .map(|(r, p)| ((0..3).map(|a| (p[a] - r.p[a]).powi(2)).sum::<f64>()).sqrt())
            .collect()
    };
    let (eb, ea) = (size(&before), size(&after));
    if let Some(top) = d
        .report
        .located
        .iter()
        .find(|s| matches!(s.kind.as_str(), "grows_with" | "periodic" | "direction"))
    {
        if let Some(x) = feature_values(rec, &top.feature) {
            let path = dir.join(format!("residual-vs-{}.svg", file_safe(&top.feature)));
            residual_plot(&path, &top.feature, &x, &eb, &ea)
                .map_err(|e| format!("{}: {e}", path.display()))?;
        }
    }
    for run in &rec.runs {
        let path = dir.join(format!("run-{}.svg", file_safe(&run.label)));
        let r = run.rows.clone();
        path_plot(&path, &run.label, rec, r, &before, &after)
            .map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

/// The values of a located feature (`s2`, `s2 - s1`, `theta2 - theta1`, ...).
fn feature_values(rec: &Recording, name: &str) -> Option<Vec<f64>> {
    let col = |tok: &str| -> Option<usize> {
        let (kind, i) = if let Some(i) = tok.strip_prefix("theta") {
            (1, i)
        } else if let Some(i) = tok.strip_prefix('s') {
            (0, i)
        } else {
            return None;
        };
        let i: usize = i.parse().ok()?;
        (1..=rec.n_tubes).contains(&i).then_some(2 * (i - 1) + kind)
    };
    let (a, b) = match name.split_once(" - ") {
        Some((a, b)) => (col(a)?, Some(col(b)?)),
        None => (col(name)?, None),
    };
    Some(
        rec.rows
            .iter()
            .map(|r| r.q[a] - b.map_or(0.0, |b| r.q[b]))
            .collect(),
    )
}

fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
        if x.is_finite() {
            (lo.min(x), hi.max(x))
        } else {
            (lo, hi)
        }
    });
    if lo.is_finite() && hi > lo {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    } else if lo.is_finite() {
        (lo - 1.0, lo + 1.0)
    } else {
        (0.0, 1.0)
    }
}

fn residual_plot(
    path: &Path,
    feature: &str,
    x: &[f64],
    before: &[f64],
    after: &[f64],
) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let (x0, x1) = range(x.iter().copied());
    let (_, y1) = range(before.iter().chain(after).copied());
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("tip error against {feature}"), ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, 0.0..y1)?;
    chart
        .configure_mesh()
        .x_desc(feature)
        .y_desc("tip error, mm")
        .draw()?;
    chart
        .draw_series(
            x.iter()
                .zip(before)
                .map(|(x, y)| Circle::new((*x, *y), POINT_PX, BEFORE.filled())),
        )?
        .label("user model")
        .legend(|(x, y)| Circle::new((x, y), 4, BEFORE.filled()));
    chart
        .draw_series(
            x.iter()
                .zip(after)
                .map(|(x, y)| Circle::new((*x, *y), POINT_PX, AFTER.filled())),
        )?
        .label("fitted model")
        .legend(|(x, y)| Circle::new((x, y), 4, AFTER.filled()));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

fn path_plot(
    path: &Path,
    label: &str,
    rec: &Recording,
    rows: std::ops::Range<usize>,
    before: &[[f64; 3]],
    after: &[[f64; 3]],
) -> Result<(), Box<dyn std::error::Error>> {
    // the two axes of W along which the measured path spreads most
    let spread = |a: usize| {
        let (lo, hi) = range(rec.rows[rows.clone()].iter().map(|r| r.p[a]));
        hi - lo
    };
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|a, b| spread(*b).total_cmp(&spread(*a)));
    let (u, v) = (axes[0].min(axes[1]), axes[0].max(axes[1]));
    let name = ["x", "y", "z"];
    let all = rows
        .clone()
        .flat_map(|k| [rec.rows[k].p, before[k], after[k]]);
    let (u0, u1) = range(all.clone().map(|p| p[u]));
    let (v0, v1) = range(all.map(|p| p[v]));
    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("run {label}: measured and modelled tip"),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(u0..u1, v0..v1)?;
    chart
        .configure_mesh()
        .x_desc(format!("{}, mm", name[u]))
        .y_desc(format!("{}, mm", name[v]))
        .draw()?;
    chart
        .draw_series(rows.clone().map(|k| {
            Circle::new(
                (rec.rows[k].p[u], rec.rows[k].p[v]),
                POINT_PX,
                MEASURED.filled(),
            )
        }))?
        .label("measured")
        .legend(|(x, y)| Circle::new((x, y), 4, MEASURED.filled()));
    chart
        .draw_series(LineSeries::new(
            rows.clone().map(|k| (before[k][u], before[k][v])),
            BEFORE.stroke_width(2),
        ))?
        .label("user model")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BEFORE.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(
            rows.map(|k| (after[k][u], after[k][v])),
            AFTER.stroke_width(2),
        ))?
        .label("fitted model")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], AFTER.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

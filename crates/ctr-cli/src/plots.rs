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
use ctr_formats::{AtomicFile, Recording};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::error::Error;
use std::ops::Range;
use std::path::Path;

/// A plot's chart: x and y in data units.
type Chart<'a, 'b> = ChartContext<'a, SVGBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Size of each plot, pixels.
const SIZE: (u32, u32) = (900, 600);
/// Radius of a measured point, pixels.
const POINT_PX: i32 = 2;
/// Radius of a point in the legend, pixels.
const LEGEND_POINT_PX: i32 = 4;
/// Width of a model's path, pixels.
const LINE_PX: u32 = 2;
/// Length of a path's line in the legend, pixels.
const LEGEND_LINE_PX: i32 = 20;
/// Caption font size, pixels.
const CAPTION_PX: u32 = 22;
/// Margin around the chart, pixels.
const MARGIN_PX: u32 = 12;
/// Height of the x axis' label area, pixels.
const X_LABELS_PX: u32 = 40;
/// Width of the y axis' label area, pixels.
const Y_LABELS_PX: u32 = 60;
/// Opacity of the legend's background.
const LEGEND_OPACITY: f64 = 0.8;
/// Colour of the user model.
const BEFORE: RGBColor = RGBColor(214, 39, 40);
/// Colour of the fitted model.
const AFTER: RGBColor = RGBColor(31, 119, 180);
/// Colour of the measured tips.
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

/// The two models drawn in every plot: their values (per row), colour and label.
fn models<'a, T>(before: &'a [T], after: &'a [T]) -> [(&'a [T], RGBColor, &'static str); 2] {
    [
        (before, BEFORE, "user model"),
        (after, AFTER, "fitted model"),
    ]
}

/// Writes one plot into `path` (atomically, as every output): the caption, the axes
/// over `x` and `y` with their descriptions, `draw`'s series, and the legend.
fn plot(
    path: &Path,
    caption: String,
    axes: (Range<f64>, &str),
    y: (Range<f64>, &str),
    draw: impl FnOnce(&mut Chart<'_, '_>) -> Result<(), Box<dyn Error>>,
) -> Result<(), Box<dyn Error>> {
    let mut svg = String::new();
    draw_plot(&mut svg, caption, axes, y, draw)?;
    // the caller names the path
    AtomicFile::write_file(path, svg.as_bytes()).map_err(|e| e.kind().to_string())?;
    Ok(())
}

fn draw_plot(
    svg: &mut String,
    caption: String,
    (x, x_desc): (Range<f64>, &str),
    (y, y_desc): (Range<f64>, &str),
    draw: impl FnOnce(&mut Chart<'_, '_>) -> Result<(), Box<dyn Error>>,
) -> Result<(), Box<dyn Error>> {
    let root = SVGBackend::with_string(svg, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", CAPTION_PX))
        .margin(MARGIN_PX)
        .x_label_area_size(X_LABELS_PX)
        .y_label_area_size(Y_LABELS_PX)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .draw()?;
    draw(&mut chart)?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(LEGEND_OPACITY))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

fn residual_plot(
    path: &Path,
    feature: &str,
    x: &[f64],
    before: &[f64],
    after: &[f64],
) -> Result<(), Box<dyn Error>> {
    let (x0, x1) = range(x.iter().copied());
    let (_, y1) = range(before.iter().chain(after).copied());
    let caption = format!("tip error against {feature}");
    plot(
        path,
        caption,
        (x0..x1, feature),
        (0.0..y1, "tip error, mm"),
        |chart| {
            for (size, color, label) in models(before, after) {
                chart
                    .draw_series(
                        x.iter()
                            .zip(size)
                            .map(|(x, y)| Circle::new((*x, *y), POINT_PX, color.filled())),
                    )?
                    .label(label)
                    .legend(move |(x, y)| Circle::new((x, y), LEGEND_POINT_PX, color.filled()));
            }
            Ok(())
        },
    )
}

fn path_plot(
    path: &Path,
    label: &str,
    rec: &Recording,
    rows: Range<usize>,
    before: &[[f64; 3]],
    after: &[[f64; 3]],
) -> Result<(), Box<dyn Error>> {
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
    let caption = format!("run {label}: measured and modelled tip");
    let (u_desc, v_desc) = (format!("{}, mm", name[u]), format!("{}, mm", name[v]));
    plot(
        path,
        caption,
        (u0..u1, &u_desc),
        (v0..v1, &v_desc),
        |chart| {
            chart
                .draw_series(rows.clone().map(|k| {
                    Circle::new(
                        (rec.rows[k].p[u], rec.rows[k].p[v]),
                        POINT_PX,
                        MEASURED.filled(),
                    )
                }))?
                .label("measured")
                .legend(|(x, y)| Circle::new((x, y), LEGEND_POINT_PX, MEASURED.filled()));
            for (tips, color, label) in models(before, after) {
                let style = color.stroke_width(LINE_PX);
                chart
                    .draw_series(LineSeries::new(
                        rows.clone().map(|k| (tips[k][u], tips[k][v])),
                        style,
                    ))?
                    .label(label)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + LEGEND_LINE_PX, y)], style)
                    });
            }
            Ok(())
        },
    )
}

//! The plots of a diagnosis, as SVG text (plotters; no fonts needed), drawn from the
//! report and the recording the report was made from:
//!
//! - `error-by-run.svg`: each run's RMS tip error under the user model and the fitted
//!   one;
//! - `residual-vs-<feature>.svg`: the tip error's size against the feature that located
//!   the user model's error best (a joint, an exposed length, a relative angle or time),
//!   for the user model and the fitted one;
//! - `run-<label>.svg`: per run, the measured tip path and both models' paths, projected
//!   on the plane of W in which the measured path spreads most.
//!
//! The models' tips are the row model's ([`predict`]) along the recorded commands; the
//! located feature is the report's (its first `grows_with`, `periodic` or `direction`
//! statement).

use crate::error::DiagnoseError;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_formats::Recording;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::error::Error;
use std::ops::Range;

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
/// Size of a bar's square in the legend, pixels.
const LEGEND_BAR_PX: i32 = 6;
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
/// Share of a run's slot of the error-by-run chart each of its two bars takes.
const BAR_WIDTH: f64 = 0.35;
/// Colour of the user model.
const BEFORE: RGBColor = RGBColor(214, 39, 40);
/// Colour of the fitted model.
const AFTER: RGBColor = RGBColor(31, 119, 180);
/// Colour of the measured tips.
const MEASURED: RGBColor = RGBColor(60, 60, 60);
/// The kinds of located statement whose feature the residual is plotted against.
const PLOTTED_KINDS: [&str; 3] = ["grows_with", "periodic", "direction"];

/// One plot: its file name (as `ctr-cli diagnose --plots` writes it), its caption and
/// its SVG text.
#[derive(Clone, Debug, PartialEq)]
pub struct Plot {
    /// File name, e.g. `run-feed.svg` (characters other than letters, digits and `-` of
    /// a label become `_`).
    pub file_name: String,
    /// What it shows, in words.
    pub caption: String,
    /// The SVG document.
    pub svg: String,
}

/// What the plots draw: per row the measured tip and both models' tips, the runs, and
/// the located feature's values.
#[derive(Clone, Debug)]
pub(crate) struct Traces {
    /// Each run's label and rows.
    pub runs: Vec<(String, Range<usize>)>,
    /// Measured tips, mm.
    pub measured: Vec<[f64; 3]>,
    /// The user model's tips, mm.
    pub before: Vec<[f64; 3]>,
    /// The fitted model's tips, mm.
    pub after: Vec<[f64; 3]>,
    /// The feature that located the error best and its value per row.
    pub feature: Option<(String, Vec<f64>)>,
}

/// A run's RMS tip error under both models.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RunError {
    /// The run's label.
    pub label: String,
    /// Its rows.
    pub rows: usize,
    /// RMS under the user model, mm.
    pub before_mm: f64,
    /// RMS under the fitted model, mm.
    pub after_mm: f64,
}

impl Traces {
    /// Simulates both models along the recording and finds the report's located
    /// feature (`report`: the report as JSON).
    pub fn new(
        report: &serde_json::Value,
        rec: &Recording,
        user: &ModelSpec,
        fitted: &ModelSpec,
    ) -> Result<Traces, DiagnoseError> {
        let runs: Vec<usize> = (0..rec.runs.len()).collect();
        let tips = |m: &ModelSpec| {
            predict(m, rec, &runs)
                .map(|p| p.p)
                .map_err(|e| DiagnoseError::Model(e.to_string()))
        };
        let feature = report["located"]
            .as_array()
            .into_iter()
            .flatten()
            .find(|s| PLOTTED_KINDS.contains(&s["kind"].as_str().unwrap_or_default()))
            .and_then(|s| s["feature"].as_str())
            .and_then(|name| {
                crate::locate::feature_values(rec, name).map(|v| (name.to_owned(), v))
            });
        Ok(Traces {
            runs: rec
                .runs
                .iter()
                .map(|r| (r.label.clone(), r.rows.clone()))
                .collect(),
            measured: rec.rows.iter().map(|r| r.p).collect(),
            before: tips(user)?,
            after: tips(fitted)?,
            feature,
        })
    }

    /// The size of every row's tip error under `tips`, mm.
    fn error_sizes(&self, tips: &[[f64; 3]]) -> Vec<f64> {
        let norm = |e: &[f64; 3]| (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
        self.measured
            .iter()
            .zip(tips)
            .map(|(m, p)| norm(&[p[0] - m[0], p[1] - m[1], p[2] - m[2]]))
            .collect()
    }

    /// Each run's RMS tip error under both models.
    pub fn run_errors(&self) -> Vec<RunError> {
        let rms = |sizes: &[f64]| {
            (sizes.iter().map(|e| e * e).sum::<f64>() / sizes.len().max(1) as f64).sqrt()
        };
        let (eb, ea) = (
            self.error_sizes(&self.before),
            self.error_sizes(&self.after),
        );
        self.runs
            .iter()
            .map(|(label, rows)| RunError {
                label: label.clone(),
                rows: rows.len(),
                before_mm: rms(&eb[rows.clone()]),
                after_mm: rms(&ea[rows.clone()]),
            })
            .collect()
    }

    /// Every plot: error by run, the residual against the located feature (when the
    /// report located the error on one), each run's paths.
    pub fn plots(&self) -> Result<Vec<Plot>, String> {
        let mut out = vec![error_by_run(&self.run_errors())?];
        if let Some((name, x)) = &self.feature {
            let (eb, ea) = (
                self.error_sizes(&self.before),
                self.error_sizes(&self.after),
            );
            out.push(residual_plot(name, x, &eb, &ea)?);
        }
        for (label, rows) in &self.runs {
            out.push(path_plot(self, label, rows.clone())?);
        }
        Ok(out)
    }
}

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

/// The two models drawn in every plot: their values (per row or run), colour and
/// label.
fn models<'a, T>(before: &'a [T], after: &'a [T]) -> [(&'a [T], RGBColor, &'static str); 2] {
    [
        (before, BEFORE, "user model"),
        (after, AFTER, "fitted model"),
    ]
}

/// An axis: its range, its description and, if not plain numbers, its tick labels.
struct Axis<'a> {
    range: Range<f64>,
    desc: &'a str,
    labels: Option<&'a dyn Fn(&f64) -> String>,
}

impl<'a> Axis<'a> {
    fn new(range: Range<f64>, desc: &'a str) -> Self {
        Axis {
            range,
            desc,
            labels: None,
        }
    }
}

/// One plot named `file_name`: the caption, the axes, `draw`'s series and the legend.
fn plot(
    file_name: String,
    caption: String,
    x: Axis<'_>,
    y: Axis<'_>,
    draw: impl FnOnce(&mut Chart<'_, '_>) -> Result<(), Box<dyn Error>>,
) -> Result<Plot, String> {
    let mut svg = String::new();
    let drawn = (|| -> Result<(), Box<dyn Error>> {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(&caption, ("sans-serif", CAPTION_PX))
            .margin(MARGIN_PX)
            .x_label_area_size(X_LABELS_PX)
            .y_label_area_size(Y_LABELS_PX)
            .build_cartesian_2d(x.range, y.range)?;
        let mut mesh = chart.configure_mesh();
        mesh.x_desc(x.desc).y_desc(y.desc);
        if let Some(f) = x.labels {
            mesh.x_label_formatter(f);
        }
        mesh.draw()?;
        draw(&mut chart)?;
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(LEGEND_OPACITY))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    })();
    drawn.map_err(|e| format!("{file_name}: {e}"))?;
    Ok(Plot {
        file_name,
        caption,
        svg,
    })
}

/// Grouped bars: each run's RMS error under both models, the runs at 0, 1, 2, ...
fn error_by_run(runs: &[RunError]) -> Result<Plot, String> {
    let (_, top) = range(runs.iter().flat_map(|r| [r.before_mm, r.after_mm]));
    let labels = |x: &f64| {
        let i = x.round();
        let near = (x - i).abs() < 1e-9 && i >= 0.0;
        near.then(|| runs.get(i as usize).map(|r| r.label.clone()))
            .flatten()
            .unwrap_or_default()
    };
    let x = Axis {
        range: -0.5..runs.len() as f64 - 0.5,
        desc: "run",
        labels: Some(&labels),
    };
    plot(
        "error-by-run.svg".into(),
        "RMS tip error by run".into(),
        x,
        Axis::new(0.0..top, "RMS tip error, mm"),
        |chart| {
            let (before, after): (Vec<f64>, Vec<f64>) =
                runs.iter().map(|r| (r.before_mm, r.after_mm)).unzip();
            for (k, (values, color, label)) in models(&before, &after).into_iter().enumerate() {
                // the user model's bar left of the run's tick, the fitted one's right
                let left = if k == 0 { -BAR_WIDTH } else { 0.0 };
                chart
                    .draw_series(values.iter().enumerate().map(|(i, v)| {
                        let x0 = i as f64 + left;
                        Rectangle::new([(x0, 0.0), (x0 + BAR_WIDTH, *v)], color.filled())
                    }))?
                    .label(label)
                    .legend(move |(x, y)| {
                        Rectangle::new(
                            [
                                (x - LEGEND_BAR_PX, y - LEGEND_BAR_PX),
                                (x + LEGEND_BAR_PX, y + LEGEND_BAR_PX),
                            ],
                            color.filled(),
                        )
                    });
            }
            Ok(())
        },
    )
}

fn residual_plot(feature: &str, x: &[f64], before: &[f64], after: &[f64]) -> Result<Plot, String> {
    let (x0, x1) = range(x.iter().copied());
    let (_, y1) = range(before.iter().chain(after).copied());
    plot(
        format!("residual-vs-{}.svg", file_safe(feature)),
        format!("tip error against {feature}"),
        Axis::new(x0..x1, feature),
        Axis::new(0.0..y1, "tip error, mm"),
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

fn path_plot(t: &Traces, label: &str, rows: Range<usize>) -> Result<Plot, String> {
    // the two axes of W along which the measured path spreads most
    let spread = |a: usize| {
        let (lo, hi) = range(t.measured[rows.clone()].iter().map(|p| p[a]));
        hi - lo
    };
    let mut axes = [0usize, 1, 2];
    axes.sort_by(|a, b| spread(*b).total_cmp(&spread(*a)));
    let (u, v) = (axes[0].min(axes[1]), axes[0].max(axes[1]));
    let name = ["x", "y", "z"];
    let all = rows
        .clone()
        .flat_map(|k| [t.measured[k], t.before[k], t.after[k]]);
    let (u0, u1) = range(all.clone().map(|p| p[u]));
    let (v0, v1) = range(all.map(|p| p[v]));
    let (u_desc, v_desc) = (format!("{}, mm", name[u]), format!("{}, mm", name[v]));
    plot(
        format!("run-{}.svg", file_safe(label)),
        format!("run {label}: measured and modelled tip"),
        Axis::new(u0..u1, &u_desc),
        Axis::new(v0..v1, &v_desc),
        |chart| {
            chart
                .draw_series(rows.clone().map(|k| {
                    Circle::new(
                        (t.measured[k][u], t.measured[k][v]),
                        POINT_PX,
                        MEASURED.filled(),
                    )
                }))?
                .label("measured")
                .legend(|(x, y)| Circle::new((x, y), LEGEND_POINT_PX, MEASURED.filled()));
            for (tips, color, label) in models(&t.before, &t.after) {
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

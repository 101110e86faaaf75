//! Rows near a snap: where a model, solved along each run of a recording row after row
//! (warm-started, as `ctr-cli fk` solves a joint file, so the branch followed is the
//! one the robot is on), is within the warning margin of a snap or on an unstable
//! branch. A snap in the data looks like a huge outlier; where the model says the robot
//! is about to snap, it is physics, not a tracker glitch.
//!
//! The margins are those the simulation of the recording already computed
//! ([`Prediction::margin`](ctr_analysis::simulate::Prediction::margin)): marking rows
//! costs no solve. Rows whose solve did not converge have no margin and are not marked.

use ctr_formats::Recording;
use serde::{Deserialize, Serialize};

/// Rows after a marked range that still count as near its snap (for the tracker
/// outliers): the row where a model that snaps one row before the robot has already
/// jumped, and its margin risen again.
pub const ROWS_AFTER_A_SNAP: usize = 1;

/// Ranges a sentence names before "and N more".
const RANGES_IN_WORDS: usize = 4;

/// A range of consecutive rows of one run whose stability margin is below a threshold.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MarginRange {
    /// The run's label.
    pub run: String,
    /// File lines of the range's first and last row (as the recording reader reports
    /// them: the header is line 1).
    pub lines: [usize; 2],
    /// Rows in the range.
    pub rows: usize,
    /// The smallest stability margin in the range (dimensionless: 1 far from a snap, 0
    /// at one, negative on an unstable branch).
    pub lowest_margin: f64,
    /// The file line of that smallest margin.
    pub lowest_line: usize,
}

/// The rows one model marks.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Marks {
    /// Ranges of rows whose margin is below the warning margin (rows on an unstable
    /// branch included), per run in file order.
    pub near_snap: Vec<MarginRange>,
    /// Ranges of rows whose margin is negative: the model is on an unstable branch
    /// there (each lies inside a `near_snap` range).
    pub unstable: Vec<MarginRange>,
}

/// The report's `stability`: the rows where the user's (nominal) or the fitted model is
/// near a snap.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stability {
    /// The warning margin: rows whose margin is below it are near a snap.
    pub warn_margin: f64,
    /// The user's model, solved along the recording.
    pub nominal: Marks,
    /// The fitted model, as simulated for `final`.
    pub fitted: Marks,
    /// File lines of the tracker outliers (`outlier_lines`) that lie in a `near_snap`
    /// range of either model or in the row right after one: a jump there is physics.
    pub outlier_lines_near_snap: Vec<usize>,
}

/// `warn_margin` checked: a finite number, not negative (the message says what is
/// wrong, without the option's name).
///
/// ```
/// assert_eq!(ctr_diagnosis::checked_warn_margin(0.3), Ok(0.3));
/// assert!(ctr_diagnosis::checked_warn_margin(-1.0).unwrap_err().starts_with("-1 is not"));
/// ```
pub fn checked_warn_margin(x: f64) -> Result<f64, String> {
    if x.is_finite() && x >= 0.0 {
        Ok(x)
    } else {
        Err(format!(
            "{x} is not a warning margin (a finite number >= 0: rows whose stability margin \
             is below it are marked near a snap; 0 marks only rows on an unstable branch)"
        ))
    }
}

impl Marks {
    /// The ranges of `rec`'s rows whose margin (`margin`, one per row, `NaN` for none)
    /// is below `warn_margin`, and those below zero.
    pub fn of(rec: &Recording, margin: &[f64], warn_margin: f64) -> Marks {
        Marks {
            near_snap: ranges(rec, margin, warn_margin),
            unstable: ranges(rec, margin, 0.0),
        }
    }

    /// Whether no row is marked.
    pub fn is_empty(&self) -> bool {
        self.near_snap.is_empty() && self.unstable.is_empty()
    }
}

/// Ranges of consecutive rows of a run with a margin below `below`.
fn ranges(rec: &Recording, margin: &[f64], below: f64) -> Vec<MarginRange> {
    let mut out = Vec::new();
    for run in &rec.runs {
        let mut open: Option<MarginRange> = None;
        for r in run.rows.clone() {
            let m = margin.get(r).copied().unwrap_or(f64::NAN);
            let line = rec.rows[r].line;
            // a NaN margin (a row not solved or not converged) is not a low one
            let low = m < below;
            if !low {
                out.extend(open.take());
                continue;
            }
            match &mut open {
                Some(range) => {
                    range.lines[1] = line;
                    range.rows += 1;
                    if m < range.lowest_margin {
                        range.lowest_margin = m;
                        range.lowest_line = line;
                    }
                }
                None => {
                    open = Some(MarginRange {
                        run: run.label.clone(),
                        lines: [line, line],
                        rows: 1,
                        lowest_margin: m,
                        lowest_line: line,
                    })
                }
            }
        }
        out.extend(open);
    }
    out
}

/// Whether each row is near a snap under a model whose margins are `margin`: below
/// `warn_margin`, or within [`ROWS_AFTER_A_SNAP`] rows after such a row of its run.
pub(crate) fn near_rows(rec: &Recording, margin: &[f64], warn_margin: f64) -> Vec<bool> {
    let mut near = vec![false; rec.rows.len()];
    for run in &rec.runs {
        let mut since_low = usize::MAX;
        for r in run.rows.clone() {
            let m = margin.get(r).copied().unwrap_or(f64::NAN);
            since_low = if m < warn_margin {
                0
            } else {
                since_low.saturating_add(1)
            };
            near[r] = since_low <= ROWS_AFTER_A_SNAP;
        }
    }
    near
}

impl Stability {
    /// The marks of both models (margins per row of the recording) and the outlier rows
    /// (indices, ascending) near a snap of either.
    pub(crate) fn new(
        rec: &Recording,
        warn_margin: f64,
        nominal: &[f64],
        fitted: &[f64],
        outliers: &[usize],
    ) -> Stability {
        let (a, b) = (
            near_rows(rec, nominal, warn_margin),
            near_rows(rec, fitted, warn_margin),
        );
        Stability {
            warn_margin,
            nominal: Marks::of(rec, nominal, warn_margin),
            fitted: Marks::of(rec, fitted, warn_margin),
            outlier_lines_near_snap: outliers
                .iter()
                .filter(|&&r| a[r] || b[r])
                .map(|&r| rec.rows[r].line)
                .collect(),
        }
    }

    /// The summary's line (`None` when no row is marked).
    pub fn words(&self) -> Option<String> {
        if self.fitted == self.nominal {
            near_snap_words(
                self.warn_margin,
                &[("the user's and the fitted model are", &self.fitted)],
            )
        } else {
            near_snap_words(
                self.warn_margin,
                &[
                    ("the fitted model is", &self.fitted),
                    ("the user's model is", &self.nominal),
                ],
            )
        }
    }
}

/// A margin in words, three significant digits: `0.245`, `0.0120`, `-0.00310`.
fn margin_words(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (2 - v.abs().log10().floor() as i32).clamp(0, 12) as usize;
    format!("{v:.digits$}")
}

/// One range in words: `lines 412-431 of run 'a' (lowest 0.0120)`.
fn range_words(r: &MarginRange) -> String {
    let lines = if r.lines[0] == r.lines[1] {
        format!("line {}", r.lines[0])
    } else {
        format!("lines {}-{}", r.lines[0], r.lines[1])
    };
    format!(
        "{lines} of run '{}' (lowest {})",
        r.run,
        margin_words(r.lowest_margin)
    )
}

fn list_words(ranges: &[MarginRange]) -> String {
    let mut parts: Vec<String> = ranges
        .iter()
        .take(RANGES_IN_WORDS)
        .map(range_words)
        .collect();
    if ranges.len() > RANGES_IN_WORDS {
        parts.push(format!("{} more ranges", ranges.len() - RANGES_IN_WORDS));
    }
    parts.join(", ")
}

/// One line saying where each model is near a snap, or `None` when none marks a row:
/// `Near a snap: the fitted model is within 0.05 of a snap at lines 412-431 of run 'a'
/// (lowest 0.0120): a jump in the data there is physics, not a tracker glitch.` Each
/// model is named with its verb (`"the fitted model is"`, `"a.toml is"`) and its marks.
pub fn near_snap_words(warn_margin: f64, models: &[(&str, &Marks)]) -> Option<String> {
    let parts: Vec<String> = models
        .iter()
        .filter(|(_, m)| !m.is_empty())
        .map(|(who, m)| {
            let mut s = format!(
                "{who} within {warn_margin} of a snap at {}",
                list_words(&m.near_snap)
            );
            if !m.unstable.is_empty() {
                s += &format!(
                    ", and on an unstable branch (margin below 0) at {}",
                    list_words(&m.unstable)
                );
            }
            s
        })
        .collect();
    (!parts.is_empty()).then(|| {
        format!(
            "Near a snap: {}: a jump in the data there is physics, not a tracker glitch.",
            parts.join("; ")
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ctr_formats::Recording;

    fn rec() -> Recording {
        let mut text = String::from("run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n");
        for k in 0..4 {
            text += &format!("a,{},0,0,0,0\n", 10 + k);
        }
        for k in 0..3 {
            text += &format!("b,{},0,0,0,0\n", 10 + k);
        }
        Recording::read(text.as_bytes(), "rec.csv", 1).unwrap()
    }

    #[test]
    fn ranges_stop_at_run_ends_and_at_rows_without_a_margin() {
        let rec = rec();
        // lines 2-5 run a, 6-8 run b
        let m = [0.5, 0.01, -0.02, 0.03, 0.04, f64::NAN, 0.01];
        let marks = Marks::of(&rec, &m, 0.05);
        let lines: Vec<([usize; 2], &str)> = marks
            .near_snap
            .iter()
            .map(|r| (r.lines, r.run.as_str()))
            .collect();
        assert_eq!(lines, [([3, 5], "a"), ([6, 6], "b"), ([8, 8], "b")]);
        assert_eq!(marks.near_snap[0].rows, 3);
        assert_eq!(marks.near_snap[0].lowest_margin, -0.02);
        assert_eq!(marks.near_snap[0].lowest_line, 4);
        assert_eq!(marks.unstable.len(), 1);
        assert_eq!(marks.unstable[0].lines, [4, 4]);
        assert_eq!(
            near_rows(&rec, &m, 0.05),
            [false, true, true, true, true, true, true]
        );
        let words = near_snap_words(0.05, &[("the fitted model is", &marks)]).unwrap();
        assert!(
            words.starts_with(
                "Near a snap: the fitted model is within 0.05 of a snap at lines 3-5 of \
                 run 'a' (lowest -0.0200), line 6 of run 'b'"
            ),
            "{words}"
        );
        assert!(words.contains("unstable branch (margin below 0) at line 4 of run 'a'"));
        assert_eq!(near_snap_words(0.05, &[("x", &Marks::default())]), None);
    }
}

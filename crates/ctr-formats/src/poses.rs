//! Static configuration sets (`data/FORMATS-EXTENSION.md`, "Static configuration
//! sets"): a recording whose rows are poses held, not a trajectory.
//!
//! A recording is a static set when it has a `pose` column, or the `n_frames,spread_mm`
//! pair, or both:
//! - `pose`: a label; contiguous rows with the same label are the frames of one held
//!   pose (the tracker's samples of it kept whole), and they must command the same
//!   joints. A label names one pose: it must not start again after other rows (a pose
//!   visited again gets a label of its own; the same joints are found repeated anyway).
//!   Without it every row is a pose of its own.
//! - `n_frames,spread_mm`: the row is the mean of `n_frames` tracker frames (an integer,
//!   at least 1) whose RMS distance from their mean is `spread_mm` (3-D, mm, the
//!   sample's `sqrt(sum |p_i - p_mean|^2 / (n - 1))`; 0 for one frame).
//!
//! The order of the poses in a run is the order they were visited (friction depends on
//! it); their times, if any, say nothing of the motion between them.

use crate::error::ErrorKind;
use std::collections::HashMap;
use std::ops::Range;

/// One held pose of a static set: its label and its rows (the frames kept).
#[derive(Clone, Debug, PartialEq)]
pub struct Pose {
    /// The label (the row's 1-based line when the file has no `pose` column).
    pub label: String,
    /// Its rows, as indices into `Recording::rows`: one, or its frames.
    pub rows: Range<usize>,
}

/// A row that is the mean of several tracker frames (`n_frames,spread_mm`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frames {
    /// Frames averaged (at least 1).
    pub n: u32,
    /// RMS distance of the frames from their mean, mm (3-D, sample).
    pub spread_mm: f64,
}

impl Frames {
    /// The frames' cell values checked: `n` a whole number at least 1, `spread_mm` at
    /// least 0 (0 for one frame).
    pub(crate) fn checked(n: f64, spread_mm: f64) -> Result<Self, ErrorKind> {
        let bad = |message: String| Err(ErrorKind::Csv { message });
        if n.fract() != 0.0 || !(1.0..=f64::from(u32::MAX)).contains(&n) {
            return bad(format!(
                "column n_frames: {n} is not a whole number of frames of at least 1"
            ));
        }
        if spread_mm < 0.0 {
            return bad(format!(
                "column spread_mm: {spread_mm} is negative; wanted the frames' RMS distance \
                 from their mean, mm (>= 0)"
            ));
        }
        Ok(Frames {
            n: n as u32,
            spread_mm,
        })
    }
}

/// The poses of a static set read so far.
#[derive(Default)]
pub(crate) struct PosesSoFar {
    pub(crate) poses: Vec<Pose>,
    /// Each label's pose, to refuse one that starts again.
    labels: HashMap<String, usize>,
}

impl PosesSoFar {
    /// Puts row `i` (of run `run`, commanding `q`, at `line`) in its pose: the pose of
    /// the row before when `label` is the same and the run too (then with the same
    /// joints as its first row), else a new one. `label` is `None` without a `pose`
    /// column (every row its own pose); `first_q` gives a pose's first row's joints.
    pub(crate) fn add(
        &mut self,
        label: Option<&str>,
        i: usize,
        line: usize,
        same_run: bool,
        q: &[f64],
        first_q: impl Fn(usize) -> Vec<f64>,
    ) -> Result<(), ErrorKind> {
        let Some(label) = label else {
            self.poses.push(Pose {
                label: line.to_string(),
                rows: i..i + 1,
            });
            return Ok(());
        };
        if let Some(pose) = self.poses.last_mut() {
            if pose.label == label && same_run {
                let first = first_q(pose.rows.start);
                if first != q {
                    return Err(ErrorKind::Csv {
                        message: format!(
                            "column pose: pose {label}'s frames command other joints than \
                             its first row's ({first:?} against {q:?}); the rows of one pose \
                             are frames of one held configuration"
                        ),
                    });
                }
                pose.rows.end = i + 1;
                return Ok(());
            }
        }
        if let Some(&earlier) = self.labels.get(label) {
            return Err(ErrorKind::Csv {
                message: format!(
                    "column pose: pose {label} starts again here after other rows (its frames \
                     are rows {} to {} of the data); a pose's frames are contiguous rows of \
                     one run: give a pose visited again a label of its own",
                    self.poses[earlier].rows.start + 1,
                    self.poses[earlier].rows.end
                ),
            });
        }
        self.labels.insert(label.to_owned(), self.poses.len());
        self.poses.push(Pose {
            label: label.to_owned(),
            rows: i..i + 1,
        });
        Ok(())
    }
}

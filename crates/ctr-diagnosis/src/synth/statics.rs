//! Generated static configuration sets (`ctr_formats::poses`): the calibration protocol
//! most labs use. Poses drawn at random over the joint space (feeds by increments,
//! rotations, uniform inside [`Ranges`]), held while the tracker takes
//! [`StaticSpec::frames`] frames of Gaussian noise; several sessions, each a run and each
//! its own world (a robot that changed between sessions: another precurvature, another
//! registration). The frames are written whole (one row each, a `pose` label) or
//! averaged (one row per pose, `n_frames,spread_mm`).
//!
//! ```
//! use ctr_analysis::model::ModelSpec;
//! use ctr_diagnosis::synth::{static_set, Ranges, StaticSpec};
//! let spec = ctr_formats::RobotSpec::from_toml_str(
//!     "[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\nlength_mm = 200.0\n\
//!      curved_length_mm = 80.0\ncurvature_radius_mm = 100.0\nyoungs_modulus_mpa = 58000.0\n\
//!      poisson_ratio = 0.33\n", "one.toml")?;
//! let ranges = Ranges { increments_mm: vec![[60.0, 150.0]], theta_deg: [-180.0, 180.0] };
//! let set = StaticSpec { poses: vec![30, 20], frames: 5, ..StaticSpec::default() };
//! let world = ModelSpec::from_spec(&spec);
//! let s = static_set(&[world.clone(), world], &ranges, &set)?;
//! assert_eq!(s.recording.rows.len(), 250);
//! assert_eq!(s.recording.poses.as_ref().map(Vec::len), Some(50));
//! assert_eq!(s.recording.runs.len(), 2);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use super::{Ranges, Synthetic, COMMAND_DECIMALS, DEFAULT_NOISE_SIGMA_MM};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::rng::Rng;
use ctr_analysis::simulate::{predict, SimError};
use ctr_formats::{Frames, Pose, RecordedRow, Recording, Run};

/// How a static set is drawn and measured (the worlds, one per session, are
/// [`static_set`]'s).
#[derive(Clone, Debug, PartialEq)]
pub struct StaticSpec {
    /// Seed of every random choice (poses, noise).
    pub seed: u64,
    /// Poses of each session, in order (a session is a run, `session-1`, ...).
    pub poses: Vec<usize>,
    /// Tracker frames per pose (at least 1).
    pub frames: usize,
    /// Whether each pose's frames are written averaged (`n_frames,spread_mm`) rather
    /// than whole (a row each, labelled by `pose`).
    pub averaged: bool,
    /// Tracker noise of one frame, standard deviation per axis, mm.
    pub noise_sigma_mm: f64,
    /// Whether every session runs the first session's poses again (a lab's pose list
    /// run on another day) rather than poses of its own.
    pub same_poses: bool,
    /// Name of the recording.
    pub file: String,
}

impl Default for StaticSpec {
    fn default() -> Self {
        StaticSpec {
            seed: 1,
            poses: vec![60],
            frames: 20,
            averaged: false,
            noise_sigma_mm: DEFAULT_NOISE_SIGMA_MM,
            same_poses: false,
            file: "static.csv".into(),
        }
    }
}

/// A static set of `worlds` (one per session of `spec.poses`, the robot in that
/// session) held at poses drawn inside `ranges`, measured as [`StaticSpec`] says.
/// `Synthetic::noise` holds each row's tracker error (of an averaged row, its frames'
/// mean).
///
/// # Panics
/// If `worlds` does not have one model per session, or `spec.frames` is 0.
pub fn static_set(
    worlds: &[ModelSpec],
    ranges: &Ranges,
    spec: &StaticSpec,
) -> Result<Synthetic, SimError> {
    assert_eq!(worlds.len(), spec.poses.len(), "one world per session");
    assert!(spec.frames >= 1, "at least one frame per pose");
    let n = worlds[0].robot.n_tubes();
    let mut rng = Rng::new(spec.seed);
    let (mut rows, mut runs, mut poses) = (Vec::new(), Vec::new(), Vec::new());
    let (mut clean, mut noise, mut failed) = (Vec::new(), Vec::new(), 0);
    let mut first: Vec<Vec<f64>> = Vec::new();
    for (k, (&count, world)) in spec.poses.iter().zip(worlds).enumerate() {
        let drawn: Vec<Vec<f64>> = if spec.same_poses && k > 0 {
            first.iter().cycle().take(count).cloned().collect()
        } else {
            (0..count).map(|_| pose(ranges, n, &mut rng)).collect()
        };
        if k == 0 {
            first.clone_from(&drawn);
        }
        // the session as the world sees it: each pose once, in the order visited
        let session = session_recording(n, &drawn);
        let pred = predict(world, &session, &[0])?;
        failed += pred.failed;
        let start = rows.len();
        for (j, q) in drawn.iter().enumerate() {
            let frames: Vec<[f64; 3]> = (0..spec.frames)
                .map(|_| std::array::from_fn(|_| spec.noise_sigma_mm * rng.normal()))
                .collect();
            let first = rows.len();
            let label = format!("s{}-p{}", k + 1, j + 1);
            let mut push = |e: [f64; 3], frames: Option<Frames>| {
                let p = pred.p[j];
                rows.push(RecordedRow {
                    line: rows.len() + 2,
                    t_s: rows.len() as f64,
                    run: k,
                    q: q.clone(),
                    p: [p[0] + e[0], p[1] + e[1], p[2] + e[2]],
                    quaternion: None,
                    tangent: None,
                    force_n: [0.0; 3],
                    frames,
                });
                clean.push(p);
                noise.push(e);
            };
            if spec.averaged {
                let m = spec.frames as f64;
                let mean: [f64; 3] =
                    std::array::from_fn(|a| frames.iter().map(|f| f[a]).sum::<f64>() / m);
                let sum2: f64 = frames
                    .iter()
                    .map(|f| (0..3).map(|a| (f[a] - mean[a]).powi(2)).sum::<f64>())
                    .sum();
                let spread_mm = if spec.frames > 1 {
                    (sum2 / (m - 1.0)).sqrt()
                } else {
                    0.0
                };
                push(
                    mean,
                    Some(Frames {
                        n: spec.frames as u32,
                        spread_mm,
                    }),
                );
            } else {
                frames.into_iter().for_each(|f| push(f, None));
            }
            poses.push(Pose {
                label,
                rows: first..rows.len(),
            });
        }
        runs.push(Run {
            label: format!("session-{}", k + 1),
            rows: start..rows.len(),
        });
    }
    Ok(Synthetic {
        recording: Recording {
            file: spec.file.clone(),
            n_tubes: n,
            rows,
            runs,
            has_time: false,
            has_force: false,
            poses: Some(poses),
            angular: None,
        },
        clean,
        noise,
        outlier_rows: Vec::new(),
        failed,
    })
}

/// A pose drawn uniformly inside `ranges` (feeds by their increments) for `n` tubes,
/// rounded as commands are.
fn pose(ranges: &Ranges, n: usize, rng: &mut Rng) -> Vec<f64> {
    let round = |v: f64| {
        let k = 10f64.powi(COMMAND_DECIMALS);
        (v * k).round() / k
    };
    let [lo, hi] = ranges.theta_deg;
    let mut s = 0.0;
    let mut q = Vec::with_capacity(2 * n);
    for [a, b] in ranges.increments_mm.iter().take(n) {
        s += a + (b - a) * rng.uniform();
        q.push(round(s));
        q.push(round(lo + (hi - lo) * rng.uniform()));
    }
    q
}

/// One run of the poses `drawn` of an `n`-tube robot, each once (what the world is
/// simulated on).
fn session_recording(n: usize, drawn: &[Vec<f64>]) -> Recording {
    let rows = drawn
        .iter()
        .enumerate()
        .map(|(j, q)| RecordedRow {
            line: j + 2,
            t_s: j as f64,
            run: 0,
            q: q.clone(),
            p: [0.0; 3],
            quaternion: None,
            tangent: None,
            force_n: [0.0; 3],
            frames: None,
        })
        .collect();
    Recording {
        file: "session".into(),
        n_tubes: n,
        rows,
        runs: vec![Run {
            label: "session".into(),
            rows: 0..drawn.len(),
        }],
        has_time: false,
        has_force: false,
        poses: None,
        angular: None,
    }
}

/// The static set's columns of `rec` for [`super::write_csv`]: its header names
/// (`pose` where a pose has several rows or a row no frames; `n_frames,spread_mm` where
/// every row has frames) and a row's cells.
pub(crate) struct StaticColumns {
    pose_of_row: Option<Vec<usize>>,
    frames: bool,
}

impl StaticColumns {
    /// `None` for a time series.
    pub(crate) fn of(rec: &Recording) -> Option<Self> {
        let poses = rec.poses.as_ref()?;
        let frames = rec.rows.iter().all(|r| r.frames.is_some());
        let labelled = !frames || poses.iter().any(|p| p.rows.len() > 1);
        let pose_of_row = labelled.then(|| {
            let mut of = vec![0; rec.rows.len()];
            for (j, p) in poses.iter().enumerate() {
                of[p.rows.clone()].iter_mut().for_each(|o| *o = j);
            }
            of
        });
        Some(StaticColumns {
            pose_of_row,
            frames,
        })
    }

    /// The header names.
    pub(crate) fn names(&self) -> Vec<String> {
        let mut out = Vec::new();
        if self.pose_of_row.is_some() {
            out.push("pose".to_owned());
        }
        if self.frames {
            out.extend(["n_frames".to_owned(), "spread_mm".to_owned()]);
        }
        out
    }

    /// Row `r`'s cells.
    pub(crate) fn cells(&self, rec: &Recording, r: usize) -> Vec<String> {
        let mut out = Vec::new();
        if let (Some(of), Some(poses)) = (&self.pose_of_row, &rec.poses) {
            out.push(poses[of[r]].label.clone());
        }
        if let (true, Some(f)) = (self.frames, rec.rows[r].frames) {
            out.push(f.n.to_string());
            out.push(ctr_formats::format_float(f.spread_mm));
        }
        out
    }
}

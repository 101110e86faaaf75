//! Synthetic recordings with concealed effects: the proof bench of the diagnosis.
//!
//! The world is one of the project's own models with effects switched on (a
//! [`ModelSpec`], run along the commands by [`simulate::predict`](ctr_analysis::simulate::predict)).
//! [`generate`] commands it through the seed paper's experiments ([`experiments`]):
//!
//! | run | what is commanded |
//! |---|---|
//! | `feed` | the innermost tube fed out over its increment range and back, the others at the centre of theirs, every rotation 0 |
//! | `feed-b` | the same with the innermost tube turned by [`SynthSpec::feed_b_rotation_deg`] |
//! | `rot-outer`, `rot-middle`, `rot-inner` | each tube in turn turned a full turn and back, the others at 0 (`rot-tube<i>` for four tubes, `rot` for one) |
//! | `scatter` | a random walk inside the ranges (feeds by increments, rotations) |
//!
//! Rows are [`SynthSpec::sample_period_s`] apart within a run, runs
//! [`SynthSpec::run_gap_s`] apart. The tracker adds Gaussian noise of
//! [`SynthSpec::noise_sigma_mm`] per axis and, on a few rows
//! ([`SynthSpec::outlier_fraction`]), a jump of [`SynthSpec::outlier_size_mm`] in a random
//! direction. With [`SynthSpec::angular`] it also measures the tip frame
//! (`qw,qx,qy,qz`) or the tip's tangent (`tx,ty,tz`), turned by a Gaussian rotation of
//! [`SynthSpec::angular_noise_sigma_deg`] per component (a tangent's in the plane normal
//! to it), drawn after everything else. Everything random comes from one seeded
//! generator ([`Rng`]): the same inputs give the same recording bit for bit.
//! [`write_csv`] writes the result as the contract's recording
//! (`t_s,run,s1_mm,theta1_deg,...,x_mm,y_mm,z_mm`) for `ctr-cli diagnose`.
//!
//! ```
//! use ctr_formats::{Effects, Latency, RobotSpec};
//! use ctr_analysis::model::ModelSpec;
//! use ctr_diagnosis::synth::{generate, write_csv, Ranges, SynthSpec};
//! let spec = RobotSpec::from_toml_str(r#"
//! [[tube]]
//! outer_diameter_mm = 1.8
//! inner_diameter_mm = 1.5
//! length_mm = 180.0
//! curved_length_mm = 60.0
//! curvature_radius_mm = 200.0
//! youngs_modulus_mpa = 58000.0
//! poisson_ratio = 0.33
//! [[tube]]
//! outer_diameter_mm = 1.2
//! inner_diameter_mm = 0.9
//! length_mm = 260.0
//! curved_length_mm = 90.0
//! curvature_radius_mm = 100.0
//! youngs_modulus_mpa = 58000.0
//! poisson_ratio = 0.33
//! "#, "nitinol2.toml")?;
//! let mut world = ModelSpec::from_spec(&spec);
//! world.effects = Effects { latency: Some(Latency { tau_s: 0.4 }), ..Default::default() };
//! let ranges = Ranges { increments_mm: vec![[10.0, 60.0], [10.0, 80.0]], theta_deg: [-180.0, 180.0] };
//! let synth = SynthSpec { walk_rows: 100, rotation_step_deg: 10.0, ..SynthSpec::default() };
//! let out = generate(&world, &ranges, &synth)?;
//! let labels: Vec<&str> = out.recording.runs.iter().map(|r| r.label.as_str()).collect();
//! assert_eq!(labels, ["feed", "feed-b", "rot-outer", "rot-inner", "scatter"]);
//! assert_eq!(out.failed, 0);
//! // the noise actually added is close to sqrt(3) sigma
//! assert!((out.noise_floor_rms_mm() / (3f64.sqrt() * synth.noise_sigma_mm) - 1.0).abs() < 0.1);
//! let mut csv = Vec::new();
//! write_csv(&out.recording, &mut csv)?;
//! let text = String::from_utf8(csv)?;
//! assert!(text.starts_with("t_s,run,s1_mm,theta1_deg,s2_mm,theta2_deg,x_mm,y_mm,z_mm\n0,feed,"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub(crate) mod reframe;
pub(crate) mod statics;
pub(crate) mod unmodelled;

pub use crate::synth::reframe::{
    Recovered, Reframe, Reframed, ACCOUNT_TOLERANCE, DRAW_GLITCH_MM, DRAW_GLITCH_SHARE,
    DRAW_MAX_SHIFT_MM, DRAW_MAX_TURN_DEG, DRAW_MAX_ZERO_DEG, DRAW_MAX_ZERO_MM, DRAW_SHIFT_S,
    FRAME_TOLERANCE, SHIFT_TOLERANCE_S, ZERO_TOLERANCE,
};
pub use crate::synth::statics::{static_set, StaticSpec};
pub use crate::synth::unmodelled::{Unmodelled, WANDER_COMPONENTS, WANDER_PERIOD_SPAN};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::rng::Rng;
use ctr_analysis::simulate::{predict, Prediction, SimError};
use ctr_formats::joint_columns;
use ctr_formats::{format_float, AngularColumns, RecordedRow, Recording, Run};
use std::io::{self, Write};

/// Tracker noise of the shared recordings, standard deviation per axis, mm.
pub const DEFAULT_NOISE_SIGMA_MM: f64 = 0.2;
/// Time between two samples of a run, s (that of the shared recordings).
pub const DEFAULT_SAMPLE_PERIOD_S: f64 = 0.5;
/// Pause between two runs, s.
pub const DEFAULT_RUN_GAP_S: f64 = 5.0;
/// Samples per leg (out, or back) of a feed run.
pub const DEFAULT_FEED_STEPS: usize = 50;
/// Part of the innermost tube's increment range left out at each end of a feed run.
pub const DEFAULT_FEED_MARGIN_FRACTION: f64 = 0.1;
/// Rotation of the innermost tube during the `feed-b` run, degrees.
pub const DEFAULT_FEED_B_ROTATION_DEG: f64 = 120.0;
/// Rotation between two samples of a rotation run, degrees.
pub const DEFAULT_ROTATION_STEP_DEG: f64 = 3.0;
/// Rows of the random walk.
pub const DEFAULT_WALK_ROWS: usize = 300;
/// Standard deviation of a random-walk step of each feed increment, mm.
pub const DEFAULT_WALK_FEED_STEP_MM: f64 = 3.0;
/// Standard deviation of a random-walk step of each rotation, degrees.
pub const DEFAULT_WALK_ROTATION_STEP_DEG: f64 = 12.0;
/// Noise of a measured orientation or tangent, standard deviation per angular
/// component, degrees (an electromagnetic tracker's order).
pub const DEFAULT_ANGULAR_NOISE_SIGMA_DEG: f64 = 0.3;
/// Size of an outlier's jump, mm.
pub const DEFAULT_OUTLIER_SIZE_MM: f64 = 5.0;
/// One full turn, degrees.
const FULL_TURN_DEG: f64 = 360.0;
/// Decimals of the commanded joints (mm or degrees): commands are rounded to them, as
/// an actuator's are (and as the shared recordings write them).
pub const COMMAND_DECIMALS: i32 = 4;

/// Joint ranges the experiments stay inside, as `tests/data/shared/manifest.json`'s
/// `valid_ranges`: each tube's feed increment `s_i - s_{i-1}` (with `s_0 = 0`), mm, and
/// the rotations, degrees.
///
/// ```
/// let manifest = r#"{"robots": {"nitinol2": {"valid_ranges": {
///     "increments": [[10.0, 60.0], [10.0, 80.0]], "theta_deg": [-180.0, 180.0]}}}}"#;
/// let r = ctr_diagnosis::synth::Ranges::from_manifest(manifest, "nitinol2")?;
/// assert_eq!(r.increments_mm, [[10.0, 60.0], [10.0, 80.0]]);
/// assert_eq!(r.theta_deg, [-180.0, 180.0]);
/// # Ok::<(), String>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Ranges {
    /// `[min, max]` of each tube's feed increment, tube 1 first, mm.
    pub increments_mm: Vec<[f64; 2]>,
    /// `[min, max]` of every rotation, degrees.
    pub theta_deg: [f64; 2],
}

impl Ranges {
    /// The `valid_ranges` of `robot` in the text of a manifest like
    /// `tests/data/shared/manifest.json` (`robots.<robot>.valid_ranges.{increments, theta_deg}`).
    pub fn from_manifest(manifest_json: &str, robot: &str) -> Result<Ranges, String> {
        let v: serde_json::Value =
            serde_json::from_str(manifest_json).map_err(|e| format!("manifest: {e}"))?;
        let r = &v["robots"][robot]["valid_ranges"];
        let pair = |x: &serde_json::Value| -> Option<[f64; 2]> {
            let a = x.as_array()?;
            match a.as_slice() {
                [lo, hi] => Some([lo.as_f64()?, hi.as_f64()?]),
                _ => None,
            }
        };
        let increments_mm = r["increments"]
            .as_array()
            .and_then(|a| a.iter().map(pair).collect::<Option<Vec<_>>>())
            .ok_or_else(|| {
                format!(
                    "manifest: robots.{robot}.valid_ranges.increments: wanted [[min, max], ...]"
                )
            })?;
        let theta_deg = pair(&r["theta_deg"]).ok_or_else(|| {
            format!("manifest: robots.{robot}.valid_ranges.theta_deg: wanted [min, max]")
        })?;
        Ok(Ranges {
            increments_mm,
            theta_deg,
        })
    }

    /// The centre of every increment range, tube 1 first, mm.
    fn centre_increments(&self) -> Vec<f64> {
        self.increments_mm
            .iter()
            .map(|[lo, hi]| 0.5 * (lo + hi))
            .collect()
    }
}

/// How a synthetic recording is sampled and measured (the world is [`generate`]'s
/// `world`).
///
/// ```
/// let s = ctr_diagnosis::synth::SynthSpec { seed: 7, ..Default::default() };
/// assert_eq!(s.noise_sigma_mm, 0.2);
/// assert_eq!(s.outlier_fraction, 0.0);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct SynthSpec {
    /// Seed of every random choice (walk, noise, outliers).
    pub seed: u64,
    /// Tracker noise, standard deviation per axis, mm.
    pub noise_sigma_mm: f64,
    /// Fraction of rows (0 to 1) whose measurement jumps by [`Self::outlier_size_mm`].
    pub outlier_fraction: f64,
    /// Length of an outlier's jump (on top of the noise), mm, in a random direction.
    pub outlier_size_mm: f64,
    /// Time between two samples of a run, s.
    pub sample_period_s: f64,
    /// Pause between two runs, s.
    pub run_gap_s: f64,
    /// Samples per leg (out, or back) of a feed run (a run has `2 feed_steps + 1` rows).
    pub feed_steps: usize,
    /// Part of the innermost tube's increment range left out at each end of a feed run.
    pub feed_margin_fraction: f64,
    /// Rotation of the innermost tube during `feed-b`, degrees.
    pub feed_b_rotation_deg: f64,
    /// Rotation between two samples of a rotation run, degrees.
    pub rotation_step_deg: f64,
    /// Rows of the random walk (`scatter`); 0 leaves it out.
    pub walk_rows: usize,
    /// Standard deviation of a walk step of each feed increment, mm.
    pub walk_feed_step_mm: f64,
    /// Standard deviation of a walk step of each rotation, degrees.
    pub walk_rotation_step_deg: f64,
    /// Name of the recording (its `file`, used in messages).
    pub file: String,
    /// Effects outside the contract's vocabulary acting in the world (none by default):
    /// what a real robot holds beyond any model's effects.
    pub unmodelled: Vec<Unmodelled>,
    /// The angular columns the tracker measures besides the tip (none by default).
    pub angular: Option<AngularColumns>,
    /// Their noise, standard deviation per angular component, degrees.
    pub angular_noise_sigma_deg: f64,
}

impl Default for SynthSpec {
    fn default() -> Self {
        SynthSpec {
            seed: 1,
            noise_sigma_mm: DEFAULT_NOISE_SIGMA_MM,
            outlier_fraction: 0.0,
            outlier_size_mm: DEFAULT_OUTLIER_SIZE_MM,
            sample_period_s: DEFAULT_SAMPLE_PERIOD_S,
            run_gap_s: DEFAULT_RUN_GAP_S,
            feed_steps: DEFAULT_FEED_STEPS,
            feed_margin_fraction: DEFAULT_FEED_MARGIN_FRACTION,
            feed_b_rotation_deg: DEFAULT_FEED_B_ROTATION_DEG,
            rotation_step_deg: DEFAULT_ROTATION_STEP_DEG,
            walk_rows: DEFAULT_WALK_ROWS,
            walk_feed_step_mm: DEFAULT_WALK_FEED_STEP_MM,
            walk_rotation_step_deg: DEFAULT_WALK_ROTATION_STEP_DEG,
            file: "synthetic.csv".into(),
            unmodelled: Vec::new(),
            angular: None,
            angular_noise_sigma_deg: DEFAULT_ANGULAR_NOISE_SIGMA_DEG,
        }
    }
}

/// A generated recording and what was concealed in its measurements.
#[derive(Clone, Debug, PartialEq)]
pub struct Synthetic {
    /// The recording: commanded joints and measured tips (noise and outliers included).
    pub recording: Recording,
    /// What a perfect tracker would have measured (the world's prediction), per row, mm.
    pub clean: Vec<[f64; 3]>,
    /// What the tracker added to each row (noise, plus the jump on outlier rows), mm.
    pub noise: Vec<[f64; 3]>,
    /// Rows (indices into the recording's rows) with an outlier jump, ascending.
    pub outlier_rows: Vec<usize>,
    /// Rows whose world solve did not converge (their tip is the solver's last iterate).
    pub failed: usize,
}

impl Synthetic {
    /// RMS length of the noise actually added over the rows without an outlier, mm:
    /// the error the world's own model would leave.
    pub fn noise_floor_rms_mm(&self) -> f64 {
        let inlier: Vec<bool> = (0..self.noise.len())
            .map(|r| self.outlier_rows.binary_search(&r).is_err())
            .collect();
        self.noise_rms_mm(&inlier)
    }

    /// RMS length of the noise actually added (outlier jumps included) over the rows
    /// where `mask` is true, mm (`NaN` for none).
    ///
    /// # Panics
    /// If `mask` is shorter than the recording.
    pub fn noise_rms_mm(&self, mask: &[bool]) -> f64 {
        let (sum, n) = self
            .noise
            .iter()
            .zip(&mask[..self.noise.len()])
            .filter(|(_, m)| **m)
            .fold((0.0, 0usize), |(s, n), (v, _)| (s + norm2(v), n + 1));
        (sum / n as f64).sqrt()
    }
}

fn norm2(v: &[f64; 3]) -> f64 {
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
}

/// One commanded run: a label and its joint rows (file order and units:
/// `s1_mm, theta1_deg, ...`).
#[derive(Clone, Debug, PartialEq)]
pub struct CommandedRun {
    /// The run's label.
    pub label: String,
    /// Commanded joints per sample.
    pub joints: Vec<Vec<f64>>,
}

/// Labels of the rotation runs for `n` tubes, tube 1 first.
fn rotation_labels(n: usize) -> Vec<String> {
    match n {
        1 => vec!["rot".into()],
        2 => vec!["rot-outer".into(), "rot-inner".into()],
        3 => vec!["rot-outer".into(), "rot-middle".into(), "rot-inner".into()],
        _ => (1..=n).map(|i| format!("rot-tube{i}")).collect(),
    }
}

/// Joints (file order) from feed increments and rotations, rounded to
/// [`COMMAND_DECIMALS`] decimals.
fn joints(increments: &[f64], theta: &[f64]) -> Vec<f64> {
    let scale = 10f64.powi(COMMAND_DECIMALS);
    let round = |v: f64| (v * scale).round() / scale;
    let mut s = 0.0;
    increments
        .iter()
        .zip(theta)
        .flat_map(|(inc, th)| {
            s += inc;
            [round(s), round(*th)]
        })
        .collect()
}

/// Reflects `x` into `[lo, hi]` (a random walk bouncing off the range's ends).
fn reflect(mut x: f64, lo: f64, hi: f64) -> f64 {
    if hi <= lo {
        return lo;
    }
    for _ in 0..4 {
        if x > hi {
            x = 2.0 * hi - x;
        } else if x < lo {
            x = 2.0 * lo - x;
        } else {
            return x;
        }
    }
    x.clamp(lo, hi)
}

/// Out from `a` to `b` in `steps` equal steps and back: `2 steps + 1` values.
fn out_and_back(a: f64, b: f64, steps: usize) -> Vec<f64> {
    let steps = steps.max(1);
    let leg: Vec<f64> = (0..=steps)
        .map(|k| a + (b - a) * k as f64 / steps as f64)
        .collect();
    leg.iter()
        .chain(leg.iter().rev().skip(1))
        .copied()
        .collect()
}

/// The commanded runs of the seed paper's experiments for a robot of
/// `ranges.increments_mm.len()` tubes, plus the random walk (see the module's table).
/// The random walk draws from `rng`.
///
/// ```
/// use ctr_analysis::rng::Rng;
/// use ctr_diagnosis::synth::{experiments, Ranges, SynthSpec};
/// let ranges = Ranges { increments_mm: vec![[10.0, 50.0]; 3], theta_deg: [-180.0, 180.0] };
/// let runs = experiments(&ranges, &SynthSpec::default(), &mut Rng::new(1));
/// let labels: Vec<&str> = runs.iter().map(|r| r.label.as_str()).collect();
/// assert_eq!(labels, ["feed", "feed-b", "rot-outer", "rot-middle", "rot-inner", "scatter"]);
/// // a full turn and back in 3 degree steps
/// assert_eq!(runs[3].joints.len(), 241);
/// assert_eq!(runs[3].joints[120], [30.0, 0.0, 60.0, 360.0, 90.0, 0.0]);
/// ```
pub fn experiments(ranges: &Ranges, spec: &SynthSpec, rng: &mut Rng) -> Vec<CommandedRun> {
    let n = ranges.increments_mm.len();
    let centre = ranges.centre_increments();
    let zero = vec![0.0; n];
    let mut runs = Vec::new();
    if n == 0 {
        return runs;
    }

    // feed out and back: the innermost tube over its increment range
    let [lo, hi] = ranges.increments_mm[n - 1];
    let margin = spec.feed_margin_fraction * (hi - lo);
    let feeds = out_and_back(lo + margin, hi - margin, spec.feed_steps);
    for (label, turn) in [("feed", 0.0), ("feed-b", spec.feed_b_rotation_deg)] {
        let mut theta = zero.clone();
        theta[n - 1] = turn;
        let joints = feeds
            .iter()
            .map(|&f| {
                let mut inc = centre.clone();
                inc[n - 1] = f;
                joints(&inc, &theta)
            })
            .collect();
        runs.push(CommandedRun {
            label: label.into(),
            joints,
        });
    }

    // each tube a full turn and back (the whole theta range when it is narrower)
    let [tlo, thi] = ranges.theta_deg;
    let (start, end) = if thi - tlo >= FULL_TURN_DEG {
        (0.0, FULL_TURN_DEG)
    } else {
        (tlo, thi)
    };
    let steps = ((end - start).abs() / spec.rotation_step_deg.max(f64::EPSILON)).round() as usize;
    let angles = out_and_back(start, end, steps);
    for (i, label) in rotation_labels(n).into_iter().enumerate() {
        let joints = angles
            .iter()
            .map(|&a| {
                let mut theta = zero.clone();
                theta[i] = a;
                joints(&centre, &theta)
            })
            .collect();
        runs.push(CommandedRun { label, joints });
    }

    // a random walk inside the ranges, from the centre
    if spec.walk_rows > 0 {
        let mut inc = centre.clone();
        let mut theta = vec![0.5 * (tlo + thi); n];
        let mut rows = Vec::with_capacity(spec.walk_rows);
        rows.push(joints(&inc, &theta));
        while rows.len() < spec.walk_rows {
            for i in 0..n {
                let [lo, hi] = ranges.increments_mm[i];
                inc[i] = reflect(inc[i] + spec.walk_feed_step_mm * rng.normal(), lo, hi);
                theta[i] = reflect(
                    theta[i] + spec.walk_rotation_step_deg * rng.normal(),
                    tlo,
                    thi,
                );
            }
            rows.push(joints(&inc, &theta));
        }
        runs.push(CommandedRun {
            label: "scatter".into(),
            joints: rows,
        });
    }
    runs
}

/// Generates a recording of `world` (a model with its effects: the concealed physics)
/// commanded through [`experiments`] inside `ranges`, measured by a noisy tracker with
/// occasional outliers (see the module's documentation and its example).
///
/// The measured tip of a row is the world's prediction (time effects along each run,
/// sensor offset and registration included) plus noise. Fails when the world cannot be
/// simulated (for example joint offsets that break the feed order).
///
/// # Panics
/// If `ranges` does not give one increment range per tube of `world`.
pub fn generate(
    world: &ModelSpec,
    ranges: &Ranges,
    spec: &SynthSpec,
) -> Result<Synthetic, SimError> {
    let n = world.robot.n_tubes();
    assert_eq!(
        ranges.increments_mm.len(),
        n,
        "one increment range per tube of the world's robot"
    );
    let mut rng = Rng::new(spec.seed);
    let commanded = experiments(ranges, spec, &mut rng);
    measure(world, &commanded, spec, &mut rng)
}

/// Records `world` commanded through the runs `commanded` (a run a diagnosis suggested,
/// say), measured as [`generate`] measures: noise and outliers drawn from `spec.seed`.
///
/// ```
/// use ctr_analysis::model::ModelSpec;
/// use ctr_diagnosis::synth::{record, CommandedRun, SynthSpec};
/// let spec = ctr_formats::RobotSpec::from_toml_str(
///     "[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\nlength_mm = 200.0\n\
///      curved_length_mm = 80.0\ncurvature_radius_mm = 100.0\nyoungs_modulus_mpa = 58000.0\n\
///      poisson_ratio = 0.33\n", "one.toml")?;
/// let run = CommandedRun { label: "turn".into(), joints: vec![vec![100.0, 0.0], vec![100.0, 10.0]] };
/// let rec = record(&ModelSpec::from_spec(&spec), &[run], &SynthSpec::default())?;
/// assert_eq!(rec.recording.rows.len(), 2);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn record(
    world: &ModelSpec,
    commanded: &[CommandedRun],
    spec: &SynthSpec,
) -> Result<Synthetic, SimError> {
    measure(world, commanded, spec, &mut Rng::new(spec.seed))
}

/// Records `world` commanded through the runs `commanded` as a tracker measures it:
/// the rows as commanded, the world's tips at the actual joints, the tracker's noise
/// and outliers added, and the orientation where the tracker measures one.
fn measure(
    world: &ModelSpec,
    commanded: &[CommandedRun],
    spec: &SynthSpec,
    rng: &mut Rng,
) -> Result<Synthetic, SimError> {
    let mut recording = as_commanded(world.robot.n_tubes(), commanded, spec);
    let pred = world_tips(world, &mut recording, spec)?;
    let (noise, outlier_rows) = tracker_noise(spec, rng, recording.rows.len());
    for ((row, p), e) in recording.rows.iter_mut().zip(&pred.p).zip(&noise) {
        row.p = [p[0] + e[0], p[1] + e[1], p[2] + e[2]];
    }
    if let Some(columns) = spec.angular {
        let sigma = spec.angular_noise_sigma_deg.to_radians();
        for (row, q) in recording.rows.iter_mut().zip(&pred.q) {
            crate::start::angular::measure(row, columns, q, sigma, rng);
        }
    }
    Ok(Synthetic {
        recording,
        clean: pred.p,
        noise,
        outlier_rows,
        failed: pred.failed,
    })
}

/// The recording of the runs `commanded` of a robot with `n` tubes as commanded: one
/// row per joint vector every `spec.sample_period_s`, the runs `spec.run_gap_s` apart,
/// tips still zero.
fn as_commanded(n: usize, commanded: &[CommandedRun], spec: &SynthSpec) -> Recording {
    let mut rows = Vec::new();
    let mut runs = Vec::new();
    let mut t0 = 0.0;
    for (k, run) in commanded.iter().enumerate() {
        let start = rows.len();
        let mut t = t0;
        for (j, q) in run.joints.iter().enumerate() {
            t = t0 + j as f64 * spec.sample_period_s;
            rows.push(RecordedRow {
                line: rows.len() + 2,
                t_s: t,
                run: k,
                q: q.clone(),
                p: [0.0; 3],
                quaternion: None,
                tangent: None,
                force_n: [0.0; 3],
                frames: None,
            });
        }
        runs.push(Run {
            label: run.label.clone(),
            rows: start..rows.len(),
        });
        t0 = t + spec.run_gap_s;
    }
    Recording {
        file: spec.file.clone(),
        n_tubes: n,
        rows,
        runs,
        has_time: true,
        has_force: false,
        poses: None,
        angular: None,
    }
}

/// The world's tips (and frames) on every row of `recording`, what a perfect tracker
/// measures: the world moves with the actual joints (the unmodelled actuation applied),
/// the recording keeps the commanded ones; the unmodelled measurement effects applied
/// to the tips.
fn world_tips(
    world: &ModelSpec,
    recording: &mut Recording,
    spec: &SynthSpec,
) -> Result<Prediction, SimError> {
    let all: Vec<usize> = (0..recording.runs.len()).collect();
    let commanded_q: Vec<Vec<f64>> = recording.rows.iter().map(|r| r.q.clone()).collect();
    for row in &mut recording.rows {
        for u in &spec.unmodelled {
            u.actuate(&mut row.q, row.t_s);
        }
    }
    let mut pred = predict(world, recording, &all)?;
    for (row, q) in recording.rows.iter_mut().zip(commanded_q) {
        row.q = q;
    }
    for (p, row) in pred.p.iter_mut().zip(&recording.rows) {
        for u in &spec.unmodelled {
            u.measure(p, row.t_s);
        }
    }
    Ok(pred)
}

/// The tracker's error on each of `total` rows: normal noise of `spec.noise_sigma_mm`
/// per component, plus a jump of `spec.outlier_size_mm` in a random direction on a
/// share `spec.outlier_fraction` of the rows drawn at random (returned, ascending).
fn tracker_noise(spec: &SynthSpec, rng: &mut Rng, total: usize) -> (Vec<[f64; 3]>, Vec<usize>) {
    let mut noise: Vec<[f64; 3]> = (0..total)
        .map(|_| {
            [
                spec.noise_sigma_mm * rng.normal(),
                spec.noise_sigma_mm * rng.normal(),
                spec.noise_sigma_mm * rng.normal(),
            ]
        })
        .collect();
    let n_outliers =
        ((spec.outlier_fraction.clamp(0.0, 1.0) * total as f64).round() as usize).min(total);
    let mut outlier_rows = Vec::with_capacity(n_outliers);
    while outlier_rows.len() < n_outliers {
        let r = rng.below(total);
        if !outlier_rows.contains(&r) {
            outlier_rows.push(r);
        }
    }
    outlier_rows.sort_unstable();
    for &r in &outlier_rows {
        let d = rng.unit_vector();
        for a in 0..3 {
            noise[r][a] += spec.outlier_size_mm * d[a];
        }
    }
    (noise, outlier_rows)
}

/// Writes a recording as the contract's recording CSV: `t_s,run` (`run` alone without
/// times), a static set's `pose` and `n_frames,spread_mm` ([`statics`]), the joint
/// columns, `x_mm,y_mm,z_mm`, then `qw,qx,qy,qz` when every row has an orientation,
/// `tx,ty,tz` when every row has a tangent and `fx_n,fy_n,fz_n` when the recording has
/// forces. Numbers in Rust's shortest round-trip form ([`format_float`]):
/// [`Recording::read`] gives the same rows back.
///
/// ```
/// use ctr_formats::Recording;
/// let text = "t_s,run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n0,\"a, 1\",10,0,0,0,10\n0.5,\"a, 1\",11,0,0,0.1,11\n";
/// let rec = Recording::read(text.as_bytes(), "rec.csv", 1)?;
/// let mut out = Vec::new();
/// ctr_diagnosis::synth::write_csv(&rec, &mut out)?;
/// assert_eq!(String::from_utf8(out)?, text);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_csv(rec: &Recording, out: impl Write) -> io::Result<()> {
    let quaternions = !rec.rows.is_empty() && rec.rows.iter().all(|r| r.quaternion.is_some());
    let mut header = Vec::new();
    if rec.has_time {
        header.push("t_s".to_owned());
    }
    header.push("run".to_owned());
    let statics = statics::StaticColumns::of(rec);
    header.extend(statics.iter().flat_map(statics::StaticColumns::names));
    header.extend(joint_columns(rec.n_tubes));
    header.extend(["x_mm", "y_mm", "z_mm"].map(String::from));
    if quaternions {
        header.extend(["qw", "qx", "qy", "qz"].map(String::from));
    }
    let tangents = !rec.rows.is_empty() && rec.rows.iter().all(|r| r.tangent.is_some());
    if tangents {
        header.extend(["tx", "ty", "tz"].map(String::from));
    }
    if rec.has_force {
        header.extend(["fx_n", "fy_n", "fz_n"].map(String::from));
    }
    let mut w = csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(out);
    w.write_record(&header)?;
    let mut record: Vec<String> = Vec::with_capacity(header.len());
    for (r, row) in rec.rows.iter().enumerate() {
        record.clear();
        if rec.has_time {
            record.push(format_float(row.t_s));
        }
        record.push(rec.runs[row.run].label.clone());
        record.extend(statics.iter().flat_map(|s| s.cells(rec, r)));
        record.extend(row.q.iter().map(|&v| format_float(v)));
        record.extend(row.p.iter().map(|&v| format_float(v)));
        if let (true, Some(q)) = (quaternions, row.quaternion) {
            record.extend(q.iter().map(|&v| format_float(v)));
        }
        if let (true, Some(t)) = (tangents, row.tangent) {
            record.extend(t.iter().map(|&v| format_float(v)));
        }
        if rec.has_force {
            record.extend(row.force_n.iter().map(|&v| format_float(v)));
        }
        w.write_record(&record)?;
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect_stays_inside() {
        assert_eq!(reflect(12.0, 0.0, 10.0), 8.0);
        assert_eq!(reflect(-3.0, 0.0, 10.0), 3.0);
        assert_eq!(reflect(5.0, 0.0, 10.0), 5.0);
        assert_eq!(reflect(1e9, 0.0, 10.0), 10.0);
    }

    #[test]
    fn out_and_back_returns() {
        assert_eq!(out_and_back(0.0, 2.0, 2), [0.0, 1.0, 2.0, 1.0, 0.0]);
    }

    #[test]
    fn walk_stays_in_ranges() {
        let ranges = Ranges {
            increments_mm: vec![[20.0, 70.0], [25.0, 95.0]],
            theta_deg: [-180.0, 180.0],
        };
        let runs = experiments(&ranges, &SynthSpec::default(), &mut Rng::new(3));
        for run in &runs {
            for q in &run.joints {
                assert!((20.0..=70.0).contains(&q[0]), "{q:?}");
                assert!((25.0..=95.0).contains(&(q[2] - q[0])), "{q:?}");
                if run.label == "scatter" {
                    assert!(q[1].abs() <= 180.0 && q[3].abs() <= 180.0, "{q:?}");
                }
            }
        }
        assert_eq!(runs.iter().map(|r| r.joints.len()).sum::<usize>(), 984);
    }
}

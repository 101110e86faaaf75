//! A model with its effects, run along a recording: what the tracker should have seen.
//!
//! Each run is simulated on its own, in time order, by the row model
//! ([`crate::model`]) warm-started along it: the commanded joints pass the time effects
//! ([`crate::timeline`]: joint offsets, latency, friction), and each row is solved with
//! its recorded tip force (the loaded model, torsion; a recorded force on a rigid
//! model is refused as the core refuses it), the tip as measured.

use crate::learned::delayed_commands;
use crate::model::{ModelError, ModelSpec, RowModel};
use crate::timeline::actual_joints_flat;
use ctr_core::{JointError, SolveError, Status};
use ctr_formats::Recording;
use std::fmt;

/// Why a simulation could not run.
#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// The model cannot be prepared (an effect table that does not fit the robot, a
    /// combination not modelled, scale factors that make an invalid robot).
    Model(ModelError),
    /// The actual joints of a row (after offsets, latency, friction) are invalid.
    Joint {
        /// row index in the recording
        row: usize,
        /// what the core said
        error: JointError,
    },
    /// A loaded solve was refused (a missing density, a non-finite load).
    Load {
        /// row index in the recording
        row: usize,
        /// what the core said
        error: SolveError,
    },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Model(e) => write!(f, "{e}"),
            SimError::Joint { row, error } => write!(f, "row {}: {error}", row + 1),
            SimError::Load { row, error } => write!(f, "row {}: {error}", row + 1),
        }
    }
}

impl std::error::Error for SimError {}

/// Predicted measurements of some runs of a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct Prediction {
    /// Predicted tip per recording row (`NaN` for rows of runs not simulated), mm.
    pub p: Vec<[f64; 3]>,
    /// Predicted tip frame per recording row, unit quaternion `w, x, y, z` (z the
    /// tangent; in the measuring frame like `p`; `NaN` for rows not simulated).
    pub q: Vec<[f64; 4]>,
    /// Rows whose solve did not converge (their tip is the solver's last iterate).
    pub failed: usize,
    /// The stability margin of each row's solution ([`crate::margin`]: 1 with no snap
    /// within about 20 degrees or 20 mm, 0 at one, negative on an unstable branch) along
    /// the branch the run followed, from [`predict_with_margins`]; `NaN` for rows not
    /// simulated or not converged, and everywhere from [`predict`] and [`predict_rows`].
    pub margin: Vec<f64>,
}

/// Simulates the runs `runs` (indices into `rec.runs`) of a recording.
///
/// ```
/// use ctr_analysis::{model::ModelSpec, simulate::predict};
/// use ctr_formats::{Recording, RobotSpec};
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\n\
///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let rec = Recording::read("s1_mm,theta1_deg,x_mm,y_mm,z_mm\n50,0,0,0,50\n".as_bytes(), "rec.csv", 1)?;
/// let pred = predict(&ModelSpec::from_spec(&spec), &rec, &[0]).unwrap();
/// assert!((pred.p[0][2] - 50.0).abs() < 1e-12);
/// assert!(pred.margin[0].is_nan()); // not asked for: see predict_with_margins
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn predict(model: &ModelSpec, rec: &Recording, runs: &[usize]) -> Result<Prediction, SimError> {
    predict_on(model, rec, runs, 1)
}

/// [`predict`] with every simulated row's stability margin ([`Prediction::margin`]),
/// at the cost of the margin's probes.
///
/// ```
/// use ctr_analysis::{model::ModelSpec, simulate::predict_with_margins};
/// use ctr_formats::{Recording, RobotSpec};
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\n\
///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let rec = Recording::read("s1_mm,theta1_deg,x_mm,y_mm,z_mm\n50,0,0,0,50\n".as_bytes(), "rec.csv", 1)?;
/// let pred = predict_with_margins(&ModelSpec::from_spec(&spec), &rec, &[0]).unwrap();
/// assert_eq!(pred.margin[0], 1.0); // one tube: nothing to snap against
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn predict_with_margins(
    model: &ModelSpec,
    rec: &Recording,
    runs: &[usize],
) -> Result<Prediction, SimError> {
    predict_with_margins_on(model, rec, runs, 1)
}

/// [`predict`] with the runs on `threads` workers (at least one): the same
/// prediction at any thread count (each run is simulated alone, from its first row).
///
/// ```
/// use ctr_analysis::{model::ModelSpec, simulate::{predict, predict_on}};
/// use ctr_formats::{Recording, RobotSpec};
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\n\
///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let rec = Recording::read("run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\na,50,0,0,0,50\nb,60,0,0,0,60\n".as_bytes(), "rec.csv", 1)?;
/// let m = ModelSpec::from_spec(&spec);
/// assert_eq!(predict_on(&m, &rec, &[0, 1], 2).unwrap().p, predict(&m, &rec, &[0, 1]).unwrap().p);
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn predict_on(
    model: &ModelSpec,
    rec: &Recording,
    runs: &[usize],
    threads: usize,
) -> Result<Prediction, SimError> {
    simulate(model, rec, runs, |_| true, false, threads)
}

/// [`predict_with_margins`] with the runs on `threads` workers (at least one): the
/// same prediction and margins at any thread count.
pub fn predict_with_margins_on(
    model: &ModelSpec,
    rec: &Recording,
    runs: &[usize],
    threads: usize,
) -> Result<Prediction, SimError> {
    simulate(model, rec, runs, |_| true, true, threads)
}

/// Simulates only the rows `rows` (indices into `rec.rows`, ascending) of a
/// recording: the time effects still run along each whole run that holds one of them
/// (they remember), but only these rows are solved, each warm-started from the last
/// solved row of its run. Every other row of [`Prediction::p`] is `NaN`. What a fit
/// that counts some rows needs, at the cost of those rows alone.
///
/// ```
/// use ctr_analysis::{model::ModelSpec, simulate::{predict, predict_rows}};
/// use ctr_formats::{Recording, RobotSpec};
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\n\
///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let rec = Recording::read("s1_mm,theta1_deg,x_mm,y_mm,z_mm\n50,0,0,0,50\n60,0,0,0,60\n".as_bytes(), "rec.csv", 1)?;
/// let model = ModelSpec::from_spec(&spec);
/// let some = predict_rows(&model, &rec, &[1]).unwrap();
/// assert!(some.p[0][2].is_nan());
/// assert_eq!(some.p[1], predict(&model, &rec, &[0]).unwrap().p[1]);
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn predict_rows(
    model: &ModelSpec,
    rec: &Recording,
    rows: &[usize],
) -> Result<Prediction, SimError> {
    predict_rows_on(model, rec, rows, 1)
}

/// [`predict_rows`] with the runs on `threads` workers (at least one): the same
/// prediction at any thread count.
///
/// ```
/// use ctr_analysis::{model::ModelSpec, simulate::{predict_rows, predict_rows_on}};
/// use ctr_formats::{Recording, RobotSpec};
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 90.0\ncurvature_radius_mm = 100.0\n\
///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let csv = "run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\na,150,0,0,0,150\nb,160,10,0,0,160\nc,170,20,0,0,170\n";
/// let rec = Recording::read(csv.as_bytes(), "rec.csv", 1)?;
/// let m = ModelSpec::from_spec(&spec);
/// let (two, one) = (predict_rows_on(&m, &rec, &[0, 2], 2)?, predict_rows(&m, &rec, &[0, 2])?);
/// assert_eq!((two.p[0], two.p[2]), (one.p[0], one.p[2]));
/// assert!(two.p[1][0].is_nan()); // not asked for
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn predict_rows_on(
    model: &ModelSpec,
    rec: &Recording,
    rows: &[usize],
    threads: usize,
) -> Result<Prediction, SimError> {
    let runs = runs_holding(rec, rows);
    let mut keep = vec![false; rec.rows.len()];
    for &r in rows {
        keep[r] = true;
    }
    simulate(model, rec, &runs, |row| keep[row], false, threads)
}

/// The runs of `rec` that hold one of `rows` (ascending row indices).
pub(crate) fn runs_holding(rec: &Recording, rows: &[usize]) -> Vec<usize> {
    (0..rec.runs.len())
        .filter(|&r| {
            let range = &rec.runs[r].rows;
            // the first listed row at or after the run's start lies inside it
            let at = rows.partition_point(|&row| row < range.start);
            rows.get(at).is_some_and(|row| range.contains(row))
        })
        .collect()
}

/// The runs `runs` simulated, the rows `keep` says solved, with margins if `margins`,
/// the runs on `threads` workers (each run a time series of its own; the result does
/// not depend on the thread count, and an error is the first run's in order).
fn simulate(
    model: &ModelSpec,
    rec: &Recording,
    runs: &[usize],
    keep: impl Fn(usize) -> bool + Sync,
    margins: bool,
    threads: usize,
) -> Result<Prediction, SimError> {
    let rows = model.rows().map_err(SimError::Model)?;
    let parts = ctr_formats::parallel::map(runs, threads.max(1), |&run| {
        run_tips(model, &rows, rec, run, &keep, margins)
    });
    let mut out = Prediction {
        p: vec![[f64::NAN; 3]; rec.rows.len()],
        q: vec![[f64::NAN; 4]; rec.rows.len()],
        failed: 0,
        margin: vec![f64::NAN; rec.rows.len()],
    };
    for part in parts {
        for tip in part? {
            match tip.margin {
                Some(m) => out.margin[tip.row] = m,
                None => out.failed += 1,
            }
            out.p[tip.row] = tip.p;
            out.q[tip.row] = tip.q;
        }
    }
    Ok(out)
}

/// A solved row of a run.
struct RowTip {
    row: usize,
    p: [f64; 3],
    q: [f64; 4],
    /// The stability margin where the solve converged (`None`: it did not).
    margin: Option<f64>,
}

/// The rows `keep` says solved of run `run`, in order, warm-started along it, with the
/// learned discrepancy added.
/// The actual joints of run `run` of `rec` under `rows`' joint effects, row after row;
/// `None` where it has none (the recorded commands are the actual joints).
pub(crate) fn shifted_joints(rows: &RowModel, rec: &Recording, run: usize) -> Option<RunJoints> {
    rows.shifts_joints().then(|| {
        let range = rec.runs[run].rows.clone();
        let width = 2 * rows.robot().n_tubes();
        let t: Vec<f64> = rec.rows[range.clone()].iter().map(|r| r.t_s).collect();
        let q: Vec<f64> = rec.rows[range]
            .iter()
            .flat_map(|r| r.q.iter().copied())
            .collect();
        RunJoints {
            width,
            values: actual_joints_flat(&t, &q, width, rows.time_effects()),
        }
    })
}

/// A run's actual joints ([`shifted_joints`]), row after row.
pub(crate) struct RunJoints {
    width: usize,
    values: Vec<f64>,
}

impl RunJoints {
    /// The actual joints of the run's row `k` (file units).
    pub(crate) fn row(&self, k: usize) -> &[f64] {
        &self.values[k * self.width..(k + 1) * self.width]
    }
}

/// Why row `row` could not be simulated: its actual joints, or a loaded solve refused.
pub(crate) fn row_error(row: usize, error: SolveError) -> SimError {
    match error {
        SolveError::Joint(error) => SimError::Joint { row, error },
        error => SimError::Load { row, error },
    }
}

fn run_tips(
    model: &ModelSpec,
    rows: &RowModel,
    rec: &Recording,
    run: usize,
    keep: &impl Fn(usize) -> bool,
    margins: bool,
) -> Result<Vec<RowTip>, SimError> {
    let range = rec.runs[run].rows.clone();
    let shifted = shifted_joints(rows, rec, run);
    let mut solver = rows.solver();
    if margins {
        solver = solver.with_margins();
    }
    let mut out = Vec::with_capacity(range.len());
    for (k, row) in range.clone().enumerate() {
        if !keep(row) {
            continue;
        }
        let a = shifted.as_ref().map_or(&rec.rows[row].q[..], |v| v.row(k));
        let r = &rec.rows[row];
        let tip = solver
            .fk_timed(&r.q, a, r.t_s, r.force_n)
            .map_err(|error| row_error(row, error))?;
        out.push(RowTip {
            row,
            p: tip.position,
            q: tip.quaternion,
            margin: (tip.status == Status::Converged).then_some(tip.stability_margin),
        });
    }
    if let Some(gp) = &model.discrepancy {
        // the learned discrepancy along the run, from the delayed commands
        let commands = delayed_commands(model, rec, run);
        let joints: Vec<&[f64]> = commands.iter().map(|q| &q[..]).collect();
        let along = gp.along_run(&joints);
        for tip in &mut out {
            let (d, _) = &along[tip.row - range.start];
            for a in 0..3 {
                tip.p[a] += d[a];
            }
        }
    }
    Ok(out)
}

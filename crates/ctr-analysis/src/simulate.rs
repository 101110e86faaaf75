//! A model with its effects, run along a recording: what the tracker should have seen.
//!
//! Each run is simulated on its own, in time order, with a solver warm-started along it:
//! the commanded joints pass the time effects ([`crate::timeline`]: joint offsets,
//! latency, friction), the robot's tubes are scaled (`stiffness`, `precurvature`), each
//! row is solved (with the tubes' weight and the recorded tip force when either is
//! present, by the core's Cosserat statics, else by the unloaded model with clearance
//! kinks), and the tip is reported as measured (sensor offset, then registration).

use crate::timeline::actual_joints;
use crate::timeline::TimeEffects;
use ctr_core::{Gravity, JointError, Loads, Model, Request, Robot, SolveError, Solver, Status};
use ctr_formats::joints_of;
use ctr_formats::AnyRobot;
use ctr_formats::{Effects, Recording, RobotSpec};
use std::fmt;

/// A robot, its base model and its effects: everything that predicts a recording.
///
/// ```
/// use ctr_analysis::simulate::ModelSpec;
/// use ctr_formats::RobotSpec;
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 90.0\ncurvature_radius_mm = 100.0\n\
///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let m = ModelSpec::from_spec(&spec);
/// assert!(m.effects.is_empty());
/// # Ok::<(), ctr_formats::Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct ModelSpec {
    /// The robot as described (unscaled).
    pub robot: AnyRobot,
    /// The base mechanics.
    pub model: Model,
    /// The effects on top.
    pub effects: Effects,
}

impl ModelSpec {
    /// The model a robot file describes.
    pub fn from_spec(spec: &RobotSpec) -> Self {
        ModelSpec {
            robot: spec.robot,
            model: spec.model,
            effects: spec.effects.clone(),
        }
    }
}

/// Why a simulation could not run.
#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// The scale factors make an invalid robot.
    Robot(ctr_core::RobotError),
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
            SimError::Robot(e) => write!(f, "{e}"),
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
    /// Rows whose solve did not converge (their tip is the solver's last iterate).
    pub failed: usize,
}

/// Simulates the runs `runs` (indices into `rec.runs`) of a recording.
///
/// ```
/// use ctr_analysis::simulate::{predict, ModelSpec};
/// use ctr_formats::{Recording, RobotSpec};
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\n\
///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// let rec = Recording::read("s1_mm,theta1_deg,x_mm,y_mm,z_mm\n50,0,0,0,50\n".as_bytes(), "rec.csv", 1)?;
/// let pred = predict(&ModelSpec::from_spec(&spec), &rec, &[0]).unwrap();
/// assert!((pred.p[0][2] - 50.0).abs() < 1e-12);
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn predict(model: &ModelSpec, rec: &Recording, runs: &[usize]) -> Result<Prediction, SimError> {
    let mut out = Prediction {
        p: vec![[f64::NAN; 3]; rec.rows.len()],
        failed: 0,
    };
    let (k, c) = model.effects.scale_factors(model.robot.n_tubes());
    let robot = model.robot.scaled(&k, &c).map_err(SimError::Robot)?;
    match &robot {
        AnyRobot::One(r) => predict_n(r, model, rec, runs, &mut out)?,
        AnyRobot::Two(r) => predict_n(r, model, rec, runs, &mut out)?,
        AnyRobot::Three(r) => predict_n(r, model, rec, runs, &mut out)?,
        AnyRobot::Four(r) => predict_n(r, model, rec, runs, &mut out)?,
    }
    Ok(out)
}

fn predict_n<const N: usize>(
    robot: &Robot<f64, N>,
    model: &ModelSpec,
    rec: &Recording,
    runs: &[usize],
    out: &mut Prediction,
) -> Result<(), SimError> {
    let effects = &model.effects;
    let core = effects.core_effects::<N>();
    let time = TimeEffects::of(effects, N);
    let shifts = effects.needs_time() || time.joint_offset.iter().any(|&o| o != 0.0);
    let gravity = effects
        .gravity
        .as_ref()
        .map(|g| Gravity::new(g.direction_w, g.g_m_s2));
    for &run in runs {
        let range = rec.runs[run].rows.clone();
        // shifted joints per row of the run; without shifts the recorded ones as they are
        let shifted =
            shifts.then(|| actual_joints(&rec.run_times(run), &rec.run_joints(run), &time));
        let mut solver = Solver::<f64, N>::default();
        for (k, row) in range.enumerate() {
            let a = shifted.as_ref().map_or(&rec.rows[row].q, |v| &v[k]);
            let q = joints_of::<N>(a);
            let force = rec.rows[row].force_n;
            let mut request = Request::new(q, model.model).effects(&core);
            if gravity.is_some() || force.iter().any(|&f| f != 0.0) {
                request = request.loads(Loads {
                    gravity,
                    tip_force_n: force,
                    ..Default::default()
                });
            }
            let sol = solver.solve(robot, request).map_err(|error| match error {
                SolveError::Joint(error) => SimError::Joint { row, error },
                error => SimError::Load { row, error },
            })?;
            if sol.status != Status::Converged {
                out.failed += 1;
            }
            out.p[row] = sol.tip.position.into();
        }
    }
    Ok(())
}

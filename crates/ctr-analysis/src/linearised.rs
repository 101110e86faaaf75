//! A recording's prediction that moves without solving again: what a fit's Jacobian
//! needs for the effects that act on the joints or on the measurement alone.
//!
//! A fit moves effect parameters a small step at a time and asks how the predicted
//! tips move. Two kinds of effect leave the mechanics alone:
//!
//! - on the joints (`joint_offset`, `latency`, `friction`): they change each row's
//!   actual joints `a` and nothing else, so to first order the tip frame moves with
//!   the joint Jacobian `J = [J_p; J_w]` at the row:
//!
//!   ```text
//!   p' = p + J_p (a' - a),    R' = exp([J_w (a' - a)]x) R
//!   ```
//!
//!   (`J_w` the tip frame's angular velocity in W per unit of each joint);
//! - on the measurement (`sensor_offset`, `sensor_rotation`, `registration`): they
//!   map the tip frame to the measured one after the mechanics (the core's
//!   `Effects::measured`, `p = R_reg (p_tip + R_tip d) + t`), exactly.
//!
//! [`Linearised::new`] solves the rows of a model once without its measurement, with
//! the core's analytic joint Jacobian ([`crate::model::RowSolver::fk_jacobian`]);
//! [`Linearised::predict`] then gives the prediction of any model that differs from it
//! only in those six effects, at the cost of the time effects along the runs and no
//! solve. The central difference of two such predictions is the chain rule
//! `J_tip da/dx` (the actual joints' change from the time effects themselves, exact
//! in the measurement): the diagnosis's fits take these columns of their Jacobian
//! from here instead of two solves of every row per parameter.

use crate::model::{ModelSpec, RowModel};
use crate::simulate::{Prediction, SimError};
use crate::timeline::actual_joints;
use ctr_core::{Frame, SolveError};
use ctr_formats::{canonical_quaternion, Recording};
use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector3};

/// The mechanics of `model`: without the effects on the joints and the measurement.
fn mechanics(model: &ModelSpec) -> ModelSpec {
    let mut m = without_measurement(model);
    m.effects.joint_offset = None;
    m.effects.latency = None;
    m.effects.friction = None;
    m
}

/// `model` without its measurement (sensor offset and rotation, registration).
fn without_measurement(model: &ModelSpec) -> ModelSpec {
    let mut m = model.clone();
    m.effects.sensor_offset = None;
    m.effects.sensor_rotation = None;
    m.effects.registration = None;
    m
}

/// The rows of a model solved once, unmeasured, with their joint Jacobians (module
/// doc).
#[derive(Clone, Debug)]
pub struct Linearised {
    /// What every model [`predict`](Self::predict) is given must share.
    mechanics: ModelSpec,
    /// Joints per row (`2 n`).
    width: usize,
    /// The runs simulated (indices into the recording's runs).
    runs: Vec<usize>,
    /// Which recording rows were solved.
    solved: Vec<bool>,
    /// Per recording row: the actual joints solved at (file units), `width` values.
    actual: Vec<f64>,
    /// Per recording row: the tip frame before the measurement (identity where not
    /// solved).
    tip: Vec<Frame<f64>>,
    /// Per recording row: `width` Jacobian columns (file units; position, then
    /// angular velocity in W).
    jacobian: Vec<[f64; 6]>,
}

impl Linearised {
    /// The rows `rows` (ascending; their runs simulated whole for the time effects, as
    /// [`crate::simulate::predict_rows`] does) of `model` solved without its
    /// measurement, with their joint Jacobians. `Ok(None)` where the model has no
    /// analytic joint Jacobian or is more than mechanics, joints and measurement:
    /// gravity or a recorded tip force (loaded solves), a learned discrepancy or an
    /// empirical correction (on the commanded joints, after the measurement).
    ///
    /// ```
    /// use ctr_analysis::{linearised::Linearised, model::ModelSpec, simulate::predict};
    /// use ctr_formats::{JointOffset, Recording, RobotSpec};
    /// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
    ///     length_mm = 260.0\ncurved_length_mm = 90.0\ncurvature_radius_mm = 100.0\n\
    ///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
    /// let rec = Recording::read("s1_mm,theta1_deg,x_mm,y_mm,z_mm\n150,0,0,0,150\n".as_bytes(), "rec.csv", 1)?;
    /// let m = ModelSpec::from_spec(&spec);
    /// let lin = Linearised::new(&m, &rec, &[0])?.expect("unloaded: the core has a Jacobian");
    /// // fed 0.001 mm further: to first order, as a solve says
    /// let mut moved = m.clone();
    /// moved.effects.joint_offset = Some(JointOffset { feed_mm: vec![1e-3], rotation_deg: vec![0.0] });
    /// let (near, solved) = (lin.predict(&moved, &rec)?.unwrap(), predict(&moved, &rec, &[0])?);
    /// assert!((0..3).all(|a| (near.p[0][a] - solved.p[0][a]).abs() < 1e-8));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(
        model: &ModelSpec,
        rec: &Recording,
        rows: &[usize],
    ) -> Result<Option<Self>, SimError> {
        let loaded = model.effects.gravity.is_some()
            || rows
                .iter()
                .any(|&r| rec.rows[r].force_n.iter().any(|&f| f != 0.0));
        if loaded || model.discrepancy.is_some() || model.empirical.is_some() {
            return Ok(None);
        }
        let unmeasured = without_measurement(model);
        let row_model = unmeasured.rows().map_err(SimError::Model)?;
        let width = 2 * model.robot.n_tubes();
        let n = rec.rows.len();
        let mut solved = vec![false; n];
        for &r in rows {
            solved[r] = true;
        }
        let runs = crate::simulate::runs_holding(rec, rows);
        let mut out = Linearised {
            mechanics: mechanics(model),
            width,
            runs,
            solved,
            actual: vec![f64::NAN; n * width],
            tip: vec![Frame::identity(); n],
            jacobian: vec![[0.0; 6]; n * width],
        };
        let mut columns = Vec::with_capacity(width);
        for &run in &out.runs {
            let range = rec.runs[run].rows.clone();
            let actual = run_actual(&row_model, rec, run);
            let mut solver = row_model.solver();
            for (k, row) in range.enumerate() {
                if !out.solved[row] {
                    continue;
                }
                let a = &actual[k];
                let tip = match solver.fk_jacobian(a, &mut columns) {
                    Ok(tip) => tip,
                    Err(SolveError::Unsupported(_)) => return Ok(None),
                    Err(SolveError::Joint(error)) => return Err(SimError::Joint { row, error }),
                    Err(error) => return Err(SimError::Load { row, error }),
                };
                out.actual[row * width..(row + 1) * width].copy_from_slice(a);
                out.jacobian[row * width..(row + 1) * width].copy_from_slice(&columns);
                out.tip[row] = frame_of(tip.position, tip.quaternion);
            }
        }
        Ok(Some(out))
    }

    /// The prediction of `model` on the rows solved: their actual joints from its own
    /// joint effects along each run, the tip moved to first order by the joint
    /// Jacobian, then its measurement, exactly (module doc). `Ok(None)` when `model`
    /// differs from the linearised one in more than its joint and measurement effects;
    /// [`SimError::Joint`] where its actual joints leave the robot's ranges, as a solve
    /// would say. Every row not solved is `NaN`; margins are `NaN`.
    pub fn predict(
        &self,
        model: &ModelSpec,
        rec: &Recording,
    ) -> Result<Option<Prediction>, SimError> {
        if mechanics(model) != self.mechanics {
            return Ok(None);
        }
        let n = rec.rows.len();
        let row_model = model.rows().map_err(SimError::Model)?;
        let measurement = model.effects.core_effects::<1>();
        let mut out = Prediction {
            p: vec![[f64::NAN; 3]; n],
            q: vec![[f64::NAN; 4]; n],
            failed: 0,
            margin: vec![f64::NAN; n],
        };
        let w = self.width;
        for &run in &self.runs {
            let range = rec.runs[run].rows.clone();
            let actual = run_actual(&row_model, rec, run);
            for (k, row) in range.enumerate() {
                if !self.solved[row] {
                    continue;
                }
                let a = &actual[k];
                row_model
                    .robot()
                    .validate_joints(a)
                    .map_err(|error| SimError::Joint { row, error })?;
                let mut dp = Vector3::zeros();
                let mut omega = Vector3::zeros();
                for (j, col) in self.jacobian[row * w..(row + 1) * w].iter().enumerate() {
                    let da = a[j] - self.actual[row * w + j];
                    dp += Vector3::new(col[0], col[1], col[2]) * da;
                    omega += Vector3::new(col[3], col[4], col[5]) * da;
                }
                let tip = &self.tip[row];
                let moved = Frame {
                    rotation: Rotation3::new(omega).into_inner() * tip.rotation,
                    position: tip.position + dp,
                };
                let measured = measurement.measured(&moved);
                out.p[row] = measured.position.into();
                out.q[row] = canonical_quaternion(&measured.orientation());
            }
        }
        Ok(Some(out))
    }
}

/// The actual joints of run `run` of `rec` under `rows`' joint effects (the recorded
/// commands where it has none), row after row.
fn run_actual(rows: &RowModel, rec: &Recording, run: usize) -> Vec<Vec<f64>> {
    if rows.shifts_joints() {
        actual_joints(
            &rec.run_times(run),
            &rec.run_joints(run),
            rows.time_effects(),
        )
    } else {
        rec.run_joints(run)
    }
}

/// The frame of a position and a unit quaternion `w, x, y, z`.
fn frame_of(p: [f64; 3], q: [f64; 4]) -> Frame<f64> {
    let rotation: Matrix3<f64> =
        UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
            .to_rotation_matrix()
            .into_inner();
    Frame {
        rotation,
        position: Vector3::from(p),
    }
}

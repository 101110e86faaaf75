//! The row model: a robot file's model (its robot, `[model] kind` and
//! `[model.effects]`) solving rows of joints. `ctr-cli fk`, the simulation of
//! recordings (and through it the diagnosis), the inverse kinematics and `ctr_py` all
//! solve through it, so a row means the same everywhere.
//!
//! A [`ModelSpec`] describes the model (the robot as the file describes it, the
//! mechanics, the effects); [`ModelSpec::rows`] prepares it once per job as a
//! [`RowModel`]: the tubes scaled (`stiffness`, `precurvature`), the core's per-solve
//! effects made (clearance kinks, sensor offset, registration), gravity set up. A row
//! is then solved in three steps:
//!
//! 1. the commanded joints (file order and units) become the actual ones: plus the
//!    `joint_offset`s, in file units (mm, degrees: the contract's convention); with
//!    time effects (`latency`, `friction` with a non-zero play) whole runs go through
//!    [`crate::timeline::actual_joints`] instead ([`RowModel::actual_joints`]), which
//!    adds the offsets, delays and applies the play operators along the run;
//! 2. the mechanics (`kernel`): one core request with the effects, and the loads where
//!    there are any (the tubes' weight, a recorded tip force): the core's Cosserat
//!    statics, which model torsion (a load on the rigid model is refused, as the core
//!    refuses it);
//! 3. the tip as measured: the sensor offset in the tip frame, then the registration.
//!
//! ```
//! use ctr_analysis::model::ModelSpec;
//! use ctr_formats::RobotSpec;
//! let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
//!     length_mm = 260.0\ncurved_length_mm = 0.0\nyoungs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n\
//!     [model.effects.registration]\ntranslation_mm = [1.0, 2.0, 3.0]\n", "r.toml")?;
//! let rows = ModelSpec::from_spec(&spec).rows()?;
//! let tip = rows.solver().fk(&[50.0, 0.0])?;
//! assert!((tip.position[2] - 53.0).abs() < 1e-12); // as the tracker sees it
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod derivatives;
mod kernel;
mod tip;

pub use kernel::Kept;
pub(crate) use kernel::{AnyKernel, Bound, Kernel};
pub(crate) use tip::{
    file_jacobian, log_so3, tip_jacobian, CoreFk, Jacobian, Solved, TipFk, MAX_JOINTS,
};
pub use tip::{FD_STEP_MM, FD_STEP_RAD, FK_ACCEPT_RESIDUAL, FK_RESIDUAL_TOLERANCE};

use crate::discrepancy::Gp;
use crate::limits::JointLimits;
use crate::margin::Margins;
use crate::timeline::{actual_joints_flat, TimeEffects};
use ctr_core::{Model, SolveError};
use ctr_formats::{AnyRobot, Correction, Effects, ErrorKind, FkResult, RobotSpec};

/// The name [`RowModel::needs_times`] gives a `[model.empirical]` term in time.
pub const EMPIRICAL: &str = "empirical";
use std::fmt;
use std::ops::Range;
use std::sync::Arc;

/// A robot, its base mechanics and its effects: everything that predicts a tip.
///
/// ```
/// use ctr_analysis::model::ModelSpec;
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
    /// `[model.empirical]`: a labelled data-driven correction added to the tip after
    /// everything else (not physics).
    pub empirical: Option<Correction>,
    /// `[model.discrepancy]`, prepared: a learned discrepancy over the joints and their
    /// history added to the tip along each run (not physics; `crate::discrepancy`).
    pub discrepancy: Option<Arc<Gp>>,
}

/// Why a model cannot be prepared, or its time effects cannot run.
#[derive(Clone, Debug, PartialEq)]
pub enum ModelError {
    /// An effect table does not fit the robot, or the combination is not modelled; the
    /// message starts with the key (`model.effects.gravity: ...`).
    Effect(String),
    /// The scale factors make an invalid robot.
    Robot(ctr_core::RobotError),
    /// A time effect needs the rows' times and none were given (`latency`).
    NeedsTime {
        /// the effect id
        effect: &'static str,
    },
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ModelError::Effect(m) => f.write_str(m),
            ModelError::Robot(e) => write!(f, "{e}"),
            ModelError::NeedsTime { effect: EMPIRICAL } => write!(
                f,
                "model.{EMPIRICAL}: a term in t needs the rows' times (t_s, seconds)"
            ),
            ModelError::NeedsTime { effect } => write!(
                f,
                "model.effects.{effect}: needs the rows' times (t_s, seconds) to act along a run"
            ),
        }
    }
}

impl std::error::Error for ModelError {}

impl ModelSpec {
    /// The model a robot file describes.
    pub fn from_spec(spec: &RobotSpec) -> Self {
        ModelSpec {
            robot: spec.robot,
            model: spec.model,
            effects: spec.effects.clone(),
            empirical: spec.empirical.clone(),
            // positive definite by the file's check (noise_mm > 0)
            discrepancy: spec
                .discrepancy
                .as_ref()
                .and_then(|d| Gp::new(d).ok())
                .map(Arc::new),
        }
    }

    /// `robot` under `model` without effects.
    pub fn plain(robot: &AnyRobot, model: Model) -> Self {
        ModelSpec {
            robot: *robot,
            model,
            effects: Effects::default(),
            empirical: None,
            discrepancy: None,
        }
    }

    /// Checks the effects as a robot file's are checked (tables that fit the robot, what
    /// the tube densities allow) and refuses `gravity` with the rigid model (the loaded
    /// solver models torsion).
    ///
    /// ```
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::{AnyRobot, Effects, Gravity};
    /// let t = ctr_core::TubeParams { density_kg_m3: Some(6450.0), ..ctr_core::TubeParams::<f64>::new(1.2, 0.9, 260.0, 0.0, 58000.0, 0.33) };
    /// let mut m = ModelSpec::plain(&AnyRobot::new(&[t]).unwrap(), ctr_core::Model::Rigid);
    /// m.effects.gravity = Some(Gravity { direction_w: [0.0, 0.0, -1.0], g_m_s2: 9.81 });
    /// assert!(m.check().unwrap_err().to_string().starts_with("model.effects.gravity:"));
    /// ```
    pub fn check(&self) -> Result<(), ModelError> {
        let has_density = self
            .robot
            .tube_params()
            .iter()
            .all(|p| p.density_kg_m3.is_some());
        self.effects
            .check(self.robot.n_tubes(), has_density)
            .map_err(|(_, message)| ModelError::Effect(message))?;
        if self.effects.gravity.is_some() && self.model == Model::Rigid {
            return Err(ModelError::Effect(
                "model.effects.gravity: the loaded solver models torsion; it cannot be combined \
                 with the rigid model (kind = \"rigid\" or --model rigid)"
                    .into(),
            ));
        }
        if let Some(c) = &self.empirical {
            // the terms as a file would write them, checked as a file's are
            Correction::check(&c.to_file(), self.robot.n_tubes())
                .map_err(|(_, message)| ModelError::Effect(message))?;
        }
        Ok(())
    }

    /// The model prepared to solve rows: [`check`](Self::check)ed, then the tubes
    /// scaled (an invalid scaled robot is [`ModelError::Robot`]).
    pub fn rows(&self) -> Result<RowModel, ModelError> {
        self.check()?;
        let n = self.robot.n_tubes();
        let (k, c) = self.effects.scale_factors(n);
        let robot = self.robot.scaled(&k, &c).map_err(ModelError::Robot)?;
        let time = TimeEffects::of(&self.effects, &robot);
        Ok(RowModel {
            kernel: AnyKernel::new(&robot, self.model, &self.effects),
            shifts: time.joint_offset.iter().any(|&o| o != 0.0),
            time,
            robot,
            spec: self.clone(),
        })
    }

    /// Forward kinematics of one row of commanded joints (file order and units), solved
    /// cold: [`rows`](Self::rows) and [`RowSolver::fk`] in one call, for a single row
    /// (for many, keep the [`RowModel`] and its [`RowModel::solver`]).
    ///
    /// ```
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::AnyRobot;
    /// use ctr_core::{Model, Status, TubeParams};
    /// let t = TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33); // straight
    /// let robot = AnyRobot::new(&[t]).unwrap();
    /// let fk = ModelSpec::plain(&robot, Model::Torsion).fk(&[50.0, 30.0]).unwrap();
    /// assert_eq!(fk.status, Status::Converged);
    /// assert!((fk.position[2] - 50.0).abs() < 1e-12);
    /// ```
    pub fn fk(&self, joints: &[f64]) -> Result<FkResult, FkError> {
        let rows = self.rows().map_err(FkError::Model)?;
        let tip = rows.solver().fk(joints).map_err(FkError::Solve)?;
        Ok(tip)
    }
}

/// Why [`RowModel::tip_jacobian`] gave no Jacobian.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum JacobianError {
    /// A time effect is on: the tip depends on the rows before it.
    TimeEffect {
        /// the effect id
        effect: &'static str,
    },
    /// The forward kinematics does not converge at the joints (or they are outside the
    /// core's ranges).
    NoSolution,
}

impl fmt::Display for JacobianError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            JacobianError::TimeEffect { effect } => write!(
                f,
                "model.effects.{effect}: the tip Jacobian is the static model's, and this time \
                 effect makes the tip depend on the rows before it"
            ),
            JacobianError::NoSolution => {
                f.write_str("no Jacobian: the forward kinematics does not converge there")
            }
        }
    }
}

impl std::error::Error for JacobianError {}

/// Why [`ModelSpec::fk`] gave no tip.
#[derive(Clone, Debug, PartialEq)]
pub enum FkError {
    /// The model cannot be prepared.
    Model(ModelError),
    /// The row cannot be solved (joints out of range, a refused combination).
    Solve(SolveError),
}

impl fmt::Display for FkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FkError::Model(e) => write!(f, "{e}"),
            FkError::Solve(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for FkError {}

/// A model prepared to solve rows (see the [module doc](self)).
#[derive(Clone, Debug)]
pub struct RowModel {
    spec: ModelSpec,
    /// the robot with its tubes scaled
    robot: AnyRobot,
    kernel: AnyKernel,
    time: TimeEffects,
    /// a joint offset is non-zero
    shifts: bool,
}

impl RowModel {
    /// The model as described.
    pub fn spec(&self) -> &ModelSpec {
        &self.spec
    }

    /// The robot the rows are solved on (tubes scaled by the effects).
    pub fn robot(&self) -> &AnyRobot {
        &self.robot
    }

    /// The base mechanics.
    pub fn model(&self) -> Model {
        self.spec.model
    }

    /// The effects.
    pub fn effects(&self) -> &Effects {
        &self.spec.effects
    }

    /// The joint offsets and time effects in file units.
    pub fn time_effects(&self) -> &TimeEffects {
        &self.time
    }

    /// True when an effect needs the rows' order (and for latency their times): the
    /// rows must go through [`actual_joints`](Self::actual_joints) first.
    pub fn needs_time(&self) -> bool {
        self.spec.effects.needs_time()
            || self.corrects_with_time()
            || self.spec.discrepancy.is_some()
    }

    /// The time effect that needs times (not just order) and is on: `latency`, or
    /// [`EMPIRICAL`] for a `[model.empirical]` term in `t`.
    pub fn needs_times(&self) -> Option<&'static str> {
        if self.spec.effects.latency.is_some_and(|l| l.tau_s != 0.0) {
            Some("latency")
        } else if self.corrects_with_time() {
            Some(EMPIRICAL)
        } else {
            None
        }
    }

    /// True when the empirical correction has a term in time.
    fn corrects_with_time(&self) -> bool {
        self.spec
            .empirical
            .as_ref()
            .is_some_and(Correction::uses_time)
    }

    /// True when the actual joints differ from the commanded ones (joint offsets or
    /// time effects).
    pub fn shifts_joints(&self) -> bool {
        self.needs_time() || self.shifts
    }

    /// The actual joints of rows with time effects: `joints` row after row (file order
    /// and units, `2 n` values a row), `runs` the rows of each run (in order, covering
    /// every row once, each run a time series of its own), `t_s` each row's time
    /// (non-decreasing within a run). Without times the row index stands for time,
    /// which the play friction needs only for order; latency then is refused
    /// ([`ModelError::NeedsTime`]). Returns the actual joints, row after row, with the
    /// joint offsets added.
    ///
    /// ```
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::{AnyRobot, Effects, Friction};
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// let robot = AnyRobot::new(&[t, ctr_core::TubeParams::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// let mut m = ModelSpec::plain(&robot, ctr_core::Model::Torsion);
    /// m.effects.friction = Some(Friction { rotation_play_deg: vec![5.0], ..Default::default() });
    /// let rows = [30.0, 0.0, 80.0, 0.0, 30.0, 0.0, 80.0, 20.0];
    /// let a = m.rows().unwrap().actual_joints(&rows, None, &[0..2]).unwrap();
    /// assert_eq!(a[7], 15.0); // the inner tube lags by the play
    /// ```
    pub fn actual_joints(
        &self,
        joints: &[f64],
        t_s: Option<&[f64]>,
        runs: &[Range<usize>],
    ) -> Result<Vec<f64>, ModelError> {
        let width = 2 * self.robot.n_tubes();
        if t_s.is_none() {
            if let Some(effect) = self.needs_times() {
                return Err(ModelError::NeedsTime { effect });
            }
        }
        let mut out = vec![0.0; joints.len()];
        for run in runs {
            let q = &joints[run.start * width..run.end * width];
            let t: Vec<f64> = match t_s {
                Some(t) => t[run.clone()].to_vec(),
                None => run.clone().map(|r| r as f64).collect(),
            };
            let a = actual_joints_flat(&t, q, width, &self.time);
            out[run.start * width..run.end * width].copy_from_slice(&a);
        }
        Ok(out)
    }

    /// What a row's failed solve means (the location is the caller's): joints out of
    /// the robot's ranges (when the effects move the joints, said so), or a load or
    /// combination the core refused.
    pub fn row_error(&self, e: SolveError) -> ErrorKind {
        let effects = &self.spec.effects;
        match e {
            SolveError::Joint(e) if self.shifts_joints() => {
                let moved: Vec<&str> = [
                    ("joint_offset", effects.joint_offset.is_some()),
                    ("latency", effects.latency.is_some()),
                    ("friction", effects.friction.is_some()),
                ]
                .into_iter()
                .filter_map(|(id, on)| on.then_some(id))
                .collect();
                ErrorKind::Effect {
                    message: format!(
                        "the actual joints (the commanded ones moved by model.effects {}) \
                         leave the robot's ranges: {e}",
                        moved.join(", ")
                    ),
                }
            }
            SolveError::Joint(e) => ErrorKind::Joint(e),
            other => ErrorKind::Effect {
                message: other.to_string(),
            },
        }
    }

    /// The time effect that is on (`latency`, else `friction` with a play), if any:
    /// with one, a row's tip depends on the rows before it.
    pub fn time_effect(&self) -> Option<&'static str> {
        if let Some(effect) = self.needs_times() {
            return Some(effect);
        }
        self.needs_time().then_some("friction")
    }

    /// The row model's tip as the IK sees it: joint slices in mm and rad, FK solved to
    /// [`FK_RESIDUAL_TOLERANCE`], the joint offsets added (the time effects are not:
    /// the IK refuses them).
    pub(crate) fn tip_fk(&self) -> Box<dyn TipFk> {
        let offsets = &self.time.joint_offset;
        match &self.kernel {
            AnyKernel::One(k) => Box::new(CoreFk::new(*k, offsets)),
            AnyKernel::Two(k) => Box::new(CoreFk::new(*k, offsets)),
            AnyKernel::Three(k) => Box::new(CoreFk::new(*k, offsets)),
            AnyKernel::Four(k) => Box::new(CoreFk::new(*k, offsets)),
        }
    }

    /// The tip Jacobian at the commanded `joints` (file order and units), of the tip as
    /// measured: one column per joint, in joint order; in each, entries 0..3
    /// `d position / d joint` (mm per mm, mm per degree) and entries 3..6 the tip's
    /// angular velocity in W (rad per mm, rad per degree). The core's analytic Jacobian
    /// (through joint offsets, clearance kinks, sensor offset, registration), or under
    /// gravity central differences with probes inside the core's joint ranges (see
    /// [`crate::model`]; the IK uses the same function with its limits).
    ///
    /// ```
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::AnyRobot;
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33); // straight
    /// let rows = ModelSpec::plain(&AnyRobot::new(&[t]).unwrap(), ctr_core::Model::Torsion).rows()?;
    /// let j = rows.tip_jacobian(&[50.0, 30.0])?;
    /// assert!((j[0][2] - 1.0).abs() < 1e-6); // feeding moves the tip along z
    /// assert!((j[1][5] - 1f64.to_radians()).abs() < 1e-9); // turning spins it about z
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Panics
    /// If `joints.len() != 2 * n_tubes`.
    pub fn tip_jacobian(&self, joints: &[f64]) -> Result<Vec<[f64; 6]>, JacobianError> {
        if let Some(effect) = self.time_effect() {
            return Err(JacobianError::TimeEffect { effect });
        }
        let lengths: Vec<f64> = self
            .robot
            .tube_params()
            .iter()
            .map(|p| p.length_mm)
            .collect();
        // the core's own ranges only: a robot file's [limits] bound the IK, not the model
        let ranges = JointLimits::new(&lengths, None).map_err(|_| JacobianError::NoSolution)?;
        file_jacobian(&mut *self.tip_fk(), &ranges, joints).ok_or(JacobianError::NoSolution)
    }

    /// A solver that warm-starts each row from the previous ones.
    pub fn solver(&self) -> RowSolver<'_> {
        RowSolver {
            model: self,
            bound: self.kernel.bind(),
            buf: Vec::new(),
            margins: Margins::Off,
        }
    }
}

/// Solves rows of a [`RowModel`], warm-starting each from the previous ones.
#[derive(Clone, Debug)]
pub struct RowSolver<'m> {
    model: &'m RowModel,
    bound: Bound<'m>,
    /// the actual joints of the last commanded row (with joint offsets)
    buf: Vec<f64>,
    /// which rows' stability margins are computed ([`RowSolver::margins`])
    margins: Margins,
}

impl RowSolver<'_> {
    /// This solver with every row's stability margin ([`crate::margin`]) computed;
    /// without, [`FkResult::stability_margin`] is NaN (the margin's probes cost up to
    /// `4 n + 2` more solves on a row whose tubes are softer in twist than uncoupled
    /// ones).
    ///
    /// ```
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::AnyRobot;
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// let rows = ModelSpec::plain(&AnyRobot::new(&[t]).unwrap(), ctr_core::Model::Torsion).rows()?;
    /// assert!(rows.solver().fk(&[50.0, 0.0])?.stability_margin.is_nan());
    /// assert_eq!(rows.solver().with_margins().fk(&[50.0, 0.0])?.stability_margin, 1.0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn with_margins(self) -> Self {
        self.margins(Margins::Exact)
    }

    /// This solver with the stability margins `which` computes ([`Margins`]; the
    /// default is [`Margins::Off`]).
    pub fn margins(mut self, which: Margins) -> Self {
        self.margins = which;
        self
    }

    /// Solves the commanded joints of one row (file order and units): the joint offsets
    /// are added, then the mechanics and the measurement (module doc). For models
    /// without time effects (else see [`RowModel::actual_joints`] and
    /// [`fk_actual`](Self::fk_actual)). `SolveError::Joint` when the (actual) joints are
    /// out of the robot's ranges.
    ///
    /// # Panics
    /// If `joints.len() != 2 * n_tubes`.
    pub fn fk(&mut self, joints: &[f64]) -> Result<FkResult, SolveError> {
        if !self.model.shifts {
            return self.fk_timed(joints, joints, f64::NAN, [0.0; 3]);
        }
        let actual = self.actual_of(joints);
        let tip = self.fk_timed(joints, &actual, f64::NAN, [0.0; 3]);
        self.buf = actual;
        tip
    }

    /// Solves one row as a time series gives it: its actual joints (as
    /// [`RowModel::actual_joints`] gives them) under the tip force `force_n`, then the
    /// `[model.empirical]` correction at its commanded joints and time `t_s` (s).
    ///
    /// # Panics
    /// If a joint row is not `2 n_tubes` values.
    pub fn fk_timed(
        &mut self,
        commanded: &[f64],
        actual: &[f64],
        t_s: f64,
        force_n: [f64; 3],
    ) -> Result<FkResult, SolveError> {
        let mut tip = self.bound.fk(actual, force_n, self.margins)?;
        if let Some(c) = &self.model.spec.empirical {
            c.apply(commanded, t_s, &mut tip.position);
        }
        Ok(tip)
    }

    /// Solves one row's actual joints (offsets and time effects already applied, as
    /// [`RowModel::actual_joints`] gives them) under the tip force `force_n` (N, in W;
    /// zeros: none): the model alone, without the `[model.empirical]` correction (see
    /// [`fk_timed`](Self::fk_timed)).
    ///
    /// # Panics
    /// If `actual.len() != 2 * n_tubes`.
    pub fn fk_actual(&mut self, actual: &[f64], force_n: [f64; 3]) -> Result<FkResult, SolveError> {
        self.bound.fk(actual, force_n, self.margins)
    }

    /// [`fk`](Self::fk) with the backbone: the points (x, y, z, mm) from the guide exit
    /// to the tip, one per integration step, in the measuring frame (the registration
    /// applied, as to the tip). For models without time effects.
    ///
    /// ```
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::AnyRobot;
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33); // straight
    /// let rows = ModelSpec::plain(&AnyRobot::new(&[t]).unwrap(), ctr_core::Model::Torsion).rows()?;
    /// let (tip, points) = rows.solver().backbone(&[50.0, 0.0])?;
    /// assert_eq!(points.last().unwrap(), &tip.position);
    /// assert!(points.iter().all(|p| p[0] == 0.0 && p[1] == 0.0));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Panics
    /// If `joints.len() != 2 * n_tubes`.
    pub fn backbone(&mut self, joints: &[f64]) -> Result<(FkResult, Vec<[f64; 3]>), SolveError> {
        let actual = self.actual_of(joints);
        let out = self.bound.backbone(&actual, [0.0; 3], self.margins);
        self.buf = actual;
        out
    }

    /// The actual joints of a commanded row, in the reused buffer.
    fn actual_of(&mut self, joints: &[f64]) -> Vec<f64> {
        let offset = &self.model.time.joint_offset;
        assert_eq!(joints.len(), offset.len(), "a joint row has 2 n values");
        let mut buf = std::mem::take(&mut self.buf);
        buf.clear();
        // as the timeline adds them: commanded + offset, file units
        buf.extend(joints.iter().zip(offset).map(|(q, o)| q + o));
        buf
    }

    /// Forgets the warm-start memory.
    pub fn reset(&mut self) {
        self.bound.reset();
    }
}

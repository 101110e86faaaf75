//! Forward kinematics of a robot file's whole model: its robot, `[model] kind` and
//! `[model.effects]`. What `ctr-cli fk`, `ctr-cli ik` and `ctr_py` solve.
//!
//! An [`FkModel`] is built once per job: the tubes scaled (`stiffness`,
//! `precurvature`), the core's per-solve effects made (clearance kinks, sensor offset,
//! registration) and gravity set up. A row is then composed exactly as
//! [`crate::simulate::predict`] composes it:
//!
//! 1. the commanded joints (file order and units) plus the `joint_offset`s; with time
//!    effects (`latency`, `friction` with a non-zero play) the whole run goes through
//!    [`crate::timeline::actual_joints`] instead ([`FkModel::actual_joints`]), which adds
//!    the offsets, delays and applies the play operators along the run;
//! 2. the mechanics on the scaled robot: with `gravity`, the core's Cosserat statics
//!    (`Solver::solve_loaded`, torsion included), else the base model with the
//!    clearance kinks (`Solver::solve_with`);
//! 3. the tip as measured: the sensor offset in the tip frame, then the registration
//!    (for the loaded solve through the core effects' `measured`).
//!
//! A model without any effect table solves with [`AnyRobot::solver`] as before: the
//! same numbers, bit for bit, as the core's `Solver::solve`.

use crate::robot::{FkSolver, Kinematics};
use crate::timeline::actual_joints;
use crate::timeline::TimeEffects;
use ctr_core::effects::Effects as CoreEffects;
use ctr_core::{Gravity, Loads, Model, Request, Robot, SolveError, Solver};
use ctr_formats::joints_of;
use ctr_formats::ErrorKind;
use ctr_formats::{AnyRobot, FkResult};
use ctr_formats::{Effects, RobotSpec};
use std::fmt;
use std::ops::Range;

/// Why an [`FkModel`] cannot be built or its time effects cannot run.
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
            ModelError::NeedsTime { effect } => write!(
                f,
                "model.effects.{effect}: needs the rows' times (t_s, seconds) to act along a run"
            ),
        }
    }
}

impl std::error::Error for ModelError {}

/// A robot file's model, ready to solve rows.
///
/// ```
/// use ctr_analysis::model::FkModel;
/// use ctr_formats::RobotSpec;
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\nyoungs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n\
///     [model.effects.registration]\ntranslation_mm = [1.0, 2.0, 3.0]\n", "r.toml")?;
/// let model = FkModel::from_spec(&spec, None).unwrap();
/// let tip = model.solver().fk(&[50.0, 0.0]).unwrap();
/// assert!((tip.position[2] - 53.0).abs() < 1e-12); // as the tracker sees it
/// # Ok::<(), ctr_formats::Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct FkModel {
    /// The robot with its tubes scaled.
    robot: AnyRobot,
    model: Model,
    effects: Effects,
    /// Joint offsets, file order and units.
    joint_offset: Vec<f64>,
    /// No effect table at all: the plain solve.
    plain: bool,
}

impl FkModel {
    /// The model of `robot` (as described, unscaled) solved with `model` and `effects`.
    ///
    /// Refused: effects that do not fit the robot (see the robot file's checks), and
    /// `gravity` with `Model::Rigid` (the loaded solver always models torsion).
    pub fn new(robot: &AnyRobot, model: Model, effects: &Effects) -> Result<Self, ModelError> {
        let n = robot.n_tubes();
        let has_density = robot
            .tube_params()
            .iter()
            .all(|p| p.density_kg_m3.is_some());
        effects
            .check(n, has_density)
            .map_err(|(_, message)| ModelError::Effect(message))?;
        if effects.gravity.is_some() && model == Model::Rigid {
            return Err(ModelError::Effect(
                "model.effects.gravity: the loaded solver models torsion; it cannot be combined \
                 with the rigid model (kind = \"rigid\" or --model rigid)"
                    .into(),
            ));
        }
        let (k, c) = effects.scale_factors(n);
        let scaled = robot.scaled(&k, &c).map_err(ModelError::Robot)?;
        Ok(FkModel {
            robot: if effects.stiffness.is_some() || effects.precurvature.is_some() {
                scaled
            } else {
                *robot
            },
            model,
            joint_offset: TimeEffects::of(effects, n).joint_offset,
            plain: effects.is_empty(),
            effects: effects.clone(),
        })
    }

    /// The model a robot file describes; `model` overrides its `[model] kind`.
    pub fn from_spec(spec: &RobotSpec, model: Option<Model>) -> Result<Self, ModelError> {
        FkModel::new(&spec.robot, model.unwrap_or(spec.model), &spec.effects)
    }

    /// The robot the rows are solved on (tubes scaled by the effects).
    pub fn robot(&self) -> &AnyRobot {
        &self.robot
    }

    /// The base mechanics.
    pub fn model(&self) -> Model {
        self.model
    }

    /// The effects.
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// True without any effect table: rows are solved by the plain core solve.
    pub fn is_plain(&self) -> bool {
        self.plain
    }

    /// True when an effect needs the rows' order (and for latency their times): the
    /// rows must go through [`actual_joints`](Self::actual_joints) first.
    pub fn needs_time(&self) -> bool {
        self.effects.needs_time()
    }

    /// The time effect that needs times (not just order) and is on: `latency`.
    pub fn needs_times(&self) -> Option<&'static str> {
        self.effects
            .latency
            .is_some_and(|l| l.tau_s != 0.0)
            .then_some("latency")
    }

    /// True when the actual joints differ from the commanded ones (joint offsets or
    /// time effects).
    pub fn shifts_joints(&self) -> bool {
        self.needs_time() || self.joint_offset.iter().any(|&o| o != 0.0)
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
    /// use ctr_analysis::model::FkModel;
    /// use ctr_formats::{AnyRobot, Effects, Friction};
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// let robot = AnyRobot::new(&[t, ctr_core::TubeParams::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// let e = Effects { friction: Some(Friction { rotation_play_deg: vec![5.0], feed_play_mm: vec![] }), ..Default::default() };
    /// let m = FkModel::new(&robot, ctr_core::Model::Torsion, &e).unwrap();
    /// let rows = [30.0, 0.0, 80.0, 0.0, 30.0, 0.0, 80.0, 20.0];
    /// let a = m.actual_joints(&rows, None, &[0..2]).unwrap();
    /// assert_eq!(a[7], 15.0); // the inner tube lags by the play
    /// ```
    pub fn actual_joints(
        &self,
        joints: &[f64],
        t_s: Option<&[f64]>,
        runs: &[Range<usize>],
    ) -> Result<Vec<f64>, ModelError> {
        let n = self.robot.n_tubes();
        let width = 2 * n;
        if t_s.is_none() {
            if let Some(effect) = self.needs_times() {
                return Err(ModelError::NeedsTime { effect });
            }
        }
        let time = TimeEffects::of(&self.effects, n);
        let mut out = vec![0.0; joints.len()];
        for run in runs {
            let q: Vec<Vec<f64>> = run
                .clone()
                .map(|r| joints[r * width..(r + 1) * width].to_vec())
                .collect();
            let t: Vec<f64> = match t_s {
                Some(t) => t[run.clone()].to_vec(),
                None => run.clone().map(|r| r as f64).collect(),
            };
            for (k, a) in actual_joints(&t, &q, &time).into_iter().enumerate() {
                let r = run.start + k;
                out[r * width..(r + 1) * width].copy_from_slice(&a);
            }
        }
        Ok(out)
    }

    /// What a row's failed solve means (the location is the caller's): joints out of
    /// the robot's ranges (when the effects move the joints, said so), or a load the
    /// core refused.
    pub fn row_error(&self, e: SolveError) -> ErrorKind {
        match e {
            SolveError::Joint(e) if self.shifts_joints() => {
                let moved: Vec<&str> = [
                    ("joint_offset", self.effects.joint_offset.is_some()),
                    ("latency", self.effects.latency.is_some()),
                    ("friction", self.effects.friction.is_some()),
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

    /// A solver that warm-starts each row from the previous ones.
    pub fn solver(&self) -> ModelSolver<'_> {
        if self.plain {
            return ModelSolver {
                inner: Inner::Plain(self.robot.solver(), self.model),
            };
        }
        fn with<const N: usize>(m: &FkModel, robot: &Robot<f64, N>) -> Effective<N> {
            Effective {
                robot: *robot,
                solver: Solver::default(),
                core: m.effects.core_effects::<N>(),
                gravity: m
                    .effects
                    .gravity
                    .as_ref()
                    .map(|g| Gravity::new(g.direction_w, g.g_m_s2)),
                model: m.model,
            }
        }
        let inner = match &self.robot {
            AnyRobot::One(r) => AnyEffective::One(with(self, r)),
            AnyRobot::Two(r) => AnyEffective::Two(with(self, r)),
            AnyRobot::Three(r) => AnyEffective::Three(with(self, r)),
            AnyRobot::Four(r) => AnyEffective::Four(with(self, r)),
        };
        ModelSolver {
            inner: Inner::Effects {
                offset: &self.joint_offset,
                shift: self.joint_offset.iter().any(|&o| o != 0.0),
                buf: vec![0.0; self.joint_offset.len()],
                solver: Box::new(inner),
            },
        }
    }
}

/// One tube count's solver with effects.
#[derive(Clone, Copy, Debug)]
struct Effective<const N: usize> {
    robot: Robot<f64, N>,
    solver: Solver<f64, N>,
    core: CoreEffects<f64, N>,
    gravity: Option<Gravity<f64>>,
    model: Model,
}

impl<const N: usize> Effective<N> {
    fn solve(&mut self, a: &[f64]) -> Result<FkResult, SolveError> {
        let q = joints_of::<N>(a);
        let mut request = Request::new(q, self.model).effects(&self.core);
        if self.gravity.is_some() {
            request = request.loads(Loads {
                gravity: self.gravity,
                ..Default::default()
            });
        }
        let sol = self.solver.solve(&self.robot, request)?;
        Ok(FkResult::from_solution(&sol))
    }
}

// one per solver, boxed by its owner
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum AnyEffective {
    One(Effective<1>),
    Two(Effective<2>),
    Three(Effective<3>),
    Four(Effective<4>),
}

/// Solves rows of an [`FkModel`], warm-starting each from the previous ones.
#[derive(Clone, Debug)]
pub struct ModelSolver<'m> {
    inner: Inner<'m>,
}

// one per worker's chunk, on its stack: the plain variant stays unboxed (the fast path)
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum Inner<'m> {
    /// No effects: the plain solve.
    Plain(FkSolver<'m>, Model),
    /// With effects.
    Effects {
        /// joint offsets, file order
        offset: &'m [f64],
        /// any offset non-zero
        shift: bool,
        /// the shifted joints
        buf: Vec<f64>,
        /// the solver for the tube count
        solver: Box<AnyEffective>,
    },
}

impl ModelSolver<'_> {
    /// Solves the commanded joints of one row (file order and units): the joint offsets
    /// are added, then the mechanics and the measurement (module docs). Only for models
    /// without time effects (else see [`FkModel::actual_joints`] and
    /// [`fk_actual`](Self::fk_actual)). `SolveError::Joint` when the (actual) joints are
    /// out of the robot's ranges.
    ///
    /// # Panics
    /// If `joints.len() != 2 * n_tubes`.
    pub fn fk(&mut self, joints: &[f64]) -> Result<FkResult, SolveError> {
        match &mut self.inner {
            Inner::Plain(s, model) => s.fk(joints, *model).map_err(SolveError::Joint),
            Inner::Effects {
                offset,
                shift,
                buf,
                solver,
            } => {
                assert_eq!(joints.len(), offset.len(), "a joint row has 2 n values");
                let a = if *shift {
                    // as the timeline adds them: commanded + offset, file units
                    for ((b, q), o) in buf.iter_mut().zip(joints).zip(offset.iter()) {
                        *b = q + o;
                    }
                    &buf[..]
                } else {
                    joints
                };
                solver.solve(a)
            }
        }
    }

    /// Solves one row's actual joints (offsets and time effects already applied, as
    /// [`FkModel::actual_joints`] gives them).
    ///
    /// # Panics
    /// If `actual.len() != 2 * n_tubes`.
    pub fn fk_actual(&mut self, actual: &[f64]) -> Result<FkResult, SolveError> {
        match &mut self.inner {
            Inner::Plain(s, model) => s.fk(actual, *model).map_err(SolveError::Joint),
            Inner::Effects { solver, .. } => solver.solve(actual),
        }
    }
}

impl AnyEffective {
    fn solve(&mut self, a: &[f64]) -> Result<FkResult, SolveError> {
        match self {
            AnyEffective::One(e) => e.solve(a),
            AnyEffective::Two(e) => e.solve(a),
            AnyEffective::Three(e) => e.solve(a),
            AnyEffective::Four(e) => e.solve(a),
        }
    }
}

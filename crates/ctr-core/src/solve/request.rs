//! The one solve request: everything a forward-kinematics solve depends on, and what
//! comes back.
//!
//! A [`Request`] names the joints and the mechanics ([`Model`]) and optionally the
//! effects, the loads, the boundary friction moments, and where to write a derivative
//! of the tip and backbone points (buffers of the caller's: a solve allocates
//! nothing); [`Solver::solve`](crate::Solver::solve) answers with a [`Solution`](crate::Solution). Every
//! combination the mechanics model is accepted; the others are a
//! [`SolveError::Unsupported`] naming what is missing, never a silent approximation:
//!
//! | with | rigid | torsion | loads (torsion) |
//! |---|---|---|---|
//! | effects: offsets, sensor offset, registration | yes | yes | yes |
//! | clearance kinks | yes | yes | no |
//! | boundary friction moments | no | yes | no |
//! | joint or parameter Jacobian, or both | yes | yes (with kinks, friction) | no |
//! | compliance ([`Request::compliance`]) | no | yes (at zero load) | yes |
//! | softest mode's gradient ([`Solver::softest_mode_gradient`](crate::Solver::softest_mode_gradient)) | yes (constant) | yes (no friction moments) | no |
//! | backbone points | yes | yes | yes |

use super::jacobian::{JointJacobian, ParameterJacobian};
use super::Model;
use crate::model::effects::Effects;
use crate::model::joints::{JointError, Joints};
use crate::model::loads::Loads;
use crate::real::Real;
use core::fmt;
use nalgebra::{Matrix6, Vector3};

/// Where a solve writes a derivative of its tip (see [`Request::joint_jacobian`],
/// [`Request::parameter_jacobian`], [`Request::compliance`]).
#[derive(Debug)]
pub enum Derivative<'a, T: Real, const N: usize> {
    /// d(tip)/d(commanded joints).
    Joints(&'a mut JointJacobian<T, N>),
    /// d(tip)/d(each tube's stiffness and precurvature scale factors).
    Parameters(&'a mut ParameterJacobian<T, N>),
    /// Both at once: one derivative pass carries the joints and the parameters (where
    /// the tube count allows, else two passes), the same numbers as each alone.
    JointsAndParameters(&'a mut JointJacobian<T, N>, &'a mut ParameterJacobian<T, N>),
    /// The tip's compliance: the 6 x 6 derivative of `(p_tip, rotation)` with respect
    /// to `(F_tip, M_tip)`. Rows: tip displacement (mm), then the tip frame's rotation as
    /// a spatial angle vector (rad, `[dphi]x = dR R^T`), as measured; columns: tip force
    /// (N), then tip moment (N mm), in W.
    Loads(&'a mut Matrix6<T>),
}

/// One forward-kinematics request.
///
/// ```
/// use ctr_core::{JointJacobian, Joints, Loads, Model, Request, Robot, Solver, Status, TubeParams};
/// use ctr_core::effects::{Effects, Registration};
/// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
/// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
/// let robot = Robot::new([outer, inner])?;
/// let effects = Effects { registration: Some(Registration::from_axis_angle([0.0, 0.0, 1.0], 0.1, [1.0, 0.0, 0.0])), ..Default::default() };
/// let q = Joints::from_mm_deg([40.0, 90.0], [0.0, 120.0]);
/// // this model, these effects, with the joint Jacobian, in one call
/// let mut jac = JointJacobian::nan();
/// let sol = Solver::default().solve(&robot, Request::new(q, Model::Torsion).effects(&effects).joint_jacobian(&mut jac))?;
/// assert_eq!(sol.status, Status::Converged);
/// assert!(jac.feed[0].iter().all(|v| v.is_finite()));
/// // loads need the torsion model
/// let loads = Loads { tip_force_n: [0.0, 0.0, -0.1], ..Default::default() };
/// assert!(Solver::default().solve(&robot, Request::new(q, Model::Rigid).loads(loads)).is_err());
/// # Ok::<(), Box<dyn core::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Request<'a, T: Real, const N: usize> {
    /// The commanded joints.
    pub joints: Joints<T, N>,
    /// The mechanics.
    pub model: Model,
    /// Kinematic effects: joint offsets, clearance kinks, sensor offset, registration.
    pub effects: Option<&'a Effects<T, N>>,
    /// External loads (the loaded solver, torsion model).
    pub loads: Option<Loads<T>>,
    /// Boundary friction moment coefficient `mu'_j sigma_j` of each pair (see
    /// [`crate::friction::BoundaryMoment`]); torsion model, no loads.
    pub friction: Option<[T; N]>,
    /// Where to write a derivative of the tip.
    pub derivative: Option<Derivative<'a, T, N>>,
    /// Where to write backbone points (positions from the guide exit to the tip, one per
    /// integration step; in the measuring frame where the effects have a registration).
    pub backbone: Option<&'a mut [Vector3<T>]>,
    /// Ignore (and keep) the solver's warm-start memory.
    pub cold: bool,
}

impl<'a, T: Real, const N: usize> Request<'a, T, N> {
    /// The tip at `joints` under `model`, nothing else.
    pub fn new(joints: Joints<T, N>, model: Model) -> Self {
        Request {
            joints,
            model,
            effects: None,
            loads: None,
            friction: None,
            derivative: None,
            backbone: None,
            cold: false,
        }
    }
    /// With kinematic effects.
    pub fn effects(mut self, effects: &'a Effects<T, N>) -> Self {
        self.effects = Some(effects);
        self
    }
    /// Under loads.
    pub fn loads(mut self, loads: Loads<T>) -> Self {
        self.loads = Some(loads);
        self
    }
    /// With boundary friction moments (`mu'_j sigma_j` per pair).
    pub fn friction(mut self, coefficients: [T; N]) -> Self {
        self.friction = Some(coefficients);
        self
    }
    /// Writing the joint Jacobian of the tip into `jacobian`.
    pub fn joint_jacobian(mut self, jacobian: &'a mut JointJacobian<T, N>) -> Self {
        self.derivative = Some(Derivative::Joints(jacobian));
        self
    }
    /// Writing the parameter Jacobian of the tip into `jacobian`.
    pub fn parameter_jacobian(mut self, jacobian: &'a mut ParameterJacobian<T, N>) -> Self {
        self.derivative = Some(Derivative::Parameters(jacobian));
        self
    }
    /// Writing the joint Jacobian of the tip into `joints` and its parameter Jacobian
    /// into `parameters`, from one derivative pass where the tube count allows (up to
    /// three tubes; four take two passes).
    ///
    /// ```
    /// use ctr_core::{JointJacobian, Joints, Model, ParameterJacobian, Request, Robot, Solver, TubeParams};
    /// let robot = Robot::new([TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) }]).unwrap();
    /// let q = Joints::new([50.0], [0.3]);
    /// let (mut j, mut p) = (JointJacobian::nan(), ParameterJacobian::nan());
    /// Solver::default().solve(&robot, Request::new(q, Model::Torsion).jacobians(&mut j, &mut p)).unwrap();
    /// let mut alone = ParameterJacobian::nan();
    /// Solver::default().solve(&robot, Request::new(q, Model::Torsion).parameter_jacobian(&mut alone)).unwrap();
    /// assert!((p.curvature[0] - alone.curvature[0]).norm() < 1e-12);
    /// ```
    pub fn jacobians(
        mut self,
        joints: &'a mut JointJacobian<T, N>,
        parameters: &'a mut ParameterJacobian<T, N>,
    ) -> Self {
        self.derivative = Some(Derivative::JointsAndParameters(joints, parameters));
        self
    }
    /// Writing the tip's compliance into `compliance` (see [`Derivative::Loads`]): the
    /// loaded solver answers, at zero load without [`loads`](Self::loads).
    pub fn compliance(mut self, compliance: &'a mut Matrix6<T>) -> Self {
        self.derivative = Some(Derivative::Loads(compliance));
        self
    }
    /// Writing backbone points into `points`.
    pub fn backbone(mut self, points: &'a mut [Vector3<T>]) -> Self {
        self.backbone = Some(points);
        self
    }
    /// Solved cold: the solver's warm-start memory is neither used nor changed.
    pub fn cold(mut self) -> Self {
        self.cold = true;
        self
    }
}

/// A combination of a request the mechanics do not model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unsupported {
    /// Loads (or a compliance) with the rigid model: the loaded solver models torsion.
    LoadsOnRigid,
    /// Clearance kinks with loads: the loaded solver has no kinks.
    ClearanceWithLoads,
    /// Boundary friction moments with the rigid model (they act on the twist).
    FrictionOnRigid,
    /// Boundary friction moments with loads.
    FrictionWithLoads,
    /// A joint or parameter Jacobian under loads.
    JacobianWithLoads,
    /// The softest mode's gradient under loads or with boundary friction moments (it is
    /// computed for the unloaded, frictionless twist).
    SoftestModeGradient,
    /// A derivative at a given solution under loads, with boundary friction moments or
    /// with a sensor offset (see `Solver::derivative_at`).
    DerivativeAtSolution,
}

impl fmt::Display for Unsupported {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Unsupported::LoadsOnRigid => {
                "loads need the torsion model: the loaded solver models torsion"
            }
            Unsupported::ClearanceWithLoads => {
                "clearance together with loads is not modelled (the loaded solver has no clearance kinks)"
            }
            Unsupported::FrictionOnRigid => {
                "boundary friction moments act on the twist: they need the torsion model"
            }
            Unsupported::FrictionWithLoads => {
                "boundary friction moments together with loads are not modelled"
            }
            Unsupported::JacobianWithLoads => {
                "joint and parameter Jacobians under loads are not computed (the compliance is)"
            }
            Unsupported::SoftestModeGradient => {
                "the softest mode's gradient is computed for the unloaded model without friction moments"
            }
            Unsupported::DerivativeAtSolution => {
                "a derivative at a given solution is computed without loads, friction moments or a sensor offset (ask for it in the solve)"
            }
        })
    }
}

/// Why a solve could not start. Solver trouble after the start is a
/// [`Status`](crate::Status), not an error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolveError {
    /// The (actual) joints are invalid for the robot.
    Joint(JointError),
    /// Gravity is modelled but a tube has no `density_kg_m3`.
    MissingDensity {
        /// tube number, 1 = outermost
        tube: usize,
    },
    /// A load value is NaN or infinite.
    NotFinite,
    /// The request combines what the mechanics do not model.
    Unsupported(Unsupported),
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::Joint(e) => e.fmt(f),
            SolveError::MissingDensity { tube } => {
                write!(
                    f,
                    "tube {tube}: density_kg_m3 is needed where gravity is modelled"
                )
            }
            SolveError::NotFinite => write!(f, "loads must be finite numbers"),
            SolveError::Unsupported(u) => u.fmt(f),
        }
    }
}

impl From<JointError> for SolveError {
    fn from(e: JointError) -> Self {
        SolveError::Joint(e)
    }
}

impl core::error::Error for SolveError {}

impl<T: Real, const N: usize> Request<'_, T, N> {
    /// The first combination of this request that the mechanics do not model.
    pub(crate) fn unsupported(&self) -> Option<Unsupported> {
        let loaded = self.loaded();
        let clearance = self
            .effects
            .is_some_and(|e| e.clearance.iter().any(Option::is_some));
        if loaded && self.model == Model::Rigid {
            Some(Unsupported::LoadsOnRigid)
        } else if loaded && clearance {
            Some(Unsupported::ClearanceWithLoads)
        } else if self.friction.is_some() && self.model == Model::Rigid {
            Some(Unsupported::FrictionOnRigid)
        } else if self.friction.is_some() && loaded {
            Some(Unsupported::FrictionWithLoads)
        } else if loaded
            && matches!(
                self.derivative,
                Some(
                    Derivative::Joints(_)
                        | Derivative::Parameters(_)
                        | Derivative::JointsAndParameters(..)
                )
            )
        {
            Some(Unsupported::JacobianWithLoads)
        } else {
            None
        }
    }

    /// True when the loaded solver answers: loads that load something, or a compliance.
    pub(crate) fn loaded(&self) -> bool {
        self.loads.is_some_and(|l| !l.is_none())
            || matches!(self.derivative, Some(Derivative::Loads(_)))
    }
}

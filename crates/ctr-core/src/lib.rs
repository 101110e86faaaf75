//! # ctr-core
//!
//! Forward kinematics of concentric tube robots (CTRs), `no_std` and allocation-free:
//! nested, precurved, elastic tubes whose bending and twist follow from their moment
//! balance. The physics follows Liu et al., "Modeling of and Experimenting with
//! Concentric Tube Robots: Considering Clearance, Friction and Torsion", Sensors 23
//! (2023) 3709, generalised to `N` tubes (1 to [`MAX_TUBES`]) with the transmissions
//! behind the guide twisting too; the equations are in [`integrate::twist`].
//!
//! One [`Request`] a [`Solver`] answers: the tip pose under the rigid or the torsion
//! model, with effects ([`Effects`]: joint offsets, clearance kinks, the tracker's
//! frame, the sensor's place), loads ([`Loads`]: the tubes' weight and a tip force and
//! moment, as Cosserat statics) or friction moments, the joint or parameter Jacobian or
//! the compliance written into the caller's buffers, and the backbone. Every
//! [`Solution`] carries its [`Status`] (a solve that does not converge is a status, not
//! an error) and its signed softest twist mode; where the branch a warm start was on
//! ends, the solver follows the robot to the stable equilibrium it snaps to. Generic
//! over `f64` and `f32` ([`Real`]).
//!
//! Conventions (`docs/formats.md`): tube 1 (index 0) is the outermost; `s_i` is
//! tube i's exposed length beyond the guide exit, `theta_i` its actuator angle about +z;
//! W has its origin at the guide exit and +z along insertion, +x where tube 1 bends with
//! zero rotations and a positive radius. Lengths are mm, angles rad inside the core.
//!
//! ```
//! use ctr_core::{Joints, Model, Request, Robot, Solver, Status, TubeParams};
//! let outer = TubeParams { curvature_radius_mm: Some(300.0), ..TubeParams::<f64>::new(1.9, 1.6, 160.0, 80.0, 58000.0, 0.33) };
//! let middle = TubeParams { curvature_radius_mm: Some(180.0), ..TubeParams::<f64>::new(1.4, 1.1, 220.0, 70.0, 58000.0, 0.33) };
//! let inner = TubeParams { curvature_radius_mm: Some(80.0), ..TubeParams::<f64>::new(0.9, 0.6, 280.0, 50.0, 58000.0, 0.33) };
//! let robot = Robot::new([outer, middle, inner])?;
//! let mut solver = Solver::default();
//! let q = Joints::from_mm_deg([30.0, 60.0, 90.0], [0.0, 45.0, -30.0]);
//! let sol = solver.solve(&robot, Request::new(q, Model::Torsion))?;
//! assert_eq!(sol.status, Status::Converged);
//! let q = sol.tip.orientation();
//! assert!((q.norm() - 1.0).abs() < 1e-12);
//! # Ok::<(), Box<dyn core::error::Error>>(())
//! ```
//!
//! # Layout
//!
//! - [`math`]: dual numbers, the SE(3) exponential, small linear algebra;
//! - [`model`]: the robot, joints, sections, effects, friction memory, loads;
//! - [`integrate`]: one RK4 over the twist, variation and loaded states, and the pass
//!   along the backbone;
//! - [`solve`]: the one [`Request`] a [`Solver`] answers, Newton's loop, the shooting,
//!   the loaded model, the Jacobians, the softest mode and its gradient, the snap.
#![no_std]
#![forbid(unsafe_code)]

/// The linear algebra crate the core is built on (its types appear in the API).
pub use nalgebra;

pub mod integrate;
pub mod math;
pub mod model;
mod real;
pub mod solve;

pub use math::se3::Frame;
pub use model::effects::{self, ClearanceProfile, Effects, Registration};
pub use model::friction::{self, BoundaryMoment, PlayFriction};
pub use model::joints::{JointError, JointKind, Joints};
pub use model::loads::{Gravity, Loads, STANDARD_GRAVITY_M_S2};
pub use model::robot::{Field, Robot, RobotError, Tube, TubeParams};
pub use real::Real;
pub use solve::jacobian::{JointJacobian, ParameterJacobian};
pub use solve::{
    Derivative, Model, Request, SoftestModeGradient, Solution, SolveError, Solver, SolverConfig,
    Status, Unsupported, DEFAULT_MAX_ITERATIONS, DEFAULT_MAX_STEP_MM, DEFAULT_STEP_FRACTION,
};

/// Most tubes a robot may have.
pub const MAX_TUBES: usize = 4;

impl core::error::Error for RobotError {}
impl core::error::Error for JointError {}

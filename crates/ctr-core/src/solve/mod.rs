//! Forward kinematics: the solver, its settings, warm start and results.
//!
//! [`Solver::solve`] answers one [`Request`] (joints, mechanics, and optionally effects,
//! loads, friction moments, a derivative, backbone points) for a validated [`Robot`]:
//! the tip frame (tube n's material frame at its tip: z the tangent, x the side its
//! precurvature bends toward) with a [`Status`] and the final boundary residual. The
//! `rigid` model keeps every tube's angle equal to its actuator angle (constant
//! curvature per section, closed form); the `torsion` model solves the twist
//! boundary-value problem of [`crate::integrate::twist`] by shooting ([`newton`]); loads
//! go to the Cosserat statics of [`crate::integrate::loaded`]. A solve never panics and
//! never allocates; a result that is not [`Status::Converged`] says so.
//!
//! - [`request`]: what a solve is asked and what it answers;
//! - [`newton`]: the one Newton loop;
//! - [`shooting`]: the unloaded model (rigid, torsion, boundary friction moments);
//! - [`loaded`]: the loaded model and its compliance;
//! - [`jacobian`]: joint and parameter Jacobians from one dual-number pass;
//! - [`softest`]: the softest mode's gradient over the joints (two dual-number passes).

pub mod jacobian;
pub mod loaded;
pub mod newton;
pub mod request;
pub mod shooting;
mod snap;
pub mod softest;

pub use request::{Derivative, Request, SolveError, Unsupported};
pub use softest::SoftestModeGradient;

use crate::math::se3::Frame;
use crate::model::joints::Joints;
use crate::model::robot::Robot;
use crate::model::sections::Sections;
use crate::real::{c, Real};

/// Which mechanics the solve uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Model {
    /// Torsionally rigid tubes: every tube's angle is its actuator angle everywhere.
    Rigid,
    /// Torsionally compliant tubes, transmissions included (see [`crate::integrate::twist`]).
    #[default]
    Torsion,
}

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// Newton's step fell below the tolerance.
    Converged,
    /// The iteration bound was reached first; the result is the best iterate.
    IterationLimit,
    /// The iteration produced non-finite numbers or a singular Jacobian; the result is
    /// the best finite iterate (where its pose is not finite, the rigid model's pose,
    /// with a softest mode of 0: a result is never NaN).
    Diverged,
}

/// Solver settings.
///
/// ```
/// let cfg = ctr_core::SolverConfig::<f64>::default();
/// assert!(cfg.max_step_mm > 0.0 && cfg.max_iterations > 0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverConfig<T> {
    /// Longest RK4 step, mm: a safety cap, and the widest spacing of backbone points
    /// (lower it for a finer backbone).
    pub max_step_mm: T,
    /// RK4 step as a fraction of each section's shortest length scale (bending radius,
    /// twist wavelength; see `sections::step_length`). [`DEFAULT_STEP_FRACTION`] keeps the
    /// tip within 1.1e-4 mm of the reference tables on the shared robots (3e-5 mm on the
    /// nitinol ones; convergence study in `crates/ctr-core/tests/convergence.rs`).
    pub step_fraction: T,
    /// Most Newton iterations (integrations with sensitivities) per start; a torsion
    /// solve makes at most three starts (warm, cold on coarse steps, cold on the full
    /// steps), each only when the one before it failed.
    pub max_iterations: u32,
    /// Newton stops when its step in every base twist rate is below this, rad/mm; the
    /// pose pass then checks the residual.
    pub step_tolerance_per_mm: T,
    /// A solve has converged when every free-tip twist rate `|u_i(s_i)|` is below this,
    /// rad/mm (a torque residual of `G J` times it).
    pub residual_tolerance_per_mm: T,
}

/// Default longest RK4 step, mm.
pub const DEFAULT_MAX_STEP_MM: f64 = 25.0;
/// Default RK4 step as a fraction of a section's length scale.
pub const DEFAULT_STEP_FRACTION: f64 = 0.15;
/// Default bound on Newton iterations.
pub const DEFAULT_MAX_ITERATIONS: u32 = 30;

/// Newton step tolerance in `f64`, rad/mm: convergence is quadratic, so the error left
/// after a step of this size is about its square, and the pose pass verifies it.
pub const F64_STEP_TOLERANCE: f64 = 1e-6;
/// Residual tolerance in `f64`, rad/mm: moves the tip by < 1e-8 mm on the shared robots.
pub const F64_RESIDUAL_TOLERANCE: f64 = 1e-12;
/// Newton step tolerance in `f32`, rad/mm.
pub const F32_STEP_TOLERANCE: f64 = 1e-5;
/// Residual tolerance in `f32`, rad/mm, a decade above the floor `f32` rounding
/// reaches (1e-10 to 1e-9); leaves < 3e-4 mm at the tip on the shared robots.
pub const F32_RESIDUAL_TOLERANCE: f64 = 1e-8;

impl<T: Real> Default for SolverConfig<T> {
    fn default() -> Self {
        // single precision has a 24-bit mantissa: epsilon 1.2e-7
        let single = T::default_epsilon() > c(1e-10);
        SolverConfig {
            max_step_mm: c(DEFAULT_MAX_STEP_MM),
            step_fraction: c(DEFAULT_STEP_FRACTION),
            max_iterations: DEFAULT_MAX_ITERATIONS,
            step_tolerance_per_mm: c(if single {
                F32_STEP_TOLERANCE
            } else {
                F64_STEP_TOLERANCE
            }),
            residual_tolerance_per_mm: c(if single {
                F32_RESIDUAL_TOLERANCE
            } else {
                F64_RESIDUAL_TOLERANCE
            }),
        }
    }
}

/// The result of one forward-kinematics solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solution<T: Real, const N: usize> {
    /// Tube n's material frame at the tip, in W (mm).
    pub tip: Frame<T>,
    /// How the solve ended.
    pub status: Status,
    /// Largest free-tip torque residual `|u_i(s_i)|`, rad/mm (0 for `rigid`).
    pub residual_per_mm: T,
    /// Newton iterations used.
    pub iterations: u32,
    /// Twist rate of each tube at the guide exit, rad/mm.
    pub base_twist_per_mm: [T; N],
    /// Angle of each tube's material frame at the guide exit, rad.
    pub base_angle_rad: [T; N],
    /// Stiffness of the softest twist mode relative to uncoupled tubes: the smallest
    /// singular value of the shooting Jacobian `d u_i(s_i) / d u_k(0)` (dimensionless; 1
    /// for tubes that do not interact), signed with its determinant. It falls to zero
    /// where the robot snaps (a fold of the twist boundary-value problem, where it goes as
    /// the square root of the joint distance left) and is negative on a branch past one
    /// (an unstable equilibrium); 1 for the `rigid` model and a single tube. The std
    /// layer turns it into a distance to the snap (`ctr_analysis::margin`).
    pub softest_mode: T,
    /// Points the backbone has ([`Request::backbone`]; written as far as the buffer
    /// reached); 0 without a buffer.
    pub backbone_points: usize,
}

impl<T: Real, const N: usize> Solution<T, N> {
    /// A solution with every number NaN, before a solve writes it.
    pub(crate) fn nan() -> Self {
        let nan = c::<T>(f64::NAN);
        let mut tip = Frame::identity();
        tip.position *= nan;
        Solution {
            tip,
            status: Status::Diverged,
            residual_per_mm: nan,
            iterations: 0,
            base_twist_per_mm: [nan; N],
            base_angle_rad: [nan; N],
            softest_mode: nan,
            backbone_points: 0,
        }
    }
}

/// Memory carried between solves along a trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
struct WarmStart<T, const N: usize> {
    /// last two solutions' unknowns and joints, newest first
    x: [[T; N]; 2],
    q: [Joints<T, N>; 2],
    count: usize,
    /// the newest solution's stability margin
    margin: T,
}

/// A forward-kinematics solver: settings plus warm-start memory, no heap.
///
/// ```
/// use ctr_core::{Joints, Model, Request, Robot, Solver, Status, TubeParams};
/// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
/// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
/// let robot = Robot::new([outer, inner]).unwrap();
/// let mut solver = Solver::default();
/// let q = Joints::from_mm_deg([40.0, 90.0], [0.0, 120.0]);
/// let sol = solver.solve(&robot, Request::new(q, Model::Torsion)).unwrap();
/// assert_eq!(sol.status, Status::Converged);
/// assert!(sol.tip.position.z > 50.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solver<T, const N: usize> {
    /// Settings.
    pub config: SolverConfig<T>,
    warm: WarmStart<T, N>,
    /// last loaded solve's unknowns and chord Jacobian (see [`loaded`])
    pub(crate) loaded: Option<loaded::LoadedWarm<T, N>>,
}

impl<T: Real, const N: usize> Default for Solver<T, N> {
    fn default() -> Self {
        Self::new(SolverConfig::default())
    }
}

/// The derivative `d` of the tip (with the tip's rotation `rotation` before the
/// measurement) as `e`'s measurement sees it.
fn measured_derivative<T: Real, const N: usize>(
    e: &crate::model::effects::Effects<T, N>,
    rotation: &nalgebra::Matrix3<T>,
    d: &mut Derivative<'_, T, N>,
) {
    // the derivatives' lever arm is the sensor offset turned into W at the tip
    let arm = rotation * nalgebra::Vector3::from(e.sensor_offset_mm);
    let measure = |c: &mut nalgebra::Vector6<T>| *c = e.measured_column(c, &arm);
    match d {
        Derivative::Joints(j) => j
            .feed
            .iter_mut()
            .chain(j.rotation.iter_mut())
            .for_each(measure),
        Derivative::Parameters(j) => j.columns_mut().for_each(measure),
        Derivative::JointsAndParameters(j, p) => j
            .feed
            .iter_mut()
            .chain(j.rotation.iter_mut())
            .chain(p.columns_mut())
            .for_each(measure),
        Derivative::Loads(m) => {
            for k in 0..6 {
                let mut col: nalgebra::Vector6<T> = m.column(k).into_owned();
                measure(&mut col);
                m.set_column(k, &col);
            }
        }
    }
}

impl<T: Real, const N: usize> Solver<T, N> {
    /// A solver with the given settings and no warm-start memory.
    ///
    /// ```
    /// let s = ctr_core::Solver::<f64, 3>::new(ctr_core::SolverConfig { max_step_mm: 2.0, ..Default::default() });
    /// assert_eq!(s.config.max_step_mm, 2.0);
    /// ```
    pub fn new(config: SolverConfig<T>) -> Self {
        let q = Joints::new([T::zero(); N], [T::zero(); N]);
        Solver {
            config,
            warm: WarmStart {
                x: [[T::zero(); N]; 2],
                q: [q; 2],
                count: 0,
                margin: T::one(),
            },
            loaded: None,
        }
    }

    /// Forgets the warm-start memory: the next solve starts cold.
    ///
    /// ```
    /// let mut s = ctr_core::Solver::<f64, 2>::default();
    /// s.reset();
    /// ```
    pub fn reset(&mut self) {
        self.warm.count = 0;
        self.loaded = None;
    }

    /// Solves a [`Request`], warm-started from this solver's previous solves
    /// (extrapolated along the joint-space direction of the last two) unless the request
    /// is cold. Errors only for joints the robot cannot take, unusable loads and
    /// combinations the mechanics do not model; solver trouble is a [`Status`].
    ///
    /// ```
    /// # use ctr_core::{Joints, Model, Request, Robot, Solver, TubeParams};
    /// # let robot = Robot::new([TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) }]).unwrap();
    /// let mut solver = Solver::default();
    /// let sol = solver.solve(&robot, Request::new(Joints::from_mm_deg([50.0], [0.0]), Model::Torsion)).unwrap();
    /// // one tube: an arc of radius 100 mm over 50 mm bends toward +x
    /// let r = 100.0_f64;
    /// assert!((sol.tip.position.x - r * (1.0 - (50.0 / r).cos())).abs() < 1e-9);
    /// ```
    pub fn solve(
        &mut self,
        robot: &Robot<T, N>,
        request: Request<'_, T, N>,
    ) -> Result<Solution<T, N>, SolveError> {
        if let Some(u) = request.unsupported() {
            return Err(SolveError::Unsupported(u));
        }
        let q = match request.effects {
            Some(e) => e.actual(&request.joints),
            None => request.joints,
        };
        q.validate(robot)?;
        // a cold request keeps the memory for the solves after it
        let memory = request.cold.then(|| {
            let m = (self.warm, self.loaded);
            self.reset();
            m
        });
        let answer = self.answer(robot, &q, request);
        if let Some((warm, loaded)) = memory {
            self.warm = warm;
            self.loaded = loaded;
        }
        answer
    }

    /// [`solve`](Self::solve) on the checked actual joints `q`: the mechanics, then the
    /// tip and its derivative as measured.
    #[inline(always)]
    fn answer(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        mut request: Request<'_, T, N>,
    ) -> Result<Solution<T, N>, SolveError> {
        let sections = self.sections(robot, q);
        let effects = request.effects;
        let loaded = request.loaded();
        let mut derivative = request.derivative.take();
        let mut sol = if loaded {
            self.loaded_answer(robot, q, &sections, request, derivative.as_mut())?
        } else {
            self.unloaded_answer(robot, q, &sections, request, derivative.as_mut())
        };
        if let Some(e) = effects {
            if let Some(d) = derivative.as_mut() {
                measured_derivative(e, &sol.tip.rotation, d);
            }
            sol.tip = e.measured(&sol.tip);
        }
        Ok(sol)
    }

    /// The derivative `request` asks for (a joint or a parameter Jacobian, or both) at
    /// `solution`, a solution of the same request without it from a solver with this
    /// one's settings, without solving again: the same numbers as asking for it in the
    /// solve (the solve's warm start does not depend on it, so a chain of plain solves
    /// can be differentiated afterwards, row by row on any thread). Not under loads,
    /// with boundary friction moments or with a sensor offset (whose lever arm needs the
    /// tip before the measurement): [`SolveError::Unsupported`].
    ///
    /// ```
    /// use ctr_core::{JointJacobian, Joints, Model, Request, Robot, Solver, TubeParams};
    /// let robot = Robot::new([TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) }]).unwrap();
    /// let q = Joints::new([50.0], [0.3]);
    /// let mut solver = Solver::default();
    /// let plain = solver.clone().solve(&robot, Request::new(q, Model::Torsion)).unwrap();
    /// let (mut later, mut within) = (JointJacobian::nan(), JointJacobian::nan());
    /// solver.derivative_at(&robot, Request::new(q, Model::Torsion).joint_jacobian(&mut later), &plain).unwrap();
    /// solver.solve(&robot, Request::new(q, Model::Torsion).joint_jacobian(&mut within)).unwrap();
    /// assert_eq!(later, within);
    /// ```
    pub fn derivative_at(
        &self,
        robot: &Robot<T, N>,
        mut request: Request<'_, T, N>,
        solution: &Solution<T, N>,
    ) -> Result<(), SolveError> {
        if let Some(u) = request.unsupported() {
            return Err(SolveError::Unsupported(u));
        }
        let offset = request
            .effects
            .is_some_and(|e| e.sensor_offset_mm.iter().any(|v| *v != T::zero()));
        let friction = request
            .friction
            .is_some_and(|f| f.iter().any(|v| *v != T::zero()));
        if request.loaded() || friction || offset {
            return Err(SolveError::Unsupported(Unsupported::DerivativeAtSolution));
        }
        let q = match request.effects {
            Some(e) => e.actual(&request.joints),
            None => request.joints,
        };
        q.validate(robot)?;
        let sections = self.sections(robot, &q);
        let setup = shooting::unloaded_setup(robot, &q, &sections, &request);
        let Some(mut derivative) = request.derivative.take() else {
            return Ok(());
        };
        shooting::derivative_of(
            &setup,
            &solution.base_twist_per_mm,
            request.model,
            &mut derivative,
        );
        if let Some(e) = request.effects {
            measured_derivative(e, &solution.tip.rotation, &mut derivative);
        }
        Ok(())
    }

    /// The backbone's sections at `q` with this solver's step settings.
    pub(crate) fn sections(&self, robot: &Robot<T, N>, q: &Joints<T, N>) -> Sections<T, N> {
        let k = robot.each(|t| t.curvature_per_mm());
        Sections::new(
            robot,
            &q.s_mm,
            &k,
            self.config.max_step_mm,
            self.config.step_fraction,
        )
    }

    /// Warm-start guess: linear extrapolation of the last two solutions along the
    /// projection of the joint step onto the last step.
    fn guess(&self, q: &Joints<T, N>) -> [T; N] {
        match self.warm.count {
            0 => [T::zero(); N],
            1 => self.warm.x[0],
            _ => {
                let alpha = extrapolation(q, &self.warm.q[0], &self.warm.q[1]);
                let mut x = self.warm.x[0];
                for i in 0..N {
                    x[i] += (self.warm.x[0][i] - self.warm.x[1][i]) * alpha;
                }
                x
            }
        }
    }

    /// Keeps a converged solution for the next guess; `continued`: it continues the
    /// branch of the last one (its warm start converged there), so that the two may be
    /// extrapolated. After a snap or a retry the last one is forgotten: a line through
    /// solutions on two branches points nowhere (along small joint steps it sent the
    /// next guess into a third equilibrium's basin, the tip jumping 208 mm).
    fn remember(&mut self, q: &Joints<T, N>, base_twist: &[T; N], margin: T, continued: bool) {
        self.warm.margin = margin;
        self.warm.x[1] = self.warm.x[0];
        self.warm.q[1] = self.warm.q[0];
        self.warm.x[0] = *base_twist;
        self.warm.q[0] = *q;
        self.warm.count = if continued {
            (self.warm.count + 1).min(2)
        } else {
            1
        };
    }
}

/// How far to extrapolate along the last step of a trajectory: the projection of the
/// new joint step `q - q1` onto the last one `q1 - q0`, as a fraction of it, in [0, 2].
/// Feeds (mm) and angles (rad) weigh alike; they only set the fraction.
pub(crate) fn extrapolation<T: Real, const N: usize>(
    q: &Joints<T, N>,
    q1: &Joints<T, N>,
    q0: &Joints<T, N>,
) -> T {
    let mut num = T::zero();
    let mut den = T::zero();
    for i in 0..N {
        let a = q.s_mm[i] - q1.s_mm[i];
        let b = q1.s_mm[i] - q0.s_mm[i];
        let ta = q.theta_rad[i] - q1.theta_rad[i];
        let tb = q1.theta_rad[i] - q0.theta_rad[i];
        num += a * b + ta * tb;
        den += b * b + tb * tb;
    }
    if den > T::zero() {
        (num / den).max(T::zero()).min(c(2.0))
    } else {
        T::zero()
    }
}

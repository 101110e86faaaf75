//! Forward kinematics: the solver, its settings, warm start and results.
//!
//! [`Solver::solve`] takes a validated [`Robot`] and [`Joints`] and returns the tip
//! frame (tube n's material frame at its tip: z the tangent, x the side its precurvature
//! bends toward) with a [`Status`] and the final boundary residual. The `rigid` model
//! keeps every tube's angle equal to its actuator angle (constant curvature per section,
//! closed form); the `torsion` model solves the twist boundary-value problem of
//! [`crate::twist`] by shooting. A solve never panics and never allocates; a result
//! that is not [`Status::Converged`] says so.

use crate::effects::{ClearanceProfile, Effects};
use crate::joints::{JointError, Joints};
use crate::real::{c, Real};
use crate::robot::Robot;
use crate::se3::{exp, Frame};
use crate::sections::Sections;

use crate::twist::{self, inner_twist, PointSink, State};
use nalgebra::Vector3;

/// Which mechanics the solve uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Model {
    /// Torsionally rigid tubes: every tube's angle is its actuator angle everywhere.
    Rigid,
    /// Torsionally compliant tubes, transmissions included (see [`crate::twist`]).
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
    /// the best finite iterate.
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
    /// Most Newton iterations (integrations with sensitivities) per solve.
    pub max_iterations: u32,
    /// Newton stops when its step in every base twist rate is below this, rad/mm; the
    /// pose pass then checks the residual.
    pub step_tolerance_per_mm: T,
    /// A solve has converged when every free-tip twist rate `|u_i(s_i)|` is below this,
    /// rad/mm (a torque residual of `G J` times it).
    pub residual_tolerance_per_mm: T,
}

/// The coarse phase of a cold solve ends when Newton's step is this many times the
/// step tolerance: closer than that, the coarse grid's own error dominates.
const COARSE_STEP_TOLERANCE_FACTOR: f64 = 100.0;

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
    /// Elastic stability margin: the smallest singular value of the shooting Jacobian
    /// `d u_i(s_i) / d u_k(0)` (dimensionless; 1 for tubes that do not interact), signed
    /// with its determinant. It falls to zero where the robot snaps (a bifurcation of the
    /// twist boundary-value problem) and is negative on a branch past one (an unstable
    /// equilibrium); 1 for the `rigid` model and a single tube.
    pub stability_margin: T,
}

/// Memory carried between solves along a trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
struct WarmStart<T, const N: usize> {
    /// last two solutions' unknowns and joints, newest first
    x: [[T; N]; 2],
    q: [Joints<T, N>; 2],
    count: usize,
}

/// A forward-kinematics solver: settings plus warm-start memory, no heap.
///
/// ```
/// use ctr_core::{Joints, Model, Robot, Solver, Status, TubeParams};
/// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
/// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
/// let robot = Robot::new([outer, inner]).unwrap();
/// let mut solver = Solver::default();
/// let q = Joints::from_mm_deg([40.0, 90.0], [0.0, 120.0]);
/// let sol = solver.solve(&robot, &q, Model::Torsion).unwrap();
/// assert_eq!(sol.status, Status::Converged);
/// assert!(sol.tip.position.z > 50.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solver<T, const N: usize> {
    /// Settings.
    pub config: SolverConfig<T>,
    warm: WarmStart<T, N>,
    /// last loaded solve's unknowns and chord Jacobian (see [`crate::loads`])
    pub(crate) loaded: Option<crate::loads::LoadedWarm<T, N>>,
}

impl<T: Real, const N: usize> Default for Solver<T, N> {
    fn default() -> Self {
        Self::new(SolverConfig::default())
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

    /// Solves the forward kinematics, warm-started from the previous solves of this
    /// solver (extrapolated along the joint-space direction of the last two).
    /// Errors only for joints the robot cannot take; solver trouble is a [`Status`].
    ///
    /// ```
    /// # use ctr_core::{Joints, Model, Robot, Solver, TubeParams};
    /// # let robot = Robot::new([TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) }]).unwrap();
    /// let mut solver = Solver::default();
    /// let sol = solver.solve(&robot, &Joints::from_mm_deg([50.0], [0.0]), Model::Torsion).unwrap();
    /// // one tube: an arc of radius 100 mm over 50 mm bends toward +x
    /// let r = 100.0_f64;
    /// assert!((sol.tip.position.x - r * (1.0 - (50.0 / r).cos())).abs() < 1e-9);
    /// ```
    pub fn solve(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
    ) -> Result<Solution<T, N>, JointError> {
        self.solve_into(robot, q, model, None).map(|(s, _)| s)
    }

    /// As [`solve`](Self::solve), ignoring and keeping the warm-start memory.
    ///
    /// ```
    /// # use ctr_core::{Joints, Model, Robot, Solver, TubeParams};
    /// # let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// let sol = Solver::default().solve_cold(&robot, &Joints::from_mm_deg([50.0], [0.0]), Model::Rigid).unwrap();
    /// assert!((sol.tip.position.z - 50.0).abs() < 1e-12); // a straight tube
    /// ```
    pub fn solve_cold(
        &self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
    ) -> Result<Solution<T, N>, JointError> {
        let mut s = *self;
        s.reset();
        s.solve(robot, q, model)
    }

    /// Solves and writes backbone points (positions in W, mm, from the guide exit to the
    /// tip, one per integration step; the guide exit itself first) into `points`.
    /// Returns the solution and the number of points the backbone has; if that exceeds
    /// `points.len()`, only the first `points.len()` were written.
    ///
    /// ```
    /// # use ctr_core::{Joints, Model, Robot, Solver, TubeParams};
    /// # let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// let mut pts = [nalgebra::Vector3::zeros(); 64];
    /// let (_, n) = Solver::default().solve_backbone(&robot, &Joints::from_mm_deg([40.0], [0.0]), Model::Torsion, &mut pts).unwrap();
    /// assert!(n > 2 && n <= 64);
    /// assert!((pts[n - 1].z - 40.0).abs() < 1e-12);
    /// ```
    pub fn solve_backbone(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
        points: &mut [Vector3<T>],
    ) -> Result<(Solution<T, N>, usize), JointError> {
        self.solve_into(robot, q, model, Some(points))
    }

    /// Solves with kinematic effects (see [`crate::effects`]): joint offsets are added to
    /// the commanded joints, clearance kinks bend the backbone where tubes leave each
    /// other, and the tip is reported as measured (sensor offset, then registration).
    ///
    /// ```
    /// use ctr_core::{effects::{Effects, Registration}, Joints, Model, Robot, Solver, TubeParams};
    /// let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 0.0, 58000.0, 0.33)]).unwrap();
    /// let effects = Effects {
    ///     registration: Some(Registration::from_axis_angle([0.0, 0.0, 1.0], 0.0, [1.0, 2.0, 3.0])),
    ///     ..Default::default()
    /// };
    /// let sol = Solver::default().solve_with(&robot, &Joints::new([50.0], [0.0]), Model::Torsion, &effects).unwrap();
    /// assert!((sol.tip.position.z - 53.0).abs() < 1e-12);
    /// ```
    pub fn solve_with(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
        effects: &Effects<T, N>,
    ) -> Result<Solution<T, N>, JointError> {
        let actual = effects.actual(q);
        let (mut sol, _) = self.solve_effects(robot, &actual, model, None, &effects.clearance)?;
        sol.tip = effects.measured(&sol.tip);
        Ok(sol)
    }

    fn solve_into(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
        points: Option<&mut [Vector3<T>]>,
    ) -> Result<(Solution<T, N>, usize), JointError> {
        self.solve_effects(robot, q, model, points, &[None; N])
    }

    fn solve_effects(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
        points: Option<&mut [Vector3<T>]>,
        clearance: &[Option<ClearanceProfile<T>>; N],
    ) -> Result<(Solution<T, N>, usize), JointError> {
        q.validate(robot)?;
        let sections = self.sections(robot, q);
        Ok(self.solve_sections(robot, q, model, &sections, points, clearance))
    }

    /// The backbone's sections at `q` with this solver's step settings.
    pub(crate) fn sections(&self, robot: &Robot<T, N>, q: &Joints<T, N>) -> Sections<T, N> {
        let k = robot.tubes().map(|t| t.curvature_per_mm());
        Sections::new(
            robot,
            &q.s_mm,
            &k,
            self.config.max_step_mm,
            self.config.step_fraction,
        )
    }

    /// [`solve_effects`](Self::solve_effects) on validated joints and their sections.
    pub(crate) fn solve_sections(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
        sections: &Sections<T, N>,
        points: Option<&mut [Vector3<T>]>,
        clearance: &[Option<ClearanceProfile<T>>; N],
    ) -> (Solution<T, N>, usize) {
        let mut sink = PointSink {
            buf: points,
            written: 0,
            needed: 0,
        };
        let (sol, n) = match model {
            Model::Rigid => (rigid(q, sections, clearance, &mut sink), sink.needed),
            Model::Torsion => {
                let guess = self.guess(q);
                let cold = self.warm.count == 0;
                let mut sol = self.shoot(robot, q, sections, guess, cold, clearance, &mut sink);
                if sol.status != Status::Converged && !cold {
                    // a warm start from far away can land in another basin: retry cold
                    let iterations = sol.iterations;
                    sol = self.shoot(
                        robot,
                        q,
                        sections,
                        [T::zero(); N],
                        true,
                        clearance,
                        &mut sink,
                    );
                    sol.iterations += iterations;
                }
                if sol.status == Status::Converged {
                    self.remember(q, &sol.base_twist_per_mm);
                }
                (sol, sink.needed)
            }
        };
        (sol, n)
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

    fn remember(&mut self, q: &Joints<T, N>, base_twist: &[T; N]) {
        self.warm.x[1] = self.warm.x[0];
        self.warm.q[1] = self.warm.q[0];
        self.warm.x[0] = *base_twist;
        self.warm.q[0] = *q;
        self.warm.count = (self.warm.count + 1).min(2);
    }

    /// Newton shooting on the base twist rates, then one pass for the pose.
    ///
    /// Newton stops on its step size (`step_tolerance_per_mm`): convergence is
    /// quadratic, so the error left after a step of size d is about d^2. The pose pass
    /// integrates the twist once more and measures the residual it leaves; only if that
    /// exceeds `residual_tolerance_per_mm` does Newton go on.
    fn shoot(
        &self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        sections: &Sections<T, N>,
        guess: [T; N],
        cold: bool,
        clearance: &[Option<ClearanceProfile<T>>; N],
        sink: &mut PointSink<'_, T>,
    ) -> Solution<T, N> {
        let m = N - 1;
        // a cold start first converges on the coarse grid (cheap), then refines
        let mut coarse = cold;
        let cfg = &self.config;
        let huge = T::max_value().unwrap_or(T::one());
        let mut x = guess;
        let mut iterations = 0;
        let mut best = (x, huge);
        let mut prev_norm = huge;
        let mut last_step = [T::zero(); N];
        let mut last_jac = [[T::zero(); N]; N];
        let mut damping = T::one();
        let mut diverged = false;
        loop {
            // Newton until the step is small
            while m > 0 && iterations < cfg.max_iterations {
                iterations += 1;
                let (r, jac) = residual::<T, N, true>(robot, q, sections, &x, coarse);
                let norm = max_abs(&r, m);
                if !norm.is_finite() {
                    diverged = true;
                    break;
                }
                if norm < best.1 {
                    best = (x, norm);
                }
                if norm > prev_norm * c(1.5) && damping > c(1.0 / 64.0) {
                    // the last step overshot: go back half way and try again
                    damping *= c(0.5);
                    for i in 0..m {
                        x[i] += last_step[i] * damping;
                    }
                    continue;
                }
                prev_norm = norm;
                damping = T::one();
                last_jac = jac;
                let Some(dx) = solve_linear::<T, N>(jac, r, m) else {
                    diverged = true;
                    break;
                };
                let mut step = T::zero();
                for i in 0..m {
                    x[i] -= dx[i];
                    last_step[i] = dx[i];
                    step = step.max(dx[i].abs());
                }
                if !step.is_finite() {
                    diverged = true;
                    break;
                }
                if coarse && step <= cfg.step_tolerance_per_mm * c(COARSE_STEP_TOLERANCE_FACTOR) {
                    coarse = false;
                    prev_norm = huge;
                    best.1 = huge;
                } else if step <= cfg.step_tolerance_per_mm {
                    break;
                }
            }
            if diverged || !all_finite(&x) {
                diverged = true;
                x = best.0;
            }
            sink.written = 0;
            sink.needed = 0;
            let mut sol = pose_pass(robot, q, sections, &x, clearance, sink);
            sol.iterations = iterations;
            sol.stability_margin = if m > 0 && iterations > 0 {
                smallest_singular_value(&last_jac, m)
            } else {
                T::one()
            };
            let r = sol.residual_per_mm;
            let finite = sol.tip.position.iter().all(|v| v.is_finite()) && r.is_finite();
            sol.status = if diverged || !finite {
                Status::Diverged
            } else if r <= cfg.residual_tolerance_per_mm {
                Status::Converged
            } else if iterations < cfg.max_iterations {
                prev_norm = huge;
                continue;
            } else {
                Status::IterationLimit
            };
            return sol;
        }
    }
}

fn all_finite<T: Real, const N: usize>(x: &[T; N]) -> bool {
    x.iter().all(|v| v.is_finite())
}

fn max_abs<T: Real, const N: usize>(r: &[T; N], m: usize) -> T {
    let mut n = T::zero();
    for v in r.iter().take(m) {
        if !v.is_finite() {
            return T::max_value().unwrap_or(T::one()) * c(2.0);
        }
        n = n.max(v.abs());
    }
    n
}

/// Initial twist state at the guide exit for unknowns `x`, and tube n's angle there.
fn initial_state<T: Real, const N: usize, const SENS: bool>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    x: &[T; N],
) -> (State<T, N>, T, T, [T; N]) {
    let gj = robot.tubes().map(|t| t.torsional_stiffness_nmm2());
    let mut st = State::zero();
    let present = if sections.len > 0 {
        sections.list[0].present
    } else {
        [false; N]
    };
    for j in 0..N - 1 {
        st.w[j] = x[j];
        if SENS {
            st.dw[j][j] = T::one();
        }
    }
    let (un, dun) = inner_twist::<T, N, SENS>(&present, &gj, &st.w, &st.dw);
    let trans_n = robot.tubes()[N - 1].params().length_mm - q.s_mm[N - 1];
    let psi_n = q.theta_rad[N - 1] + trans_n * un;
    for j in 0..N - 1 {
        let trans = robot.tubes()[j].params().length_mm - q.s_mm[j];
        let b = q.theta_rad[j] + trans * x[j] - psi_n;
        let (s, co) = b.sin_cos();
        st.z[j] = [co, s];
        if SENS {
            for k in 0..N - 1 {
                st.db[j][k] = -trans_n * dun[k];
            }
            st.db[j][j] += trans;
        }
    }
    (st, psi_n, un, gj)
}

/// Residuals `u_i(s_i)` and their Jacobian `d r_i / d x_k` for `i, k < N-1`.
fn residual<T: Real, const N: usize, const SENS: bool>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    x: &[T; N],
    coarse: bool,
) -> ([T; N], [[T; N]; N]) {
    let (mut st, _, _, gj) = initial_state::<T, N, SENS>(robot, q, sections, x);
    let mut r = [T::zero(); N];
    let mut jac = [[T::zero(); N]; N];
    let mut done = [false; N];
    let mut frame = Frame::identity();
    let mut sink = PointSink {
        buf: None,
        written: 0,
        needed: 0,
    };
    let record =
        |st: &State<T, N>, at: T, done: &mut [bool; N], r: &mut [T; N], jac: &mut [[T; N]; N]| {
            for j in 0..N - 1 {
                if !done[j] && q.s_mm[j] <= at {
                    done[j] = true;
                    r[j] = st.w[j];
                    jac[j] = st.dw[j];
                }
            }
        };
    record(&st, T::zero(), &mut done, &mut r, &mut jac);
    for sec in sections.list.iter().take(sections.len) {
        twist::section::<T, N, SENS, false>(sec, coarse, &gj, &mut st, &mut frame, &mut sink);
        record(&st, sec.end, &mut done, &mut r, &mut jac);
    }
    record(
        &st,
        T::max_value().unwrap_or(T::one()),
        &mut done,
        &mut r,
        &mut jac,
    );
    (r, jac)
}

/// Integrates the converged twist once more and chains the pose.
fn pose_pass<T: Real, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    x: &[T; N],
    clearance: &[Option<ClearanceProfile<T>>; N],
    sink: &mut PointSink<'_, T>,
) -> Solution<T, N> {
    let (mut st, psi_n, un0, gj) = initial_state::<T, N, false>(robot, q, sections, x);
    let mut base_twist = *x;
    base_twist[N - 1] = un0;
    let mut base_angle = [T::zero(); N];
    for j in 0..N {
        let trans = robot.tubes()[j].params().length_mm - q.s_mm[j];
        base_angle[j] = q.theta_rad[j] + trans * base_twist[j];
    }
    let mut frame = Frame::identity();
    let (s, co) = psi_n.sin_cos();
    frame.rotate_z((co, s));
    sink.push(&frame.position);
    let mut residual = T::zero();
    let mut done = [false; N];
    let record = |st: &State<T, N>, at: T, done: &mut [bool; N], residual: &mut T| {
        for j in 0..N - 1 {
            if !done[j] && q.s_mm[j] <= at {
                done[j] = true;
                *residual = residual.max(st.w[j].abs());
                if !st.w[j].is_finite() {
                    *residual = T::max_value().unwrap_or(T::one());
                }
            }
        }
    };
    record(&st, T::zero(), &mut done, &mut residual);
    let mut kinked = [false; N];
    kinks(q, clearance, &st, T::zero(), &mut kinked, &mut frame);
    for sec in sections.list.iter().take(sections.len) {
        twist::section::<T, N, false, true>(sec, false, &gj, &mut st, &mut frame, sink);
        record(&st, sec.end, &mut done, &mut residual);
        kinks(q, clearance, &st, sec.end, &mut kinked, &mut frame);
    }
    Solution {
        tip: frame,
        status: Status::Converged,
        residual_per_mm: residual,
        stability_margin: T::one(),
        iterations: 0,
        base_twist_per_mm: base_twist,
        base_angle_rad: base_angle,
    }
}

/// The torsionally rigid model: constant curvature per section, exact exponentials.
fn rigid<T: Real, const N: usize>(
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    clearance: &[Option<ClearanceProfile<T>>; N],
    sink: &mut PointSink<'_, T>,
) -> Solution<T, N> {
    let mut st = State::<T, N>::zero();
    let tn = q.theta_rad[N - 1];
    for j in 0..N - 1 {
        let (s, co) = (q.theta_rad[j] - tn).sin_cos();
        st.z[j] = [co, s];
    }
    let mut frame = Frame::identity();
    let (s, co) = tn.sin_cos();
    frame.rotate_z((co, s));
    sink.push(&frame.position);
    let e3 = Vector3::z();
    let mut kinked = [false; N];
    kinks(q, clearance, &st, T::zero(), &mut kinked, &mut frame);
    for sec in sections.list.iter().take(sections.len) {
        let rate = twist::body_rate(sec, &st, T::zero());
        let len = sec.end - sec.start;
        let sub = if sink.active() {
            twist::steps(len, sec.h)
        } else {
            1
        };
        let h = len / nalgebra::convert::<f64, T>(sub as f64);
        let (r, p) = exp(rate * h, e3 * h);
        for _ in 0..sub {
            frame.compose(&r, &p);
            sink.push(&frame.position);
        }
        kinks(q, clearance, &st, sec.end, &mut kinked, &mut frame);
    }
    Solution {
        tip: frame,
        status: Status::Converged,
        residual_per_mm: T::zero(),
        iterations: 0,
        base_twist_per_mm: [T::zero(); N],
        base_angle_rad: q.theta_rad,
        stability_margin: T::one(),
    }
}

/// Applies the clearance kinks of the tubes whose tips lie at `at` (where the next
/// tube leaves them).
fn kinks<T: Real, const N: usize>(
    q: &Joints<T, N>,
    clearance: &[Option<ClearanceProfile<T>>; N],
    st: &State<T, N>,
    at: T,
    kinked: &mut [bool; N],
    frame: &mut Frame<T>,
) {
    for i in 0..N - 1 {
        if kinked[i] || q.s_mm[i] > at {
            continue;
        }
        kinked[i] = true;
        if let Some(profile) = &clearance[i] {
            if q.s_mm[i + 1] > q.s_mm[i] {
                crate::effects::kink(frame, profile, st.z[i], st.z[i + 1]);
            }
        }
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

/// Smallest singular value of the leading `m x m` block (m <= 3), from the eigenvalues
/// of `J^T J`, signed with `det J`; unused dimensions are padded so they never count.
fn smallest_singular_value<T: Real, const N: usize>(jac: &[[T; N]; N], m: usize) -> T {
    if m == 1 {
        return jac[0][0];
    }
    if m == 2 {
        // closed form for 2x2: sigma_min = |det| / sigma_max, sigma_max^2 the larger
        // eigenvalue of J^T J
        let (a, b, cc, d) = (jac[0][0], jac[0][1], jac[1][0], jac[1][1]);
        let det = a * d - b * cc;
        let fro = a * a + b * b + cc * cc + d * d;
        let disc = (fro * fro - det * det * c(4.0)).max(T::zero()).sqrt();
        let smax = ((fro + disc) * c(0.5)).sqrt();
        return if smax > T::zero() {
            det / smax
        } else {
            T::zero()
        };
    }
    const PAD: f64 = 1e30;
    let mut a = nalgebra::Matrix3::<T>::from_diagonal_element(c(PAD));
    for i in 0..m.min(3) {
        for k in 0..m.min(3) {
            a[(i, k)] = jac[i][k];
        }
    }
    let ata = a.transpose() * a;
    let eig = nalgebra::SymmetricEigen::new(ata).eigenvalues;
    let min = eig
        .iter()
        .fold(T::max_value().unwrap_or(T::one()), |acc, &v| acc.min(v));
    // the sign of det J tells the branches apart: it is +1 with no coupling (J = I) and
    // flips at every bifurcation the solution passes
    let sigma = min.max(T::zero()).sqrt();
    if a.determinant() < T::zero() {
        -sigma
    } else {
        sigma
    }
}

/// Solves `J dx = r` for the leading `m x m` block by Gaussian elimination with
/// partial pivoting; `None` if singular.
pub(crate) fn solve_linear<T: Real, const N: usize>(
    mut a: [[T; N]; N],
    mut b: [T; N],
    m: usize,
) -> Option<[T; N]> {
    let mut scale = T::zero();
    for row in a.iter().take(m) {
        for v in row.iter().take(m) {
            scale = scale.max(v.abs());
        }
    }
    let tiny = scale * T::default_epsilon() * c(16.0);
    for col in 0..m {
        let mut piv = col;
        for row in col + 1..m {
            if a[row][col].abs() > a[piv][col].abs() {
                piv = row;
            }
        }
        let pivot = a[piv][col].abs();
        if pivot <= tiny || !pivot.is_finite() {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..m {
            let f = a[row][col] / a[col][col];
            for k in col..m {
                let v = a[col][k];
                a[row][k] -= f * v;
            }
            let v = b[col];
            b[row] -= f * v;
        }
    }
    let mut x = [T::zero(); N];
    for col in (0..m).rev() {
        let mut acc = b[col];
        for k in col + 1..m {
            acc -= a[col][k] * x[k];
        }
        x[col] = acc / a[col][col];
    }
    Some(x)
}

//! A robot whose tube count is known only at run time, and forward kinematics on it.
//!
//! The core fixes the tube count `N` at compile time ([`Robot<f64, N>`]); a file can hold
//! 1 to [`MAX_TUBES`] tubes, so [`AnyRobot`] is an enum over the four sizes and every
//! method dispatches to the core with the matching `N`. Joint vectors cross this
//! boundary as slices in file order: `s1_mm, theta1_deg, s2_mm, theta2_deg, ...`.
//!
//! Tip orientations are returned as quaternions `(w, x, y, z)` with a canonical sign:
//! `w >= 0`, and when `w == 0` the first non-zero of `x, y, z` is positive, so that the
//! same rotation always prints the same four numbers.

use ctr_core::{
    JointError, Joints, Model, Request, Robot, RobotError, Solution, SolveError, Solver, Status,
    TubeParams, MAX_TUBES,
};
use nalgebra::UnitQuaternion;

/// A validated robot of 1 to [`MAX_TUBES`] tubes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AnyRobot {
    /// One tube.
    One(Robot<f64, 1>),
    /// Two tubes.
    Two(Robot<f64, 2>),
    /// Three tubes.
    Three(Robot<f64, 3>),
    /// Four tubes.
    Four(Robot<f64, 4>),
}

/// Runs `$body` with `$r` bound to the inner `Robot<f64, N>` of an [`AnyRobot`].
macro_rules! with_robot {
    ($robot:expr, $r:ident => $body:expr) => {
        match $robot {
            AnyRobot::One($r) => $body,
            AnyRobot::Two($r) => $body,
            AnyRobot::Three($r) => $body,
            AnyRobot::Four($r) => $body,
        }
    };
}

/// The result of one forward-kinematics solve, in file units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FkResult {
    /// Tip position in W, mm: `x, y, z`.
    pub position: [f64; 3],
    /// Tip orientation, unit quaternion `w, x, y, z`, canonical sign (see module docs).
    pub quaternion: [f64; 4],
    /// How the solve ended.
    pub status: Status,
    /// Largest free-tip torque residual, rad/mm (0 for the rigid model).
    pub residual_per_mm: f64,
    /// Newton iterations used.
    pub iterations: u32,
}

impl FkResult {
    /// Converts a core solution.
    pub fn from_solution<const N: usize>(sol: &Solution<f64, N>) -> Self {
        let p = sol.tip.position;
        FkResult {
            position: [p.x, p.y, p.z],
            quaternion: canonical_quaternion(&sol.tip.orientation()),
            status: sol.status,
            residual_per_mm: sol.residual_per_mm,
            iterations: sol.iterations,
        }
    }
}

/// `(w, x, y, z)` of `q` with the canonical sign: `w >= 0`; for `w == 0` the first
/// non-zero of `x, y, z` positive.
///
/// ```
/// use nalgebra::{Quaternion, UnitQuaternion};
/// let q = UnitQuaternion::from_quaternion(Quaternion::new(-0.6, 0.8, 0.0, 0.0));
/// assert_eq!(ctr_analysis::canonical_quaternion(&q), [0.6, -0.8, 0.0, 0.0]);
/// ```
pub fn canonical_quaternion(q: &UnitQuaternion<f64>) -> [f64; 4] {
    let v = [q.w, q.i, q.j, q.k];
    let lead = v.iter().copied().find(|c| *c != 0.0).unwrap_or(1.0);
    if lead < 0.0 {
        v.map(|c| -c)
    } else {
        v
    }
}

/// A file-order joint vector (`s1_mm, theta1_deg, ...`) as the core's joints.
pub(crate) fn joints_of<const N: usize>(joints: &[f64]) -> Joints<f64, N> {
    assert_eq!(
        joints.len(),
        2 * N,
        "a joint vector of a {N}-tube robot has {} values (s1_mm, theta1_deg, ...)",
        2 * N
    );
    Joints::from_mm_deg(
        core::array::from_fn(|i| joints[2 * i]),
        core::array::from_fn(|i| joints[2 * i + 1]),
    )
}

fn params_array<const N: usize>(params: &[TubeParams<f64>]) -> [TubeParams<f64>; N] {
    core::array::from_fn(|i| params[i])
}

impl AnyRobot {
    /// Validates the tubes (outermost first) with the core.
    ///
    /// ```
    /// use ctr_analysis::AnyRobot;
    /// use ctr_core::{RobotError, TubeParams};
    /// let t = TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// assert_eq!(AnyRobot::new(&[t]).unwrap().n_tubes(), 1);
    /// assert!(matches!(AnyRobot::new(&[t; 5]), Err(RobotError::TubeCount { count: 5 })));
    /// ```
    pub fn new(params: &[TubeParams<f64>]) -> Result<Self, RobotError> {
        Ok(match params.len() {
            1 => AnyRobot::One(Robot::new(params_array(params))?),
            2 => AnyRobot::Two(Robot::new(params_array(params))?),
            3 => AnyRobot::Three(Robot::new(params_array(params))?),
            4 => AnyRobot::Four(Robot::new(params_array(params))?),
            count => return Err(RobotError::TubeCount { count }),
        })
    }

    /// The number of tubes.
    pub fn n_tubes(&self) -> usize {
        with_robot!(self, r => r.tubes().len())
    }

    /// A copy with each tube's E I and G J scaled by `stiffness[i]` and its precurvature
    /// radius by `radius_factor[i]` (the `stiffness` and `precurvature` effects; see
    /// [`Robot::scaled`]).
    ///
    /// # Panics
    /// If a slice's length is not the tube count.
    ///
    /// ```
    /// # use ctr_analysis::AnyRobot;
    /// # let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// let r = AnyRobot::new(&[t]).unwrap();
    /// assert!(r.scaled(&[2.0], &[1.0]).is_ok());
    /// assert!(r.scaled(&[-1.0], &[1.0]).is_err());
    /// ```
    pub fn scaled(&self, stiffness: &[f64], radius_factor: &[f64]) -> Result<Self, RobotError> {
        fn go<const N: usize>(
            r: &Robot<f64, N>,
            k: &[f64],
            c: &[f64],
        ) -> Result<Robot<f64, N>, RobotError> {
            r.scaled(
                core::array::from_fn(|i| k[i]),
                core::array::from_fn(|i| c[i]),
            )
        }
        Ok(match self {
            AnyRobot::One(r) => AnyRobot::One(go(r, stiffness, radius_factor)?),
            AnyRobot::Two(r) => AnyRobot::Two(go(r, stiffness, radius_factor)?),
            AnyRobot::Three(r) => AnyRobot::Three(go(r, stiffness, radius_factor)?),
            AnyRobot::Four(r) => AnyRobot::Four(go(r, stiffness, radius_factor)?),
        })
    }

    /// The parameters each tube was built from, outermost first.
    pub fn tube_params(&self) -> Vec<TubeParams<f64>> {
        with_robot!(self, r => r.tubes().iter().map(|t| *t.params()).collect())
    }

    /// The joint column names in file order: `s1_mm, theta1_deg, ..., sn_mm, thetan_deg`.
    ///
    /// ```
    /// # use ctr_analysis::AnyRobot;
    /// # let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// assert_eq!(AnyRobot::new(&[t]).unwrap().joint_columns(), ["s1_mm", "theta1_deg"]);
    /// ```
    pub fn joint_columns(&self) -> Vec<String> {
        joint_columns(self.n_tubes())
    }

    /// Checks a joint vector (file order, mm and degrees) against the robot.
    ///
    /// # Panics
    /// If `joints.len() != 2 * n_tubes()`.
    pub fn validate_joints(&self, joints: &[f64]) -> Result<(), JointError> {
        fn check<const N: usize>(r: &Robot<f64, N>, joints: &[f64]) -> Result<(), JointError> {
            joints_of::<N>(joints).validate(r)
        }
        with_robot!(self, r => check(r, joints))
    }

    /// Forward kinematics of one joint vector (file order, mm and degrees), solved cold:
    /// the result depends on nothing but the arguments.
    ///
    /// # Panics
    /// If `joints.len() != 2 * n_tubes()`.
    ///
    /// ```
    /// use ctr_analysis::AnyRobot;
    /// use ctr_core::{Model, Status, TubeParams};
    /// let t = TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33); // straight
    /// let robot = AnyRobot::new(&[t]).unwrap();
    /// let fk = robot.fk(&[50.0, 30.0], Model::Torsion).unwrap();
    /// assert_eq!(fk.status, Status::Converged);
    /// assert!((fk.position[2] - 50.0).abs() < 1e-12);
    /// ```
    pub fn fk(&self, joints: &[f64], model: Model) -> Result<FkResult, JointError> {
        self.solver().fk(joints, model)
    }

    /// A solver for this robot that warm-starts each solve from the previous ones.
    pub fn solver(&self) -> FkSolver<'_> {
        let solver = match self {
            AnyRobot::One(_) => AnySolver::One(Solver::default()),
            AnyRobot::Two(_) => AnySolver::Two(Solver::default()),
            AnyRobot::Three(_) => AnySolver::Three(Solver::default()),
            AnyRobot::Four(_) => AnySolver::Four(Solver::default()),
        };
        FkSolver {
            robot: self,
            solver,
        }
    }
}

/// The joint column names of an `n`-tube robot in file order.
pub fn joint_columns(n: usize) -> Vec<String> {
    (1..=n)
        .flat_map(|i| [format!("s{i}_mm"), format!("theta{i}_deg")])
        .collect()
}

#[derive(Clone, Copy, Debug)]
enum AnySolver {
    One(Solver<f64, 1>),
    Two(Solver<f64, 2>),
    Three(Solver<f64, 3>),
    Four(Solver<f64, 4>),
}

/// A core [`Solver`] bound to an [`AnyRobot`]: successive [`fk`](Self::fk) calls are
/// warm-started along the sequence exactly as the core's `Solver::solve` does.
#[derive(Clone, Copy, Debug)]
pub struct FkSolver<'r> {
    robot: &'r AnyRobot,
    solver: AnySolver,
}

impl FkSolver<'_> {
    /// Solves one joint vector (file order, mm and degrees), warm-started.
    ///
    /// # Panics
    /// If `joints.len() != 2 * n_tubes()`.
    pub fn fk(&mut self, joints: &[f64], model: Model) -> Result<FkResult, JointError> {
        fn solve<const N: usize>(
            s: &mut Solver<f64, N>,
            r: &Robot<f64, N>,
            joints: &[f64],
            model: Model,
        ) -> Result<FkResult, JointError> {
            match s.solve(r, Request::new(joints_of::<N>(joints), model)) {
                Ok(sol) => Ok(FkResult::from_solution(&sol)),
                Err(SolveError::Joint(e)) => Err(e),
                // an unloaded request of the core's models has no other error
                Err(e) => unreachable!("{e}"),
            }
        }
        match (self.robot, &mut self.solver) {
            (AnyRobot::One(r), AnySolver::One(s)) => solve(s, r, joints, model),
            (AnyRobot::Two(r), AnySolver::Two(s)) => solve(s, r, joints, model),
            (AnyRobot::Three(r), AnySolver::Three(s)) => solve(s, r, joints, model),
            (AnyRobot::Four(r), AnySolver::Four(s)) => solve(s, r, joints, model),
            _ => unreachable!("an FkSolver is built for its robot's tube count"),
        }
    }

    /// Forgets the warm-start memory.
    pub fn reset(&mut self) {
        match &mut self.solver {
            AnySolver::One(s) => s.reset(),
            AnySolver::Two(s) => s.reset(),
            AnySolver::Three(s) => s.reset(),
            AnySolver::Four(s) => s.reset(),
        }
    }
}

const _: () = assert!(MAX_TUBES == 4, "AnyRobot has one variant per tube count");

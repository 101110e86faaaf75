//! Forward kinematics of an [`AnyRobot`]: the core's solver for the robot's tube count.

use ctr_core::{JointError, Model, Request, Robot, SolveError, Solver};
use ctr_formats::{joints_of, AnyRobot, FkResult};

/// Forward kinematics on a robot whose tube count is known at run time.
pub trait Kinematics {
    /// Forward kinematics of one joint vector (file order, mm and degrees), solved cold.
    fn fk(&self, joints: &[f64], model: Model) -> Result<FkResult, JointError>;
    /// A solver for this robot that warm-starts each solve from the previous ones.
    fn solver(&self) -> FkSolver<'_>;
}

impl Kinematics for AnyRobot {
    /// Forward kinematics of one joint vector (file order, mm and degrees), solved cold:
    /// the result depends on nothing but the arguments.
    ///
    /// # Panics
    /// If `joints.len() != 2 * n_tubes()`.
    ///
    /// ```
    /// use ctr_analysis::Kinematics;
    /// use ctr_formats::AnyRobot;
    /// use ctr_core::{Model, Status, TubeParams};
    /// let t = TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33); // straight
    /// let robot = AnyRobot::new(&[t]).unwrap();
    /// let fk = robot.fk(&[50.0, 30.0], Model::Torsion).unwrap();
    /// assert_eq!(fk.status, Status::Converged);
    /// assert!((fk.position[2] - 50.0).abs() < 1e-12);
    /// ```
    fn fk(&self, joints: &[f64], model: Model) -> Result<FkResult, JointError> {
        self.solver().fk(joints, model)
    }

    /// A solver for this robot that warm-starts each solve from the previous ones.
    fn solver(&self) -> FkSolver<'_> {
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

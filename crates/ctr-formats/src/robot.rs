//! A robot whose tube count is known only at run time, and the file-order conventions
//! that go with it.
//!
//! The core fixes the tube count `N` at compile time ([`Robot<f64, N>`]); a file can hold
//! 1 to [`MAX_TUBES`] tubes, so [`AnyRobot`] is an enum over the four sizes and every
//! method dispatches to the core with the matching `N` ([`with_robot!`](crate::with_robot)
//! for the layers above). Joint vectors cross this boundary as slices in file order:
//! `s1_mm, theta1_deg, s2_mm, theta2_deg, ...` ([`joints_of`]).
//!
//! Tip orientations are returned as quaternions `(w, x, y, z)` with a canonical sign:
//! `w >= 0`, and when `w == 0` the first non-zero of `x, y, z` is positive, so that the
//! same rotation always prints the same four numbers.

use ctr_core::{JointError, Joints, Robot, RobotError, Solution, Status, TubeParams, MAX_TUBES};
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

/// Runs `$body` with `$r` bound to the inner `Robot<f64, N>` of an [`AnyRobot`] (`N` the
/// tube count: `$body` is compiled once per size).
///
/// ```
/// use ctr_formats::{with_robot, AnyRobot};
/// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
/// let robot = AnyRobot::new(&[t, ctr_core::TubeParams::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
/// assert_eq!(with_robot!(&robot, r => r.tubes().len()), 2);
/// ```
#[macro_export]
macro_rules! with_robot {
    ($robot:expr, $r:ident => $body:expr) => {
        match $robot {
            $crate::AnyRobot::One($r) => $body,
            $crate::AnyRobot::Two($r) => $body,
            $crate::AnyRobot::Three($r) => $body,
            $crate::AnyRobot::Four($r) => $body,
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
    /// The core's softest twist mode (`ctr_core::Solution::softest_mode`): the
    /// stiffness of the softest twist mode relative to uncoupled tubes, signed.
    pub softest_mode: f64,
    /// The stability margin (`ctr_analysis::margin`): the joint distance to the nearest
    /// snap over 20 mm or degrees, capped at 1; 0 at a snap, negative on an unstable
    /// branch.
    pub stability_margin: f64,
}

impl FkResult {
    /// Converts a core solution whose stability margin is `stability_margin`.
    pub fn from_solution<const N: usize>(sol: &Solution<f64, N>, stability_margin: f64) -> Self {
        let p = sol.tip.position;
        FkResult {
            position: [p.x, p.y, p.z],
            quaternion: canonical_quaternion(&sol.tip.orientation()),
            status: sol.status,
            residual_per_mm: sol.residual_per_mm,
            iterations: sol.iterations,
            softest_mode: sol.softest_mode,
            stability_margin,
        }
    }
}

/// `(w, x, y, z)` of `q` with the canonical sign: `w >= 0`; for `w == 0` the first
/// non-zero of `x, y, z` positive.
///
/// ```
/// use nalgebra::{Quaternion, UnitQuaternion};
/// let q = UnitQuaternion::from_quaternion(Quaternion::new(-0.6, 0.8, 0.0, 0.0));
/// assert_eq!(ctr_formats::canonical_quaternion(&q), [0.6, -0.8, 0.0, 0.0]);
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

/// A file-order joint vector (`s1_mm, theta1_deg, ...`, mm and degrees) as the core's
/// joints.
///
/// # Panics
/// If `joints.len() != 2 N`.
///
/// ```
/// let q = ctr_formats::joints_of::<1>(&[40.0, 180.0]);
/// assert!((q.theta_rad[0] - core::f64::consts::PI).abs() < 1e-15);
/// ```
pub fn joints_of<const N: usize>(joints: &[f64]) -> Joints<f64, N> {
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
    /// use ctr_formats::AnyRobot;
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
    /// # use ctr_formats::AnyRobot;
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
    /// # use ctr_formats::AnyRobot;
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
}

/// The tube number of a joint-like column name (`s3_mm`, `theta3_deg`).
pub(crate) fn tube_of_column(name: &str) -> Option<usize> {
    let digits = name
        .strip_prefix('s')
        .and_then(|r| r.strip_suffix("_mm"))
        .or_else(|| {
            name.strip_prefix("theta")
                .and_then(|r| r.strip_suffix("_deg"))
        })?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// The joint column names of an `n`-tube robot in file order.
pub fn joint_columns(n: usize) -> Vec<String> {
    (1..=n)
        .flat_map(|i| [format!("s{i}_mm"), format!("theta{i}_deg")])
        .collect()
}

const _: () = assert!(MAX_TUBES == 4, "AnyRobot has one variant per tube count");

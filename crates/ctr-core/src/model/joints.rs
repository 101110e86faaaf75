//! Joint values: exposed length `s_i` (mm) and actuator angle `theta_i` of each tube.
//!
//! Conventions (formats spec): `s_i` is tube i's arc length from the guide exit to its
//! tip, `0 <= s_1 <= s_2 <= ... <= s_n <= length`; `theta_i` is the angle the actuator
//! has turned tube i about +z, right-handed, measured at the actuator (not the tip).
//! Files use degrees; the core keeps radians.

use crate::model::robot::Robot;
use crate::real::{c, Real};
use core::fmt;

/// Which half of a joint pair a [`JointError`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// the feed `s_i` (file column `si_mm`)
    Feed,
    /// the rotation `theta_i` (file column `thetai_deg`)
    Rotation,
}

/// Why a joint vector was refused. Tubes are numbered from 1 (outermost).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointError {
    /// NaN or infinite value.
    NotFinite {
        /// tube number
        tube: usize,
        /// feed or rotation
        kind: JointKind,
    },
    /// `s_i < 0`.
    NegativeFeed {
        /// tube number
        tube: usize,
        /// the value, mm
        s_mm: f64,
    },
    /// `s_i < s_{i-1}`: an inner tube must reach at least as far as the one around it.
    FeedOrder {
        /// tube number (the inner one of the pair)
        tube: usize,
        /// its feed, mm
        s_mm: f64,
        /// the enclosing tube's feed, mm
        outer_s_mm: f64,
    },
    /// `s_i` exceeds the tube's length.
    BeyondLength {
        /// tube number
        tube: usize,
        /// its feed, mm
        s_mm: f64,
        /// the tube's length, mm
        length_mm: f64,
    },
}

impl fmt::Display for JointError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            JointError::NotFinite { tube, kind } => match kind {
                JointKind::Feed => write!(f, "s{tube}_mm must be a finite number"),
                JointKind::Rotation => write!(f, "theta{tube}_deg must be a finite number"),
            },
            JointError::NegativeFeed { tube, s_mm } => write!(f, "s{tube}_mm = {s_mm} must be >= 0"),
            JointError::FeedOrder { tube, s_mm, outer_s_mm } => write!(
                f,
                "s{tube}_mm = {s_mm} must be >= s{}_mm = {outer_s_mm} (inner tubes reach at least as far as outer ones)",
                tube - 1
            ),
            JointError::BeyondLength { tube, s_mm, length_mm } => write!(
                f,
                "s{tube}_mm = {s_mm} exceeds tube {tube}'s length_mm = {length_mm}"
            ),
        }
    }
}

/// A joint vector: feeds in mm, rotations in radians, outermost tube first.
///
/// ```
/// use ctr_core::Joints;
/// let q = Joints::from_mm_deg([30.0, 60.0], [0.0, 90.0]);
/// assert!((q.theta_rad[1] - core::f64::consts::FRAC_PI_2).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Joints<T, const N: usize> {
    /// Exposed length of each tube, mm.
    pub s_mm: [T; N],
    /// Actuator angle of each tube, rad.
    pub theta_rad: [T; N],
}

impl<T: Real, const N: usize> Joints<T, N> {
    /// From feeds in mm and rotations in radians.
    ///
    /// ```
    /// let q = ctr_core::Joints::new([10.0], [0.5]);
    /// assert_eq!(q.theta_rad[0], 0.5);
    /// ```
    pub fn new(s_mm: [T; N], theta_rad: [T; N]) -> Self {
        Joints { s_mm, theta_rad }
    }

    /// From feeds in mm and rotations in degrees (the file convention).
    ///
    /// ```
    /// let q = ctr_core::Joints::from_mm_deg([10.0], [180.0]);
    /// assert!((q.theta_rad[0] - core::f64::consts::PI).abs() < 1e-15);
    /// ```
    pub fn from_mm_deg(s_mm: [T; N], theta_deg: [T; N]) -> Self {
        let k = T::pi() / c(180.0);
        Joints {
            s_mm,
            theta_rad: theta_deg.map(|d| d * k),
        }
    }

    /// Rotations in degrees.
    ///
    /// ```
    /// let q = ctr_core::Joints::new([10.0], [core::f64::consts::PI]);
    /// assert!((q.theta_deg()[0] - 180.0).abs() < 1e-12);
    /// ```
    pub fn theta_deg(&self) -> [T; N] {
        let k = c::<T>(180.0) / T::pi();
        self.theta_rad.map(|r| r * k)
    }

    /// Checks the joints against a robot: finite, `0 <= s_1 <= ... <= s_n`, each `s_i`
    /// within its tube's length.
    ///
    /// ```
    /// use ctr_core::{JointError, Joints, Robot, TubeParams};
    /// let r = Robot::new([
    ///     TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33),
    ///     TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33),
    /// ]).unwrap();
    /// assert!(Joints::from_mm_deg([30.0, 20.0], [0.0, 0.0]).validate(&r).is_err());
    /// assert!(Joints::from_mm_deg([30.0, 70.0], [0.0, 0.0]).validate(&r).is_ok());
    /// ```
    pub fn validate(&self, robot: &Robot<T, N>) -> Result<(), JointError> {
        for i in 0..N {
            let tube = i + 1;
            if !self.s_mm[i].is_finite() {
                return Err(JointError::NotFinite {
                    tube,
                    kind: JointKind::Feed,
                });
            }
            if !self.theta_rad[i].is_finite() {
                return Err(JointError::NotFinite {
                    tube,
                    kind: JointKind::Rotation,
                });
            }
        }
        for i in 0..N {
            let tube = i + 1;
            let s = self.s_mm[i];
            if s < T::zero() {
                return Err(JointError::NegativeFeed { tube, s_mm: f(s) });
            }
            if i > 0 && s < self.s_mm[i - 1] {
                return Err(JointError::FeedOrder {
                    tube,
                    s_mm: f(s),
                    outer_s_mm: f(self.s_mm[i - 1]),
                });
            }
            let length = robot.tubes()[i].params().length_mm;
            if s > length {
                return Err(JointError::BeyondLength {
                    tube,
                    s_mm: f(s),
                    length_mm: f(length),
                });
            }
        }
        Ok(())
    }
}

fn f<T: Real>(v: T) -> f64 {
    v.to_subset().unwrap_or(f64::NAN)
}

//! External loads on the robot: the tubes' weight, a tip force and a tip moment. The
//! mechanics under load (Cosserat statics) are in [`crate::integrate::loaded`]; a solve
//! takes loads with [`crate::Request::loads`].

use crate::real::Real;
use nalgebra::Vector3;

/// Standard gravity, m/s^2.
pub const STANDARD_GRAVITY_M_S2: f64 = 9.81;

/// Gravity acting on the exposed tubes.
///
/// ```
/// let g = ctr_core::Gravity::<f64>::new([-1.0, 0.0, 0.0], 9.81);
/// assert_eq!(g.direction[0], -1.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gravity<T> {
    /// Unit direction of g in W.
    pub direction: [T; 3],
    /// Magnitude, m/s^2.
    pub g_m_s2: T,
}

impl<T: Real> Gravity<T> {
    /// Gravity along `direction` (normalised here) of magnitude `g_m_s2`.
    ///
    /// ```
    /// let g = ctr_core::Gravity::<f64>::new([0.0, 0.0, -2.0], 9.81);
    /// assert_eq!(g.direction, [0.0, 0.0, -1.0]);
    /// ```
    pub fn new(direction: [T; 3], g_m_s2: T) -> Self {
        let v = Vector3::from(direction);
        let n = v.norm();
        let d = if n > T::zero() { v / n } else { v };
        Gravity {
            direction: [d.x, d.y, d.z],
            g_m_s2,
        }
    }
}

/// Loads on the robot.
///
/// ```
/// let loads = ctr_core::Loads::<f64> { tip_force_n: [0.0, 0.0, -0.1], ..Default::default() };
/// assert!(loads.gravity.is_none() && !loads.is_none());
/// assert!(ctr_core::Loads::<f64>::default().is_none());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Loads<T> {
    /// The tubes' weight, if modelled.
    pub gravity: Option<Gravity<T>>,
    /// Force applied at the tip, N, in W.
    pub tip_force_n: [T; 3],
    /// Moment applied at the tip, N mm, in W.
    pub tip_moment_nmm: [T; 3],
}

impl<T: Real> Default for Loads<T> {
    fn default() -> Self {
        Loads {
            gravity: None,
            tip_force_n: [T::zero(); 3],
            tip_moment_nmm: [T::zero(); 3],
        }
    }
}

impl<T: Real> Loads<T> {
    /// True when nothing loads the robot: no gravity, zero tip force and moment.
    pub fn is_none(&self) -> bool {
        self.gravity.is_none()
            && self
                .tip_force_n
                .iter()
                .chain(&self.tip_moment_nmm)
                .all(|v| *v == T::zero())
    }
}

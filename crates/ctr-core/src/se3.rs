//! Rigid transforms and the SE(3) exponential used to chain the backbone segments.
//!
//! A segment with body twist `xi = (omega, v)` (angular rate `omega` per mm, linear rate
//! `v`, body frame) over unit length moves the frame by `exp(xi^)`:
//! `R = I + sin(t)/t W + (1 - cos t)/t^2 W^2`, `p = V v`,
//! `V = I + (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2`, with `W = omega^`, `t = |omega|`
//! (Lynch & Park, Modern Robotics, eq. 3.51 and 3.88). Near `t = 0` the coefficients
//! switch to their Taylor series so the result stays accurate to machine precision.

use crate::real::{c, Real};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};

/// A frame in the world: rotation (columns are the frame's axes in W) and origin, mm.
///
/// ```
/// use ctr_core::Frame;
/// let f = Frame::<f64>::identity();
/// assert_eq!(f.position.norm(), 0.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame<T: Real> {
    /// Rotation matrix from the frame to W.
    pub rotation: Matrix3<T>,
    /// Origin in W, mm.
    pub position: Vector3<T>,
}

impl<T: Real> Frame<T> {
    /// The world frame itself.
    ///
    /// ```
    /// let f = ctr_core::Frame::<f64>::identity();
    /// assert_eq!(f.rotation, nalgebra::Matrix3::identity());
    /// ```
    pub fn identity() -> Self {
        Frame {
            rotation: Matrix3::identity(),
            position: Vector3::zeros(),
        }
    }

    /// The orientation as a unit quaternion (w, x, y, z).
    ///
    /// ```
    /// let q = ctr_core::Frame::<f64>::identity().orientation();
    /// assert_eq!(q.w, 1.0);
    /// ```
    pub fn orientation(&self) -> UnitQuaternion<T> {
        UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(
            self.rotation,
        ))
    }

    /// Moves this frame by a transform expressed in its own body coordinates.
    #[inline]
    pub(crate) fn compose(&mut self, r: &Matrix3<T>, p: &Vector3<T>) {
        self.position += self.rotation * p;
        self.rotation *= r;
    }

    /// Rotates the frame about its own z axis by the angle whose (cos, sin) is given.
    #[inline]
    pub(crate) fn rotate_z(&mut self, cs: (T, T)) {
        let (co, si) = cs;
        let x = self.rotation.column(0).into_owned();
        let y = self.rotation.column(1).into_owned();
        self.rotation.set_column(0, &(x * co + y * si));
        self.rotation.set_column(1, &(y * co - x * si));
    }
}

/// `exp` of the body twist `(omega, v)` (already multiplied by the length): rotation and
/// translation of the end frame in the start frame.
///
/// ```
/// use ctr_core::se3::exp;
/// use nalgebra::Vector3;
/// // a quarter circle of radius 10 mm bending toward +x
/// let k = 0.1;
/// let len = core::f64::consts::FRAC_PI_2 / k;
/// let (r, p) = exp(Vector3::new(0.0, k * len, 0.0), Vector3::new(0.0, 0.0, len));
/// assert!((p - Vector3::new(10.0, 0.0, 10.0)).norm() < 1e-12);
/// assert!((r[(0, 2)] - 1.0).abs() < 1e-12);
/// ```
#[inline]
pub fn exp<T: Real>(omega: Vector3<T>, v: Vector3<T>) -> (Matrix3<T>, Vector3<T>) {
    let t2 = omega.norm_squared();
    // Coefficients a = sin t / t, b = (1 - cos t)/t^2, d = (t - sin t)/t^3.
    let (a, b, d) = if t2 < c(1e-4) {
        // Taylor series to t^6: error below 1e-17 for t < 1e-2.
        let t4 = t2 * t2;
        (
            T::one() - t2 / c(6.0) + t4 / c(120.0) - t4 * t2 / c(5040.0),
            c::<T>(0.5) - t2 / c(24.0) + t4 / c(720.0) - t4 * t2 / c(40320.0),
            c::<T>(1.0 / 6.0) - t2 / c(120.0) + t4 / c(5040.0) - t4 * t2 / c(362880.0),
        )
    } else {
        let t = t2.sqrt();
        let (s, co) = t.sin_cos();
        (s / t, (T::one() - co) / t2, (t - s) / (t2 * t))
    };
    let w = omega.cross_matrix();
    let w2 = w * w;
    let r = Matrix3::identity() + w * a + w2 * b;
    let vm = Matrix3::identity() + w * b + w2 * d;
    (r, vm * v)
}

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
    let (a, b, d) = if t2 < c(SERIES_LIMIT_SQ) {
        (sinc_series(t2), versine_series(t2), sin_defect_series(t2))
    } else {
        let t = t2.sqrt();
        let (s, co) = t.sin_cos();
        (s / t, (T::one() - co) / t2, (t - s) / (t2 * t))
    };
    // R = I + a W + b W^2 with W^2 = omega omega^T - t^2 I, element by element
    let (x, y, z) = (omega.x, omega.y, omega.z);
    let (ax, ay, az) = (a * x, a * y, a * z);
    let (bxy, bxz, byz) = (b * x * y, b * x * z, b * y * z);
    let r = Matrix3::new(
        T::one() - b * (y * y + z * z),
        bxy - az,
        bxz + ay,
        bxy + az,
        T::one() - b * (x * x + z * z),
        byz - ax,
        bxz - ay,
        byz + ax,
        T::one() - b * (x * x + y * y),
    );
    // p = V v = v + b omega x v + d omega x (omega x v)
    let wv = omega.cross(&v);
    let p = v + wv * b + omega.cross(&wv) * d;
    (r, p)
}

/// Below this squared angle (t < 0.3 rad) the Taylor series to `t^10` are exact to
/// machine precision: the first omitted term of `sin t / t` is `t^12 / 13! < 1e-16`.
/// RK4 steps turn the frame by about 0.1 rad, so exponentials need no trigonometry.
pub const SERIES_LIMIT_SQ: f64 = 0.09;

/// `sin t / t` from `t^2`, Horner form, for `t^2 < SERIES_LIMIT_SQ`.
#[inline(always)]
fn sinc_series<T: Real>(t2: T) -> T {
    T::one()
        - t2 / c(6.0)
            * (T::one()
                - t2 / c(20.0)
                    * (T::one()
                        - t2 / c(42.0) * (T::one() - t2 / c(72.0) * (T::one() - t2 / c(110.0)))))
}

/// `(1 - cos t) / t^2` from `t^2`.
#[inline(always)]
fn versine_series<T: Real>(t2: T) -> T {
    c::<T>(0.5)
        * (T::one()
            - t2 / c(12.0)
                * (T::one()
                    - t2 / c(30.0)
                        * (T::one()
                            - t2 / c(56.0)
                                * (T::one() - t2 / c(90.0) * (T::one() - t2 / c(132.0))))))
}

/// `(t - sin t) / t^3` from `t^2`.
#[inline(always)]
fn sin_defect_series<T: Real>(t2: T) -> T {
    c::<T>(1.0 / 6.0)
        * (T::one()
            - t2 / c(20.0)
                * (T::one()
                    - t2 / c(42.0)
                        * (T::one()
                            - t2 / c(72.0)
                                * (T::one() - t2 / c(110.0) * (T::one() - t2 / c(156.0))))))
}

/// `(sin x, cos x)`, by Taylor series (exact to machine precision) for `|x| < 0.3`.
#[inline(always)]
pub(crate) fn sin_cos<T: Real>(x: T) -> (T, T) {
    let x2 = x * x;
    if x2 < c(SERIES_LIMIT_SQ) {
        (x * sinc_series(x2), T::one() - x2 * versine_series(x2))
    } else {
        x.sin_cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_match_the_closed_forms_at_the_switch() {
        for t in [1e-3_f64, 0.05, 0.1, 0.2, 0.2999] {
            let t2 = t * t;
            assert!((sinc_series(t2) - t.sin() / t).abs() < 2e-16);
            // 2 sin^2(t/2) avoids the cancellation of 1 - cos t
            assert!((versine_series(t2) - 2.0 * (t / 2.0).sin().powi(2) / t2).abs() < 2e-16);
            if t >= 0.1 {
                // t - sin t cancels to ~1e-16 / t^3 relative: compare loosely there
                assert!((sin_defect_series(t2) - (t - t.sin()) / (t2 * t)).abs() < 1e-12);
            }
            let (s, co) = sin_cos(t);
            assert!((s - t.sin()).abs() < 1e-16 && (co - t.cos()).abs() < 2e-16);
        }
    }
}

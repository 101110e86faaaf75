//! Rigid transforms and the one SE(3) exponential that chains the backbone segments.
//!
//! A segment with body twist `xi = (omega, v)` (angular rate `omega` per mm, linear rate
//! `v`, body frame) over unit length moves the frame by `exp(xi^)`:
//! `R = I + sin(t)/t W + (1 - cos t)/t^2 W^2`, `p = V v`,
//! `V = I + (1 - cos t)/t^2 W + (t - sin t)/t^3 W^2`, with `W = omega^`, `t = |omega|`
//! (Lynch & Park, Modern Robotics, eq. 3.51 and 3.88). Near `t = 0` the coefficients
//! switch to their Taylor series so the result stays accurate to machine precision.
//!
//! `exp_of` is generic over plain and dual numbers ([`Num`]): the pose passes, the
//! Jacobian passes and [`exp`] (its nalgebra face) all use it.

use super::dual::Num;
use super::linalg::{cross, M3, V3};
use super::series::{Series, SERIES_LIMIT_SQ, SINC, SIN_DEFECT, VERSINE};
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

    /// Rotates the frame about its own y axis by the angle whose (cos, sin) is given.
    #[inline]
    pub(crate) fn rotate_y(&mut self, co: T, si: T) {
        let z = T::zero();
        let ry = Matrix3::new(co, z, si, z, T::one(), z, -si, z, co);
        self.rotation *= ry;
    }

    /// Rotates the frame about its own z axis by the angle whose (cos, sin) is given.
    #[inline]
    pub(crate) fn rotate_z(&mut self, co: T, si: T) {
        let x = self.rotation.column(0).into_owned();
        let y = self.rotation.column(1).into_owned();
        self.rotation.set_column(0, &(x * co + y * si));
        self.rotation.set_column(1, &(y * co - x * si));
    }
}

/// A series at `t2` as a plain or dual number (the derivative only where there are
/// derivatives to carry).
#[inline(always)]
fn series<T: Real, S: Num<T>>(t2: S, s: &Series) -> S {
    let v = s.value(t2.re());
    if S::DUAL {
        t2.chain(v, s.derivative(t2.re()))
    } else {
        S::cst(v)
    }
}

/// `exp` of the body twist `(omega, v)` (already multiplied by the length): rotation and
/// translation of the end frame in the start frame (`exp_of` on nalgebra types).
///
/// ```
/// use ctr_core::math::se3::exp;
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
    let (r, p) = exp_of::<T, T>([omega.x, omega.y, omega.z], [v.x, v.y, v.z]);
    (
        Matrix3::from_fn(|i, j| r[i][j]),
        Vector3::new(p[0], p[1], p[2]),
    )
}

/// The SE(3) exponential on plain or dual numbers: `(R, p)` with `R` row-major.
#[inline(always)]
pub(crate) fn exp_of<T: Real, S: Num<T>>(w: V3<S>, v: V3<S>) -> (M3<S>, V3<S>) {
    let one = S::cst(T::one());
    let t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    // coefficients a = sin t / t, b = (1 - cos t)/t^2, d = (t - sin t)/t^3
    let (a, b, d) = if t2.re() < c(SERIES_LIMIT_SQ) {
        (
            series(t2, &SINC),
            series(t2, &VERSINE),
            series(t2, &SIN_DEFECT),
        )
    } else {
        let t = t2.sqrt();
        let (s, co) = t.sin_cos();
        (s / t, (one - co) / t2, (t - s) / (t2 * t))
    };
    // R = I + a W + b W^2 with W^2 = omega omega^T - t^2 I, element by element
    let (x, y, z) = (w[0], w[1], w[2]);
    let (ax, ay, az) = (a * x, a * y, a * z);
    let (bx, by) = (b * x, b * y);
    let (bxy, bxz, byz) = (bx * y, bx * z, by * z);
    let r = [
        [one - b * (y * y + z * z), bxy - az, bxz + ay],
        [bxy + az, one - b * (x * x + z * z), byz - ax],
        [bxz - ay, byz + ax, one - b * (x * x + y * y)],
    ];
    // p = V v = v + b omega x v + d omega x (omega x v)
    let wv = cross(&w, &v);
    let wwv = cross(&w, &wv);
    let p = [
        v[0] + wv[0] * b + wwv[0] * d,
        v[1] + wv[1] * b + wwv[1] * d,
        v[2] + wv[2] * b + wwv[2] * d,
    ];
    (r, p)
}

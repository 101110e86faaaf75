//! Effects beyond the base mechanics, as switchable parameters in physical units.
//!
//! Names follow the contract's vocabulary (`docs/formats.md`):
//!
//! - `joint_offset`: an actuator's zero differs from the nominal one; the actual joints
//!   are `commanded + offset` (feeds mm, rotations rad).
//! - `clearance`: the gap between tube i and tube i+1 lets tube i+1 leave tube i's tip
//!   with an extra deflection `delta(phi)`, a kink about tube i+1's body y axis (toward
//!   its precurvature side), where `phi = psi_{i+1} - psi_i` is the actual relative
//!   angle there (after torsion). The seed paper (Liu et al. 2023, eq. 17 and Fig. 4)
//!   measures `delta` as a table over the relative angle, largest near 205 degrees on
//!   its robot; [`ClearanceProfile::Cosine`] is the smooth one-harmonic form
//!   `delta = delta_max (1 + cos(phi - phi_peak)) / 2`, [`ClearanceProfile::Table`] the
//!   measured table with periodic linear interpolation. The seed's correction of the
//!   rotation angle at that point (`Delta theta = theta_2 + theta_1 - beta`, eq. 17, the
//!   twist the tubes took between the actuators and the outer tip) is built in: the
//!   kink is applied about the inner tube's actual bending direction from the torsion
//!   solve, not the commanded one, so it needs no separate term.
//! - `registration`: the measuring frame is offset or rotated from W:
//!   `p_measured = R p_W + t`, orientations `R R_tip`.
//! - `sensor_offset`: the tracked point sits at a fixed offset in the tip frame:
//!   `p = p_tip + R_tip d`.
//! - `stiffness`, `precurvature`: scale factors per tube, see [`crate::Robot::scaled`].
//! - `gravity` and tip loads: [`crate::Loads`]. `friction`: [`crate::friction`].
//! - `latency` needs a recording's time series and lives in the std crate.
//!
//! A solve takes them with [`crate::Request::effects`]: joint offsets before the
//! mechanics, clearance kinks inside it (and in its Jacobians), sensor offset and
//! registration on its results.

use crate::math::dual::Num;
use crate::math::se3::Frame;
use crate::model::joints::Joints;
use crate::real::{c, Real};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3, Vector6};

/// Capacity of a clearance table (values over one turn of the relative angle).
pub const CLEARANCE_TABLE_CAPACITY: usize = 72;

/// Extra deflection of an inner tube where it leaves the next outer tube's tip, as a
/// function of the relative angle `phi = psi_{i+1} - psi_i` there.
///
/// ```
/// use ctr_core::effects::ClearanceProfile;
/// let p = ClearanceProfile::Cosine { max_deflection_rad: 0.04, peak_rad: 205f64.to_radians() };
/// assert!((p.deflection(205f64.to_radians()) - 0.04).abs() < 1e-15);
/// assert!(p.deflection(25f64.to_radians()).abs() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ClearanceProfile<T> {
    /// `delta = max_deflection (1 + cos(phi - peak)) / 2`.
    Cosine {
        /// largest deflection, rad
        max_deflection_rad: T,
        /// relative angle where it is largest, rad
        peak_rad: T,
    },
    /// Values at `phi = 2 pi k / len`, `k = 0..len`, interpolated linearly and
    /// periodically (the seed's measured "database").
    Table {
        /// deflections, rad; only the first `len` are used
        values_rad: [T; CLEARANCE_TABLE_CAPACITY],
        /// number of values used, 1..=CLEARANCE_TABLE_CAPACITY
        len: usize,
    },
}

impl<T: Real> ClearanceProfile<T> {
    /// A table from a slice of values evenly spaced over one turn; `None` if the slice
    /// is empty or longer than [`CLEARANCE_TABLE_CAPACITY`].
    ///
    /// ```
    /// use ctr_core::effects::ClearanceProfile;
    /// let t = ClearanceProfile::table(&[0.0, 1.0, 0.0, -1.0]).unwrap();
    /// assert!((t.deflection(core::f64::consts::FRAC_PI_4) - 0.5).abs() < 1e-15);
    /// ```
    pub fn table(values: &[T]) -> Option<Self> {
        if values.is_empty() || values.len() > CLEARANCE_TABLE_CAPACITY {
            return None;
        }
        let mut values_rad = [T::zero(); CLEARANCE_TABLE_CAPACITY];
        values_rad[..values.len()].copy_from_slice(values);
        Some(ClearanceProfile::Table {
            values_rad,
            len: values.len(),
        })
    }

    /// Deflection at relative angle `phi`, rad.
    ///
    /// ```
    /// use ctr_core::effects::ClearanceProfile;
    /// let p = ClearanceProfile::table(&[0.1_f64]).unwrap();
    /// assert_eq!(p.deflection(2.0), 0.1);
    /// ```
    pub fn deflection(&self, phi: T) -> T {
        let (s, co) = phi.sin_cos();
        self.deflection_cs(co, s)
    }

    /// Deflection from `(cos phi, sin phi)`, on plain or dual numbers.
    pub(crate) fn deflection_cs<S: Num<T>>(&self, cos_phi: S, sin_phi: S) -> S {
        match *self {
            ClearanceProfile::Cosine {
                max_deflection_rad,
                peak_rad,
            } => {
                let (sp, cp) = peak_rad.sin_cos();
                (S::cst(T::one()) + cos_phi * cp + sin_phi * sp) * max_deflection_rad * c::<T>(0.5)
            }
            ClearanceProfile::Table { values_rad, len } => {
                let len = len.clamp(1, CLEARANCE_TABLE_CAPACITY);
                let turn = T::two_pi();
                let mut phi = sin_phi.atan2(cos_phi);
                if phi.re() < T::zero() {
                    phi += S::cst(turn);
                }
                let x = phi / S::cst(turn) * nalgebra::convert::<f64, T>(len as f64);
                let floor = x.re().floor();
                let k: f64 = floor.to_subset().unwrap_or(0.0);
                let k0 = if k.is_finite() && k >= 0.0 {
                    (k as usize) % len
                } else {
                    0
                };
                let frac = x - S::cst(floor);
                let k1 = (k0 + 1) % len;
                (S::cst(T::one()) - frac) * values_rad[k0] + frac * values_rad[k1]
            }
        }
    }
}

/// A rigid transform from W to the measuring frame: `p_measured = R p_W + t`.
///
/// ```
/// use ctr_core::effects::Registration;
/// let r = Registration::<f64>::from_axis_angle([0.0, 0.0, 1.0], core::f64::consts::FRAC_PI_2, [1.0, 0.0, 0.0]);
/// let p = r.apply_point(&ctr_core::nalgebra::Vector3::new(1.0, 0.0, 0.0));
/// assert!((p - ctr_core::nalgebra::Vector3::new(1.0, 1.0, 0.0)).norm() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Registration<T: Real> {
    /// Rotation R.
    pub rotation: Matrix3<T>,
    /// Translation t, mm.
    pub translation_mm: Vector3<T>,
}

impl<T: Real> Registration<T> {
    /// The identity transform.
    ///
    /// ```
    /// let r = ctr_core::effects::Registration::<f64>::identity();
    /// assert_eq!(r.translation_mm.norm(), 0.0);
    /// ```
    pub fn identity() -> Self {
        Registration {
            rotation: Matrix3::identity(),
            translation_mm: Vector3::zeros(),
        }
    }
    /// From a rotation of `angle_rad` about `axis` (normalised; a zero axis means no
    /// rotation) and a translation in mm.
    ///
    /// ```
    /// let r = ctr_core::effects::Registration::<f64>::from_axis_angle([0.0, 0.0, 0.0], 1.0, [0.0; 3]);
    /// assert_eq!(r.rotation, ctr_core::nalgebra::Matrix3::identity());
    /// ```
    pub fn from_axis_angle(axis: [T; 3], angle_rad: T, translation_mm: [T; 3]) -> Self {
        let v = Vector3::from(axis);
        let rotation = if v.norm() > T::zero() {
            *Rotation3::from_axis_angle(&Unit::new_normalize(v), angle_rad).matrix()
        } else {
            Matrix3::identity()
        };
        Registration {
            rotation,
            translation_mm: Vector3::from(translation_mm),
        }
    }
    /// Maps a point from W to the measuring frame.
    ///
    /// ```
    /// let r = ctr_core::effects::Registration::<f64>::identity();
    /// let p = ctr_core::nalgebra::Vector3::new(1.0, 2.0, 3.0);
    /// assert_eq!(r.apply_point(&p), p);
    /// ```
    pub fn apply_point(&self, p: &Vector3<T>) -> Vector3<T> {
        self.rotation * p + self.translation_mm
    }
}

/// The kinematic effects of a robot, all off by default.
///
/// ```
/// use ctr_core::effects::{ClearanceProfile, Effects};
/// let mut e = Effects::<f64, 2>::default();
/// e.clearance[0] = Some(ClearanceProfile::Cosine { max_deflection_rad: 0.04, peak_rad: 3.58 });
/// assert!(e.registration.is_none());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Effects<T: Real, const N: usize> {
    /// Added to the commanded feeds, mm.
    pub feed_offset_mm: [T; N],
    /// Added to the commanded rotations, rad.
    pub rotation_offset_rad: [T; N],
    /// Entry i: the kink where tube i+2 leaves tube i+1 (0-based: tube index i+1 leaves
    /// tube index i); the last entry is unused.
    pub clearance: [Option<ClearanceProfile<T>>; N],
    /// Measuring frame, if not W.
    pub registration: Option<Registration<T>>,
    /// Tracked point in the tip frame, mm.
    pub sensor_offset_mm: [T; 3],
    /// The tracked sensor's orientation in the tip frame (the hand-eye part of a
    /// tracker's calibration), if it is not the tip frame's: the measured frame is
    /// `R_tip S`. It turns only the measured orientation and tangent, not the point.
    pub sensor_rotation: Option<Matrix3<T>>,
}

impl<T: Real, const N: usize> Default for Effects<T, N> {
    fn default() -> Self {
        Effects {
            feed_offset_mm: [T::zero(); N],
            rotation_offset_rad: [T::zero(); N],
            clearance: [None; N],
            registration: None,
            sensor_offset_mm: [T::zero(); 3],
            sensor_rotation: None,
        }
    }
}

impl<T: Real, const N: usize> Effects<T, N> {
    /// The joints the tubes actually take for the commanded `q`: `q` plus the joint
    /// offsets.
    ///
    /// ```
    /// use ctr_core::{effects::Effects, Joints};
    /// let e = Effects::<f64, 1> { feed_offset_mm: [0.5], rotation_offset_rad: [0.1], ..Default::default() };
    /// let q = e.actual(&Joints::new([40.0], [1.0]));
    /// assert_eq!((q.s_mm[0], q.theta_rad[0]), (40.5, 1.1));
    /// ```
    pub fn actual(&self, q: &Joints<T, N>) -> Joints<T, N> {
        let mut actual = *q;
        for i in 0..N {
            actual.s_mm[i] += self.feed_offset_mm[i];
            actual.theta_rad[i] += self.rotation_offset_rad[i];
        }
        actual
    }

    /// The tip frame as measured: the sensor offset and the sensor's rotation in the tip
    /// frame, then the registration. (A constant rotation on the right leaves the
    /// frame's angular velocity in W unchanged, so the derivative columns need only the
    /// offset's lever arm and the registration: `measured_column`.)
    ///
    /// ```
    /// use ctr_core::{effects::Effects, Frame};
    /// let e = Effects::<f64, 1> { sensor_offset_mm: [0.0, 0.0, 2.0], ..Default::default() };
    /// let f = e.measured(&Frame::identity());
    /// assert_eq!(f.position.z, 2.0);
    /// ```
    pub fn measured(&self, tip: &Frame<T>) -> Frame<T> {
        let mut f = *tip;
        f.position += tip.rotation * Vector3::from(self.sensor_offset_mm);
        if let Some(s) = &self.sensor_rotation {
            f.rotation *= s;
        }
        if let Some(r) = &self.registration {
            f.position = r.apply_point(&f.position);
            f.rotation = r.rotation * f.rotation;
        }
        f
    }
}

impl<T: Real, const N: usize> Effects<T, N> {
    /// A derivative column `(dp, omega)` of the tip (W) as the measured point and frame
    /// see it: the tracked point `p + R d` moves with `dp + omega x (R d)`, then the
    /// registration turns both blocks. `arm` is `R d` at the solution.
    pub(crate) fn measured_column(&self, col: &Vector6<T>, arm: &Vector3<T>) -> Vector6<T> {
        let omega = col.fixed_rows::<3>(3).into_owned();
        let mut dp = col.fixed_rows::<3>(0) + omega.cross(arm);
        let mut w = omega;
        if let Some(r) = &self.registration {
            dp = r.rotation * dp;
            w = r.rotation * w;
        }
        Vector6::new(dp[0], dp[1], dp[2], w[0], w[1], w[2])
    }
}

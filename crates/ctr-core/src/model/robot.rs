//! Validated robot parameters: the tubes, outermost first.
//!
//! A [`Robot`] is built from one [`TubeParams`] per tube, which mirror the robot TOML of
//! `docs/formats.md` field for field (mm, MPa, kg/m^3). Construction checks
//! every field and returns a [`RobotError`] naming the tube and the field; a `Robot`
//! therefore never holds a negative diameter, tubes that do not nest or a curved part
//! longer than its tube.
//!
//! Derived values (formats spec): `I = pi (OD^4 - ID^4) / 64`, `J = 2 I`,
//! `G = E / (2 (1 + nu))`, bending stiffness `E I`, torsional stiffness `G J`, both in
//! N mm^2 (MPa x mm^4). Measured stiffnesses given in the file override the derived ones.

use crate::real::{c, Real};
use core::fmt;

/// The fields of a tube, named as in the robot TOML.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// `outer_diameter_mm`
    OuterDiameter,
    /// `inner_diameter_mm`
    InnerDiameter,
    /// `length_mm`
    Length,
    /// `curved_length_mm`
    CurvedLength,
    /// `curvature_radius_mm`
    CurvatureRadius,
    /// `youngs_modulus_mpa`
    YoungsModulus,
    /// `poisson_ratio`
    PoissonRatio,
    /// `bending_stiffness_nmm2`
    BendingStiffness,
    /// `torsional_stiffness_nmm2`
    TorsionalStiffness,
    /// `density_kg_m3`
    Density,
}

impl Field {
    /// The key of this field in the robot TOML.
    ///
    /// ```
    /// assert_eq!(ctr_core::Field::YoungsModulus.key(), "youngs_modulus_mpa");
    /// ```
    pub const fn key(self) -> &'static str {
        match self {
            Field::OuterDiameter => "outer_diameter_mm",
            Field::InnerDiameter => "inner_diameter_mm",
            Field::Length => "length_mm",
            Field::CurvedLength => "curved_length_mm",
            Field::CurvatureRadius => "curvature_radius_mm",
            Field::YoungsModulus => "youngs_modulus_mpa",
            Field::PoissonRatio => "poisson_ratio",
            Field::BendingStiffness => "bending_stiffness_nmm2",
            Field::TorsionalStiffness => "torsional_stiffness_nmm2",
            Field::Density => "density_kg_m3",
        }
    }
}

/// Why a set of tube parameters was refused. Tubes are numbered from 1 (outermost).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RobotError {
    /// A value is NaN or infinite.
    NotFinite {
        /// tube number, 1 = outermost
        tube: usize,
        /// the offending field
        field: Field,
    },
    /// A value that must be > 0 is not.
    NotPositive {
        /// tube number, 1 = outermost
        tube: usize,
        /// the offending field
        field: Field,
        /// the value found
        value: f64,
    },
    /// A value that must be >= 0 is negative.
    Negative {
        /// tube number, 1 = outermost
        tube: usize,
        /// the offending field
        field: Field,
        /// the value found
        value: f64,
    },
    /// `outer_diameter_mm <= inner_diameter_mm`.
    WallNotPositive {
        /// tube number, 1 = outermost
        tube: usize,
        /// outer diameter found, mm
        outer_mm: f64,
        /// inner diameter found, mm
        inner_mm: f64,
    },
    /// Tube `inner` does not fit inside tube `inner - 1`: its outer diameter is not
    /// smaller than the outer tube's inner diameter.
    DoNotNest {
        /// the inner tube's number
        inner: usize,
        /// its outer diameter, mm
        inner_outer_diameter_mm: f64,
        /// the enclosing tube's inner diameter, mm
        outer_inner_diameter_mm: f64,
    },
    /// `curved_length_mm > length_mm`.
    CurvedLongerThanTube {
        /// tube number, 1 = outermost
        tube: usize,
        /// curved length found, mm
        curved_mm: f64,
        /// tube length, mm
        length_mm: f64,
    },
    /// Poisson ratio outside `[0, 0.5)`.
    PoissonOutOfRange {
        /// tube number, 1 = outermost
        tube: usize,
        /// the value found
        value: f64,
    },
    /// A curvature radius of zero (infinite curvature). Omit the radius for a straight tube.
    ZeroRadius {
        /// tube number, 1 = outermost
        tube: usize,
    },
    /// The number of tubes is outside 1..=[`MAX_TUBES`](crate::MAX_TUBES).
    TubeCount {
        /// the number requested
        count: usize,
    },
}

impl fmt::Display for RobotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            RobotError::NotFinite { tube, field } => {
                write!(f, "tube {tube}: {} must be a finite number", field.key())
            }
            RobotError::NotPositive { tube, field, value } => {
                write!(f, "tube {tube}: {} = {value} must be > 0", field.key())
            }
            RobotError::Negative { tube, field, value } => {
                write!(f, "tube {tube}: {} = {value} must be >= 0", field.key())
            }
            RobotError::WallNotPositive { tube, outer_mm, inner_mm } => write!(
                f,
                "tube {tube}: outer_diameter_mm = {outer_mm} must be larger than inner_diameter_mm = {inner_mm}"
            ),
            RobotError::DoNotNest { inner, inner_outer_diameter_mm, outer_inner_diameter_mm } => write!(
                f,
                "tube {inner}: outer_diameter_mm = {inner_outer_diameter_mm} does not fit inside tube {}'s inner_diameter_mm = {outer_inner_diameter_mm}",
                inner - 1
            ),
            RobotError::CurvedLongerThanTube { tube, curved_mm, length_mm } => write!(
                f,
                "tube {tube}: curved_length_mm = {curved_mm} must not exceed length_mm = {length_mm}"
            ),
            RobotError::PoissonOutOfRange { tube, value } => {
                write!(f, "tube {tube}: poisson_ratio = {value} must lie in [0, 0.5)")
            }
            RobotError::ZeroRadius { tube } => write!(
                f,
                "tube {tube}: curvature_radius_mm must not be 0 (omit it for a straight tube)"
            ),
            RobotError::TubeCount { count } => {
                write!(f, "a robot has 1 to {} tubes, not {count}", crate::MAX_TUBES)
            }
        }
    }
}

/// One tube as described in the robot file (mm, MPa, kg/m^3), before validation.
///
/// ```
/// use ctr_core::TubeParams;
/// let outer = TubeParams::<f64> {
///     curvature_radius_mm: Some(97.0),
///     ..TubeParams::<f64>::new(6.8, 4.9, 180.0, 74.0, 2000.0, 0.41)
/// };
/// assert!(outer.validate(1).is_ok());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TubeParams<T> {
    /// Outer diameter, mm.
    pub outer_diameter_mm: T,
    /// Inner diameter, mm.
    pub inner_diameter_mm: T,
    /// Whole length from actuator to tip, mm.
    pub length_mm: T,
    /// Length of the precurved distal part, mm.
    pub curved_length_mm: T,
    /// Signed radius of the precurved part, mm; `None` for a straight tube.
    pub curvature_radius_mm: Option<T>,
    /// Young's modulus, MPa.
    pub youngs_modulus_mpa: T,
    /// Poisson ratio, in `[0, 0.5)`.
    pub poisson_ratio: T,
    /// Measured bending stiffness E I, N mm^2 (overrides the derived one).
    pub bending_stiffness_nmm2: Option<T>,
    /// Measured torsional stiffness G J, N mm^2 (overrides the derived one).
    pub torsional_stiffness_nmm2: Option<T>,
    /// Density, kg/m^3 (only needed where gravity is modelled).
    pub density_kg_m3: Option<T>,
}

impl<T: Real> TubeParams<T> {
    /// A straight tube with the required fields; set the optional ones with struct update.
    ///
    /// ```
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// assert_eq!(t.curvature_radius_mm, None);
    /// ```
    pub fn new(
        outer_diameter_mm: T,
        inner_diameter_mm: T,
        length_mm: T,
        curved_length_mm: T,
        youngs_modulus_mpa: T,
        poisson_ratio: T,
    ) -> Self {
        TubeParams {
            outer_diameter_mm,
            inner_diameter_mm,
            length_mm,
            curved_length_mm,
            curvature_radius_mm: None,
            youngs_modulus_mpa,
            poisson_ratio,
            bending_stiffness_nmm2: None,
            torsional_stiffness_nmm2: None,
            density_kg_m3: None,
        }
    }

    /// Checks this tube alone (`tube` is its number, 1 = outermost, used in errors) and
    /// derives its stiffnesses.
    ///
    /// ```
    /// use ctr_core::{Field, RobotError, TubeParams};
    /// let bad = TubeParams::<f64>::new(1.0, 1.2, 100.0, 50.0, 58000.0, 0.33);
    /// assert!(matches!(bad.validate(2), Err(RobotError::WallNotPositive { tube: 2, .. })));
    /// ```
    pub fn validate(&self, tube: usize) -> Result<Tube<T>, RobotError> {
        let finite = |field: Field, v: T| {
            if v.is_finite() {
                Ok(v)
            } else {
                Err(RobotError::NotFinite { tube, field })
            }
        };
        let positive = |field: Field, v: T| {
            finite(field, v)?;
            if v > T::zero() {
                Ok(v)
            } else {
                Err(RobotError::NotPositive {
                    tube,
                    field,
                    value: to_f64(v),
                })
            }
        };
        let non_negative = |field: Field, v: T| {
            finite(field, v)?;
            if v >= T::zero() {
                Ok(v)
            } else {
                Err(RobotError::Negative {
                    tube,
                    field,
                    value: to_f64(v),
                })
            }
        };
        let od = positive(Field::OuterDiameter, self.outer_diameter_mm)?;
        let id = non_negative(Field::InnerDiameter, self.inner_diameter_mm)?;
        if od <= id {
            return Err(RobotError::WallNotPositive {
                tube,
                outer_mm: to_f64(od),
                inner_mm: to_f64(id),
            });
        }
        let length = positive(Field::Length, self.length_mm)?;
        let curved = non_negative(Field::CurvedLength, self.curved_length_mm)?;
        if curved > length {
            return Err(RobotError::CurvedLongerThanTube {
                tube,
                curved_mm: to_f64(curved),
                length_mm: to_f64(length),
            });
        }
        let curvature = match self.curvature_radius_mm {
            None => T::zero(),
            Some(r) => {
                finite(Field::CurvatureRadius, r)?;
                if r == T::zero() {
                    return Err(RobotError::ZeroRadius { tube });
                }
                T::one() / r
            }
        };
        let e = positive(Field::YoungsModulus, self.youngs_modulus_mpa)?;
        let nu = finite(Field::PoissonRatio, self.poisson_ratio)?;
        if nu < T::zero() || nu >= c(0.5) {
            return Err(RobotError::PoissonOutOfRange {
                tube,
                value: to_f64(nu),
            });
        }
        let second_moment = T::pi() * (od.powi(4) - id.powi(4)) / c(64.0);
        let shear = e / (c::<T>(2.0) * (T::one() + nu));
        let bending = match self.bending_stiffness_nmm2 {
            Some(v) => positive(Field::BendingStiffness, v)?,
            None => e * second_moment,
        };
        let torsional = match self.torsional_stiffness_nmm2 {
            Some(v) => positive(Field::TorsionalStiffness, v)?,
            None => shear * c(2.0) * second_moment,
        };
        let density = match self.density_kg_m3 {
            Some(v) => Some(non_negative(Field::Density, v)?),
            None => None,
        };
        Ok(Tube {
            params: *self,
            curvature,
            bending,
            torsional,
            area_mm2: T::pi() * (od * od - id * id) / c(4.0),
            density,
        })
    }
}

/// Best-effort conversion for error messages.
fn to_f64<T: Real>(v: T) -> f64 {
    // `to_subset` is exact for f32/f64 and never panics.
    v.to_subset().unwrap_or(f64::NAN)
}

/// A validated tube with its derived stiffnesses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tube<T> {
    params: TubeParams<T>,
    curvature: T,
    bending: T,
    torsional: T,
    area_mm2: T,
    density: Option<T>,
}

impl<T: Real> Tube<T> {
    /// The parameters it was built from.
    ///
    /// ```
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33).validate(1).unwrap();
    /// assert_eq!(t.params().length_mm, 180.0);
    /// ```
    pub fn params(&self) -> &TubeParams<T> {
        &self.params
    }
    /// Signed precurvature of the curved part, 1/mm (0 for a straight tube).
    ///
    /// ```
    /// let mut p = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// p.curvature_radius_mm = Some(-200.0);
    /// assert_eq!(p.validate(1).unwrap().curvature_per_mm(), -0.005);
    /// ```
    pub fn curvature_per_mm(&self) -> T {
        self.curvature
    }
    /// Bending stiffness E I, N mm^2.
    ///
    /// ```
    /// let t = ctr_core::TubeParams::<f64>::new(2.0, 0.0, 100.0, 0.0, 64.0, 0.0).validate(1).unwrap();
    /// assert!((t.bending_stiffness_nmm2() - core::f64::consts::PI * 16.0).abs() < 1e-12);
    /// ```
    pub fn bending_stiffness_nmm2(&self) -> T {
        self.bending
    }
    /// Torsional stiffness G J, N mm^2.
    ///
    /// ```
    /// let t = ctr_core::TubeParams::<f64>::new(2.0, 0.0, 100.0, 0.0, 64.0, 0.0).validate(1).unwrap();
    /// // nu = 0: G = E / 2, J = 2 I, so G J = E I
    /// assert!((t.torsional_stiffness_nmm2() - t.bending_stiffness_nmm2()).abs() < 1e-12);
    /// ```
    pub fn torsional_stiffness_nmm2(&self) -> T {
        self.torsional
    }
    /// Cross-section area of the wall, mm^2.
    ///
    /// ```
    /// let t = ctr_core::TubeParams::<f64>::new(2.0, 0.0, 100.0, 0.0, 64.0, 0.0).validate(1).unwrap();
    /// assert!((t.area_mm2() - core::f64::consts::PI).abs() < 1e-12);
    /// ```
    pub fn area_mm2(&self) -> T {
        self.area_mm2
    }
    /// Density, kg/m^3, if the file gave one.
    ///
    /// ```
    /// let t = ctr_core::TubeParams::<f64>::new(2.0, 0.0, 100.0, 0.0, 64.0, 0.0).validate(1).unwrap();
    /// assert_eq!(t.density_kg_m3(), None);
    /// ```
    pub fn density_kg_m3(&self) -> Option<T> {
        self.density
    }
}

/// A robot of `N` nested tubes, index 0 the outermost (tube 1 in files and messages).
///
/// ```
/// use ctr_core::{Robot, TubeParams};
/// let outer = TubeParams { curvature_radius_mm: Some(-97.0), ..TubeParams::<f64>::new(6.8, 4.9, 124.0, 74.0, 150.0, 0.41) };
/// let inner = TubeParams { curvature_radius_mm: Some(98.5), ..TubeParams::<f64>::new(4.5, 3.3, 174.0, 114.0, 300.0, 0.41) };
/// let robot = Robot::new([outer, inner]).unwrap();
/// assert_eq!(robot.tubes().len(), 2);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Robot<T, const N: usize> {
    tubes: [Tube<T>; N],
}

impl<T: Real, const N: usize> Robot<T, N> {
    /// Validates every tube and their nesting.
    ///
    /// ```
    /// use ctr_core::{Robot, RobotError, TubeParams};
    /// let a = TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// let b = TubeParams::<f64>::new(1.6, 0.9, 260.0, 90.0, 58000.0, 0.33); // 1.6 > 1.5: does not fit
    /// assert!(matches!(Robot::new([a, b]), Err(RobotError::DoNotNest { inner: 2, .. })));
    /// ```
    pub fn new(params: [TubeParams<T>; N]) -> Result<Self, RobotError> {
        if N == 0 || N > crate::MAX_TUBES {
            return Err(RobotError::TubeCount { count: N });
        }
        let mut tubes = [params[0].validate(1)?; N];
        for i in 1..N {
            tubes[i] = params[i].validate(i + 1)?;
            let od = params[i].outer_diameter_mm;
            let enclosing = params[i - 1].inner_diameter_mm;
            if od >= enclosing {
                return Err(RobotError::DoNotNest {
                    inner: i + 1,
                    inner_outer_diameter_mm: to_f64(od),
                    outer_inner_diameter_mm: to_f64(enclosing),
                });
            }
        }
        Ok(Robot { tubes })
    }

    /// The validated tubes, outermost first.
    ///
    /// ```
    /// # use ctr_core::{Robot, TubeParams};
    /// let r = Robot::new([TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33)]).unwrap();
    /// assert_eq!(r.tubes()[0].params().outer_diameter_mm, 1.8);
    /// ```
    pub fn tubes(&self) -> &[Tube<T>; N] {
        &self.tubes
    }

    /// Each tube's value of `f`, outermost first (the tubes are not copied).
    #[inline(always)]
    pub(crate) fn each<U>(&self, f: impl Fn(&Tube<T>) -> U) -> [U; N] {
        core::array::from_fn(|i| f(&self.tubes[i]))
    }

    /// Clearance between tube `i` and tube `i + 1` (0-based), mm:
    /// `inner_diameter(i) - outer_diameter(i + 1)`; `None` past the innermost tube.
    ///
    /// ```
    /// # use ctr_core::{Robot, TubeParams};
    /// let r = Robot::new([
    ///     TubeParams::<f64>::new(6.8, 4.9, 124.0, 74.0, 150.0, 0.41),
    ///     TubeParams::<f64>::new(4.5, 3.3, 174.0, 114.0, 300.0, 0.41),
    /// ]).unwrap();
    /// assert!((r.clearance_mm(0).unwrap() - 0.4).abs() < 1e-12);
    /// assert_eq!(r.clearance_mm(1), None);
    /// ```
    pub fn clearance_mm(&self, i: usize) -> Option<T> {
        if i + 1 < N {
            Some(
                self.tubes[i].params.inner_diameter_mm - self.tubes[i + 1].params.outer_diameter_mm,
            )
        } else {
            None
        }
    }

    /// A copy with each tube's E I and G J scaled by `factor[i]` and its precurvature
    /// radius by `radius_factor[i]` (the `stiffness` and `precurvature` effects).
    /// Factors must be finite and positive.
    ///
    /// ```
    /// # use ctr_core::{Robot, TubeParams};
    /// let r = Robot::new([TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) }]).unwrap();
    /// let s = r.scaled([2.0], [0.5]).unwrap();
    /// assert_eq!(s.tubes()[0].curvature_per_mm(), 0.02);
    /// ```
    pub fn scaled(&self, stiffness: [T; N], radius_factor: [T; N]) -> Result<Self, RobotError> {
        let mut out = *self;
        for i in 0..N {
            for (v, field) in [
                (stiffness[i], Field::YoungsModulus),
                (radius_factor[i], Field::CurvatureRadius),
            ] {
                if !v.is_finite() {
                    return Err(RobotError::NotFinite { tube: i + 1, field });
                }
                if v <= T::zero() {
                    return Err(RobotError::NotPositive {
                        tube: i + 1,
                        field,
                        value: to_f64(v),
                    });
                }
            }
            let t = &mut out.tubes[i];
            t.bending *= stiffness[i];
            t.torsional *= stiffness[i];
            t.curvature /= radius_factor[i];
            t.params.youngs_modulus_mpa *= stiffness[i];
            t.params.bending_stiffness_nmm2 =
                t.params.bending_stiffness_nmm2.map(|b| b * stiffness[i]);
            t.params.torsional_stiffness_nmm2 =
                t.params.torsional_stiffness_nmm2.map(|b| b * stiffness[i]);
            t.params.curvature_radius_mm =
                t.params.curvature_radius_mm.map(|r| r * radius_factor[i]);
        }
        Ok(out)
    }
}

//! Forward-mode dual numbers: a value and its derivatives with respect to `K` unknowns.
//!
//! Integrating an ODE with RK4 in dual numbers integrates the state and its variational
//! equations (the derivatives of the state with respect to the unknowns) with the same
//! RK4: exact derivatives of the discrete map, not finite differences. The Jacobians,
//! the loaded model's shooting Jacobian and the friction Newton use it.

use crate::real::{c, Real};
use core::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};
use nalgebra::{ComplexField, RealField};

/// Arithmetic the integrators need, for plain scalars `T` and for [`Dual`]s over `T`.
pub trait Num<T: Real>:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Mul<T, Output = Self>
    + AddAssign
    + SubAssign
{
    /// True for numbers that carry derivatives: lets generic code skip derivative-only
    /// work on plain numbers at compile time.
    const DUAL: bool;
    /// A constant (zero derivatives).
    fn cst(v: T) -> Self;
    /// The value.
    fn re(self) -> T;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Sine and cosine ([`crate::math::series`] below 0.3 rad: for the small angles of
    /// a step).
    fn sin_cos(self) -> (Self, Self);
    /// Sine and cosine of an angle of any size by the platform's trigonometry: for the
    /// boundary angles (actuator angles, twists over whole transmissions).
    #[inline(always)]
    fn sin_cos_wide(self) -> (Self, Self) {
        let (s, co) = ComplexField::sin_cos(self.re());
        (self.chain(s, co), self.chain(co, -s))
    }
    /// The angle of the point `(x, self)`, in `(-pi, pi]`.
    fn atan2(self, x: Self) -> Self;
    /// `f(self)` from the value `f(re)` and the derivative `f'(re)` of a scalar function
    /// `f` (the chain rule): evaluates `f` once on plain numbers.
    ///
    /// ```
    /// use ctr_core::math::dual::{Dual, Num};
    /// let x = Dual::<f64, 1>::var(2.0, 0);
    /// let cube = x.chain(8.0, 12.0); // x^3 and 3 x^2 at 2
    /// assert_eq!((cube.re, cube.eps[0]), (8.0, 12.0));
    /// ```
    fn chain(self, value: T, derivative: T) -> Self;
}

impl<T: Real> Num<T> for T {
    const DUAL: bool = false;
    #[inline(always)]
    fn cst(v: T) -> Self {
        v
    }
    #[inline(always)]
    fn re(self) -> T {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        nalgebra::ComplexField::sqrt(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        super::series::sin_cos(self)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        RealField::atan2(self, x)
    }
    #[inline(always)]
    fn chain(self, value: T, _derivative: T) -> Self {
        value
    }
}

/// A value with its gradient with respect to `K` unknowns.
///
/// ```
/// use ctr_core::math::dual::{Dual, Num};
/// let x = Dual::<f64, 2>::var(3.0, 0);
/// let y = Dual::<f64, 2>::var(2.0, 1);
/// let f = x * x * y; // d/dx = 2xy = 12, d/dy = x^2 = 9
/// assert_eq!(f.re(), 18.0);
/// assert_eq!(f.eps, [12.0, 9.0]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<T, const K: usize> {
    /// The value.
    pub re: T,
    /// Its derivatives.
    pub eps: [T; K],
}

impl<T: Real, const K: usize> Dual<T, K> {
    /// The `i`-th unknown with value `v` (derivative 1 with respect to itself).
    ///
    /// ```
    /// let x = ctr_core::math::dual::Dual::<f64, 3>::var(1.5, 2);
    /// assert_eq!(x.eps, [0.0, 0.0, 1.0]);
    /// ```
    pub fn var(v: T, i: usize) -> Self {
        let mut eps = [T::zero(); K];
        if let Some(e) = eps.get_mut(i) {
            *e = T::one();
        }
        Dual { re: v, eps }
    }
}

impl<T: Real, const K: usize> Num<T> for Dual<T, K> {
    const DUAL: bool = true;
    #[inline(always)]
    fn cst(v: T) -> Self {
        Dual {
            re: v,
            eps: [T::zero(); K],
        }
    }
    #[inline(always)]
    fn re(self) -> T {
        self.re
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let r = nalgebra::ComplexField::sqrt(self.re);
        self.chain(r, c::<T>(0.5) / r)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, co) = super::series::sin_cos(self.re);
        (self.chain(s, co), self.chain(co, -s))
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        // d atan2(y, x) = (x dy - y dx) / (x^2 + y^2)
        let r2 = x.re * x.re + self.re * self.re;
        let mut eps = [T::zero(); K];
        for i in 0..K {
            eps[i] = (x.re * self.eps[i] - self.re * x.eps[i]) / r2;
        }
        Dual {
            re: RealField::atan2(self.re, x.re),
            eps,
        }
    }
    #[inline(always)]
    fn chain(self, re: T, d: T) -> Self {
        Dual {
            re,
            eps: self.eps.map(|e| e * d),
        }
    }
}

impl<T: Real, const K: usize> Add for Dual<T, K> {
    type Output = Self;
    #[inline(always)]
    fn add(mut self, o: Self) -> Self {
        self.re += o.re;
        for i in 0..K {
            self.eps[i] += o.eps[i];
        }
        self
    }
}
impl<T: Real, const K: usize> Sub for Dual<T, K> {
    type Output = Self;
    #[inline(always)]
    fn sub(mut self, o: Self) -> Self {
        self.re -= o.re;
        for i in 0..K {
            self.eps[i] -= o.eps[i];
        }
        self
    }
}
impl<T: Real, const K: usize> Mul for Dual<T, K> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let mut eps = [T::zero(); K];
        for i in 0..K {
            eps[i] = self.eps[i] * o.re + o.eps[i] * self.re;
        }
        Dual {
            re: self.re * o.re,
            eps,
        }
    }
}
impl<T: Real, const K: usize> Div for Dual<T, K> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let inv = T::one() / o.re;
        let re = self.re * inv;
        let mut eps = [T::zero(); K];
        for i in 0..K {
            eps[i] = (self.eps[i] - re * o.eps[i]) * inv;
        }
        Dual { re, eps }
    }
}
impl<T: Real, const K: usize> Neg for Dual<T, K> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Dual {
            re: -self.re,
            eps: self.eps.map(|e| -e),
        }
    }
}
impl<T: Real, const K: usize> Mul<T> for Dual<T, K> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, k: T) -> Self {
        Dual {
            re: self.re * k,
            eps: self.eps.map(|e| e * k),
        }
    }
}
impl<T: Real, const K: usize> AddAssign for Dual<T, K> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<T: Real, const K: usize> SubAssign for Dual<T, K> {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_closed_forms() {
        let x = Dual::<f64, 1>::var(0.7, 0);
        let (s, co) = x.sin_cos();
        assert!((s.eps[0] - 0.7_f64.cos()).abs() < 1e-15);
        assert!((co.eps[0] + 0.7_f64.sin()).abs() < 1e-15);
        let r = (x * x + Dual::cst(1.0)).sqrt();
        assert!((r.eps[0] - 0.7 / (0.49_f64 + 1.0).sqrt()).abs() < 1e-15);
        let q = Dual::cst(2.0) / x;
        assert!((q.eps[0] + 2.0 / 0.49).abs() < 1e-13);
        // atan2 against differences, in every quadrant
        for (y, x0) in [(0.3, 0.8), (0.5, -0.2), (-0.4, -0.9), (-0.7, 0.1)] {
            let a = Dual::<f64, 2>::var(y, 0).atan2(Dual::var(x0, 1));
            let h = 1e-7;
            let dy = (f64::atan2(y + h, x0) - f64::atan2(y - h, x0)) / (2.0 * h);
            let dx = (f64::atan2(y, x0 + h) - f64::atan2(y, x0 - h)) / (2.0 * h);
            assert!((a.eps[0] - dy).abs() < 1e-8 && (a.eps[1] - dx).abs() < 1e-8);
            assert!((a.re - f64::atan2(y, x0)).abs() < 1e-15);
        }
    }
}

//! The Taylor series of the SE(3) exponential's coefficients, and a sine and cosine
//! built on them: below `t = 0.3` rad they are exact to machine precision and need no
//! trigonometry (RK4 steps turn the frame by about 0.1 rad).

use crate::real::{c, Real};

/// Below this squared angle (t < 0.3 rad) the Taylor series to `t^10` are exact to
/// machine precision: the first omitted term of `sin t / t` is `t^12 / 13! < 1e-16`.
/// RK4 steps turn the frame by about 0.1 rad, so exponentials need no trigonometry.
pub const SERIES_LIMIT_SQ: f64 = 0.09;

/// A Taylor series in `t^2` in Horner form, `lead (1 - t2/d0 (1 - t2/d1 (...)))`.
pub(crate) struct Series {
    lead: f64,
    divisors: [f64; 5],
}

/// `sin t / t`.
pub(crate) const SINC: Series = Series {
    lead: 1.0,
    divisors: [6.0, 20.0, 42.0, 72.0, 110.0],
};
/// `(1 - cos t) / t^2`.
pub(crate) const VERSINE: Series = Series {
    lead: 0.5,
    divisors: [12.0, 30.0, 56.0, 90.0, 132.0],
};
/// `(t - sin t) / t^3`.
pub(crate) const SIN_DEFECT: Series = Series {
    lead: 1.0 / 6.0,
    divisors: [20.0, 42.0, 72.0, 110.0, 156.0],
};

impl Series {
    /// The value at `t2` (< [`SERIES_LIMIT_SQ`]).
    #[inline(always)]
    pub(crate) fn value<T: Real>(&self, t2: T) -> T {
        let mut acc = T::one();
        for d in self.divisors.iter().rev() {
            acc = T::one() - t2 / c(*d) * acc;
        }
        c::<T>(self.lead) * acc
    }

    /// The derivative with respect to `t2` at `t2`: the polynomial
    /// `lead sum_k c_k t2^k` (`c_0 = 1`, `c_k = -c_{k-1} / d_{k-1}`) differentiated term
    /// by term, in Horner form.
    #[inline(always)]
    pub(crate) fn derivative<T: Real>(&self, t2: T) -> T {
        let mut coefficient = [T::one(); 6];
        for k in 1..6 {
            coefficient[k] = -coefficient[k - 1] / c(self.divisors[k - 1]);
        }
        let mut acc = T::zero();
        for k in (1..6).rev() {
            acc = acc * t2 + coefficient[k] * c(k as f64);
        }
        acc * c(self.lead)
    }
}

/// `(sin x, cos x)`, by Taylor series (exact to machine precision) for `|x| < 0.3`.
#[inline(always)]
pub(crate) fn sin_cos<T: Real>(x: T) -> (T, T) {
    let x2 = x * x;
    if x2 < c(SERIES_LIMIT_SQ) {
        (x * SINC.value(x2), T::one() - x2 * VERSINE.value(x2))
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
            assert!((SINC.value(t2) - t.sin() / t).abs() < 2e-16);
            // 2 sin^2(t/2) avoids the cancellation of 1 - cos t
            assert!((VERSINE.value(t2) - 2.0 * (t / 2.0).sin().powi(2) / t2).abs() < 2e-16);
            if t >= 0.1 {
                // t - sin t cancels to ~1e-16 / t^3 relative: compare loosely there
                assert!((SIN_DEFECT.value(t2) - (t - t.sin()) / (t2 * t)).abs() < 1e-12);
            }
            let (s, co) = sin_cos(t);
            assert!((s - t.sin()).abs() < 1e-16 && (co - t.cos()).abs() < 2e-16);
        }
    }

    #[test]
    fn series_derivatives_match_differences() {
        for t2 in [1e-4_f64, 0.01, 0.05, 0.0899] {
            for s in [&SINC, &VERSINE, &SIN_DEFECT] {
                let h = 1e-6;
                let fd = (s.value(t2 + h) - s.value(t2 - h)) / (2.0 * h);
                assert!((s.derivative(t2) - fd).abs() < 1e-9, "{t2}");
            }
        }
    }
}

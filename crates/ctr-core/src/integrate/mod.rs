//! Integration along the backbone: the one classical RK4 step (`rk4_step`) over any
//! state that forms a vector space (`OdeState`), and the systems it advances:
//!
//! - [`twist`]: the unloaded twist equations on plain or dual numbers, integrated
//!   section by section (RK4 with a 4th-order Magnus pose step, or in closed form where
//!   at most one tube is curved);
//! - [`variations`]: the same with the sensitivities to the shooting unknowns carried
//!   explicitly (Newton's Jacobian, a third of the cost of dual numbers);
//! - [`sensitivities`]: the same on any directions of the unknowns and the joints (the
//!   softest mode's gradient);
//! - [`loaded`]: the Cosserat statics under gravity and tip loads;
//! - [`pass`]: one pass from the guide exit to the tip (boundary conditions, tips,
//!   clearance kinks, friction moments) for the unloaded systems;
//! - [`pose`]: the frames a pass moves (plain, with derivatives, or none).

pub mod loaded;
pub mod pass;
pub mod pose;
pub mod sensitivities;
pub mod twist;
pub mod variations;

use crate::math::dual::Num;
use crate::real::{c, Real};
use core::ops::Mul;

/// A state RK4 advances: its moving components, of scalar type `S`, form a vector space.
pub(crate) trait OdeState<S>: Copy {
    /// `self[i] = f(self[i], [k_0[i], ..., k_{K-1}[i]])` for every moving component `i`.
    fn zip_with<const K: usize>(&mut self, k: [&Self; K], f: impl Fn(S, [S; K]) -> S);
}

/// Where in a step RK4 evaluates the right-hand side (for systems whose coefficients
/// vary along the step, as the loaded model's internal force does).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Stage {
    /// Half way: `k2` and `k3`.
    Middle,
    /// The step's end: `k4`.
    End,
}

/// A right-hand side RK4 evaluates: `d x / ds` at a stage of the step (a trait rather
/// than a closure, so that it inlines into the step).
pub(crate) trait Rhs<X> {
    /// `d x / ds` at `x`, at `stage` of the step.
    fn rhs(&self, x: &X, stage: Stage) -> X;
}

/// `x + h d`.
#[inline(always)]
pub(crate) fn axpy<T: Real, S: Num<T> + Mul<H, Output = S>, H: Copy, X: OdeState<S>>(
    x: &X,
    d: &X,
    h: H,
) -> X {
    let mut o = *x;
    o.zip_with([d], |v, [dv]| v + dv * h);
    o
}

/// One classical RK4 step of length `h` (with `half = h / 2`, `sixth = h / 6`) from `x`,
/// where `k1 = f(x)` is given (it is the previous step's end: first same as last).
#[inline(always)]
pub(crate) fn rk4_step<T, S, H, X>(x: &X, k1: &X, h: H, half: H, sixth: H, f: &impl Rhs<X>) -> X
where
    T: Real,
    S: Num<T> + Mul<H, Output = S>,
    H: Copy,
    X: OdeState<S>,
{
    let k2 = f.rhs(&axpy(x, k1, half), Stage::Middle);
    let k3 = f.rhs(&axpy(x, &k2, half), Stage::Middle);
    let k4 = f.rhs(&axpy(x, &k3, h), Stage::End);
    let mut next = *x;
    next.zip_with([k1, &k2, &k3, &k4], |v, [a, b, d, e]| {
        v + (a + (b + d) * c::<T>(2.0) + e) * sixth
    });
    next
}

/// Number of equal RK4 steps for a section of length `len` at most `h_max` long each.
#[inline]
pub(crate) fn steps<T: Real>(len: T, h_max: T) -> usize {
    const MAX_STEPS_PER_SECTION: usize = 100_000;
    let n: f64 = (len / h_max).ceil().to_subset().unwrap_or(1.0);
    if n.is_finite() && n >= 1.0 {
        (n as usize).min(MAX_STEPS_PER_SECTION)
    } else {
        1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `y' = y` as a one-component state.
    #[derive(Clone, Copy)]
    struct Scalar(f64);

    struct Growth;

    impl Rhs<Scalar> for Growth {
        fn rhs(&self, x: &Scalar, _: Stage) -> Scalar {
            *x
        }
    }

    impl OdeState<f64> for Scalar {
        fn zip_with<const K: usize>(&mut self, k: [&Self; K], f: impl Fn(f64, [f64; K]) -> f64) {
            self.0 = f(self.0, k.map(|s| s.0));
        }
    }

    /// RK4 is 4th order: halving the step divides the error by about 16.
    #[test]
    fn rk4_is_fourth_order() {
        let error = |n: usize| {
            let h = 1.0 / n as f64;
            let mut y = Scalar(1.0);
            for _ in 0..n {
                let k1 = y;
                y = rk4_step(&y, &k1, h, h / 2.0, h / 6.0, &Growth);
            }
            (y.0 - 1f64.exp()).abs()
        };
        let ratio = error(8) / error(16);
        assert!((ratio - 16.0).abs() < 1.0, "{ratio}");
    }
}

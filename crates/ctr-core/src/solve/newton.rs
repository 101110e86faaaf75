//! Newton's method on shooting residuals: the one loop every solve iterates with.
//!
//! Each iteration evaluates the residual `r(x)` at the unknowns, and its Jacobian `J`
//! (with the residual, or separately where `Policy::chord` keeps an old one), and
//! steps `x <- x - J^{-1} r`. It stops
//!
//! - on the step (`|dx|_max <= step_tolerance`): convergence is quadratic, so the error
//!   left after a step of size d is about d^2; the caller verifies the residual with
//!   its pose pass and may resume; or
//! - on the residual (`|r| <= residual_tolerance`, the norm the problem defines), where
//!   the evaluation itself gives the pose;
//!
//! and otherwise at the iteration bound or when numbers stop being finite. A step that
//! makes the residual grow by more than `OVERSHOOT` is halved and retried (down to
//! `MIN_DAMPING`); a cold unloaded solve first converges on coarse RK4 steps.

use crate::math::linalg::{max_abs, solve_linear};
use crate::real::{c, Real};

/// A step is an overshoot when the residual grows by more than this factor.
pub(crate) const OVERSHOOT: f64 = 1.5;
/// Smallest fraction of an overshooting step tried.
pub(crate) const MIN_DAMPING: f64 = 1.0 / 64.0;
/// A chord iteration whose residual shrinks by less than this factor refreshes its
/// Jacobian (a Newton step).
pub(crate) const CHORD_CONTRACTION: f64 = 0.25;
/// The coarse phase of a cold solve ends when Newton's step is this many times the
/// step tolerance: closer than that, the coarse grid's own error dominates.
pub(crate) const COARSE_STEP_TOLERANCE_FACTOR: f64 = 100.0;

/// A residual and, where it comes with it, its Jacobian.
pub(crate) struct Evaluation<T, const M: usize> {
    pub r: [T; M],
    /// The size the stopping test and the overshoot test compare (non-finite: broken).
    pub norm: T,
    pub jacobian: Option<[[T; M]; M]>,
}

/// What Newton's method iterates on.
pub(crate) trait Shooting<T, const M: usize> {
    /// The residual at `x` (on the coarse steps when `coarse`).
    fn residual(&mut self, x: &[T; M], coarse: bool) -> Evaluation<T, M>;
    /// The Jacobian at `x`, where [`residual`](Self::residual) does not give it.
    fn jacobian(&mut self, x: &[T; M]) -> Option<[[T; M]; M]>;
}

/// How Newton's method stops and steps.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Policy<T> {
    /// Unknowns in use (the leading `m` of the arrays).
    pub m: usize,
    pub max_iterations: u32,
    /// `Some`: stop on a small step (see the module doc); `None`: on a small residual.
    pub step_tolerance: Option<T>,
    pub residual_tolerance: T,
    /// Halve overshooting steps.
    pub backtrack: bool,
    /// Keep the last Jacobian while the residual contracts by [`CHORD_CONTRACTION`].
    pub chord: bool,
}

/// Why [`Newton::run`] stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Stop {
    /// The step fell below the step tolerance (or there is nothing to solve).
    Step,
    /// The residual fell below the residual tolerance at the current unknowns.
    Residual,
    /// The iteration bound was reached.
    Limit,
    /// Numbers stopped being finite or the Jacobian is singular.
    Diverged,
}

/// The iteration's state, kept between [`run`](Newton::run)s so that a caller can
/// verify and resume.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Newton<T, const M: usize> {
    /// The unknowns.
    pub x: [T; M],
    /// Residual evaluations so far.
    pub iterations: u32,
    /// The unknowns with the smallest residual norm seen, and that norm.
    pub best: ([T; M], T),
    /// The Jacobian of the last step taken (zero before the first).
    pub jacobian: [[T; M]; M],
    have_jacobian: bool,
    prev_norm: T,
    last_step: [T; M],
    /// the residual the last step was taken from (for the chord's Broyden update)
    last_r: Option<[T; M]>,
    damping: T,
    /// On the coarse steps of a cold start.
    pub coarse: bool,
}

impl<T: Real, const M: usize> Newton<T, M> {
    /// Starts at `x0`, on the coarse steps when `coarse`.
    pub fn new(x0: [T; M], coarse: bool) -> Self {
        let huge = T::max_value().unwrap_or(T::one());
        Newton {
            x: x0,
            iterations: 0,
            best: (x0, huge),
            jacobian: [[T::zero(); M]; M],
            have_jacobian: false,
            prev_norm: huge,
            last_step: [T::zero(); M],
            last_r: None,
            damping: T::one(),
            coarse,
        }
    }

    /// Starts with a Jacobian from an earlier solve (for `Policy::chord`).
    pub fn with_jacobian(mut self, jacobian: [[T; M]; M]) -> Self {
        self.jacobian = jacobian;
        self.have_jacobian = true;
        self
    }

    /// Forgets the last residual, so that the next evaluation is not taken for an
    /// overshoot (after the caller has moved on, e.g. verified the residual).
    pub fn forget_norm(&mut self) {
        self.prev_norm = T::max_value().unwrap_or(T::one());
    }

    /// Iterates until one of the [`Stop`]s. Inlined into its few callers: their number
    /// of unknowns is then a constant the linear solve is unrolled for.
    #[inline(always)]
    pub fn run(&mut self, problem: &mut impl Shooting<T, M>, policy: &Policy<T>) -> Stop {
        let m = policy.m;
        let huge = T::max_value().unwrap_or(T::one());
        loop {
            if m == 0 {
                return Stop::Step;
            }
            if self.iterations >= policy.max_iterations {
                return Stop::Limit;
            }
            self.iterations += 1;
            let ev = problem.residual(&self.x, self.coarse);
            let norm = ev.norm;
            if !norm.is_finite() {
                return Stop::Diverged;
            }
            if norm < self.best.1 {
                self.best = (self.x, norm);
            }
            if policy.step_tolerance.is_none() && norm <= policy.residual_tolerance {
                return Stop::Residual;
            }
            if policy.backtrack
                && norm > self.prev_norm * c(OVERSHOOT)
                && self.damping > c(MIN_DAMPING)
            {
                // the last step overshot: go back half way and try again
                self.damping *= c(0.5);
                for i in 0..m {
                    self.x[i] += self.last_step[i] * self.damping;
                }
                self.last_r = None;
                continue;
            }
            let refresh = !policy.chord
                || !self.have_jacobian
                || norm > self.prev_norm * c(CHORD_CONTRACTION);
            self.prev_norm = norm;
            self.damping = T::one();
            if let Some(j) = ev.jacobian {
                self.jacobian = j;
                self.have_jacobian = true;
            } else if refresh {
                let Some(j) = problem.jacobian(&self.x) else {
                    return Stop::Diverged;
                };
                self.jacobian = j;
                self.have_jacobian = true;
            } else if let Some(r0) = self.last_r {
                broyden(&mut self.jacobian, &r0, &ev.r, &self.last_step, m);
            }
            self.last_r = Some(ev.r);
            let Some(dx) = solve_linear::<T, M>(self.jacobian, ev.r, m) else {
                return Stop::Diverged;
            };
            for i in 0..m {
                self.x[i] -= dx[i];
            }
            self.last_step = dx;
            let step = max_abs(&dx, m);
            if !step.is_finite() || step >= huge {
                return Stop::Diverged;
            }
            if let Some(tol) = policy.step_tolerance {
                if self.coarse && step <= tol * c(COARSE_STEP_TOLERANCE_FACTOR) {
                    self.coarse = false;
                    self.prev_norm = huge;
                    self.best.1 = huge;
                } else if step <= tol {
                    return Stop::Step;
                }
            }
        }
    }

    /// True when every unknown is finite.
    pub fn finite(&self) -> bool {
        self.x.iter().all(|v| v.is_finite())
    }
}

/// Broyden's ("good") rank-one update of a chord Jacobian `j` (rows: residuals) after
/// the step `x <- x - dx` took the residual from `r0` to `r1`: the secant condition
/// `J' (-dx) = r1 - r0`, changing `J` least. Keeps a chord iteration superlinear
/// without a new derivative pass.
fn broyden<T: Real, const M: usize>(
    j: &mut [[T; M]; M],
    r0: &[T; M],
    r1: &[T; M],
    dx: &[T; M],
    m: usize,
) {
    let mut dd = T::zero();
    for k in 0..m {
        dd += dx[k] * dx[k];
    }
    if dd <= T::zero() || !dd.is_finite() {
        return;
    }
    for i in 0..m {
        // (dr - J ds) with ds = -dx
        let mut js = T::zero();
        for k in 0..m {
            js -= j[i][k] * dx[k];
        }
        let u = (r1[i] - r0[i] - js) / dd;
        for k in 0..m {
            j[i][k] -= u * dx[k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `r(x) = (x0^2 - 2, x1 - x0)`: Newton finds sqrt(2) twice over.
    struct Root;

    impl Shooting<f64, 2> for Root {
        fn residual(&mut self, x: &[f64; 2], _: bool) -> Evaluation<f64, 2> {
            let r = [x[0] * x[0] - 2.0, x[1] - x[0]];
            Evaluation {
                r,
                norm: r[0].abs().max(r[1].abs()),
                jacobian: None,
            }
        }
        fn jacobian(&mut self, x: &[f64; 2]) -> Option<[[f64; 2]; 2]> {
            Some([[2.0 * x[0], 0.0], [-1.0, 1.0]])
        }
    }

    #[test]
    fn converges_on_the_step_and_on_the_residual() {
        for (step_tolerance, chord, want) in [
            (Some(1e-12), false, Stop::Step),
            (None, false, Stop::Residual),
            (None, true, Stop::Residual),
        ] {
            let policy = Policy {
                m: 2,
                max_iterations: 50,
                step_tolerance,
                residual_tolerance: 1e-14,
                backtrack: true,
                chord,
            };
            let mut n = Newton::new([1.0, 0.0], false);
            assert_eq!(n.run(&mut Root, &policy), want);
            assert!((n.x[0] - 2f64.sqrt()).abs() < 1e-12 && (n.x[1] - n.x[0]).abs() < 1e-12);
        }
        let policy = Policy {
            m: 2,
            max_iterations: 2,
            step_tolerance: None,
            residual_tolerance: 1e-14,
            backtrack: false,
            chord: false,
        };
        assert_eq!(
            Newton::new([1.0, 0.0], false).run(&mut Root, &policy),
            Stop::Limit
        );
    }
}

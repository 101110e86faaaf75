//! Snap-through: where the branch a robot is on ends, the stable branch it jumps to.
//!
//! # Physics
//!
//! The torsion model's equilibria at given joints are the roots of the shooting residual
//! `r(x) = (u_1(s_1), ..., u_{n-1}(s_{n-1}))` of the base twist rates `x`
//! ([`crate::integrate::twist`]). Along a joint path they form branches; a branch ends at
//! a fold, where the shooting Jacobian `R_x` is singular and the stability margin
//! ([`super::Solution::softest_mode`]) is zero: there a stable equilibrium meets an
//! unstable one and both vanish. A robot moved past a fold snaps (Dupont et al., IEEE
//! T-RO 26(2) 2010; Gilbert, Hendrick & Webster, IEEE T-RO 32(1) 2016): it leaves along
//! the mode that went soft, the right singular vector `v` of the smallest singular value
//! of `R_x` at the last equilibrium, to the nearest stable equilibrium.
//!
//! So when a warm start fails or lands on the unstable side of a fold, the solver looks
//! along the line `x_prev + t v`, `|t| <= span`, for the roots of `r` (sign changes of
//! `r . v'` for one unknown, local minima of `|r|` for more), nearest first, and takes the
//! first from which Newton converges to a stable equilibrium (margin > 0). `span` bounds
//! every equilibrium's base twist: over a section where tubes `l` are curved, a first
//! integral of the twist equations gives `|u_j| <= 2 sqrt(sum_l |g_j a_l|)`
//! ([`SPAN_FACTOR`] times that, the largest over the sections, is scanned).

use super::newton::Shooting;
use super::shooting::Twist;
use super::{Solution, Solver, Status};
use crate::integrate::pass::{Mechanics, Setup};
use crate::integrate::twist::Inputs;
use crate::math::linalg::softest_direction;
use crate::model::effects::Registration;
use crate::real::{c, Real};
use nalgebra::Vector3;

/// Most points of the scan along the soft mode, each side of the last equilibrium.
pub(crate) const MAX_SCAN_POINTS: usize = 512;
/// Longest scan step, as the change of a tube's angle at the guide exit it makes
/// through the longest tube (rad): the residual turns once per `2 pi` of it, so the
/// scan sees every root of one turn.
pub(crate) const SCAN_ANGLE_STEP_RAD: f64 = 0.2;
/// Starts tried from the scan, nearest first.
pub(crate) const MAX_STARTS: usize = 4;
/// An origin whose scalar is below this fraction of its slope times a step counts as a
/// root (see the scan).
pub(crate) const ORIGIN_FRACTION: f64 = 1e-3;
/// The scan reaches this many times the first-integral bound of the twist rates (module
/// doc: the bound is 2 sqrt(sum |g a|)).
pub(crate) const SPAN_FACTOR: f64 = 1.5;

impl<T: Real, const N: usize> Solver<T, N> {
    /// Looks for the stable equilibrium the robot snaps to from the last equilibrium
    /// `from` (module doc); on success writes it into `sol` (with the trace) and returns
    /// true, else leaves `sol` as it was.
    pub(super) fn stable_branch(
        &self,
        setup: &Setup<'_, T, N>,
        inp: &Inputs<T, T, N>,
        from: [T; N],
        trace: Option<&mut [Vector3<T>]>,
        registration: Option<Registration<T>>,
        sol: &mut Solution<T, N>,
    ) -> bool {
        let m = N - 1;
        if m == 0 {
            return false;
        }
        let span = twist_bound(setup) * c(SPAN_FACTOR);
        if span <= T::zero() || !span.is_finite() {
            return false;
        }
        // an origin beyond every equilibrium (a diverged iterate): the untwisted state
        let from = if from.iter().take(m).all(|v| v.abs() <= span) {
            from
        } else {
            [T::zero(); N]
        };
        let mut problem = Twist {
            setup: Setup {
                mechanics: Mechanics::Torsion { coarse: false },
                ..*setup
            },
            inp: *inp,
        };
        let at = |t: T, v: &[T; N]| -> [T; N] { core::array::from_fn(|i| from[i] + v[i] * t) };
        let here = problem.residual(&from, false);
        let Some(jac) = here.jacobian else {
            return false;
        };
        let v = softest_direction(&jac, m);
        // a signed scalar along the line: the residual along the left singular vector
        // `J v / |J v|` (for one unknown, the residual itself; near the origin it grows
        // as `|J v| t`), and the residual's size
        let (left, stiffness) = {
            let mut w = [T::zero(); N];
            for i in 0..m {
                for k in 0..m {
                    w[i] += jac[i][k] * v[k];
                }
            }
            let n = w.iter().take(m).fold(T::zero(), |a, b| a + *b * *b).sqrt();
            if n > T::zero() {
                w.iter_mut().for_each(|x| *x /= n);
            }
            (w, n)
        };
        let longest = setup
            .robot
            .tubes()
            .iter()
            .fold(T::zero(), |a, t| a.max(t.params().length_mm));
        let fine = c::<T>(SCAN_ANGLE_STEP_RAD) / longest;
        let mut points = MAX_SCAN_POINTS;
        for k in 1..MAX_SCAN_POINTS {
            if span / c::<T>(k as f64) <= fine {
                points = k;
                break;
            }
        }
        let step = span / c::<T>(points as f64);
        // candidate starts: for each side, the points where the scalar changes sign or
        // the residual's size has a local minimum, in order of distance
        let mut starts = [(T::zero(), T::zero()); MAX_STARTS];
        let mut found = 0;
        let mut sample = |k: isize| -> (T, T, T) {
            let t = step * c::<T>(k as f64);
            let r = problem.residual(&at(t, &v), false).r;
            let along = (0..m).fold(T::zero(), |a, i| a + r[i] * left[i]);
            let size = (0..m).fold(T::zero(), |a, i| a + r[i] * r[i]).sqrt();
            (t, along, size)
        };
        let origin = sample(0);
        // an origin that is an equilibrium (an unstable one) has no sign: give each side
        // the sign its slope gives the scalar there, so that a root within the first
        // step (beside a pitchfork) shows as a change of sign
        let tiny = stiffness * step * c(ORIGIN_FRACTION);
        let side = |sign: T| {
            if origin.1.abs() < tiny {
                (origin.0, sign * tiny, origin.2)
            } else {
                origin
            }
        };
        let mut last = [side(T::one()), side(-T::one())];
        let mut before = last;
        for k in 1..=points as isize {
            for (side, sign) in [(0usize, 1isize), (1, -1)] {
                let now = sample(sign * k);
                let (prev, prev2) = (last[side], before[side]);
                let crossing = now.1.is_finite()
                    && prev.1.is_finite()
                    && (now.1 == T::zero() || (now.1 > T::zero()) != (prev.1 > T::zero()));
                let dip = m > 1 && k >= 2 && prev.2 < now.2 && prev.2 < prev2.2;
                if (crossing || dip) && found < MAX_STARTS {
                    let t = if crossing && k == 1 {
                        // beside the origin (an equilibrium itself, maybe): from the far
                        // sample, so that Newton does not fall back to the origin
                        now.0
                    } else if crossing {
                        // secant between the two samples
                        let w = prev.1 / (prev.1 - now.1);
                        prev.0 + (now.0 - prev.0) * w
                    } else {
                        prev.0
                    };
                    starts[found] = (t.abs(), t);
                    found += 1;
                }
                before[side] = prev;
                last[side] = now;
            }
            if found == MAX_STARTS {
                break;
            }
        }
        let mut candidate = *sol;
        for &(_, t) in starts.iter().take(found) {
            self.shoot(
                setup,
                inp,
                at(t, &v),
                false,
                None,
                registration,
                &mut candidate,
            );
            if candidate.status == Status::Converged && candidate.softest_mode > T::zero() {
                let x = candidate.base_twist_per_mm;
                let iterations = candidate.iterations;
                // once more from the root itself, tracing the backbone where asked
                self.shoot(setup, inp, x, false, trace, registration, sol);
                sol.iterations += iterations;
                return sol.status == Status::Converged;
            }
        }
        false
    }
}

/// The largest first-integral bound `2 sqrt(sum_l |g_j a_l|)` of a base twist rate over
/// the configuration's sections (module doc), rad/mm.
fn twist_bound<T: Real, const N: usize>(setup: &Setup<'_, T, N>) -> T {
    let mut most = T::zero();
    for sec in setup.sections.list.iter().take(setup.sections.len) {
        let a = sec.a.iter().fold(T::zero(), |acc, v| acc + v.abs());
        for g in &sec.g {
            most = most.max(g.abs() * a);
        }
    }
    most.sqrt() * c(2.0)
}

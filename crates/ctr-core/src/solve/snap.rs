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
        let Some(mut line) = SoftLine::new(setup, inp, from) else {
            return false;
        };
        let points = scan_points(setup, span);
        let step = span / c::<T>(points as f64);
        let (starts, found) = line.starts(step, points);
        self.first_stable(
            setup,
            inp,
            &line,
            &starts[..found],
            trace,
            registration,
            sol,
        )
    }

    /// Newton from each start `t` on `line` (nearest first) until one converges to a
    /// stable equilibrium; that one is solved once more from its own root, tracing the
    /// backbone where asked, into `sol`. True when it converged.
    fn first_stable(
        &self,
        setup: &Setup<'_, T, N>,
        inp: &Inputs<T, T, N>,
        line: &SoftLine<'_, T, N>,
        starts: &[(T, T)],
        trace: Option<&mut [Vector3<T>]>,
        registration: Option<Registration<T>>,
        sol: &mut Solution<T, N>,
    ) -> bool {
        let mut candidate = *sol;
        for &(_, t) in starts {
            self.shoot(
                setup,
                inp,
                line.at(t),
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

/// Points of the scan each side of the origin: enough that a step changes a tube's
/// angle at the guide exit by at most [`SCAN_ANGLE_STEP_RAD`] through the longest tube,
/// at most [`MAX_SCAN_POINTS`].
fn scan_points<T: Real, const N: usize>(setup: &Setup<'_, T, N>, span: T) -> usize {
    let longest = setup
        .robot
        .tubes()
        .iter()
        .fold(T::zero(), |a, t| a.max(t.params().length_mm));
    let fine = c::<T>(SCAN_ANGLE_STEP_RAD) / longest;
    for k in 1..MAX_SCAN_POINTS {
        if span / c::<T>(k as f64) <= fine {
            return k;
        }
    }
    MAX_SCAN_POINTS
}

/// The line `from + t v` along the soft mode `v` of the shooting Jacobian at `from`, and
/// the signed scalar the scan follows along it (module doc).
struct SoftLine<'a, T: Real, const N: usize> {
    problem: Twist<'a, T, N>,
    from: [T; N],
    /// the right singular vector of the smallest singular value at `from`
    v: [T; N],
    /// the residual's direction along the left singular vector `J v / |J v|`
    left: [T; N],
    /// `|J v|`
    stiffness: T,
}

impl<'a, T: Real, const N: usize> SoftLine<'a, T, N> {
    /// The line from `from`; `None` without a shooting Jacobian there.
    fn new(setup: &Setup<'a, T, N>, inp: &Inputs<T, T, N>, from: [T; N]) -> Option<Self> {
        let m = N - 1;
        let mut problem = Twist {
            setup: Setup {
                mechanics: Mechanics::Torsion { coarse: false },
                ..*setup
            },
            inp: *inp,
        };
        let jac = problem.residual(&from, false).jacobian?;
        let v = softest_direction(&jac, m);
        // a signed scalar along the line: the residual along the left singular vector
        // `J v / |J v|` (for one unknown, the residual itself; near the origin it grows
        // as `|J v| t`), and the residual's size
        let mut left = [T::zero(); N];
        for i in 0..m {
            for k in 0..m {
                left[i] += jac[i][k] * v[k];
            }
        }
        let stiffness = left
            .iter()
            .take(m)
            .fold(T::zero(), |a, b| a + *b * *b)
            .sqrt();
        if stiffness > T::zero() {
            left.iter_mut().for_each(|x| *x /= stiffness);
        }
        Some(SoftLine {
            problem,
            from,
            v,
            left,
            stiffness,
        })
    }

    /// The unknowns at `t` along the line.
    fn at(&self, t: T) -> [T; N] {
        core::array::from_fn(|i| self.from[i] + self.v[i] * t)
    }

    /// `(t, the scalar, the residual's size)` at point `k` of the scan, `step` apart.
    fn sample(&mut self, k: isize, step: T) -> (T, T, T) {
        let m = N - 1;
        let t = step * c::<T>(k as f64);
        let x = self.at(t);
        let r = self.problem.residual(&x, false).r;
        let along = (0..m).fold(T::zero(), |a, i| a + r[i] * self.left[i]);
        let size = (0..m).fold(T::zero(), |a, i| a + r[i] * r[i]).sqrt();
        (t, along, size)
    }

    /// Candidate starts, `(|t|, t)` in the order found: on each side, out to `points`
    /// steps of `step`, the points where the scalar changes sign or the residual's size
    /// has a local minimum, nearest first (at most [`MAX_STARTS`]).
    fn starts(&mut self, step: T, points: usize) -> ([(T, T); MAX_STARTS], usize) {
        let m = N - 1;
        let mut starts = [(T::zero(), T::zero()); MAX_STARTS];
        let mut found = 0;
        let origin = self.sample(0, step);
        // an origin that is an equilibrium (an unstable one) has no sign: give each side
        // the sign its slope gives the scalar there, so that a root within the first
        // step (beside a pitchfork) shows as a change of sign
        let tiny = self.stiffness * step * c(ORIGIN_FRACTION);
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
                let now = self.sample(sign * k, step);
                let (prev, prev2) = (last[side], before[side]);
                let crossing = now.1.is_finite()
                    && prev.1.is_finite()
                    && (now.1 == T::zero() || (now.1 > T::zero()) != (prev.1 > T::zero()));
                let dip = m > 1 && k >= 2 && prev.2 < now.2 && prev.2 < prev2.2;
                if (crossing || dip) && found < MAX_STARTS {
                    starts[found] = start_between(prev, now, crossing, k == 1);
                    found += 1;
                }
                before[side] = prev;
                last[side] = now;
            }
            if found == MAX_STARTS {
                break;
            }
        }
        (starts, found)
    }
}

/// The start `(|t|, t)` for a sign change (`crossing`) or a dip between the samples
/// `prev` and `now` (`(t, scalar, size)`); `first`: `now` is the first step's.
fn start_between<T: Real>(prev: (T, T, T), now: (T, T, T), crossing: bool, first: bool) -> (T, T) {
    let t = if crossing && first {
        // beside the origin (an equilibrium itself, maybe): from the far sample, so
        // that Newton does not fall back to the origin
        now.0
    } else if crossing {
        // secant between the two samples
        let w = prev.1 / (prev.1 - now.1);
        prev.0 + (now.0 - prev.0) * w
    } else {
        prev.0
    };
    (t.abs(), t)
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

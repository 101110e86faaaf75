//! The softest mode's gradient over the joints, from its singular vectors and two
//! sensitivity passes (no solves).
//!
//! # Method
//!
//! At a converged torsion solution the shooting unknowns `x(q)` solve `R(x, q) = 0`, and
//! the softest mode is the smallest singular value `sigma` of `J = R_x` (signed with
//! `det J`; [`super::Solution::softest_mode`]). With `u`, `v` its unit left and right
//! singular vectors (`J v = |sigma| u`), a change `dJ` changes `|sigma|` by `u^T dJ v`.
//! Along a joint `q_p` the solution moves too, `dx/dq_p = -J^{-1} R_p`, so along the
//! direction `d_p = (dx/dq_p, e_p)` of the unknowns and joints together
//!
//! ```text
//! d|sigma| / d q_p = u^T (d/dd_p R_x) v = d/dt [ u^T R_z(x + t v, q) d_p ] at t = 0
//! ```
//!
//! (the mixed second derivative of `u . R` along `v` and `d_p`, in either order), and
//! `u^T R_z d_p` is zero at `x` itself (`R_x dx/dq_p + R_p = 0`). Hence two passes with
//! sensitivities ([`crate::integrate::sensitivities`]): one at `x` along the unknowns,
//! the feeds and the rotations (but the last, whose derivative is minus the sum of the
//! others': the model is invariant under a common rotation), which gives `J`, its
//! singular vectors and `R_q`; and one at `x + h v` ([`SOFTEST_STEP_RAD_PER_MM`]) along
//! the `2 N - 1` directions `d_p`, whose `u^T R_z d_p` over `h` is the gradient (less
//! the first pass's, zero up to rounding). The first pass's `J` is the one Newton's
//! passes integrate, so `value` is the solver's softest mode at `x`; the derivatives
//! are those of the twist equations along the solver's RK4 steps, which differ from
//! differences of solves by the discretisation error (within 2.2e-4 of the gradient on
//! the shared robots and near a snap, `tests/softest.rs`), and the difference along `v`
//! adds about 1e-7.
//!
//! Within one configuration of the sections (the same cuts in the same order, each
//! section integrated in the same number of steps) the solver's discrete map is smooth
//! in the joints; where a feed moves a cut past another, or a section's step count
//! changes, it has a kink or a small step. [`SoftestModeGradient::smooth_within_mm`]
//! says how far the feeds may move before that happens ([`Solver::same_steps`] compares
//! two joint vectors), so that a caller can tell whether a finite difference of the
//! softest mode is this gradient's.

use super::request::{Request, SolveError, Unsupported};
use super::{Model, Solution, Solver};
use crate::integrate::pass::{Mechanics, Setup};
use crate::integrate::sensitivities::{residual_sensitivities, Seeds};
use crate::integrate::steps;
use crate::math::linalg::{smallest_singular_value, softest_direction, solve_linear};
use crate::model::joints::Joints;
use crate::model::robot::Robot;
use crate::model::sections::{Section, Sections};
use crate::real::{c, Real};
use crate::MAX_TUBES;

/// Step of the difference along the softest direction of the unknowns, rad/mm (the base
/// twist rates; at most about 0.05 rad/mm on the shared robots).
pub const SOFTEST_STEP_RAD_PER_MM: f64 = 1e-8;

/// The softest mode of a solution and its gradient over the joints ([`Solver::softest_mode_gradient`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftestModeGradient<T, const N: usize> {
    /// The softest mode at the solution's unknowns (dimensionless; as
    /// [`Solution::softest_mode`], from the shooting Jacobian at the unknowns given).
    pub value: T,
    /// `d sigma / d s_i`, per mm.
    pub feed: [T; N],
    /// `d sigma / d theta_i`, per rad.
    pub rotation: [T; N],
    /// How far any one feed may move (mm, either way) with the backbone cut into the
    /// same sections, integrated in the same numbers of steps ([`Solver::same_steps`]):
    /// within it the softest mode the solver reports is a smooth function of the joints,
    /// whose differences this gradient predicts (module doc). Infinite for rigid tubes
    /// and a single tube.
    pub smooth_within_mm: T,
}

impl<T: Real, const N: usize> SoftestModeGradient<T, N> {
    fn constant(value: T) -> Self {
        SoftestModeGradient {
            value,
            feed: [T::zero(); N],
            rotation: [T::zero(); N],
            smooth_within_mm: T::max_value().unwrap_or(T::one()),
        }
    }
}

impl<T: Real, const N: usize> Solver<T, N> {
    /// The gradient of the softest mode over the (commanded) joints of `request` at
    /// `solution`, a converged solve of it (module doc): two sensitivity passes, no
    /// solve, the warm-start memory untouched. Rigid tubes and a single tube have a
    /// constant softest mode of 1. NaN where the shooting Jacobian is singular (a
    /// fold). Computed for the unloaded model without boundary friction moments; the
    /// others are [`SolveError::Unsupported`].
    ///
    /// ```
    /// use ctr_core::{Joints, Model, Request, Robot, Solver, TubeParams};
    /// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
    /// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
    /// let robot = Robot::new([outer, inner]).unwrap();
    /// let q = |deg: f64| Joints::from_mm_deg([40.0, 90.0], [0.0, deg]);
    /// // solved twice, so that the softest mode is that of the solution's own Jacobian
    /// let settled = |deg: f64| {
    ///     let mut solver = Solver::default();
    ///     solver.solve(&robot, Request::new(q(deg), Model::Torsion)).unwrap();
    ///     let sol = solver.solve(&robot, Request::new(q(deg), Model::Torsion)).unwrap();
    ///     (solver, sol)
    /// };
    /// let (solver, sol) = settled(120.0);
    /// let g = solver.softest_mode_gradient(&robot, Request::new(q(120.0), Model::Torsion), &sol).unwrap();
    /// assert!((g.value - sol.softest_mode).abs() < 1e-12);
    /// // against a central difference of solves in the inner tube's rotation
    /// let h = 1e-3_f64;
    /// let d = (settled(120.0 + h).1.softest_mode - settled(120.0 - h).1.softest_mode)
    ///     / (2.0 * h.to_radians());
    /// assert!((g.rotation[1] - d).abs() < 1e-4 * d.abs(), "{} {d}", g.rotation[1]);
    /// // only relative angles count
    /// assert!((g.rotation[0] + g.rotation[1]).abs() < 1e-12);
    /// ```
    pub fn softest_mode_gradient(
        &self,
        robot: &Robot<T, N>,
        request: Request<'_, T, N>,
        solution: &Solution<T, N>,
    ) -> Result<SoftestModeGradient<T, N>, SolveError> {
        if let Some(u) = request.unsupported() {
            return Err(SolveError::Unsupported(u));
        }
        if request.loaded() || request.friction.is_some() {
            return Err(SolveError::Unsupported(Unsupported::SoftestModeGradient));
        }
        let q = match request.effects {
            Some(e) => e.actual(&request.joints),
            None => request.joints,
        };
        q.validate(robot)?;
        if request.model == Model::Rigid || N < 2 {
            return Ok(SoftestModeGradient::constant(T::one()));
        }
        let sections = self.sections(robot, &q);
        let setup = Setup {
            robot,
            q: &q,
            sections: &sections,
            mechanics: Mechanics::Torsion { coarse: false },
            clearance: None,
            friction: None,
        };
        let x = &solution.base_twist_per_mm;
        // columns: N - 1 unknowns, N feeds, N - 1 rotations; then the 2 N - 1 joints
        macro_rules! dispatch {
            ($($k1:literal, $k2:literal);*) => {
                $(if 3 * N - 2 == $k1 {
                    let mut g = gradient::<T, N, $k1, $k2>(&setup, x);
                    g.smooth_within_mm = smooth_within(robot, &q, &sections);
                    return Ok(g);
                })*
            };
        }
        dispatch!(4, 3; 7, 5; 10, 7);
        Ok(SoftestModeGradient::constant(c(f64::NAN)))
    }

    /// True when joints `a` and `b` (actual joints, as the solve integrates them) cut
    /// the backbone into the same sections, from the same cuts in the same order, each
    /// integrated in the same number of RK4 steps: the solver's discrete map is then
    /// smooth on the segment between them (module doc; the cuts move linearly with the
    /// joints, so two that keep their order at both ends keep it between, and so do the
    /// step counts).
    ///
    /// ```
    /// use ctr_core::{Joints, Robot, Solver, TubeParams};
    /// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
    /// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
    /// let robot = Robot::new([outer, inner]).unwrap();
    /// let solver = Solver::<f64, 2>::default();
    /// let q = |s2: f64| Joints::from_mm_deg([40.0, s2], [0.0, 30.0]);
    /// assert!(solver.same_steps(&robot, &q(100.0), &q(100.001)));
    /// // the inner tube's curve start (s2 - 90) passes the outer tube's tip at s2 = 130
    /// assert!(!solver.same_steps(&robot, &q(129.999), &q(130.001)));
    /// ```
    pub fn same_steps(&self, robot: &Robot<T, N>, a: &Joints<T, N>, b: &Joints<T, N>) -> bool {
        let (sa, sb) = (self.sections(robot, a), self.sections(robot, b));
        sa.len == sb.len
            && sa
                .list
                .iter()
                .zip(sb.list.iter())
                .take(sa.len)
                .all(|(x, y)| alike(robot, a, x, b, y))
    }
}

/// The softest mode and its gradient at the unknowns `x` ([`Solver::softest_mode_gradient`]):
/// `K1 = 3 N - 2` columns (unknowns, feeds, rotations but the last) at `x`, then
/// `K2 = 2 N - 1` (each joint with the unknowns' response to it) at `x + h v`.
fn gradient<T: Real, const N: usize, const K1: usize, const K2: usize>(
    setup: &Setup<'_, T, N>,
    x: &[T; N],
) -> SoftestModeGradient<T, N> {
    let m = N - 1;
    let nan = SoftestModeGradient::constant(c(f64::NAN));
    let mut seeds = Seeds::<T, N, K1>::zero();
    for j in 0..m {
        seeds.x[j][j] = T::one();
    }
    for i in 0..N {
        seeds.s[i][m + i] = T::one();
    }
    for i in 0..N - 1 {
        seeds.theta[i][m + N + i] = T::one();
    }
    let (_, dr) = residual_sensitivities(setup, x, &seeds);
    let mut jac = [[T::zero(); N]; N];
    for i in 0..m {
        for k in 0..m {
            jac[i][k] = dr[i][k];
        }
    }
    let value = smallest_singular_value(&jac, m);
    // the singular vectors: v the softest direction, u = J v / |J v|
    let v = softest_direction(&jac, m);
    let mut u = [T::zero(); N];
    for i in 0..m {
        for k in 0..m {
            u[i] += jac[i][k] * v[k];
        }
    }
    let size = u.iter().take(m).fold(T::zero(), |a, b| a + *b * *b).sqrt();
    if !size.is_finite() || size <= T::zero() || !value.is_finite() {
        return nan;
    }
    u.iter_mut().for_each(|w| *w /= size);
    // each joint p with the unknowns' response dx/dq_p = -J^{-1} R_p: along it u . R
    // stays zero to first order at x, and its change from x to x + h v is h times the
    // softest mode's derivative (module doc)
    let mut response = Seeds::<T, N, K2>::zero();
    let mut at_x = [T::zero(); K2];
    for p in 0..K2 {
        let rp: [T; N] = core::array::from_fn(|i| if i < m { dr[i][m + p] } else { T::zero() });
        let Some(dx) = solve_linear::<T, N>(jac, rp, m) else {
            return nan;
        };
        for j in 0..m {
            response.x[j][p] = -dx[j];
        }
        if p < N {
            response.s[p][p] = T::one();
        } else {
            response.theta[p - N][p] = T::one();
        }
        for i in 0..m {
            let mut along = rp[i];
            for j in 0..m {
                along -= jac[i][j] * dx[j];
            }
            at_x[p] += u[i] * along;
        }
    }
    let h = c::<T>(SOFTEST_STEP_RAD_PER_MM);
    let moved: [T; N] = core::array::from_fn(|i| x[i] + v[i] * h);
    let (_, dr2) = residual_sensitivities(setup, &moved, &response);
    // the sign of the softest mode is that of det J (linalg::smallest_singular_value)
    let sign = if value < T::zero() {
        -T::one()
    } else {
        T::one()
    };
    let mut joint = [T::zero(); K2];
    for (p, d) in joint.iter_mut().enumerate() {
        let mut after = T::zero();
        for i in 0..m {
            after += u[i] * dr2[i][p];
        }
        *d = sign * (after - at_x[p]) / h;
    }
    let mut out = SoftestModeGradient::constant(value);
    out.feed[..N].copy_from_slice(&joint[..N]);
    let mut last = T::zero();
    for i in 0..N - 1 {
        out.rotation[i] = joint[N + i];
        last -= out.rotation[i];
    }
    out.rotation[N - 1] = last;
    out
}

/// How far any one feed may move from `q` (mm, either way) with `sections` (those of
/// `q`) unchanged in their cuts, order and step counts: the least distance between two
/// cuts of different tubes (or a cut and the guide exit: a feed moves only its own
/// tube's two cuts, together) but two behind the guide exit, and of each RK4 section's
/// length to the next change of its step count (`ceil(len / h)`). Conservative: cuts
/// beyond the tip count too.
fn smooth_within<T: Real, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
) -> T {
    let mut least = T::max_value().unwrap_or(T::one());
    // (where, whose): the guide exit belongs to no tube
    let mut cuts = [(T::zero(), N); 2 * MAX_TUBES + 1];
    for i in 0..N {
        let s = q.s_mm[i];
        cuts[1 + 2 * i] = (s, i);
        cuts[2 + 2 * i] = (s - robot.tubes()[i].params().curved_length_mm, i);
    }
    let used = 2 * N + 1;
    for a in 0..used {
        for b in a + 1..used {
            let ((va, ta), (vb, tb)) = (cuts[a], cuts[b]);
            // two cuts behind the guide exit cut nothing, in either order (they are
            // measured against the exit itself, whose owner is none)
            let behind = va <= T::zero() && vb <= T::zero() && ta < N && tb < N;
            if ta != tb && !behind {
                least = least.min((va - vb).abs());
            }
        }
    }
    for sec in sections.list.iter().take(sections.len) {
        if sec.curved > 1 {
            let len = sec.end - sec.start;
            let n = c::<T>(steps(len, sec.h) as f64);
            least = least.min(len - (n - T::one()) * sec.h).min(n * sec.h - len);
        }
    }
    least
}

/// Where a cut at `v` of joints `q` comes from: 0 the guide exit, `1 + i` tube i's tip,
/// `1 + N + i` the start of its curve (as [`crate::integrate::twist`] tells them
/// apart); `usize::MAX` none of them.
fn source<T: Real, const N: usize>(robot: &Robot<T, N>, q: &Joints<T, N>, v: T) -> usize {
    if v == T::zero() {
        return 0;
    }
    if let Some(i) = q.s_mm.iter().position(|&s| s == v) {
        return 1 + i;
    }
    (0..N)
        .find(|&i| q.s_mm[i] - robot.tubes()[i].params().curved_length_mm == v)
        .map_or(usize::MAX, |i| 1 + N + i)
}

/// True when two sections are integrated alike (see [`Solver::same_steps`]).
fn alike<T: Real, const N: usize>(
    robot: &Robot<T, N>,
    qa: &Joints<T, N>,
    a: &Section<T, N>,
    qb: &Joints<T, N>,
    b: &Section<T, N>,
) -> bool {
    // full steps: the steps of a warm solve, as every converged one ends on
    let count = |s: &Section<T, N>| {
        if s.curved <= 1 {
            1
        } else {
            steps(s.end - s.start, s.h)
        }
    };
    source(robot, qa, a.start) == source(robot, qb, b.start)
        && source(robot, qa, a.end) == source(robot, qb, b.end)
        && a.present == b.present
        && a.curved_a == b.curved_a
        && a.curved_g == b.curved_g
        && count(a) == count(b)
}

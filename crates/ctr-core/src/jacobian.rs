//! Jacobians of the tip pose: with respect to the joints, to model parameters, and to tip
//! loads (the compliance matrix), from integrated sensitivities (no finite differences).
//!
//! # Method
//!
//! A converged solve leaves the shooting unknowns `x` (the base twist rates `u_j(0)`,
//! `j < n`) where the free-tip residuals vanish, `R(x, p) = 0` with `R_j = u_j(s_j)`
//! ([`crate::twist`]), and gives the tip pose `P(x, p)`, where `p` are the joints (or
//! the model parameters). One more integration runs in forward-mode dual numbers
//! ([`crate::dual`]) with `x` and `p` as derivative directions: the integrator is the
//! solver's own discrete map (same sections, RK4 steps, closed-form single-curve
//! sections, Magnus pose steps, SE(3) exponentials), so its derivatives are exact
//! derivatives of what [`Solver::solve`] computes. The twist state is carried as dual
//! numbers; the frame is carried plain, with one spatial twist per direction updated by
//! the exponential's left Jacobian at each step (`src/tangent.rs` derives it): the same
//! derivative as differentiating the 3 x 3 products entry by entry, at a fraction of the
//! cost. By the implicit function theorem
//!
//! ```text
//! dx/dp = -R_x^{-1} R_p,        dP/dp = P_p + P_x dx/dp
//! ```
//!
//! How the joints enter: `theta_i` through the base angles
//! `psi_i(0) = theta_i + (length_i - s_i) u_i(0)`; `s_i` through the transmission
//! length `length_i - s_i` and through the section boundaries `s_i` and
//! `s_i - curved_length_i`. Each section is integrated in a fixed number of equal steps
//! of length `(end - start) / n`, so a moving end point makes the step length a dual
//! number: the derivative of the discrete map includes the integrand at the moving end
//! times the end point's derivative, as the Leibniz rule does for the exact solution.
//!
//! The model is exactly invariant under a common rotation of all tubes (the robot turns
//! about W's z axis), so the rotation columns sum to `(e_z x p, e_z)`: the last one is
//! that minus the others, which saves one derivative direction. In the joint pass the
//! stiffnesses stay plain numbers (only the parameter pass differentiates them).
//!
//! Orientation columns are the tip frame's angular velocity in the world frame W per
//! unit joint rate (the spatial, or geometric, Jacobian): `[omega]x = (dR/dp) R^T`.
//! Position columns are `dp_tip/dp` in W. Rows: `(dx, dy, dz, omega_x, omega_y,
//! omega_z)`.
//!
//! Where the shooting Jacobian `R_x` is singular (a snap: the stability margin is 0)
//! the pose has no derivative and the entries are NaN. A configuration where two cuts
//! coincide (e.g. `s_i = s_j - curved_length_j`) is a kink of the forward kinematics;
//! there the one-sided derivative of one side is returned.

use crate::dual::{Dual, Num};
use crate::joints::{JointError, Joints};
use crate::real::{c, Real};
use crate::robot::Robot;
use crate::se3::SERIES_LIMIT_SQ;
use crate::sections::{Section, Sections};
use crate::solver::{solve_linear, Model, Solution, Solver};
use crate::tangent::{Pose, Tangents};
use core::ops::{Add, Mul, Neg, Sub};
use nalgebra::Vector6;

/// Not a number, in `T`: marks entries that have no value.
fn nan<T: Real>() -> T {
    c(f64::NAN)
}

/// Most columns of a Jacobian: three parameters per tube (see [`ParameterJacobian`]).
const MAX_COLUMNS: usize = 3 * crate::MAX_TUBES;

/// d(tip pose)/d(joints) at a solution: one 6-vector column per joint.
///
/// Each column is `(dp_x, dp_y, dp_z, omega_x, omega_y, omega_z)` in W: the tip
/// position's derivative (mm per mm of feed, mm per rad of rotation) and the tip frame's
/// spatial angular velocity per unit joint rate (rad per mm, rad per rad). As a 6 x 2N
/// matrix the feeds come first: column `i` is `s_i`, column `N + i` is `theta_i`.
///
/// ```
/// use ctr_core::{Joints, Model, Robot, Solver, TubeParams};
/// // one straight tube: feeding moves the tip along z, turning it spins the tip about z
/// let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
/// let (_, jac) = Solver::default().solve_jacobian(&robot, &Joints::new([50.0], [0.3]), Model::Torsion).unwrap();
/// assert!((jac.entry(2, 0) - 1.0).abs() < 1e-12); // dz/ds
/// assert!((jac.entry(5, 1) - 1.0).abs() < 1e-12); // omega_z / dtheta
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointJacobian<T: Real, const N: usize> {
    /// Column of each feed `s_i`.
    pub feed: [Vector6<T>; N],
    /// Column of each rotation `theta_i`.
    pub rotation: [Vector6<T>; N],
}

impl<T: Real, const N: usize> JointJacobian<T, N> {
    /// Column `j` of the 6 x 2N matrix (`s_j` for `j < N`, else `theta_{j-N}`);
    /// `None` past the last column.
    ///
    /// ```
    /// # use ctr_core::{Joints, Model, Robot, Solver, TubeParams};
    /// # let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// let (_, jac) = Solver::default().solve_jacobian(&robot, &Joints::new([50.0], [0.0]), Model::Rigid).unwrap();
    /// assert_eq!(jac.column(1), Some(jac.rotation[0]));
    /// assert_eq!(jac.column(2), None);
    /// ```
    pub fn column(&self, j: usize) -> Option<Vector6<T>> {
        if j < N {
            Some(self.feed[j])
        } else {
            self.rotation.get(j - N).copied()
        }
    }

    /// Entry `(row, col)` of the 6 x 2N matrix; NaN outside it.
    ///
    /// ```
    /// # use ctr_core::{Joints, Model, Robot, Solver, TubeParams};
    /// # let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// let (_, jac) = Solver::default().solve_jacobian(&robot, &Joints::new([50.0], [0.0]), Model::Rigid).unwrap();
    /// assert!(jac.entry(6, 0).is_nan());
    /// ```
    pub fn entry(&self, row: usize, col: usize) -> T {
        match self.column(col) {
            Some(v) if row < 6 => v[row],
            _ => nan::<T>(),
        }
    }
}

/// d(tip pose)/d(model parameters) at a solution, each parameter a scale factor at 1.
///
/// Columns as in [`JointJacobian`] (position mm, spatial angular velocity rad, per unit
/// of the factor). Per tube i: `bending_stiffness[i]` scales `E I_i` alone,
/// `torsional_stiffness[i]` scales `G J_i` alone, `curvature[i]` scales the
/// precurvature `k_i`. The `stiffness` effect of [`Robot::scaled`] (both stiffnesses) is
/// the sum of the first two columns; its radius factor is minus the curvature column.
///
/// ```
/// use ctr_core::{Joints, Model, Robot, Solver, TubeParams};
/// let robot = Robot::new([TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) }]).unwrap();
/// let (_, jac) = Solver::default().solve_parameter_jacobian(&robot, &Joints::new([50.0], [0.0]), Model::Torsion).unwrap();
/// // one tube: the shape does not depend on its stiffness
/// assert!(jac.bending_stiffness[0].norm() < 1e-12);
/// // an arc of curvature k over L: dx/dk = L sin(kL)/k - (1 - cos kL)/k^2, times k
/// let (k, l) = (0.01_f64, 50.0_f64);
/// let dx = l * (k * l).sin() - (1.0 - (k * l).cos()) / k;
/// assert!((jac.curvature[0][0] - dx).abs() < 1e-9);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParameterJacobian<T: Real, const N: usize> {
    /// Columns for the bending stiffness scale of each tube.
    pub bending_stiffness: [Vector6<T>; N],
    /// Columns for the torsional stiffness scale of each tube.
    pub torsional_stiffness: [Vector6<T>; N],
    /// Columns for the precurvature scale of each tube.
    pub curvature: [Vector6<T>; N],
}

// ---------------------------------------------------------------------------------------
// The solver's unloaded integrator, generic over plain and dual numbers.

/// Arithmetic shared by plain and dual numbers, without the scalar type.
pub(crate) trait Ring:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self>
{
}
impl<S: Copy + Add<Output = S> + Sub<Output = S> + Mul<Output = S> + Neg<Output = S>> Ring for S {}

pub(crate) type V3<S> = [S; 3];
pub(crate) type M3<S> = [[S; 3]; 3];

/// `a x b`.
#[inline(always)]
pub(crate) fn cross<S: Ring>(a: &V3<S>, b: &V3<S>) -> V3<S> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The 3 x 3 product `a b`.
#[inline(always)]
pub(crate) fn mat_mul<S: Ring>(a: &M3<S>, b: &M3<S>) -> M3<S> {
    core::array::from_fn(|i| {
        core::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j])
    })
}

/// A frame: rotation (row-major, columns the frame's axes in W) and origin.
#[derive(Clone, Copy)]
pub(crate) struct GFrame<S> {
    pub r: M3<S>,
    pub p: V3<S>,
}

impl<T: Real, S: Num<T>> Pose<T, S> for GFrame<S> {
    #[inline(always)]
    fn step(&mut self, w: V3<S>, v: V3<S>) {
        let (r, p) = exp_g(w, v);
        self.compose(&r, &p);
    }
    #[inline(always)]
    fn rotate_z(&mut self, co: S, si: S) {
        GFrame::rotate_z(self, co, si);
    }
    #[inline(always)]
    fn advance(&mut self, h: S) {
        for i in 0..3 {
            self.p[i] += self.r[i][2] * h;
        }
    }
}

impl<S: Ring> GFrame<S> {
    pub fn identity(zero: S, one: S) -> Self {
        GFrame {
            r: [[one, zero, zero], [zero, one, zero], [zero, zero, one]],
            p: [zero; 3],
        }
    }
    /// Moves the frame by `(r, p)` given in its own body coordinates.
    #[inline(always)]
    fn compose(&mut self, r: &M3<S>, p: &V3<S>) {
        let m = self.r;
        for i in 0..3 {
            self.p[i] = self.p[i] + m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2];
        }
        self.r = mat_mul(&m, r);
    }
    /// Rotates the frame about its own z axis by the angle whose (cos, sin) is given.
    #[inline(always)]
    fn rotate_z(&mut self, co: S, si: S) {
        for row in self.r.iter_mut() {
            let (x, y) = (row[0], row[1]);
            row[0] = x * co + y * si;
            row[1] = y * co - x * si;
        }
    }
}

/// `lead (1 - t2/d0 (1 - t2/d1 (...)))`: the Taylor series of [`crate::se3`], with its
/// derivative with respect to `t2` (evaluated once on plain numbers, then chained).
#[inline(always)]
pub(crate) fn series<T: Real, S: Num<T>>(t2: S, lead: f64, divisors: &[f64; 5]) -> S {
    let x = Dual::<T, 1>::var(t2.re(), 0);
    let one = Dual::<T, 1>::cst(T::one());
    let mut acc = one;
    for d in divisors.iter().rev() {
        acc = one - x * acc * c::<T>(1.0 / d);
    }
    let f = acc * c::<T>(lead);
    t2.chain(f.re, f.eps[0])
}

/// [`crate::se3::exp`] on generic numbers.
#[inline(always)]
fn exp_g<T: Real, S: Num<T>>(w: V3<S>, v: V3<S>) -> (M3<S>, V3<S>) {
    let one = S::cst(T::one());
    let t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    let (a, b, d) = if t2.re() < c(SERIES_LIMIT_SQ) {
        (
            series(t2, 1.0, &[6.0, 20.0, 42.0, 72.0, 110.0]),
            series(t2, 0.5, &[12.0, 30.0, 56.0, 90.0, 132.0]),
            series(t2, 1.0 / 6.0, &[20.0, 42.0, 72.0, 110.0, 156.0]),
        )
    } else {
        let t = t2.sqrt();
        let (s, co) = t.sin_cos();
        (s / t, (one - co) / t2, (t - s) / (t2 * t))
    };
    let (x, y, z) = (w[0], w[1], w[2]);
    let (ax, ay, az) = (a * x, a * y, a * z);
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (bx, by) = (b * x, b * y);
    let (bxy, bxz, byz) = (bx * y, bx * z, by * z);
    let r = [
        [one - b * (yy + zz), bxy - az, bxz + ay],
        [bxy + az, one - b * (xx + zz), byz - ax],
        [bxz - ay, byz + ax, one - b * (xx + yy)],
    ];
    let wv = cross(&w, &v);
    let wwv = cross(&w, &wv);
    let p = [
        v[0] + wv[0] * b + wwv[0] * d,
        v[1] + wv[1] * b + wwv[1] * d,
        v[2] + wv[2] * b + wwv[2] * d,
    ];
    (r, p)
}

/// Everything a solve depends on: joints and unknowns as `S`, the tubes' stiffnesses and
/// precurvatures as `C` (plain numbers unless they are differentiated too).
#[derive(Clone, Copy)]
pub(crate) struct Inputs<S, C, const N: usize> {
    /// feeds, mm
    pub s: [S; N],
    /// actuator angles, rad
    pub theta: [S; N],
    /// base twist rates `u_j(0)`, `j < N-1`, rad/mm
    pub x: [S; N],
    /// bending stiffness, N mm^2
    pub ei: [C; N],
    /// torsional stiffness, N mm^2
    pub gj: [C; N],
    /// precurvature, 1/mm
    pub k: [C; N],
}

impl<T: Real, const N: usize> Inputs<T, T, N> {
    /// The plain inputs of a robot at joints `q` and unknowns `x`.
    pub fn plain(robot: &Robot<T, N>, q: &Joints<T, N>, x: &[T; N]) -> Self {
        Inputs {
            s: q.s_mm,
            theta: q.theta_rad,
            x: *x,
            ei: robot.tubes().map(|t| t.bending_stiffness_nmm2()),
            gj: robot.tubes().map(|t| t.torsional_stiffness_nmm2()),
            k: robot.tubes().map(|t| t.curvature_per_mm()),
        }
    }
}

/// Twist state: `(cos b_j, sin b_j)` and `u_j` for `j < N-1` (entry N-1 of z is (1, 0)).
#[derive(Clone, Copy)]
pub(crate) struct GState<S, const N: usize> {
    pub z: [[S; 2]; N],
    pub w: [S; N],
}

impl<S: Ring, const N: usize> GState<S, N> {
    #[inline(always)]
    fn axpy(&self, d: &Self, h: S) -> Self {
        let mut o = *self;
        for j in 0..N - 1 {
            o.z[j][0] = o.z[j][0] + d.z[j][0] * h;
            o.z[j][1] = o.z[j][1] + d.z[j][1] * h;
            o.w[j] = o.w[j] + d.w[j] * h;
        }
        o
    }
}

/// One section's coefficients: its length as `S`, the stiffness terms as `C`.
pub(crate) struct GSection<S, C, const N: usize> {
    pub len: S,
    pub present: [bool; N],
    pub a: [C; N],
    pub curved_a: [bool; N],
    pub g: [C; N],
    pub curved_g: [bool; N],
    pub gj: [C; N],
    pub curved: usize,
    pub single: usize,
    pub steps: usize,
    pub inv_gj_n: C,
}

/// A cut of the backbone as a generic number: 0, a tip `s_i` or a curve start
/// `s_i - curved_length_i`, found by the value the plain cut has.
fn cut<T: Real, S: Num<T>, C, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    inp: &Inputs<S, C, N>,
    v: T,
) -> S {
    if v == T::zero() {
        return S::cst(v);
    }
    for i in 0..N {
        if v == q.s_mm[i] {
            return inp.s[i];
        }
    }
    for i in 0..N {
        let cl = robot.tubes()[i].params().curved_length_mm;
        if v == q.s_mm[i] - cl {
            return inp.s[i] - S::cst(cl);
        }
    }
    S::cst(v)
}

impl<S: Copy, C: Copy, const N: usize> GSection<S, C, N> {
    pub fn new<T: Real>(
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        inp: &Inputs<S, C, N>,
        sec: &Section<T, N>,
    ) -> Self
    where
        S: Num<T> + Mul<C, Output = S>,
        C: Num<T>,
    {
        let zero = C::cst(T::zero());
        let len = cut(robot, q, inp, sec.end) - cut(robot, q, inp, sec.start);
        let mut stiff = zero;
        for i in 0..N {
            if sec.present[i] {
                stiff += inp.ei[i];
            }
        }
        let mut a = [zero; N];
        let mut g = [zero; N];
        let mut curved_a = [false; N];
        let mut curved_g = [false; N];
        for i in 0..N {
            if sec.a[i] != T::zero() {
                let ek = inp.ei[i] * inp.k[i];
                a[i] = ek / stiff;
                g[i] = ek / inp.gj[i];
                curved_a[i] = true;
                curved_g[i] = sec.g[i] != T::zero();
            }
        }
        let steps = if sec.curved <= 1 {
            1
        } else {
            crate::twist::steps(sec.end - sec.start, sec.h)
        };
        GSection {
            len,
            present: sec.present,
            a,
            curved_a,
            g,
            curved_g,
            gj: inp.gj,
            curved: sec.curved,
            single: sec.single,
            steps,
            inv_gj_n: C::cst(T::one()) / inp.gj[N - 1],
        }
    }

    /// Tube n's twist rate from the conservation of torque.
    #[inline(always)]
    fn inner_twist<T: Real>(&self, w: &[S; N]) -> S
    where
        S: Num<T> + Mul<C, Output = S>,
    {
        let mut un = S::cst(T::zero());
        for j in 0..N - 1 {
            if self.present[j] {
                un -= w[j] * self.gj[j];
            }
        }
        un * self.inv_gj_n
    }

    /// The twist equations' right-hand side, kept out of line: the dual arithmetic of
    /// four inlined stages would not fit the instruction cache (measured 4 % faster).
    #[inline(never)]
    fn rhs<T: Real>(&self, st: &GState<S, N>) -> GState<S, N>
    where
        S: Num<T> + Mul<C, Output = S>,
    {
        self.rhs_inline(st)
    }

    #[inline(always)]
    fn rhs_inline<T: Real>(&self, st: &GState<S, N>) -> GState<S, N>
    where
        S: Num<T> + Mul<C, Output = S>,
    {
        let zero = S::cst(T::zero());
        let mut d = GState {
            z: [[zero; 2]; N],
            w: [zero; N],
        };
        let un = self.inner_twist(&st.w);
        let mut acc = [zero; N];
        for j in 0..N - 1 {
            if !self.present[j] {
                continue;
            }
            let om = st.w[j] - un;
            let [cj, sj] = st.z[j];
            d.z[j] = [-(sj * om), cj * om];
            // sin(b_j - b_l) serves the pair both ways: tube j's torque with a_l, tube
            // l's with -a_j
            for l in j + 1..N {
                let pull_j = self.curved_g[j] && self.curved_a[l];
                let pull_l = l < N - 1 && self.curved_g[l] && self.curved_a[j];
                if pull_j || pull_l {
                    // the innermost tube is the reference: z_{N-1} = (1, 0) always
                    let sd = if l == N - 1 {
                        sj
                    } else {
                        let [cl, sl] = st.z[l];
                        sj * cl - cj * sl
                    };
                    if pull_j {
                        acc[j] += sd * self.a[l];
                    }
                    if pull_l {
                        acc[l] -= sd * self.a[j];
                    }
                }
            }
            if self.curved_g[j] {
                d.w[j] = acc[j] * self.g[j];
            }
        }
        d
    }

    /// Tube n's body angular rate from the relative angles `z` and its twist `un`; with
    /// `rate`, `z` and `un` are rates (d/ds) and so is the result.
    #[inline(always)]
    fn body_rate<T: Real>(&self, z: &[[S; 2]; N], un: S, rate: bool) -> V3<S>
    where
        S: Num<T> + Mul<C, Output = S>,
    {
        let mut ux = S::cst(T::zero());
        let mut uy = S::cst(T::zero());
        for l in 0..N - 1 {
            if self.curved_a[l] {
                ux -= z[l][1] * self.a[l];
                uy += z[l][0] * self.a[l];
            }
        }
        // z_{N-1} = (1, 0) (the innermost tube is the reference); its rate is zero
        if self.curved_a[N - 1] && !rate {
            uy += S::cst(T::one()) * self.a[N - 1];
        }
        [ux, uy, un]
    }

    /// Integrates the twist across the section and moves the frame (sink-less
    /// [`crate::twist::section`] with the pose).
    pub fn integrate<T: Real, F: Pose<T, S>>(&self, st: &mut GState<S, N>, frame: &mut F)
    where
        S: Num<T> + Mul<C, Output = S>,
    {
        let zero = S::cst(T::zero());
        let one = S::cst(T::one());
        if self.curved <= 1 {
            let un = self.inner_twist(&st.w);
            let h = self.len;
            self.pose_constant_twist(st, un, h, frame);
            for j in 0..N - 1 {
                if !self.present[j] {
                    continue;
                }
                let (s, co) = ((st.w[j] - un) * h).sin_cos();
                let [cj, sj] = st.z[j];
                st.z[j] = [cj * co - sj * s, sj * co + cj * s];
            }
            return;
        }
        let n = self.steps;
        let h = self.len * (T::one() / nalgebra::convert::<f64, T>(n as f64));
        let half = h * c::<T>(0.5);
        let sixth = h * c::<T>(1.0 / 6.0);
        let h2_12 = h * h * c::<T>(1.0 / 12.0);
        let mut k1 = self.rhs(st);
        // body rate and its derivative at the step's start (the last step's end)
        let mut a0 = self.body_rate(&st.z, self.inner_twist(&st.w), false);
        let mut d0 = self.body_rate(&k1.z, self.inner_twist(&k1.w), true);
        for _ in 0..n {
            let k2 = self.rhs(&st.axpy(&k1, half));
            let k3 = self.rhs(&st.axpy(&k2, half));
            let k4 = self.rhs(&st.axpy(&k3, h));
            let mut next = *st;
            for j in 0..N - 1 {
                for cc in 0..2 {
                    next.z[j][cc] += sixth
                        * (k1.z[j][cc] + (k2.z[j][cc] + k3.z[j][cc]) * c::<T>(2.0) + k4.z[j][cc]);
                }
                next.w[j] += sixth * (k1.w[j] + (k2.w[j] + k3.w[j]) * c::<T>(2.0) + k4.w[j]);
            }
            let k1_next = self.rhs(&next);
            let a1 = self.body_rate(&next.z, self.inner_twist(&next.w), false);
            let d1 = self.body_rate(&k1_next.z, self.inner_twist(&k1_next.w), true);
            let a01 = cross(&a0, &a1);
            let mut omega = [zero; 3];
            for i in 0..3 {
                omega[i] = (a0[i] + a1[i]) * half + (d0[i] - d1[i] + a01[i]) * h2_12;
            }
            // v = e3 h + (a0 - a1) x e3 h^2/12
            let v = [(a0[1] - a1[1]) * h2_12, (a1[0] - a0[0]) * h2_12, h];
            frame.step(omega, v);
            *st = next;
            k1 = k1_next;
            a0 = a1;
            d0 = d1;
        }
        for j in 0..N - 1 {
            let [cj, sj] = st.z[j];
            let inv = one / (cj * cj + sj * sj).sqrt();
            st.z[j] = [cj * inv, sj * inv];
        }
    }

    #[inline(always)]
    fn pose_constant_twist<T: Real, F: Pose<T, S>>(
        &self,
        st: &GState<S, N>,
        un: S,
        h: S,
        frame: &mut F,
    ) where
        S: Num<T> + Mul<C, Output = S>,
    {
        let zero = S::cst(T::zero());
        let one = S::cst(T::one());
        if self.curved == 0 {
            frame.advance(h);
            let (s, co) = (un * h).sin_cos();
            frame.rotate_z(co, s);
            return;
        }
        let l = self.single;
        let ul = if l == N - 1 { un } else { st.w[l] };
        let [cl, sl] = st.z[l];
        let inv = one / (cl * cl + sl * sl).sqrt();
        let (cl, sl) = (cl * inv, sl * inv);
        frame.rotate_z(cl, sl);
        frame.step([zero, h * self.a[l], ul * h], [zero, zero, h]);
        let (s, co) = ((ul - un) * h).sin_cos();
        let (c2, s2) = (cl * co - sl * s, sl * co + cl * s);
        frame.rotate_z(c2, -s2);
    }
}

/// The result of one generic integration: free-tip twists and the tip frame.
pub(crate) struct Pass<S, F, const N: usize> {
    /// `u_j(s_j)`, `j < N-1` (zero for `rigid`)
    pub r: [S; N],
    /// the tip frame, moved from `frame` (the world frame) by [`integrate`]
    pub frame: F,
}

/// The solver's unloaded integration (torsion: the pose pass at unknowns `inp.x`;
/// rigid: constant curvature per section) on generic numbers, moving `frame` (the
/// world frame on entry) along: a plain [`GFrame`], one with derivatives
/// ([`Tangents`]), or none ([`NoPose`](crate::tangent::NoPose)).
pub(crate) fn integrate<T: Real, S, C, F, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    inp: &Inputs<S, C, N>,
    model: Model,
    friction: Option<&[T; N]>,
    mut frame: F,
) -> Pass<S, F, N>
where
    S: Num<T> + Mul<C, Output = S>,
    C: Num<T>,
    F: Pose<T, S>,
{
    let zero = S::cst(T::zero());
    let one = S::cst(T::one());
    let mut st = GState {
        z: [[zero; 2]; N],
        w: [zero; N],
    };
    st.z[N - 1] = [one, zero];
    let mut r = [zero; N];
    if model == Model::Rigid {
        let tn = inp.theta[N - 1];
        for j in 0..N - 1 {
            let (s, co) = (inp.theta[j] - tn).sin_cos();
            st.z[j] = [co, s];
        }
        let (s, co) = tn.sin_cos();
        frame.rotate_z(co, s);
        for sec in sections.list.iter().take(sections.len) {
            let g = GSection::new(robot, q, inp, sec);
            let mut rate = g.body_rate(&st.z, zero, false);
            for v in rate.iter_mut() {
                *v = *v * g.len;
            }
            frame.step(rate, [zero, zero, g.len]);
        }
        return Pass { r, frame };
    }
    let trans = |i: usize| S::cst(robot.tubes()[i].params().length_mm) - inp.s[i];
    let present = if sections.len > 0 {
        sections.list[0].present
    } else {
        [false; N]
    };
    let mut un = zero;
    for j in 0..N - 1 {
        st.w[j] = inp.x[j];
        if present[j] {
            un -= inp.x[j] * inp.gj[j];
        }
    }
    un = un * (C::cst(T::one()) / inp.gj[N - 1]);
    let psi_n = inp.theta[N - 1] + trans(N - 1) * un;
    for j in 0..N - 1 {
        let b = inp.theta[j] + trans(j) * inp.x[j] - psi_n;
        let (s, co) = b.sin_cos();
        st.z[j] = [co, s];
    }
    let (s, co) = psi_n.sin_cos();
    frame.rotate_z(co, s);
    let mut done = [false; N];
    let record = |st: &GState<S, N>, at: T, done: &mut [bool; N], r: &mut [S; N]| {
        for j in 0..N - 1 {
            if !done[j] && q.s_mm[j] <= at {
                done[j] = true;
                r[j] = st.w[j];
            }
        }
    };
    record(&st, T::zero(), &mut done, &mut r);
    for sec in sections.list.iter().take(sections.len) {
        let g = GSection::new(robot, q, inp, sec);
        g.integrate(&mut st, &mut frame);
        if let Some(coefficient) = friction {
            boundary_moments(q, inp, &g, sec.end, coefficient, &done, &mut st);
        }
        record(&st, sec.end, &mut done, &mut r);
    }
    record(&st, T::max_value().unwrap_or(T::one()), &mut done, &mut r);
    Pass { r, frame }
}

/// The seed's boundary friction moment (see [`crate::friction`]) at the tips that end
/// the section just integrated: tube j's tip carries `tau_j = coefficient_j |M_j|`
/// (`M_j` the bending moment tube j carries there), so its residual is
/// `u_j(s_j) - tau_j / G J_j`; the neighbour j+1 takes `-tau_j`, which raises its
/// twist rate by `tau_j / G J_{j+1}` (the innermost tube's follows from the torque
/// balance by itself). Tube j's twist past its own tip is never used again, so it
/// takes the residual, which [`integrate`]'s record then keeps.
fn boundary_moments<T: Real, S, C, const N: usize>(
    q: &Joints<T, N>,
    inp: &Inputs<S, C, N>,
    g: &GSection<S, C, N>,
    end: T,
    coefficient: &[T; N],
    done: &[bool; N],
    st: &mut GState<S, N>,
) where
    S: Num<T> + Mul<C, Output = S>,
    C: Num<T>,
{
    for j in 0..N - 1 {
        if done[j] || q.s_mm[j] > end || coefficient[j] == T::zero() {
            continue;
        }
        // tube j's moment E I_j (u - k_j e_j), e_j its precurvature direction
        let [ux, uy, _] = g.body_rate(&st.z, S::cst(T::zero()), false);
        let (mut mx, mut my) = (ux, uy);
        if g.curved_a[j] {
            let [cj, sj] = st.z[j];
            mx += sj * inp.k[j];
            my -= cj * inp.k[j];
        }
        let moment = (mx * mx + my * my).sqrt() * inp.ei[j];
        let tau = moment * coefficient[j];
        // recorded below as u_j(s_j) - tau_j / G J_j
        st.w[j] -= tau * (C::cst(T::one()) / inp.gj[j]);
        if j + 1 < N - 1 {
            st.w[j + 1] += tau * (C::cst(T::one()) / inp.gj[j + 1]);
        }
    }
}

// ---------------------------------------------------------------------------------------
// Jacobians from one dual pass.

/// Which derivative directions a pass seeds after the shooting unknowns.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Wrt {
    /// `s_0..s_{N-1}`, then `theta_0..theta_{N-2}` (the last rotation's column follows
    /// from the others, see [`Solver::solve_jacobian`])
    Joints,
    /// bending stiffness scales, torsional stiffness scales, curvature scales
    Parameters,
}

/// A dual number with derivative `d` in direction `i` (and value `v`).
fn seeded<T: Real, const K: usize>(v: T, i: usize, d: T) -> Dual<T, K> {
    let mut x = Dual::cst(v);
    if let Some(e) = x.eps.get_mut(i) {
        *e = d;
    }
    x
}

/// Total derivatives of a tip pose with respect to `p` (`cols` of them after the `m`
/// unknowns), by the implicit function theorem: `dP/dp = P_p - P_x R_x^{-1} R_p`.
/// `r` are the residuals as duals over `(x, p)`, `tangent[k]` the pose's partial
/// derivative `(dp, omega)` in direction `k`. NaN where `R_x` is singular.
pub(crate) fn implicit_columns<T: Real, const N: usize, const K: usize>(
    r: &[Dual<T, K>; N],
    tangent: &[Vector6<T>; K],
    m: usize,
    cols: usize,
) -> [Vector6<T>; MAX_COLUMNS] {
    let mut out = [Vector6::from_element(nan::<T>()); MAX_COLUMNS];
    // R_x^{-1}, one column per unit vector
    let mut rx = [[T::zero(); N]; N];
    for i in 0..m {
        for k in 0..m {
            rx[i][k] = r[i].eps[k];
        }
    }
    let mut inv = [[T::zero(); N]; N];
    for k in 0..m {
        let mut e = [T::zero(); N];
        e[k] = T::one();
        let Some(col) = solve_linear::<T, N>(rx, e, m) else {
            return out;
        };
        for i in 0..m {
            inv[i][k] = col[i];
        }
    }
    for (p, slot) in out.iter_mut().enumerate().take(cols) {
        let col = m + p;
        if col >= K {
            break;
        }
        // dx/dp = -R_x^{-1} R_p
        let mut v = tangent[col];
        for i in 0..m {
            let mut dx = T::zero();
            for k in 0..m {
                dx -= inv[i][k] * r[k].eps[col];
            }
            v += tangent[i] * dx;
        }
        *slot = v;
    }
    out
}

/// One dual pass with `K` directions (`m` unknowns, then the parameters of `wrt`).
fn pass<T: Real, const N: usize, const K: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    x: &[T; N],
    model: Model,
    wrt: Wrt,
) -> [Vector6<T>; MAX_COLUMNS] {
    let m = if model == Model::Torsion { N - 1 } else { 0 };
    let plain = Inputs::plain(robot, q, x);
    let dual = |a: &[T; N]| a.map(Dual::<T, K>::cst);
    let seed_x = |xs: &mut [Dual<T, K>; N]| {
        for j in 0..m {
            xs[j] = Dual::var(x[j], j);
        }
    };
    let out = match wrt {
        Wrt::Joints => {
            // the stiffnesses stay plain numbers: half the work in every product
            let mut inp = Inputs {
                s: dual(&plain.s),
                theta: dual(&plain.theta),
                x: dual(&plain.x),
                ei: plain.ei,
                gj: plain.gj,
                k: plain.k,
            };
            seed_x(&mut inp.x);
            for i in 0..N {
                inp.s[i] = Dual::var(plain.s[i], m + i);
            }
            for i in 0..N - 1 {
                inp.theta[i] = Dual::var(plain.theta[i], m + N + i);
            }
            let pass = integrate(robot, q, sections, &inp, model, None, Tangents::identity());
            let tangent = pass.frame.columns();
            let mut cols = implicit_columns::<T, N, K>(&pass.r, &tangent, m, 2 * N - 1);
            // Turning every tube by the same angle turns the whole robot about W's z
            // axis (the model is exactly invariant), so the rotation columns sum to
            // (e_z x p, e_z): the last one follows from the others.
            let p = pass.frame.p;
            let mut last = Vector6::new(-p[1], p[0], T::zero(), T::zero(), T::zero(), T::one());
            for i in 0..N - 1 {
                last -= cols[N + i];
            }
            cols[2 * N - 1] = last;
            return cols;
        }
        Wrt::Parameters => {
            // d/d(scale) at scale 1 is the value itself
            let mut inp = Inputs {
                s: dual(&plain.s),
                theta: dual(&plain.theta),
                x: dual(&plain.x),
                ei: dual(&plain.ei),
                gj: dual(&plain.gj),
                k: dual(&plain.k),
            };
            seed_x(&mut inp.x);
            for i in 0..N {
                inp.ei[i] = seeded(plain.ei[i], m + i, plain.ei[i]);
                inp.gj[i] = seeded(plain.gj[i], m + N + i, plain.gj[i]);
                inp.k[i] = seeded(plain.k[i], m + 2 * N + i, plain.k[i]);
            }
            integrate(robot, q, sections, &inp, model, None, Tangents::identity())
        }
    };
    implicit_columns::<T, N, K>(&out.r, &out.frame.columns(), m, 3 * N)
}

/// Runs [`pass`] with the fewest directions `K` that hold `m + columns` (`N` is a
/// constant, so only one arm survives optimisation).
fn dispatch<T: Real, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    x: &[T; N],
    model: Model,
    wrt: Wrt,
) -> [Vector6<T>; MAX_COLUMNS] {
    let columns = match wrt {
        Wrt::Joints => 2 * N - 1,
        Wrt::Parameters => 3 * N,
    };
    let needed = (N - 1) + columns;
    macro_rules! run {
        ($($k:literal),*) => {
            $(if needed <= $k {
                return pass::<T, N, $k>(robot, q, sections, x, model, wrt);
            })*
        };
    }
    run!(1, 3, 4, 7, 10, 11, 15);
    [Vector6::from_element(nan::<T>()); MAX_COLUMNS]
}

impl<T: Real, const N: usize> Solver<T, N> {
    /// Solves the forward kinematics (as [`solve`](Self::solve), warm-started) and
    /// returns the tip's [`JointJacobian`] there, from integrated sensitivities (see the
    /// [module doc](crate::jacobian)). Allocation-free; entries are NaN where the
    /// shooting Jacobian is singular (a snap). Meaningful where the solution converged.
    ///
    /// ```
    /// use ctr_core::{Joints, Model, Robot, Solver, Status, TubeParams};
    /// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
    /// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
    /// let robot = Robot::new([outer, inner]).unwrap();
    /// let mut solver = Solver::default();
    /// let q = Joints::from_mm_deg([40.0, 90.0], [0.0, 120.0]);
    /// let (sol, jac) = solver.solve_jacobian(&robot, &q, Model::Torsion).unwrap();
    /// assert_eq!(sol.status, Status::Converged);
    /// // turning both tubes together turns the tip about z: dp/dtheta = e_z x p
    /// let spin = jac.rotation[0] + jac.rotation[1];
    /// assert!((spin[0] + sol.tip.position.y).abs() < 1e-9 && (spin[1] - sol.tip.position.x).abs() < 1e-9);
    /// ```
    pub fn solve_jacobian(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
    ) -> Result<(Solution<T, N>, JointJacobian<T, N>), JointError> {
        let (sol, cols) = self.solve_columns(robot, q, model, Wrt::Joints)?;
        let mut jac = JointJacobian {
            feed: [Vector6::zeros(); N],
            rotation: [Vector6::zeros(); N],
        };
        // zipped copies: no slice lengths to check, no panic path
        let mut from = cols.iter();
        for (d, s) in jac
            .feed
            .iter_mut()
            .chain(jac.rotation.iter_mut())
            .zip(&mut from)
        {
            *d = *s;
        }
        Ok((sol, jac))
    }

    /// [`solve_jacobian`](Self::solve_jacobian) for the tip as
    /// [`solve_with`](Self::solve_with) reports it: at the joints shifted by the
    /// effects' offsets, the tracked point at the sensor offset, in the registered
    /// measuring frame (columns `(dp, omega)` of the measured point and frame in the
    /// measuring frame). Clearance kinks are not differentiated: with any clearance
    /// profile set, the solution is `solve_with`'s and every Jacobian entry is NaN.
    ///
    /// ```
    /// use ctr_core::{effects::{Effects, Registration}, Joints, Model, Robot, Solver, TubeParams};
    /// let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// // a straight tube seen from a frame turned 90 degrees about x: feeding moves the
    /// // measured tip along -y
    /// let effects = Effects {
    ///     registration: Some(Registration::from_axis_angle([1.0, 0.0, 0.0], core::f64::consts::FRAC_PI_2, [0.0; 3])),
    ///     ..Default::default()
    /// };
    /// let q = Joints::new([50.0], [0.0]);
    /// let (_, jac) = Solver::default().solve_jacobian_with(&robot, &q, Model::Torsion, &effects).unwrap();
    /// assert!((jac.feed[0][1] + 1.0).abs() < 1e-12);
    /// ```
    pub fn solve_jacobian_with(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
        effects: &crate::effects::Effects<T, N>,
    ) -> Result<(Solution<T, N>, JointJacobian<T, N>), JointError> {
        if effects.clearance.iter().any(Option::is_some) {
            let sol = self.solve_with(robot, q, model, effects)?;
            let none = Vector6::from_element(nan::<T>());
            return Ok((
                sol,
                JointJacobian {
                    feed: [none; N],
                    rotation: [none; N],
                },
            ));
        }
        let (mut sol, mut jac) = self.solve_jacobian(robot, &effects.actual(q), model)?;
        // the tracked point p + R o moves with dp + omega x (R o); then the registration
        // turns both blocks
        let arm = sol.tip.rotation * nalgebra::Vector3::from(effects.sensor_offset_mm);
        for col in jac.feed.iter_mut().chain(jac.rotation.iter_mut()) {
            let omega = col.fixed_rows::<3>(3).into_owned();
            let mut dp = col.fixed_rows::<3>(0) + omega.cross(&arm);
            let mut w = omega;
            if let Some(r) = &effects.registration {
                dp = r.rotation * dp;
                w = r.rotation * w;
            }
            *col = Vector6::new(dp[0], dp[1], dp[2], w[0], w[1], w[2]);
        }
        sol.tip = effects.measured(&sol.tip);
        Ok((sol, jac))
    }

    /// Solves the forward kinematics (warm-started) and returns the tip's
    /// [`ParameterJacobian`]: derivatives with respect to each tube's bending
    /// stiffness, torsional stiffness and precurvature scale factors, at 1.
    ///
    /// ```
    /// use ctr_core::{Joints, Model, Robot, Solver, TubeParams};
    /// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
    /// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
    /// let robot = Robot::new([outer, inner]).unwrap();
    /// let q = Joints::from_mm_deg([40.0, 90.0], [0.0, 120.0]);
    /// let (_, jac) = Solver::default().solve_parameter_jacobian(&robot, &q, Model::Torsion).unwrap();
    /// // the unloaded shape depends on stiffness ratios only: a common scale changes nothing
    /// let common: ctr_core::nalgebra::Vector6<f64> = (0..2).map(|i| jac.bending_stiffness[i] + jac.torsional_stiffness[i]).sum();
    /// assert!(common.norm() < 1e-9);
    /// ```
    pub fn solve_parameter_jacobian(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
    ) -> Result<(Solution<T, N>, ParameterJacobian<T, N>), JointError> {
        let (sol, cols) = self.solve_columns(robot, q, model, Wrt::Parameters)?;
        let mut jac = ParameterJacobian {
            bending_stiffness: [Vector6::zeros(); N],
            torsional_stiffness: [Vector6::zeros(); N],
            curvature: [Vector6::zeros(); N],
        };
        let targets = jac
            .bending_stiffness
            .iter_mut()
            .chain(jac.torsional_stiffness.iter_mut())
            .chain(jac.curvature.iter_mut());
        for (d, s) in targets.zip(cols.iter()) {
            *d = *s;
        }
        Ok((sol, jac))
    }

    /// Solves (as [`solve`](Self::solve)) and runs the dual pass on the same sections.
    fn solve_columns(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        model: Model,
        wrt: Wrt,
    ) -> Result<(Solution<T, N>, [Vector6<T>; MAX_COLUMNS]), JointError> {
        q.validate(robot)?;
        let sections = self.sections(robot, q);
        let (sol, _) = self.solve_sections(robot, q, model, &sections, None, &[None; N]);
        let cols = dispatch(robot, q, &sections, &sol.base_twist_per_mm, model, wrt);
        Ok((sol, cols))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three precurved tubes, the innermost with radius `r` mm, at a configuration where
    /// every tube is exposed.
    fn three_tubes(r: f64) -> (Robot<f64, 3>, Joints<f64, 3>) {
        let t = |od, id, len, cl, r| crate::TubeParams {
            curvature_radius_mm: Some(r),
            ..crate::TubeParams::<f64>::new(od, id, len, cl, 58000.0, 0.33)
        };
        let robot = Robot::new([
            t(1.9, 1.6, 160.0, 80.0, 300.0),
            t(1.4, 1.1, 220.0, 70.0, 180.0),
            t(0.9, 0.6, 280.0, 50.0, r),
        ])
        .unwrap();
        let q = Joints::from_mm_deg([30.0, 60.0, 95.0], [10.0, 100.0, -60.0]);
        (robot, q)
    }

    /// The spatial-twist derivatives ([`Tangents`]) equal the derivatives of the frame
    /// carried entry by entry in dual numbers, in both the series and the closed-form
    /// branches of the exponential (rigid sections turn by more than 0.3 rad).
    #[test]
    fn tangents_equal_dual_frames() {
        let (robot, q) = three_tubes(40.0);
        let cfg = crate::SolverConfig::<f64>::default();
        let k = robot.tubes().map(|t| t.curvature_per_mm());
        let sections = Sections::new(&robot, &q.s_mm, &k, cfg.max_step_mm, cfg.step_fraction);
        let sol = Solver::default().solve(&robot, &q, Model::Torsion).unwrap();
        let mut inp = Inputs {
            s: q.s_mm.map(Dual::<f64, 7>::cst),
            theta: q.theta_rad.map(Dual::cst),
            x: sol.base_twist_per_mm.map(Dual::cst),
            ei: robot.tubes().map(|t| t.bending_stiffness_nmm2()),
            gj: robot.tubes().map(|t| t.torsional_stiffness_nmm2()),
            k,
        };
        for j in 0..2 {
            inp.x[j] = Dual::var(sol.base_twist_per_mm[j], j);
        }
        for i in 0..3 {
            inp.s[i] = Dual::var(q.s_mm[i], 2 + i);
        }
        for i in 0..2 {
            inp.theta[i] = Dual::var(q.theta_rad[i], 5 + i);
        }
        let mut largest = 0.0_f64;
        for model in [Model::Rigid, Model::Torsion] {
            let zero = Dual::cst(0.0);
            let one = Dual::cst(1.0);
            let a = integrate(
                &robot,
                &q,
                &sections,
                &inp,
                model,
                None,
                GFrame::identity(zero, one),
            );
            let b = integrate(
                &robot,
                &q,
                &sections,
                &inp,
                model,
                None,
                Tangents::<f64, 7>::identity(),
            );
            let want = crate::tangent::columns_of_duals(&a.frame.p, &a.frame.r);
            let got = b.frame.columns();
            for i in 0..3 {
                assert!((b.frame.p[i] - a.frame.p[i].re).abs() < 1e-12);
            }
            for (w, g) in want.iter().zip(&got) {
                let scale = w.norm().max(1.0);
                largest = largest.max((w - g).norm() / scale);
            }
        }
        assert!(largest < 1e-12, "largest relative difference {largest:e}");
    }

    /// The generic integrator on plain numbers is the solver's pose pass.
    #[test]
    fn plain_pass_reproduces_the_solver() {
        let (robot, q) = three_tubes(80.0);
        for model in [Model::Rigid, Model::Torsion] {
            let sol = Solver::default().solve(&robot, &q, model).unwrap();
            let k = robot.tubes().map(|t| t.curvature_per_mm());
            let cfg = crate::SolverConfig::<f64>::default();
            let sections = Sections::new(&robot, &q.s_mm, &k, cfg.max_step_mm, cfg.step_fraction);
            let inp = Inputs::plain(&robot, &q, &sol.base_twist_per_mm);
            let out = integrate(
                &robot,
                &q,
                &sections,
                &inp,
                model,
                None,
                GFrame::identity(0.0, 1.0),
            );
            for i in 0..3 {
                assert!((out.frame.p[i] - sol.tip.position[i]).abs() < 1e-12);
                for j in 0..3 {
                    assert!((out.frame.r[i][j] - sol.tip.rotation[(i, j)]).abs() < 1e-13);
                }
            }
            for j in 0..2 {
                assert!(out.r[j].abs() <= 1e-12);
            }
        }
    }
}

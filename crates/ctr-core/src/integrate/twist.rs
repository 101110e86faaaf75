//! The torsionally compliant model: twist of every tube along the backbone.
//!
//! # Physics
//!
//! Tube `i` has bending stiffness `K_i = E_i I_i`, torsional stiffness `G_i J_i` and,
//! where its exposed curved part lies, precurvature `k_i` about its own body y axis
//! (formats spec: bending toward body +x). Let `psi_i(s)` be the angle of tube i's
//! material frame about the common tangent and `u_i = psi_i'` its twist rate. With no
//! external load the tubes share one bending curvature, the stiffness-weighted mean of
//! their precurvatures (moment balance; seed paper eq. 5-7), here in tube n's frame:
//!
//! ```text
//! u_xy = sum_l a_l (-sin b_l, cos b_l),   a_l = K_l k_l / sum_present K,   b_l = psi_l - psi_n
//! ```
//!
//! and every tube's twist obeys the torsion balance (Rucker, Jones & Webster, IEEE T-RO
//! 26(5), 2010, eq. 13; seed eq. 8 for two tubes):
//!
//! ```text
//! u_i' = (K_i k_i / G_i J_i) sum_l a_l sin(b_i - b_l)
//! ```
//!
//! The right-hand sides are antisymmetric, so the total torsional moment
//! `sum_i G_i J_i u_i` is conserved; at the free tips it is zero, so it is zero
//! everywhere and tube n's twist follows from the others:
//! `u_n = -sum_{i<n, present} G_i J_i u_i / G_n J_n`. Only relative angles enter, so
//! the state is `b_i` and `u_i` for `i < n`: `n - 1` angles, carried as unit complex
//! numbers `(cos b_i, sin b_i)` so that a step needs no trigonometry.
//!
//! Boundary conditions: behind the guide exit tube i is straight over
//! `length_i - s_i` and twists uniformly there, so at the exit
//! `psi_i(0) = theta_i + (length_i - s_i) u_i(0)`; each free tip carries no torque,
//! `u_i(s_i) = 0`. The unknowns are `x = (u_1(0), ..., u_{n-1}(0))`, the residuals
//! `r_i = u_i(s_i)`, solved by Newton's method ([`crate::solve::newton`]) on the
//! sensitivities `d(b, u)/dx` integrated alongside the state (variational equations,
//! [`crate::integrate::variations`]) with classic RK4.
//!
//! Sections where at most one tube is curved have `u_i' = 0` (a single curved tube
//! couples to nothing): constant twist, the relative angles advance linearly and the
//! backbone is a helix in the curved tube's frame, integrated in closed form.
//!
//! The pose is a product of SE(3) exponentials of tube n's body twist
//! `xi = (u_x, u_y, u_n; 0, 0, 1)`: exact in closed-form sections, and over an RK4 step
//! of length h the 4th-order Magnus expansion
//! `Omega = h/2 (A0 + A1) + h^2/12 (A0' - A1') + h^2/12 [A0, A1]`
//! (corrected trapezoid rule for the integral; the commutator term of the body-frame
//! equation `g' = g A`, whose sign is opposite to that of `Y' = A Y`).

use super::pose::Pose;
use super::{rk4_step, steps, OdeState, Rhs, Stage};
use crate::math::dual::Num;
use crate::model::joints::Joints;
use crate::model::robot::Robot;
use crate::model::sections::Section;
use crate::real::{c, Real};
use core::marker::PhantomData;
use core::ops::Mul;

/// Everything a pass depends on: joints and unknowns as `S`, the tubes' stiffnesses and
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
            ei: robot.each(|t| t.bending_stiffness_nmm2()),
            gj: robot.each(|t| t.torsional_stiffness_nmm2()),
            k: robot.each(|t| t.curvature_per_mm()),
        }
    }
}

/// One section's coefficients: its length as `S`, the stiffness terms as `C` (copies of
/// the plain section's where nothing is differentiated).
pub(crate) struct TwistSection<T, S, C, const N: usize> {
    pub len: S,
    pub present: [bool; N],
    /// `E I_i k_i / sum(E I present)`, 1/mm
    pub a: [C; N],
    pub curved_a: [bool; N],
    /// `E I_i k_i / G J_i`, 1/mm
    pub g: [C; N],
    pub curved_g: [bool; N],
    pub gj: [C; N],
    pub inv_gj_n: C,
    /// tubes curved over the section, and the only one where there is one
    pub curved: usize,
    pub single: usize,
    /// RK4 steps across the section (on the coarse or the full steps; 1 where it is
    /// integrated in closed form)
    pub steps: usize,
    /// the full RK4 step, mm (closed-form sections are cut into such steps where the
    /// pass traces the backbone)
    pub h: T,
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

impl<T: Real, S: Copy, C: Copy, const N: usize> TwistSection<T, S, C, N> {
    /// The coefficients of section `sec` with the inputs' numbers: the length follows
    /// the joints, the stiffness terms the stiffnesses (on plain numbers they are the
    /// section's own). `coarse`: the steps of a cold start's first iterations.
    /// `inv_gj_n` is `1 / G J_n`.
    #[inline]
    pub fn new(
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        inp: &Inputs<S, C, N>,
        sec: &Section<T, N>,
        coarse: bool,
        inv_gj_n: C,
    ) -> Self
    where
        S: Num<T> + Mul<C, Output = S>,
        C: Num<T>,
    {
        let zero = C::cst(T::zero());
        let mut a = [zero; N];
        let mut g = [zero; N];
        let len;
        if !S::DUAL && !C::DUAL {
            len = S::cst(sec.end - sec.start);
            for i in 0..N {
                a[i] = C::cst(sec.a[i]);
                g[i] = C::cst(sec.g[i]);
            }
        } else {
            len = cut(robot, q, inp, sec.end) - cut(robot, q, inp, sec.start);
            let mut stiff = zero;
            for i in 0..N {
                if sec.present[i] {
                    stiff += inp.ei[i];
                }
            }
            for i in 0..N {
                if sec.curved_a[i] {
                    let ek = inp.ei[i] * inp.k[i];
                    a[i] = ek / stiff;
                    g[i] = ek / inp.gj[i];
                }
            }
        }
        TwistSection {
            len,
            present: sec.present,
            a,
            curved_a: sec.curved_a,
            g,
            curved_g: sec.curved_g,
            gj: inp.gj,
            inv_gj_n,
            curved: sec.curved,
            single: sec.single,
            steps: if sec.curved <= 1 {
                1
            } else {
                steps(
                    sec.end - sec.start,
                    if coarse { sec.h_coarse } else { sec.h },
                )
            },
            h: sec.h,
        }
    }

    /// Tube n's twist rate from the conservation of torque.
    #[inline(always)]
    pub fn inner_twist(&self, w: &[S; N]) -> S
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

    /// The twist equations' right-hand side on the values (see the module doc).
    #[inline(always)]
    pub fn rhs(&self, st: &TwistState<S, N>) -> TwistState<S, N>
    where
        S: Num<T> + Mul<C, Output = S>,
    {
        let zero = S::cst(T::zero());
        let mut d = TwistState {
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
    pub fn body_rate(&self, z: &[[S; 2]; N], un: S, rate: bool) -> [S; 3]
    where
        S: Num<T> + Mul<C, Output = S>,
    {
        body_rate(&self.a, &self.curved_a, z, un, rate)
    }

    /// Moves `frame` over a stretch of length `h` where tube n's frame sees one curved
    /// tube `l` (or none): constant twist in tube l's frame, exact exponential.
    #[inline(always)]
    fn pose_constant_twist<F: Pose<T, S>>(&self, st: &TwistState<S, N>, un: S, h: S, frame: &mut F)
    where
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
        // into tube l's frame, move, and back by the advanced relative angle
        frame.rotate_z(cl, sl);
        frame.step([zero, h * self.a[l], ul * h], [zero, zero, h]);
        let (s, co) = ((ul - un) * h).sin_cos();
        let (c2, s2) = (cl * co - sl * s, sl * co + cl * s);
        frame.rotate_z(c2, -s2);
    }
}

/// Tube n's body angular rate `(u_x, u_y, u_n)` from the tubes' curvature shares `a`
/// (of the curved tubes, `curved`), the relative angles `z` and its twist `un` (module
/// doc); with `rate`, `z` and `un` are rates (d/ds) and so is the result.
#[inline(always)]
pub(crate) fn body_rate<T: Real, S: Num<T> + Mul<C, Output = S>, C: Copy, const N: usize>(
    a: &[C; N],
    curved: &[bool; N],
    z: &[[S; 2]; N],
    un: S,
    rate: bool,
) -> [S; 3] {
    let mut ux = S::cst(T::zero());
    let mut uy = S::cst(T::zero());
    for l in 0..N - 1 {
        if curved[l] {
            ux -= z[l][1] * a[l];
            uy += z[l][0] * a[l];
        }
    }
    // z_{N-1} = (1, 0) (the innermost tube is the reference); its rate is zero
    if curved[N - 1] && !rate {
        uy += S::cst(T::one()) * a[N - 1];
    }
    [ux, uy, un]
}

/// The twist values at one arc length: `(cos b_j, sin b_j)` and `u_j` for `j < N-1`
/// (entry N-1 of `z` is `(1, 0)`: tube n is the reference).
#[derive(Clone, Copy)]
pub(crate) struct TwistState<S, const N: usize> {
    pub z: [[S; 2]; N],
    pub w: [S; N],
}

impl<S: Copy, const N: usize> OdeState<S> for TwistState<S, N> {
    #[inline(always)]
    fn zip_with<const K: usize>(&mut self, k: [&Self; K], f: impl Fn(S, [S; K]) -> S) {
        for j in 0..N - 1 {
            for cc in 0..2 {
                self.z[j][cc] = f(self.z[j][cc], k.map(|x| x.z[j][cc]));
            }
            self.w[j] = f(self.w[j], k.map(|x| x.w[j]));
        }
    }
}

/// A state a section integration advances: the twist values, and whatever rides along
/// (the variations of [`crate::integrate::variations`]).
pub(crate) trait TwistOde<T, S, C, const N: usize>: OdeState<S> {
    /// The twist values.
    fn values(&self) -> &TwistState<S, N>;
    /// The relative angles, to put back on the unit circle.
    fn values_mut(&mut self) -> &mut TwistState<S, N>;
    /// d/ds inside section `sec`.
    fn rhs(&self, sec: &TwistSection<T, S, C, N>) -> Self;
    /// Advances over `h` at constant twist (`un` tube n's): the relative angles turn
    /// by `(u_j - u_n) h`.
    fn rotate(&mut self, sec: &TwistSection<T, S, C, N>, un: S, h: S);
}

impl<T: Real, S: Num<T> + Mul<C, Output = S>, C: Copy, const N: usize> TwistOde<T, S, C, N>
    for TwistState<S, N>
{
    #[inline(always)]
    fn values(&self) -> &TwistState<S, N> {
        self
    }
    #[inline(always)]
    fn values_mut(&mut self) -> &mut TwistState<S, N> {
        self
    }
    #[inline(always)]
    fn rhs(&self, sec: &TwistSection<T, S, C, N>) -> Self {
        if S::DUAL {
            rhs_out_of_line(sec, self)
        } else {
            sec.rhs(self)
        }
    }
    #[inline(always)]
    fn rotate(&mut self, sec: &TwistSection<T, S, C, N>, un: S, h: S) {
        rotate_angles(&mut self.z, &self.w, &sec.present, un, h);
    }
}

/// [`TwistSection::rhs`] kept out of line: on dual numbers, four inlined stages would
/// not fit the instruction cache (measured 4 % faster).
#[inline(never)]
fn rhs_out_of_line<T: Real, S: Num<T> + Mul<C, Output = S>, C: Copy, const N: usize>(
    sec: &TwistSection<T, S, C, N>,
    st: &TwistState<S, N>,
) -> TwistState<S, N> {
    sec.rhs(st)
}

/// Turns the relative angles of the present tubes by `(u_j - u_n) h`.
#[inline(always)]
pub(crate) fn rotate_angles<T: Real, S: Num<T>, const N: usize>(
    z: &mut [[S; 2]; N],
    w: &[S; N],
    present: &[bool; N],
    un: S,
    h: S,
) {
    for j in 0..N - 1 {
        if !present[j] {
            continue;
        }
        let (s, co) = ((w[j] - un) * h).sin_cos();
        let [cj, sj] = z[j];
        z[j] = [cj * co - sj * s, sj * co + cj * s];
    }
}

/// The twist equations of one section as RK4's right-hand side.
struct Twist<'a, T, S, C, St, const N: usize> {
    sec: &'a TwistSection<T, S, C, N>,
    state: PhantomData<St>,
}

impl<T, S, C, St, const N: usize> Rhs<St> for Twist<'_, T, S, C, St, N>
where
    T: Real,
    S: Num<T> + Mul<C, Output = S>,
    C: Copy,
    St: TwistOde<T, S, C, N>,
{
    #[inline(always)]
    fn rhs(&self, x: &St, _: Stage) -> St {
        x.rhs(self.sec)
    }
}

/// Largest turn of a relative angle over one RK4 step of a coupled section, rad.
///
/// The section's own step ([`crate::model::sections`]) resolves the coupling's length
/// scales, not the rates at which the relative angles turn, `u_j - u_n`. At an
/// equilibrium those are small, but Newton's iterates can carry large ones: where a
/// tube ends with a torque left (its residual), that torque passes to tube n, whose
/// twist rate jumps by `G_j J_j / G_n J_n` times the tube's (629 times for a soft
/// wire inside stiff tubes). RK4 on a turning angle `z' = i w z` is unstable beyond
/// `w h` ~ 2.8 and already off by 0.5 % of a turn per step at `w h` = 1: past that the
/// pass overflows or lands on a root of the discretisation rather than of the
/// equations. So a coupled section takes at least the steps that keep every turn per
/// step below this, at the rates it starts with.
pub(crate) const MAX_TURN_PER_STEP: f64 = 1.0;

/// Most RK4 steps [`turn_steps`] asks of one section: a bound on what an iterate far
/// off costs (a turn of up to 64 rad across a section is resolved; a wandering
/// iterate's rates beyond that are not, and its start fails as before, to be retried).
/// With 4096, the IK's far targets on four-tube robots took 16 times as long.
const MAX_TURN_STEPS: usize = 64;

/// RK4 steps that keep every relative angle's turn per step at the rates of `st` (the
/// section's start) below [`MAX_TURN_PER_STEP`] (1 when nothing turns).
#[inline]
fn turn_steps<T, S, C, const N: usize>(
    sec: &TwistSection<T, S, C, N>,
    st: &TwistState<S, N>,
) -> usize
where
    T: Real,
    S: Num<T> + Mul<C, Output = S>,
    C: Copy,
{
    let un = sec.inner_twist(&st.w).re();
    let mut rate = T::zero();
    for j in 0..N - 1 {
        if sec.present[j] {
            rate = rate.max((st.w[j].re() - un).abs());
        }
    }
    if rate > T::zero() {
        steps(sec.len.re() * rate, c(MAX_TURN_PER_STEP)).min(MAX_TURN_STEPS)
    } else {
        1
    }
}

/// Integrates the twist state across one section and moves `frame` along (tube n's
/// material frame): RK4 with the Magnus pose step, or in closed form where at most one
/// tube is curved (cut into steps of the RK4 length where the frame traces points).
#[inline]
pub(crate) fn section<T, S, C, St, F, const N: usize>(
    sec: &TwistSection<T, S, C, N>,
    st: &mut St,
    frame: &mut F,
) where
    T: Real,
    S: Num<T> + Mul<C, Output = S>,
    C: Copy,
    St: TwistOde<T, S, C, N>,
    F: Pose<T, S>,
{
    if sec.curved <= 1 {
        let un = sec.inner_twist(&st.values().w);
        let sub = if frame.traces() {
            steps(sec.len.re(), sec.h)
        } else {
            1
        };
        let h = if sub == 1 {
            sec.len
        } else {
            sec.len / S::cst(nalgebra::convert(sub as f64))
        };
        for _ in 0..sub {
            if F::MOVES {
                sec.pose_constant_twist(st.values(), un, h, frame);
                frame.mark();
            }
            st.rotate(sec, un, h);
        }
        return;
    }
    let n = sec.steps.max(turn_steps(sec, st.values()));
    let h = sec.len / S::cst(nalgebra::convert(n as f64));
    let half = h * c::<T>(0.5);
    let sixth = h / S::cst(c(6.0));
    let h2_12 = h * h / S::cst(c(12.0));
    let mut k1 = st.rhs(sec);
    let zero = S::cst(T::zero());
    // tube n's body rate and its derivative at the step's start (the last step's end)
    let rates = |x: &St, d: &St| {
        (
            sec.body_rate(&x.values().z, sec.inner_twist(&x.values().w), false),
            sec.body_rate(&d.values().z, sec.inner_twist(&d.values().w), true),
        )
    };
    let (mut a0, mut d0) = if F::MOVES {
        rates(st, &k1)
    } else {
        ([zero; 3], [zero; 3])
    };
    for _ in 0..n {
        let next = rk4_step(
            st,
            &k1,
            h,
            half,
            sixth,
            &Twist {
                sec,
                state: PhantomData,
            },
        );
        let k1_next = next.rhs(sec);
        if F::MOVES {
            let (a1, d1) = rates(&next, &k1_next);
            // Magnus: Omega = h/2 (A0 + A1) + h^2/12 (A0' - A1') + h^2/12 [A0, A1]
            let a01 = crate::math::linalg::cross(&a0, &a1);
            let omega: [S; 3] = core::array::from_fn(|i| {
                (a0[i] + a1[i]) * half + (d0[i] - d1[i]) * h2_12 + a01[i] * h2_12
            });
            // v = e3 h + (a0 - a1) x e3 h^2/12
            let v = [(a0[1] - a1[1]) * h2_12, (a1[0] - a0[0]) * h2_12, h];
            frame.step(omega, v);
            frame.mark();
            a0 = a1;
            d0 = d1;
        }
        *st = next;
        k1 = k1_next;
    }
    // RK4 keeps |z| = 1 only to its order: put the angles back on the unit circle
    let one = S::cst(T::one());
    let v = st.values_mut();
    for j in 0..N - 1 {
        let [cj, sj] = v.z[j];
        let inv = one / (cj * cj + sj * sj).sqrt();
        v.z[j] = [cj * inv, sj * inv];
    }
}

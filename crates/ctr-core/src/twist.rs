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
//! `r_i = u_i(s_i)`, solved by Newton's method on sensitivities `d(b, u)/dx` integrated
//! alongside the state (variational equations) with classic RK4.
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

use crate::real::Real;
use crate::se3::{exp, sin_cos, Frame};
use crate::sections::Section;
use nalgebra::Vector3;

/// Twist state at one arc length: relative angles and twist rates, with sensitivities.
#[derive(Clone, Copy, Debug)]
pub(crate) struct State<T, const N: usize> {
    /// `(cos b_j, sin b_j)`, `b_j = psi_j - psi_n`; entry `N-1` is `(1, 0)`
    pub z: [[T; 2]; N],
    /// twist rate `u_j` of tube `j < N-1`, rad/mm
    pub w: [T; N],
    /// `d b_j / d x_k`
    pub db: [[T; N]; N],
    /// `d u_j / d x_k`
    pub dw: [[T; N]; N],
}

impl<T: Real, const N: usize> State<T, N> {
    pub fn zero() -> Self {
        let mut z = [[T::zero(); 2]; N];
        z[N - 1] = [T::one(), T::zero()];
        State {
            z,
            w: [T::zero(); N],
            db: [[T::zero(); N]; N],
            dw: [[T::zero(); N]; N],
        }
    }

    /// `self + h d` over the entries that move.
    #[inline(always)]
    fn step<const SENS: bool>(&self, d: &Self, h: T) -> Self {
        let mut o = *self;
        for j in 0..N - 1 {
            o.z[j][0] += d.z[j][0] * h;
            o.z[j][1] += d.z[j][1] * h;
            o.w[j] += d.w[j] * h;
            if SENS {
                for k in 0..N - 1 {
                    o.db[j][k] += d.db[j][k] * h;
                    o.dw[j][k] += d.dw[j][k] * h;
                }
            }
        }
        o
    }
}

/// Tube n's twist rate from the conservation of torque, and its sensitivities.
#[inline(always)]
pub(crate) fn inner_twist<T: Real, const N: usize, const SENS: bool>(
    present: &[bool; N],
    gj: &[T; N],
    w: &[T; N],
    dw: &[[T; N]; N],
) -> (T, [T; N]) {
    let mut un = T::zero();
    let mut dun = [T::zero(); N];
    for j in 0..N - 1 {
        if present[j] {
            un -= gj[j] * w[j];
            if SENS {
                for k in 0..N - 1 {
                    dun[k] -= gj[j] * dw[j][k];
                }
            }
        }
    }
    let inv = T::one() / gj[N - 1];
    if SENS {
        for d in dun.iter_mut() {
            *d *= inv;
        }
    }
    (un * inv, dun)
}

/// Derivative of the state along s inside a section.
#[inline(always)]
pub(crate) fn rhs<T: Real, const N: usize, const SENS: bool>(
    sec: &Section<T, N>,
    gj: &[T; N],
    st: &State<T, N>,
) -> State<T, N> {
    let mut d = State::zero();
    d.z[N - 1] = [T::zero(), T::zero()];
    let (un, dun) = inner_twist::<T, N, SENS>(&sec.present, gj, &st.w, &st.dw);
    for j in 0..N - 1 {
        if !sec.present[j] {
            continue;
        }
        let om = st.w[j] - un;
        let [cj, sj] = st.z[j];
        d.z[j] = [-sj * om, cj * om];
        if SENS {
            for k in 0..N - 1 {
                d.db[j][k] = st.dw[j][k] - dun[k];
            }
        }
        if sec.g[j] != T::zero() {
            let mut acc = T::zero();
            for l in 0..N {
                if l != j && sec.a[l] != T::zero() {
                    let [cl, sl] = st.z[l];
                    acc += sec.a[l] * (sj * cl - cj * sl);
                    if SENS {
                        let cosd = cj * cl + sj * sl;
                        for k in 0..N - 1 {
                            d.dw[j][k] += sec.g[j] * sec.a[l] * cosd * (st.db[j][k] - st.db[l][k]);
                        }
                    }
                }
            }
            d.w[j] = sec.g[j] * acc;
        }
    }
    d
}

/// Tube n's body angular rate (bending in its frame, twist about the tangent), 1/mm.
#[inline(always)]
pub(crate) fn body_rate<T: Real, const N: usize>(
    sec: &Section<T, N>,
    st: &State<T, N>,
    un: T,
) -> Vector3<T> {
    let mut ux = T::zero();
    let mut uy = T::zero();
    for l in 0..N {
        if sec.a[l] != T::zero() {
            ux -= sec.a[l] * st.z[l][1];
            uy += sec.a[l] * st.z[l][0];
        }
    }
    Vector3::new(ux, uy, un)
}

/// Derivative of [`body_rate`] along s, from the state derivative `d`.
#[inline(always)]
fn body_rate_derivative<T: Real, const N: usize>(
    sec: &Section<T, N>,
    gj: &[T; N],
    d: &State<T, N>,
) -> Vector3<T> {
    let mut ux = T::zero();
    let mut uy = T::zero();
    for l in 0..N {
        if sec.a[l] != T::zero() {
            ux -= sec.a[l] * d.z[l][1];
            uy += sec.a[l] * d.z[l][0];
        }
    }
    let (dun, _) = inner_twist::<T, N, false>(&sec.present, gj, &d.w, &d.dw);
    Vector3::new(ux, uy, dun)
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

/// Writes points to an optional caller buffer, counting those that did not fit.
pub(crate) struct PointSink<'a, T: Real> {
    pub buf: Option<&'a mut [Vector3<T>]>,
    pub written: usize,
    pub needed: usize,
}

impl<T: Real> PointSink<'_, T> {
    #[inline]
    pub fn push(&mut self, p: &Vector3<T>) {
        if let Some(buf) = self.buf.as_deref_mut() {
            if let Some(slot) = buf.get_mut(self.needed) {
                *slot = *p;
                self.written += 1;
            }
            self.needed += 1;
        }
    }
    #[inline]
    pub fn active(&self) -> bool {
        self.buf.is_some()
    }
}

/// Integrates the twist state across one section. With `POSE`, also moves `frame`
/// (tube n's material frame) and writes backbone points.
#[inline]
pub(crate) fn section<T: Real, const N: usize, const SENS: bool, const POSE: bool>(
    sec: &Section<T, N>,
    coarse: bool,
    gj: &[T; N],
    st: &mut State<T, N>,
    frame: &mut Frame<T>,
    sink: &mut PointSink<'_, T>,
) {
    let len = sec.end - sec.start;
    if sec.curved <= 1 {
        let (un, dun) = inner_twist::<T, N, SENS>(&sec.present, gj, &st.w, &st.dw);
        let sub = if POSE && sink.active() {
            steps(len, sec.h)
        } else {
            1
        };
        let h = len / nalgebra::convert::<f64, T>(sub as f64);
        for _ in 0..sub {
            if POSE {
                pose_constant_twist(sec, st, un, h, frame);
                sink.push(&frame.position);
            }
            for j in 0..N - 1 {
                if !sec.present[j] {
                    continue;
                }
                let (s, co) = sin_cos((st.w[j] - un) * h);
                let [cj, sj] = st.z[j];
                st.z[j] = [cj * co - sj * s, sj * co + cj * s];
                if SENS {
                    for k in 0..N - 1 {
                        st.db[j][k] += (st.dw[j][k] - dun[k]) * h;
                    }
                }
            }
        }
        return;
    }
    let n = steps(len, if coarse { sec.h_coarse } else { sec.h });
    let h = len / nalgebra::convert::<f64, T>(n as f64);
    let half = h * nalgebra::convert(0.5);
    let sixth = h / nalgebra::convert(6.0);
    let mut k1 = rhs::<T, N, SENS>(sec, gj, st);
    // tube n's body rate and its derivative at the step's start (the last step's end)
    let (mut a0, mut d0) = if POSE {
        let (un0, _) = inner_twist::<T, N, false>(&sec.present, gj, &st.w, &st.dw);
        (body_rate(sec, st, un0), body_rate_derivative(sec, gj, &k1))
    } else {
        (Vector3::zeros(), Vector3::zeros())
    };
    for _ in 0..n {
        let k2 = rhs::<T, N, SENS>(sec, gj, &st.step::<SENS>(&k1, half));
        let k3 = rhs::<T, N, SENS>(sec, gj, &st.step::<SENS>(&k2, half));
        let k4 = rhs::<T, N, SENS>(sec, gj, &st.step::<SENS>(&k3, h));
        let mut next = *st;
        for j in 0..N - 1 {
            for c in 0..2 {
                next.z[j][c] += sixth
                    * (k1.z[j][c]
                        + (k2.z[j][c] + k3.z[j][c]) * nalgebra::convert(2.0)
                        + k4.z[j][c]);
            }
            next.w[j] += sixth * (k1.w[j] + (k2.w[j] + k3.w[j]) * nalgebra::convert(2.0) + k4.w[j]);
            if SENS {
                for k in 0..N - 1 {
                    next.db[j][k] += sixth
                        * (k1.db[j][k]
                            + (k2.db[j][k] + k3.db[j][k]) * nalgebra::convert(2.0)
                            + k4.db[j][k]);
                    next.dw[j][k] += sixth
                        * (k1.dw[j][k]
                            + (k2.dw[j][k] + k3.dw[j][k]) * nalgebra::convert(2.0)
                            + k4.dw[j][k]);
                }
            }
        }
        let k1_next = rhs::<T, N, SENS>(sec, gj, &next);
        if POSE {
            let (un1, _) = inner_twist::<T, N, false>(&sec.present, gj, &next.w, &next.dw);
            let a1 = body_rate(sec, &next, un1);
            let d1 = body_rate_derivative(sec, gj, &k1_next);
            let h2_12 = h * h / nalgebra::convert(12.0);
            let e3 = Vector3::z();
            let omega = (a0 + a1) * half + (d0 - d1) * h2_12 + a0.cross(&a1) * h2_12;
            let v = e3 * h + (a0 - a1).cross(&e3) * h2_12;
            let (r, p) = exp(omega, v);
            frame.compose(&r, &p);
            sink.push(&frame.position);
            a0 = a1;
            d0 = d1;
        }
        *st = next;
        k1 = k1_next;
    }
    // RK4 keeps |z| = 1 only to its order: put the angles back on the unit circle
    for j in 0..N - 1 {
        let [cj, sj] = st.z[j];
        let inv = T::one() / (cj * cj + sj * sj).sqrt();
        st.z[j] = [cj * inv, sj * inv];
    }
}

/// Pose over a stretch of length `h` where tube n's frame sees one curved tube `l` (or
/// none): constant twist in tube l's frame, exact exponential.
#[inline]
fn pose_constant_twist<T: Real, const N: usize>(
    sec: &Section<T, N>,
    st: &State<T, N>,
    un: T,
    h: T,
    frame: &mut Frame<T>,
) {
    let e3 = Vector3::z();
    if sec.curved == 0 {
        frame.position += frame.rotation.column(2) * h;
        let (s, co) = sin_cos(un * h);
        frame.rotate_z((co, s));
        return;
    }
    let l = sec.single;
    let ul = if l == N - 1 { un } else { st.w[l] };
    let [cl, sl] = st.z[l];
    let inv = T::one() / (cl * cl + sl * sl).sqrt();
    let (cl, sl) = (cl * inv, sl * inv);
    // into tube l's frame, move, and back by the advanced relative angle
    frame.rotate_z((cl, sl));
    let (r, p) = exp(Vector3::new(T::zero(), sec.a[l], ul) * h, e3 * h);
    frame.compose(&r, &p);
    let (s, co) = sin_cos((ul - un) * h);
    let (c2, s2) = (cl * co - sl * s, sl * co + cl * s);
    frame.rotate_z((c2, -s2));
}

//! The mechanics under external loads: the tubes' weight, a tip force and a tip moment
//! (Cosserat statics).
//!
//! # Physics
//!
//! With loads the tubes still share one backbone, but the bending curvature now also
//! carries the internal moment. In tube n's material frame `R` (z the tangent):
//!
//! ```text
//! p' = R e3                       n(s) = F_tip + integral_s^{s_n} f         (force, W)
//! R' = R [u]x                     m'   = -p' x n                            (moment, W)
//! u_xy = (R^T m)_xy / K + sum_l a_l (-sin b_l, cos b_l)      K = sum_present E I
//! u_n  = ((R^T m)_z - sum_{j<n} G J_j u_j) / G J_n           (torque balance)
//! b_j' = u_j - u_n,   u_j' = (E I_j k_j / G J_j) (cos b_j u_x + sin b_j u_y)
//! ```
//!
//! (Rucker, Jones & Webster, IEEE T-RO 26(5), 2010, eq. 12-13; the unloaded model of
//! [`crate::integrate::twist`] is the case `m = 0`.) The weight per length of tube i on its
//! exposed part is `f_i = rho_i A_i g` (kg/m^3 x mm^2 x m/s^2 x 1e-9 = N/mm); the guide
//! holds everything behind `s = 0`. Boundary conditions: the transmissions twist as in
//! the unloaded model, the free tips carry no torque `u_j(s_j) = 0`, and the tip moment
//! is `m(s_n) = M_tip`. The unknowns are the base twists `u_j(0)` (`j < n`) and the base
//! moment `m(0)` (W), `n + 2` in all, solved by Newton's method; the shooting Jacobian
//! comes from integrating the state in dual numbers ([`crate::math::dual`]), which is RK4 on
//! the variational equations. The force `n(s)` is known in closed form (piecewise
//! linear), so it is not an unknown.

use super::pass::{guide_exit, present_at_exit};
use super::twist::Inputs;
use super::{rk4_step, steps, OdeState, Rhs, Stage};
use crate::math::dual::Num;
use crate::math::linalg::cross;
use crate::math::se3::Frame;
use crate::model::joints::Joints;
use crate::model::robot::Robot;
use crate::model::sections::{Section, Sections};
use crate::real::{c, Real};
use nalgebra::{Matrix3, Vector3};

/// Most unknowns of a loaded solve: `MAX_TUBES - 1` base twists and a base moment.
pub const MAX_UNKNOWNS: usize = crate::MAX_TUBES - 1 + 3;

/// kg/m^3 x mm^2 x m/s^2 in N/mm.
pub(crate) const WEIGHT_UNIT: f64 = 1e-9;

/// State of the loaded integration: position, orientation (unit quaternion w, x, y, z of
/// tube n's frame), internal moment (W), relative angles, twist rates.
#[derive(Clone, Copy)]
pub(crate) struct LState<S, const N: usize> {
    pub p: [S; 3],
    pub q: [S; 4],
    pub m: [S; 3],
    pub z: [[S; 2]; N],
    pub w: [S; N],
}

impl<S: Copy, const N: usize> OdeState<S> for LState<S, N> {
    #[inline(always)]
    fn zip_with<const K: usize>(&mut self, k: [&Self; K], f: impl Fn(S, [S; K]) -> S) {
        for i in 0..3 {
            self.p[i] = f(self.p[i], k.map(|x| x.p[i]));
            self.m[i] = f(self.m[i], k.map(|x| x.m[i]));
        }
        for i in 0..4 {
            self.q[i] = f(self.q[i], k.map(|x| x.q[i]));
        }
        for j in 0..N {
            for cc in 0..2 {
                self.z[j][cc] = f(self.z[j][cc], k.map(|x| x.z[j][cc]));
            }
            self.w[j] = f(self.w[j], k.map(|x| x.w[j]));
        }
    }
}

impl<T: Real, const N: usize> LState<T, N> {
    /// Tube n's frame at this state.
    pub fn frame(&self) -> Frame<T> {
        let q = nalgebra::Quaternion::new(self.q[0], self.q[1], self.q[2], self.q[3]);
        let r: Matrix3<T> = nalgebra::UnitQuaternion::from_quaternion(q)
            .to_rotation_matrix()
            .into_inner();
        Frame {
            rotation: r,
            position: Vector3::new(self.p[0], self.p[1], self.p[2]),
        }
    }
}

impl<S: Copy, const N: usize> LState<S, N> {
    /// The rotation matrix of the orientation, row-major.
    pub fn rotation<T: Real>(&self) -> [[S; 3]; 3]
    where
        S: Num<T>,
    {
        let [qw, qx, qy, qz] = self.q;
        let one = S::cst(T::one());
        let two = c::<T>(2.0);
        [
            [
                one - (qy * qy + qz * qz) * two,
                (qx * qy - qw * qz) * two,
                (qx * qz + qw * qy) * two,
            ],
            [
                (qx * qy + qw * qz) * two,
                one - (qx * qx + qz * qz) * two,
                (qy * qz - qw * qx) * two,
            ],
            [
                (qx * qz - qw * qy) * two,
                (qy * qz + qw * qx) * two,
                one - (qx * qx + qy * qy) * two,
            ],
        ]
    }
}

/// What a loaded pass depends on besides the unknowns: the weight per length of each
/// tube (N/mm) along the unit direction of gravity, the tip loads, and the joints.
pub(crate) struct Ctx<T, S, const N: usize> {
    pub gj: [T; N],
    pub weight: [T; N],
    pub dir: Vector3<T>,
    pub s: [T; N],
    /// tip force, N, and moment, N mm (W)
    pub tip_force: [S; 3],
    pub tip_moment: [S; 3],
}

impl<T: Real, S: Num<T>, const N: usize> Ctx<T, S, N> {
    /// Internal force at arc length `at` (W, N): the tip force plus the weight beyond.
    fn force(&self, at: T) -> [S; 3] {
        let mut beyond = T::zero();
        for i in 0..N {
            if self.s[i] > at {
                beyond += self.weight[i] * (self.s[i] - at.max(T::zero()));
            }
        }
        let w = self.dir * beyond;
        [
            self.tip_force[0] + S::cst(w.x),
            self.tip_force[1] + S::cst(w.y),
            self.tip_force[2] + S::cst(w.z),
        ]
    }
}

#[inline(always)]
fn rhs<T: Real, S: Num<T>, const N: usize>(
    sec: &Section<T, N>,
    gj: &[T; N],
    st: &LState<S, N>,
    force: [S; 3],
) -> LState<S, N> {
    let [qw, qx, qy, qz] = st.q;
    let two = c::<T>(2.0);
    // columns of R from the unit quaternion
    let (xx, yy, zz) = (qx * qx, qy * qy, qz * qz);
    let (xy, xz, yz, wx, wy, wz) = (qx * qy, qx * qz, qy * qz, qw * qx, qw * qy, qw * qz);
    let one = S::cst(T::one());
    let ex = [one - (yy + zz) * two, (xy + wz) * two, (xz - wy) * two];
    let ey = [(xy - wz) * two, one - (xx + zz) * two, (yz + wx) * two];
    let ez = [(xz + wy) * two, (yz - wx) * two, one - (xx + yy) * two];
    let dot = |a: &[S; 3], b: &[S; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (mbx, mby, mbz) = (dot(&ex, &st.m), dot(&ey, &st.m), dot(&ez, &st.m));
    let mut ux = mbx * sec.inv_k;
    let mut uy = mby * sec.inv_k;
    for l in 0..N {
        if sec.a[l] != T::zero() {
            ux -= st.z[l][1] * sec.a[l];
            uy += st.z[l][0] * sec.a[l];
        }
    }
    let mut torque = mbz;
    for j in 0..N - 1 {
        if sec.present[j] {
            torque -= st.w[j] * gj[j];
        }
    }
    let un = torque * (T::one() / gj[N - 1]);
    let zero = S::cst(T::zero());
    let mut d = LState {
        p: ez,
        q: [zero; 4],
        m: [zero; 3],
        z: [[zero; 2]; N],
        w: [zero; N],
    };
    let half = c::<T>(0.5);
    // q' = q (0, u) / 2
    d.q = [
        -(qx * ux + qy * uy + qz * un) * half,
        (qw * ux + qy * un - qz * uy) * half,
        (qw * uy + qz * ux - qx * un) * half,
        (qw * un + qx * uy - qy * ux) * half,
    ];
    let pm = cross(&ez, &force);
    d.m = [-pm[0], -pm[1], -pm[2]];
    for j in 0..N - 1 {
        if !sec.present[j] {
            continue;
        }
        let om = st.w[j] - un;
        let [cj, sj] = st.z[j];
        d.z[j] = [-(sj * om), cj * om];
        if sec.g[j] != T::zero() {
            d.w[j] = (cj * ux + sj * uy) * sec.g[j];
        }
    }
    d
}

/// The loaded equations over one RK4 step: the internal force at its middle and end.
struct Step<'a, T, S, const N: usize> {
    sec: &'a Section<T, N>,
    gj: &'a [T; N],
    middle: [S; 3],
    end: [S; 3],
}

impl<T: Real, S: Num<T>, const N: usize> Rhs<LState<S, N>> for Step<'_, T, S, N> {
    #[inline(always)]
    fn rhs(&self, x: &LState<S, N>, stage: Stage) -> LState<S, N> {
        let force = match stage {
            Stage::Middle => self.middle,
            Stage::End => self.end,
        };
        rhs(self.sec, self.gj, x, force)
    }
}

/// RK4 across one section (the force varies linearly along it), the orientation and
/// the relative angles put back on the unit sphere and circle after every step. With
/// `trace`, the position after every step is handed to it.
fn section<T: Real, S: Num<T>, const N: usize>(
    sec: &Section<T, N>,
    ctx: &Ctx<T, S, N>,
    st: &mut LState<S, N>,
    trace: &mut impl FnMut(&LState<S, N>),
) {
    let len = sec.end - sec.start;
    let n = steps(len, sec.h);
    let h = len / nalgebra::convert::<f64, T>(n as f64);
    let half = h * c(0.5);
    let sixth = h / c(6.0);
    let mut s = sec.start;
    let mut k1 = rhs(sec, &ctx.gj, st, ctx.force(s));
    for i in 0..n {
        let step = Step {
            sec,
            gj: &ctx.gj,
            middle: ctx.force(s + half),
            end: ctx.force(s + h),
        };
        *st = rk4_step(st, &k1, h, half, sixth, &step);
        // back onto the unit sphere / circle
        let nq =
            (st.q[0] * st.q[0] + st.q[1] * st.q[1] + st.q[2] * st.q[2] + st.q[3] * st.q[3]).sqrt();
        let inv = S::cst(T::one()) / nq;
        for v in st.q.iter_mut() {
            *v = *v * inv;
        }
        for j in 0..N - 1 {
            let nz = (st.z[j][0] * st.z[j][0] + st.z[j][1] * st.z[j][1]).sqrt();
            let inv = S::cst(T::one()) / nz;
            st.z[j] = [st.z[j][0] * inv, st.z[j][1] * inv];
        }
        trace(st);
        s += h;
        // the next step starts where this one ended (first same as last); after the
        // section's last step the next section starts with its own
        if i + 1 < n {
            k1 = rhs(sec, &ctx.gj, st, step.end);
        }
    }
}

/// The unknowns of a loaded solve: base twists `x[..N-1]`, base moment `x[N-1..N+2]` (W).
pub(crate) type Unknowns<S> = [S; MAX_UNKNOWNS];

/// Integrates from the guide exit to the tip for the unknowns `x`; returns the
/// residuals (free-tip twists, then the tip moment error) and the final state.
pub(crate) fn pass<T: Real, S: Num<T>, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    ctx: &Ctx<T, S, N>,
    x: &Unknowns<S>,
    mut trace: impl FnMut(&LState<S, N>),
) -> (Unknowns<S>, LState<S, N>) {
    let zero = S::cst(T::zero());
    let m0 = [x[N - 1], x[N], x[N + 1]];
    let present = present_at_exit(sections);
    let inp = Inputs {
        s: q.s_mm.map(S::cst),
        theta: q.theta_rad.map(S::cst),
        x: core::array::from_fn(|j| if j < N - 1 { x[j] } else { zero }),
        ei: [T::zero(); N],
        gj: ctx.gj,
        k: [T::zero(); N],
    };
    let exit = guide_exit(robot, &inp, &present, m0[2]);
    let psi_n = exit.angle[N - 1];
    let (sh, ch) = (psi_n * c::<T>(0.5)).sin_cos();
    let mut st = LState {
        p: [zero; 3],
        q: [ch, zero, zero, sh],
        m: m0,
        z: [[zero; 2]; N],
        w: inp.x,
    };
    for j in 0..N - 1 {
        let (s, co) = (exit.angle[j] - psi_n).sin_cos();
        st.z[j] = [co, s];
    }
    st.z[N - 1] = [S::cst(T::one()), zero];
    trace(&st);
    let mut r = [zero; MAX_UNKNOWNS];
    let mut done = [false; N];
    let mut record = |st: &LState<S, N>, at: T, r: &mut Unknowns<S>| {
        for j in 0..N - 1 {
            if !done[j] && q.s_mm[j] <= at {
                done[j] = true;
                r[j] = st.w[j];
            }
        }
    };
    record(&st, T::zero(), &mut r);
    for sec in sections.list.iter().take(sections.len) {
        section(sec, ctx, &mut st, &mut trace);
        record(&st, sec.end, &mut r);
    }
    record(&st, T::max_value().unwrap_or(T::one()), &mut r);
    for i in 0..3 {
        r[N - 1 + i] = st.m[i] - ctx.tip_moment[i];
    }
    (r, st)
}

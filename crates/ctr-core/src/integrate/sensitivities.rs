//! The twist equations with their sensitivities to `K` directions in the unknowns and
//! the joints at once: the variational equations of [`super::variations`] on `K`
//! columns, seeded at the guide exit and at the cuts a feed moves.
//!
//! A column `k` is a direction `(dx, ds, dtheta)` of the unknowns `x` (base twist rates,
//! rad/mm), the feeds (mm) and the rotations (rad). Its state is `(beta_jk, omega_jk)`,
//! the derivatives of the relative angles `b_j` and twist rates `u_j` along it, which
//! obey the same linear equations for every column (see [`super::variations`]). The
//! joints enter in two places (the boundary conditions of [`super::pass`]):
//!
//! - at the guide exit, `psi_i(0) = theta_i + (length_i - s_i) u_i(0)`, so a column
//!   starts with `d psi_i = dtheta_i + (length_i - s_i) du_i(0) - ds_i u_i(0)` and
//!   `beta_j = d psi_j - d psi_n`, `omega_j = dx_j` (tube n's twist from the torque
//!   balance);
//! - a feed moves the cuts of its tube (its tip and the start of its curve): a cut at
//!   `c` between sections A and B that moves by `dc` integrates A's equations instead of
//!   B's over `dc`, so the state beyond it changes by `(f_A - f_B) dc` (Leibniz's rule),
//!   added to the column where the cut is crossed. Where the cut is tube j's own tip,
//!   that is also the change of its free-tip residual `u_j(s_j)`, which is recorded
//!   there (`f_B` is zero for a tube that ends).
//!
//! These are derivatives of the exact twist equations integrated by the solver's RK4
//! steps, not exact derivatives of the discrete map (as the dual numbers of
//! [`crate::solve::jacobian`] are): the two differ by the discretisation error
//! (`tests/softest.rs` finds the softest mode's gradient within 2.2e-4 of central
//! differences of solves on the shared robots). In exchange a column costs about a third
//! of a dual direction's work (the angle's sensitivity carried once, the stiffnesses
//! plain: on nitinol3 a pass of 7 columns is about 10k instructions, one of 7 dual
//! directions 23k).

use super::pass::{guide_exit, present_at_exit, values_at, Setup};
use super::pose::NoPose;
use super::twist::{rotate_angles, section, Inputs, TwistOde, TwistSection, TwistState};
use super::OdeState;
use crate::model::joints::Joints;
use crate::model::robot::Robot;
use crate::real::Real;

/// The `K` directions of a sensitivity pass: entry `[i][k]` is how much the unknown
/// `x_i` (rad/mm; `i < N - 1`), the feed `s_i` (mm) or the rotation `theta_i` (rad)
/// moves along column `k`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Seeds<T, const N: usize, const K: usize> {
    pub x: [[T; K]; N],
    pub s: [[T; K]; N],
    pub theta: [[T; K]; N],
}

impl<T: Real, const N: usize, const K: usize> Seeds<T, N, K> {
    /// No direction moves anything.
    pub fn zero() -> Self {
        Seeds {
            x: [[T::zero(); K]; N],
            s: [[T::zero(); K]; N],
            theta: [[T::zero(); K]; N],
        }
    }
}

/// Twist values and their sensitivities along `K` columns.
#[derive(Clone, Copy)]
pub(crate) struct Sensitivities<T, const N: usize, const K: usize> {
    pub v: TwistState<T, N>,
    /// `d b_j / d column k`
    pub db: [[T; K]; N],
    /// `d u_j / d column k`
    pub dw: [[T; K]; N],
}

impl<T: Real, const N: usize, const K: usize> OdeState<T> for Sensitivities<T, N, K> {
    #[inline(always)]
    fn zip_with<const M: usize>(&mut self, k: [&Self; M], f: impl Fn(T, [T; M]) -> T) {
        for j in 0..N - 1 {
            for cc in 0..2 {
                self.v.z[j][cc] = f(self.v.z[j][cc], k.map(|x| x.v.z[j][cc]));
            }
            self.v.w[j] = f(self.v.w[j], k.map(|x| x.v.w[j]));
            for m in 0..K {
                self.db[j][m] = f(self.db[j][m], k.map(|x| x.db[j][m]));
                self.dw[j][m] = f(self.dw[j][m], k.map(|x| x.dw[j][m]));
            }
        }
    }
}

/// Tube n's twist sensitivities from the conservation of torque.
#[inline(always)]
fn inner_sensitivity<T: Real, const N: usize, const K: usize>(
    sec: &TwistSection<T, T, T, N>,
    dw: &[[T; K]; N],
) -> [T; K] {
    let mut dun = [T::zero(); K];
    for j in 0..N - 1 {
        if sec.present[j] {
            for k in 0..K {
                dun[k] -= sec.gj[j] * dw[j][k];
            }
        }
    }
    for d in dun.iter_mut() {
        *d *= sec.inv_gj_n;
    }
    dun
}

impl<T: Real, const N: usize, const K: usize> TwistOde<T, T, T, N> for Sensitivities<T, N, K> {
    #[inline(always)]
    fn values(&self) -> &TwistState<T, N> {
        &self.v
    }
    #[inline(always)]
    fn values_mut(&mut self) -> &mut TwistState<T, N> {
        &mut self.v
    }
    #[inline(always)]
    fn rhs(&self, sec: &TwistSection<T, T, T, N>) -> Self {
        let v = sec.rhs(&self.v);
        let mut d = Sensitivities {
            v,
            db: [[T::zero(); K]; N],
            dw: [[T::zero(); K]; N],
        };
        let dun = inner_sensitivity(sec, &self.dw);
        for j in 0..N - 1 {
            if !sec.present[j] {
                continue;
            }
            for k in 0..K {
                d.db[j][k] = self.dw[j][k] - dun[k];
            }
            if !sec.curved_g[j] {
                continue;
            }
            let [cj, sj] = self.v.z[j];
            for l in 0..N {
                if l != j && sec.curved_a[l] {
                    let [cl, sl] = self.v.z[l];
                    let gain = sec.g[j] * sec.a[l] * (cj * cl + sj * sl);
                    for k in 0..K {
                        d.dw[j][k] += gain * (self.db[j][k] - self.db[l][k]);
                    }
                }
            }
        }
        d
    }
    #[inline(always)]
    fn rotate(&mut self, sec: &TwistSection<T, T, T, N>, un: T, h: T) {
        let dun = inner_sensitivity(sec, &self.dw);
        rotate_angles(&mut self.v.z, &self.v.w, &sec.present, un, h);
        for j in 0..N - 1 {
            if sec.present[j] {
                for k in 0..K {
                    self.db[j][k] += (self.dw[j][k] - dun[k]) * h;
                }
            }
        }
    }
}

/// The free-tip residuals `u_j(s_j)` and their derivatives along the columns of `seeds`
/// (module doc), `j < N - 1`, at the unknowns `x`: one pass on the full steps of
/// `setup`'s sections (torsion model; clearance and friction moments are not applied).
pub(crate) fn residual_sensitivities<T: Real, const N: usize, const K: usize>(
    setup: &Setup<'_, T, N>,
    x: &[T; N],
    seeds: &Seeds<T, N, K>,
) -> ([T; N], [[T; K]; N]) {
    let robot = setup.robot;
    let q = setup.q;
    let inp = Inputs::plain(robot, q, x);
    let present = present_at_exit(setup.sections);
    let exit = guide_exit(robot, &inp, &present, T::zero());
    let mut st = Sensitivities {
        v: values_at(&exit),
        db: [[T::zero(); K]; N],
        dw: [[T::zero(); K]; N],
    };
    let inv_gj_n = T::one() / inp.gj[N - 1];
    for k in 0..K {
        let mut dun = T::zero();
        for j in 0..N - 1 {
            if present[j] {
                dun -= inp.gj[j] * seeds.x[j][k];
            }
        }
        dun *= inv_gj_n;
        let dpsi = |i: usize| {
            let du = if i < N - 1 { seeds.x[i][k] } else { dun };
            let transmission = robot.tubes()[i].params().length_mm - q.s_mm[i];
            seeds.theta[i][k] + transmission * du - seeds.s[i][k] * exit.twist[i]
        };
        let dpsi_n = dpsi(N - 1);
        for j in 0..N - 1 {
            st.dw[j][k] = seeds.x[j][k];
            st.db[j][k] = dpsi(j) - dpsi_n;
        }
    }
    let mut r = [T::zero(); N];
    let mut dr = [[T::zero(); K]; N];
    let mut recorded = [false; N];
    let mut record = |st: &Sensitivities<T, N, K>, at: T| {
        for j in 0..N - 1 {
            if !recorded[j] && q.s_mm[j] <= at {
                recorded[j] = true;
                r[j] = st.v.w[j];
                dr[j] = st.dw[j];
            }
        }
    };
    record(&st, T::zero());
    let sections = setup.sections;
    let len = sections.len;
    for (i, sec) in sections.list.iter().enumerate().take(len) {
        let a = TwistSection::new(robot, q, &inp, sec, false, inv_gj_n);
        section(&a, &mut st, &mut NoPose);
        if let Some(next) = sections.list.get(i + 1).filter(|_| i + 1 < len) {
            if let Some(moves) = cut_seed(robot, q, sec.end, seeds) {
                let b = TwistSection::new(robot, q, &inp, next, false, inv_gj_n);
                cross(&a, &b, &mut st, &moves);
            }
        }
        record(&st, sec.end);
    }
    record(&st, T::max_value().unwrap_or(T::one()));
    (r, dr)
}

/// How far the cut at `v` moves along each column: that of the feed whose tip or curve
/// start it is (`None`: the guide exit, or a cut no feed moves).
fn cut_seed<T: Real, const N: usize, const K: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    v: T,
    seeds: &Seeds<T, N, K>,
) -> Option<[T; K]> {
    if v == T::zero() {
        return None;
    }
    // as `twist::cut` tells them apart: tips first, then curve starts
    let tube = (0..N).find(|&i| q.s_mm[i] == v).or_else(|| {
        (0..N).find(|&i| q.s_mm[i] - robot.tubes()[i].params().curved_length_mm == v)
    })?;
    Some(seeds.s[tube])
}

/// Adds `(f_A - f_B) dc` to the columns (module doc) where the cut between sections `a`
/// and `b` moves by `moves[k]` along column k.
fn cross<T: Real, const N: usize, const K: usize>(
    a: &TwistSection<T, T, T, N>,
    b: &TwistSection<T, T, T, N>,
    st: &mut Sensitivities<T, N, K>,
    moves: &[T; K],
) {
    let (fa, fb) = (a.rhs(&st.v), b.rhs(&st.v));
    let (una, unb) = (a.inner_twist(&st.v.w), b.inner_twist(&st.v.w));
    for j in 0..N - 1 {
        // d b_j / ds = u_j - u_n where tube j is present, 0 where it has ended
        let angle_rate = |present: bool, un: T| {
            if present {
                st.v.w[j] - un
            } else {
                T::zero()
            }
        };
        let jb = angle_rate(a.present[j], una) - angle_rate(b.present[j], unb);
        let jw = fa.w[j] - fb.w[j];
        for k in 0..K {
            st.db[j][k] += jb * moves[k];
            st.dw[j][k] += jw * moves[k];
        }
    }
}

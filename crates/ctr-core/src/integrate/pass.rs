//! One pass along the backbone of the unloaded model, from the guide exit to the tip:
//! the boundary conditions at the guide exit, the sections in order, the free-tip
//! residuals, the clearance kinks and the boundary friction moments where tubes end.
//! Every unloaded computation is this pass on some numbers and some frame: Newton's
//! residuals (`Variations`, no pose), the pose of a
//! solution (plain numbers, [`Frame`](crate::Frame)), the Jacobians (dual numbers,
//! `Tangents`) and the friction solve (dual numbers).
//!
//! # Boundary conditions (the one place they are written)
//!
//! Behind the guide exit tube i is straight over its transmission `length_i - s_i` and
//! twists uniformly there, so its material angle at the exit is
//! `psi_i(0) = theta_i + (length_i - s_i) u_i(0)`; the unknowns are the base twist
//! rates `u_j(0)`, `j < n`, and tube n's follows from the torque balance,
//! `G J_n u_n(0) = tau_z - sum_{j<n, present} G J_j u_j(0)` (`tau_z` the internal
//! torque about the tangent, zero without loads). Each free tip carries no torque:
//! the residuals are `u_j(s_j)`, `j < n` (minus the friction moment where there is one).

use super::pose::Pose;
use super::twist::{body_rate, section, Inputs, TwistOde, TwistSection, TwistState};
use super::variations::Variations;
use crate::math::dual::Num;
use crate::model::effects::ClearanceProfile;
use crate::model::joints::Joints;
use crate::model::robot::Robot;
use crate::model::sections::{Section, Sections};
use crate::real::Real;
use core::ops::Mul;

/// Which mechanics a pass integrates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Mechanics {
    /// Every tube's angle is its actuator angle: constant curvature per section.
    Rigid,
    /// The twist equations, on the full steps or the coarse steps of a cold start.
    Torsion { coarse: bool },
}

/// The tube twist rates and material angles at the guide exit.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GuideExit<S, const N: usize> {
    /// `u_i(0)`, rad/mm
    pub twist: [S; N],
    /// `psi_i(0)`, rad
    pub angle: [S; N],
}

/// The boundary conditions at the guide exit (module doc) for unknowns `inp.x` and the
/// torque `tau_z` about the tangent there (N mm).
#[inline]
pub(crate) fn guide_exit<T, S, C, const N: usize>(
    robot: &Robot<T, N>,
    inp: &Inputs<S, C, N>,
    present: &[bool; N],
    tau_z: S,
) -> GuideExit<S, N>
where
    T: Real,
    S: Num<T> + Mul<C, Output = S>,
    C: Num<T>,
{
    let mut twist = inp.x;
    let mut torque = tau_z;
    for j in 0..N - 1 {
        if present[j] {
            torque -= inp.x[j] * inp.gj[j];
        }
    }
    twist[N - 1] = torque * (C::cst(T::one()) / inp.gj[N - 1]);
    let angle = core::array::from_fn(|i| {
        inp.theta[i] + (S::cst(robot.tubes()[i].params().length_mm) - inp.s[i]) * twist[i]
    });
    GuideExit { twist, angle }
}

/// The tubes present at the guide exit (none without sections).
pub(crate) fn present_at_exit<T: Real, const N: usize>(sections: &Sections<T, N>) -> [bool; N] {
    if sections.len > 0 {
        sections.list[0].present
    } else {
        [false; N]
    }
}

/// A state that can start a pass: built at the guide exit from the inputs.
pub(crate) trait Start<T, S, C, const N: usize>: TwistOde<T, S, C, N> + Sized {
    /// The state at the guide exit and the boundary values there.
    fn at_guide_exit(
        robot: &Robot<T, N>,
        inp: &Inputs<S, C, N>,
        present: &[bool; N],
    ) -> (Self, GuideExit<S, N>);
    /// The state of the rigid model: no twist, every tube at its actuator angle.
    fn rigid(inp: &Inputs<S, C, N>) -> (Self, GuideExit<S, N>);
    /// What a free tip records: its twist rate (and sensitivities).
    type Tip: Copy;
    /// Tube j's record at its tip.
    fn tip(&self, j: usize) -> Self::Tip;
}

/// The relative angles `(cos, sin)(psi_j - psi_n)` and twists `u_j` at the exit.
pub(crate) fn values_at<T: Real, S: Num<T>, const N: usize>(
    exit: &GuideExit<S, N>,
) -> TwistState<S, N> {
    let zero = S::cst(T::zero());
    let mut st = TwistState {
        z: [[zero; 2]; N],
        w: [zero; N],
    };
    st.z[N - 1] = [S::cst(T::one()), zero];
    for j in 0..N - 1 {
        st.w[j] = exit.twist[j];
        let (s, co) = (exit.angle[j] - exit.angle[N - 1]).sin_cos_wide();
        st.z[j] = [co, s];
    }
    st
}

impl<T, S, C, const N: usize> Start<T, S, C, N> for TwistState<S, N>
where
    T: Real,
    S: Num<T> + Mul<C, Output = S>,
    C: Num<T>,
{
    #[inline]
    fn at_guide_exit(
        robot: &Robot<T, N>,
        inp: &Inputs<S, C, N>,
        present: &[bool; N],
    ) -> (Self, GuideExit<S, N>) {
        let exit = guide_exit(robot, inp, present, S::cst(T::zero()));
        (values_at(&exit), exit)
    }
    fn rigid(inp: &Inputs<S, C, N>) -> (Self, GuideExit<S, N>) {
        let exit = GuideExit {
            twist: [S::cst(T::zero()); N],
            angle: inp.theta,
        };
        (values_at(&exit), exit)
    }
    type Tip = S;
    fn tip(&self, j: usize) -> S {
        self.w[j]
    }
}

impl<T: Real, const N: usize> Start<T, T, T, N> for Variations<T, N> {
    /// The sensitivities at the exit are the variations of [`guide_exit`]:
    /// `d u_j(0) / d x_k = delta_jk`, `d u_n(0) / d x_k = -G J_k / G J_n` (present k),
    /// and `d b_j / d x_k = (length_j - s_j) delta_jk - (length_n - s_n) d u_n / d x_k`.
    #[inline]
    fn at_guide_exit(
        robot: &Robot<T, N>,
        inp: &Inputs<T, T, N>,
        present: &[bool; N],
    ) -> (Self, GuideExit<T, N>) {
        let exit = guide_exit(robot, inp, present, T::zero());
        let mut st = Variations {
            v: values_at(&exit),
            db: [[T::zero(); N]; N],
            dw: [[T::zero(); N]; N],
        };
        let trans = |i: usize| robot.tubes()[i].params().length_mm - inp.s[i];
        let inv = T::one() / inp.gj[N - 1];
        let mut dun = [T::zero(); N];
        for k in 0..N - 1 {
            if present[k] {
                dun[k] = (T::zero() - inp.gj[k]) * inv;
            }
        }
        let trans_n = trans(N - 1);
        for j in 0..N - 1 {
            st.dw[j][j] = T::one();
            for k in 0..N - 1 {
                st.db[j][k] = -trans_n * dun[k];
            }
            st.db[j][j] += trans(j);
        }
        (st, exit)
    }
    fn rigid(inp: &Inputs<T, T, N>) -> (Self, GuideExit<T, N>) {
        let (v, exit) = TwistState::rigid(inp);
        let st = Variations {
            v,
            db: [[T::zero(); N]; N],
            dw: [[T::zero(); N]; N],
        };
        (st, exit)
    }
    type Tip = (T, [T; N]);
    fn tip(&self, j: usize) -> (T, [T; N]) {
        (self.v.w[j], self.dw[j])
    }
}

/// What a pass needs besides its numbers.
#[derive(Clone, Copy)]
pub(crate) struct Setup<'a, T: Real, const N: usize> {
    pub robot: &'a Robot<T, N>,
    /// The (actual) joints as plain numbers: where the tips and cuts are.
    pub q: &'a Joints<T, N>,
    pub sections: &'a Sections<T, N>,
    pub mechanics: Mechanics,
    /// Clearance kink of each pair (entry i: tube i+1 leaving tube i), applied where the
    /// pass moves a frame.
    pub clearance: Option<&'a [Option<ClearanceProfile<T>>; N]>,
    /// Boundary friction moment coefficient `mu'_j sigma_j` of each pair (see
    /// [`crate::friction::BoundaryMoment`]). Its effect on the values is applied, not on
    /// [`Variations`]' sensitivities: a pass with friction runs on plain or dual numbers.
    pub friction: Option<&'a [T; N]>,
}

/// The result of a pass.
pub(crate) struct Pass<R, F, S, const N: usize> {
    /// Tube j's record at its tip, `j < N - 1` (`None` for the rigid model).
    pub tips: [Option<R>; N],
    /// The tip frame, moved from the frame given (the world frame) by the pass.
    pub frame: F,
    /// The boundary values at the guide exit.
    pub exit: GuideExit<S, N>,
}

/// Integrates from the guide exit to the tip for the inputs `inp`, moving `frame`.
pub(crate) fn run<T, S, C, St, F, const N: usize>(
    setup: &Setup<'_, T, N>,
    inp: &Inputs<S, C, N>,
    mut frame: F,
) -> Pass<St::Tip, F, S, N>
where
    T: Real,
    S: Num<T> + Mul<C, Output = S>,
    C: Num<T>,
    St: Start<T, S, C, N>,
    F: Pose<T, S>,
{
    let present = present_at_exit(setup.sections);
    let torsion = matches!(setup.mechanics, Mechanics::Torsion { .. });
    let (mut st, exit) = if torsion {
        St::at_guide_exit(setup.robot, inp, &present)
    } else {
        // the rigid model: no twist, every tube at its actuator angle
        St::rigid(inp)
    };
    if F::MOVES {
        let (s, co) = exit.angle[N - 1].sin_cos_wide();
        frame.rotate_z(co, s);
        frame.mark();
    }
    let mut tips = [None; N];
    let q = setup.q;
    let record = |st: &St, at: T, tips: &mut [Option<St::Tip>; N]| {
        for j in 0..N - 1 {
            if tips[j].is_none() && q.s_mm[j] <= at {
                tips[j] = Some(st.tip(j));
            }
        }
    };
    let mut kinked = [false; N];
    if torsion {
        record(&st, T::zero(), &mut tips);
    }
    let clearance = setup.clearance.filter(|_| F::MOVES);
    if let Some(c) = clearance {
        kinks(q, c, st.values(), T::zero(), &mut kinked, &mut frame);
    }
    let coarse = matches!(setup.mechanics, Mechanics::Torsion { coarse: true });
    let inv_gj_n = C::cst(T::one()) / inp.gj[N - 1];
    for sec in setup.sections.list.iter().take(setup.sections.len) {
        if torsion {
            let g = TwistSection::new(setup.robot, q, inp, sec, coarse, inv_gj_n);
            section(&g, &mut st, &mut frame);
            if let Some(coefficient) = setup.friction {
                boundary_moments(q, inp, &g, sec.end, coefficient, &tips, st.values_mut());
            }
            record(&st, sec.end, &mut tips);
        } else if F::MOVES {
            rigid_section(setup, inp, sec, st.values(), &mut frame);
        }
        if let Some(c) = clearance {
            kinks(q, c, st.values(), sec.end, &mut kinked, &mut frame);
        }
    }
    if torsion {
        record(&st, T::max_value().unwrap_or(T::one()), &mut tips);
    }
    Pass { tips, frame, exit }
}

/// A section of the rigid model: constant curvature, one exponential (cut into steps of
/// the RK4 length where the frame traces points).
fn rigid_section<T, S, C, F, const N: usize>(
    setup: &Setup<'_, T, N>,
    inp: &Inputs<S, C, N>,
    sec: &Section<T, N>,
    st: &TwistState<S, N>,
    frame: &mut F,
) where
    T: Real,
    S: Num<T> + Mul<C, Output = S>,
    C: Num<T>,
    F: Pose<T, S>,
{
    let zero = S::cst(T::zero());
    let (len, rate) = if !S::DUAL && !C::DUAL {
        // plain numbers: the section's own coefficients
        let a = sec.a.map(C::cst);
        let len = S::cst(sec.end - sec.start);
        (len, body_rate(&a, &sec.curved_a, &st.z, zero, false))
    } else {
        let g = TwistSection::new(setup.robot, setup.q, inp, sec, false, inp.gj[N - 1]);
        (g.len, g.body_rate(&st.z, zero, false))
    };
    let sub = if frame.traces() {
        super::steps(len.re(), sec.h)
    } else {
        1
    };
    let h = if sub == 1 {
        len
    } else {
        len / S::cst(nalgebra::convert(sub as f64))
    };
    for _ in 0..sub {
        frame.step(rate.map(|v| v * h), [zero, zero, h]);
        frame.mark();
    }
}

/// Applies the clearance kinks of the tubes whose tips lie at `at` (where the next
/// tube leaves them).
fn kinks<T, S, F, const N: usize>(
    q: &Joints<T, N>,
    clearance: &[Option<ClearanceProfile<T>>; N],
    st: &TwistState<S, N>,
    at: T,
    kinked: &mut [bool; N],
    frame: &mut F,
) where
    T: Real,
    S: Num<T>,
    F: Pose<T, S>,
{
    for i in 0..N - 1 {
        if kinked[i] || q.s_mm[i] > at {
            continue;
        }
        kinked[i] = true;
        if let Some(profile) = &clearance[i] {
            if q.s_mm[i + 1] > q.s_mm[i] {
                kink(frame, profile, st.z[i], st.z[i + 1]);
            }
        }
    }
}

/// The seed's boundary friction moment (see [`crate::friction`]) at the tips that end
/// the section just integrated: tube j's tip carries `tau_j = coefficient_j |M_j|`
/// (`M_j` the bending moment tube j carries there), so its residual is
/// `u_j(s_j) - tau_j / G J_j`; the neighbour j+1 takes `-tau_j`, which raises its
/// twist rate by `tau_j / G J_{j+1}` (the innermost tube's follows from the torque
/// balance by itself). Tube j's twist past its own tip is never used again, so it
/// takes the residual, which the pass's record then keeps.
fn boundary_moments<T, S, C, R, const N: usize>(
    q: &Joints<T, N>,
    inp: &Inputs<S, C, N>,
    g: &TwistSection<T, S, C, N>,
    end: T,
    coefficient: &[T; N],
    tips: &[Option<R>; N],
    st: &mut TwistState<S, N>,
) where
    T: Real,
    S: Num<T> + Mul<C, Output = S>,
    C: Num<T>,
{
    for j in 0..N - 1 {
        if tips[j].is_some() || q.s_mm[j] > end || coefficient[j] == T::zero() {
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

/// Applies the clearance kink of a pair (the inner tube leaving the outer one's tip)
/// to tube n's frame, given the relative angles `(cos, sin)` of the outer (`zi`) and
/// inner (`zj`) tube to tube n: a turn by `delta(phi)` about the inner tube's body y
/// axis, `phi = b_j - b_i` (plain or dual numbers; `frame` any [`Pose`]).
#[inline]
pub(crate) fn kink<T: Real, S: Num<T>, F: Pose<T, S>>(
    frame: &mut F,
    profile: &ClearanceProfile<T>,
    zi: [S; 2],
    zj: [S; 2],
) {
    let cos_phi = zj[0] * zi[0] + zj[1] * zi[1];
    let sin_phi = zj[1] * zi[0] - zj[0] * zi[1];
    let delta = profile.deflection_cs(cos_phi, sin_phi);
    if !S::DUAL && delta.re() == T::zero() {
        return;
    }
    let (s, co) = delta.sin_cos_wide();
    frame.rotate_z(zj[0], zj[1]);
    frame.rotate_y(co, s);
    frame.rotate_z(zj[0], -zj[1]);
}

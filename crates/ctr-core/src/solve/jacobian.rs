//! Jacobians of the tip pose: with respect to the joints, to model parameters, and to tip
//! loads (the compliance matrix), from integrated sensitivities (no finite differences).
//!
//! # Method
//!
//! A converged solve leaves the shooting unknowns `x` (the base twist rates `u_j(0)`,
//! `j < n`) where the free-tip residuals vanish, `R(x, p) = 0` with `R_j = u_j(s_j)`
//! ([`crate::integrate::twist`]), and gives the tip pose `P(x, p)`, where `p` are the
//! joints (or the model parameters). One more integration runs in forward-mode dual
//! numbers ([`crate::math::dual`]) with `x` and `p` as derivative directions: the
//! integrator is the
//! solver's own discrete map (same sections, RK4 steps, closed-form single-curve
//! sections, Magnus pose steps, SE(3) exponentials), so its derivatives are exact
//! derivatives of what [`Solver::solve`](crate::Solver::solve) computes. The twist state
//! is carried as dual numbers; the frame is carried plain, with one spatial twist per
//! direction updated by the exponential's left Jacobian at each step
//! ([`crate::integrate::pose`] derives it): the same
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
//! The same pass carries the clearance kinks (differentiated through the relative
//! angle they depend on) and the boundary friction moments (whose residuals then enter
//! `R`). Where the shooting Jacobian `R_x` is singular (a snap: the stability margin is
//! 0) the pose has no derivative and the entries are NaN. A configuration where two
//! cuts coincide (e.g. `s_i = s_j - curved_length_j`), or where a clearance table has a
//! corner, is a kink of the forward kinematics; there the one-sided derivative of one
//! side is returned.

use crate::integrate::pass::{run, Setup};
use crate::integrate::pose::Tangents;
use crate::integrate::twist::{Inputs, TwistState};
use crate::math::dual::{Dual, Num};
use crate::math::linalg::{solve_linear, V3};
use crate::real::{c, Real};
use crate::solve::Model;
use nalgebra::Vector6;

/// Not a number, in `T`: marks entries that have no value.
fn nan<T: Real>() -> T {
    c(f64::NAN)
}

/// Most columns of one derivative pass: two joints and three parameters per tube (see
/// [`JointJacobian`], [`ParameterJacobian`]).
const MAX_COLUMNS: usize = 5 * crate::MAX_TUBES;

/// d(tip pose)/d(joints) at a solution: one 6-vector column per joint.
///
/// Each column is `(dp_x, dp_y, dp_z, omega_x, omega_y, omega_z)` in W: the tip
/// position's derivative (mm per mm of feed, mm per rad of rotation) and the tip frame's
/// spatial angular velocity per unit joint rate (rad per mm, rad per rad). As a 6 x 2N
/// matrix the feeds come first: column `i` is `s_i`, column `N + i` is `theta_i`.
///
/// ```
/// use ctr_core::{JointJacobian, Joints, Model, Request, Robot, Solver, TubeParams};
/// // one straight tube: feeding moves the tip along z, turning it spins the tip about z
/// let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
/// let mut jac = JointJacobian::nan();
/// Solver::default().solve(&robot, Request::new(Joints::new([50.0], [0.3]), Model::Torsion).joint_jacobian(&mut jac)).unwrap();
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
    /// Every entry NaN: a buffer for [`Request::joint_jacobian`](crate::Request::joint_jacobian)
    /// that shows what a solve did not write.
    ///
    /// ```
    /// assert!(ctr_core::JointJacobian::<f64, 2>::nan().feed[1][5].is_nan());
    /// ```
    pub fn nan() -> Self {
        let none = Vector6::from_element(nan::<T>());
        JointJacobian {
            feed: [none; N],
            rotation: [none; N],
        }
    }

    /// Column `j` of the 6 x 2N matrix (`s_j` for `j < N`, else `theta_{j-N}`);
    /// `None` past the last column.
    ///
    /// ```
    /// # use ctr_core::{JointJacobian, Joints, Model, Request, Robot, Solver, TubeParams};
    /// # let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// let mut jac = JointJacobian::nan();
    /// Solver::default().solve(&robot, Request::new(Joints::new([50.0], [0.0]), Model::Rigid).joint_jacobian(&mut jac)).unwrap();
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
    /// # use ctr_core::{JointJacobian, Joints, Model, Request, Robot, Solver, TubeParams};
    /// # let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)]).unwrap();
    /// let mut jac = JointJacobian::nan();
    /// Solver::default().solve(&robot, Request::new(Joints::new([50.0], [0.0]), Model::Rigid).joint_jacobian(&mut jac)).unwrap();
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
/// precurvature `k_i`. The `stiffness` effect of [`crate::Robot::scaled`] (both stiffnesses) is
/// the sum of the first two columns; its radius factor is minus the curvature column.
///
/// ```
/// use ctr_core::{Joints, Model, ParameterJacobian, Request, Robot, Solver, TubeParams};
/// let robot = Robot::new([TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) }]).unwrap();
/// let mut jac = ParameterJacobian::nan();
/// Solver::default().solve(&robot, Request::new(Joints::new([50.0], [0.0]), Model::Torsion).parameter_jacobian(&mut jac)).unwrap();
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

impl<T: Real, const N: usize> ParameterJacobian<T, N> {
    /// Every column: the bending stiffness's, the torsional stiffness's, then the
    /// curvature's, tube 1 first.
    pub(crate) fn columns_mut(&mut self) -> impl Iterator<Item = &mut Vector6<T>> {
        self.bending_stiffness
            .iter_mut()
            .chain(self.torsional_stiffness.iter_mut())
            .chain(self.curvature.iter_mut())
    }

    /// Every entry NaN (see [`JointJacobian::nan`]).
    ///
    /// ```
    /// assert!(ctr_core::ParameterJacobian::<f64, 1>::nan().curvature[0][0].is_nan());
    /// ```
    pub fn nan() -> Self {
        let none = Vector6::from_element(nan::<T>());
        ParameterJacobian {
            bending_stiffness: [none; N],
            torsional_stiffness: [none; N],
            curvature: [none; N],
        }
    }
}

/// Which derivative directions a pass seeds after the shooting unknowns.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Wrt {
    /// `s_0..s_{N-1}`, then `theta_0..theta_{N-2}` (the last rotation's column follows
    /// from the others, see [`pass`])
    Joints,
    /// bending stiffness scales, torsional stiffness scales, curvature scales
    Parameters,
    /// the joints' directions, then the parameters'
    Both,
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
    setup: &Setup<'_, T, N>,
    x: &[T; N],
    model: Model,
    wrt: Wrt,
) -> [Vector6<T>; MAX_COLUMNS] {
    let m = if model == Model::Torsion { N - 1 } else { 0 };
    let plain = Inputs::plain(setup.robot, setup.q, x);
    let dual = |a: &[T; N]| a.map(Dual::<T, K>::cst);
    let seed_x = |xs: &mut [Dual<T, K>; N]| {
        for j in 0..m {
            xs[j] = Dual::var(x[j], j);
        }
    };
    let residuals =
        |tips: &[Option<Dual<T, K>>; N]| tips.map(|t| t.unwrap_or(Dual::cst(T::zero())));
    // the unknowns, then the feeds and all rotations but the last (see `last_rotation`)
    let seed_joints =
        |xs: &mut [Dual<T, K>; N], s: &mut [Dual<T, K>; N], th: &mut [Dual<T, K>; N]| {
            seed_x(xs);
            for i in 0..N {
                s[i] = Dual::var(plain.s[i], m + i);
            }
            for i in 0..N - 1 {
                th[i] = Dual::var(plain.theta[i], m + N + i);
            }
        };
    // every input dual, the parameters' scales seeded from direction `at` on
    // (d/d(scale) at scale 1 is the value itself)
    let with_scales = |at: usize| {
        let mut inp = Inputs {
            s: dual(&plain.s),
            theta: dual(&plain.theta),
            x: dual(&plain.x),
            ei: dual(&plain.ei),
            gj: dual(&plain.gj),
            k: dual(&plain.k),
        };
        for i in 0..N {
            inp.ei[i] = seeded(plain.ei[i], at + i, plain.ei[i]);
            inp.gj[i] = seeded(plain.gj[i], at + N + i, plain.gj[i]);
            inp.k[i] = seeded(plain.k[i], at + 2 * N + i, plain.k[i]);
        }
        inp
    };
    match wrt {
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
            seed_joints(&mut inp.x, &mut inp.s, &mut inp.theta);
            let pass = run::<T, _, T, TwistState<_, N>, _, N>(setup, &inp, Tangents::identity());
            let tangent = pass.frame.columns();
            let mut cols =
                implicit_columns::<T, N, K>(&residuals(&pass.tips), &tangent, m, 2 * N - 1);
            last_rotation::<T, N>(&mut cols, &pass.frame.p);
            cols
        }
        Wrt::Both => {
            // the parameters after the joints' 2 N - 1 directions
            let mut inp = with_scales(m + 2 * N - 1);
            seed_joints(&mut inp.x, &mut inp.s, &mut inp.theta);
            let pass = run::<T, _, _, TwistState<_, N>, _, N>(setup, &inp, Tangents::identity());
            let tangent = pass.frame.columns();
            let found = implicit_columns::<T, N, K>(&residuals(&pass.tips), &tangent, m, 5 * N - 1);
            // the joints' 2 N columns (the last rotation from the others), then the
            // parameters' 3 N
            let mut cols = [Vector6::from_element(nan::<T>()); MAX_COLUMNS];
            cols[..2 * N - 1].copy_from_slice(&found[..2 * N - 1]);
            last_rotation::<T, N>(&mut cols, &pass.frame.p);
            cols[2 * N..5 * N].copy_from_slice(&found[2 * N - 1..5 * N - 1]);
            cols
        }
        Wrt::Parameters => {
            let mut inp = with_scales(m);
            seed_x(&mut inp.x);
            let pass = run::<T, _, _, TwistState<_, N>, _, N>(setup, &inp, Tangents::identity());
            implicit_columns::<T, N, K>(&residuals(&pass.tips), &pass.frame.columns(), m, 3 * N)
        }
    }
}

/// Completes the joint columns `cols` (feeds, then `N - 1` rotations) with the last
/// rotation's, the tip at `p`. Turning every tube by the same angle turns the whole
/// robot about W's z axis (the model is exactly invariant, kinks and friction moments
/// included: they depend on relative angles), so the rotation columns sum to
/// `(e_z x p, e_z)`: the last one follows from the others.
fn last_rotation<T: Real, const N: usize>(cols: &mut [Vector6<T>; MAX_COLUMNS], p: &V3<T>) {
    let mut last = Vector6::new(-p[1], p[0], T::zero(), T::zero(), T::zero(), T::one());
    for i in 0..N - 1 {
        last -= cols[N + i];
    }
    cols[2 * N - 1] = last;
}

/// Runs [`pass`] with the fewest directions `K` that hold `m + columns` (`N` is a
/// constant, so only one arm survives optimisation); NaN columns where none does.
fn dispatch<T: Real, const N: usize>(
    setup: &Setup<'_, T, N>,
    x: &[T; N],
    model: Model,
    wrt: Wrt,
) -> [Vector6<T>; MAX_COLUMNS] {
    let columns = match wrt {
        Wrt::Joints => 2 * N - 1,
        Wrt::Parameters => 3 * N,
        Wrt::Both => 5 * N - 1,
    };
    let needed = (N - 1) + columns;
    macro_rules! run {
        ($($k:literal),*) => {
            $(if needed <= $k {
                return pass::<T, N, $k>(setup, x, model, wrt);
            })*
        };
    }
    run!(1, 3, 4, 7, 10, 11, 15, 16);
    [Vector6::from_element(nan::<T>()); MAX_COLUMNS]
}

/// The [`JointJacobian`] of the tip of `setup` (its kinks and friction moments
/// included) at the solution with base twists `x`. Allocation-free; NaN where the
/// shooting Jacobian is singular (a snap).
pub(crate) fn joints<T: Real, const N: usize>(
    setup: &Setup<'_, T, N>,
    x: &[T; N],
    model: Model,
    jac: &mut JointJacobian<T, N>,
) {
    let cols = dispatch(setup, x, model, Wrt::Joints);
    // zipped copies: no slice lengths to check, no panic path
    for (d, s) in jac
        .feed
        .iter_mut()
        .chain(jac.rotation.iter_mut())
        .zip(cols.iter())
    {
        *d = *s;
    }
}

/// The [`JointJacobian`] and the [`ParameterJacobian`] of the tip of `setup` at the
/// solution with base twists `x`: one pass where its directions fit [`dispatch`]'s
/// widths (up to three tubes), else each alone.
pub(crate) fn both<T: Real, const N: usize>(
    setup: &Setup<'_, T, N>,
    x: &[T; N],
    model: Model,
    joint: &mut JointJacobian<T, N>,
    parameter: &mut ParameterJacobian<T, N>,
) {
    // dispatch's count of directions
    if (N - 1) + 5 * N - 1 > WIDEST {
        joints(setup, x, model, joint);
        parameters(setup, x, model, parameter);
        return;
    }
    let cols = dispatch(setup, x, model, Wrt::Both);
    let targets = joint
        .feed
        .iter_mut()
        .chain(joint.rotation.iter_mut())
        .chain(parameter.columns_mut());
    for (d, s) in targets.zip(cols.iter()) {
        *d = *s;
    }
}

/// The widest derivative pass [`dispatch`] runs, in directions.
const WIDEST: usize = 16;

/// The [`ParameterJacobian`] of the tip of `setup` at the solution with base twists `x`.
pub(crate) fn parameters<T: Real, const N: usize>(
    setup: &Setup<'_, T, N>,
    x: &[T; N],
    model: Model,
    jac: &mut ParameterJacobian<T, N>,
) {
    let cols = dispatch(setup, x, model, Wrt::Parameters);
    for (d, s) in jac.columns_mut().zip(cols.iter()) {
        *d = *s;
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::pass::Mechanics;
    use crate::integrate::pose::Pose;
    use crate::math::linalg::{mat_mul, M3, V3};
    use crate::math::se3::exp_of;
    use crate::model::sections::Sections;
    use crate::{Joints, Request, Robot, Solver};

    /// A frame carried entry by entry in dual numbers: the plain way to differentiate
    /// the pose, which [`Tangents`] replaces.
    #[derive(Clone, Copy)]
    struct DualFrame<const K: usize> {
        r: M3<Dual<f64, K>>,
        p: V3<Dual<f64, K>>,
    }

    impl<const K: usize> Pose<f64, Dual<f64, K>> for DualFrame<K> {
        fn step(&mut self, w: V3<Dual<f64, K>>, v: V3<Dual<f64, K>>) {
            let (r, p) = exp_of(w, v);
            let m = self.r;
            for i in 0..3 {
                self.p[i] = self.p[i] + m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2];
            }
            self.r = mat_mul(&m, &r);
        }
        fn rotate_z(&mut self, co: Dual<f64, K>, si: Dual<f64, K>) {
            for row in self.r.iter_mut() {
                let (x, y) = (row[0], row[1]);
                row[0] = x * co + y * si;
                row[1] = y * co - x * si;
            }
        }
        fn rotate_y(&mut self, co: Dual<f64, K>, si: Dual<f64, K>) {
            for row in self.r.iter_mut() {
                let (x, z) = (row[0], row[2]);
                row[0] = x * co - z * si;
                row[2] = x * si + z * co;
            }
        }
        fn advance(&mut self, h: Dual<f64, K>) {
            for i in 0..3 {
                self.p[i] += self.r[i][2] * h;
            }
        }
    }

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

    fn sections(robot: &Robot<f64, 3>, q: &Joints<f64, 3>) -> Sections<f64, 3> {
        let cfg = crate::SolverConfig::<f64>::default();
        let k = robot.each(|t| t.curvature_per_mm());
        Sections::new(robot, &q.s_mm, &k, cfg.max_step_mm, cfg.step_fraction)
    }

    /// The spatial-twist derivatives ([`Tangents`]) equal the derivatives of the frame
    /// carried entry by entry in dual numbers, in both the series and the closed-form
    /// branches of the exponential (rigid sections turn by more than 0.3 rad).
    #[test]
    fn tangents_equal_dual_frames() {
        let (robot, q) = three_tubes(40.0);
        let sections = sections(&robot, &q);
        let sol = Solver::default()
            .solve(&robot, Request::new(q, Model::Torsion))
            .unwrap();
        let mut inp = Inputs {
            s: q.s_mm.map(Dual::<f64, 7>::cst),
            theta: q.theta_rad.map(Dual::cst),
            x: sol.base_twist_per_mm.map(Dual::cst),
            ei: robot.each(|t| t.bending_stiffness_nmm2()),
            gj: robot.each(|t| t.torsional_stiffness_nmm2()),
            k: robot.each(|t| t.curvature_per_mm()),
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
        for mechanics in [Mechanics::Rigid, Mechanics::Torsion { coarse: false }] {
            let setup = Setup {
                robot: &robot,
                q: &q,
                sections: &sections,
                mechanics,
                clearance: None,
                friction: None,
            };
            let zero = Dual::cst(0.0);
            let one = Dual::cst(1.0);
            let frame = DualFrame {
                r: [[one, zero, zero], [zero, one, zero], [zero, zero, one]],
                p: [zero; 3],
            };
            let a = run::<f64, _, f64, TwistState<_, 3>, _, 3>(&setup, &inp, frame);
            let b = run::<f64, _, f64, TwistState<_, 3>, _, 3>(
                &setup,
                &inp,
                Tangents::<f64, 7>::identity(),
            );
            let want = crate::integrate::pose::columns_of_duals(&a.frame.p, &a.frame.r);
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

    /// The pass on dual numbers carries the plain numbers of the solver's own pose pass.
    #[test]
    fn dual_pass_carries_the_solution() {
        let (robot, q) = three_tubes(80.0);
        let sections = sections(&robot, &q);
        for model in [Model::Rigid, Model::Torsion] {
            let sol = Solver::default()
                .solve(&robot, Request::new(q, model))
                .unwrap();
            let setup = Setup {
                robot: &robot,
                q: &q,
                sections: &sections,
                mechanics: match model {
                    Model::Rigid => Mechanics::Rigid,
                    Model::Torsion => Mechanics::Torsion { coarse: false },
                },
                clearance: None,
                friction: None,
            };
            let plain = Inputs::plain(&robot, &q, &sol.base_twist_per_mm);
            let inp = Inputs {
                s: plain.s.map(Dual::<f64, 2>::cst),
                theta: plain.theta.map(Dual::cst),
                x: plain.x.map(Dual::cst),
                ei: plain.ei,
                gj: plain.gj,
                k: plain.k,
            };
            let out = run::<f64, _, f64, TwistState<_, 3>, _, 3>(
                &setup,
                &inp,
                Tangents::<f64, 2>::identity(),
            );
            for i in 0..3 {
                assert!((out.frame.p[i] - sol.tip.position[i]).abs() < 1e-12);
                for j in 0..3 {
                    assert!((out.frame.r[i][j] - sol.tip.rotation[(i, j)]).abs() < 1e-13);
                }
            }
            for j in 0..2 {
                assert!(out.tips[j].map_or(0.0, |t| t.re).abs() <= 1e-12);
            }
        }
    }
}

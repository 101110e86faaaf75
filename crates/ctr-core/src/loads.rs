//! External loads: the tubes' weight, a tip force and a tip moment (Cosserat statics).
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
//! [`crate::twist`] is the case `m = 0`.) The weight per length of tube i on its
//! exposed part is `f_i = rho_i A_i g` (kg/m^3 x mm^2 x m/s^2 x 1e-9 = N/mm); the guide
//! holds everything behind `s = 0`. Boundary conditions: the transmissions twist as in
//! the unloaded model, the free tips carry no torque `u_j(s_j) = 0`, and the tip moment
//! is `m(s_n) = M_tip`. The unknowns are the base twists `u_j(0)` (`j < n`) and the base
//! moment `m(0)` (W), `n + 2` in all, solved by Newton's method; the shooting Jacobian
//! comes from integrating the state in dual numbers ([`crate::dual`]), which is RK4 on
//! the variational equations. The force `n(s)` is known in closed form (piecewise
//! linear), so it is not an unknown.

use crate::dual::{Dual, Num};
use crate::jacobian::cross;
use crate::joints::{JointError, Joints};
use crate::real::{c, Real};
use crate::robot::Robot;
use crate::se3::Frame;
use crate::sections::{Section, Sections};
use crate::solver::{solve_linear, Model, Solution, Solver, Status};
use core::fmt;
use nalgebra::{Matrix3, Matrix6, Vector3};

/// Most unknowns of a loaded solve: `MAX_TUBES - 1` base twists and a base moment.
pub const MAX_UNKNOWNS: usize = crate::MAX_TUBES - 1 + 3;

/// Derivative directions of a compliance pass: the unknowns, tip force and tip moment.
const COMPLIANCE_DIRECTIONS: usize = MAX_UNKNOWNS + 6;

/// Standard gravity, m/s^2.
pub const STANDARD_GRAVITY_M_S2: f64 = 9.81;

/// A chord iteration whose residual shrinks by less than this factor refreshes its
/// Jacobian (a Newton step).
const CHORD_CONTRACTION: f64 = 0.25;

/// kg/m^3 x mm^2 x m/s^2 in N/mm.
const WEIGHT_UNIT: f64 = 1e-9;

/// Gravity acting on the exposed tubes.
///
/// ```
/// let g = ctr_core::Gravity::<f64>::new([-1.0, 0.0, 0.0], 9.81);
/// assert_eq!(g.direction[0], -1.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gravity<T> {
    /// Unit direction of g in W.
    pub direction: [T; 3],
    /// Magnitude, m/s^2.
    pub g_m_s2: T,
}

impl<T: Real> Gravity<T> {
    /// Gravity along `direction` (normalised here) of magnitude `g_m_s2`.
    ///
    /// ```
    /// let g = ctr_core::Gravity::<f64>::new([0.0, 0.0, -2.0], 9.81);
    /// assert_eq!(g.direction, [0.0, 0.0, -1.0]);
    /// ```
    pub fn new(direction: [T; 3], g_m_s2: T) -> Self {
        let v = Vector3::from(direction);
        let n = v.norm();
        let d = if n > T::zero() { v / n } else { v };
        Gravity {
            direction: [d.x, d.y, d.z],
            g_m_s2,
        }
    }
}

/// Loads on the robot.
///
/// ```
/// let loads = ctr_core::Loads::<f64> { tip_force_n: [0.0, 0.0, -0.1], ..Default::default() };
/// assert!(loads.gravity.is_none());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Loads<T> {
    /// The tubes' weight, if modelled.
    pub gravity: Option<Gravity<T>>,
    /// Force applied at the tip, N, in W.
    pub tip_force_n: [T; 3],
    /// Moment applied at the tip, N mm, in W.
    pub tip_moment_nmm: [T; 3],
}

impl<T: Real> Default for Loads<T> {
    fn default() -> Self {
        Loads {
            gravity: None,
            tip_force_n: [T::zero(); 3],
            tip_moment_nmm: [T::zero(); 3],
        }
    }
}

/// Why a loaded solve could not start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LoadError {
    /// The joints are invalid for the robot.
    Joint(JointError),
    /// Gravity is modelled but a tube has no `density_kg_m3`.
    MissingDensity {
        /// tube number, 1 = outermost
        tube: usize,
    },
    /// A load value is NaN or infinite.
    NotFinite,
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoadError::Joint(e) => e.fmt(f),
            LoadError::MissingDensity { tube } => {
                write!(
                    f,
                    "tube {tube}: density_kg_m3 is needed where gravity is modelled"
                )
            }
            LoadError::NotFinite => write!(f, "loads must be finite numbers"),
        }
    }
}

impl From<JointError> for LoadError {
    fn from(e: JointError) -> Self {
        LoadError::Joint(e)
    }
}

impl core::error::Error for LoadError {}

/// Warm-start memory of loaded solves: unknowns and the chord Jacobian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LoadedWarm<T, const N: usize> {
    x: [T; MAX_UNKNOWNS],
    jac: [[T; MAX_UNKNOWNS]; MAX_UNKNOWNS],
    q: Joints<T, N>,
    /// the solve before: its unknowns and joints, for extrapolation
    before: Option<([T; MAX_UNKNOWNS], Joints<T, N>)>,
}

/// State of the loaded integration: position, orientation (unit quaternion w, x, y, z of
/// tube n's frame), internal moment (W), relative angles, twist rates.
#[derive(Clone, Copy)]
struct LState<S, const N: usize> {
    p: [S; 3],
    q: [S; 4],
    m: [S; 3],
    z: [[S; 2]; N],
    w: [S; N],
}

/// A loaded solve's solution, unknowns, sections and per-solve constants.
type LoadedSolve<T, const N: usize> =
    (Solution<T, N>, [T; MAX_UNKNOWNS], Sections<T, N>, Ctx<T, N>);

/// Per-solve constants.
struct Ctx<T, const N: usize> {
    gj: [T; N],
    weight: [T; N],
    dir: Vector3<T>,
    s: [T; N],
}

impl<T: Real, const N: usize> Ctx<T, N> {
    /// Internal force at arc length `at` (W, N): the tip force `tip` plus the weight
    /// beyond.
    fn force<S: Num<T>>(&self, at: T, tip: &[S; 3]) -> [S; 3] {
        let mut beyond = T::zero();
        for i in 0..N {
            if self.s[i] > at {
                beyond += self.weight[i] * (self.s[i] - at.max(T::zero()));
            }
        }
        let w = self.dir * beyond;
        [
            tip[0] + S::cst(w.x),
            tip[1] + S::cst(w.y),
            tip[2] + S::cst(w.z),
        ]
    }
}

#[inline(always)]
fn rhs<T: Real, S: Num<T>, const N: usize>(
    sec: &Section<T, N>,
    ctx: &Ctx<T, N>,
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
            torque -= st.w[j] * ctx.gj[j];
        }
    }
    let un = torque * (T::one() / ctx.gj[N - 1]);
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

impl<S: Copy, const N: usize> LState<S, N> {
    fn axpy<T: Real>(&self, d: &Self, h: T) -> Self
    where
        S: Num<T>,
    {
        let mut o = *self;
        for i in 0..3 {
            o.p[i] += d.p[i] * h;
            o.m[i] += d.m[i] * h;
        }
        for i in 0..4 {
            o.q[i] += d.q[i] * h;
        }
        for j in 0..N {
            o.z[j][0] += d.z[j][0] * h;
            o.z[j][1] += d.z[j][1] * h;
            o.w[j] += d.w[j] * h;
        }
        o
    }
}

/// RK4 across one section; the force varies linearly along it.
fn section<T: Real, S: Num<T>, const N: usize>(
    sec: &Section<T, N>,
    ctx: &Ctx<T, N>,
    tip_force: &[S; 3],
    st: &mut LState<S, N>,
) {
    let len = sec.end - sec.start;
    let n = crate::twist::steps(len, sec.h);
    let h = len / nalgebra::convert::<f64, T>(n as f64);
    let half = h * c(0.5);
    let mut s = sec.start;
    for _ in 0..n {
        let f0 = ctx.force(s, tip_force);
        let f1 = ctx.force(s + half, tip_force);
        let f2 = ctx.force(s + h, tip_force);
        let k1 = rhs(sec, ctx, st, f0);
        let k2 = rhs(sec, ctx, &st.axpy(&k1, half), f1);
        let k3 = rhs(sec, ctx, &st.axpy(&k2, half), f1);
        let k4 = rhs(sec, ctx, &st.axpy(&k3, h), f2);
        let sixth = h / c(6.0);
        let third = h / c(3.0);
        *st = st
            .axpy(&k1, sixth)
            .axpy(&k2, third)
            .axpy(&k3, third)
            .axpy(&k4, sixth);
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
        s += h;
    }
}

/// Integrates from the guide exit to the tip for unknowns given as `S` values; returns
/// the residuals (free-tip twists, then the tip moment error) and the final state.
fn integrate<T: Real, S: Num<T>, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    ctx: &Ctx<T, N>,
    tip_force: &[S; 3],
    tip_moment: &[S; 3],
    x: &[S; MAX_UNKNOWNS],
) -> ([S; MAX_UNKNOWNS], LState<S, N>) {
    let zero = S::cst(T::zero());
    let m0 = [x[N - 1], x[N], x[N + 1]];
    let mut st = LState {
        p: [zero; 3],
        q: [zero; 4],
        m: m0,
        z: [[zero; 2]; N],
        w: [zero; N],
    };
    let present = if sections.len > 0 {
        sections.list[0].present
    } else {
        [false; N]
    };
    let mut torque = m0[2];
    for j in 0..N - 1 {
        st.w[j] = x[j];
        if present[j] {
            torque -= x[j] * ctx.gj[j];
        }
    }
    let un = torque * (T::one() / ctx.gj[N - 1]);
    let trans_n = robot.tubes()[N - 1].params().length_mm - q.s_mm[N - 1];
    let psi_n = un * trans_n + S::cst(q.theta_rad[N - 1]);
    let (sh, ch) = (psi_n * c::<T>(0.5)).sin_cos();
    st.q = [ch, zero, zero, sh];
    for j in 0..N - 1 {
        let trans = robot.tubes()[j].params().length_mm - q.s_mm[j];
        let b = x[j] * trans + S::cst(q.theta_rad[j]) - psi_n;
        let (s, co) = b.sin_cos();
        st.z[j] = [co, s];
    }
    st.z[N - 1] = [S::cst(T::one()), zero];
    let mut r = [zero; MAX_UNKNOWNS];
    let mut done = [false; N];
    let mut record = |st: &LState<S, N>, at: T, r: &mut [S; MAX_UNKNOWNS]| {
        for j in 0..N - 1 {
            if !done[j] && q.s_mm[j] <= at {
                done[j] = true;
                r[j] = st.w[j];
            }
        }
    };
    record(&st, T::zero(), &mut r);
    for sec in sections.list.iter().take(sections.len) {
        section(sec, ctx, tip_force, &mut st);
        record(&st, sec.end, &mut r);
    }
    record(&st, T::max_value().unwrap_or(T::one()), &mut r);
    for i in 0..3 {
        r[N - 1 + i] = st.m[i] - tip_moment[i];
    }
    (r, st)
}

impl<T: Real, const N: usize> Solver<T, N> {
    /// Forward kinematics under loads: gravity on the exposed tubes and a tip force and
    /// moment, torsion included (see the module doc). Warm-started from this solver's
    /// previous unloaded solves for the twists; the base moment starts at zero.
    ///
    /// ```
    /// use ctr_core::{Gravity, Joints, Loads, Model, Robot, Solver, Status, TubeParams};
    /// let tube = TubeParams { density_kg_m3: Some(6450.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 0.0, 58000.0, 0.33) };
    /// let robot = Robot::new([tube]).unwrap();
    /// let loads = Loads { gravity: Some(Gravity::new([-1.0, 0.0, 0.0], 9.81)), ..Default::default() };
    /// let sol = Solver::default().solve_loaded(&robot, &Joints::from_mm_deg([100.0], [0.0]), &loads).unwrap();
    /// assert_eq!(sol.status, Status::Converged);
    /// assert!(sol.tip.position.x < 0.0); // sags along -x
    /// ```
    pub fn solve_loaded(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        loads: &Loads<T>,
    ) -> Result<Solution<T, N>, LoadError> {
        self.loaded_solve(robot, q, loads).map(|(sol, ..)| sol)
    }

    /// [`solve_loaded`](Self::solve_loaded), also returning the unknowns, the sections
    /// and the per-solve constants.
    fn loaded_solve(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        loads: &Loads<T>,
    ) -> Result<LoadedSolve<T, N>, LoadError> {
        q.validate(robot)?;
        let finite = |v: &[T; 3]| v.iter().all(|x| x.is_finite());
        if !finite(&loads.tip_force_n) || !finite(&loads.tip_moment_nmm) {
            return Err(LoadError::NotFinite);
        }
        let mut weight = [T::zero(); N];
        let mut dir = Vector3::zeros();
        if let Some(g) = loads.gravity {
            if !finite(&g.direction) || !g.g_m_s2.is_finite() {
                return Err(LoadError::NotFinite);
            }
            dir = Vector3::from(g.direction);
            for (i, t) in robot.tubes().iter().enumerate() {
                let rho = t
                    .density_kg_m3()
                    .ok_or(LoadError::MissingDensity { tube: i + 1 })?;
                weight[i] = rho * t.area_mm2() * g.g_m_s2 * c(WEIGHT_UNIT);
            }
        }
        // start from the last loaded solve, else from the unloaded twist
        let warm = self.loaded;
        let mut extra_iterations = 0;
        let mut margin = T::one();
        let mut x = [T::zero(); MAX_UNKNOWNS];
        match &warm {
            Some(w) => {
                x = w.x;
                if let Some((x0, q0)) = &w.before {
                    let alpha = crate::solver::extrapolation(q, &w.q, q0);
                    for i in 0..MAX_UNKNOWNS {
                        x[i] += (w.x[i] - x0[i]) * alpha;
                    }
                }
            }
            None => {
                let unloaded = self.solve(robot, q, Model::Torsion)?;
                extra_iterations = unloaded.iterations;
                margin = unloaded.stability_margin;
                x[..N - 1].copy_from_slice(&unloaded.base_twist_per_mm[..N - 1]);
            }
        }
        let sections = self.sections(robot, q);
        let ctx = Ctx {
            gj: robot.tubes().map(|t| t.torsional_stiffness_nmm2()),
            weight,
            dir,
            s: q.s_mm,
        };
        let unknowns = N + 2;
        let cfg = self.config;
        let mut iterations = 0;
        let status;
        // Chord iteration: the Jacobian from one dual-number pass serves several plain
        // passes (the load is a mild perturbation, so it barely changes); each plain pass
        // also yields the residual and pose, so convergence costs no extra pass. A slow
        // contraction refreshes the Jacobian.
        let mut jac: Option<[[T; MAX_UNKNOWNS]; MAX_UNKNOWNS]> = warm.map(|w| w.jac);
        let mut prev_res = T::max_value().unwrap_or(T::one());
        let scale = |i: usize| {
            if i < N - 1 {
                T::one()
            } else {
                T::one() / robot.tubes()[N - 1].bending_stiffness_nmm2()
            }
        };
        let (st, res) = loop {
            let (r, st) = integrate::<T, T, N>(
                robot,
                q,
                &sections,
                &ctx,
                &loads.tip_force_n,
                &loads.tip_moment_nmm,
                &x,
            );
            let mut res = T::zero();
            let mut rv = [T::zero(); MAX_UNKNOWNS];
            for i in 0..unknowns {
                rv[i] = r[i];
                // moments (N mm) over the bending stiffness become rad/mm
                res = res.max(r[i].abs() * scale(i));
            }
            let finite = res.is_finite() && st.p.iter().all(|v| v.is_finite());
            if !finite {
                status = Status::Diverged;
                break (st, res);
            }
            if res <= cfg.residual_tolerance_per_mm {
                status = Status::Converged;
                break (st, res);
            }
            if iterations >= cfg.max_iterations {
                status = Status::IterationLimit;
                break (st, res);
            }
            iterations += 1;
            if jac.is_none() || res > prev_res * c(CHORD_CONTRACTION) {
                let xd: [Dual<T, MAX_UNKNOWNS>; MAX_UNKNOWNS] =
                    core::array::from_fn(|i| Dual::var(x[i], i));
                let fd = loads.tip_force_n.map(Dual::cst);
                let md = loads.tip_moment_nmm.map(Dual::cst);
                let (rd, _) = integrate(robot, q, &sections, &ctx, &fd, &md, &xd);
                let mut j = [[T::zero(); MAX_UNKNOWNS]; MAX_UNKNOWNS];
                for i in 0..unknowns {
                    j[i] = rd[i].eps;
                }
                jac = Some(j);
            }
            prev_res = res;
            let Some(dx) = jac.and_then(|j| solve_linear::<T, MAX_UNKNOWNS>(j, rv, unknowns))
            else {
                status = Status::Diverged;
                break (st, res);
            };
            for i in 0..unknowns {
                x[i] -= dx[i];
            }
        };
        self.loaded = match (status, jac) {
            (Status::Converged, Some(jac)) => Some(LoadedWarm {
                x,
                jac,
                q: *q,
                before: warm.map(|w| (w.x, w.q)),
            }),
            _ => None,
        };
        let mut base_twist = [T::zero(); N];
        base_twist[..N - 1].copy_from_slice(&x[..N - 1]);
        let mut torque = x[N + 1];
        for j in 0..N - 1 {
            if sections.len > 0 && sections.list[0].present[j] {
                torque -= x[j] * ctx.gj[j];
            }
        }
        base_twist[N - 1] = torque / ctx.gj[N - 1];
        let mut base_angle = [T::zero(); N];
        for j in 0..N {
            base_angle[j] =
                q.theta_rad[j] + (robot.tubes()[j].params().length_mm - q.s_mm[j]) * base_twist[j];
        }
        let sol = Solution {
            tip: frame_of(&st),
            status,
            residual_per_mm: res,
            iterations: iterations + extra_iterations,
            base_twist_per_mm: base_twist,
            base_angle_rad: base_angle,
            // the loaded shooting Jacobian mixes units (twists and moments): the
            // unloaded solve's margin is reported
            stability_margin: margin,
        };
        Ok((sol, x, sections, ctx))
    }

    /// Solves under `loads` (as [`solve_loaded`](Self::solve_loaded)) and returns the
    /// tip's compliance there: the 6 x 6 derivative of `(p_tip, rotation)` with respect
    /// to `(F_tip, M_tip)`, all in W. Rows: tip displacement (mm), then the tip frame's
    /// rotation as a spatial angle vector (rad, `[dphi]x = dR R^T`); columns: tip force
    /// (N), then tip moment (N mm). So the blocks are mm/N, mm/(N mm), rad/N and
    /// rad/(N mm). With default loads it is the compliance at zero load.
    ///
    /// Computed from one dual-number integration of the loaded model at the solution,
    /// with the unknowns (base twists and base moment) eliminated by the implicit
    /// function theorem, as in [`crate::jacobian`]. Entries are NaN where the loaded
    /// shooting Jacobian is singular.
    ///
    /// ```
    /// use ctr_core::{Joints, Loads, Robot, Solver, TubeParams};
    /// // a straight cantilever: dx/dF_x = L^3 / (3 E I), dphi_y/dM_y = L / (E I)
    /// let robot = Robot::new([TubeParams::<f64>::new(1.2, 0.9, 300.0, 0.0, 58000.0, 0.33)]).unwrap();
    /// let ei = robot.tubes()[0].bending_stiffness_nmm2();
    /// let l = 100.0;
    /// let (_, c) = Solver::default().solve_compliance(&robot, &Joints::new([l], [0.0]), &Loads::default()).unwrap();
    /// assert!((c[(0, 0)] - l * l * l / (3.0 * ei)).abs() < 1e-9 * c[(0, 0)]);
    /// assert!((c[(4, 4)] - l / ei).abs() < 1e-9 * c[(4, 4)]);
    /// ```
    pub fn solve_compliance(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        loads: &Loads<T>,
    ) -> Result<(Solution<T, N>, Matrix6<T>), LoadError> {
        let (sol, x, sections, ctx) = self.loaded_solve(robot, q, loads)?;
        let unknowns = N + 2;
        // directions: the unknowns, then F_x, F_y, F_z, M_x, M_y, M_z
        let xd: [Dual<T, COMPLIANCE_DIRECTIONS>; MAX_UNKNOWNS] =
            core::array::from_fn(|i| Dual::var(x[i], i));
        let fd: [Dual<T, COMPLIANCE_DIRECTIONS>; 3] =
            core::array::from_fn(|i| Dual::var(loads.tip_force_n[i], unknowns + i));
        let md: [Dual<T, COMPLIANCE_DIRECTIONS>; 3] =
            core::array::from_fn(|i| Dual::var(loads.tip_moment_nmm[i], unknowns + 3 + i));
        let (r, st) = integrate(robot, q, &sections, &ctx, &fd, &md, &xd);
        // the tip rotation from the quaternion, as duals
        let [qw, qx, qy, qz] = st.q;
        let one = Dual::cst(T::one());
        let two = c::<T>(2.0);
        let rot = [
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
        ];
        // r holds the residuals of the `unknowns` unknowns (the rest are zero)
        let tangent = crate::tangent::columns_of_duals(&st.p, &rot);
        let cols = crate::jacobian::implicit_columns::<T, MAX_UNKNOWNS, COMPLIANCE_DIRECTIONS>(
            &r, &tangent, unknowns, 6,
        );
        let mut m = Matrix6::zeros();
        for (j, col) in cols.iter().take(6).enumerate() {
            m.set_column(j, col);
        }
        Ok((sol, m))
    }
}

fn frame_of<T: Real, const N: usize>(st: &LState<T, N>) -> Frame<T> {
    let q = nalgebra::Quaternion::new(st.q[0], st.q[1], st.q[2], st.q[3]);
    let r: Matrix3<T> = nalgebra::UnitQuaternion::from_quaternion(q)
        .to_rotation_matrix()
        .into_inner();
    Frame {
        rotation: r,
        position: Vector3::new(st.p[0], st.p[1], st.p[2]),
    }
}

//! The loaded model: Newton on the base twists and the base moment
//! ([`crate::integrate::loaded`]), and the compliance at the solution.
//!
//! Chord iteration: the Jacobian from one dual-number pass serves several plain passes
//! (the load is a mild perturbation, so it barely changes); each plain pass also yields
//! the residual and the pose, so convergence costs no extra pass, and a slow
//! contraction refreshes the Jacobian. The first loaded solve starts from the unloaded
//! twist, later ones from the last loaded solution (extrapolated along the trajectory).

use super::newton::{Evaluation, Newton, Policy, Shooting, Stop};
use super::request::{Derivative, Request, SolveError};
use super::{extrapolation, Model, Solution, Solver, Status};
use crate::integrate::loaded::{pass, Ctx, LState, Unknowns, MAX_UNKNOWNS, WEIGHT_UNIT};
use crate::integrate::pass::{guide_exit, present_at_exit};
use crate::integrate::pose::columns_of_duals;
use crate::integrate::twist::Inputs;
use crate::math::dual::{Dual, Num};
use crate::model::joints::Joints;
use crate::model::loads::Loads;
use crate::model::robot::Robot;
use crate::model::sections::Sections;
use crate::real::{c, Real};
use nalgebra::{Matrix6, Vector3};

/// Derivative directions of a compliance pass: the unknowns, tip force and tip moment.
const COMPLIANCE_DIRECTIONS: usize = MAX_UNKNOWNS + 6;

/// Warm-start memory of loaded solves: unknowns and the chord Jacobian.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LoadedWarm<T, const N: usize> {
    x: Unknowns<T>,
    jac: [[T; MAX_UNKNOWNS]; MAX_UNKNOWNS],
    q: Joints<T, N>,
    /// the solve before: its unknowns and joints, for extrapolation
    before: Option<(Unknowns<T>, Joints<T, N>)>,
}

/// Newton's residual of the loaded model; keeps the last plain pass's final state.
struct Loaded<'a, T: Real, const N: usize> {
    robot: &'a Robot<T, N>,
    q: &'a Joints<T, N>,
    sections: &'a Sections<T, N>,
    ctx: Ctx<T, T, N>,
    unknowns: usize,
    /// the last plain pass's final state and residual norm
    last: Option<(LState<T, N>, T)>,
}

impl<T: Real, const N: usize> Shooting<T, MAX_UNKNOWNS> for Loaded<'_, T, N> {
    fn residual(&mut self, x: &Unknowns<T>, _: bool) -> Evaluation<T, MAX_UNKNOWNS> {
        let (r, st) = pass(self.robot, self.q, self.sections, &self.ctx, x, |_| {});
        let mut rv = [T::zero(); MAX_UNKNOWNS];
        let mut norm = T::zero();
        let moment_scale = T::one() / self.robot.tubes()[N - 1].bending_stiffness_nmm2();
        for i in 0..self.unknowns {
            rv[i] = r[i];
            // moments (N mm) over the bending stiffness become rad/mm
            let scale = if i < N - 1 { T::one() } else { moment_scale };
            norm = norm.max(r[i].abs() * scale);
        }
        if !st.p.iter().all(|v| v.is_finite()) {
            norm = c(f64::NAN);
        }
        self.last = Some((st, norm));
        Evaluation {
            r: rv,
            norm,
            jacobian: None,
        }
    }

    fn jacobian(&mut self, x: &Unknowns<T>) -> Option<[[T; MAX_UNKNOWNS]; MAX_UNKNOWNS]> {
        let xd: Unknowns<Dual<T, MAX_UNKNOWNS>> = core::array::from_fn(|i| Dual::var(x[i], i));
        let ctx = Ctx {
            gj: self.ctx.gj,
            weight: self.ctx.weight,
            dir: self.ctx.dir,
            s: self.ctx.s,
            tip_force: self.ctx.tip_force.map(Dual::cst),
            tip_moment: self.ctx.tip_moment.map(Dual::cst),
        };
        let (rd, _) = pass(self.robot, self.q, self.sections, &ctx, &xd, |_| {});
        let mut j = [[T::zero(); MAX_UNKNOWNS]; MAX_UNKNOWNS];
        for i in 0..self.unknowns {
            j[i] = rd[i].eps;
        }
        Some(j)
    }
}

impl<T: Real, const N: usize> Solver<T, N> {
    /// Where a loaded solve at `q` starts: the last loaded solve's unknowns,
    /// extrapolated along the joints, else the unloaded twist (solved here: its
    /// iterations and softest mode come with it; else 0 and 1).
    fn loaded_start(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
    ) -> Result<([T; MAX_UNKNOWNS], u32, T), SolveError> {
        let mut x = [T::zero(); MAX_UNKNOWNS];
        match &self.loaded {
            Some(w) => {
                x = w.x;
                if let Some((x0, q0)) = &w.before {
                    let alpha = extrapolation(q, &w.q, q0);
                    for i in 0..MAX_UNKNOWNS {
                        x[i] += (w.x[i] - x0[i]) * alpha;
                    }
                }
                Ok((x, 0, T::one()))
            }
            None => {
                let unloaded = self.solve(robot, Request::new(*q, Model::Torsion))?;
                x[..N - 1].copy_from_slice(&unloaded.base_twist_per_mm[..N - 1]);
                Ok((x, unloaded.iterations, unloaded.softest_mode))
            }
        }
    }

    /// A request with loads (or a compliance) on the checked actual joints `q`.
    pub(super) fn loaded_answer(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        sections: &Sections<T, N>,
        request: Request<'_, T, N>,
        derivative: Option<&mut Derivative<'_, T, N>>,
    ) -> Result<Solution<T, N>, SolveError> {
        let loads = request.loads.unwrap_or_default();
        let ctx = context(robot, q, &loads)?;
        let registration = request.effects.and_then(|e| e.registration);
        let warm = self.loaded;
        let (x, extra_iterations, margin) = self.loaded_start(robot, q)?;
        let unknowns = N + 2;
        let policy = Policy {
            m: unknowns,
            max_iterations: self.config.max_iterations,
            step_tolerance: None,
            residual_tolerance: self.config.residual_tolerance_per_mm,
            backtrack: false,
            chord: true,
        };
        let mut newton = Newton::new(x, false);
        if let Some(w) = &warm {
            newton = newton.with_jacobian(w.jac);
        }
        let mut problem = Loaded {
            robot,
            q,
            sections,
            ctx,
            unknowns,
            last: None,
        };
        let stop = newton.run(&mut problem, &policy);
        let x = newton.x;
        // the last pass's state is the solution's, but at the bound Newton stepped after it
        if stop == Stop::Limit {
            problem.residual(&x, false);
        }
        let (st, res) = problem.last.unwrap_or((nan_state(), c(f64::NAN)));
        let status = match stop {
            Stop::Residual | Stop::Step => Status::Converged,
            Stop::Limit if res <= self.config.residual_tolerance_per_mm => Status::Converged,
            Stop::Limit => Status::IterationLimit,
            Stop::Diverged => Status::Diverged,
        };
        self.loaded = match status {
            Status::Converged => Some(LoadedWarm {
                x,
                jac: newton.jacobian,
                q: *q,
                before: warm.map(|w| (w.x, w.q)),
            }),
            _ => None,
        };
        let present = present_at_exit(sections);
        let inp = Inputs {
            s: q.s_mm,
            theta: q.theta_rad,
            x: core::array::from_fn(|j| if j < N - 1 { x[j] } else { T::zero() }),
            ei: [T::zero(); N],
            gj: problem.ctx.gj,
            k: [T::zero(); N],
        };
        let exit = guide_exit(robot, &inp, &present, x[N + 1]);
        let mut solution = Solution {
            tip: st.frame(),
            status,
            residual_per_mm: res,
            iterations: newton.iterations + extra_iterations,
            base_twist_per_mm: exit.twist,
            base_angle_rad: exit.angle,
            // the loaded shooting Jacobian mixes units (twists and moments): the
            // unloaded solve's margin is reported
            softest_mode: margin,
            backbone_points: 0,
        };
        let mut points = 0;
        if let Some(buf) = request.backbone {
            let _ = pass(robot, q, sections, &problem.ctx, &x, |s| {
                if let Some(slot) = buf.get_mut(points) {
                    let p = Vector3::new(s.p[0], s.p[1], s.p[2]);
                    *slot = registration.map_or(p, |r| r.apply_point(&p));
                }
                points += 1;
            });
        }
        solution.backbone_points = points;
        if let Some(Derivative::Loads(m)) = derivative {
            **m = compliance(robot, q, sections, &problem.ctx, &x, unknowns);
        }
        Ok(solution)
    }
}

/// A state of NaNs (for a solve whose Newton never evaluated: no unknowns to solve).
fn nan_state<T: Real, const N: usize>() -> LState<T, N> {
    let nan = c::<T>(f64::NAN);
    LState {
        p: [nan; 3],
        q: [nan; 4],
        m: [nan; 3],
        z: [[nan; 2]; N],
        w: [nan; N],
    }
}

/// The per-solve constants of the loads: each tube's weight per length and the
/// direction of gravity, the tip loads.
fn context<T: Real, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    loads: &Loads<T>,
) -> Result<Ctx<T, T, N>, SolveError> {
    let finite = |v: &[T; 3]| v.iter().all(|x| x.is_finite());
    if !finite(&loads.tip_force_n) || !finite(&loads.tip_moment_nmm) {
        return Err(SolveError::NotFinite);
    }
    let mut weight = [T::zero(); N];
    let mut dir = Vector3::zeros();
    if let Some(g) = loads.gravity {
        if !finite(&g.direction) || !g.g_m_s2.is_finite() {
            return Err(SolveError::NotFinite);
        }
        dir = Vector3::from(g.direction);
        for (i, t) in robot.tubes().iter().enumerate() {
            let rho = t
                .density_kg_m3()
                .ok_or(SolveError::MissingDensity { tube: i + 1 })?;
            weight[i] = rho * t.area_mm2() * g.g_m_s2 * c(WEIGHT_UNIT);
        }
    }
    Ok(Ctx {
        gj: robot.each(|t| t.torsional_stiffness_nmm2()),
        weight,
        dir,
        s: q.s_mm,
        tip_force: loads.tip_force_n,
        tip_moment: loads.tip_moment_nmm,
    })
}

/// The tip's compliance at the solution `x`: one dual-number pass with the unknowns,
/// the tip force and the tip moment as directions, the unknowns eliminated by the
/// implicit function theorem (as in [`super::jacobian`]). NaN where the loaded shooting
/// Jacobian is singular.
fn compliance<T: Real, const N: usize>(
    robot: &Robot<T, N>,
    q: &Joints<T, N>,
    sections: &Sections<T, N>,
    ctx: &Ctx<T, T, N>,
    x: &Unknowns<T>,
    unknowns: usize,
) -> Matrix6<T> {
    // directions: the unknowns, then F_x, F_y, F_z, M_x, M_y, M_z
    let xd: Unknowns<Dual<T, COMPLIANCE_DIRECTIONS>> = core::array::from_fn(|i| Dual::var(x[i], i));
    let dual = Ctx {
        gj: ctx.gj,
        weight: ctx.weight,
        dir: ctx.dir,
        s: ctx.s,
        tip_force: core::array::from_fn(|i| Dual::var(ctx.tip_force[i], unknowns + i)),
        tip_moment: core::array::from_fn(|i| Dual::var(ctx.tip_moment[i], unknowns + 3 + i)),
    };
    let (r, st) = pass(robot, q, sections, &dual, &xd, |_| {});
    // r holds the residuals of the `unknowns` unknowns (the rest are zero)
    let tangent = columns_of_duals(&st.p, &st.rotation());
    let cols = super::jacobian::implicit_columns::<T, MAX_UNKNOWNS, COMPLIANCE_DIRECTIONS>(
        &r, &tangent, unknowns, 6,
    );
    let mut m = Matrix6::zeros();
    for (j, col) in cols.iter().take(6).enumerate() {
        m.set_column(j, col);
    }
    m
}

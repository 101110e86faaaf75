//! The unloaded model: the rigid model's closed form, shooting on the base twist rates
//! for the torsion model ([`crate::integrate::twist`]), and the seed's boundary friction
//! moments on top of it ([`crate::friction::BoundaryMoment`]).
//!
//! A torsion solve iterates Newton ([`super::newton`]) on passes with variations
//! ([`crate::integrate::variations`]), warm-started from the solver's memory (or, cold,
//! on coarse steps first), then integrates the converged twist once more with the pose
//! (`pose`), which also measures the residual it leaves; only if that exceeds the
//! residual tolerance does Newton go on. A warm start that fails is retried cold, and a
//! cold start on coarse steps that fails is retried on the full steps.

use super::jacobian;
use super::newton::{Evaluation, Newton, Policy, Shooting, Stop};
use super::request::{Derivative, Request};
use super::{Model, Solution, Solver, Status};

use crate::integrate::pass::{run, Mechanics, Setup};
use crate::integrate::pose::{NoPose, Traced};
use crate::integrate::twist::{Inputs, TwistState};
use crate::integrate::variations::Variations;
use crate::math::dual::{Dual, Num};
use crate::math::linalg::{max_abs, smallest_singular_value};
use crate::math::se3::Frame;
use crate::model::effects::Registration;
use crate::model::joints::Joints;
use crate::model::robot::Robot;
use crate::model::sections::Sections;
use crate::real::Real;
use nalgebra::Vector3;

/// Directions of a friction solve's Newton Jacobian: the base twists.
const FRICTION_DIRECTIONS: usize = crate::MAX_TUBES - 1;

/// Newton's residual of the torsion model: free-tip twists and their sensitivities from
/// one pass with variations.
pub(super) struct Twist<'a, T: Real, const N: usize> {
    pub setup: Setup<'a, T, N>,
    pub inp: Inputs<T, T, N>,
}

impl<T: Real, const N: usize> Shooting<T, N> for Twist<'_, T, N> {
    fn residual(&mut self, x: &[T; N], coarse: bool) -> Evaluation<T, N> {
        self.setup.mechanics = Mechanics::Torsion { coarse };
        self.inp.x = *x;
        let pass = run::<T, T, T, Variations<T, N>, _, N>(&self.setup, &self.inp, NoPose);
        let mut r = [T::zero(); N];
        let mut jac = [[T::zero(); N]; N];
        for j in 0..N - 1 {
            if let Some((w, dw)) = pass.tips[j] {
                r[j] = w;
                jac[j] = dw;
            }
        }
        Evaluation {
            r,
            norm: max_abs(&r, N - 1),
            jacobian: Some(jac),
        }
    }
    fn jacobian(&mut self, _: &[T; N]) -> Option<[[T; N]; N]> {
        None
    }
}

/// Newton's residual with boundary friction moments: a pass on dual numbers (the
/// moments' magnitudes depend on the unknowns too).
struct Friction<'a, T: Real, const N: usize> {
    setup: Setup<'a, T, N>,
    inp: Inputs<T, T, N>,
}

impl<T: Real, const N: usize> Shooting<T, N> for Friction<'_, T, N> {
    fn residual(&mut self, x: &[T; N], _: bool) -> Evaluation<T, N> {
        let m = N - 1;
        let inp = Inputs {
            s: self.inp.s.map(Dual::<T, FRICTION_DIRECTIONS>::cst),
            theta: self.inp.theta.map(Dual::cst),
            x: core::array::from_fn(|j| {
                if j < m {
                    Dual::var(x[j], j)
                } else {
                    Dual::cst(x[j])
                }
            }),
            ei: self.inp.ei,
            gj: self.inp.gj,
            k: self.inp.k,
        };
        let pass = run::<T, _, T, TwistState<_, N>, _, N>(&self.setup, &inp, NoPose);
        let mut r = [T::zero(); N];
        let mut jac = [[T::zero(); N]; N];
        for i in 0..m {
            if let Some(t) = pass.tips[i] {
                r[i] = t.re;
                for k in 0..m {
                    jac[i][k] = t.eps.get(k).copied().unwrap_or(T::zero());
                }
            }
        }
        Evaluation {
            r,
            norm: max_abs(&r, m),
            jacobian: Some(jac),
        }
    }
    fn jacobian(&mut self, _: &[T; N]) -> Option<[[T; N]; N]> {
        None
    }
}

/// Integrates the twist at the unknowns `inp.x` once more with the pose (tracing the
/// backbone into `trace`): the solution there, its status to be set.
fn pose<T: Real, const N: usize>(
    setup: &Setup<'_, T, N>,
    inp: &Inputs<T, T, N>,
    trace: Option<&mut [Vector3<T>]>,
    registration: Option<Registration<T>>,
    sol: &mut Solution<T, N>,
) {
    let (tip, tips, exit, points) = match trace {
        Some(buf) => {
            let traced = Traced::new(Frame::identity(), buf, registration);
            let pass = run::<T, T, T, TwistState<T, N>, _, N>(setup, inp, traced);
            (pass.frame.frame, pass.tips, pass.exit, pass.frame.needed)
        }
        None => {
            let pass = run::<T, T, T, TwistState<T, N>, _, N>(setup, inp, Frame::identity());
            (pass.frame, pass.tips, pass.exit, 0)
        }
    };
    let mut residual = T::zero();
    for t in tips.iter().take(N - 1).flatten() {
        residual = if t.is_finite() {
            residual.max(t.abs())
        } else {
            T::max_value().unwrap_or(T::one())
        };
    }
    *sol = Solution {
        tip,
        status: Status::Converged,
        residual_per_mm: residual,
        iterations: 0,
        base_twist_per_mm: exit.twist,
        base_angle_rad: exit.angle,
        softest_mode: T::one(),
        backbone_points: points,
    };
}

/// The unloaded integration of `request` on the checked actual joints `q` cut into
/// `sections`: its mechanics and clearance kinks (the friction moments are the caller's).
pub(crate) fn unloaded_setup<'s, T: Real, const N: usize>(
    robot: &'s Robot<T, N>,
    q: &'s Joints<T, N>,
    sections: &'s Sections<T, N>,
    request: &Request<'s, T, N>,
) -> Setup<'s, T, N> {
    Setup {
        robot,
        q,
        sections,
        mechanics: match request.model {
            Model::Rigid => Mechanics::Rigid,
            Model::Torsion => Mechanics::Torsion { coarse: false },
        },
        clearance: request
            .effects
            .map(|e| &e.clearance)
            .filter(|c| c.iter().any(Option::is_some)),
        friction: None,
    }
}

/// The joint or parameter Jacobian (or both) `derivative` asks for, of the unmeasured tip
/// of `setup` at the base twists `x` (a compliance is the loaded solver's).
pub(crate) fn derivative_of<T: Real, const N: usize>(
    setup: &Setup<'_, T, N>,
    x: &[T; N],
    model: Model,
    derivative: &mut Derivative<'_, T, N>,
) {
    match derivative {
        Derivative::Joints(j) => jacobian::joints(setup, x, model, j),
        Derivative::Parameters(j) => jacobian::parameters(setup, x, model, j),
        Derivative::JointsAndParameters(j, p) => jacobian::both(setup, x, model, j, p),
        Derivative::Loads(_) => {}
    }
}

impl<T: Real, const N: usize> Solver<T, N> {
    /// A request without loads on the checked actual joints `q`.
    #[inline(always)]
    pub(super) fn unloaded_answer(
        &mut self,
        robot: &Robot<T, N>,
        q: &Joints<T, N>,
        sections: &Sections<T, N>,
        request: Request<'_, T, N>,
        derivative: Option<&mut Derivative<'_, T, N>>,
    ) -> Solution<T, N> {
        let friction = request
            .friction
            .filter(|f| f.iter().any(|v| *v != T::zero()));
        let registration = request.effects.and_then(|e| e.registration);
        let mut setup = unloaded_setup(robot, q, sections, &request);
        let inp = Inputs::plain(robot, q, &[T::zero(); N]);
        let mut backbone = request.backbone;
        let mut sol = Solution::nan();
        match request.model {
            Model::Rigid => pose(
                &setup,
                &inp,
                backbone.as_deref_mut(),
                registration,
                &mut sol,
            ),
            Model::Torsion => self.torsion(
                &setup,
                &inp,
                backbone.as_deref_mut(),
                registration,
                &mut sol,
            ),
        }
        // the friction moments start from the frictionless solution (without one, that
        // is the answer, with its status); their pose pass traces the backbone again
        if let Some(coefficient) = &friction {
            if sol.status == Status::Converged {
                setup.friction = Some(coefficient);
                let free = sol;
                self.boundary_friction(&setup, &inp, &free, backbone, registration, &mut sol);
            }
        }
        if let Some(d) = derivative {
            derivative_of(&setup, &sol.base_twist_per_mm, request.model, d);
        }
        sol
    }

    /// The torsion model, warm-started (a warm start that fails is retried cold, a cold
    /// start on coarse steps that fails on the full steps).
    #[inline(always)]
    fn torsion(
        &mut self,
        setup: &Setup<'_, T, N>,
        inp: &Inputs<T, T, N>,
        mut trace: Option<&mut [Vector3<T>]>,
        registration: Option<Registration<T>>,
        sol: &mut Solution<T, N>,
    ) {
        let q = setup.q;
        let guess = self.guess(q);
        let cold = self.warm.count == 0;
        self.shoot(
            setup,
            inp,
            guess,
            cold,
            trace.as_deref_mut(),
            registration,
            sol,
        );
        // the branch the last solution was on ends at a fold, where a warm start fails
        // or lands on the unstable side: the robot snaps to a stable branch (`snap`);
        // a cold start that lands on an unstable equilibrium looks for a stable one
        let unstable =
            |sol: &Solution<T, N>| sol.status == Status::Converged && sol.softest_mode < T::zero();
        // the answer continues the branch of the memory's guess (else it snapped, or a
        // retry found it: the memory's older solution is then on another branch)
        let continued = sol.status == Status::Converged && !unstable(sol);
        if !continued {
            let iterations = sol.iterations;
            // from the last equilibrium (where the branch was stable), else from where
            // this solve ended: an unstable equilibrium's soft mode leads to the stable
            // ones beside it
            let was_stable = !cold && self.warm.margin > T::zero();
            let mut snapped = was_stable
                && self.stable_branch(
                    setup,
                    inp,
                    self.warm.x[0],
                    trace.as_deref_mut(),
                    registration,
                    sol,
                );
            if !snapped && sol.status != Status::Converged && !cold {
                // a warm start from far away can land in another basin: retry cold
                self.shoot(
                    setup,
                    inp,
                    [T::zero(); N],
                    true,
                    trace.as_deref_mut(),
                    registration,
                    sol,
                );
            }
            if !snapped && (sol.status != Status::Converged || unstable(sol)) {
                let from = sol.base_twist_per_mm;
                if from.iter().all(|v| v.is_finite()) {
                    snapped = self.stable_branch(
                        setup,
                        inp,
                        from,
                        trace.as_deref_mut(),
                        registration,
                        sol,
                    );
                }
            }
            let _ = snapped;
            sol.iterations += iterations;
        }
        if sol.status != Status::Converged {
            // the coarse steps of a cold start can be too long for the twist rates of
            // Newton's first iterates (RK4 on the relative angles goes unstable where a
            // relative twist rate times the step passes ~2.8, and Newton wanders):
            // retry on the full steps, which resolve the coupling of the answer
            let iterations = sol.iterations;
            self.shoot(setup, inp, [T::zero(); N], false, trace, registration, sol);
            sol.iterations += iterations;
        }
        if sol.status == Status::Converged {
            self.remember(q, &sol.base_twist_per_mm, sol.softest_mode, continued);
        }
    }

    /// Newton shooting on the base twist rates from `guess`, then the pose pass (see the
    /// module doc).
    pub(super) fn shoot(
        &self,
        setup: &Setup<'_, T, N>,
        inp: &Inputs<T, T, N>,
        guess: [T; N],
        cold: bool,
        mut trace: Option<&mut [Vector3<T>]>,
        registration: Option<Registration<T>>,
        sol: &mut Solution<T, N>,
    ) {
        let m = N - 1;
        let cfg = &self.config;
        let policy = Policy {
            m,
            max_iterations: cfg.max_iterations,
            step_tolerance: Some(cfg.step_tolerance_per_mm),
            residual_tolerance: cfg.residual_tolerance_per_mm,
            backtrack: true,
            chord: false,
        };
        let mut newton = Newton::new(guess, cold);
        let mut problem = Twist {
            setup: *setup,
            inp: *inp,
        };
        let full = Setup {
            mechanics: Mechanics::Torsion { coarse: false },
            ..*setup
        };
        loop {
            let stop = newton.run(&mut problem, &policy);
            let diverged = stop == Stop::Diverged || !newton.finite();
            let x = if diverged { newton.best.0 } else { newton.x };
            pose(
                &full,
                &Inputs { x, ..*inp },
                trace.as_deref_mut(),
                registration,
                sol,
            );
            sol.iterations = newton.iterations;
            if m > 0 && newton.iterations > 0 {
                sol.softest_mode = smallest_singular_value(&newton.jacobian, m);
            }
            let r = sol.residual_per_mm;
            let finite = sol.tip.position.iter().all(|v| v.is_finite()) && r.is_finite();
            if !finite {
                // no finite pose at the best iterate (RK4 on steps too long for its twist
                // rates overflows): the rigid model's closed form instead, never NaN
                let rigid = Setup {
                    mechanics: Mechanics::Rigid,
                    ..*setup
                };
                pose(&rigid, inp, trace.as_deref_mut(), registration, sol);
                sol.iterations = newton.iterations;
                sol.softest_mode = T::zero();
            }
            sol.status = if diverged || !finite {
                Status::Diverged
            } else if r <= cfg.residual_tolerance_per_mm {
                Status::Converged
            } else if newton.iterations < cfg.max_iterations {
                newton.forget_norm();
                continue;
            } else {
                Status::IterationLimit
            };
            return;
        }
    }

    /// The boundary friction moments of `setup.friction` from the frictionless solution
    /// `free`: Newton on the base twists with a dual-number Jacobian, then the pose.
    fn boundary_friction(
        &self,
        setup: &Setup<'_, T, N>,
        inp: &Inputs<T, T, N>,
        free: &Solution<T, N>,
        trace: Option<&mut [Vector3<T>]>,
        registration: Option<Registration<T>>,
        sol: &mut Solution<T, N>,
    ) {
        let policy = Policy {
            m: N - 1,
            max_iterations: self.config.max_iterations,
            step_tolerance: None,
            residual_tolerance: self.config.residual_tolerance_per_mm,
            backtrack: false,
            chord: false,
        };
        let mut newton = Newton::new(free.base_twist_per_mm, false);
        let mut problem = Friction {
            setup: *setup,
            inp: *inp,
        };
        let status = match newton.run(&mut problem, &policy) {
            Stop::Residual | Stop::Step => Status::Converged,
            Stop::Limit => Status::IterationLimit,
            Stop::Diverged => Status::Diverged,
        };
        pose(
            setup,
            &Inputs {
                x: newton.x,
                ..*inp
            },
            trace,
            registration,
            sol,
        );
        sol.status = status;
        sol.iterations = free.iterations + newton.iterations;
        sol.softest_mode = free.softest_mode;
    }
}

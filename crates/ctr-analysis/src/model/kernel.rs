//! The one place a row becomes a core request.
//!
//! A [`Kernel`] holds a model's mechanics for a tube count `N`: the robot with its
//! tubes scaled (`stiffness`, `precurvature`), the base mechanics, the per-solve effects
//! the core applies (clearance kinks, sensor offset, registration) and gravity. Given a
//! row's actual joints (joint offsets and time effects already applied, in file units,
//! by [`super::RowModel`]) and its tip force, it asks the core one
//! [`ctr_core::Request`]: the loaded solver where there is a load (gravity or
//! a force), the unloaded one otherwise, the tip as measured. `ctr-cli fk`, the
//! simulation of recordings (and so the diagnosis) and the inverse kinematics all solve
//! through it.

use crate::margin::{self, Margin, Margins, MAX_JOINTS, PROBE_STEP, SCREEN_FACTOR};
use ctr_core::{
    Effects as CoreEffects, Gravity, JointJacobian, Joints, Loads, Model, ParameterJacobian,
    Request, Robot, Solution, SolveError, Solver, MAX_TUBES,
};
use ctr_formats::{joints_of, AnyRobot, Effects, FkResult};
use nalgebra::Vector3;

/// A model's mechanics for `N` tubes (module doc).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Kernel<const N: usize> {
    robot: Robot<f64, N>,
    model: Model,
    /// the core's per-solve effects; `None` where they would change nothing
    effects: Option<CoreEffects<f64, N>>,
    gravity: Option<Gravity<f64>>,
}

impl<const N: usize> Kernel<N> {
    /// The mechanics of `robot` (scaled already) under `model` with the file's `effects`.
    fn new(robot: &Robot<f64, N>, model: Model, effects: &Effects) -> Self {
        let core = effects.core_effects::<N>();
        Kernel {
            robot: *robot,
            model,
            effects: (core != CoreEffects::default()).then_some(core),
            gravity: effects
                .gravity
                .as_ref()
                .map(|g| Gravity::new(g.direction_w, g.g_m_s2)),
        }
    }

    /// The core request of actual joints `q` with the tip force `force_n` (N, in W).
    fn request(&self, q: Joints<f64, N>, force_n: [f64; 3]) -> Request<'_, f64, N> {
        let mut request = Request::new(q, self.model);
        if let Some(e) = &self.effects {
            request = request.effects(e);
        }
        if self.gravity.is_some() || force_n.iter().any(|&f| f != 0.0) {
            request = request.loads(Loads {
                gravity: self.gravity,
                tip_force_n: force_n,
                ..Default::default()
            });
        }
        request
    }

    /// The tip as measured at actual joints `q` under the tip force `force_n`,
    /// warm-started from `solver`'s memory.
    pub fn solve(
        &self,
        solver: &mut Solver<f64, N>,
        q: Joints<f64, N>,
        force_n: [f64; 3],
    ) -> Result<Solution<f64, N>, SolveError> {
        solver.solve(&self.robot, self.request(q, force_n))
    }

    /// The stability margin ([`crate::margin`]) of `sol`, just solved at actual joints
    /// `q` under `force_n` by `solver` (its memory now on `sol`): the sign of the softest
    /// mode where that is far from any fold, else the distance to the fold from forward
    /// differences of warm solves, each settled (solved twice, so that the softest mode
    /// is that of the solution's own shooting Jacobian, not of Newton's iterate before
    /// it). With `need` [`Margins::Below`] only where it may be below. The solver is
    /// not moved.
    pub fn margin(
        &self,
        solver: &Solver<f64, N>,
        q: Joints<f64, N>,
        force_n: [f64; 3],
        sol: &Solution<f64, N>,
        need: Margins,
    ) -> Margin {
        let softest = sol.softest_mode;
        match need {
            Margins::Off => return Margin::new(f64::NAN, &[]),
            Margins::Below(x) if Margin::at_least(softest).value.abs() >= x => {
                return Margin::at_least(softest)
            }
            Margins::Below(x) => {
                if let Some(m) = self.screen(solver, q, force_n, sol, x) {
                    return m;
                }
            }
            _ => {}
        }
        if !softest.is_finite() || margin::is_far(softest) {
            return Margin::new(softest, &[]);
        }
        let settled = |q: Joints<f64, N>| -> Option<f64> {
            let mut s = *solver;
            self.solve(&mut s, q, force_n).ok()?;
            let again = self.solve(&mut s, q, force_n).ok()?;
            let v = again.softest_mode;
            // a probe past the fold (or that failed) says nothing of this branch
            (v.is_finite() && v.signum() == softest.signum()).then_some(v)
        };
        let at = settled(q).unwrap_or(softest);
        let rad = PROBE_STEP.to_radians();
        let mut gradient = [0.0; 2 * MAX_TUBES];
        for (k, g) in gradient.iter_mut().enumerate().take(2 * N) {
            let moved = |sign: f64| {
                let mut p = q;
                if k < N {
                    p.s_mm[k] += sign * PROBE_STEP;
                } else {
                    p.theta_rad[k - N] += sign * rad;
                }
                settled(p)
            };
            // forward, or backward where the forward probe crossed the fold or failed
            *g = match moved(1.0) {
                Some(up) => (up - at) / PROBE_STEP,
                None => moved(-1.0).map_or(0.0, |down| (at - down) / PROBE_STEP),
            };
        }
        Margin::new(at, &gradient[..2 * N])
    }

    /// The screen of [`Margins::Below`] (`warn`) on a row the softest mode alone does not
    /// clear (see [`crate::margin`], "Screening"): the margin from the softest mode's
    /// analytic gradient ([`Solver::softest_mode_gradient`], no solves) where it is at
    /// least [`SCREEN_FACTOR`] times `warn` and every feed probe of the exact margin
    /// (forward or backward, [`PROBE_STEP`]) lies within the stretch where the solver's
    /// discrete map is smooth
    /// ([`SoftestModeGradient::smooth_within_mm`](ctr_core::SoftestModeGradient)): then
    /// the exact margin is at least `warn`, and this is the analytic margin over
    /// [`SCREEN_FACTOR`], a lower bound of it. `None`: the exact margin is needed (loads,
    /// a warning within reach, a cut or a step count within a probe's step).
    fn screen(
        &self,
        solver: &Solver<f64, N>,
        q: Joints<f64, N>,
        force_n: [f64; 3],
        sol: &Solution<f64, N>,
        warn: f64,
    ) -> Option<Margin> {
        let request = self.request(q, force_n);
        if request.loads.is_some() {
            return None;
        }
        let g = solver
            .softest_mode_gradient(&self.robot, request, sol)
            .ok()?;
        // the probes, forward or backward, within the smooth stretch
        if g.smooth_within_mm <= PROBE_STEP {
            return None;
        }
        // per mm on feeds, per degree on rotations, as the probes'
        let per_degree = 1f64.to_radians();
        let mut gradient = [0.0; 2 * MAX_TUBES];
        for i in 0..N {
            gradient[i] = g.feed[i];
            gradient[N + i] = g.rotation[i] * per_degree;
        }
        let m = Margin::new(g.value, &gradient[..2 * N]);
        (m.value >= SCREEN_FACTOR * warn).then(|| Margin {
            value: m.value / SCREEN_FACTOR,
            gradient: [0.0; MAX_JOINTS],
        })
    }

    /// [`solve`](Self::solve) with the backbone points written into `points` (as far as
    /// it reaches; the solution says how many there are), in the measuring frame.
    pub fn backbone(
        &self,
        solver: &mut Solver<f64, N>,
        q: Joints<f64, N>,
        force_n: [f64; 3],
        points: &mut [Vector3<f64>],
    ) -> Result<Solution<f64, N>, SolveError> {
        solver.solve(&self.robot, self.request(q, force_n).backbone(points))
    }

    /// [`solve`](Self::solve) without a tip force, with the joint Jacobian of the
    /// measured tip written into `jacobian` (the core's analytic one; under gravity the
    /// core has none: [`SolveError::Unsupported`]).
    pub fn jacobian(
        &self,
        solver: &mut Solver<f64, N>,
        q: Joints<f64, N>,
        jacobian: &mut JointJacobian<f64, N>,
    ) -> Result<Solution<f64, N>, SolveError> {
        solver.solve(
            &self.robot,
            self.request(q, [0.0; 3]).joint_jacobian(jacobian),
        )
    }

    /// The joint Jacobian (into `joints`) and the parameter Jacobian (into `parameters`)
    /// asked for, of the measured tip at `sol`, a solution of [`solve`](Self::solve)
    /// at `q` without a tip force: the same numbers as asking in the solve, without
    /// solving again (the core's `Solver::derivative_at`; not with a sensor offset).
    pub fn derivatives_at(
        &self,
        solver: &Solver<f64, N>,
        q: Joints<f64, N>,
        sol: &Solution<f64, N>,
        joints: Option<&mut JointJacobian<f64, N>>,
        parameters: Option<&mut ParameterJacobian<f64, N>>,
    ) -> Result<(), SolveError> {
        let request = self.request(q, [0.0; 3]);
        let request = match (joints, parameters) {
            (Some(j), Some(p)) => request.jacobians(j, p),
            (Some(j), None) => request.joint_jacobian(j),
            (None, Some(p)) => request.parameter_jacobian(p),
            (None, None) => return Ok(()),
        };
        solver.derivative_at(&self.robot, request, sol)
    }
}

/// A [`Kernel`] for the tube count a file decided.
// one per job, built once and borrowed by every solver: its size is never copied in a loop
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub(crate) enum AnyKernel {
    One(Kernel<1>),
    Two(Kernel<2>),
    Three(Kernel<3>),
    Four(Kernel<4>),
}

impl AnyKernel {
    /// The mechanics of `robot` (scaled already) under `model` with the file's `effects`.
    pub fn new(robot: &AnyRobot, model: Model, effects: &Effects) -> Self {
        match robot {
            AnyRobot::One(r) => AnyKernel::One(Kernel::new(r, model, effects)),
            AnyRobot::Two(r) => AnyKernel::Two(Kernel::new(r, model, effects)),
            AnyRobot::Three(r) => AnyKernel::Three(Kernel::new(r, model, effects)),
            AnyRobot::Four(r) => AnyKernel::Four(Kernel::new(r, model, effects)),
        }
    }

    /// This kernel with a fresh core solver (warm-start memory) of its tube count.
    pub fn bind(&self) -> Bound<'_> {
        match self {
            AnyKernel::One(k) => Bound::One(k, Solver::default()),
            AnyKernel::Two(k) => Bound::Two(k, Solver::default()),
            AnyKernel::Three(k) => Bound::Three(k, Solver::default()),
            AnyKernel::Four(k) => Bound::Four(k, Solver::default()),
        }
    }
}

/// A [`Kernel`] and a core solver of its tube count.
#[derive(Clone, Debug)]
pub(crate) enum Bound<'k> {
    One(&'k Kernel<1>, Solver<f64, 1>),
    Two(&'k Kernel<2>, Solver<f64, 2>),
    Three(&'k Kernel<3>, Solver<f64, 3>),
    Four(&'k Kernel<4>, Solver<f64, 4>),
}

/// A row's core solution, kept by [`crate::model::RowSolver::fk_kept`] for its derivatives
/// later ([`crate::model::RowSolver::derivatives_at`]).
#[derive(Clone, Copy, Debug)]
pub enum Kept {
    /// A one-tube robot's.
    One(Solution<f64, 1>),
    /// A two-tube robot's.
    Two(Solution<f64, 2>),
    /// A three-tube robot's.
    Three(Solution<f64, 3>),
    /// A four-tube robot's.
    Four(Solution<f64, 4>),
}

/// `body` with `k` (the kernel) and `s` (the solver) of whichever tube count `bound` has.
macro_rules! each_count {
    ($bound:expr, |$k:ident, $s:ident| $body:expr) => {
        match $bound {
            Bound::One($k, $s) => $body,
            Bound::Two($k, $s) => $body,
            Bound::Three($k, $s) => $body,
            Bound::Four($k, $s) => $body,
        }
    };
}

impl Bound<'_> {
    /// The tip of actual joints in file order and units (mm, degrees) under the tip
    /// force `force_n`, warm-started; with its stability margin when `margins` (else
    /// NaN: the margin's probes cost solves).
    ///
    /// # Panics
    /// If `actual.len()` is not twice the tube count.
    pub fn fk(
        &mut self,
        actual: &[f64],
        force_n: [f64; 3],
        margins: Margins,
    ) -> Result<FkResult, SolveError> {
        each_count!(self, |k, s| {
            let q = joints_of(actual);
            k.solve(s, q, force_n).map(|sol| {
                let m = k.margin(s, q, force_n, &sol, margins).value;
                FkResult::from_solution(&sol, m)
            })
        })
    }

    /// [`fk`](Self::fk) of a row without a tip force, with the joint Jacobian of the tip
    /// as measured written into `columns`: `2 n` columns in file order and units (per
    /// mm of feed, per degree of rotation), entries 0..3 the position's, 3..6 the tip
    /// frame's angular velocity in the measuring frame. The core's analytic Jacobian:
    /// under gravity it has none ([`SolveError::Unsupported`]). No stability margin.
    ///
    /// # Panics
    /// If `actual.len()` is not twice the tube count.
    pub fn fk_jacobian(
        &mut self,
        actual: &[f64],
        columns: &mut Vec<[f64; 6]>,
    ) -> Result<FkResult, SolveError> {
        each_count!(self, |k, s| {
            let q = joints_of(actual);
            let mut jac = JointJacobian::nan();
            k.jacobian(s, q, &mut jac).map(|sol| {
                joint_columns(&jac, columns);
                FkResult::from_solution(&sol, f64::NAN)
            })
        })
    }

    /// [`fk`](Self::fk) without a stability margin, with the core's solution kept for
    /// [`derivatives_at`](Self::derivatives_at).
    ///
    /// # Panics
    /// If `actual.len()` is not twice the tube count.
    pub fn fk_kept(
        &mut self,
        actual: &[f64],
        force_n: [f64; 3],
    ) -> Result<(FkResult, Kept), SolveError> {
        macro_rules! kept {
            ($k:expr, $s:expr, $variant:ident) => {
                $k.solve($s, joints_of(actual), force_n)
                    .map(|sol| (FkResult::from_solution(&sol, f64::NAN), Kept::$variant(sol)))
            };
        }
        match self {
            Bound::One(k, s) => kept!(k, s, One),
            Bound::Two(k, s) => kept!(k, s, Two),
            Bound::Three(k, s) => kept!(k, s, Three),
            Bound::Four(k, s) => kept!(k, s, Four),
        }
    }

    /// The joint columns (into `joints`, as [`fk_jacobian`](Self::fk_jacobian)'s) and
    /// the scale columns (into `scales`, [`scale_columns`]) asked for, at `kept`, the
    /// row `actual` solved by [`fk_kept`](Self::fk_kept) without a tip force by a solver
    /// of this model (any, warm or not: nothing is solved again).
    ///
    /// # Panics
    /// If `actual.len()` is not twice the tube count, or `kept` is of another tube count.
    pub fn derivatives_at(
        &self,
        actual: &[f64],
        kept: &Kept,
        joints: Option<&mut Vec<[f64; 6]>>,
        scales: Option<&mut Vec<[f64; 6]>>,
    ) -> Result<(), SolveError> {
        macro_rules! at {
            ($k:expr, $s:expr, $sol:expr) => {{
                let (mut jac, mut par) = (JointJacobian::nan(), ParameterJacobian::nan());
                let (j, p) = (joints.is_some(), scales.is_some());
                $k.derivatives_at(
                    $s,
                    joints_of(actual),
                    $sol,
                    j.then_some(&mut jac),
                    p.then_some(&mut par),
                )?;
                if let Some(columns) = joints {
                    joint_columns(&jac, columns);
                }
                if let Some(columns) = scales {
                    scale_columns(&par, columns);
                }
                Ok(())
            }};
        }
        match (self, kept) {
            (Bound::One(k, s), Kept::One(sol)) => at!(k, s, sol),
            (Bound::Two(k, s), Kept::Two(sol)) => at!(k, s, sol),
            (Bound::Three(k, s), Kept::Three(sol)) => at!(k, s, sol),
            (Bound::Four(k, s), Kept::Four(sol)) => at!(k, s, sol),
            _ => panic!("a row kept by a solver of another tube count"),
        }
    }

    /// [`fk`](Self::fk) with the backbone points (x, y, z, mm, from the guide exit to
    /// the tip) in the measuring frame.
    ///
    /// # Panics
    /// If `actual.len()` is not twice the tube count.
    pub fn backbone(
        &mut self,
        actual: &[f64],
        force_n: [f64; 3],
        margins: Margins,
    ) -> Result<(FkResult, Vec<[f64; 3]>), SolveError> {
        /// Points a backbone buffer starts with (grown to what the solve reports).
        const FIRST_POINTS: usize = 256;
        let mut points = vec![Vector3::zeros(); FIRST_POINTS];
        let memory = self.clone();
        loop {
            let sol = each_count!(&mut *self, |k, s| {
                let q = joints_of(actual);
                k.backbone(s, q, force_n, &mut points).map(|sol| {
                    let margin = k.margin(s, q, force_n, &sol, margins).value;
                    (FkResult::from_solution(&sol, margin), sol.backbone_points)
                })
            })?;
            let (tip, n) = sol;
            if n <= points.len() {
                return Ok((tip, points[..n].iter().map(|p| [p.x, p.y, p.z]).collect()));
            }
            // the same solve again, from the same memory, with room for every point
            *self = memory.clone();
            points.resize(n, Vector3::zeros());
        }
    }

    /// Forgets the warm-start memory.
    pub fn reset(&mut self) {
        each_count!(self, |_k, s| s.reset())
    }
}

/// The joint Jacobian's columns in file order and units into `columns`: per tube the
/// feed's (per mm), then the rotation's (per degree).
fn joint_columns<const N: usize>(jac: &JointJacobian<f64, N>, columns: &mut Vec<[f64; 6]>) {
    let per_degree = 1f64.to_radians();
    columns.clear();
    for (feed, rotation) in jac.feed.iter().zip(&jac.rotation) {
        columns.push(core::array::from_fn(|a| feed[a]));
        columns.push(core::array::from_fn(|a| rotation[a] * per_degree));
    }
}

/// The parameter Jacobian's columns of the `stiffness` and `precurvature` effects into
/// `columns`: per tube the stiffness scale's (E I and G J together), then per tube the
/// curvature scale's.
fn scale_columns<const N: usize>(jac: &ParameterJacobian<f64, N>, columns: &mut Vec<[f64; 6]>) {
    columns.clear();
    for (bending, torsional) in jac.bending_stiffness.iter().zip(&jac.torsional_stiffness) {
        columns.push(core::array::from_fn(|a| bending[a] + torsional[a]));
    }
    for curvature in &jac.curvature {
        columns.push(core::array::from_fn(|a| curvature[a]));
    }
}

const _: () = assert!(MAX_TUBES == 4, "AnyKernel has one variant per tube count");

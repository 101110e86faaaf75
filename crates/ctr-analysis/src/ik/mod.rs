//! Inverse kinematics: joint values that put the tip at a target position (and
//! optionally orientation), within the joint limits.
//!
//! # Method
//!
//! The seed paper's damped Levenberg-Marquardt (Liu et al. 2023, eqs. 20-21, after
//! Sugihara 2011) on the joint vector `q = (s_1, theta_1, ..., s_n, theta_n)` (mm, rad):
//!
//! ```text
//! e   = target - tip(q)          position (mm), and orientation log(R_target R^T) (rad)
//! E   = 1/2 e^T W_E e            W_E = diag(position_weight x3, orientation_weight x3)
//! g   = J^T W_E e                J = d tip / d q (orientation rows: angular velocity in W)
//! H   = J^T W_E J + W_N          W_N = diag(damping) + lambda M
//! q' = q + dq,  dq = argmin 1/2 dq^T H dq - g^T dq  subject to the joint limits
//! ```
//!
//! `M = diag(1, rotation_scale_mm^2, ...)` weighs a radian as `rotation_scale_mm`
//! millimetres. The constant damping of a rotation, `damping_rotation`, scales with
//! the square of its lever arm (`(J^T W_E J)_kk`, the tip's weighted motion per radian)
//! below `rotation_scale_mm` where the damping adapts: held fixed it would swamp a
//! rotation whose tip is near its axis, and the steps would crawl (see
//! [`IkOptions::damping_rotation`]). Without adaptive damping `W_N` is the paper's,
//! constant.
//!
//! Without limits the step is the paper's `dq = H^-1 g`. Here each step is that small
//! QP, solved with clarabel, so that `q + dq` satisfies the limits exactly: feed order
//! `s_1 <= ... <= s_n`, `0 <= s_i <= length_i`, and the robot file's `[limits]` (feed,
//! increment and rotation ranges; see [`JointLimits`]). When the unconstrained step
//! already stays inside, it is the QP's solution and clarabel is not called. The QP's
//! answer is finally projected onto the limits with exact comparisons, so every
//! iterate passes the file's and the core's checks bit for bit.
//!
//! With `adaptive_damping` (the default) `lambda` follows Nielsen's gain-ratio rule: a
//! step that lowers `E` is taken and `lambda` shrinks by up to 3 as the model predicted
//! it well; a step that does not is refused and `lambda` grows (2, 4, 8, ... times).
//! Without it `W_N = diag(damping)` and every step is taken, as in the paper.
//!
//! The Jacobian is the row model's tip Jacobian (the core's analytic one through the
//! file's static effects; under gravity central differences of the FK solved to tight
//! tolerances, probes kept inside the limits): see [`crate::model`].
//!
//! # Starts
//!
//! [`Ik::solve`] starts from `q0` when given (warm start: along a trajectory of targets,
//! the previous solution; [`Ik::solve_trajectory`] does this). A cold target, or a warm
//! start that does not reach, restarts from the joint vectors of a fixed table of
//! `seed_samples` points drawn inside the limits (deterministically from `seed`, FK
//! solved once when the [`Ik`] is built), nearest to the target first, `restarts`
//! times at most. A solve depends only on its arguments (the FK warm-start memory is
//! cleared at its start): the same target and `q0` give the same bits on any thread.
//!
//! # Unreachable targets
//!
//! A start ends when the tip is within `tolerance_mm` (and `orientation_tolerance_rad`),
//! when `E` stops decreasing (three accepted steps in a row each lowering it by less
//! than 1e-4 of itself, no step lowering it at all, or no step possible within the
//! limits: a local minimum of the distance, on the workspace boundary for a target
//! outside it), or after `max_iterations`. The result is the start that came closest,
//! with [`IkStatus::Unreachable`] when none reached. For a target far outside, the
//! Gauss-Newton model misses the curvature of the large residual and the last steps
//! are slow; the progress rule stops there, so the reported distance is that of a
//! local minimum to about 1e-4 relative (0.006 mm at 74 mm in the tests), and it
//! is never farther than the closest of 20,000 random points of the workspace.
//!
//! ```
//! use ctr_formats::{RobotSpec, TubeLimits};
//! use ctr_analysis::ik::{Ik, IkOptions, IkStatus};
//! use ctr_formats::IkTarget;
//! let mut spec = RobotSpec::from_toml_str(r#"
//! [[tube]]
//! outer_diameter_mm = 1.8
//! inner_diameter_mm = 1.5
//! length_mm = 180.0
//! curved_length_mm = 60.0
//! curvature_radius_mm = 200.0
//! youngs_modulus_mpa = 58000.0
//! poisson_ratio = 0.33
//! [[tube]]
//! outer_diameter_mm = 1.2
//! inner_diameter_mm = 0.9
//! length_mm = 260.0
//! curved_length_mm = 90.0
//! curvature_radius_mm = 100.0
//! youngs_modulus_mpa = 58000.0
//! poisson_ratio = 0.33
//! "#, "robot.toml")?;
//! let t = TubeLimits { increment_mm: Some([10.0, 60.0]), ..Default::default() };
//! spec.limits = Some(vec![t, t]);
//! let mut ik = Ik::from_spec(&spec, IkOptions::default())?;
//! let goal = ik.fk(&[30.0, 0.2, 70.0, -1.0]).unwrap();
//! let r = ik.solve(&IkTarget::position(goal.position.into()), None);
//! assert_eq!(r.status, IkStatus::Reached);
//! assert!(r.residual_mm <= 1e-4 && ik.limits().contains(&r.q));
//! let far = ik.solve(&IkTarget::position([500.0, 0.0, 0.0]), None);
//! assert_eq!(far.status, IkStatus::Unreachable);
//! assert!(far.residual_mm > 300.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Stability margin
//!
//! With [`IkOptions::min_margin`] `X` no iterate, and so no result, has a stability
//! margin ([`crate::margin`]: 1 with no snap within about 20 degrees or 20 mm, 0 at one)
//! below `X`. It is a constraint of every step, not a filter of the results:
//!
//! ```text
//! m(q + dq) ~ m(q) + grad m . dq >= level       one more row of the step's QP
//! level = min(X + MARGIN_SLACK + backoff, m(q))   (dq = 0 stays feasible)
//! ```
//!
//! `grad m` is the one the iterate's FK solve gives with its margin
//! ([`crate::margin::Margin::gradient`]), so the constraint costs no solves beyond the
//! margin's own.
//! A trial whose margin is below `X + MARGIN_SLACK` is refused like one that does not
//! lower `E` (`lambda` grows), and `backoff` grows by what the linear model
//! overestimated (it halves after each step taken). A start below the floor first takes
//! steps that raise the margin, each aiming at a fraction of the deficit that halves
//! when a step does not raise it; the table's starts are points within the floor
//! ([`IkError::MinMargin`] when none is), and when no start ends within it (a `q0`
//! below that could not be raised) one more starts from the nearest. Where the robot is
//! bistable a cold FK (a row of `ctr-cli fk`) can land on another equilibrium than the
//! one the steps followed: a start ends at its last iterate whose margin clears the
//! floor solved cold as well. A target not reached whose last steps the margin shaped,
//! or whose result is within [`MARGIN_ACTIVE_BAND`] of `X`, is
//! [`IkStatus::UnreachableWithMargin`]: the closest point found within the floor.
//!
//! ```
//! use ctr_analysis::ik::{Ik, IkOptions, IkStatus};
//! use ctr_formats::{IkTarget, RobotSpec, TubeLimits};
//! // the seed's robot with 100 mm longer transmissions: the pair snaps
//! let mut spec = RobotSpec::from_toml_str(r#"
//! [[tube]]
//! outer_diameter_mm = 6.8
//! inner_diameter_mm = 4.9
//! length_mm = 224.0
//! curved_length_mm = 74.0
//! curvature_radius_mm = -97.0
//! youngs_modulus_mpa = 150.0
//! poisson_ratio = 0.41
//! [[tube]]
//! outer_diameter_mm = 4.5
//! inner_diameter_mm = 3.3
//! length_mm = 274.0
//! curved_length_mm = 114.0
//! curvature_radius_mm = 98.5
//! youngs_modulus_mpa = 300.0
//! poisson_ratio = 0.41
//! "#, "robot.toml")?;
//! // feeds pinned: only the rotations move
//! let pin = |s: f64| TubeLimits { s_mm: Some([s, s]), ..Default::default() };
//! spec.limits = Some(vec![pin(55.0), pin(95.0)]);
//! let options = IkOptions { min_margin: Some(0.4), ..Default::default() };
//! let mut ik = Ik::from_spec(&spec, options)?;
//! // near the opposed curvatures the margin is low: that tip is refused...
//! let low = ik.from_file_units(&[55.0, 0.0, 95.0, 18.0]);
//! assert!(ik.stability_margin(&low).unwrap() < 0.4);
//! let tip = ik.fk(&low).unwrap().position;
//! let r = ik.solve(&IkTarget::position(tip.into()), None);
//! assert_eq!(r.status, IkStatus::UnreachableWithMargin);
//! assert!(r.stability_margin >= 0.4 && ik.stability_margin(&r.q).unwrap() >= 0.4);
//! // ... and one farther from it reached
//! let calm = ik.from_file_units(&[55.0, 0.0, 95.0, 90.0]);
//! let tip = ik.fk(&calm).unwrap().position;
//! assert_eq!(ik.solve(&IkTarget::position(tip.into()), None).status, IkStatus::Reached);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod margin;
mod options;
mod qp;
mod step;

pub use margin::{MARGIN_ACTIVE_BAND, MARGIN_SLACK};
pub use options::{IkError, IkOptions, IkResult, IkStatus};
use step::{nan_frame, Attempt, End};

use crate::limits::JointLimits;
use crate::model::{file_jacobian, ModelSpec, TipFk};
use crate::rng::Rng;
use ctr_core::{Frame, Model};
use ctr_formats::AnyRobot;
use ctr_formats::{Effects, IkTarget, RobotSpec, TubeLimits};

use qp::StepQp;

/// An inverse-kinematics solver for one robot, its model and its limits. Holds the
/// FK warm-start memory, the start table and one clarabel solver; clone it for each
/// thread.
pub struct Ik {
    fk: Box<dyn TipFk>,
    limits: JointLimits,
    qp: StepQp,
    options: IkOptions,
    /// start table: joints, tip and stability margin
    samples: Vec<(Vec<f64>, Frame<f64>, f64)>,
}

impl Clone for Ik {
    fn clone(&self) -> Self {
        Ik {
            fk: self.fk.boxed_clone(),
            limits: self.limits.clone(),
            qp: self.qp.clone(),
            options: self.options,
            samples: self.samples.clone(),
        }
    }
}

impl std::fmt::Debug for Ik {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ik")
            .field("n_tubes", &self.fk.n_tubes())
            .field("limits", &self.limits)
            .field("options", &self.options)
            .field("samples", &self.samples.len())
            .finish()
    }
}

// one `Ik` per thread: it must be able to move there
const _: fn() = || {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<Ik>();
};

impl Ik {
    /// An IK solver for `robot` solved with `model`, within the core's joint ranges and
    /// `limits` (one entry per tube, as in the robot file's `[limits]`).
    pub fn new(
        robot: &AnyRobot,
        model: Model,
        limits: Option<&[TubeLimits]>,
        options: IkOptions,
    ) -> Result<Ik, IkError> {
        Ik::with_effects(robot, model, &Effects::default(), limits, options)
    }

    /// As [`new`](Self::new), with a robot file's `[model.effects]` (`robot` as
    /// described, unscaled). The forward model inside the IK is the file's whole static
    /// model ([`crate::model`]): joint offsets (the joints found are the commanded ones),
    /// scaled tubes, clearance kinks or gravity, and the tip as measured (sensor offset,
    /// registration): targets are in the measuring frame. Time effects (latency,
    /// friction with a non-zero play) make a row's tip depend on the rows before it and
    /// cannot be inverted row by row: refused ([`IkError::Effect`]).
    pub fn with_effects(
        robot: &AnyRobot,
        model: Model,
        effects: &Effects,
        limits: Option<&[TubeLimits]>,
        options: IkOptions,
    ) -> Result<Ik, IkError> {
        let spec = ModelSpec {
            robot: *robot,
            model,
            effects: effects.clone(),
            empirical: None,
            discrepancy: None,
        };
        let rows = spec.rows().map_err(|e| IkError::Effect(e.to_string()))?;
        for (effect, on) in [
            ("latency", effects.latency.is_some_and(|l| l.tau_s != 0.0)),
            (
                "friction",
                effects
                    .friction
                    .as_ref()
                    .is_some_and(ctr_formats::Friction::acts),
            ),
        ] {
            if on {
                return Err(IkError::Effect(format!(
                    "model.effects.{effect}: a time effect cannot be inverted target by target \
                     (the tip at a row depends on the rows before it); ik solves the static \
                     model: remove the {effect} table for ik"
                )));
            }
        }
        options.check()?;
        let lengths: Vec<f64> = robot.tube_params().iter().map(|p| p.length_mm).collect();
        let limits = JointLimits::new(&lengths, limits)?;
        let mut fk = rows.tip_fk();
        if options.min_margin.is_some() {
            fk.with_margins();
        }
        let mut rng = Rng::new(options.seed);
        let n = 2 * limits.n_tubes();
        let mut samples = Vec::with_capacity(options.seed_samples);
        for k in 0..options.seed_samples {
            let q = if k == 0 {
                limits.center()
            } else {
                let u: Vec<f64> = (0..n).map(|_| rng.uniform()).collect();
                limits.point(&u)
            };
            if let Some(s) = fk.cold(&q) {
                samples.push((q, s.tip, s.margin));
            }
        }
        if let Some(x) = options.min_margin {
            let floor = margin::floor(x);
            if !samples.iter().any(|s| s.2 >= floor) {
                return Err(IkError::MinMargin {
                    min_margin: x,
                    samples: samples.len(),
                    largest: samples.iter().map(|s| s.2).fold(f64::NAN, f64::max),
                });
            }
        }
        Ok(Ik {
            fk,
            qp: StepQp::new(&limits, options.min_margin.is_some()),
            limits,
            options,
            samples,
        })
    }

    /// An IK solver for a robot file's robot, model, effects (see
    /// [`with_effects`](Self::with_effects)) and `[limits]`.
    pub fn from_spec(spec: &RobotSpec, options: IkOptions) -> Result<Ik, IkError> {
        Ik::for_spec(spec, spec.model, options)
    }

    /// [`from_spec`](Self::from_spec) under `model` instead of the file's kind. A file
    /// with a `[model.empirical]` correction is refused ([`IkError::Effect`]): the IK
    /// inverts the physical model only, and would silently leave the correction out.
    pub fn for_spec(spec: &RobotSpec, model: Model, options: IkOptions) -> Result<Ik, IkError> {
        if spec.discrepancy.is_some() {
            return Err(IkError::Effect(
                "model.discrepancy: the inverse kinematics inverts the physical model only and \
                 cannot take a learned discrepancy; remove [model.discrepancy] from the robot \
                 file for ik"
                    .into(),
            ));
        }
        if spec.empirical.is_some() {
            return Err(IkError::Effect(
                "model.empirical: the inverse kinematics inverts the physical model only and \
                 cannot take a data-driven correction; remove [model.empirical] from the robot \
                 file for ik"
                    .into(),
            ));
        }
        Ik::with_effects(
            &spec.robot,
            model,
            &spec.effects,
            spec.limits.as_deref(),
            options,
        )
    }

    /// The settings.
    pub fn options(&self) -> &IkOptions {
        &self.options
    }

    /// The limits every result satisfies.
    pub fn limits(&self) -> &JointLimits {
        &self.limits
    }

    /// The number of tubes.
    pub fn n_tubes(&self) -> usize {
        self.fk.n_tubes()
    }

    /// Joints in file units (mm, degrees) from solver units (see
    /// [`JointLimits::to_file_units`]).
    pub fn to_file_units(&self, q: &[f64]) -> Vec<f64> {
        self.limits.to_file_units(q)
    }

    /// Joints in solver units (mm, rad) from file units (mm, degrees).
    pub fn from_file_units(&self, joints: &[f64]) -> Vec<f64> {
        self.limits.from_file_units(joints)
    }

    /// The tip Jacobian at `joints` (file units: `s_1` mm, `theta_1` degrees, ...) as
    /// the IK computes it: the row model's
    /// ([`RowModel::tip_jacobian`](crate::model::RowModel::tip_jacobian)), with probes
    /// kept inside this solver's limits where it takes differences. `None` when the
    /// joints are outside the core's ranges or the FK does not converge there.
    ///
    /// # Panics
    /// If `joints` does not have `2 n` values.
    ///
    /// ```
    /// use ctr_analysis::ik::{Ik, IkOptions};
    /// use ctr_core::{Model, TubeParams};
    /// let t = TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33); // straight
    /// let robot = ctr_formats::AnyRobot::new(&[t]).unwrap();
    /// let options = IkOptions { seed_samples: 0, ..Default::default() };
    /// let ik = Ik::new(&robot, Model::Torsion, None, options).unwrap();
    /// let j = ik.tip_jacobian(&[50.0, 30.0]).unwrap();
    /// assert!((j[0][2] - 1.0).abs() < 1e-6); // feeding moves the tip along z
    /// ```
    pub fn tip_jacobian(&self, joints: &[f64]) -> Option<Vec<[f64; 6]>> {
        file_jacobian(&mut *self.fk.boxed_clone(), &self.limits, joints)
    }

    /// The tip at `q` (mm, rad), solved cold with the IK's tight FK tolerances; `None`
    /// when the joints are outside the core's ranges or the solve does not converge.
    pub fn fk(&self, q: &[f64]) -> Option<Frame<f64>> {
        assert_eq!(q.len(), 2 * self.n_tubes());
        self.fk.cold(q).map(|s| s.tip)
    }

    /// The stability margin ([`crate::margin`]) at `q` (mm, rad), solved cold as
    /// [`fk`](Self::fk) solves it: dimensionless, 1 with no snap within about 20 degrees
    /// or 20 mm, 0 at one. `None` where the FK does not converge.
    ///
    /// # Panics
    /// If `q` does not have `2 n` values.
    ///
    /// ```
    /// use ctr_analysis::ik::{Ik, IkOptions};
    /// use ctr_core::{Model, TubeParams};
    /// let t = TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33); // one tube
    /// let robot = ctr_formats::AnyRobot::new(&[t]).unwrap();
    /// let ik = Ik::new(&robot, Model::Torsion, None, IkOptions::default()).unwrap();
    /// assert_eq!(ik.stability_margin(&[50.0, 0.3]), Some(1.0)); // nothing to snap
    /// ```
    pub fn stability_margin(&self, q: &[f64]) -> Option<f64> {
        assert_eq!(q.len(), 2 * self.n_tubes());
        let mut fk = self.fk.boxed_clone();
        fk.with_margins();
        fk.cold(q).map(|s| s.margin)
    }

    /// Solves for `target` from `q0` (mm, rad; projected onto the limits), or cold
    /// from the start table when `q0` is `None`. When the first start does not reach,
    /// up to `restarts` more start from the table's points nearest the target; the
    /// result is the start that reached, or else the closest.
    ///
    /// # Panics
    /// If `q0` does not have `2 n` values.
    pub fn solve(&mut self, target: &IkTarget, q0: Option<&[f64]>) -> IkResult {
        self.solve_observed(target, q0, &mut |_| {})
    }

    /// As [`solve`](Self::solve), calling `observer` with every joint vector the
    /// forward kinematics is solved at as an iterate or trial step (not the
    /// finite-difference probes, which stay within `1e-6` of an iterate).
    pub fn solve_observed(
        &mut self,
        target: &IkTarget,
        q0: Option<&[f64]>,
        observer: &mut dyn FnMut(&[f64]),
    ) -> IkResult {
        let n = 2 * self.n_tubes();
        let mut best: Option<Attempt> = None;
        let mut iterations = 0;
        let mut starts = 0;
        let max_starts = 1 + self.options.restarts as usize;
        let mut first = q0.map(|q| {
            assert_eq!(q.len(), n, "q0 must have {n} values");
            let mut q = q.to_vec();
            self.limits.project(&mut q);
            q
        });
        let mut table: Option<std::vec::IntoIter<Vec<f64>>> = None;
        while starts < max_starts {
            let start = match first.take() {
                Some(q) => q,
                None => {
                    let t = table
                        .get_or_insert_with(|| self.cold_starts(target, max_starts).into_iter());
                    match t.next() {
                        Some(q) => q,
                        None => break,
                    }
                }
            };
            starts += 1;
            let a = self.run(target, start, observer);
            iterations += a.iterations;
            let reached = a.end == End::Reached;
            if best.as_ref().is_none_or(|b| better(&a, b)) {
                best = Some(a);
            }
            if reached {
                break;
            }
        }
        if best.as_ref().is_some_and(|b| !b.feasible) {
            // with a margin floor and no start within it (a warm start below it that
            // could not be raised): the table's points are within it, and so is the
            // first iterate of a start from one of them
            let nearest = self.cold_starts(target, 1).into_iter().next();
            if let Some(q) = nearest {
                starts += 1;
                let a = self.run(target, q, observer);
                iterations += a.iterations;
                if best.as_ref().is_none_or(|b| better(&a, b)) {
                    best = Some(a);
                }
            }
        }
        let a = best.filter(|b| b.feasible).unwrap_or_else(|| Attempt {
            q: self.limits.center(),
            tip: nan_frame(),
            cost: f64::INFINITY,
            iterations: 0,
            end: End::FkFailed,
            margin: f64::NAN,
            feasible: false,
            held: false,
        });
        let (pos, ori) = self.residuals(target, &a.tip);
        let margin_active = self.options.min_margin.is_some_and(|x| {
            a.end != End::FkFailed && (a.held || a.margin - x <= MARGIN_ACTIVE_BAND)
        });
        IkResult {
            status: match a.end {
                End::Reached => IkStatus::Reached,
                _ if margin_active => IkStatus::UnreachableWithMargin,
                End::Stalled => IkStatus::Unreachable,
                End::IterationLimit => IkStatus::IterationLimit,
                End::FkFailed => IkStatus::FkFailed,
            },
            q: a.q,
            tip: a.tip,
            residual_mm: pos,
            orientation_residual_rad: ori,
            iterations,
            starts: starts as u32,
            stability_margin: a.margin,
        }
    }

    /// Solves a trajectory of targets in order, each warm-started from the previous
    /// result (the first from `q0`, or cold).
    pub fn solve_trajectory(&mut self, targets: &[IkTarget], q0: Option<&[f64]>) -> Vec<IkResult> {
        let mut prev = q0.map(<[f64]>::to_vec);
        targets
            .iter()
            .map(|t| {
                let r = self.solve(t, prev.as_deref());
                prev = Some(r.q.clone());
                r
            })
            .collect()
    }

    /// The start table's joint vectors nearest the target first (at most `count`; with
    /// a margin floor, those within it), or without a table the middle of the limits and
    /// seeded random points.
    fn cold_starts(&self, target: &IkTarget, count: usize) -> Vec<Vec<f64>> {
        if self.samples.is_empty() {
            let mut rng = Rng::new(self.options.seed);
            let n = 2 * self.n_tubes();
            return (0..count)
                .map(|k| {
                    if k == 0 {
                        self.limits.center()
                    } else {
                        let u: Vec<f64> = (0..n).map(|_| rng.uniform()).collect();
                        self.limits.point(&u)
                    }
                })
                .collect();
        }
        // with a margin floor, only the points within it (without, margins are NaN: not
        // computed)
        let within = |m: f64| {
            self.options
                .min_margin
                .is_none_or(|x| m >= margin::floor(x))
        };
        let mut order: Vec<(f64, usize)> = self
            .samples
            .iter()
            .enumerate()
            .filter(|(_, s)| within(s.2))
            .map(|(k, (_, tip, _))| (self.error(target, tip).1, k))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        order
            .iter()
            .take(count)
            .map(|&(_, k)| self.samples[k].0.clone())
            .collect()
    }
}

/// Whether attempt `a` is a better result than `b`: one within the margin floor beats
/// one below it; then one that reached; then the closer one that solved.
fn better(a: &Attempt, b: &Attempt) -> bool {
    if a.feasible != b.feasible {
        return a.feasible;
    }
    a.end == End::Reached || (a.end != End::FkFailed && (b.end == End::FkFailed || a.cost < b.cost))
}

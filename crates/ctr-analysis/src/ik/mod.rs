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
//! H   = J^T W_E J + W_N          W_N = diag(damping) + lambda diag(J^T W_E J)
//! q' = q + dq,  dq = argmin 1/2 dq^T H dq - g^T dq  subject to the joint limits
//! ```
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
//! The Jacobian comes from central finite differences of the core's forward
//! kinematics, solved to tight tolerances (one function, `fk::tip_jacobian`, to be
//! replaced by the core's analytic Jacobian when it has one).
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

mod fk;
mod limits;
mod qp;

pub use fk::{FD_STEP_MM, FD_STEP_RAD, FK_ACCEPT_RESIDUAL, FK_RESIDUAL_TOLERANCE};
pub use limits::{JointLimits, LimitsError, RotationRange};

use crate::model::{AnyKernel, ModelSpec};
use ctr_core::{Frame, Model};
use ctr_formats::AnyRobot;
use ctr_formats::{Effects, IkTarget, RobotSpec, TubeLimits};
use fk::{log_so3, tip_jacobian, CoreFk, Jacobian, TipFk, MAX_JOINTS};
use nalgebra::{SMatrix, SVector, Vector3, Vector6};

type Square = SMatrix<f64, MAX_JOINTS, MAX_JOINTS>;
type Joint = SVector<f64, MAX_JOINTS>;
use qp::StepQp;

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IkStatus {
    /// The tip is within the tolerances of the target.
    Reached,
    /// No start reached the target: every one ended where the distance stops
    /// decreasing within the limits. `q` is the closest point found (for a target
    /// outside the workspace, the closest reachable point).
    Unreachable,
    /// The closest start was still improving when it ran out of iterations.
    IterationLimit,
    /// The forward kinematics could not be solved at any start point.
    FkFailed,
}

impl IkStatus {
    /// Lower-case name for files and messages: `reached`, `unreachable`,
    /// `iteration_limit`, `fk_failed`.
    pub fn name(self) -> &'static str {
        match self {
            IkStatus::Reached => "reached",
            IkStatus::Unreachable => "unreachable",
            IkStatus::IterationLimit => "iteration_limit",
            IkStatus::FkFailed => "fk_failed",
        }
    }
}

/// The result of one solve.
#[derive(Clone, Debug, PartialEq)]
pub struct IkResult {
    /// Joints `s_1 (mm), theta_1 (rad), ...`, inside the limits
    /// ([`Ik::to_file_units`] for mm and degrees).
    pub q: Vec<f64>,
    /// The tip at `q` (NaN when the status is `FkFailed`).
    pub tip: Frame<f64>,
    /// Distance from the tip to the target position, mm.
    pub residual_mm: f64,
    /// Angle between the tip and target orientations, rad (`None` for a position-only
    /// target).
    pub orientation_residual_rad: Option<f64>,
    /// Levenberg-Marquardt steps over all starts.
    pub iterations: u32,
    /// Starts tried (1 when the first reached).
    pub starts: u32,
    /// How it ended.
    pub status: IkStatus,
}

/// Settings of the solver. Units: mm and rad.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkOptions {
    /// `W_E` on each position component, 1/mm^2 (scales the cost only relative to
    /// `orientation_weight` and the damping).
    pub position_weight: f64,
    /// `W_E` on each orientation component, 1/rad^2 (default 100: 1 rad weighs as 10 mm).
    pub orientation_weight: f64,
    /// Constant part of `W_N` on each feed (mm^2 of tip error per mm^2 of feed).
    pub damping_feed: f64,
    /// Constant part of `W_N` on each rotation (mm^2 of tip error per rad^2).
    pub damping_rotation: f64,
    /// Adapt `lambda M` on top of the constant damping (module docs).
    pub adaptive_damping: bool,
    /// Starting `lambda` of each start.
    pub initial_lambda: f64,
    /// The length that makes a radian comparable to a millimetre in the adaptive
    /// damping `lambda M`, `M = diag(1, rotation_scale_mm^2, ...)`, mm.
    pub rotation_scale_mm: f64,
    /// Reached when the tip is this close to the target position, mm.
    pub tolerance_mm: f64,
    /// ... and, for a pose target, this close in orientation, rad.
    pub orientation_tolerance_rad: f64,
    /// Most steps per start.
    pub max_iterations: u32,
    /// Further starts after the first when it does not reach.
    pub restarts: u32,
    /// Seed of the start table.
    pub seed: u64,
    /// Points in the start table (drawn inside the limits when the [`Ik`] is built).
    pub seed_samples: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            position_weight: 1.0,
            orientation_weight: 100.0,
            damping_feed: 1e-6,
            damping_rotation: 1e-4,
            adaptive_damping: true,
            initial_lambda: 1e-3,
            rotation_scale_mm: 10.0,
            tolerance_mm: 1e-4,
            orientation_tolerance_rad: 1e-4,
            max_iterations: 100,
            restarts: 8,
            seed: 0x5eed,
            seed_samples: 256,
        }
    }
}

/// Why an [`Ik`] cannot be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum IkError {
    /// The limits are unusable.
    #[error(transparent)]
    Limits(#[from] LimitsError),
    /// An effect of the robot file cannot be inverted row by row (latency, friction),
    /// or does not fit the robot; the message starts with its key.
    #[error("{0}")]
    Effect(String),
    /// An option is out of its range.
    #[error("IK option {name} = {value} must be {wanted}")]
    Option {
        /// the field of [`IkOptions`]
        name: &'static str,
        /// its value
        value: f64,
        /// what it must be
        wanted: &'static str,
    },
}

/// Relative decrease of `E` below which an accepted step counts as no progress.
const STALL_DECREASE: f64 = 1e-4;
/// Accepted steps without progress in a row that end a start.
const STALL_STEPS: u32 = 3;
/// A step shorter than this (mm or rad, largest component) ends a start.
const MIN_STEP: f64 = 1e-11;
/// `lambda` beyond which no step can lower `E`: the start ends.
const MAX_LAMBDA: f64 = 1e12;
/// Smallest `lambda` (the constant damping stays underneath).
const MIN_LAMBDA: f64 = 1e-12;

/// An inverse-kinematics solver for one robot, its model and its limits. Holds the
/// FK warm-start memory, the start table and one clarabel solver; clone it for each
/// thread.
pub struct Ik {
    fk: Box<dyn TipFk>,
    limits: JointLimits,
    qp: StepQp,
    options: IkOptions,
    /// start table: joints and tip
    samples: Vec<(Vec<f64>, Frame<f64>)>,
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

/// SplitMix64: a small deterministic generator for the start table.
struct SplitMix(u64);

impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// How one start ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum End {
    Reached,
    Stalled,
    IterationLimit,
    FkFailed,
}

struct Attempt {
    q: Vec<f64>,
    tip: Frame<f64>,
    cost: f64,
    iterations: u32,
    end: End,
}

fn check_option(
    name: &'static str,
    value: f64,
    ok: bool,
    wanted: &'static str,
) -> Result<(), IkError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(IkError::Option {
            name,
            value,
            wanted,
        })
    }
}

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
        };
        let rows = spec.rows().map_err(|e| IkError::Effect(e.to_string()))?;
        for (effect, on) in [
            ("latency", effects.latency.is_some_and(|l| l.tau_s != 0.0)),
            (
                "friction",
                effects.friction.as_ref().is_some_and(|f| {
                    f.rotation_play_deg
                        .iter()
                        .chain(&f.feed_play_mm)
                        .any(|&w| w > 0.0)
                }),
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
        let o = &options;
        check_option(
            "position_weight",
            o.position_weight,
            o.position_weight > 0.0,
            "> 0",
        )?;
        check_option(
            "orientation_weight",
            o.orientation_weight,
            o.orientation_weight >= 0.0,
            ">= 0",
        )?;
        check_option("damping_feed", o.damping_feed, o.damping_feed > 0.0, "> 0")?;
        check_option(
            "damping_rotation",
            o.damping_rotation,
            o.damping_rotation > 0.0,
            "> 0",
        )?;
        check_option(
            "initial_lambda",
            o.initial_lambda,
            o.initial_lambda >= 0.0,
            ">= 0",
        )?;
        check_option(
            "rotation_scale_mm",
            o.rotation_scale_mm,
            o.rotation_scale_mm > 0.0,
            "> 0",
        )?;
        check_option("tolerance_mm", o.tolerance_mm, o.tolerance_mm > 0.0, "> 0")?;
        check_option(
            "orientation_tolerance_rad",
            o.orientation_tolerance_rad,
            o.orientation_tolerance_rad > 0.0,
            "> 0",
        )?;
        let lengths: Vec<f64> = robot.tube_params().iter().map(|p| p.length_mm).collect();
        let limits = JointLimits::new(&lengths, limits)?;
        let offsets = &rows.time_effects().joint_offset;
        let fk: Box<dyn TipFk> = match rows.kernel() {
            AnyKernel::One(k) => Box::new(CoreFk::new(*k, offsets)),
            AnyKernel::Two(k) => Box::new(CoreFk::new(*k, offsets)),
            AnyKernel::Three(k) => Box::new(CoreFk::new(*k, offsets)),
            AnyKernel::Four(k) => Box::new(CoreFk::new(*k, offsets)),
        };
        let mut rng = SplitMix(options.seed);
        let n = 2 * limits.n_tubes();
        let mut samples = Vec::with_capacity(options.seed_samples);
        for k in 0..options.seed_samples {
            let q = if k == 0 {
                limits.center()
            } else {
                let u: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
                limits.point(&u)
            };
            if let Some(tip) = fk.cold(&q) {
                samples.push((q, tip));
            }
        }
        Ok(Ik {
            fk,
            qp: StepQp::new(&limits),
            limits,
            options,
            samples,
        })
    }

    /// An IK solver for a robot file's robot, model, effects (see
    /// [`with_effects`](Self::with_effects)) and `[limits]`.
    pub fn from_spec(spec: &RobotSpec, options: IkOptions) -> Result<Ik, IkError> {
        Ik::with_effects(
            &spec.robot,
            spec.model,
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

    /// The tip at `q` (mm, rad), solved cold with the IK's tight FK tolerances; `None`
    /// when the joints are outside the core's ranges or the solve does not converge.
    pub fn fk(&self, q: &[f64]) -> Option<Frame<f64>> {
        assert_eq!(q.len(), 2 * self.n_tubes());
        self.fk.cold(q)
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
            let better = reached
                || match &best {
                    None => true,
                    Some(b) => {
                        a.end != End::FkFailed && (b.end == End::FkFailed || a.cost < b.cost)
                    }
                };
            if better {
                best = Some(a);
            }
            if reached {
                break;
            }
        }
        let a = best.unwrap_or_else(|| Attempt {
            q: self.limits.center(),
            tip: nan_frame(),
            cost: f64::INFINITY,
            iterations: 0,
            end: End::FkFailed,
        });
        let (pos, ori) = self.residuals(target, &a.tip);
        IkResult {
            status: match a.end {
                End::Reached => IkStatus::Reached,
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

    /// The start table's joint vectors nearest the target first (at most `count`), or
    /// without a table the middle of the limits and seeded random points.
    fn cold_starts(&self, target: &IkTarget, count: usize) -> Vec<Vec<f64>> {
        if self.samples.is_empty() {
            let mut rng = SplitMix(self.options.seed);
            let n = 2 * self.n_tubes();
            return (0..count)
                .map(|k| {
                    if k == 0 {
                        self.limits.center()
                    } else {
                        let u: Vec<f64> = (0..n).map(|_| rng.next_f64()).collect();
                        self.limits.point(&u)
                    }
                })
                .collect();
        }
        let mut order: Vec<(f64, usize)> = self
            .samples
            .iter()
            .enumerate()
            .map(|(k, (_, tip))| (self.error(target, tip).1, k))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        order
            .iter()
            .take(count)
            .map(|&(_, k)| self.samples[k].0.clone())
            .collect()
    }

    /// The diagonal of `W_E` (orientation weights 0 for a position-only target).
    fn weights(&self, target: &IkTarget) -> Vector6<f64> {
        let o = &self.options;
        let ow = if target.orientation.is_some() {
            o.orientation_weight
        } else {
            0.0
        };
        Vector6::new(
            o.position_weight,
            o.position_weight,
            o.position_weight,
            ow,
            ow,
            ow,
        )
    }

    /// The error `target - tip` (position, then orientation or zeros) and
    /// `E = 1/2 e^T W_E e`.
    fn error(&self, target: &IkTarget, tip: &Frame<f64>) -> (Vector6<f64>, f64) {
        let w = self.weights(target);
        let mut e = Vector6::zeros();
        e.fixed_rows_mut::<3>(0)
            .copy_from(&(target.position - tip.position));
        if let Some(o) = &target.orientation {
            let r = o.to_rotation_matrix().into_inner() * tip.rotation.transpose();
            e.fixed_rows_mut::<3>(3).copy_from(&log_so3(&r));
        }
        let cost = 0.5 * e.component_mul(&e).dot(&w);
        (e, cost)
    }

    /// Position distance (mm) and orientation angle (rad) from the target.
    fn residuals(&self, target: &IkTarget, tip: &Frame<f64>) -> (f64, Option<f64>) {
        let pos = (target.position - tip.position).norm();
        let ori = target.orientation.map(|o| {
            let r = o.to_rotation_matrix().into_inner() * tip.rotation.transpose();
            log_so3(&r).norm()
        });
        (pos, ori)
    }

    fn reached(&self, target: &IkTarget, tip: &Frame<f64>) -> bool {
        let (pos, ori) = self.residuals(target, tip);
        pos <= self.options.tolerance_mm
            && ori.is_none_or(|a| a <= self.options.orientation_tolerance_rad)
    }

    /// One Levenberg-Marquardt run from `q` (inside the limits).
    fn run(
        &mut self,
        target: &IkTarget,
        mut q: Vec<f64>,
        observer: &mut dyn FnMut(&[f64]),
    ) -> Attempt {
        let n = q.len();
        let o = self.options;
        let w = self.weights(target);
        self.fk.reset();
        observer(&q);
        let Some(mut tip) = self.fk.trial(&q) else {
            return Attempt {
                q,
                tip: nan_frame(),
                cost: f64::INFINITY,
                iterations: 0,
                end: End::FkFailed,
            };
        };
        self.fk.accept();
        let (mut e, mut cost) = self.error(target, &tip);
        let mut lambda = o.initial_lambda;
        let mut nu = 2.0;
        let mut jac = Jacobian::zeros();
        let mut a = Square::zeros();
        let mut g = Joint::zeros();
        let mut fresh = false;
        let mut stalls = 0;
        let mut iterations = 0;
        let end = loop {
            if self.reached(target, &tip) {
                break End::Reached;
            }
            if iterations >= o.max_iterations {
                break End::IterationLimit;
            }
            iterations += 1;
            if !fresh {
                tip_jacobian(&*self.fk, &self.limits, &q, &tip, &mut jac);
                let mut jw = jac.transpose();
                for (c, wc) in w.iter().enumerate() {
                    jw.column_mut(c).scale_mut(*wc);
                }
                a = jw * jac;
                g = jw * e;
                fresh = true;
                if !(a.iter().all(|v| v.is_finite()) && g.iter().all(|v| v.is_finite())) {
                    break End::Stalled;
                }
            }
            let mut h = a;
            for k in n..MAX_JOINTS {
                // padding: an identity block gives a zero step there
                h[(k, k)] = 1.0;
            }
            for k in 0..n {
                let (base, metric) = if k % 2 == 0 {
                    (o.damping_feed, 1.0)
                } else {
                    (
                        o.damping_rotation,
                        o.rotation_scale_mm * o.rotation_scale_mm,
                    )
                };
                let adapt = if o.adaptive_damping {
                    lambda * metric
                } else {
                    0.0
                };
                h[(k, k)] += base + adapt;
            }
            // the unconstrained minimizer is the QP's solution when it stays inside
            let free = h.cholesky().map(|c| c.solve(&g));
            let inside = free.as_ref().is_some_and(|dq| {
                let trial: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
                self.limits.admits(&trial)
            });
            let dq = match (free, inside) {
                (Some(dq), true) => dq,
                _ => match self
                    .qp
                    .step(&h, &g, &q)
                    .map(|dq| Joint::from_fn(|k, _| if k < n { dq[k] } else { 0.0 }))
                {
                    // dq = 0 is feasible with model value 0: a solution must not be worse
                    Some(dq)
                        if 0.5 * dq.dot(&(h * dq)) - g.dot(&dq) <= 1e-12 * g.norm() * dq.norm() =>
                    {
                        dq
                    }
                    _ => {
                        // clarabel failed: damp harder, as for a refused step
                        if !o.adaptive_damping {
                            break End::Stalled;
                        }
                        lambda = (lambda * nu).max(1e-6);
                        nu *= 2.0;
                        if lambda > MAX_LAMBDA {
                            break End::Stalled;
                        }
                        continue;
                    }
                },
            };
            let mut q_new: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
            self.limits.project(&mut q_new);
            let moved = q
                .iter()
                .zip(&q_new)
                .enumerate()
                .map(|(k, (a, b))| {
                    let d = b - a;
                    if k % 2 == 1 {
                        // a wrap of a full turn is no move
                        let t = std::f64::consts::TAU;
                        (d - t * (d / t).round()).abs()
                    } else {
                        d.abs()
                    }
                })
                .fold(0.0, f64::max);
            if moved < MIN_STEP {
                break End::Stalled;
            }
            observer(&q_new);
            let trial = self.fk.trial(&q_new);
            let accepted = match trial {
                None => None,
                Some(t) => {
                    let (e_new, cost_new) = self.error(target, &t);
                    (cost_new < cost || !o.adaptive_damping).then_some((t, e_new, cost_new))
                }
            };
            match accepted {
                Some((t, e_new, cost_new)) => {
                    // predicted decrease of the Gauss-Newton model for this step
                    let pred = g.dot(&dq) - 0.5 * dq.dot(&(a * dq));
                    let rho = if pred > 0.0 {
                        (cost - cost_new) / pred
                    } else {
                        1.0
                    };
                    let progress = (cost - cost_new) / cost;
                    q = q_new;
                    tip = t;
                    e = e_new;
                    cost = cost_new;
                    self.fk.accept();
                    fresh = false;
                    if o.adaptive_damping {
                        lambda = (lambda
                            * (1.0_f64 / 3.0).max(1.0 - (2.0 * rho - 1.0_f64).powi(3)))
                        .max(MIN_LAMBDA);
                        nu = 2.0;
                    }
                    if progress < STALL_DECREASE {
                        stalls += 1;
                        if stalls >= STALL_STEPS {
                            break End::Stalled;
                        }
                    } else {
                        stalls = 0;
                    }
                }
                None => {
                    if !o.adaptive_damping {
                        break End::Stalled;
                    }
                    lambda = (lambda * nu).max(1e-6);
                    nu *= 2.0;
                    if lambda > MAX_LAMBDA {
                        break End::Stalled;
                    }
                }
            }
        };
        let end = if end != End::Reached && self.reached(target, &tip) {
            End::Reached
        } else {
            end
        };
        Attempt {
            q,
            tip,
            cost,
            iterations,
            end,
        }
    }
}

fn nan_frame() -> Frame<f64> {
    Frame {
        rotation: nalgebra::Matrix3::from_element(f64::NAN),
        position: Vector3::from_element(f64::NAN),
    }
}

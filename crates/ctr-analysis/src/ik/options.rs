//! What an IK solve is asked and what it answers: the settings ([`IkOptions`]), the
//! result ([`IkResult`], [`IkStatus`]) and why a solver cannot be built ([`IkError`]).

#[cfg(doc)]
use super::Ik;
use crate::limits::LimitsError;
use ctr_core::Frame;

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
    /// Not reached, and the stability margin held the solve back
    /// ([`IkOptions::min_margin`]): the last steps were limited by it, or the point
    /// found is within [`MARGIN_ACTIVE_BAND`](super::MARGIN_ACTIVE_BAND) of it. `q` is the closest point found
    /// whose margin is at least `min_margin`; the target may be reachable on a less
    /// stable configuration.
    UnreachableWithMargin,
}

impl IkStatus {
    /// Lower-case name for files and messages: `reached`, `unreachable`,
    /// `iteration_limit`, `fk_failed`, `unreachable_with_margin`.
    ///
    /// ```
    /// use ctr_analysis::ik::IkStatus;
    /// assert_eq!(IkStatus::UnreachableWithMargin.name(), "unreachable_with_margin");
    /// ```
    pub fn name(self) -> &'static str {
        match self {
            IkStatus::Reached => "reached",
            IkStatus::Unreachable => "unreachable",
            IkStatus::IterationLimit => "iteration_limit",
            IkStatus::FkFailed => "fk_failed",
            IkStatus::UnreachableWithMargin => "unreachable_with_margin",
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
    /// The stability margin ([`crate::margin`]) of the equilibrium `tip` is on, on the
    /// branch the steps followed (dimensionless; NaN when the status is `FkFailed`).
    /// With [`IkOptions::min_margin`] it is at least `min_margin + MARGIN_SLACK`, and so
    /// is the margin of `q` solved cold.
    pub stability_margin: f64,
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
    /// Constant part of `W_N` on each rotation (mm^2 of tip error per rad^2), for a
    /// rotation whose lever arm (weighted tip motion per radian) is at least
    /// `rotation_scale_mm`; one with a shorter lever arm `l` gets this times
    /// `(l / rotation_scale_mm)^2`: the damping scales with the lever arm, so that it
    /// never holds back a rotation whose tip is near its axis. The scaling goes with
    /// `adaptive_damping` (whose `lambda` then keeps the steps in hand); without it the
    /// step is the paper's, with this damping constant.
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
    /// Smallest stability margin allowed (dimensionless, [`crate::margin`]: 1 with no
    /// snap within about 20 degrees or mm, 0 at one; at most 1): no iterate, and
    /// so no result, has a smaller one. A constraint of every step (module doc,
    /// "Stability margin"), not a filter of the results. `None`: unconstrained.
    pub min_margin: Option<f64>,
}

impl IkOptions {
    /// Checks every setting's range ([`IkError::Option`] names the first one out of it).
    pub fn check(&self) -> Result<(), IkError> {
        let o = self;
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
        if let Some(m) = o.min_margin {
            check_option("min_margin", m, true, "a finite number")?;
        }
        Ok(())
    }
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
            min_margin: None,
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
    /// No point of the start table has the stability margin asked for
    /// ([`IkOptions::min_margin`]): the limits hold no joints that stable, as far as
    /// the table sees.
    #[error("{}", min_margin_words(*min_margin, *samples, *largest))]
    MinMargin {
        /// the margin asked for
        min_margin: f64,
        /// joint vectors of the start table solved
        samples: usize,
        /// the largest margin among them (NaN when there are none)
        largest: f64,
    },
}

fn min_margin_words(min_margin: f64, samples: usize, largest: f64) -> String {
    if samples == 0 {
        return format!(
            "IK option min_margin = {min_margin} needs start points within it, and the start \
             table is empty (seed_samples = 0)"
        );
    }
    format!(
        "IK option min_margin = {min_margin}: none of the {samples} joint vectors sampled \
         within the limits has a stability margin that large (the largest: {largest}); \
         lower it, or widen the limits"
    )
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

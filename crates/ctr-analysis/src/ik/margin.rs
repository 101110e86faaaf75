//! The stability-margin constraint of the steps ([`IkOptions::min_margin`]; the method
//! is in the [module doc](super), "Stability margin").
//!
//! [`Guard`] holds one start's state: the margin at the current iterate and its
//! gradient, the level the linearised margin must reach after a step, and whether the
//! margin shaped the last steps. The gradient is the one the FK solve of the iterate
//! gives with its margin ([`crate::margin::Margin::gradient`]: the softest mode's
//! gradient by the kernel's central differences, scaled), so a step costs no probes
//! beyond the margin's own.

#[cfg(doc)]
use super::IkOptions;
use crate::model::{Solved, MAX_JOINTS};
use nalgebra::SVector;

type Joint = SVector<f64, MAX_JOINTS>;

/// What every iterate's margin must clear beyond `min_margin` (dimensionless), so that a
/// re-solve of a result (warm from elsewhere, or cold) never reads below `min_margin`.
pub const MARGIN_SLACK: f64 = 1e-3;
/// A result not reached whose margin is within this of `min_margin` (dimensionless) is
/// held back by it ([`super::IkStatus::UnreachableWithMargin`]).
pub const MARGIN_ACTIVE_BAND: f64 = 1e-2;
/// Smallest fraction of the margin's deficit a restoring step aims to make up (see
/// [`Guard::level`]); below it the start gives up (dimensionless).
const MIN_RESTORE_FRACTION: f64 = 1e-3;
/// Factor on the back-off after an accepted step (dimensionless).
const BACKOFF_DECAY: f64 = 0.5;

/// What an iterate's margin must reach under the floor `min_margin`: `min_margin +`
/// [`MARGIN_SLACK`].
pub(super) fn floor(min_margin: f64) -> f64 {
    min_margin + MARGIN_SLACK
}

/// One start's margin constraint.
#[derive(Clone, Copy, Debug)]
pub(super) struct Guard {
    /// `min_margin + MARGIN_SLACK`: what an iterate must have
    pub floor: f64,
    /// the margin at the current iterate
    pub margin: f64,
    /// its gradient, per mm (feeds) and per rad (rotations); zero where not known
    pub grad: Joint,
    /// how far above `floor` the linearised margin aims: what the linear model
    /// overestimated the margin by on refused steps, decaying on accepted ones
    backoff: f64,
    /// while restoring: the fraction of the deficit the next step aims to make up
    restore: f64,
    /// the margin shaped the last step (its row cut the free step, or the step was
    /// refused for it)
    pub held: bool,
}

impl Guard {
    /// The constraint `min_margin` at a start solved to `start`.
    pub fn new(min_margin: f64, start: &Solved) -> Self {
        Guard {
            floor: floor(min_margin),
            margin: start.margin,
            grad: Joint::from(start.margin_gradient),
            backoff: 0.0,
            restore: 1.0,
            held: false,
        }
    }

    /// Whether `m` is a margin an iterate may have.
    pub fn allows(&self, m: f64) -> bool {
        m >= self.floor
    }

    /// The current iterate is below the floor: steps raise the margin first.
    pub fn restoring(&self) -> bool {
        !self.allows(self.margin)
    }

    /// The level the linearised margin `margin + grad . dq` must reach: `floor` plus the
    /// back-off, but never above the current margin (`dq = 0` stays feasible); while
    /// restoring, the fraction `restore` of the way up to it.
    pub fn level(&self) -> f64 {
        let aim = self.floor + self.backoff;
        if self.restoring() {
            self.margin + self.restore * (aim - self.margin)
        } else {
            aim.min(self.margin)
        }
    }

    /// The linearised margin after the step `dq`.
    pub fn predicted(&self, dq: &Joint) -> f64 {
        self.margin + self.grad.dot(dq)
    }

    /// Whether the step `dq` satisfies the linearised constraint.
    pub fn admits(&self, dq: &Joint) -> bool {
        self.predicted(dq) >= self.level()
    }

    /// The constraint as the QP's row `a . dq <= b`.
    pub fn row(&self) -> (Joint, f64) {
        (-self.grad, self.margin - self.level())
    }

    /// Whether a trial whose margin is `m` may be taken (while restoring: any rise).
    pub fn accepts(&self, m: f64) -> bool {
        if self.restoring() {
            m > self.margin
        } else {
            self.allows(m)
        }
    }

    /// A step was taken to the iterate solved to `to`.
    pub fn took(&mut self, to: &Solved) {
        if self.restoring() {
            self.restore = (2.0 * self.restore).min(1.0);
        }
        self.backoff *= BACKOFF_DECAY;
        self.margin = to.margin;
        self.grad = Joint::from(to.margin_gradient);
    }

    /// The step `dq` was refused for its margin `m`: aim higher by what the linear
    /// model missed, and while restoring aim for less of the deficit. `false` when a
    /// restoring start should give up.
    pub fn refused(&mut self, dq: &Joint, m: f64) -> bool {
        self.held = true;
        if m.is_finite() {
            self.backoff += (self.predicted(dq) - m).max(0.0);
        }
        if self.restoring() {
            self.restore *= 0.5;
            return self.restore >= MIN_RESTORE_FRACTION;
        }
        true
    }

    /// The QP found no step: while restoring, aim for less of the deficit. `false` when
    /// the start should give up.
    pub fn no_step(&mut self) -> bool {
        if self.restoring() {
            self.restore *= 0.5;
            return self.restore >= MIN_RESTORE_FRACTION;
        }
        true
    }
}

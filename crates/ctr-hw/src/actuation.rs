//! The mapping from joint values to motor ticks: which motor drives which joint, how, and
//! within which limits.
//!
//! # Conventions
//!
//! * Rotation joints are in **degrees**, feed (translation) joints in **millimetres**.
//! * `gear_ratio` is motor revolutions per joint revolution (rotation joints, default 1).
//! * `mm_per_rev` is the feed, in mm, per motor revolution (feed joints, required).
//! * `direction` is +1 when increasing the joint value increases the motor's position,
//!   -1 otherwise.
//! * `zero_offset_ticks` is the motor position, in ticks, at joint value 0.
//!
//! With `u` the motor revolutions per joint unit (`gear_ratio / 360` or `1 / mm_per_rev`):
//!
//! ```text
//! ticks = zero_offset_ticks + direction * round(value * u * ticks_per_rev)
//! value = direction * (ticks - zero_offset_ticks) / (u * ticks_per_rev)
//! ```
//!
//! Limits (`min`, `max`, in joint units, inclusive) are checked before a value is turned
//! into ticks, so nothing out of range ever reaches the bus. `max_speed` (joint units per
//! second) becomes the motor's profile velocity.
//!
//! # TOML shape
//!
//! The `[actuation]` section of a robot file holds one `[[actuation.joint]]` table per
//! joint, in the order of the joint vector:
//!
//! ```toml
//! [[actuation.joint]]
//! name = "alpha1"           # rotation of tube 1
//! motor_id = 1
//! kind = "rotation"         # "rotation" (degrees) or "feed" (mm)
//! gear_ratio = 1.0          # motor revs per joint rev; rotation only, default 1
//! ticks_per_rev = 4096      # default 4096
//! direction = 1             # +1 or -1, default +1
//! zero_offset_ticks = 0     # default 0
//! min = -180.0              # degrees
//! max = 180.0
//! max_speed = 90.0          # degrees per second
//!
//! [[actuation.joint]]
//! name = "beta1"            # feed of tube 1
//! motor_id = 2
//! kind = "feed"
//! mm_per_rev = 8.0          # lead of the screw; feed only, required
//! direction = -1
//! min = -60.0               # mm
//! max = 0.0
//! max_speed = 10.0          # mm per second
//! ```
//!
//! Unknown keys are rejected, as are duplicate names or motor IDs, `min > max`,
//! non-positive speeds, ratios or leads, and keys that do not fit the kind.
//!
//! ```
//! use ctr_hw::actuation::Actuation;
//! #[derive(serde::Deserialize)]
//! struct Robot { actuation: Actuation }
//!
//! let robot: Robot = toml::from_str(r#"
//!     [[actuation.joint]]
//!     name = "alpha1"
//!     motor_id = 1
//!     kind = "rotation"
//!     min = -180.0
//!     max = 180.0
//!     max_speed = 90.0
//!
//!     [[actuation.joint]]
//!     name = "beta1"
//!     motor_id = 2
//!     kind = "feed"
//!     mm_per_rev = 8.0
//!     min = -60.0
//!     max = 0.0
//!     max_speed = 10.0
//! "#)?;
//! let ticks = robot.actuation.to_ticks(&[90.0, -8.0])?;
//! assert_eq!(ticks, [1024, -4096]);
//! assert!(robot.actuation.to_ticks(&[90.0, 1.0]).is_err()); // beta1 above its max
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt;

use serde::Deserialize;

use crate::control_table::{PROFILE_MAX, VELOCITY_UNIT_RPM};
use crate::protocol::MAX_DEVICE_ID;

/// What a joint does.
///
/// ```
/// use ctr_hw::actuation::JointKind;
/// assert_eq!(JointKind::Feed.unit(), "mm");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotation of a tube, in degrees.
    Rotation,
    /// Translation (feed) of a tube, in millimetres.
    Feed,
}

impl JointKind {
    /// The unit of the joint value.
    ///
    /// ```
    /// assert_eq!(ctr_hw::actuation::JointKind::Rotation.unit(), "deg");
    /// ```
    pub fn unit(self) -> &'static str {
        match self {
            Self::Rotation => "deg",
            Self::Feed => "mm",
        }
    }
}

/// Which of a joint's limits was violated.
///
/// ```
/// assert_eq!(ctr_hw::actuation::Limit::Max.to_string(), "max");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Limit {
    /// The lower limit.
    Min,
    /// The upper limit.
    Max,
}

impl fmt::Display for Limit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Min => "min",
            Self::Max => "max",
        })
    }
}

/// Errors of the actuation mapping; none of them sends anything.
///
/// ```
/// use ctr_hw::actuation::{ActuationError, JointActuation, Limit};
/// let j = JointActuation::rotation("alpha1", 1, -180.0, 180.0, 90.0);
/// let err = j.to_ticks(200.0).unwrap_err();
/// assert_eq!(err.to_string(), "joint alpha1: 200 deg is above its max limit 180 deg");
/// assert!(matches!(err, ActuationError::OutOfLimits { limit: Limit::Max, .. }));
/// ```
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ActuationError {
    /// A value beyond a joint limit.
    #[error("joint {joint}: {value} {unit} is {} its {limit} limit {bound} {unit}", if *.limit == Limit::Min { "below" } else { "above" })]
    OutOfLimits {
        /// The joint's name.
        joint: String,
        /// The requested value.
        value: f64,
        /// Which limit.
        limit: Limit,
        /// The limit's value.
        bound: f64,
        /// The joint's unit.
        unit: &'static str,
    },
    /// A NaN or infinite value.
    #[error("joint {joint}: value {value} is not finite")]
    NotFinite {
        /// The joint's name.
        joint: String,
        /// The requested value.
        value: f64,
    },
    /// The value does not fit the motor's 32-bit position.
    #[error("joint {joint}: {value} gives a position beyond the motor's range")]
    TickOverflow {
        /// The joint's name.
        joint: String,
        /// The requested value.
        value: f64,
    },
    /// A joint's configuration is unusable.
    #[error("joint {joint}: {reason}")]
    InvalidJoint {
        /// The joint's name.
        joint: String,
        /// What is wrong.
        reason: String,
    },
    /// Two joints share a name.
    #[error("joint name {name} is used twice")]
    DuplicateName {
        /// The name.
        name: String,
    },
    /// Two joints share a motor.
    #[error("motor ID {motor_id} drives both {first} and {second}")]
    DuplicateMotor {
        /// The motor ID.
        motor_id: u8,
        /// The first joint using it.
        first: String,
        /// The second joint using it.
        second: String,
    },
    /// A joint vector of the wrong length.
    #[error("expected {expected} joint values, got {got}")]
    CountMismatch {
        /// Number of joints.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
    /// No joint with this name.
    #[error("no joint named {name}")]
    UnknownJoint {
        /// The name asked for.
        name: String,
    },
}

fn default_ticks_per_rev() -> u32 {
    crate::control_table::TICKS_PER_REV
}

fn default_direction() -> i8 {
    1
}

/// How one joint is driven: one `[[actuation.joint]]` table (see the module docs).
///
/// ```
/// use ctr_hw::actuation::JointActuation;
/// let feed = JointActuation::feed("beta1", 2, 8.0, -60.0, 0.0, 10.0);
/// assert_eq!(feed.to_ticks(-4.0).unwrap(), -2048);
/// assert_eq!(feed.from_ticks(-2048), -4.0);
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointActuation {
    /// The joint's name (unique).
    pub name: String,
    /// The ID of the motor that drives it (unique, 0..=252).
    pub motor_id: u8,
    /// Rotation (degrees) or feed (mm).
    pub kind: JointKind,
    /// Encoder ticks per motor revolution.
    #[serde(default = "default_ticks_per_rev")]
    pub ticks_per_rev: u32,
    /// Feed joints: mm of travel per motor revolution.
    #[serde(default)]
    pub mm_per_rev: Option<f64>,
    /// Rotation joints: motor revolutions per joint revolution (default 1).
    #[serde(default)]
    pub gear_ratio: Option<f64>,
    /// +1 or -1.
    #[serde(default = "default_direction")]
    pub direction: i8,
    /// Motor position in ticks at joint value 0.
    #[serde(default)]
    pub zero_offset_ticks: i32,
    /// Lower joint limit, inclusive.
    pub min: f64,
    /// Upper joint limit, inclusive.
    pub max: f64,
    /// Largest joint speed, in joint units per second.
    pub max_speed: f64,
}

impl JointActuation {
    /// A rotation joint with defaults (gear ratio 1, 4096 ticks, direction +1, offset 0).
    ///
    /// ```
    /// let j = ctr_hw::actuation::JointActuation::rotation("alpha1", 1, -180.0, 180.0, 90.0);
    /// assert_eq!(j.to_ticks(360.0 / 4096.0).unwrap(), 1);
    /// ```
    pub fn rotation(name: &str, motor_id: u8, min: f64, max: f64, max_speed: f64) -> Self {
        Self {
            name: name.to_owned(),
            motor_id,
            kind: JointKind::Rotation,
            ticks_per_rev: default_ticks_per_rev(),
            mm_per_rev: None,
            gear_ratio: None,
            direction: 1,
            zero_offset_ticks: 0,
            min,
            max,
            max_speed,
        }
    }

    /// A feed joint with defaults (4096 ticks, direction +1, offset 0).
    ///
    /// ```
    /// let j = ctr_hw::actuation::JointActuation::feed("beta1", 2, 8.0, -60.0, 0.0, 10.0);
    /// assert_eq!(j.mm_per_rev, Some(8.0));
    /// ```
    pub fn feed(
        name: &str,
        motor_id: u8,
        mm_per_rev: f64,
        min: f64,
        max: f64,
        max_speed: f64,
    ) -> Self {
        Self {
            kind: JointKind::Feed,
            mm_per_rev: Some(mm_per_rev),
            ..Self::rotation(name, motor_id, min, max, max_speed)
        }
    }

    /// Checks the configuration of this joint alone.
    ///
    /// ```
    /// let mut j = ctr_hw::actuation::JointActuation::rotation("a", 1, 10.0, -10.0, 90.0);
    /// assert!(j.validate().is_err()); // min > max
    /// j.min = -10.0;
    /// j.max = 10.0;
    /// assert!(j.validate().is_ok());
    /// ```
    pub fn validate(&self) -> Result<(), ActuationError> {
        let invalid = |reason: String| ActuationError::InvalidJoint {
            joint: self.name.clone(),
            reason,
        };
        if self.name.is_empty() {
            return Err(invalid("empty name".into()));
        }
        if self.motor_id > MAX_DEVICE_ID {
            return Err(invalid(format!(
                "motor_id {} is not a device ID (0..=252)",
                self.motor_id
            )));
        }
        if self.ticks_per_rev == 0 {
            return Err(invalid("ticks_per_rev must be positive".into()));
        }
        if self.direction != 1 && self.direction != -1 {
            return Err(invalid(format!(
                "direction must be 1 or -1, got {}",
                self.direction
            )));
        }
        match self.kind {
            JointKind::Feed => {
                if self.gear_ratio.is_some() {
                    return Err(invalid("gear_ratio applies to rotation joints".into()));
                }
                match self.mm_per_rev {
                    None => return Err(invalid("feed joint needs mm_per_rev".into())),
                    Some(lead) if !(lead.is_finite() && lead > 0.0) => {
                        return Err(invalid(format!("mm_per_rev must be positive, got {lead}")))
                    }
                    Some(_) => {}
                }
            }
            JointKind::Rotation => {
                if self.mm_per_rev.is_some() {
                    return Err(invalid("mm_per_rev applies to feed joints".into()));
                }
                if let Some(ratio) = self.gear_ratio {
                    if !(ratio.is_finite() && ratio > 0.0) {
                        return Err(invalid(format!("gear_ratio must be positive, got {ratio}")));
                    }
                }
            }
        }
        if !(self.min.is_finite() && self.max.is_finite()) {
            return Err(invalid("limits must be finite".into()));
        }
        if self.min > self.max {
            return Err(invalid(format!(
                "min {} is above max {}",
                self.min, self.max
            )));
        }
        if !(self.max_speed.is_finite() && self.max_speed > 0.0) {
            return Err(invalid(format!(
                "max_speed must be positive, got {}",
                self.max_speed
            )));
        }
        for (what, bound) in [(Limit::Min, self.min), (Limit::Max, self.max)] {
            if self.raw_ticks(bound).is_none() {
                return Err(invalid(format!(
                    "{what} limit {bound} is beyond the motor's range"
                )));
            }
        }
        Ok(())
    }

    /// Motor revolutions per joint unit (per degree or per mm).
    ///
    /// ```
    /// let j = ctr_hw::actuation::JointActuation::feed("b", 2, 8.0, -60.0, 0.0, 10.0);
    /// assert_eq!(j.motor_revs_per_unit(), 0.125);
    /// ```
    pub fn motor_revs_per_unit(&self) -> f64 {
        match self.kind {
            JointKind::Rotation => self.gear_ratio.unwrap_or(1.0) / 360.0,
            JointKind::Feed => 1.0 / self.mm_per_rev.unwrap_or(f64::NAN),
        }
    }

    /// Checks `value` against the limits (inclusive).
    ///
    /// ```
    /// let j = ctr_hw::actuation::JointActuation::rotation("a", 1, -90.0, 90.0, 45.0);
    /// assert!(j.check(90.0).is_ok());
    /// assert!(j.check(-90.5).is_err());
    /// assert!(j.check(f64::NAN).is_err());
    /// ```
    pub fn check(&self, value: f64) -> Result<(), ActuationError> {
        if !value.is_finite() {
            return Err(ActuationError::NotFinite {
                joint: self.name.clone(),
                value,
            });
        }
        let violated = if value < self.min {
            Some((Limit::Min, self.min))
        } else if value > self.max {
            Some((Limit::Max, self.max))
        } else {
            None
        };
        match violated {
            Some((limit, bound)) => Err(ActuationError::OutOfLimits {
                joint: self.name.clone(),
                value,
                limit,
                bound,
                unit: self.kind.unit(),
            }),
            None => Ok(()),
        }
    }

    /// The motor position for a joint value, after the limit check.
    ///
    /// ```
    /// use ctr_hw::actuation::JointActuation;
    /// let mut j = JointActuation::rotation("a", 1, -180.0, 180.0, 90.0);
    /// j.gear_ratio = Some(2.0);
    /// j.direction = -1;
    /// j.zero_offset_ticks = 100;
    /// assert_eq!(j.to_ticks(45.0).unwrap(), 100 - 1024);
    /// ```
    pub fn to_ticks(&self, value: f64) -> Result<i32, ActuationError> {
        self.check(value)?;
        self.raw_ticks(value)
            .ok_or_else(|| ActuationError::TickOverflow {
                joint: self.name.clone(),
                value,
            })
    }

    /// The joint value for a motor position (no limit check: positions are facts).
    ///
    /// ```
    /// let j = ctr_hw::actuation::JointActuation::rotation("a", 1, -180.0, 180.0, 90.0);
    /// assert_eq!(j.from_ticks(2048), 180.0);
    /// ```
    pub fn from_ticks(&self, ticks: i32) -> f64 {
        let relative = f64::from(ticks) - f64::from(self.zero_offset_ticks);
        f64::from(self.direction) * relative
            / (self.motor_revs_per_unit() * f64::from(self.ticks_per_rev))
    }

    /// The profile velocity (X-series units of 0.229 rev/min) for `max_speed`, rounded
    /// down so the joint never exceeds it, at least 1 (0 would mean "unlimited").
    ///
    /// ```
    /// let j = ctr_hw::actuation::JointActuation::rotation("a", 1, -180.0, 180.0, 90.0);
    /// // 90 deg/s = 15 rev/min = 65.5 units
    /// assert_eq!(j.profile_velocity(), 65);
    /// ```
    pub fn profile_velocity(&self) -> u32 {
        let rpm = self.max_speed * self.motor_revs_per_unit() * 60.0;
        let units = (rpm / VELOCITY_UNIT_RPM).floor();
        if units.is_finite() {
            (units as u32).clamp(1, PROFILE_MAX)
        } else {
            1
        }
    }

    fn raw_ticks(&self, value: f64) -> Option<i32> {
        let delta = (value * self.motor_revs_per_unit() * f64::from(self.ticks_per_rev)).round();
        let ticks = f64::from(self.zero_offset_ticks) + f64::from(self.direction) * delta;
        if ticks.is_finite() && ticks >= f64::from(i32::MIN) && ticks <= f64::from(i32::MAX) {
            Some(ticks as i32)
        } else {
            None
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ActuationSection {
    #[serde(default)]
    joint: Vec<JointActuation>,
}

/// The validated joint-to-motor mapping of a rig, in joint-vector order. Deserializes from
/// an `[actuation]` section (see the module docs) and checks it.
///
/// ```
/// use ctr_hw::actuation::{Actuation, JointActuation};
/// let act = Actuation::new(vec![
///     JointActuation::rotation("alpha1", 1, -180.0, 180.0, 90.0),
///     JointActuation::feed("beta1", 2, 8.0, -60.0, 0.0, 10.0),
/// ])?;
/// assert_eq!(act.motor_ids(), [1, 2]);
/// assert_eq!(act.from_ticks(&[1024, -4096])?, [90.0, -8.0]);
/// # Ok::<(), ctr_hw::actuation::ActuationError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(try_from = "ActuationSection")]
pub struct Actuation {
    joints: Vec<JointActuation>,
}

impl TryFrom<ActuationSection> for Actuation {
    type Error = ActuationError;

    fn try_from(section: ActuationSection) -> Result<Self, Self::Error> {
        Self::new(section.joint)
    }
}

impl Actuation {
    /// Validates each joint and the uniqueness of names and motor IDs.
    ///
    /// ```
    /// use ctr_hw::actuation::{Actuation, JointActuation, ActuationError};
    /// let err = Actuation::new(vec![
    ///     JointActuation::rotation("a", 1, -1.0, 1.0, 1.0),
    ///     JointActuation::rotation("b", 1, -1.0, 1.0, 1.0),
    /// ]).unwrap_err();
    /// assert!(matches!(err, ActuationError::DuplicateMotor { motor_id: 1, .. }));
    /// ```
    pub fn new(joints: Vec<JointActuation>) -> Result<Self, ActuationError> {
        for (i, joint) in joints.iter().enumerate() {
            joint.validate()?;
            for earlier in &joints[..i] {
                if earlier.name == joint.name {
                    return Err(ActuationError::DuplicateName {
                        name: joint.name.clone(),
                    });
                }
                if earlier.motor_id == joint.motor_id {
                    return Err(ActuationError::DuplicateMotor {
                        motor_id: joint.motor_id,
                        first: earlier.name.clone(),
                        second: joint.name.clone(),
                    });
                }
            }
        }
        Ok(Self { joints })
    }

    /// The joints in order.
    ///
    /// ```
    /// use ctr_hw::actuation::{Actuation, JointActuation};
    /// let act = Actuation::new(vec![JointActuation::rotation("a", 1, -1.0, 1.0, 1.0)]).unwrap();
    /// assert_eq!(act.joints()[0].name, "a");
    /// ```
    pub fn joints(&self) -> &[JointActuation] {
        &self.joints
    }

    /// Number of joints.
    ///
    /// ```
    /// assert_eq!(ctr_hw::actuation::Actuation::new(vec![]).unwrap().len(), 0);
    /// ```
    pub fn len(&self) -> usize {
        self.joints.len()
    }

    /// Whether there are no joints.
    ///
    /// ```
    /// assert!(ctr_hw::actuation::Actuation::new(vec![]).unwrap().is_empty());
    /// ```
    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }

    /// The index of the joint called `name`.
    ///
    /// ```
    /// use ctr_hw::actuation::{Actuation, JointActuation};
    /// let act = Actuation::new(vec![JointActuation::rotation("a", 1, -1.0, 1.0, 1.0)]).unwrap();
    /// assert_eq!(act.index_of("a").unwrap(), 0);
    /// assert!(act.index_of("zz").is_err());
    /// ```
    pub fn index_of(&self, name: &str) -> Result<usize, ActuationError> {
        self.joints
            .iter()
            .position(|j| j.name == name)
            .ok_or_else(|| ActuationError::UnknownJoint {
                name: name.to_owned(),
            })
    }

    /// The motor IDs in joint order.
    ///
    /// ```
    /// use ctr_hw::actuation::{Actuation, JointActuation};
    /// let act = Actuation::new(vec![JointActuation::rotation("a", 7, -1.0, 1.0, 1.0)]).unwrap();
    /// assert_eq!(act.motor_ids(), [7]);
    /// ```
    pub fn motor_ids(&self) -> Vec<u8> {
        self.joints.iter().map(|j| j.motor_id).collect()
    }

    /// Motor positions for a full joint vector; every value is checked before any is
    /// converted, and the first violation is returned.
    ///
    /// ```
    /// use ctr_hw::actuation::{Actuation, JointActuation};
    /// let act = Actuation::new(vec![JointActuation::rotation("a", 1, -90.0, 90.0, 1.0)]).unwrap();
    /// assert_eq!(act.to_ticks(&[90.0]).unwrap(), [1024]);
    /// assert!(act.to_ticks(&[90.0, 1.0]).is_err()); // wrong length
    /// ```
    pub fn to_ticks(&self, values: &[f64]) -> Result<Vec<i32>, ActuationError> {
        self.check_count(values.len())?;
        for (joint, &value) in self.joints.iter().zip(values) {
            joint.check(value)?;
        }
        self.joints
            .iter()
            .zip(values)
            .map(|(joint, &value)| joint.to_ticks(value))
            .collect()
    }

    /// Joint values for motor positions in joint order.
    ///
    /// ```
    /// use ctr_hw::actuation::{Actuation, JointActuation};
    /// let act = Actuation::new(vec![JointActuation::rotation("a", 1, -90.0, 90.0, 1.0)]).unwrap();
    /// assert_eq!(act.from_ticks(&[-1024]).unwrap(), [-90.0]);
    /// ```
    pub fn from_ticks(&self, ticks: &[i32]) -> Result<Vec<f64>, ActuationError> {
        self.check_count(ticks.len())?;
        Ok(self
            .joints
            .iter()
            .zip(ticks)
            .map(|(joint, &t)| joint.from_ticks(t))
            .collect())
    }

    fn check_count(&self, got: usize) -> Result<(), ActuationError> {
        if got != self.joints.len() {
            return Err(ActuationError::CountMismatch {
                expected: self.joints.len(),
                got,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct Robot {
        actuation: Actuation,
    }

    const FOUR_JOINTS: &str = r#"
        [[actuation.joint]]
        name = "alpha1"
        motor_id = 1
        kind = "rotation"
        gear_ratio = 2.0
        min = -180.0
        max = 180.0
        max_speed = 90.0

        [[actuation.joint]]
        name = "beta1"
        motor_id = 2
        kind = "feed"
        mm_per_rev = 8.0
        direction = -1
        zero_offset_ticks = 500
        min = -60.0
        max = 0.0
        max_speed = 10.0

        [[actuation.joint]]
        name = "alpha2"
        motor_id = 3
        kind = "rotation"
        ticks_per_rev = 1000
        min = -360
        max = 360
        max_speed = 180

        [[actuation.joint]]
        name = "beta2"
        motor_id = 4
        kind = "feed"
        mm_per_rev = 2.5
        min = -30.0
        max = 0.0
        max_speed = 5.0
    "#;

    fn four() -> Actuation {
        toml::from_str::<Robot>(FOUR_JOINTS).unwrap().actuation
    }

    #[test]
    fn parses_the_documented_shape() {
        let act = four();
        assert_eq!(act.len(), 4);
        assert_eq!(act.motor_ids(), [1, 2, 3, 4]);
        let beta1 = &act.joints()[1];
        assert_eq!(beta1.direction, -1);
        assert_eq!(beta1.zero_offset_ticks, 500);
        assert_eq!(act.joints()[2].ticks_per_rev, 1000);
        assert_eq!(act.joints()[2].min, -360.0); // integers accepted for floats
        assert_eq!(act.joints()[0].ticks_per_rev, 4096);
    }

    #[test]
    fn converts_both_ways() {
        let act = four();
        // alpha1: gear 2 → 1 joint rev = 8192 ticks; 45° = 1024.
        // beta1: 8 mm/rev, reversed, offset 500; -8 mm → 500 + 4096.
        // alpha2: 1000 ticks/rev; 36° = 100.
        // beta2: 2.5 mm/rev; -5 mm = -2 rev = -8192.
        let ticks = act.to_ticks(&[45.0, -8.0, 36.0, -5.0]).unwrap();
        assert_eq!(ticks, [1024, 4596, 100, -8192]);
        assert_eq!(act.from_ticks(&ticks).unwrap(), [45.0, -8.0, 36.0, -5.0]);
        // Round trip within half a tick of resolution.
        for joint in act.joints() {
            let resolution = 1.0 / (joint.motor_revs_per_unit() * f64::from(joint.ticks_per_rev));
            for k in 0..=20 {
                let value = joint.min + (joint.max - joint.min) * f64::from(k) / 20.0;
                let back = joint.from_ticks(joint.to_ticks(value).unwrap());
                assert!((back - value).abs() <= 0.5 * resolution + 1e-12);
            }
        }
    }

    #[test]
    fn limits_are_checked_before_conversion_and_name_the_joint() {
        let act = four();
        let err = act.to_ticks(&[0.0, 0.5, 0.0, 0.0]).unwrap_err();
        assert_eq!(
            err,
            ActuationError::OutOfLimits {
                joint: "beta1".into(),
                value: 0.5,
                limit: Limit::Max,
                bound: 0.0,
                unit: "mm",
            }
        );
        let err = act.to_ticks(&[-181.0, 0.0, 0.0, 0.0]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "joint alpha1: -181 deg is below its min limit -180 deg"
        );
        assert!(matches!(
            act.to_ticks(&[0.0, 0.0, f64::INFINITY, 0.0]),
            Err(ActuationError::NotFinite { .. })
        ));
        // Limits are inclusive.
        assert!(act.to_ticks(&[180.0, -60.0, -360.0, 0.0]).is_ok());
    }

    #[test]
    fn rejects_bad_sections() {
        let cases = [
            (
                "unknown key",
                FOUR_JOINTS.replace("gear_ratio", "gear_raito"),
            ),
            (
                "duplicate id",
                FOUR_JOINTS.replace("motor_id = 4", "motor_id = 3"),
            ),
            (
                "duplicate name",
                FOUR_JOINTS.replace("\"beta2\"", "\"beta1\""),
            ),
            (
                "feed without lead",
                FOUR_JOINTS.replace("mm_per_rev = 2.5", ""),
            ),
            (
                "rotation with lead",
                FOUR_JOINTS.replace("ticks_per_rev = 1000", "mm_per_rev = 1.0"),
            ),
            (
                "bad direction",
                FOUR_JOINTS.replace("direction = -1", "direction = 2"),
            ),
            (
                "min above max",
                FOUR_JOINTS.replace("min = -30.0", "min = 30.0"),
            ),
            (
                "zero speed",
                FOUR_JOINTS.replace("max_speed = 5.0", "max_speed = 0.0"),
            ),
            ("bad kind", FOUR_JOINTS.replace("\"feed\"", "\"slide\"")),
            (
                "broadcast id",
                FOUR_JOINTS.replace("motor_id = 4", "motor_id = 254"),
            ),
        ];
        for (what, text) in cases {
            assert!(toml::from_str::<Robot>(&text).is_err(), "{what} accepted");
        }
        let err = toml::from_str::<Robot>(&FOUR_JOINTS.replace("motor_id = 4", "motor_id = 3"))
            .err()
            .unwrap();
        assert!(err
            .to_string()
            .contains("motor ID 3 drives both alpha2 and beta2"));
    }

    #[test]
    fn limits_beyond_the_motor_range_are_rejected() {
        let joint = JointActuation::feed("b", 1, 0.001, -1e9, 0.0, 1.0);
        assert!(matches!(
            joint.validate(),
            Err(ActuationError::InvalidJoint { .. })
        ));
    }

    #[test]
    fn profile_velocity_never_exceeds_max_speed() {
        for joint in four().joints() {
            let pv = joint.profile_velocity();
            let speed = f64::from(pv) * VELOCITY_UNIT_RPM / 60.0 / joint.motor_revs_per_unit();
            assert!(speed <= joint.max_speed, "{}", joint.name);
            assert!(pv >= 1);
        }
    }

    #[test]
    fn unknown_joint_names() {
        assert!(matches!(
            four().index_of("gamma"),
            Err(ActuationError::UnknownJoint { .. })
        ));
    }
}

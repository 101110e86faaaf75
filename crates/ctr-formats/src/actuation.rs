//! `[actuation]`: which motor drives which joint of the robot, and how (the shape is
//! documented in [the module above](super)).
//!
//! This is the one schema of an actuated joint: robot files are read into
//! [`ActuatedJoint`] here, and `ctr-hw` drives its motors with the very same structs
//! (it adds only what needs the motors' control table: limit checks on commands and
//! profile velocities). What the robot file adds to the tables is the naming rule that
//! ties each one to a joint column: `s{i}` is the feed of tube i (column `s{i}_mm`,
//! kind `feed`, mm) and `theta{i}` its rotation (column `theta{i}_deg`, kind
//! `rotation`, degrees). The joint value in the file's units is what the motor mapping
//! converts, unchanged: `s{i} = 0` is tube i's tip at the guide exit, `theta{i} = 0`
//! its zero rotation.
//!
//! # Motor mapping
//!
//! With `u` the motor revolutions per joint unit ([`ActuatedJoint::motor_revs_per_unit`]:
//! `1 / mm_per_rev` for a feed, `gear_ratio / 360` for a rotation):
//!
//! ```text
//! ticks = zero_offset_ticks + direction * round(value * u * ticks_per_rev)
//! value = direction * (ticks - zero_offset_ticks) / (u * ticks_per_rev)
//! ```
//!
//! A motor position is a signed 32-bit register: limits whose position does not fit it
//! are refused when the section is validated.

use super::toml_doc::Key;
use serde::{Deserialize, Serialize};
use std::fmt;

/// `[actuation]`: one `[[actuation.joint]]` per joint (a feed and a rotation per tube).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuationSection {
    /// `[[actuation.joint]]` tables, in any order in the file; a validated robot keeps
    /// them in joint-column order (`s1`, `theta1`, `s2`, ...).
    #[serde(default)]
    pub joint: Vec<ActuatedJoint>,
}

/// What a joint does (`kind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ActuatorKind {
    /// Rotation of a tube (`theta{i}`), degrees.
    Rotation,
    /// Feed of a tube (`s{i}`), mm.
    Feed,
}

impl ActuatorKind {
    /// The name used in files: `rotation` or `feed`.
    ///
    /// ```
    /// assert_eq!(ctr_formats::ActuatorKind::Rotation.as_str(), "rotation");
    /// ```
    pub fn as_str(self) -> &'static str {
        match self {
            ActuatorKind::Rotation => "rotation",
            ActuatorKind::Feed => "feed",
        }
    }

    /// The unit of the joint value: `mm` (feed) or `deg` (rotation).
    ///
    /// ```
    /// use ctr_formats::ActuatorKind;
    /// assert_eq!(ActuatorKind::Feed.unit(), "mm");
    /// assert_eq!(ActuatorKind::Rotation.unit(), "deg");
    /// ```
    pub fn unit(self) -> &'static str {
        match self {
            ActuatorKind::Feed => "mm",
            ActuatorKind::Rotation => "deg",
        }
    }
}

/// The encoder ticks per motor revolution of the X-series servos.
pub const DEFAULT_TICKS_PER_REV: u32 = 4096;

/// Largest device ID a motor can have (253..=255 are reserved by Dynamixel 2.0).
pub const MAX_MOTOR_ID: u8 = 252;

/// Degrees per revolution, for rotation joints.
const DEGREES_PER_REV: f64 = 360.0;

fn default_ticks_per_rev() -> u32 {
    DEFAULT_TICKS_PER_REV
}

fn default_direction() -> i8 {
    1
}

/// One `[[actuation.joint]]` table: the motor that drives a joint and how.
///
/// ```
/// use ctr_formats::ActuatedJoint;
/// let mut s1 = ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 10.0);
/// s1.direction = -1;
/// s1.zero_offset_ticks = 100;
/// assert_eq!(s1.to_ticks(4.0), Some(100 - 2048));
/// assert_eq!(s1.from_ticks(100 - 2048), 4.0);
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatedJoint {
    /// `s{i}` (feed of tube i) or `theta{i}` (rotation of tube i).
    pub name: String,
    /// The Dynamixel ID of the motor that drives it (0..=252, unique).
    pub motor_id: u8,
    /// `feed` for `s{i}`, `rotation` for `theta{i}`.
    pub kind: ActuatorKind,
    /// Encoder ticks per motor revolution (default 4096).
    #[serde(default = "default_ticks_per_rev")]
    pub ticks_per_rev: u32,
    /// Feed joints only (required there): mm of feed per motor revolution.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mm_per_rev: Option<f64>,
    /// Rotation joints only: motor revolutions per tube revolution (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gear_ratio: Option<f64>,
    /// `1` when the motor position grows with the joint value, `-1` otherwise.
    #[serde(default = "default_direction")]
    pub direction: i8,
    /// Motor position, in ticks, at joint value 0.
    #[serde(default)]
    pub zero_offset_ticks: i32,
    /// Lowest joint value (mm or degrees), inclusive.
    pub min: f64,
    /// Highest joint value (mm or degrees), inclusive.
    pub max: f64,
    /// Largest joint speed, mm/s or degrees/s (the motors' profile velocity).
    pub max_speed: f64,
}

impl ActuatedJoint {
    /// The feed `s{tube}` with the defaults (4096 ticks, direction 1, offset 0): `mm_per_rev`
    /// mm per motor revolution, limits in mm, `max_speed` in mm/s.
    ///
    /// ```
    /// let s2 = ctr_formats::ActuatedJoint::feed(2, 3, 8.0, 0.0, 150.0, 6.0);
    /// assert_eq!((s2.name.as_str(), s2.mm_per_rev), ("s2", Some(8.0)));
    /// ```
    pub fn feed(
        tube: usize,
        motor_id: u8,
        mm_per_rev: f64,
        min: f64,
        max: f64,
        max_speed: f64,
    ) -> Self {
        let joint = JointId {
            tube,
            kind: ActuatorKind::Feed,
        };
        Self::with_defaults(joint, motor_id, Some(mm_per_rev), [min, max], max_speed)
    }

    /// The rotation `theta{tube}` with the defaults (gear ratio 1, 4096 ticks, direction 1,
    /// offset 0): limits in degrees, `max_speed` in degrees/s.
    ///
    /// ```
    /// let theta1 = ctr_formats::ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0);
    /// assert_eq!(theta1.name, "theta1");
    /// assert_eq!(theta1.to_ticks(360.0 / 4096.0), Some(1));
    /// ```
    pub fn rotation(tube: usize, motor_id: u8, min: f64, max: f64, max_speed: f64) -> Self {
        let joint = JointId {
            tube,
            kind: ActuatorKind::Rotation,
        };
        Self::with_defaults(joint, motor_id, None, [min, max], max_speed)
    }

    fn with_defaults(
        joint: JointId,
        motor_id: u8,
        mm_per_rev: Option<f64>,
        [min, max]: [f64; 2],
        max_speed: f64,
    ) -> Self {
        Self {
            name: joint.name(),
            motor_id,
            kind: joint.kind,
            ticks_per_rev: DEFAULT_TICKS_PER_REV,
            mm_per_rev,
            gear_ratio: None,
            direction: 1,
            zero_offset_ticks: 0,
            min,
            max,
            max_speed,
        }
    }

    /// The unit of the joint value and its limits: `mm` or `deg`.
    ///
    /// ```
    /// assert_eq!(ctr_formats::ActuatedJoint::rotation(1, 2, -1.0, 1.0, 1.0).unit(), "deg");
    /// ```
    pub fn unit(&self) -> &'static str {
        self.kind.unit()
    }

    /// Motor revolutions per joint unit (per degree or per mm); NaN for a feed joint
    /// without `mm_per_rev` (refused by validation).
    ///
    /// ```
    /// use ctr_formats::{ActuatedJoint, ActuatorKind};
    /// let j = ActuatedJoint {
    ///     name: "s1".into(), motor_id: 1, kind: ActuatorKind::Feed, ticks_per_rev: 4096,
    ///     mm_per_rev: Some(8.0), gear_ratio: None, direction: 1, zero_offset_ticks: 0,
    ///     min: 0.0, max: 60.0, max_speed: 10.0,
    /// };
    /// assert_eq!(j.motor_revs_per_unit(), 0.125);
    /// ```
    pub fn motor_revs_per_unit(&self) -> f64 {
        match self.kind {
            ActuatorKind::Rotation => self.gear_ratio.unwrap_or(1.0) / DEGREES_PER_REV,
            ActuatorKind::Feed => 1.0 / self.mm_per_rev.unwrap_or(f64::NAN),
        }
    }

    /// The motor position of a joint value, `zero_offset_ticks + direction * round(value *
    /// u * ticks_per_rev)` with `u` the [motor revolutions per
    /// unit](Self::motor_revs_per_unit); `None` when it does not fit the motor's signed
    /// 32-bit position register. Limits are not checked here.
    ///
    /// ```
    /// let mut theta1 = ctr_formats::ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0);
    /// theta1.gear_ratio = Some(2.0);
    /// theta1.direction = -1;
    /// theta1.zero_offset_ticks = 100;
    /// assert_eq!(theta1.to_ticks(45.0), Some(100 - 1024));
    /// assert_eq!(theta1.to_ticks(1e12), None);
    /// ```
    pub fn to_ticks(&self, value: f64) -> Option<i32> {
        let delta = (value * self.motor_revs_per_unit() * f64::from(self.ticks_per_rev)).round();
        let ticks = f64::from(self.zero_offset_ticks) + f64::from(self.direction) * delta;
        (ticks.is_finite() && ticks >= f64::from(i32::MIN) && ticks <= f64::from(i32::MAX))
            .then_some(ticks as i32)
    }

    /// The joint value of a motor position, `direction * (ticks - zero_offset_ticks) / (u *
    /// ticks_per_rev)` (the inverse of [`to_ticks`](Self::to_ticks)); no limit check:
    /// positions are facts.
    ///
    /// ```
    /// let theta1 = ctr_formats::ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0);
    /// assert_eq!(theta1.from_ticks(2048), 180.0);
    /// ```
    pub fn from_ticks(&self, ticks: i32) -> f64 {
        let relative = f64::from(ticks) - f64::from(self.zero_offset_ticks);
        f64::from(self.direction) * relative
            / (self.motor_revs_per_unit() * f64::from(self.ticks_per_rev))
    }
}

/// A joint of the robot: tube number (1 = outermost) and what it does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JointId {
    /// Tube number, 1 = outermost.
    pub tube: usize,
    /// Feed (`s`) or rotation (`theta`).
    pub kind: ActuatorKind,
}

impl JointId {
    /// Parses an actuation joint name, `s{i}` or `theta{i}` (i >= 1, no leading zero).
    ///
    /// ```
    /// use ctr_formats::{ActuatorKind, JointId};
    /// assert_eq!(JointId::parse("theta2"), Some(JointId { tube: 2, kind: ActuatorKind::Rotation }));
    /// assert_eq!(JointId::parse("s1_mm"), None);
    /// assert_eq!(JointId::parse("s01"), None);
    /// ```
    pub fn parse(name: &str) -> Option<JointId> {
        let (kind, digits) = if let Some(d) = name.strip_prefix("theta") {
            (ActuatorKind::Rotation, d)
        } else {
            (ActuatorKind::Feed, name.strip_prefix('s')?)
        };
        if digits.is_empty()
            || digits.starts_with('0')
            || !digits.bytes().all(|b| b.is_ascii_digit())
        {
            return None;
        }
        Some(JointId {
            tube: digits.parse().ok()?,
            kind,
        })
    }

    /// The actuation name: `s2`, `theta2`.
    pub fn name(self) -> String {
        match self.kind {
            ActuatorKind::Feed => format!("s{}", self.tube),
            ActuatorKind::Rotation => format!("theta{}", self.tube),
        }
    }

    /// The joint column it drives: `s2_mm`, `theta2_deg`.
    ///
    /// ```
    /// use ctr_formats::JointId;
    /// assert_eq!(JointId::parse("s2").unwrap().column(), "s2_mm");
    /// assert_eq!(JointId::parse("theta1").unwrap().read_column(), "theta1_read_deg");
    /// ```
    pub fn column(self) -> String {
        format!("{}_{}", self.name(), self.unit())
    }

    /// The recording's read-back column: `s2_read_mm`, `theta2_read_deg`.
    pub fn read_column(self) -> String {
        format!("{}_read_{}", self.name(), self.unit())
    }

    /// `mm` or `deg`.
    pub fn unit(self) -> &'static str {
        self.kind.unit()
    }

    /// Position in the joint vector `s1, theta1, s2, theta2, ...` (0-based).
    pub fn index(self) -> usize {
        2 * (self.tube - 1)
            + match self.kind {
                ActuatorKind::Feed => 0,
                ActuatorKind::Rotation => 1,
            }
    }

    /// The joints of an n-tube robot in joint-vector order.
    ///
    /// ```
    /// let names: Vec<String> = ctr_formats::JointId::all(2).map(|j| j.name()).collect();
    /// assert_eq!(names, ["s1", "theta1", "s2", "theta2"]);
    /// ```
    pub fn all(n_tubes: usize) -> impl Iterator<Item = JointId> {
        (1..=n_tubes).flat_map(|tube| {
            [ActuatorKind::Feed, ActuatorKind::Rotation].map(|kind| JointId { tube, kind })
        })
    }
}

/// What is wrong with an `[actuation]` section (see [`InvalidActuation`] for where).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ActuationProblem {
    /// `name` is neither `s{i}` nor `theta{i}`.
    #[error("name \"{name}\" is not a joint of the robot; use s1..s{n_tubes} (feed, columns s<i>_mm) or theta1..theta{n_tubes} (rotation, columns theta<i>_deg)")]
    NotAJoint {
        /// The name given.
        name: String,
        /// The robot's tube count.
        n_tubes: usize,
    },
    /// `name` is the joint of a tube the robot does not have.
    #[error("name \"{name}\": the robot has {n_tubes} tube{}", if *.n_tubes == 1 { "" } else { "s" })]
    NoSuchTube {
        /// The name given.
        name: String,
        /// The robot's tube count.
        n_tubes: usize,
    },
    /// Two tables name the same joint.
    #[error("{name} is actuated twice (also by actuation.joint {})", .first + 1)]
    ActuatedTwice {
        /// The joint's name.
        name: String,
        /// The earlier table naming it (0-based).
        first: usize,
    },
    /// `kind` does not fit the joint's name.
    #[error("kind \"{}\" does not fit {name}, a {} joint (column {}); use kind = \"{}\"", .kind.as_str(), .joint.kind.as_str(), .joint.column(), .joint.kind.as_str())]
    KindMismatch {
        /// The joint's name.
        name: String,
        /// The kind given.
        kind: ActuatorKind,
        /// The joint the name stands for.
        joint: JointId,
    },
    /// `motor_id` above [`MAX_MOTOR_ID`].
    #[error("motor_id {motor_id} is not a device ID (0..={})", MAX_MOTOR_ID)]
    NotADeviceId {
        /// The ID given.
        motor_id: u8,
    },
    /// Two joints on one motor.
    #[error("motor_id {motor_id} already drives {other}")]
    MotorTwice {
        /// The motor's ID.
        motor_id: u8,
        /// The joint of the earlier table on that motor.
        other: String,
    },
    /// `ticks_per_rev = 0`.
    #[error("ticks_per_rev must be positive")]
    NoTicksPerRev,
    /// `direction` other than 1 or -1.
    #[error("direction must be 1 or -1, not {direction}")]
    BadDirection {
        /// The direction given.
        direction: i8,
    },
    /// `gear_ratio` on a feed joint.
    #[error("gear_ratio is for rotation joints; feed joint {name} takes mm_per_rev")]
    GearRatioOnFeed {
        /// The joint's name.
        name: String,
    },
    /// A feed joint without `mm_per_rev`.
    #[error("feed joint {name} needs mm_per_rev (mm of feed per motor revolution)")]
    MissingLead {
        /// The joint's name.
        name: String,
    },
    /// `mm_per_rev` not finite and positive.
    #[error("mm_per_rev = {lead} must be positive")]
    LeadNotPositive {
        /// The lead given, mm per motor revolution.
        lead: f64,
    },
    /// `mm_per_rev` on a rotation joint.
    #[error("mm_per_rev is for feed joints; rotation joint {name} takes gear_ratio")]
    LeadOnRotation {
        /// The joint's name.
        name: String,
    },
    /// `gear_ratio` not finite and positive.
    #[error("gear_ratio = {ratio} must be positive")]
    RatioNotPositive {
        /// The ratio given, motor revolutions per tube revolution.
        ratio: f64,
    },
    /// A NaN or infinite limit.
    #[error("{key} = {value} must be finite")]
    LimitNotFinite {
        /// `min` or `max`.
        key: &'static str,
        /// The limit given.
        value: f64,
    },
    /// `min > max`.
    #[error("min = {min} is above max = {max}")]
    MinAboveMax {
        /// The lower limit.
        min: f64,
        /// The upper limit.
        max: f64,
    },
    /// `max_speed` not finite and positive.
    #[error("max_speed = {max_speed} must be positive ({unit}/s)")]
    SpeedNotPositive {
        /// The speed given.
        max_speed: f64,
        /// The joint's unit.
        unit: &'static str,
    },
    /// A limit whose motor position does not fit the signed 32-bit register.
    #[error("{key} = {bound} is beyond the motor's 32-bit position range")]
    BeyondMotorRange {
        /// `min` or `max`.
        key: &'static str,
        /// The limit given.
        bound: f64,
    },
    /// A joint of the robot without a table.
    #[error("no [[actuation.joint]] for {} (column {}); each tube needs a feed joint s<i> and a rotation joint theta<i>", .joint.name(), .joint.column())]
    MissingJoint {
        /// The joint.
        joint: JointId,
    },
}

impl ActuationProblem {
    /// The key of the `[[actuation.joint]]` table the problem is about (`None`: the
    /// section as a whole).
    ///
    /// ```
    /// use ctr_formats::ActuationProblem;
    /// assert_eq!(ActuationProblem::NoTicksPerRev.key(), Some("ticks_per_rev"));
    /// ```
    pub fn key(&self) -> Option<&'static str> {
        use ActuationProblem::*;
        Some(match self {
            NotAJoint { .. } | NoSuchTube { .. } | ActuatedTwice { .. } | MissingLead { .. } => {
                "name"
            }
            KindMismatch { .. } => "kind",
            NotADeviceId { .. } | MotorTwice { .. } => "motor_id",
            NoTicksPerRev => "ticks_per_rev",
            BadDirection { .. } => "direction",
            GearRatioOnFeed { .. } | RatioNotPositive { .. } => "gear_ratio",
            LeadNotPositive { .. } | LeadOnRotation { .. } => "mm_per_rev",
            LimitNotFinite { key, .. } | BeyondMotorRange { key, .. } => key,
            MinAboveMax { .. } => "min",
            SpeedNotPositive { .. } => "max_speed",
            MissingJoint { .. } => return None,
        })
    }
}

/// An `[actuation]` section that does not fit its robot: which table and what is wrong.
/// Shown as `actuation.joint 3: <problem>` (tables count from 1), or `actuation:
/// <problem>` for the section as a whole.
///
/// ```
/// use ctr_formats::{ActuatedJoint, ActuationProblem, ActuationSection};
/// let joint = vec![
///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 10.0),
///     ActuatedJoint::rotation(1, 1, -180.0, 180.0, 90.0),
/// ];
/// let err = ActuationSection { joint }.validate(1).unwrap_err();
/// assert_eq!(err.table, Some(1));
/// assert!(matches!(err.problem, ActuationProblem::MotorTwice { motor_id: 1, .. }));
/// assert_eq!(err.to_string(), "actuation.joint 2: motor_id 1 already drives s1");
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct InvalidActuation {
    /// The `[[actuation.joint]]` table, 0-based; `None` for the section as a whole.
    pub table: Option<usize>,
    /// What is wrong.
    pub problem: ActuationProblem,
}

impl fmt::Display for InvalidActuation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.table {
            Some(i) => write!(f, "actuation.joint {}: {}", i + 1, self.problem),
            None => write!(f, "actuation: {}", self.problem),
        }
    }
}

impl std::error::Error for InvalidActuation {}

impl InvalidActuation {
    /// The key path of the offending value, for locating it in the file.
    pub(crate) fn key_path(&self) -> Vec<Key> {
        use Key::{Index, Name};
        match (self.table, self.problem.key()) {
            (Some(i), Some(key)) => vec![Name("actuation"), Name("joint"), Index(i), Name(key)],
            _ => vec![Name("actuation")],
        }
    }
}

impl ActuationSection {
    /// Checks the section against a robot of `n_tubes` tubes and returns its joints in
    /// joint-vector order (`s1, theta1, s2, ...`): every joint actuated exactly once, by a
    /// table whose kind fits its name, each motor driving one joint, and every table
    /// usable (see [`ActuationProblem`]). The first problem in file order is returned.
    ///
    /// ```
    /// use ctr_formats::{ActuatedJoint, ActuationSection};
    /// let joint = vec![
    ///     ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0),
    ///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 10.0),
    /// ];
    /// let joints = ActuationSection { joint }.validate(1)?;
    /// assert_eq!(joints[0].name, "s1");
    /// # Ok::<(), ctr_formats::InvalidActuation>(())
    /// ```
    pub fn validate(&self, n_tubes: usize) -> Result<Vec<ActuatedJoint>, InvalidActuation> {
        let mut slots: Vec<Option<usize>> = vec![None; 2 * n_tubes];
        for i in 0..self.joint.len() {
            let id = self
                .check_joint(i, n_tubes, &slots)
                .map_err(|problem| InvalidActuation {
                    table: Some(i),
                    problem,
                })?;
            slots[id.index()] = Some(i);
        }
        if let Some(joint) = JointId::all(n_tubes).find(|j| slots[j.index()].is_none()) {
            return Err(InvalidActuation {
                table: None,
                problem: ActuationProblem::MissingJoint { joint },
            });
        }
        // every slot is filled (checked just above)
        Ok(slots
            .into_iter()
            .flatten()
            .map(|i| self.joint[i].clone())
            .collect())
    }

    /// Checks table `i` given the joints taken by the tables before it (`slots`).
    fn check_joint(
        &self,
        i: usize,
        n_tubes: usize,
        slots: &[Option<usize>],
    ) -> Result<JointId, ActuationProblem> {
        use ActuationProblem::*;
        let joint = &self.joint[i];
        let name = || joint.name.clone();
        let id = JointId::parse(&joint.name).ok_or_else(|| NotAJoint {
            name: name(),
            n_tubes,
        })?;
        if id.tube > n_tubes {
            return Err(NoSuchTube {
                name: name(),
                n_tubes,
            });
        }
        if let Some(first) = slots[id.index()] {
            return Err(ActuatedTwice {
                name: name(),
                first,
            });
        }
        if joint.kind != id.kind {
            return Err(KindMismatch {
                name: name(),
                kind: joint.kind,
                joint: id,
            });
        }
        if joint.motor_id > MAX_MOTOR_ID {
            return Err(NotADeviceId {
                motor_id: joint.motor_id,
            });
        }
        if let Some(other) = self.joint[..i]
            .iter()
            .find(|o| o.motor_id == joint.motor_id)
        {
            return Err(MotorTwice {
                motor_id: joint.motor_id,
                other: other.name.clone(),
            });
        }
        if joint.ticks_per_rev == 0 {
            return Err(NoTicksPerRev);
        }
        if joint.direction != 1 && joint.direction != -1 {
            return Err(BadDirection {
                direction: joint.direction,
            });
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        match joint.kind {
            ActuatorKind::Feed => {
                if joint.gear_ratio.is_some() {
                    return Err(GearRatioOnFeed { name: name() });
                }
                match joint.mm_per_rev {
                    None => return Err(MissingLead { name: name() }),
                    Some(lead) if !positive(lead) => return Err(LeadNotPositive { lead }),
                    Some(_) => {}
                }
            }
            ActuatorKind::Rotation => {
                if joint.mm_per_rev.is_some() {
                    return Err(LeadOnRotation { name: name() });
                }
                if let Some(ratio) = joint.gear_ratio.filter(|r| !positive(*r)) {
                    return Err(RatioNotPositive { ratio });
                }
            }
        }
        for (key, value) in [("min", joint.min), ("max", joint.max)] {
            if !value.is_finite() {
                return Err(LimitNotFinite { key, value });
            }
        }
        if joint.min > joint.max {
            return Err(MinAboveMax {
                min: joint.min,
                max: joint.max,
            });
        }
        if !positive(joint.max_speed) {
            return Err(SpeedNotPositive {
                max_speed: joint.max_speed,
                unit: id.unit(),
            });
        }
        for (key, bound) in [("min", joint.min), ("max", joint.max)] {
            if joint.to_ticks(bound).is_none() {
                return Err(BeyondMotorRange { key, bound });
            }
        }
        Ok(id)
    }
}

#[cfg(test)]
mod tests {
    use crate::{RobotFile, RobotSpec};

    const BASE: &str = r#"name = "base"

[[tube]]
outer_diameter_mm = 6.8
inner_diameter_mm = 4.9
length_mm = 124.0
curved_length_mm = 74.0
curvature_radius_mm = -97.0
youngs_modulus_mpa = 150.0
poisson_ratio = 0.41

[[tube]]
outer_diameter_mm = 4.5
inner_diameter_mm = 3.3
length_mm = 174.0
curved_length_mm = 114.0
curvature_radius_mm = 98.5
youngs_modulus_mpa = 300.0
poisson_ratio = 0.41
"#;

    /// `BASE` has 19 lines: the first table's header is on line 21.
    const ACTUATION: &str = r#"
[[actuation.joint]]
name = "theta1"
motor_id = 2
kind = "rotation"
min = -180.0
max = 180.0
max_speed = 90.0

[[actuation.joint]]
name = "s1"
motor_id = 1
kind = "feed"
mm_per_rev = 8.0
min = 0.0
max = 60.0
max_speed = 10.0

[[actuation.joint]]
name = "s2"
motor_id = 3
kind = "feed"
mm_per_rev = 2.5
direction = -1
zero_offset_ticks = 1000
min = 0.0
max = 120.0
max_speed = 5.0

[[actuation.joint]]
name = "theta2"
motor_id = 4
kind = "rotation"
gear_ratio = 2.0
ticks_per_rev = 1000
min = -360
max = 360
max_speed = 180
"#;

    fn robot(actuation: &str) -> String {
        format!("{BASE}{actuation}")
    }

    fn err(actuation: &str) -> String {
        RobotSpec::from_toml_str(&robot(actuation), "robot.toml")
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn joints_come_in_joint_vector_order_and_round_trip() {
        let spec = RobotSpec::from_toml_str(&robot(ACTUATION), "robot.toml").unwrap();
        let joints = spec.actuation.as_ref().unwrap();
        let names: Vec<&str> = joints.iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["s1", "theta1", "s2", "theta2"]);
        assert_eq!(joints[0].ticks_per_rev, 4096, "default");
        assert_eq!(joints[0].direction, 1, "default");
        assert_eq!(joints[2].zero_offset_ticks, 1000);
        assert_eq!(joints[3].min, -360.0, "integers read as floats");
        let text = spec.to_toml();
        assert!(text.contains("[[actuation.joint]]"), "{text}");
        let back = RobotSpec::from_toml_str(&text, "back.toml").unwrap();
        assert_eq!(back, spec, "{text}");
        assert_eq!(back.to_toml(), text);
        // A file keeps its own order.
        let file = RobotFile::parse(&robot(ACTUATION), "robot.toml").unwrap();
        let again = RobotFile::parse(&file.to_toml(), "again.toml").unwrap();
        assert_eq!(again, file);
        assert_eq!(again.actuation.unwrap().joint[0].name, "theta1");
    }

    #[test]
    fn robots_without_actuation_have_none() {
        let spec = RobotSpec::from_toml_str(BASE, "robot.toml").unwrap();
        assert_eq!(spec.actuation, None);
        assert!(!spec.to_toml().contains("actuation"));
    }

    #[test]
    fn errors_name_file_line_column_and_field() {
        let cases = [
            (
                ACTUATION.replace("name = \"s2\"", "name = \"alpha2\""),
                "robot.toml:39:8: actuation.joint 3: name \"alpha2\" is not a joint of the robot; use s1..s2 (feed, columns s<i>_mm) or theta1..theta2 (rotation, columns theta<i>_deg)",
            ),
            (
                ACTUATION.replace("name = \"s2\"", "name = \"s3\""),
                "robot.toml:39:8: actuation.joint 3: name \"s3\": the robot has 2 tubes",
            ),
            (
                ACTUATION.replace("name = \"s2\"", "name = \"s1\""),
                "robot.toml:39:8: actuation.joint 3: s1 is actuated twice (also by actuation.joint 2)",
            ),
            (
                ACTUATION.replace("kind = \"feed\"\nmm_per_rev = 2.5", "kind = \"rotation\"\nmm_per_rev = 2.5"),
                "robot.toml:41:8: actuation.joint 3: kind \"rotation\" does not fit s2, a feed joint (column s2_mm); use kind = \"feed\"",
            ),
            (
                ACTUATION.replace("motor_id = 3", "motor_id = 1"),
                "robot.toml:40:12: actuation.joint 3: motor_id 1 already drives s1",
            ),
            (
                ACTUATION.replace("motor_id = 3", "motor_id = 253"),
                "robot.toml:40:12: actuation.joint 3: motor_id 253 is not a device ID (0..=252)",
            ),
            (
                ACTUATION.replace("direction = -1", "direction = 0"),
                "robot.toml:43:13: actuation.joint 3: direction must be 1 or -1, not 0",
            ),
            (
                ACTUATION.replace("mm_per_rev = 2.5\n", ""),
                "robot.toml:39:8: actuation.joint 3: feed joint s2 needs mm_per_rev (mm of feed per motor revolution)",
            ),
            (
                ACTUATION.replace("mm_per_rev = 2.5", "mm_per_rev = -2.5"),
                "robot.toml:42:14: actuation.joint 3: mm_per_rev = -2.5 must be positive",
            ),
            (
                ACTUATION.replace("mm_per_rev = 2.5", "gear_ratio = 2.5"),
                "robot.toml:42:14: actuation.joint 3: gear_ratio is for rotation joints; feed joint s2 takes mm_per_rev",
            ),
            (
                ACTUATION.replace("gear_ratio = 2.0", "mm_per_rev = 2.0"),
                "robot.toml:53:14: actuation.joint 4: mm_per_rev is for feed joints; rotation joint theta2 takes gear_ratio",
            ),
            (
                ACTUATION.replace("gear_ratio = 2.0", "gear_ratio = 0.0"),
                "robot.toml:53:14: actuation.joint 4: gear_ratio = 0 must be positive",
            ),
            (
                ACTUATION.replace("ticks_per_rev = 1000", "ticks_per_rev = 0"),
                "robot.toml:54:17: actuation.joint 4: ticks_per_rev must be positive",
            ),
            (
                ACTUATION.replace("max = 120.0", "max = -1.0"),
                "robot.toml:45:7: actuation.joint 3: min = 0 is above max = -1",
            ),
            (
                ACTUATION.replace("max = 120.0", "max = nan"),
                "robot.toml:46:7: actuation.joint 3: max = NaN must be finite",
            ),
            (
                ACTUATION.replace("max_speed = 5.0", "max_speed = 0.0"),
                "robot.toml:47:13: actuation.joint 3: max_speed = 0 must be positive (mm/s)",
            ),
            (
                ACTUATION.replace("max = 120.0", "max = 1e12"),
                "robot.toml:46:7: actuation.joint 3: max = 1000000000000 is beyond the motor's 32-bit position range",
            ),
            (
                ACTUATION.replace("name = \"theta2\"", "name = \"s2\""),
                "robot.toml:50:8: actuation.joint 4: s2 is actuated twice (also by actuation.joint 3)",
            ),
        ];
        let mut wrong = Vec::new();
        for (text, expected) in cases {
            let got = err(&text);
            if got != expected {
                wrong.push(format!("got      {got}\nexpected {expected}"));
            }
        }
        assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    }

    #[test]
    fn missing_joints_and_shape_errors() {
        let three: String = ACTUATION
            .split("\n\n")
            .take(3)
            .collect::<Vec<_>>()
            .join("\n\n");
        let e = err(&three);
        assert!(
            e.starts_with("robot.toml:")
                && e.ends_with("actuation: no [[actuation.joint]] for theta2 (column theta2_deg); each tube needs a feed joint s<i> and a rotation joint theta<i>"),
            "{e}"
        );
        assert_eq!(
            err("\n[actuation]\n"),
            "robot.toml:21:1: actuation: no [[actuation.joint]] for s1 (column s1_mm); each tube needs a feed joint s<i> and a rotation joint theta<i>"
        );
        // serde's own errors: unknown key, wrong type, out-of-range integer
        let e = err(&ACTUATION.replace("max_speed = 5.0", "max_sped = 5.0"));
        assert!(e.starts_with("robot.toml:47:1: "), "{e}");
        assert!(e.contains("unknown field `max_sped`"), "{e}");
        let e = err(&ACTUATION.replace("motor_id = 3", "motor_id = 300"));
        assert!(
            e.starts_with("robot.toml:40:12: actuation.joint 3: motor_id: "),
            "{e}"
        );
        let e = err(&ACTUATION.replace(
            "kind = \"feed\"\nmm_per_rev = 2.5",
            "kind = \"slide\"\nmm_per_rev = 2.5",
        ));
        assert!(
            e.starts_with("robot.toml:41:8: actuation.joint 3: kind: "),
            "{e}"
        );
        assert!(e.contains("rotation") && e.contains("feed"), "{e}");
        assert_eq!(e.lines().count(), 1);
    }
}

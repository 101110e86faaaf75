//! The rig's side of the actuation: joint vectors to motor positions and back, checked
//! against the joint limits, and the motors' profile velocities.
//!
//! Which motor drives which joint, and how, is the robot file's `[actuation]` section
//! (`data/FORMATS-EXTENSION.md`): one [`ActuatedJoint`] per joint, `s{i}` the feed of
//! tube i (mm) and `theta{i}` its rotation (degrees). The schema, the mapping of a joint
//! value to motor ticks ([`ActuatedJoint::to_ticks`]) and the validation live in
//! `ctr_formats`; an [`Actuation`] holds a validated set of joints in joint-vector order
//! (`s1, theta1, s2, theta2, ...`) and adds what driving the motors needs:
//!
//! * limits (`min`, `max`, in joint units, inclusive) are checked before a value is
//!   turned into ticks, so nothing out of range ever reaches the bus;
//! * `max_speed` (joint units per second) becomes the motor's profile velocity, in the
//!   units of the control table ([`profile_velocity`]).
//!
//! ```
//! use ctr_formats::ActuatedJoint;
//! use ctr_hw::actuation::Actuation;
//!
//! let mut s1 = ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 10.0); // a lead of 8 mm per motor revolution
//! s1.direction = -1; // the motor turns backwards as the tube goes in
//! let theta1 = ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0);
//! let actuation = Actuation::new(vec![theta1, s1])?; // kept in joint-vector order
//! let ticks = actuation.to_ticks(&[8.0, 90.0])?;
//! assert_eq!(ticks, [-4096, 1024]);
//! assert_eq!(actuation.from_ticks(&ticks)?, [8.0, 90.0]);
//! assert!(actuation.to_ticks(&[61.0, 90.0]).is_err()); // s1 above its max
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt;

use ctr_formats::{ActuatedJoint, ActuationSection, InvalidActuation};

use crate::control_table::{PROFILE_MAX, VELOCITY_UNIT_RPM};

/// Seconds per minute: profile velocities are in revolutions per minute.
const SECONDS_PER_MINUTE: f64 = 60.0;

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
/// use ctr_formats::ActuatedJoint;
/// use ctr_hw::actuation::{check_limits, ActuationError, Limit};
/// let theta1 = ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0);
/// let err = check_limits(&theta1, 200.0).unwrap_err();
/// assert_eq!(err.to_string(), "joint theta1: 200 deg is above its max limit 180 deg");
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
    /// The joints are not a valid actuation (the robot file's rules, see
    /// [`ctr_formats::ActuationProblem`]).
    #[error(transparent)]
    Invalid(#[from] InvalidActuation),
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

/// Checks `value` against the joint's limits (inclusive).
///
/// ```
/// use ctr_hw::actuation::check_limits;
/// let theta1 = ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0);
/// assert!(check_limits(&theta1, 90.0).is_ok());
/// assert!(check_limits(&theta1, -90.5).is_err());
/// assert!(check_limits(&theta1, f64::NAN).is_err());
/// ```
pub fn check_limits(joint: &ActuatedJoint, value: f64) -> Result<(), ActuationError> {
    if !value.is_finite() {
        return Err(ActuationError::NotFinite {
            joint: joint.name.clone(),
            value,
        });
    }
    let violated = if value < joint.min {
        Some((Limit::Min, joint.min))
    } else if value > joint.max {
        Some((Limit::Max, joint.max))
    } else {
        None
    };
    match violated {
        Some((limit, bound)) => Err(ActuationError::OutOfLimits {
            joint: joint.name.clone(),
            value,
            limit,
            bound,
            unit: joint.unit(),
        }),
        None => Ok(()),
    }
}

/// The goal position for a joint value, after the limit check.
///
/// ```
/// use ctr_hw::actuation::goal_ticks;
/// let s1 = ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 10.0);
/// assert_eq!(goal_ticks(&s1, 4.0).unwrap(), 2048);
/// assert!(goal_ticks(&s1, -4.0).is_err());
/// ```
pub fn goal_ticks(joint: &ActuatedJoint, value: f64) -> Result<i32, ActuationError> {
    check_limits(joint, value)?;
    joint
        .to_ticks(value)
        .ok_or_else(|| ActuationError::TickOverflow {
            joint: joint.name.clone(),
            value,
        })
}

/// The profile velocity (X-series units of [`VELOCITY_UNIT_RPM`]) for the joint's
/// `max_speed`, rounded down so the joint never exceeds it, at least 1 (0 would mean
/// "unlimited"), at most [`PROFILE_MAX`].
///
/// ```
/// let theta1 = ctr_formats::ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0);
/// // 90 deg/s = 15 rev/min = 65.5 units
/// assert_eq!(ctr_hw::actuation::profile_velocity(&theta1), 65);
/// ```
pub fn profile_velocity(joint: &ActuatedJoint) -> u32 {
    let rpm = joint.max_speed * joint.motor_revs_per_unit() * SECONDS_PER_MINUTE;
    let units = (rpm / VELOCITY_UNIT_RPM).floor();
    if units.is_finite() {
        (units as u32).clamp(1, PROFILE_MAX)
    } else {
        1
    }
}

/// The validated joint-to-motor mapping of a rig, in joint-vector order.
///
/// ```
/// use ctr_formats::ActuatedJoint;
/// use ctr_hw::actuation::Actuation;
/// let act = Actuation::new(vec![
///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 10.0),
///     ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0),
/// ])?;
/// assert_eq!(act.motor_ids(), [1, 2]);
/// assert_eq!(act.from_ticks(&[4096, 1024])?, [8.0, 90.0]);
/// # Ok::<(), ctr_hw::actuation::ActuationError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Actuation {
    joints: Vec<ActuatedJoint>,
}

impl Actuation {
    /// Checks `joints` by the robot file's rules for a robot of `joints.len() / 2` tubes
    /// (a feed `s{i}` and a rotation `theta{i}` per tube, each once, each motor driving
    /// one joint, every table usable: [`ActuationSection::validate`]) and keeps them in
    /// joint-vector order.
    ///
    /// ```
    /// use ctr_formats::{ActuatedJoint, ActuationProblem};
    /// use ctr_hw::actuation::{Actuation, ActuationError};
    /// let err = Actuation::new(vec![
    ///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 10.0),
    ///     ActuatedJoint::rotation(1, 1, -1.0, 1.0, 1.0),
    /// ]).unwrap_err();
    /// let ActuationError::Invalid(invalid) = err else { panic!() };
    /// assert!(matches!(invalid.problem, ActuationProblem::MotorTwice { motor_id: 1, .. }));
    /// ```
    pub fn new(joints: Vec<ActuatedJoint>) -> Result<Self, ActuationError> {
        let n_tubes = joints.len().div_ceil(2);
        let joints = ActuationSection { joint: joints }.validate(n_tubes)?;
        Ok(Self { joints })
    }

    /// The joints in order.
    ///
    /// ```
    /// # use ctr_formats::ActuatedJoint;
    /// # use ctr_hw::actuation::Actuation;
    /// let act = Actuation::new(vec![
    ///     ActuatedJoint::rotation(1, 2, -1.0, 1.0, 1.0),
    ///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 1.0, 1.0),
    /// ]).unwrap();
    /// assert_eq!(act.joints()[0].name, "s1");
    /// ```
    pub fn joints(&self) -> &[ActuatedJoint] {
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
    /// # use ctr_formats::ActuatedJoint;
    /// # use ctr_hw::actuation::Actuation;
    /// let act = Actuation::new(vec![
    ///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 1.0, 1.0),
    ///     ActuatedJoint::rotation(1, 2, -1.0, 1.0, 1.0),
    /// ]).unwrap();
    /// assert_eq!(act.index_of("theta1").unwrap(), 1);
    /// assert!(act.index_of("theta2").is_err());
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
    /// # use ctr_formats::ActuatedJoint;
    /// # use ctr_hw::actuation::Actuation;
    /// let act = Actuation::new(vec![
    ///     ActuatedJoint::rotation(1, 7, -1.0, 1.0, 1.0),
    ///     ActuatedJoint::feed(1, 3, 8.0, 0.0, 1.0, 1.0),
    /// ]).unwrap();
    /// assert_eq!(act.motor_ids(), [3, 7]);
    /// ```
    pub fn motor_ids(&self) -> Vec<u8> {
        self.joints.iter().map(|j| j.motor_id).collect()
    }

    /// Motor positions for a full joint vector; every value is checked before any is
    /// converted, and the first violation is returned.
    ///
    /// ```
    /// # use ctr_formats::ActuatedJoint;
    /// # use ctr_hw::actuation::Actuation;
    /// let act = Actuation::new(vec![
    ///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 1.0),
    ///     ActuatedJoint::rotation(1, 2, -90.0, 90.0, 1.0),
    /// ]).unwrap();
    /// assert_eq!(act.to_ticks(&[0.0, 90.0]).unwrap(), [0, 1024]);
    /// assert!(act.to_ticks(&[0.0, 90.0, 1.0]).is_err()); // wrong length
    /// ```
    pub fn to_ticks(&self, values: &[f64]) -> Result<Vec<i32>, ActuationError> {
        self.check_count(values.len())?;
        for (joint, &value) in self.joints.iter().zip(values) {
            check_limits(joint, value)?;
        }
        self.joints
            .iter()
            .zip(values)
            .map(|(joint, &value)| goal_ticks(joint, value))
            .collect()
    }

    /// Joint values for motor positions in joint order.
    ///
    /// ```
    /// # use ctr_formats::ActuatedJoint;
    /// # use ctr_hw::actuation::Actuation;
    /// let act = Actuation::new(vec![
    ///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 1.0),
    ///     ActuatedJoint::rotation(1, 2, -90.0, 90.0, 1.0),
    /// ]).unwrap();
    /// assert_eq!(act.from_ticks(&[2048, -1024]).unwrap(), [4.0, -90.0]);
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
    use ctr_formats::{ActuationProblem, RobotSpec};

    /// The liu2023 tubes with a four-motor actuation: motors in the order of the tables,
    /// the joints in another.
    fn four_joints_robot() -> String {
        let tubes = include_str!("../../../data/robots/liu2023.toml");
        format!("{tubes}{FOUR_JOINTS}")
    }

    const FOUR_JOINTS: &str = r#"
        [[actuation.joint]]
        name = "theta1"
        motor_id = 1
        kind = "rotation"
        gear_ratio = 2.0
        min = -180.0
        max = 180.0
        max_speed = 90.0

        [[actuation.joint]]
        name = "s1"
        motor_id = 2
        kind = "feed"
        mm_per_rev = 8.0
        direction = -1
        zero_offset_ticks = 500
        min = -60.0
        max = 0.0
        max_speed = 10.0

        [[actuation.joint]]
        name = "theta2"
        motor_id = 3
        kind = "rotation"
        ticks_per_rev = 1000
        min = -360
        max = 360
        max_speed = 180

        [[actuation.joint]]
        name = "s2"
        motor_id = 4
        kind = "feed"
        mm_per_rev = 2.5
        min = -30.0
        max = 0.0
        max_speed = 5.0
    "#;

    fn read(robot: &str) -> Result<Actuation, String> {
        let spec = RobotSpec::from_toml_str(robot, "robot.toml").map_err(|e| e.to_string())?;
        Actuation::new(spec.actuation.expect("an [actuation] section")).map_err(|e| e.to_string())
    }

    /// In joint-vector order: s1 (motor 2), theta1 (1), s2 (4), theta2 (3).
    fn four() -> Actuation {
        read(&four_joints_robot()).unwrap()
    }

    #[test]
    fn reads_the_robot_files_section() {
        let act = four();
        assert_eq!(act.len(), 4);
        assert_eq!(act.motor_ids(), [2, 1, 4, 3]);
        let s1 = &act.joints()[0];
        assert_eq!(s1.direction, -1);
        assert_eq!(s1.zero_offset_ticks, 500);
        assert_eq!(act.joints()[3].ticks_per_rev, 1000);
        assert_eq!(act.joints()[3].min, -360.0); // integers accepted for floats
        assert_eq!(act.joints()[1].ticks_per_rev, 4096);
    }

    #[test]
    fn converts_both_ways() {
        let act = four();
        // s1: 8 mm/rev, reversed, offset 500; -8 mm → 500 + 4096.
        // theta1: gear 2 → 1 joint rev = 8192 ticks; 45° = 1024.
        // s2: 2.5 mm/rev; -5 mm = -2 rev = -8192.
        // theta2: 1000 ticks/rev; 36° = 100.
        let ticks = act.to_ticks(&[-8.0, 45.0, -5.0, 36.0]).unwrap();
        assert_eq!(ticks, [4596, 1024, -8192, 100]);
        assert_eq!(act.from_ticks(&ticks).unwrap(), [-8.0, 45.0, -5.0, 36.0]);
        // Round trip within half a tick of resolution.
        for joint in act.joints() {
            let resolution = 1.0 / (joint.motor_revs_per_unit() * f64::from(joint.ticks_per_rev));
            for k in 0..=20 {
                let value = joint.min + (joint.max - joint.min) * f64::from(k) / 20.0;
                let back = joint.from_ticks(goal_ticks(joint, value).unwrap());
                assert!((back - value).abs() <= 0.5 * resolution + 1e-12);
            }
        }
    }

    #[test]
    fn limits_are_checked_before_conversion_and_name_the_joint() {
        let act = four();
        let err = act.to_ticks(&[0.5, 0.0, 0.0, 0.0]).unwrap_err();
        assert_eq!(
            err,
            ActuationError::OutOfLimits {
                joint: "s1".into(),
                value: 0.5,
                limit: Limit::Max,
                bound: 0.0,
                unit: "mm",
            }
        );
        let err = act.to_ticks(&[0.0, -181.0, 0.0, 0.0]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "joint theta1: -181 deg is below its min limit -180 deg"
        );
        assert!(matches!(
            act.to_ticks(&[0.0, 0.0, 0.0, f64::INFINITY]),
            Err(ActuationError::NotFinite { .. })
        ));
        // Limits are inclusive.
        assert!(act.to_ticks(&[-60.0, 180.0, 0.0, -360.0]).is_ok());
    }

    #[test]
    fn rejects_bad_sections() {
        let robot = four_joints_robot();
        let cases = [
            ("unknown key", robot.replace("gear_ratio", "gear_raito")),
            (
                "duplicate id",
                robot.replace("motor_id = 4", "motor_id = 3"),
            ),
            ("duplicate name", robot.replace("\"s2\"", "\"s1\"")),
            ("feed without lead", robot.replace("mm_per_rev = 2.5", "")),
            (
                "rotation with lead",
                robot.replace("ticks_per_rev = 1000", "mm_per_rev = 1.0"),
            ),
            (
                "bad direction",
                robot.replace("direction = -1", "direction = 2"),
            ),
            ("min above max", robot.replace("min = -30.0", "min = 30.0")),
            (
                "zero speed",
                robot.replace("max_speed = 5.0", "max_speed = 0.0"),
            ),
            ("bad kind", robot.replace("\"feed\"", "\"slide\"")),
            (
                "broadcast id",
                robot.replace("motor_id = 4", "motor_id = 254"),
            ),
        ];
        for (what, text) in cases {
            assert!(read(&text).is_err(), "{what} accepted");
        }
        let err = read(&robot.replace("motor_id = 4", "motor_id = 3")).unwrap_err();
        assert!(
            err.ends_with("actuation.joint 4: motor_id 3 already drives theta2"),
            "{err}"
        );
    }

    #[test]
    fn the_same_rules_hold_for_joints_built_in_code() {
        let mut joints = vec![
            ActuatedJoint::rotation(1, 1, -180.0, 180.0, 90.0),
            ActuatedJoint::feed(1, 2, 8.0, -60.0, 0.0, 10.0),
            ActuatedJoint::rotation(2, 3, -180.0, 180.0, 90.0),
            ActuatedJoint::feed(2, 4, 2.5, -30.0, 0.0, 5.0),
        ];
        joints[3].motor_id = 3;
        let Err(ActuationError::Invalid(invalid)) = Actuation::new(joints) else {
            panic!("two joints on motor 3 accepted")
        };
        assert_eq!(invalid.table, Some(3));
        assert_eq!(
            invalid.problem,
            ActuationProblem::MotorTwice {
                motor_id: 3,
                other: "theta2".into()
            }
        );
    }

    #[test]
    fn limits_beyond_the_motor_range_are_rejected() {
        let joints = vec![
            ActuatedJoint::feed(1, 1, 0.001, -1e9, 0.0, 1.0),
            ActuatedJoint::rotation(1, 2, -1.0, 1.0, 1.0),
        ];
        assert!(matches!(
            Actuation::new(joints),
            Err(ActuationError::Invalid(InvalidActuation {
                problem: ActuationProblem::BeyondMotorRange { key: "min", .. },
                ..
            }))
        ));
    }

    #[test]
    fn profile_velocity_never_exceeds_max_speed() {
        for joint in four().joints() {
            let pv = profile_velocity(joint);
            let speed = f64::from(pv) * VELOCITY_UNIT_RPM
                / SECONDS_PER_MINUTE
                / joint.motor_revs_per_unit();
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

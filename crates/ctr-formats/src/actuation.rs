//! `[actuation]`: which motor drives which joint of the robot, and how (the shape is
//! documented in [the module above](super)).
//!
//! The tables have exactly the shape of `ctr-hw`'s `[[actuation.joint]]` (this crate
//! keeps its own serde mirror so that reading robot files needs no serial-port code);
//! what the robot file adds is the naming rule that ties each table to a joint column:
//! `s{i}` is the feed of tube i (column `s{i}_mm`, kind `feed`, mm) and `theta{i}` its
//! rotation (column `theta{i}_deg`, kind `rotation`, degrees). The joint value in the
//! file's units is what the motor mapping converts, unchanged: `s{i} = 0` is tube i's
//! tip at the guide exit, `theta{i} = 0` its zero rotation.

use super::robot_file::Key;
use serde::{Deserialize, Serialize};

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
    pub fn as_str(self) -> &'static str {
        match self {
            ActuatorKind::Rotation => "rotation",
            ActuatorKind::Feed => "feed",
        }
    }
}

/// The encoder ticks per motor revolution of the X-series servos.
pub const DEFAULT_TICKS_PER_REV: u32 = 4096;

/// Largest device ID a motor can have (253..=255 are reserved by Dynamixel 2.0).
pub const MAX_MOTOR_ID: u8 = 252;

fn default_ticks_per_rev() -> u32 {
    DEFAULT_TICKS_PER_REV
}

fn default_direction() -> i8 {
    1
}

/// One `[[actuation.joint]]` table.
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
            ActuatorKind::Rotation => self.gear_ratio.unwrap_or(1.0) / 360.0,
            ActuatorKind::Feed => 1.0 / self.mm_per_rev.unwrap_or(f64::NAN),
        }
    }

    /// The motor position of a joint value, if it fits a signed 32-bit register.
    fn ticks(&self, value: f64) -> Option<f64> {
        let delta = (value * self.motor_revs_per_unit() * f64::from(self.ticks_per_rev)).round();
        let ticks = f64::from(self.zero_offset_ticks) + f64::from(self.direction) * delta;
        (ticks.is_finite() && ticks >= f64::from(i32::MIN) && ticks <= f64::from(i32::MAX))
            .then_some(ticks)
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
        match self.kind {
            ActuatorKind::Feed => "mm",
            ActuatorKind::Rotation => "deg",
        }
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

/// Checks `[actuation]` against a robot of `n_tubes` tubes and returns its joints in
/// joint-vector order (`s1, theta1, s2, ...`). Errors come with the key path of the
/// offending value, for locating it in the file.
pub(crate) fn validate(
    section: &ActuationSection,
    n_tubes: usize,
) -> Result<Vec<ActuatedJoint>, (String, Vec<Key>)> {
    use Key::{Index, Name};
    let mut slots: Vec<Option<usize>> = vec![None; 2 * n_tubes];
    for (i, joint) in section.joint.iter().enumerate() {
        let at = |key: &'static str| vec![Name("actuation"), Name("joint"), Index(i), Name(key)];
        let fail = |key: &'static str, message: String| {
            Err((format!("actuation.joint {}: {message}", i + 1), at(key)))
        };
        let Some(id) = JointId::parse(&joint.name) else {
            return fail(
                "name",
                format!(
                    "name \"{}\" is not a joint of the robot; use s1..s{n_tubes} (feed, columns s<i>_mm) or theta1..theta{n_tubes} (rotation, columns theta<i>_deg)",
                    joint.name
                ),
            );
        };
        if id.tube > n_tubes {
            return fail(
                "name",
                format!(
                    "name \"{}\": the robot has {n_tubes} tube{}",
                    joint.name,
                    if n_tubes == 1 { "" } else { "s" }
                ),
            );
        }
        if let Some(first) = slots[id.index()] {
            return fail(
                "name",
                format!(
                    "{} is actuated twice (also by actuation.joint {})",
                    joint.name,
                    first + 1
                ),
            );
        }
        if joint.kind != id.kind {
            return fail(
                "kind",
                format!(
                    "kind \"{}\" does not fit {}, a {} joint (column {}); use kind = \"{}\"",
                    joint.kind.as_str(),
                    joint.name,
                    id.kind.as_str(),
                    id.column(),
                    id.kind.as_str()
                ),
            );
        }
        if joint.motor_id > MAX_MOTOR_ID {
            return fail(
                "motor_id",
                format!(
                    "motor_id {} is not a device ID (0..={MAX_MOTOR_ID})",
                    joint.motor_id
                ),
            );
        }
        if let Some(other) = section.joint[..i]
            .iter()
            .find(|o| o.motor_id == joint.motor_id)
        {
            return fail(
                "motor_id",
                format!("motor_id {} already drives {}", joint.motor_id, other.name),
            );
        }
        if joint.ticks_per_rev == 0 {
            return fail("ticks_per_rev", "ticks_per_rev must be positive".into());
        }
        if joint.direction != 1 && joint.direction != -1 {
            return fail(
                "direction",
                format!("direction must be 1 or -1, not {}", joint.direction),
            );
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        match joint.kind {
            ActuatorKind::Feed => {
                if joint.gear_ratio.is_some() {
                    return fail(
                        "gear_ratio",
                        format!(
                            "gear_ratio is for rotation joints; feed joint {} takes mm_per_rev",
                            joint.name
                        ),
                    );
                }
                match joint.mm_per_rev {
                    None => {
                        return Err((
                            format!(
                                "actuation.joint {}: feed joint {} needs mm_per_rev (mm of feed per motor revolution)",
                                i + 1,
                                joint.name
                            ),
                            at("name"),
                        ))
                    }
                    Some(lead) if !positive(lead) => {
                        return fail(
                            "mm_per_rev",
                            format!("mm_per_rev = {lead} must be positive"),
                        )
                    }
                    Some(_) => {}
                }
            }
            ActuatorKind::Rotation => {
                if joint.mm_per_rev.is_some() {
                    return fail(
                        "mm_per_rev",
                        format!(
                            "mm_per_rev is for feed joints; rotation joint {} takes gear_ratio",
                            joint.name
                        ),
                    );
                }
                if let Some(ratio) = joint.gear_ratio.filter(|r| !positive(*r)) {
                    return fail(
                        "gear_ratio",
                        format!("gear_ratio = {ratio} must be positive"),
                    );
                }
            }
        }
        if !joint.min.is_finite() {
            return fail("min", format!("min = {} must be finite", joint.min));
        }
        if !joint.max.is_finite() {
            return fail("max", format!("max = {} must be finite", joint.max));
        }
        if joint.min > joint.max {
            return fail(
                "min",
                format!("min = {} is above max = {}", joint.min, joint.max),
            );
        }
        if !positive(joint.max_speed) {
            return fail(
                "max_speed",
                format!(
                    "max_speed = {} must be positive ({}/s)",
                    joint.max_speed,
                    id.unit()
                ),
            );
        }
        for (key, bound) in [("min", joint.min), ("max", joint.max)] {
            if joint.ticks(bound).is_none() {
                return fail(
                    key,
                    format!("{key} = {bound} is beyond the motor's 32-bit position range"),
                );
            }
        }
        slots[id.index()] = Some(i);
    }
    if let Some(missing) = JointId::all(n_tubes).find(|j| slots[j.index()].is_none()) {
        return Err((
            format!(
                "actuation: no [[actuation.joint]] for {} (column {}); each tube needs a feed joint s<i> and a rotation joint theta<i>",
                missing.name(),
                missing.column()
            ),
            vec![Name("actuation")],
        ));
    }
    // every slot is filled (checked just above)
    Ok(slots
        .into_iter()
        .flatten()
        .map(|i| section.joint[i].clone())
        .collect())
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

//! Set-up shared by the tests of `ctr-hw`: the integration tests declare this file as a
//! module, the unit tests include it too (`#[path]` in `src/lib.rs`). It names nothing
//! but `ctr_formats`, the same crate under both.

use ctr_formats::ActuatedJoint;

/// The joints of a two-tube rig on the emulator's four motors, in joint-vector order:
/// s1 on motor 1 (-60..0 mm), theta1 on motor 2, s2 on motor 3 (-30..0 mm), theta2 on
/// motor 4 (rotations -180..180 degrees); leads of 8 mm per motor revolution; feeds at
/// most `feed_speed` mm/s, rotations at most `rotation_speed` degrees/s.
pub fn two_tubes(feed_speed: f64, rotation_speed: f64) -> Vec<ActuatedJoint> {
    vec![
        ActuatedJoint::feed(1, 1, 8.0, -60.0, 0.0, feed_speed),
        ActuatedJoint::rotation(1, 2, -180.0, 180.0, rotation_speed),
        ActuatedJoint::feed(2, 3, 8.0, -30.0, 0.0, feed_speed),
        ActuatedJoint::rotation(2, 4, -180.0, 180.0, rotation_speed),
    ]
}

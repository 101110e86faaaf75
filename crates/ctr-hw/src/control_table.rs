//! The subset of the Dynamixel X-series control table (XM430/XL430 family) that the rig
//! and the emulator use: addresses, sizes and units.
//!
//! Multi-byte values are little-endian; positions and velocities are signed.
//!
//! ```
//! use ctr_hw::control_table as ct;
//! assert_eq!((ct::GOAL_POSITION, ct::GOAL_POSITION_LEN), (116, 4));
//! // 100 units of profile velocity are 22.9 rev/min.
//! assert!((100.0 * ct::VELOCITY_UNIT_RPM - 22.9).abs() < 1e-9);
//! ```

/// Model number (2 bytes, read-only).
pub const MODEL_NUMBER: u16 = 0;
/// Firmware version (1 byte, read-only).
pub const FIRMWARE_VERSION: u16 = 6;
/// Device ID (1 byte, EEPROM).
pub const ID: u16 = 7;
/// Operating mode (1 byte, EEPROM): 3 position, 4 extended (multi-turn) position.
pub const OPERATING_MODE: u16 = 11;
/// Maximum position limit (4 bytes, EEPROM; used in position mode only).
pub const MAX_POSITION_LIMIT: u16 = 48;
/// Minimum position limit (4 bytes, EEPROM; used in position mode only).
pub const MIN_POSITION_LIMIT: u16 = 52;
/// First RAM address: below it is EEPROM, writable only while torque is off.
pub const RAM_START: u16 = 64;
/// Torque enable (1 byte): 0 off, 1 on.
pub const TORQUE_ENABLE: u16 = 64;
/// Hardware error status (1 byte, read-only); see the `HW_ERROR_*` bits.
pub const HARDWARE_ERROR_STATUS: u16 = 70;
/// Profile acceleration (4 bytes), in [`ACCELERATION_UNIT_RPM2`]; 0 means unlimited.
pub const PROFILE_ACCELERATION: u16 = 108;
/// Profile velocity (4 bytes), in [`VELOCITY_UNIT_RPM`]; 0 means the motor's maximum.
pub const PROFILE_VELOCITY: u16 = 112;
/// Goal position (4 bytes, signed ticks).
pub const GOAL_POSITION: u16 = 116;
/// Length of the goal position.
pub const GOAL_POSITION_LEN: u16 = 4;
/// Moving (1 byte, read-only): 1 while the motor moves.
pub const MOVING: u16 = 122;
/// Present velocity (4 bytes, signed, read-only), in [`VELOCITY_UNIT_RPM`].
pub const PRESENT_VELOCITY: u16 = 128;
/// Present position (4 bytes, signed ticks, read-only).
pub const PRESENT_POSITION: u16 = 132;
/// Length of the present position.
pub const PRESENT_POSITION_LEN: u16 = 4;

/// Hardware error bit: input voltage out of range.
pub const HW_ERROR_INPUT_VOLTAGE: u8 = 1 << 0;
/// Hardware error bit: overheating.
pub const HW_ERROR_OVERHEATING: u8 = 1 << 2;
/// Hardware error bit: motor encoder fault.
pub const HW_ERROR_ENCODER: u8 = 1 << 3;
/// Hardware error bit: electrical shock.
pub const HW_ERROR_ELECTRICAL_SHOCK: u8 = 1 << 4;
/// Hardware error bit: overload (persistent load above the maximum).
pub const HW_ERROR_OVERLOAD: u8 = 1 << 5;

/// One unit of velocity in revolutions per minute.
pub const VELOCITY_UNIT_RPM: f64 = 0.229;
/// One unit of acceleration in revolutions per minute squared.
pub const ACCELERATION_UNIT_RPM2: f64 = 214.577;
/// Largest profile velocity or acceleration value accepted.
pub const PROFILE_MAX: u32 = 32_767;
/// Ticks per revolution of the X-series encoder (the robot file's default
/// `ticks_per_rev`).
pub const TICKS_PER_REV: u32 = ctr_formats::DEFAULT_TICKS_PER_REV;
/// Largest goal magnitude in extended position mode (ticks).
pub const EXTENDED_POSITION_LIMIT: i32 = 1_048_575;
/// Model number of the XM430-W350.
pub const MODEL_XM430_W350: u16 = 1020;

/// Names the hardware error bits set in `status` (for messages).
///
/// ```
/// use ctr_hw::control_table as ct;
/// assert_eq!(ct::hardware_error_names(ct::HW_ERROR_OVERLOAD), ["overload"]);
/// assert!(ct::hardware_error_names(0).is_empty());
/// ```
pub fn hardware_error_names(status: u8) -> Vec<&'static str> {
    [
        (HW_ERROR_INPUT_VOLTAGE, "input voltage"),
        (HW_ERROR_OVERHEATING, "overheating"),
        (HW_ERROR_ENCODER, "motor encoder"),
        (HW_ERROR_ELECTRICAL_SHOCK, "electrical shock"),
        (HW_ERROR_OVERLOAD, "overload"),
    ]
    .into_iter()
    .filter(|(bit, _)| status & bit != 0)
    .map(|(_, name)| name)
    .collect()
}

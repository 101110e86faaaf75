//! The emulated servo: an X-series control table (see [`crate::control_table`]) and the
//! motion it commands.
//!
//! With torque on, a motor moves toward its goal with a trapezoidal profile limited by
//! the profile velocity (the velocity limit when 0) and the profile acceleration
//! (unlimited when 0). Read-only entries and EEPROM writes with torque on give an access
//! error, out-of-range values a data range or data limit error.

use std::ops::RangeInclusive;

use super::EmulatorConfig;
use crate::control_table as ct;
use crate::protocol::ErrorCode;

/// Size of the emulated control table (addresses 0..256).
const TABLE_SIZE: usize = 256;
/// Read-only addresses: model information and firmware, hardware error status, and the
/// present-value block.
const READ_ONLY: [RangeInclusive<usize>; 3] = [0..=6, 70..=70, 120..=147];
/// Baud rate (1 byte, EEPROM), as a code.
const BAUD_RATE: usize = 8;
/// The baud rate code of 57 600 baud.
const BAUD_RATE_57600: u8 = 1;
/// Return delay time (1 byte, EEPROM), in units of 2 µs.
const RETURN_DELAY_TIME: usize = 9;
/// The factory return delay: 250 units = 500 µs.
const DEFAULT_RETURN_DELAY: u8 = 250;
/// The operating mode "extended position" (multi-turn).
const EXTENDED_POSITION_MODE: u8 = 4;
/// Velocity limit (4 bytes, EEPROM), in [`ct::VELOCITY_UNIT_RPM`].
const VELOCITY_LIMIT: usize = 44;
/// The XM430-W350's velocity limit: 265 units = 60.7 rev/min.
const DEFAULT_VELOCITY_LIMIT: u32 = 265;
/// The factory maximum position limit, ticks (one revolution; unused in extended mode).
const DEFAULT_MAX_POSITION: i32 = 4095;
/// Present input voltage (2 bytes), in units of 0.1 V.
const PRESENT_INPUT_VOLTAGE: usize = 144;
/// The emulated supply: 12.0 V.
const INPUT_VOLTAGE_DECIVOLTS: u16 = 120;
/// Present temperature (1 byte), °C.
const PRESENT_TEMPERATURE: usize = 146;
/// The emulated temperature, °C.
const TEMPERATURE_CELSIUS: u8 = 30;
/// Seconds per minute: velocities are in rev/min, accelerations in rev/min².
const SECONDS_PER_MINUTE: f64 = 60.0;
/// Closer to the goal than this (ticks), a motor has arrived.
const ARRIVAL_TICKS: f64 = 0.01;

/// One emulated servo: its control table and its motion.
#[derive(Debug, Clone)]
pub(super) struct Motor {
    /// The motor's device ID.
    pub(super) id: u8,
    table: Vec<u8>,
    /// Position in ticks, not rounded.
    position: f64,
    /// Velocity in ticks per second.
    velocity: f64,
    /// Goal positions applied so far.
    pub(super) goals: usize,
}

impl Motor {
    /// A motor fresh from the factory (but in extended position mode), at rest at
    /// position 0 with torque off.
    pub(super) fn new(id: u8, config: &EmulatorConfig) -> Self {
        let mut table = vec![0u8; TABLE_SIZE];
        let model = usize::from(ct::MODEL_NUMBER);
        table[model..model + 2].copy_from_slice(&config.model_number.to_le_bytes());
        table[usize::from(ct::FIRMWARE_VERSION)] = config.firmware_version;
        table[usize::from(ct::ID)] = id;
        table[BAUD_RATE] = BAUD_RATE_57600;
        table[RETURN_DELAY_TIME] = DEFAULT_RETURN_DELAY;
        table[usize::from(ct::OPERATING_MODE)] = EXTENDED_POSITION_MODE;
        table[VELOCITY_LIMIT..VELOCITY_LIMIT + 4]
            .copy_from_slice(&DEFAULT_VELOCITY_LIMIT.to_le_bytes());
        let max = usize::from(ct::MAX_POSITION_LIMIT);
        table[max..max + 4].copy_from_slice(&DEFAULT_MAX_POSITION.to_le_bytes());
        table[PRESENT_INPUT_VOLTAGE..PRESENT_INPUT_VOLTAGE + 2]
            .copy_from_slice(&INPUT_VOLTAGE_DECIVOLTS.to_le_bytes());
        table[PRESENT_TEMPERATURE] = TEMPERATURE_CELSIUS;
        let mut motor = Self {
            id,
            table,
            position: 0.0,
            velocity: 0.0,
            goals: 0,
        };
        motor.publish();
        motor
    }

    /// The byte at `address`.
    pub(super) fn u8_at(&self, address: u16) -> u8 {
        self.table[usize::from(address)]
    }

    fn u32_at(&self, address: usize) -> u32 {
        let b = &self.table[address..address + 4];
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }

    /// The signed 32-bit value at `address`.
    pub(super) fn i32_at(&self, address: u16) -> i32 {
        self.u32_at(usize::from(address)) as i32
    }

    fn set_i32(&mut self, address: u16, value: i32) {
        let a = usize::from(address);
        self.table[a..a + 4].copy_from_slice(&value.to_le_bytes());
    }

    /// Whether torque is on.
    pub(super) fn torque_on(&self) -> bool {
        self.u8_at(ct::TORQUE_ENABLE) == 1
    }

    /// The hardware error status register.
    pub(super) fn hardware_error(&self) -> u8 {
        self.u8_at(ct::HARDWARE_ERROR_STATUS)
    }

    /// Whether the motor still moves or has somewhere to go.
    pub(super) fn active(&self) -> bool {
        self.torque_on()
            && self.hardware_error() == 0
            && (self.velocity != 0.0 || self.position != f64::from(self.i32_at(ct::GOAL_POSITION)))
    }

    /// Ticks per second of a velocity in the control table's units.
    fn ticks_per_second(units: f64) -> f64 {
        units * ct::VELOCITY_UNIT_RPM / SECONDS_PER_MINUTE * f64::from(ct::TICKS_PER_REV)
    }

    /// One integration step of `dt` simulated seconds.
    pub(super) fn step(&mut self, dt: f64) {
        if !self.torque_on() || self.hardware_error() != 0 {
            self.velocity = 0.0;
            return;
        }
        let goal = f64::from(self.i32_at(ct::GOAL_POSITION));
        let error = goal - self.position;
        if error == 0.0 && self.velocity == 0.0 {
            return;
        }
        let limit = f64::from(self.u32_at(VELOCITY_LIMIT));
        let profile = f64::from(self.u32_at(usize::from(ct::PROFILE_VELOCITY)));
        let vmax = Self::ticks_per_second(if profile == 0.0 {
            limit
        } else {
            profile.min(limit)
        });
        let accel_units = f64::from(self.u32_at(usize::from(ct::PROFILE_ACCELERATION)));
        let amax = if accel_units == 0.0 {
            f64::INFINITY
        } else {
            accel_units * ct::ACCELERATION_UNIT_RPM2 / (SECONDS_PER_MINUTE * SECONDS_PER_MINUTE)
                * f64::from(ct::TICKS_PER_REV)
        };
        // Fastest speed from which the motor can still stop at the goal.
        let stoppable = (2.0 * amax * error.abs()).sqrt();
        let desired = error.signum() * vmax.min(stoppable);
        let max_change = amax * dt;
        self.velocity += (desired - self.velocity).clamp(-max_change, max_change);
        let next = self.position + self.velocity * dt;
        let remaining = goal - next;
        if remaining.abs() < ARRIVAL_TICKS || remaining.signum() != error.signum() {
            self.position = goal;
            self.velocity = 0.0;
        } else {
            self.position = next;
        }
    }

    /// Copies the motion state into the present-value registers.
    pub(super) fn publish(&mut self) {
        let present = self.position.round() as i32;
        self.set_i32(ct::PRESENT_POSITION, present);
        let units = self.velocity / Self::ticks_per_second(1.0);
        self.set_i32(ct::PRESENT_VELOCITY, units.round() as i32);
        let moving = self.velocity != 0.0
            || (self.torque_on()
                && self.hardware_error() == 0
                && present != self.i32_at(ct::GOAL_POSITION));
        self.table[usize::from(ct::MOVING)] = u8::from(moving);
    }

    /// `length` bytes of the control table at `address`, as a read instruction gets them.
    pub(super) fn read(&self, address: u16, length: u16) -> Result<Vec<u8>, ErrorCode> {
        let start = usize::from(address);
        let end = start + usize::from(length);
        if length == 0 || end > TABLE_SIZE {
            return Err(ErrorCode::Access);
        }
        Ok(self.table[start..end].to_vec())
    }

    /// The error a write of `data` at `address` gets, if any: read-only or EEPROM
    /// addresses with torque on, values out of range.
    pub(super) fn check_write(&self, address: u16, data: &[u8]) -> Result<(), ErrorCode> {
        let start = usize::from(address);
        let end = start + data.len();
        if data.is_empty() {
            return Err(ErrorCode::DataLength);
        }
        if end > TABLE_SIZE {
            return Err(ErrorCode::Access);
        }
        if READ_ONLY
            .iter()
            .any(|r| start <= *r.end() && *r.start() < end)
        {
            return Err(ErrorCode::Access);
        }
        if start < usize::from(ct::RAM_START) && self.torque_on() {
            return Err(ErrorCode::Access);
        }
        let covers = |a: u16, n: usize| start <= usize::from(a) && usize::from(a) + n <= end;
        let value_at = |a: u16, n: usize| {
            let offset = usize::from(a) - start;
            &data[offset..offset + n]
        };
        if covers(ct::TORQUE_ENABLE, 1) {
            match value_at(ct::TORQUE_ENABLE, 1)[0] {
                0 => {}
                1 if self.hardware_error() != 0 => return Err(ErrorCode::ResultFail),
                1 => {}
                _ => return Err(ErrorCode::DataRange),
            }
        }
        if covers(ct::GOAL_POSITION, 4) {
            let b = value_at(ct::GOAL_POSITION, 4);
            let goal = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            if goal.abs() > ct::EXTENDED_POSITION_LIMIT {
                return Err(ErrorCode::DataLimit);
            }
        }
        for register in [ct::PROFILE_VELOCITY, ct::PROFILE_ACCELERATION] {
            if covers(register, 4) {
                let b = value_at(register, 4);
                if u32::from_le_bytes([b[0], b[1], b[2], b[3]]) > ct::PROFILE_MAX {
                    return Err(ErrorCode::DataRange);
                }
            }
        }
        Ok(())
    }

    /// Applies a checked write.
    pub(super) fn apply_write(&mut self, address: u16, data: &[u8]) {
        let start = usize::from(address);
        self.table[start..start + data.len()].copy_from_slice(data);
        if !self.torque_on() {
            self.velocity = 0.0;
        }
        self.publish();
    }

    /// Overloads: hardware error bit 5, torque off, stop.
    pub(super) fn overload(&mut self) {
        self.table[usize::from(ct::HARDWARE_ERROR_STATUS)] |= ct::HW_ERROR_OVERLOAD;
        self.table[usize::from(ct::TORQUE_ENABLE)] = 0;
        self.velocity = 0.0;
        self.publish();
    }

    /// Reboots: the hardware error is cleared, torque stays off.
    pub(super) fn reboot(&mut self) {
        self.table[usize::from(ct::HARDWARE_ERROR_STATUS)] = 0;
        self.table[usize::from(ct::TORQUE_ENABLE)] = 0;
        self.velocity = 0.0;
        self.publish();
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use crate::bus::BusError;
    use crate::control_table as ct;
    use crate::emulator::testing::frozen_bus;
    use crate::protocol::ErrorCode;

    #[test]
    fn enforces_access_rules() {
        let (emu, mut bus) = frozen_bus();
        let code = |result: Result<(), BusError>| match result {
            Err(BusError::Device { error, .. }) => error.code(),
            other => panic!("unexpected {other:?}"),
        };
        assert_eq!(
            code(bus.write(1, ct::PRESENT_POSITION, &[0, 0, 0, 0])),
            Some(ErrorCode::Access)
        );
        assert_eq!(
            code(bus.write(1, ct::TORQUE_ENABLE, &[2])),
            Some(ErrorCode::DataRange)
        );
        let far = (ct::EXTENDED_POSITION_LIMIT + 1).to_le_bytes();
        assert_eq!(
            code(bus.write(1, ct::GOAL_POSITION, &far)),
            Some(ErrorCode::DataLimit)
        );
        bus.write(1, ct::TORQUE_ENABLE, &[1]).unwrap();
        assert_eq!(
            code(bus.write(1, ct::OPERATING_MODE, &[3])),
            Some(ErrorCode::Access)
        );
        assert!(matches!(bus.read(1, 250, 10), Err(BusError::Device { .. })));
        // Rejected writes are not applied.
        assert_eq!(emu.applied_writes(1), 1);
    }

    #[test]
    fn moves_with_velocity_and_acceleration_limits() {
        let (emu, mut bus) = frozen_bus();
        // 100 units = 22.9 rpm = 1563.3 ticks/s; 20 units = 71.5 rpm/s... per second.
        bus.write(1, ct::PROFILE_VELOCITY, &100u32.to_le_bytes())
            .unwrap();
        bus.write(1, ct::PROFILE_ACCELERATION, &20u32.to_le_bytes())
            .unwrap();
        bus.write(1, ct::TORQUE_ENABLE, &[1]).unwrap();
        bus.write(1, ct::GOAL_POSITION, &4096i32.to_le_bytes())
            .unwrap();
        let vmax = 100.0 * 0.229 / 60.0 * 4096.0;
        let amax = 20.0 * 214.577 / 3600.0 * 4096.0;
        // Accelerating: x = a t² / 2 until v reaches vmax at t = vmax / a ≈ 0.32 s.
        emu.advance(Duration::from_millis(200));
        let expected = 0.5 * amax * 0.2f64.powi(2);
        let x = f64::from(emu.present_position(1).unwrap());
        assert!(
            (x - expected).abs() < 0.02 * expected + 2.0,
            "{x} vs {expected}"
        );
        assert_eq!(bus.read(1, ct::MOVING, 1).unwrap(), [1]);
        // Cruising at vmax.
        let before = f64::from(emu.present_position(1).unwrap());
        emu.advance(Duration::from_millis(500));
        let after = f64::from(emu.present_position(1).unwrap());
        let speed = (after - before) / 0.5;
        assert!(speed <= vmax * 1.001 + 2.0, "{speed} > {vmax}");
        assert!(speed > 0.8 * vmax);
        // Arrives and stops exactly on the goal.
        emu.advance(Duration::from_secs(5));
        assert_eq!(emu.present_position(1), Some(4096));
        assert_eq!(bus.read(1, ct::MOVING, 1).unwrap(), [0]);
        assert_eq!(bus.read(1, ct::PRESENT_VELOCITY, 4).unwrap(), [0, 0, 0, 0]);
        // Other motors never moved (torque off).
        assert_eq!(emu.present_position(2), Some(0));
    }

    #[test]
    fn torque_off_stops_motion() {
        let (emu, mut bus) = frozen_bus();
        bus.write(1, ct::TORQUE_ENABLE, &[1]).unwrap();
        bus.write(1, ct::GOAL_POSITION, &100_000i32.to_le_bytes())
            .unwrap();
        emu.advance(Duration::from_millis(100));
        bus.write(1, ct::TORQUE_ENABLE, &[0]).unwrap();
        let stopped = emu.present_position(1).unwrap();
        emu.advance(Duration::from_secs(1));
        assert_eq!(emu.present_position(1), Some(stopped));
        assert!(stopped > 0);
    }
}

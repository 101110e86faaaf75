//! An in-process emulator of a Dynamixel X-series bus (four motors by default), for tests
//! without hardware and for `ctr-cli hw emulate`.
//!
//! # What it emulates
//!
//! * Instructions: ping (unicast and broadcast), read, write, sync read, sync write,
//!   reboot; other instructions get an instruction-error status.
//! * A control-table subset (see [`crate::control_table`]): model number, firmware, ID,
//!   operating mode (extended position), velocity limit, torque enable (64), hardware
//!   error status (70), profile acceleration (108) and velocity (112), goal position
//!   (116), moving (122), present velocity (128) and present position (132). Read-only
//!   entries and EEPROM writes with torque on give an access error, out-of-range values
//!   a data range or data limit error.
//! * Motion in simulated time: with torque on, each motor moves toward its goal with a
//!   trapezoidal profile limited by profile velocity (or the velocity limit when 0) and
//!   profile acceleration (unlimited when 0). Simulated time advances with the wall
//!   clock times [`EmulatorConfig::time_scale`], plus whatever [`Emulator::advance`]
//!   adds.
//! * Fault injection ([`Emulator::inject`]): a lost instruction, dropped reply bytes, a
//!   corrupt reply CRC, a missing reply, and an overload (hardware error bit 5, torque
//!   off, alert bit in every status until reboot); [`Emulator::inject_after_goals`]
//!   arms one when a motor has applied a given number of goal positions, so that a
//!   fault strikes at a reproducible point of a run.
//! * Bookkeeping for tests: every applied write is logged ([`Emulator::write_log`]).
//!
//! # Serving
//!
//! [`Emulator::serve_pty`] opens a pseudo-terminal pair, serves the master side from a
//! thread and reports the slave path, which any serial program can open:
//!
//! ```
//! use ctr_hw::emulator::{Emulator, EmulatorConfig};
//! use ctr_hw::bus::{Bus, BusConfig};
//! use ctr_hw::transport::SerialTransport;
//!
//! let pty = Emulator::new(EmulatorConfig::default()).serve_pty()?;
//! println!("emulated bus on {}", pty.path()); // what `ctr-cli hw emulate` prints
//! let mut bus = Bus::new(SerialTransport::open(pty.path(), 57_600)?, BusConfig::default());
//! for id in 1..=4 {
//!     bus.ping(id)?;
//! }
//! pty.stop()?; // or pty.wait() to serve until the process ends
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! [`Emulator::link`] gives an in-process [`Transport`] instead, with no thread and no
//! pseudo-terminal.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::control_table as ct;
use crate::protocol::{
    instruction, Decoder, ErrorCode, Frame, Packet, StatusError, StatusPacket, BROADCAST_ID,
};
use crate::transport::{SerialTransport, Transport, TransportError};

/// Size of the emulated control table (addresses 0..256).
const TABLE_SIZE: usize = 256;
/// Read-only addresses: model information and firmware, hardware error status, and the
/// present-value block.
const READ_ONLY: [std::ops::RangeInclusive<usize>; 3] = [0..=6, 70..=70, 120..=147];
const VELOCITY_LIMIT: usize = 44;
const RETURN_DELAY_TIME: usize = 9;
const PRESENT_INPUT_VOLTAGE: usize = 144;
const PRESENT_TEMPERATURE: usize = 146;

/// Settings of an [`Emulator`].
///
/// ```
/// use ctr_hw::emulator::EmulatorConfig;
/// let fast = EmulatorConfig { time_scale: 20.0, ..EmulatorConfig::default() };
/// assert_eq!(fast.ids, [1, 2, 3, 4]);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct EmulatorConfig {
    /// The motor IDs on the bus.
    pub ids: Vec<u8>,
    /// Simulated seconds per wall-clock second (0 freezes the clock: only
    /// [`Emulator::advance`] moves time).
    pub time_scale: f64,
    /// Integration step of the motion, in simulated time.
    pub step: Duration,
    /// The model number reported by ping and at address 0.
    pub model_number: u16,
    /// The firmware version reported by ping.
    pub firmware_version: u8,
}

impl Default for EmulatorConfig {
    fn default() -> Self {
        Self {
            ids: vec![1, 2, 3, 4],
            time_scale: 1.0,
            step: Duration::from_millis(1),
            model_number: ct::MODEL_XM430_W350,
            firmware_version: 45,
        }
    }
}

/// A fault to inject, once, with [`Emulator::inject`].
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault};
/// let emu = Emulator::new(EmulatorConfig::default());
/// emu.inject(Some(2), Fault::NoReply);
/// assert_eq!(emu.pending_faults(), 1);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// The next instruction packet concerning the motor is lost on the wire: not
    /// applied, not answered.
    DropInstruction,
    /// The motor's next status packet loses this many bytes after its header (the
    /// instruction itself was applied).
    DropReplyBytes(usize),
    /// The motor's next status packet has a corrupt CRC (the instruction was applied).
    CorruptReplyCrc,
    /// The motor applies its next instruction but its status packet is lost.
    NoReply,
    /// The motor overloads now: hardware error status bit 5 (overload) is set, torque
    /// goes off, and every status carries the alert bit until a reboot.
    Overload,
}

impl Fault {
    fn affects_replies(self) -> bool {
        matches!(
            self,
            Self::DropReplyBytes(_) | Self::CorruptReplyCrc | Self::NoReply
        )
    }
}

/// One write applied to a motor's control table.
///
/// ```
/// use ctr_hw::emulator::AppliedWrite;
/// let w = AppliedWrite { id: 1, address: 116, data: vec![0, 4, 0, 0], instruction: 0x03 };
/// assert_eq!(w.address, 116);
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AppliedWrite {
    /// The motor.
    pub id: u8,
    /// The first address written.
    pub address: u16,
    /// The bytes written.
    pub data: Vec<u8>,
    /// The instruction that carried it (WRITE or SYNC_WRITE).
    pub instruction: u8,
}

/// Counters of an [`Emulator`].
///
/// ```
/// let s = ctr_hw::emulator::EmulatorStats::default();
/// assert_eq!(s.instructions_received, 0);
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EmulatorStats {
    /// Valid instruction packets received for motors on this bus (dropped ones included).
    pub instructions_received: u64,
    /// Instruction packets discarded by [`Fault::DropInstruction`].
    pub instructions_dropped: u64,
    /// Frames received with a bad CRC or length.
    pub corrupt_received: u64,
    /// Status packets sent (faulty ones included, suppressed ones not).
    pub statuses_sent: u64,
    /// Injected faults that took effect.
    pub faults_applied: u64,
}

#[derive(Debug, Clone)]
struct Motor {
    id: u8,
    table: Vec<u8>,
    position: f64,
    velocity: f64,
    /// Goal positions applied so far.
    goals: usize,
}

impl Motor {
    fn new(id: u8, config: &EmulatorConfig) -> Self {
        let mut table = vec![0u8; TABLE_SIZE];
        table[0..2].copy_from_slice(&config.model_number.to_le_bytes());
        table[usize::from(ct::FIRMWARE_VERSION)] = config.firmware_version;
        table[usize::from(ct::ID)] = id;
        table[8] = 1; // baud rate code: 57600
        table[RETURN_DELAY_TIME] = 250;
        table[usize::from(ct::OPERATING_MODE)] = 4; // extended position
        table[VELOCITY_LIMIT..VELOCITY_LIMIT + 4].copy_from_slice(&265u32.to_le_bytes());
        let max = usize::from(ct::MAX_POSITION_LIMIT);
        table[max..max + 4].copy_from_slice(&4095i32.to_le_bytes());
        table[PRESENT_INPUT_VOLTAGE..PRESENT_INPUT_VOLTAGE + 2]
            .copy_from_slice(&120u16.to_le_bytes());
        table[PRESENT_TEMPERATURE] = 30;
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

    fn u8_at(&self, address: u16) -> u8 {
        self.table[usize::from(address)]
    }

    fn u32_at(&self, address: usize) -> u32 {
        let b = &self.table[address..address + 4];
        u32::from_le_bytes([b[0], b[1], b[2], b[3]])
    }

    fn i32_at(&self, address: u16) -> i32 {
        self.u32_at(usize::from(address)) as i32
    }

    fn set_i32(&mut self, address: u16, value: i32) {
        let a = usize::from(address);
        self.table[a..a + 4].copy_from_slice(&value.to_le_bytes());
    }

    fn torque_on(&self) -> bool {
        self.u8_at(ct::TORQUE_ENABLE) == 1
    }

    fn hardware_error(&self) -> u8 {
        self.u8_at(ct::HARDWARE_ERROR_STATUS)
    }

    fn active(&self) -> bool {
        self.torque_on()
            && self.hardware_error() == 0
            && (self.velocity != 0.0 || self.position != f64::from(self.i32_at(ct::GOAL_POSITION)))
    }

    fn ticks_per_second(units: f64) -> f64 {
        units * ct::VELOCITY_UNIT_RPM / 60.0 * f64::from(ct::TICKS_PER_REV)
    }

    /// One integration step of `dt` simulated seconds.
    fn step(&mut self, dt: f64) {
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
            accel_units * ct::ACCELERATION_UNIT_RPM2 / 3600.0 * f64::from(ct::TICKS_PER_REV)
        };
        // Fastest speed from which the motor can still stop at the goal.
        let stoppable = (2.0 * amax * error.abs()).sqrt();
        let desired = error.signum() * vmax.min(stoppable);
        let max_change = amax * dt;
        self.velocity += (desired - self.velocity).clamp(-max_change, max_change);
        let next = self.position + self.velocity * dt;
        let remaining = goal - next;
        if remaining.abs() < 0.01 || remaining.signum() != error.signum() {
            self.position = goal;
            self.velocity = 0.0;
        } else {
            self.position = next;
        }
    }

    /// Copies the motion state into the present-value registers.
    fn publish(&mut self) {
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

    fn read(&self, address: u16, length: u16) -> Result<Vec<u8>, ErrorCode> {
        let start = usize::from(address);
        let end = start + usize::from(length);
        if length == 0 || end > TABLE_SIZE {
            return Err(ErrorCode::Access);
        }
        Ok(self.table[start..end].to_vec())
    }

    fn check_write(&self, address: u16, data: &[u8]) -> Result<(), ErrorCode> {
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

    fn apply_write(&mut self, address: u16, data: &[u8]) {
        let start = usize::from(address);
        self.table[start..start + data.len()].copy_from_slice(data);
        if !self.torque_on() {
            self.velocity = 0.0;
        }
        self.publish();
    }

    fn overload(&mut self) {
        self.table[usize::from(ct::HARDWARE_ERROR_STATUS)] |= ct::HW_ERROR_OVERLOAD;
        self.table[usize::from(ct::TORQUE_ENABLE)] = 0;
        self.velocity = 0.0;
        self.publish();
    }

    fn reboot(&mut self) {
        self.table[usize::from(ct::HARDWARE_ERROR_STATUS)] = 0;
        self.table[usize::from(ct::TORQUE_ENABLE)] = 0;
        self.velocity = 0.0;
        self.publish();
    }
}

#[derive(Debug)]
struct Model {
    config: EmulatorConfig,
    motors: Vec<Motor>,
    faults: Vec<(Option<u8>, Fault)>,
    /// Faults waiting for a motor's goal count: `(motor, fault, goals)`.
    scheduled: Vec<(Option<u8>, Fault, usize)>,
    log: Vec<AppliedWrite>,
    stats: EmulatorStats,
    last_wall: Instant,
    sim_time: f64,
}

impl Model {
    fn motor(&self, id: u8) -> Option<&Motor> {
        self.motors.iter().find(|m| m.id == id)
    }

    fn motor_mut(&mut self, id: u8) -> Option<&mut Motor> {
        self.motors.iter_mut().find(|m| m.id == id)
    }

    fn has(&self, id: u8) -> bool {
        self.motor(id).is_some()
    }

    /// Advances simulated time by the scaled wall-clock time since the last call.
    fn sync_clock(&mut self) {
        let now = Instant::now();
        let elapsed = now.duration_since(self.last_wall).as_secs_f64();
        self.last_wall = now;
        self.simulate(elapsed * self.config.time_scale);
    }

    fn simulate(&mut self, seconds: f64) {
        if seconds.is_nan() || seconds <= 0.0 {
            return;
        }
        let step = self.config.step.as_secs_f64().max(1e-6);
        let mut left = seconds;
        while left > 0.0 && self.motors.iter().any(Motor::active) {
            let dt = step.min(left);
            for motor in &mut self.motors {
                motor.step(dt);
            }
            left -= dt;
        }
        for motor in &mut self.motors {
            motor.publish();
        }
        self.sim_time += seconds;
    }

    fn take_fault(&mut self, matches: impl Fn(Option<u8>, Fault) -> bool) -> Option<Fault> {
        let index = self.faults.iter().position(|&(id, f)| matches(id, f))?;
        self.stats.faults_applied += 1;
        Some(self.faults.remove(index).1)
    }

    /// Handles one received frame and returns the bytes to send back.
    fn handle_frame(&mut self, frame: Frame) -> Vec<u8> {
        self.sync_clock();
        match frame.result {
            Ok(packet) => self.handle_packet(packet),
            Err(_) => {
                self.stats.corrupt_received += 1;
                // The ID byte of a damaged frame may itself be damaged; answer only when
                // it names one of our motors.
                let id = frame.raw.get(4).copied().unwrap_or(BROADCAST_ID);
                if self.has(id) {
                    self.reply(vec![(id, Err(ErrorCode::CrcError))])
                } else {
                    Vec::new()
                }
            }
        }
    }

    fn targets(&self, packet: &Packet) -> Vec<u8> {
        if packet.id != BROADCAST_ID {
            return if self.has(packet.id) {
                vec![packet.id]
            } else {
                Vec::new()
            };
        }
        match packet.instruction {
            instruction::PING => self.motors.iter().map(|m| m.id).collect(),
            instruction::SYNC_READ => packet
                .params
                .get(4..)
                .unwrap_or(&[])
                .iter()
                .copied()
                .filter(|&id| self.has(id))
                .collect(),
            instruction::SYNC_WRITE => sync_write_entries(&packet.params)
                .map(|(_, entries)| {
                    entries
                        .into_iter()
                        .map(|(id, _)| id)
                        .filter(|&id| self.has(id))
                        .collect()
                })
                .unwrap_or_default(),
            _ => Vec::new(),
        }
    }

    fn handle_packet(&mut self, packet: Packet) -> Vec<u8> {
        if packet.instruction == instruction::STATUS {
            return Vec::new();
        }
        let targets = self.targets(&packet);
        if targets.is_empty() {
            return Vec::new();
        }
        self.stats.instructions_received += 1;
        let dropped = self.take_fault(|id, fault| {
            fault == Fault::DropInstruction && id.is_none_or(|id| targets.contains(&id))
        });
        if dropped.is_some() {
            self.stats.instructions_dropped += 1;
            return Vec::new();
        }
        let params = &packet.params;
        let answers: Vec<(u8, Result<Vec<u8>, ErrorCode>)> = match packet.instruction {
            instruction::PING => targets
                .iter()
                .map(|&id| {
                    let mut data = self.config.model_number.to_le_bytes().to_vec();
                    data.push(self.config.firmware_version);
                    (id, Ok(data))
                })
                .collect(),
            instruction::READ => {
                let id = targets[0];
                let result = match address_and_length(params) {
                    Some((address, length)) if params.len() == 4 => self
                        .motor(id)
                        .map_or(Err(ErrorCode::Access), |m| m.read(address, length)),
                    _ => Err(ErrorCode::DataLength),
                };
                vec![(id, result)]
            }
            instruction::WRITE => {
                let id = targets[0];
                let result = if params.len() < 3 {
                    Err(ErrorCode::DataLength)
                } else {
                    let address = u16::from_le_bytes([params[0], params[1]]);
                    self.write(id, address, &params[2..], instruction::WRITE)
                        .map(|()| Vec::new())
                };
                vec![(id, result)]
            }
            instruction::SYNC_READ => match address_and_length(params) {
                Some((address, length)) => targets
                    .iter()
                    .map(|&id| {
                        let result = self
                            .motor(id)
                            .map_or(Err(ErrorCode::Access), |m| m.read(address, length));
                        (id, result)
                    })
                    .collect(),
                None => Vec::new(),
            },
            instruction::SYNC_WRITE => {
                if let Some((address, entries)) = sync_write_entries(params) {
                    for (id, data) in entries {
                        if self.has(id) {
                            // A broadcast gets no status: errors are silent, as on hardware.
                            let _ = self.write(id, address, &data, instruction::SYNC_WRITE);
                        }
                    }
                }
                Vec::new()
            }
            instruction::REBOOT => {
                let id = targets[0];
                if let Some(motor) = self.motor_mut(id) {
                    motor.reboot();
                }
                vec![(id, Ok(Vec::new()))]
            }
            _ if packet.id != BROADCAST_ID => vec![(targets[0], Err(ErrorCode::InstructionError))],
            _ => Vec::new(),
        };
        self.reply(answers)
    }

    fn write(&mut self, id: u8, address: u16, data: &[u8], via: u8) -> Result<(), ErrorCode> {
        let motor = self.motor_mut(id).ok_or(ErrorCode::Access)?;
        motor.check_write(address, data)?;
        motor.apply_write(address, data);
        let goal = usize::from(ct::GOAL_POSITION);
        let sets_goal =
            usize::from(address) <= goal && goal + 4 <= usize::from(address) + data.len();
        if sets_goal {
            motor.goals += 1;
        }
        self.log.push(AppliedWrite {
            id,
            address,
            data: data.to_vec(),
            instruction: via,
        });
        if sets_goal {
            self.arm_scheduled();
        }
        Ok(())
    }

    /// Injects a fault now: an overload at once on the motors it names, a wire fault
    /// into the queue.
    fn arm(&mut self, motor: Option<u8>, fault: Fault) {
        if fault == Fault::Overload {
            for m in &mut self.motors {
                if motor.is_none_or(|id| id == m.id) {
                    m.overload();
                }
            }
        } else {
            self.faults.push((motor, fault));
        }
    }

    /// Arms the scheduled faults whose motor has applied enough goal positions.
    fn arm_scheduled(&mut self) {
        let mut i = 0;
        while i < self.scheduled.len() {
            let (motor, fault, goals) = self.scheduled[i];
            let reached = self
                .motors
                .iter()
                .find(|m| motor.is_none_or(|id| id == m.id) && m.goals >= goals)
                .map(|m| m.id);
            match reached {
                Some(id) => {
                    self.scheduled.remove(i);
                    // An overload strikes the motor that reached the count; a wire fault
                    // for any motor stays for any motor.
                    let target = if fault == Fault::Overload {
                        Some(id)
                    } else {
                        motor
                    };
                    self.arm(target, fault);
                }
                None => i += 1,
            }
        }
    }

    /// Encodes the status packets, applying reply faults.
    fn reply(&mut self, answers: Vec<(u8, Result<Vec<u8>, ErrorCode>)>) -> Vec<u8> {
        let mut out = Vec::new();
        for (id, result) in answers {
            let alert = self.motor(id).is_some_and(|m| m.hardware_error() != 0);
            let (code, params) = match result {
                Ok(params) => (None, params),
                Err(code) => (Some(code), Vec::new()),
            };
            let status = StatusPacket::new(id, StatusError::from_parts(code, alert), params);
            let Ok(mut bytes) = status.encode() else {
                continue;
            };
            let fault = self.take_fault(|target, fault| {
                fault.affects_replies() && target.is_none_or(|t| t == id)
            });
            match fault {
                Some(Fault::NoReply) => continue,
                Some(Fault::CorruptReplyCrc) => {
                    if let Some(last) = bytes.last_mut() {
                        *last ^= 0x5A;
                    }
                }
                Some(Fault::DropReplyBytes(n)) => {
                    let n = n.min(bytes.len() - 7);
                    bytes.drain(7..7 + n);
                }
                _ => {}
            }
            self.stats.statuses_sent += 1;
            out.extend_from_slice(&bytes);
        }
        out
    }
}

fn address_and_length(params: &[u8]) -> Option<(u16, u16)> {
    if params.len() < 4 {
        return None;
    }
    Some((
        u16::from_le_bytes([params[0], params[1]]),
        u16::from_le_bytes([params[2], params[3]]),
    ))
}

type SyncWriteEntries = (u16, Vec<(u8, Vec<u8>)>);

fn sync_write_entries(params: &[u8]) -> Option<SyncWriteEntries> {
    let (address, length) = address_and_length(params)?;
    let length = usize::from(length);
    let body = &params[4..];
    if length == 0 || !body.len().is_multiple_of(1 + length) {
        return None;
    }
    let entries = body
        .chunks(1 + length)
        .map(|chunk| (chunk[0], chunk[1..].to_vec()))
        .collect();
    Some((address, entries))
}

/// An emulated bus. Cloning gives another handle to the same motors.
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// use ctr_hw::bus::{Bus, BusConfig};
/// use std::time::Duration;
///
/// let emu = Emulator::new(EmulatorConfig { time_scale: 0.0, ..EmulatorConfig::default() });
/// let mut bus = Bus::new(emu.link(), BusConfig::default());
/// bus.write(1, 64, &[1])?; // torque on
/// bus.write(1, 116, &2048i32.to_le_bytes())?;
/// emu.advance(Duration::from_secs(2));
/// assert_eq!(emu.present_position(1), Some(2048));
/// assert_eq!(emu.applied_writes(1), 2);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct Emulator {
    model: Arc<Mutex<Model>>,
}

impl Emulator {
    /// A bus with one motor per configured ID, all at position 0 with torque off.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig { ids: vec![5], ..EmulatorConfig::default() });
    /// assert_eq!(emu.ids(), [5]);
    /// ```
    pub fn new(config: EmulatorConfig) -> Self {
        let mut ids = config.ids.clone();
        ids.sort_unstable();
        ids.dedup();
        let motors = ids.iter().map(|&id| Motor::new(id, &config)).collect();
        Self {
            model: Arc::new(Mutex::new(Model {
                config,
                motors,
                faults: Vec::new(),
                scheduled: Vec::new(),
                log: Vec::new(),
                stats: EmulatorStats::default(),
                last_wall: Instant::now(),
                sim_time: 0.0,
            })),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Model> {
        self.model
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// The motor IDs, ascending.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).ids(), [1, 2, 3, 4]);
    /// ```
    pub fn ids(&self) -> Vec<u8> {
        self.lock().motors.iter().map(|m| m.id).collect()
    }

    /// Queues a fault for `motor` (any motor when `None`). Wire faults act once, on the
    /// next matching packet; [`Fault::Overload`] acts at once (on every motor when
    /// `None`).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// emu.inject(Some(3), Fault::Overload);
    /// assert_eq!(emu.hardware_error(3), Some(ctr_hw::control_table::HW_ERROR_OVERLOAD));
    /// ```
    pub fn inject(&self, motor: Option<u8>, fault: Fault) {
        let mut model = self.lock();
        if fault == Fault::Overload {
            model.sync_clock();
        }
        model.arm(motor, fault);
    }

    /// Schedules a fault: it is injected as by [`Emulator::inject`] as soon as `motor`
    /// has applied `goals` goal positions since the emulator was created (counting
    /// writes and sync writes that set the goal position; with `None`, as soon as any
    /// one motor has). A scheduled overload strikes the motor that reached the count.
    /// With `goals` already reached, the fault is injected at once.
    ///
    /// The goal is applied first: an overload armed by the goal of a sync write shows
    /// in the statuses that follow (for the rig: the sync read that verifies it).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault};
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let emu = Emulator::new(EmulatorConfig { time_scale: 0.0, ..EmulatorConfig::default() });
    /// emu.inject_after_goals(Some(2), Fault::Overload, 2);
    /// let mut bus = Bus::new(emu.link(), BusConfig::default());
    /// bus.write(2, 116, &100i32.to_le_bytes())?;
    /// assert_eq!(emu.hardware_error(2), Some(0));
    /// // The second goal arms the overload; the write's status already carries the alert.
    /// assert!(bus.write(2, 116, &200i32.to_le_bytes()).is_err());
    /// assert_eq!(emu.hardware_error(2), Some(ctr_hw::control_table::HW_ERROR_OVERLOAD));
    /// assert_eq!(emu.pending_faults(), 0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn inject_after_goals(&self, motor: Option<u8>, fault: Fault, goals: usize) {
        let mut model = self.lock();
        model.sync_clock();
        model.scheduled.push((motor, fault, goals));
        model.arm_scheduled();
    }

    /// Faults that have not acted yet: queued wire faults and scheduled faults.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).pending_faults(), 0);
    /// ```
    pub fn pending_faults(&self) -> usize {
        let model = self.lock();
        model.faults.len() + model.scheduled.len()
    }

    /// Goal positions motor `id` has applied so far.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).goals_applied(1), Some(0));
    /// ```
    pub fn goals_applied(&self, id: u8) -> Option<usize> {
        self.lock().motor(id).map(|m| m.goals)
    }

    /// Forgets the faults that have not acted yet (queued and scheduled).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// emu.inject(None, Fault::NoReply);
    /// emu.clear_faults();
    /// assert_eq!(emu.pending_faults(), 0);
    /// ```
    pub fn clear_faults(&self) {
        let mut model = self.lock();
        model.faults.clear();
        model.scheduled.clear();
    }

    /// Clears a motor's hardware error, as a reboot would (torque stays off).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// emu.inject(Some(1), Fault::Overload);
    /// emu.reboot(1);
    /// assert_eq!(emu.hardware_error(1), Some(0));
    /// ```
    pub fn reboot(&self, id: u8) {
        if let Some(motor) = self.lock().motor_mut(id) {
            motor.reboot();
        }
    }

    /// Advances simulated time by `dt` (on top of the scaled wall clock).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig { time_scale: 0.0, ..EmulatorConfig::default() });
    /// emu.advance(std::time::Duration::from_millis(500));
    /// assert_eq!(emu.sim_time(), 0.5);
    /// ```
    pub fn advance(&self, dt: Duration) {
        let mut model = self.lock();
        model.sync_clock();
        model.simulate(dt.as_secs_f64());
    }

    /// Simulated seconds since creation.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig { time_scale: 0.0, ..EmulatorConfig::default() });
    /// assert_eq!(emu.sim_time(), 0.0);
    /// ```
    pub fn sim_time(&self) -> f64 {
        let mut model = self.lock();
        model.sync_clock();
        model.sim_time
    }

    /// Reads a motor's control table directly (no bus, no faults).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// assert_eq!(emu.table(1, 7, 1), Some(vec![1])); // the ID register
    /// assert_eq!(emu.table(9, 7, 1), None);
    /// ```
    pub fn table(&self, id: u8, address: u16, length: u16) -> Option<Vec<u8>> {
        let mut model = self.lock();
        model.sync_clock();
        model.motor(id)?.read(address, length).ok()
    }

    /// A motor's present position in ticks.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).present_position(1), Some(0));
    /// ```
    pub fn present_position(&self, id: u8) -> Option<i32> {
        let mut model = self.lock();
        model.sync_clock();
        Some(model.motor(id)?.i32_at(ct::PRESENT_POSITION))
    }

    /// A motor's goal position in ticks.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).goal_position(2), Some(0));
    /// ```
    pub fn goal_position(&self, id: u8) -> Option<i32> {
        Some(self.lock().motor(id)?.i32_at(ct::GOAL_POSITION))
    }

    /// A motor's hardware error status register.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).hardware_error(4), Some(0));
    /// ```
    pub fn hardware_error(&self, id: u8) -> Option<u8> {
        Some(self.lock().motor(id)?.hardware_error())
    }

    /// Whether a motor's torque is on.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).torque_enabled(1), Some(false));
    /// ```
    pub fn torque_enabled(&self, id: u8) -> Option<bool> {
        Some(self.lock().motor(id)?.torque_on())
    }

    /// Every write applied so far, in order.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert!(Emulator::new(EmulatorConfig::default()).write_log().is_empty());
    /// ```
    pub fn write_log(&self) -> Vec<AppliedWrite> {
        self.lock().log.clone()
    }

    /// How many writes were applied to motor `id`.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).applied_writes(1), 0);
    /// ```
    pub fn applied_writes(&self, id: u8) -> usize {
        self.lock().log.iter().filter(|w| w.id == id).count()
    }

    /// Counters so far.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).stats().statuses_sent, 0);
    /// ```
    pub fn stats(&self) -> EmulatorStats {
        self.lock().stats
    }

    /// Feeds raw bytes received from the master and returns the bytes to answer with;
    /// `decoder` keeps partial packets between calls.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// use ctr_hw::protocol::{Decoder, Packet};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut decoder = Decoder::new();
    /// let reply = emu.process(&mut decoder, &Packet::ping(2).encode().unwrap());
    /// assert_eq!(reply[4], 2); // status from ID 2
    /// ```
    pub fn process(&self, decoder: &mut Decoder, bytes: &[u8]) -> Vec<u8> {
        decoder.push(bytes);
        let mut out = Vec::new();
        while let Some(frame) = decoder.next_frame() {
            out.extend(self.lock().handle_frame(frame));
        }
        out
    }

    /// An in-process [`Transport`] to this bus: writes are handled at once, replies are
    /// readable right after, and a read with nothing to read times out at once.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut bus = Bus::new(emu.link(), BusConfig::default());
    /// assert_eq!(bus.ping(4).unwrap().id, 4);
    /// ```
    pub fn link(&self) -> EmulatedLink {
        EmulatedLink {
            emulator: self.clone(),
            decoder: Decoder::new(),
            input: VecDeque::new(),
        }
    }

    /// Serves this bus over `transport` from a new thread until stopped.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// use ctr_hw::transport::SerialTransport;
    /// let (master, _slave) = serialport::TTYPort::pair().unwrap();
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let server = emu.serve(SerialTransport::from_port(Box::new(master)));
    /// server.stop().unwrap();
    /// ```
    pub fn serve<T: Transport + Send + 'static>(&self, mut transport: T) -> EmulatorServer {
        let stop = Arc::new(AtomicBool::new(false));
        let emulator = self.clone();
        let stop_flag = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let mut decoder = Decoder::new();
            let mut buf = [0u8; 512];
            while !stop_flag.load(Ordering::Relaxed) {
                match transport.read(&mut buf, Instant::now() + Duration::from_millis(10)) {
                    Ok(n) => {
                        let reply = emulator.process(&mut decoder, &buf[..n]);
                        if !reply.is_empty() {
                            transport.write_all(&reply)?;
                        }
                    }
                    Err(error) if transport.is_timeout(&error) => emulator.lock().sync_clock(),
                    Err(error) => return Err(error),
                }
            }
            Ok(())
        });
        EmulatorServer {
            stop,
            thread: Some(thread),
        }
    }

    /// Opens a pseudo-terminal pair and serves this bus on it; open
    /// [`PtyEmulator::path`] as a serial port to talk to it.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let pty = Emulator::new(EmulatorConfig::default()).serve_pty().unwrap();
    /// assert!(pty.path().starts_with("/dev/"));
    /// ```
    pub fn serve_pty(&self) -> Result<PtyEmulator, TransportError> {
        let (master, peer) = serialport::TTYPort::pair()?;
        let path = serialport::SerialPort::name(&peer).ok_or_else(|| TransportError::Io {
            kind: std::io::ErrorKind::NotFound,
            message: "pseudo-terminal has no path".into(),
        })?;
        let server = self.serve(SerialTransport::from_port(Box::new(master)));
        Ok(PtyEmulator {
            server,
            peer,
            path,
            emulator: self.clone(),
        })
    }
}

/// The in-process [`Transport`] returned by [`Emulator::link`].
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// use ctr_hw::transport::Transport;
/// use ctr_hw::protocol::Packet;
/// let mut link = Emulator::new(EmulatorConfig::default()).link();
/// link.write_all(&Packet::ping(1).encode().unwrap()).unwrap();
/// let mut buf = [0u8; 64];
/// assert_eq!(link.read(&mut buf, std::time::Instant::now()).unwrap(), 14);
/// ```
#[derive(Debug)]
pub struct EmulatedLink {
    emulator: Emulator,
    decoder: Decoder,
    input: VecDeque<u8>,
}

impl EmulatedLink {
    /// The emulator behind this link.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let link = Emulator::new(EmulatorConfig::default()).link();
    /// assert_eq!(link.emulator().ids().len(), 4);
    /// ```
    pub fn emulator(&self) -> &Emulator {
        &self.emulator
    }
}

impl Transport for EmulatedLink {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        let reply = self.emulator.process(&mut self.decoder, bytes);
        self.input.extend(reply);
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _deadline: Instant) -> Result<usize, TransportError> {
        if buf.is_empty() {
            return Ok(0);
        }
        if self.input.is_empty() {
            return Err(TransportError::Timeout);
        }
        let n = buf.len().min(self.input.len());
        for (slot, byte) in buf.iter_mut().zip(self.input.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }

    fn discard_input(&mut self) -> Result<(), TransportError> {
        self.input.clear();
        Ok(())
    }
}

/// A running emulator thread (see [`Emulator::serve`]); dropping it stops the thread.
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// let emu = Emulator::new(EmulatorConfig::default());
/// let server = emu.serve(emu.link()); // serving a link is pointless but harmless
/// assert!(!server.is_finished());
/// server.stop().unwrap();
/// ```
#[derive(Debug)]
pub struct EmulatorServer {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), TransportError>>>,
}

impl EmulatorServer {
    /// Stops the thread and returns how it ended.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// assert!(emu.serve(emu.link()).stop().is_ok());
    /// ```
    pub fn stop(mut self) -> Result<(), TransportError> {
        self.stop.store(true, Ordering::Relaxed);
        self.join()
    }

    /// Blocks until the thread ends by itself (a transport failure); serves forever
    /// otherwise.
    ///
    /// ```no_run
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// emu.serve(emu.link()).wait().unwrap();
    /// ```
    pub fn wait(mut self) -> Result<(), TransportError> {
        self.join()
    }

    /// Whether the thread has ended.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let server = emu.serve(emu.link());
    /// assert!(!server.is_finished());
    /// ```
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    fn join(&mut self) -> Result<(), TransportError> {
        match self.thread.take() {
            None => Ok(()),
            Some(thread) => thread.join().unwrap_or_else(|_| {
                Err(TransportError::Io {
                    kind: std::io::ErrorKind::Other,
                    message: "emulator thread panicked".into(),
                })
            }),
        }
    }
}

impl Drop for EmulatorServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        let _ = self.join();
    }
}

/// An emulator serving the master side of a pseudo-terminal (see
/// [`Emulator::serve_pty`]). It keeps its own handle on the slave side open, so that the
/// line does not hang up while clients come and go.
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// let pty = Emulator::new(EmulatorConfig::default()).serve_pty().unwrap();
/// let path = pty.path().to_owned();
/// assert_eq!(pty.emulator().ids(), [1, 2, 3, 4]);
/// pty.stop().unwrap();
/// ```
#[derive(Debug)]
pub struct PtyEmulator {
    // Field order matters: the server thread stops before the slave side closes.
    server: EmulatorServer,
    peer: serialport::TTYPort,
    path: String,
    emulator: Emulator,
}

impl PtyEmulator {
    /// The slave device path to open as a serial port (e.g. `/dev/pts/3`).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let pty = Emulator::new(EmulatorConfig::default()).serve_pty().unwrap();
    /// assert!(std::path::Path::new(pty.path()).exists());
    /// ```
    pub fn path(&self) -> &str {
        &self.path
    }

    /// The emulated bus (for fault injection and inspection).
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault};
    /// let pty = Emulator::new(EmulatorConfig::default()).serve_pty().unwrap();
    /// pty.emulator().inject(None, Fault::NoReply);
    /// ```
    pub fn emulator(&self) -> &Emulator {
        &self.emulator
    }

    /// Stops serving and closes the pseudo-terminal.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// Emulator::new(EmulatorConfig::default()).serve_pty().unwrap().stop().unwrap();
    /// ```
    pub fn stop(self) -> Result<(), TransportError> {
        let Self { server, peer, .. } = self;
        let result = server.stop();
        drop(peer);
        result
    }

    /// Serves until the thread fails (normally: until the process ends).
    ///
    /// ```no_run
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// let pty = Emulator::new(EmulatorConfig::default()).serve_pty()?;
    /// println!("{}", pty.path());
    /// pty.wait()?;
    /// # Ok::<(), ctr_hw::transport::TransportError>(())
    /// ```
    pub fn wait(self) -> Result<(), TransportError> {
        let Self { server, peer, .. } = self;
        let result = server.wait();
        drop(peer);
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::{Bus, BusConfig, BusError};

    fn frozen() -> Emulator {
        Emulator::new(EmulatorConfig {
            time_scale: 0.0,
            ..EmulatorConfig::default()
        })
    }

    fn bus(emu: &Emulator) -> Bus<EmulatedLink> {
        Bus::new(emu.link(), BusConfig::default())
    }

    #[test]
    fn answers_ping_read_and_write() {
        let emu = frozen();
        let mut bus = bus(&emu);
        for id in 1..=4 {
            let reply = bus.ping(id).unwrap();
            assert_eq!((reply.model, reply.firmware), (1020, 45));
        }
        assert!(matches!(bus.ping(5), Err(BusError::Timeout { .. })));
        bus.write(2, ct::PROFILE_VELOCITY, &100u32.to_le_bytes())
            .unwrap();
        assert_eq!(
            bus.read(2, ct::PROFILE_VELOCITY, 4).unwrap(),
            [100, 0, 0, 0]
        );
        assert_eq!(emu.applied_writes(2), 1);
    }

    #[test]
    fn enforces_access_rules() {
        let emu = frozen();
        let mut bus = bus(&emu);
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
        let emu = frozen();
        let mut bus = bus(&emu);
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
        let emu = frozen();
        let mut bus = bus(&emu);
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

    #[test]
    fn sync_instructions() {
        let emu = frozen();
        let mut bus = bus(&emu);
        let one = [1u8];
        bus.sync_write(ct::TORQUE_ENABLE, &[(1, &one[..]), (3, &one[..])])
            .unwrap();
        assert_eq!(emu.torque_enabled(1), Some(true));
        assert_eq!(emu.torque_enabled(2), Some(false));
        assert_eq!(emu.torque_enabled(3), Some(true));
        let values = bus.sync_read(&[3, 1, 2], ct::TORQUE_ENABLE, 1).unwrap();
        assert_eq!(values, [vec![1], vec![1], vec![0]]);
        let log = emu.write_log();
        assert_eq!(log.len(), 2);
        assert!(log.iter().all(|w| w.instruction == instruction::SYNC_WRITE));
    }

    #[test]
    fn overload_sets_the_alert_until_reboot() {
        let emu = frozen();
        let mut bus = bus(&emu);
        bus.write(4, ct::TORQUE_ENABLE, &[1]).unwrap();
        emu.inject(Some(4), Fault::Overload);
        assert_eq!(emu.torque_enabled(4), Some(false));
        match bus.read(4, ct::HARDWARE_ERROR_STATUS, 1) {
            Err(BusError::Alert { params, .. }) => assert_eq!(params, [ct::HW_ERROR_OVERLOAD]),
            other => panic!("unexpected {other:?}"),
        }
        // Torque cannot come back while the error stands.
        assert!(matches!(
            bus.write(4, ct::TORQUE_ENABLE, &[1]),
            Err(BusError::Device { .. })
        ));
        // Other motors are unaffected.
        assert!(bus.ping(3).is_ok());
        emu.reboot(4);
        assert!(bus.ping(4).is_ok());
    }

    #[test]
    fn faults_act_once_on_the_right_motor() {
        let emu = frozen();
        let mut bus = bus(&emu);
        emu.inject(Some(2), Fault::NoReply);
        assert!(bus.ping(1).is_ok());
        assert_eq!(emu.pending_faults(), 1);
        // The ping of 2 loses its first reply and succeeds on the retry.
        assert!(bus.ping(2).is_ok());
        assert_eq!(bus.stats().retries, 1);
        assert_eq!(emu.pending_faults(), 0);
        assert_eq!(emu.stats().faults_applied, 1);
    }

    #[test]
    fn reply_faults_damage_the_bytes() {
        let emu = frozen();
        let mut decoder = Decoder::new();
        let ping = Packet::ping(1).encode().unwrap();
        let clean = emu.process(&mut decoder, &ping);
        emu.inject(Some(1), Fault::CorruptReplyCrc);
        let corrupt = emu.process(&mut decoder, &ping);
        assert_eq!(corrupt.len(), clean.len());
        assert_ne!(corrupt, clean);
        emu.inject(Some(1), Fault::DropReplyBytes(3));
        let short = emu.process(&mut decoder, &ping);
        assert_eq!(short.len(), clean.len() - 3);
        emu.inject(None, Fault::DropInstruction);
        assert!(emu.process(&mut decoder, &ping).is_empty());
        assert_eq!(emu.stats().instructions_dropped, 1);
        // A corrupt instruction gets a CRC error status.
        let mut bad = ping.clone();
        bad[9] ^= 1;
        let reply = emu.process(&mut decoder, &bad);
        assert_eq!(reply[8], ErrorCode::CrcError.code());
    }

    #[test]
    fn scheduled_faults_wait_for_the_goal_count() {
        let emu = frozen();
        let mut bus = bus(&emu);
        emu.inject_after_goals(Some(3), Fault::NoReply, 2);
        emu.inject_after_goals(None, Fault::Overload, 3);
        let goal = |n: i32| n.to_le_bytes();
        // Sync writes count for every motor they set; other registers do not count.
        bus.sync_write(ct::GOAL_POSITION, &[(1, &goal(10)[..]), (3, &goal(10)[..])])
            .unwrap();
        bus.write(3, ct::PROFILE_VELOCITY, &goal(50)).unwrap();
        assert_eq!(emu.goals_applied(3), Some(1));
        assert_eq!(emu.pending_faults(), 2);
        assert_eq!(bus.stats().retries, 0);
        // Motor 3's second goal arms the lost reply: the write is confirmed by read-back.
        bus.write(3, ct::GOAL_POSITION, &goal(20)).unwrap();
        assert_eq!(bus.stats().confirmed_by_read_back, 1);
        assert_eq!(emu.applied_writes(3), 3);
        // The first motor to reach three goals overloads; the others do not.
        bus.write(1, ct::GOAL_POSITION, &goal(20)).unwrap();
        assert_eq!(emu.hardware_error(1), Some(0));
        bus.write(1, ct::GOAL_POSITION, &goal(30)).unwrap_err(); // alert in the status
        assert_eq!(emu.hardware_error(1), Some(ct::HW_ERROR_OVERLOAD));
        assert_eq!(emu.hardware_error(3), Some(0));
        assert_eq!(emu.pending_faults(), 0);
        // Already reached: at once.
        emu.inject_after_goals(Some(3), Fault::Overload, 1);
        assert_eq!(emu.hardware_error(3), Some(ct::HW_ERROR_OVERLOAD));
    }

    #[test]
    fn broadcast_ping_answers_in_id_order() {
        let emu = frozen();
        let mut decoder = Decoder::new();
        let bytes = emu.process(&mut decoder, &Packet::ping(BROADCAST_ID).encode().unwrap());
        let mut reader = Decoder::new();
        reader.push(&bytes);
        let mut ids = Vec::new();
        while let Some(frame) = reader.next_frame() {
            ids.push(frame.result.unwrap().id);
        }
        assert_eq!(ids, [1, 2, 3, 4]);
    }
}

//! The emulated bus behind every [`Emulator`](super::Emulator) handle: the motors, the
//! faults, the log and the clock; instruction packets in, status packets out.
//!
//! Instructions: ping (unicast and broadcast), read, write, sync read, sync write,
//! reboot; other instructions get an instruction-error status. A broadcast gets no
//! status, and neither does a frame that names none of the motors.

use std::time::Instant;

use super::faults::{self, Fault, Faults};
use super::servo::Motor;
use super::{AppliedWrite, EmulatorConfig, EmulatorStats};
use crate::control_table as ct;
use crate::protocol::{
    instruction, ErrorCode, Frame, Packet, StatusError, StatusPacket, BROADCAST_ID, ID_OFFSET,
};

/// Parameter bytes of an address.
const ADDRESS_PARAMS: usize = 2;
/// Parameter bytes of an address and a length (two bytes each).
const RANGE_PARAMS: usize = 4;
/// The shortest integration step, seconds (a zero step would never end).
const MIN_STEP_SECONDS: f64 = 1e-6;

/// The state behind every handle of an [`Emulator`](super::Emulator).
#[derive(Debug)]
pub(super) struct Model {
    config: EmulatorConfig,
    /// The motors, by ascending ID.
    pub(super) motors: Vec<Motor>,
    /// Faults that have not acted yet.
    pub(super) faults: Faults,
    /// Every applied write, in order.
    pub(super) log: Vec<AppliedWrite>,
    pub(super) stats: EmulatorStats,
    /// The wall-clock time simulated time was last advanced to.
    last_wall: Instant,
    /// Simulated seconds since creation.
    pub(super) sim_time: f64,
}

impl Model {
    /// One motor per configured ID (duplicates dropped), at rest with torque off.
    pub(super) fn new(config: EmulatorConfig) -> Self {
        let mut ids = config.ids.clone();
        ids.sort_unstable();
        ids.dedup();
        let motors = ids.iter().map(|&id| Motor::new(id, &config)).collect();
        Self {
            config,
            motors,
            faults: Faults::default(),
            log: Vec::new(),
            stats: EmulatorStats::default(),
            last_wall: Instant::now(),
            sim_time: 0.0,
        }
    }

    /// The motor with this ID.
    pub(super) fn motor(&self, id: u8) -> Option<&Motor> {
        self.motors.iter().find(|m| m.id == id)
    }

    /// The motor with this ID, mutably.
    pub(super) fn motor_mut(&mut self, id: u8) -> Option<&mut Motor> {
        self.motors.iter_mut().find(|m| m.id == id)
    }

    fn has(&self, id: u8) -> bool {
        self.motor(id).is_some()
    }

    /// Advances simulated time by the scaled wall-clock time since the last call.
    pub(super) fn sync_clock(&mut self) {
        let now = Instant::now();
        let elapsed = now.duration_since(self.last_wall).as_secs_f64();
        self.last_wall = now;
        self.simulate(elapsed * self.config.time_scale);
    }

    /// Advances simulated time by `seconds`, moving the motors in steps of the
    /// configured integration step.
    pub(super) fn simulate(&mut self, seconds: f64) {
        if seconds.is_nan() || seconds <= 0.0 {
            return;
        }
        let step = self.config.step.as_secs_f64().max(MIN_STEP_SECONDS);
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

    /// Injects a fault now (see [`Faults::arm`]).
    pub(super) fn arm(&mut self, motor: Option<u8>, fault: Fault) {
        self.faults.arm(motor, fault, &mut self.motors);
    }

    /// Schedules a fault for a motor's goal count (see [`Faults::schedule`]).
    pub(super) fn schedule(&mut self, motor: Option<u8>, fault: Fault, goals: usize) {
        self.faults.schedule(motor, fault, goals, &mut self.motors);
    }

    /// Counts a queued fault that takes effect now.
    fn applied(&mut self, fault: Option<Fault>) -> Option<Fault> {
        if fault.is_some() {
            self.stats.faults_applied += 1;
        }
        fault
    }

    /// Handles one received frame and returns the bytes to send back.
    pub(super) fn handle_frame(&mut self, frame: Frame) -> Vec<u8> {
        self.sync_clock();
        match frame.result {
            Ok(packet) => self.handle_packet(packet),
            Err(_) => {
                self.stats.corrupt_received += 1;
                // The ID byte of a damaged frame may itself be damaged; answer only when
                // it names one of our motors.
                let id = frame.raw.get(ID_OFFSET).copied().unwrap_or(BROADCAST_ID);
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
                .get(RANGE_PARAMS..)
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
        let dropped = self.faults.take(|id, fault| {
            fault == Fault::DropInstruction && id.is_none_or(|id| targets.contains(&id))
        });
        if self.applied(dropped).is_some() {
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
                    Some((address, length)) if params.len() == RANGE_PARAMS => self
                        .motor(id)
                        .map_or(Err(ErrorCode::Access), |m| m.read(address, length)),
                    _ => Err(ErrorCode::DataLength),
                };
                vec![(id, result)]
            }
            instruction::WRITE => {
                let id = targets[0];
                let result = if params.len() <= ADDRESS_PARAMS {
                    Err(ErrorCode::DataLength)
                } else {
                    let address = u16::from_le_bytes([params[0], params[1]]);
                    self.write(id, address, &params[ADDRESS_PARAMS..], instruction::WRITE)
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
        let sets_goal = usize::from(address) <= goal
            && goal + usize::from(ct::GOAL_POSITION_LEN) <= usize::from(address) + data.len();
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
            self.faults.arm_scheduled(&mut self.motors);
        }
        Ok(())
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
            let Ok(bytes) = status.encode() else {
                continue;
            };
            let fault = self.faults.take_reply_fault(id);
            let fault = self.applied(fault);
            let Some(bytes) = faults::damage(fault, bytes) else {
                continue;
            };
            self.stats.statuses_sent += 1;
            out.extend_from_slice(&bytes);
        }
        out
    }
}

/// The address and length that open the parameters of a read, a sync read and a
/// sync write.
fn address_and_length(params: &[u8]) -> Option<(u16, u16)> {
    if params.len() < RANGE_PARAMS {
        return None;
    }
    Some((
        u16::from_le_bytes([params[0], params[1]]),
        u16::from_le_bytes([params[2], params[3]]),
    ))
}

/// A sync write's address and its `(id, data)` entries.
type SyncWriteEntries = (u16, Vec<(u8, Vec<u8>)>);

/// Splits a sync write's parameters; `None` when they do not divide into entries.
fn sync_write_entries(params: &[u8]) -> Option<SyncWriteEntries> {
    let (address, length) = address_and_length(params)?;
    let length = usize::from(length);
    let body = &params[RANGE_PARAMS..];
    if length == 0 || !body.len().is_multiple_of(1 + length) {
        return None;
    }
    let entries = body
        .chunks(1 + length)
        .map(|chunk| (chunk[0], chunk[1..].to_vec()))
        .collect();
    Some((address, entries))
}

#[cfg(test)]
mod tests {
    use crate::bus::BusError;
    use crate::control_table as ct;
    use crate::emulator::testing::{frozen, frozen_bus};
    use crate::protocol::{instruction, Decoder, Packet, BROADCAST_ID};

    #[test]
    fn answers_ping_read_and_write() {
        let (emu, mut bus) = frozen_bus();
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
    fn sync_instructions() {
        let (emu, mut bus) = frozen_bus();
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

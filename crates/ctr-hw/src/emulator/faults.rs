//! Fault injection: wire faults queued for the next packet they match, overloads that
//! strike at once, and faults scheduled for the moment a motor has applied a given
//! number of goal positions.

use super::servo::Motor;
use crate::protocol::INSTRUCTION_OFFSET;

/// The mask XORed into a status packet's last CRC byte by [`Fault::CorruptReplyCrc`].
const CRC_CORRUPTION: u8 = 0x5A;

/// A fault to inject, once, with [`Emulator::inject`](super::Emulator::inject).
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
    /// Whether the fault strikes a status packet (rather than an instruction or a motor).
    fn affects_replies(self) -> bool {
        matches!(
            self,
            Self::DropReplyBytes(_) | Self::CorruptReplyCrc | Self::NoReply
        )
    }
}

/// The faults that have not acted yet.
#[derive(Debug, Default)]
pub(super) struct Faults {
    /// Wire faults waiting for their packet: `(motor, fault)`, `None` for any motor.
    queued: Vec<(Option<u8>, Fault)>,
    /// Faults waiting for a motor's goal count: `(motor, fault, goals)`.
    scheduled: Vec<(Option<u8>, Fault, usize)>,
}

impl Faults {
    /// Queued and scheduled faults.
    pub(super) fn pending(&self) -> usize {
        self.queued.len() + self.scheduled.len()
    }

    /// Forgets every fault that has not acted yet.
    pub(super) fn clear(&mut self) {
        self.queued.clear();
        self.scheduled.clear();
    }

    /// Takes the first queued fault that `matches` (motor, fault).
    pub(super) fn take(&mut self, matches: impl Fn(Option<u8>, Fault) -> bool) -> Option<Fault> {
        let index = self.queued.iter().position(|&(id, f)| matches(id, f))?;
        Some(self.queued.remove(index).1)
    }

    /// Takes the reply fault for the status of motor `id`, if one is queued.
    pub(super) fn take_reply_fault(&mut self, id: u8) -> Option<Fault> {
        self.take(|target, fault| fault.affects_replies() && target.is_none_or(|t| t == id))
    }

    /// Injects a fault now: an overload at once on the motors it names (every motor for
    /// `None`), a wire fault into the queue.
    pub(super) fn arm(&mut self, motor: Option<u8>, fault: Fault, motors: &mut [Motor]) {
        if fault == Fault::Overload {
            for m in motors {
                if motor.is_none_or(|id| id == m.id) {
                    m.overload();
                }
            }
        } else {
            self.queued.push((motor, fault));
        }
    }

    /// Schedules a fault for when `motor` (any motor for `None`) has applied `goals` goal
    /// positions, and arms it at once if that is so already.
    pub(super) fn schedule(
        &mut self,
        motor: Option<u8>,
        fault: Fault,
        goals: usize,
        motors: &mut [Motor],
    ) {
        self.scheduled.push((motor, fault, goals));
        self.arm_scheduled(motors);
    }

    /// Arms the scheduled faults whose motor has applied enough goal positions.
    pub(super) fn arm_scheduled(&mut self, motors: &mut [Motor]) {
        let mut i = 0;
        while i < self.scheduled.len() {
            let (motor, fault, goals) = self.scheduled[i];
            let reached = motors
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
                    self.arm(target, fault, motors);
                }
                None => i += 1,
            }
        }
    }
}

/// A status packet's bytes as a reply fault leaves them; `None` when the status is lost.
pub(super) fn damage(fault: Option<Fault>, mut bytes: Vec<u8>) -> Option<Vec<u8>> {
    match fault {
        Some(Fault::NoReply) => return None,
        Some(Fault::CorruptReplyCrc) => {
            if let Some(last) = bytes.last_mut() {
                *last ^= CRC_CORRUPTION;
            }
        }
        Some(Fault::DropReplyBytes(n)) => {
            let n = n.min(bytes.len() - INSTRUCTION_OFFSET);
            bytes.drain(INSTRUCTION_OFFSET..INSTRUCTION_OFFSET + n);
        }
        _ => {}
    }
    Some(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::BusError;
    use crate::control_table as ct;
    use crate::emulator::testing::{frozen, frozen_bus};
    use crate::protocol::{Decoder, ErrorCode, Packet};

    #[test]
    fn overload_sets_the_alert_until_reboot() {
        let (emu, mut bus) = frozen_bus();
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
        let (emu, mut bus) = frozen_bus();
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
        let (emu, mut bus) = frozen_bus();
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
}

//! An in-process emulator of a Dynamixel X-series bus (four motors by default), for tests
//! without hardware and for `ctr-cli hw emulate`.
//!
//! # What it emulates
//!
//! * Instructions: ping (unicast and broadcast), read, write, sync read, sync write,
//!   reboot; other instructions get an instruction-error status (the bus: `model.rs`).
//! * A control-table subset (see [`crate::control_table`]): model number, firmware, ID,
//!   operating mode (extended position), velocity limit, torque enable (64), hardware
//!   error status (70), profile acceleration (108) and velocity (112), goal position
//!   (116), moving (122), present velocity (128) and present position (132). Read-only
//!   entries and EEPROM writes with torque on give an access error, out-of-range values
//!   a data range or data limit error (the motor: `servo.rs`).
//! * Motion in simulated time: with torque on, each motor moves toward its goal with a
//!   trapezoidal profile limited by profile velocity (or the velocity limit when 0) and
//!   profile acceleration (unlimited when 0). Simulated time advances with the wall
//!   clock times [`EmulatorConfig::time_scale`], plus whatever [`Emulator::advance`]
//!   adds.
//! * Fault injection ([`Emulator::inject`]): a lost instruction, dropped reply bytes, a
//!   corrupt reply CRC, a missing reply, and an overload (hardware error bit 5, torque
//!   off, alert bit in every status until reboot); [`Emulator::inject_after_goals`]
//!   arms one when a motor has applied a given number of goal positions, so that a
//!   fault strikes at a reproducible point of a run (`faults.rs`).
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
//! [`Emulator::link`] gives an in-process [`Transport`](crate::transport::Transport)
//! instead, with no thread and no pseudo-terminal (both in `link.rs`).

mod faults;
mod link;
mod model;
mod servo;

pub use faults::Fault;
pub use link::{EmulatedLink, EmulatorServer, PtyEmulator};

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use crate::control_table as ct;
use crate::protocol::Decoder;
use model::Model;

/// The firmware version the emulated motors report.
const FIRMWARE_VERSION: u8 = 45;

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

impl EmulatorConfig {
    /// The default bus with a frozen clock: simulated time moves only with
    /// [`Emulator::advance`], so that tests see the same motion on any machine.
    ///
    /// ```
    /// let frozen = ctr_hw::emulator::EmulatorConfig::frozen();
    /// assert_eq!((frozen.time_scale, frozen.ids.len()), (0.0, 4));
    /// ```
    pub fn frozen() -> Self {
        Self {
            time_scale: 0.0,
            ..Self::default()
        }
    }
}

impl Default for EmulatorConfig {
    fn default() -> Self {
        Self {
            ids: vec![1, 2, 3, 4],
            time_scale: 1.0,
            step: Duration::from_millis(1),
            model_number: ct::MODEL_XM430_W350,
            firmware_version: FIRMWARE_VERSION,
        }
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

/// An emulated bus. Cloning gives another handle to the same motors.
///
/// ```
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// use ctr_hw::bus::{Bus, BusConfig};
/// use std::time::Duration;
///
/// let emu = Emulator::new(EmulatorConfig::frozen());
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
        Self {
            model: Arc::new(Mutex::new(Model::new(config))),
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
    /// let emu = Emulator::new(EmulatorConfig::frozen());
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
        model.schedule(motor, fault, goals);
    }

    /// Faults that have not acted yet: queued wire faults and scheduled faults.
    ///
    /// ```
    /// use ctr_hw::emulator::{Emulator, EmulatorConfig};
    /// assert_eq!(Emulator::new(EmulatorConfig::default()).pending_faults(), 0);
    /// ```
    pub fn pending_faults(&self) -> usize {
        self.lock().faults.pending()
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
        self.lock().faults.clear();
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
    /// let emu = Emulator::new(EmulatorConfig::frozen());
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
    /// let emu = Emulator::new(EmulatorConfig::frozen());
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
}

/// Helpers for the tests of the emulator and of what runs on it.
#[cfg(test)]
pub(crate) mod testing {
    use super::{EmulatedLink, Emulator, EmulatorConfig};
    use crate::bus::{Bus, BusConfig};

    /// An emulator whose clock moves only with [`Emulator::advance`].
    pub(crate) fn frozen() -> Emulator {
        Emulator::new(EmulatorConfig::frozen())
    }

    /// A bus on an in-process link to `emu`.
    pub(crate) fn bus(emu: &Emulator) -> Bus<EmulatedLink> {
        Bus::new(emu.link(), BusConfig::default())
    }

    /// A frozen emulator and a bus on an in-process link to it.
    pub(crate) fn frozen_bus() -> (Emulator, Bus<EmulatedLink>) {
        let emu = frozen();
        let bus = bus(&emu);
        (emu, bus)
    }
}

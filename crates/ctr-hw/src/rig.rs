//! Joint-level control of the rig: move joints, read them back, stop on faults.
//!
//! A [`Rig`] joins a [`Bus`] and an [`Actuation`]. Every command is checked against the
//! joint limits and converted to ticks before anything is sent; goals go out in one
//! sync write that the bus verifies by reading back (so no goal is applied twice and
//! none is lost silently, see [`crate::bus`]).
//!
//! # Faults
//!
//! Any bus failure during a rig operation (no reply after the bounded retries, a corrupt
//! reply, a device error, a hardware alert such as an overload) stops the rig:
//!
//! 1. every motor that still answers is told to hold: its goal is set to its present
//!    position;
//! 2. the hardware error status of each motor is read;
//! 3. with [`RigConfig::torque_off_on_fault`], torque is switched off;
//! 4. a [`RigFault`] is recorded and returned: the bus error that caused it, with the
//!    packet sent and the raw bytes received, and the outcome of steps 1-3.
//!
//! While a fault is recorded, [`Rig::move_to`], [`Rig::move_joint`] and [`Rig::enable`]
//! refuse to run; [`Rig::clear_fault`] re-arms the rig. Reads, [`Rig::hold`] and
//! [`Rig::torque_off`] still work.
//!
//! ```
//! use ctr_formats::ActuatedJoint;
//! use ctr_hw::actuation::Actuation;
//! use ctr_hw::bus::{Bus, BusConfig};
//! use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault};
//! use ctr_hw::rig::{Rig, RigConfig, RigError};
//! use std::time::Duration;
//!
//! let emu = Emulator::new(EmulatorConfig::frozen());
//! let actuation = Actuation::new(vec![
//!     ActuatedJoint::feed(1, 1, 8.0, 0.0, 60.0, 10.0),      // s1 on motor 1
//!     ActuatedJoint::rotation(1, 2, -180.0, 180.0, 90.0),   // theta1 on motor 2
//!     ActuatedJoint::feed(2, 3, 8.0, 0.0, 90.0, 10.0),      // s2 on motor 3
//!     ActuatedJoint::rotation(2, 4, -180.0, 180.0, 90.0),   // theta2 on motor 4
//! ])?;
//! let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), actuation, RigConfig::default());
//! rig.enable()?;
//! rig.move_to(&[8.0, 90.0, 4.0, 0.0])?;
//! emu.advance(Duration::from_secs(5));
//! assert_eq!(rig.positions()?, [8.0, 90.0, 4.0, 0.0]);
//!
//! // Out of limits: refused before anything is sent.
//! assert!(matches!(rig.move_to(&[65.0, 90.0, 4.0, 0.0]), Err(RigError::Actuation(_))));
//!
//! // An overload stops the rig and names the motor.
//! emu.inject(Some(3), Fault::Overload);
//! let err = rig.move_to(&[0.0, 0.0, 0.0, 0.0]).unwrap_err();
//! let RigError::Fault(fault) = err else { panic!() };
//! assert_eq!(fault.cause.id(), Some(3));
//! assert_eq!(fault.hardware_errors, [(3, ctr_hw::control_table::HW_ERROR_OVERLOAD)]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt;
use std::time::{Duration, Instant};

use crate::actuation::{self, Actuation, ActuationError};
use crate::bus::{Bus, BusError, PingReply};
use crate::control_table as ct;
use crate::transport::Transport;

/// Settings of a [`Rig`].
///
/// ```
/// let cfg = ctr_hw::rig::RigConfig { torque_off_on_fault: true, ..Default::default() };
/// assert!(cfg.torque_off_on_fault);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RigConfig {
    /// Switch torque off after holding, when a fault stops the rig (default: keep torque
    /// on and hold position).
    pub torque_off_on_fault: bool,
    /// Polling period of [`Rig::wait_until_still`].
    pub poll_period: Duration,
}

impl Default for RigConfig {
    fn default() -> Self {
        Self {
            torque_off_on_fault: false,
            poll_period: Duration::from_millis(10),
        }
    }
}

/// What stopped the rig, and what was done about it.
///
/// ```
/// use ctr_hw::rig::RigFault;
/// use ctr_hw::bus::BusError;
/// let fault = RigFault::new(BusError::InvalidRequest { reason: "example".into() });
/// assert!(fault.held.is_empty());
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RigFault {
    /// The bus error that stopped the rig: it names the packet sent and carries the raw
    /// bytes received.
    pub cause: BusError,
    /// Motors told to hold, with the position (ticks) they hold.
    pub held: Vec<(u8, i32)>,
    /// Motors that could not be told to hold, and why.
    pub hold_failures: Vec<(u8, BusError)>,
    /// Motors with a non-zero hardware error status (see `control_table::HW_ERROR_*`).
    pub hardware_errors: Vec<(u8, u8)>,
    /// Whether torque was switched off on every motor.
    pub torque_disabled: bool,
}

impl RigFault {
    /// A fault with its cause only (nothing held yet).
    ///
    /// ```
    /// use ctr_hw::rig::RigFault;
    /// use ctr_hw::bus::BusError;
    /// let f = RigFault::new(BusError::InvalidRequest { reason: "x".into() });
    /// assert!(!f.torque_disabled);
    /// ```
    pub fn new(cause: BusError) -> Self {
        Self {
            cause,
            held: Vec::new(),
            hold_failures: Vec::new(),
            hardware_errors: Vec::new(),
            torque_disabled: false,
        }
    }
}

impl fmt::Display for RigFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.cause)?;
        for (id, status) in &self.hardware_errors {
            write!(
                f,
                "; ID {id} hardware error {status:#04X} ({})",
                ct::hardware_error_names(*status).join(", ")
            )?;
        }
        if !self.held.is_empty() {
            let ids: Vec<String> = self.held.iter().map(|(id, _)| id.to_string()).collect();
            write!(f, "; holding IDs {}", ids.join(", "))?;
        }
        for (id, error) in &self.hold_failures {
            write!(f, "; could not hold ID {id}: {error}")?;
        }
        if self.torque_disabled {
            write!(f, "; torque off")?;
        }
        Ok(())
    }
}

/// Errors of rig operations.
///
/// ```
/// use ctr_hw::rig::RigError;
/// use ctr_hw::actuation::ActuationError;
/// let e = RigError::from(ActuationError::UnknownJoint { name: "x".into() });
/// assert_eq!(e.to_string(), "no joint named x");
/// ```
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RigError {
    /// A limit or configuration problem; nothing was sent.
    #[error(transparent)]
    Actuation(#[from] ActuationError),
    /// A bus failure stopped the rig just now.
    #[error("rig stopped: {0}")]
    Fault(Box<RigFault>),
    /// The rig is stopped by an earlier fault; nothing was sent.
    #[error("rig is stopped by an earlier fault ({0}); clear it first")]
    Faulted(Box<RigFault>),
    /// A bus failure in an operation that does not stop the rig (holding, torque off).
    #[error(transparent)]
    Bus(BusError),
    /// The joints were still moving when the wait ended.
    #[error("joints still moving after {waited:?}")]
    StillMoving {
        /// How long was waited.
        waited: Duration,
    },
}

/// The rig: a bus plus the joint-to-motor mapping.
///
/// ```
/// use ctr_formats::ActuatedJoint;
/// use ctr_hw::actuation::Actuation;
/// use ctr_hw::bus::{Bus, BusConfig};
/// use ctr_hw::emulator::{Emulator, EmulatorConfig};
/// use ctr_hw::rig::{Rig, RigConfig};
/// let emu = Emulator::new(EmulatorConfig::default());
/// let tube1 = vec![
///     ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),     // s1 on motor 1
///     ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),   // theta1 on motor 2
/// ];
/// let act = Actuation::new(tube1)?;
/// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), act, RigConfig::default());
/// assert_eq!(rig.ping_all()?.len(), 2);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Rig<T: Transport> {
    bus: Bus<T>,
    actuation: Actuation,
    config: RigConfig,
    fault: Option<RigFault>,
}

impl<T: Transport> Rig<T> {
    /// A rig over `bus` driving the joints of `actuation`.
    ///
    /// ```
    /// use ctr_hw::actuation::Actuation;
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::rig::{Rig, RigConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let rig = Rig::new(bus, Actuation::new(vec![]).unwrap(), RigConfig::default());
    /// assert!(rig.fault().is_none());
    /// ```
    pub fn new(bus: Bus<T>, actuation: Actuation, config: RigConfig) -> Self {
        Self {
            bus,
            actuation,
            config,
            fault: None,
        }
    }

    /// The joint mapping.
    ///
    /// ```
    /// use ctr_hw::actuation::Actuation;
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::rig::{Rig, RigConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let rig = Rig::new(bus, Actuation::new(vec![]).unwrap(), RigConfig::default());
    /// assert!(rig.actuation().is_empty());
    /// ```
    pub fn actuation(&self) -> &Actuation {
        &self.actuation
    }

    /// The bus (for its counters).
    ///
    /// ```
    /// use ctr_hw::actuation::Actuation;
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::rig::{Rig, RigConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let rig = Rig::new(bus, Actuation::new(vec![]).unwrap(), RigConfig::default());
    /// assert_eq!(rig.bus().stats().packets_sent, 0);
    /// ```
    pub fn bus(&self) -> &Bus<T> {
        &self.bus
    }

    /// The bus, mutably: direct access bypasses limit checks and fault handling.
    ///
    /// ```
    /// use ctr_hw::actuation::Actuation;
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::rig::{Rig, RigConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let mut rig = Rig::new(bus, Actuation::new(vec![]).unwrap(), RigConfig::default());
    /// rig.bus_mut().transport_mut().push_silence();
    /// ```
    pub fn bus_mut(&mut self) -> &mut Bus<T> {
        &mut self.bus
    }

    /// Gives the bus back.
    ///
    /// ```
    /// use ctr_hw::actuation::Actuation;
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::rig::{Rig, RigConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let rig = Rig::new(bus, Actuation::new(vec![]).unwrap(), RigConfig::default());
    /// let bus = rig.into_bus();
    /// ```
    pub fn into_bus(self) -> Bus<T> {
        self.bus
    }

    /// The recorded fault, if the rig is stopped.
    ///
    /// ```
    /// use ctr_hw::actuation::Actuation;
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::rig::{Rig, RigConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let rig = Rig::new(bus, Actuation::new(vec![]).unwrap(), RigConfig::default());
    /// assert!(rig.fault().is_none());
    /// ```
    pub fn fault(&self) -> Option<&RigFault> {
        self.fault.as_ref()
    }

    /// Forgets the recorded fault so that moves are accepted again, and returns it.
    /// Clear the cause first (e.g. reboot an overloaded motor, then [`Rig::enable`]).
    ///
    /// ```
    /// use ctr_hw::actuation::Actuation;
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::rig::{Rig, RigConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let mut rig = Rig::new(bus, Actuation::new(vec![]).unwrap(), RigConfig::default());
    /// assert!(rig.clear_fault().is_none());
    /// ```
    pub fn clear_fault(&mut self) -> Option<RigFault> {
        self.fault.take()
    }

    /// Pings every motor of the mapping, in joint order.
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// assert_eq!(rig.ping_all()?[1].id, 2);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn ping_all(&mut self) -> Result<Vec<PingReply>, RigError> {
        let mut replies = Vec::with_capacity(self.actuation.len());
        for id in self.actuation.motor_ids() {
            match self.bus.ping(id) {
                Ok(reply) => replies.push(reply),
                Err(error) => return Err(self.stop_on_fault(error)),
            }
        }
        Ok(replies)
    }

    /// Prepares the motors to move: profile velocity from each joint's `max_speed`, goal
    /// set to the present position (so nothing jumps), then torque on.
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// rig.enable()?;
    /// assert_eq!(emu.torque_enabled(1), Some(true));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn enable(&mut self) -> Result<(), RigError> {
        self.refuse_if_faulted()?;
        let ids = self.actuation.motor_ids();
        let velocities: Vec<(u8, [u8; 4])> = self
            .actuation
            .joints()
            .iter()
            .map(|j| (j.motor_id, actuation::profile_velocity(j).to_le_bytes()))
            .collect();
        let result = self
            .sync_write(ct::PROFILE_VELOCITY, &velocities)
            .and_then(|()| self.read_ticks(&ids))
            .and_then(|present| {
                let goals: Vec<(u8, [u8; 4])> = ids
                    .iter()
                    .zip(present)
                    .map(|(&id, p)| (id, p.to_le_bytes()))
                    .collect();
                self.sync_write(ct::GOAL_POSITION, &goals)
            })
            .and_then(|()| {
                let on: Vec<(u8, [u8; 1])> = ids.iter().map(|&id| (id, [1])).collect();
                self.sync_write(ct::TORQUE_ENABLE, &on)
            });
        result.map_err(|error| self.stop_on_fault(error))
    }

    /// Switches torque off on every motor (allowed while stopped by a fault).
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// rig.enable()?;
    /// rig.torque_off()?;
    /// assert_eq!(emu.torque_enabled(1), Some(false));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn torque_off(&mut self) -> Result<(), RigError> {
        let off: Vec<(u8, [u8; 1])> = self
            .actuation
            .motor_ids()
            .into_iter()
            .map(|id| (id, [0]))
            .collect();
        self.sync_write(ct::TORQUE_ENABLE, &off)
            .map_err(RigError::Bus)
    }

    /// Sends new goals for every joint (joint order, mm or degrees). All values are
    /// checked against their limits first; on success the goal ticks are returned.
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// assert_eq!(rig.move_to(&[2.0, -45.0])?, [1024, -512]);
    /// assert_eq!(emu.goal_position(1), Some(1024));
    /// assert!(rig.move_to(&[11.0, 0.0]).is_err()); // s1 above its max
    /// assert_eq!(emu.goal_position(1), Some(1024));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn move_to(&mut self, targets: &[f64]) -> Result<Vec<i32>, RigError> {
        self.refuse_if_faulted()?;
        let ticks = self.actuation.to_ticks(targets)?;
        let goals: Vec<(u8, [u8; 4])> = self
            .actuation
            .motor_ids()
            .into_iter()
            .zip(&ticks)
            .map(|(id, t)| (id, t.to_le_bytes()))
            .collect();
        self.sync_write(ct::GOAL_POSITION, &goals)
            .map_err(|error| self.stop_on_fault(error))?;
        Ok(ticks)
    }

    /// Sends a new goal for one joint, by name; returns the goal in ticks.
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// assert_eq!(rig.move_joint("theta1", 45.0)?, 512);
    /// assert!(rig.move_joint("theta9", 0.0).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn move_joint(&mut self, name: &str, value: f64) -> Result<i32, RigError> {
        self.refuse_if_faulted()?;
        let joint = &self.actuation.joints()[self.actuation.index_of(name)?];
        let ticks = actuation::goal_ticks(joint, value)?;
        let id = joint.motor_id;
        self.bus
            .write(id, ct::GOAL_POSITION, &ticks.to_le_bytes())
            .map_err(|error| self.stop_on_fault(error))?;
        Ok(ticks)
    }

    /// Present motor positions in ticks, joint order.
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// assert_eq!(rig.positions_ticks()?, [0, 0]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn positions_ticks(&mut self) -> Result<Vec<i32>, RigError> {
        let ids = self.actuation.motor_ids();
        self.read_ticks(&ids)
            .map_err(|error| self.stop_on_fault(error))
    }

    /// Present joint values (mm or degrees), joint order.
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut tube1 = tube1;
    /// tube1[1].zero_offset_ticks = -1024; // theta1's motor sits at 0 ticks = +90°
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// assert_eq!(rig.positions()?, [0.0, 90.0]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn positions(&mut self) -> Result<Vec<f64>, RigError> {
        let ticks = self.positions_ticks()?;
        Ok(self.actuation.from_ticks(&ticks)?)
    }

    /// Whether any motor is moving.
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// assert!(!rig.is_moving()?);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn is_moving(&mut self) -> Result<bool, RigError> {
        let ids = self.actuation.motor_ids();
        match self.bus.sync_read(&ids, ct::MOVING, 1) {
            Ok(flags) => Ok(flags.iter().any(|f| f[0] != 0)),
            Err(error) => Err(self.stop_on_fault(error)),
        }
    }

    /// Polls until no motor moves, then returns the joint values; gives up after
    /// `timeout` with [`RigError::StillMoving`].
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig { time_scale: 50.0, ..EmulatorConfig::default() });
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// rig.enable()?;
    /// rig.move_to(&[1.0, 45.0])?;
    /// let values = rig.wait_until_still(std::time::Duration::from_secs(2))?;
    /// assert_eq!(values, [1.0, 45.0]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn wait_until_still(&mut self, timeout: Duration) -> Result<Vec<f64>, RigError> {
        let start = Instant::now();
        loop {
            if !self.is_moving()? {
                return self.positions();
            }
            if start.elapsed() >= timeout {
                return Err(RigError::StillMoving {
                    waited: start.elapsed(),
                });
            }
            std::thread::sleep(self.config.poll_period);
        }
    }

    /// Tells every motor to hold where it is (goal = present position); allowed while
    /// stopped by a fault. Returns the held positions in joint order.
    ///
    /// ```
    /// # use ctr_hw::{actuation::*, bus::*, emulator::*, rig::*};
    /// # let tube1 = vec![
    /// #     ctr_formats::ActuatedJoint::feed(1, 1, 8.0, 0.0, 10.0, 5.0),
    /// #     ctr_formats::ActuatedJoint::rotation(1, 2, -90.0, 90.0, 45.0),
    /// # ];
    /// let emu = Emulator::new(EmulatorConfig::default());
    /// let mut rig = Rig::new(Bus::new(emu.link(), BusConfig::default()), Actuation::new(tube1)?, RigConfig::default());
    /// rig.move_to(&[5.0, 10.0])?; // torque is off, so nothing moves
    /// assert_eq!(rig.hold()?, [0, 0]);
    /// assert_eq!(emu.goal_position(2), Some(0));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn hold(&mut self) -> Result<Vec<i32>, RigError> {
        let ids = self.actuation.motor_ids();
        let mut held = Vec::with_capacity(ids.len());
        for id in ids {
            let present = self.hold_motor(id).map_err(RigError::Bus)?;
            held.push(present);
        }
        Ok(held)
    }

    fn refuse_if_faulted(&self) -> Result<(), RigError> {
        match &self.fault {
            Some(fault) => Err(RigError::Faulted(Box::new(fault.clone()))),
            None => Ok(()),
        }
    }

    fn sync_write<const N: usize>(
        &mut self,
        address: u16,
        entries: &[(u8, [u8; N])],
    ) -> Result<(), BusError> {
        let borrowed: Vec<(u8, &[u8])> = entries.iter().map(|(id, d)| (*id, &d[..])).collect();
        self.bus.sync_write(address, &borrowed).map(|_| ())
    }

    fn read_ticks(&mut self, ids: &[u8]) -> Result<Vec<i32>, BusError> {
        let values = self
            .bus
            .sync_read(ids, ct::PRESENT_POSITION, ct::PRESENT_POSITION_LEN)?;
        Ok(values.iter().map(|v| le_i32(v)).collect())
    }

    /// Writes a register; an alert status still means the write was applied.
    fn write_despite_alert(&mut self, id: u8, address: u16, data: &[u8]) -> Result<(), BusError> {
        match self.bus.write(id, address, data) {
            Err(BusError::Alert { .. }) => Ok(()),
            other => other,
        }
    }

    fn hold_motor(&mut self, id: u8) -> Result<i32, BusError> {
        let present = le_i32(&self.bus.read_despite_alert(
            id,
            ct::PRESENT_POSITION,
            ct::PRESENT_POSITION_LEN,
        )?);
        self.write_despite_alert(id, ct::GOAL_POSITION, &present.to_le_bytes())?;
        Ok(present)
    }

    /// Holds every motor that answers, gathers hardware errors, optionally switches
    /// torque off, records the fault and returns it as an error.
    fn stop_on_fault(&mut self, cause: BusError) -> RigError {
        let mut fault = RigFault::new(cause);
        let ids = self.actuation.motor_ids();
        let mut answering = Vec::with_capacity(ids.len());
        for &id in &ids {
            match self.hold_motor(id) {
                Ok(position) => {
                    fault.held.push((id, position));
                    answering.push(id);
                }
                Err(error) => fault.hold_failures.push((id, error)),
            }
        }
        for &id in &answering {
            if let Ok(status) = self
                .bus
                .read_despite_alert(id, ct::HARDWARE_ERROR_STATUS, 1)
            {
                if status[0] != 0 {
                    fault.hardware_errors.push((id, status[0]));
                }
            }
        }
        if self.config.torque_off_on_fault {
            let mut all_off = fault.hold_failures.is_empty();
            for &id in &answering {
                all_off &= self
                    .write_despite_alert(id, ct::TORQUE_ENABLE, &[0])
                    .is_ok();
            }
            fault.torque_disabled = all_off;
        }
        if self.fault.is_none() {
            self.fault = Some(fault.clone());
        }
        RigError::Fault(Box::new(fault))
    }
}

fn le_i32(bytes: &[u8]) -> i32 {
    let mut b = [0u8; 4];
    for (slot, byte) in b.iter_mut().zip(bytes) {
        *slot = *byte;
    }
    i32::from_le_bytes(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::BusConfig;
    use crate::emulator::testing::{bus, frozen};
    use crate::emulator::{EmulatedLink, Emulator, Fault};
    use crate::protocol::instruction;
    use crate::test_rigs::two_tubes;

    /// Feeds at 10 mm/s, rotations at 90 degrees/s.
    fn four_joints() -> Actuation {
        Actuation::new(two_tubes(10.0, 90.0)).unwrap()
    }

    fn rig(emu: &Emulator, config: RigConfig) -> Rig<EmulatedLink> {
        Rig::new(bus(emu), four_joints(), config)
    }

    fn goal_writes(emu: &Emulator) -> usize {
        emu.write_log()
            .iter()
            .filter(|w| w.address == ct::GOAL_POSITION)
            .count()
    }

    #[test]
    fn enable_sets_profiles_holds_and_turns_torque_on() {
        let emu = frozen();
        let mut rig = rig(&emu, RigConfig::default());
        rig.enable().unwrap();
        for id in 1..=4 {
            assert_eq!(emu.torque_enabled(id), Some(true));
        }
        // theta: 90 deg/s = 15 rpm → 65; s: 10 mm/s = 75 rpm → 327.
        assert_eq!(
            emu.table(2, ct::PROFILE_VELOCITY, 4),
            Some(vec![65, 0, 0, 0])
        );
        assert_eq!(
            emu.table(1, ct::PROFILE_VELOCITY, 4),
            Some(327u32.to_le_bytes().to_vec())
        );
    }

    #[test]
    fn limit_violation_sends_nothing() {
        let emu = frozen();
        let mut rig = rig(&emu, RigConfig::default());
        let before = rig.bus().stats().packets_sent;
        let err = rig.move_to(&[0.0, 0.0, 0.0, 200.0]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "joint theta2: 200 deg is above its max limit 180 deg"
        );
        assert_eq!(rig.bus().stats().packets_sent, before);
        assert!(emu.write_log().is_empty());
        assert!(rig.fault().is_none());
    }

    #[test]
    fn limit_violation_sends_nothing_on_a_mock_bus() {
        use crate::transport::MockTransport;
        let bus = Bus::new(MockTransport::new(), BusConfig::default());
        let mut rig = Rig::new(bus, four_joints(), RigConfig::default());
        assert!(matches!(
            rig.move_to(&[0.1, 0.0, 0.0, 0.0]),
            Err(RigError::Actuation(_))
        ));
        assert!(matches!(
            rig.move_joint("s2", -31.0),
            Err(RigError::Actuation(_))
        ));
        assert!(matches!(
            rig.move_to(&[0.0; 3]),
            Err(RigError::Actuation(ActuationError::CountMismatch { .. }))
        ));
        assert!(rig.bus().transport().written().is_empty());
    }

    #[test]
    fn each_goal_is_applied_exactly_once_even_when_the_broadcast_is_lost() {
        let emu = frozen();
        let mut rig = rig(&emu, RigConfig::default());
        emu.inject(None, Fault::DropInstruction);
        rig.move_to(&[-1.0, 10.0, -2.0, 20.0]).unwrap();
        // The sync write was lost; the read-back found every goal missing and each was
        // written once by unicast.
        assert_eq!(goal_writes(&emu), 4);
        assert!(emu
            .write_log()
            .iter()
            .all(|w| w.instruction == instruction::WRITE));
        assert_eq!(rig.bus().stats().sync_write_repairs, 4);
        rig.move_to(&[-1.0, 11.0, -2.0, 20.0]).unwrap();
        assert_eq!(goal_writes(&emu), 8);
    }

    #[test]
    fn timeouts_stop_the_rig_and_hold() {
        let emu = frozen();
        let mut rig = rig(
            &emu,
            RigConfig {
                torque_off_on_fault: true,
                ..RigConfig::default()
            },
        );
        rig.enable().unwrap();
        for _ in 0..3 {
            emu.inject(Some(2), Fault::NoReply);
        }
        let err = rig.positions().unwrap_err();
        let RigError::Fault(fault) = err else {
            panic!("unexpected {err:?}")
        };
        assert!(matches!(
            fault.cause,
            BusError::Timeout {
                id: 2,
                attempts: 3,
                ..
            }
        ));
        assert_eq!(fault.held.len(), 4);
        assert!(fault.torque_disabled);
        assert_eq!(emu.torque_enabled(1), Some(false));
        // Moves are refused until the fault is cleared; nothing is sent meanwhile.
        let sent = rig.bus().stats().packets_sent;
        assert!(matches!(rig.move_to(&[0.0; 4]), Err(RigError::Faulted(_))));
        assert_eq!(rig.bus().stats().packets_sent, sent);
        assert!(rig.clear_fault().is_some());
        rig.enable().unwrap();
        rig.move_to(&[0.0, 1.0, 0.0, 0.0]).unwrap();
    }

    #[test]
    fn fault_message_names_motor_packet_and_error() {
        let emu = frozen();
        let mut rig = rig(&emu, RigConfig::default());
        rig.enable().unwrap();
        emu.inject(Some(3), Fault::Overload);
        let err = rig.move_to(&[-1.0, 0.0, 0.0, 0.0]).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("ID 3 raised a hardware alert"), "{text}");
        assert!(
            text.contains("SYNC_READ (broadcast) [FF FF FD 00 FE"),
            "{text}"
        );
        assert!(
            text.contains("ID 3 hardware error 0x20 (overload)"),
            "{text}"
        );
        // The healthy motors hold where they are.
        let RigError::Fault(fault) = err else {
            panic!()
        };
        assert_eq!(fault.held.len(), 4);
    }
}

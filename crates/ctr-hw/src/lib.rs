//! Serial link to the servo controller of the concentric-tube-robot rig, speaking
//! Dynamixel Protocol 2.0.
//!
//! Layers, bottom up:
//!
//! * [`transport`]: bytes over a serial port ([`transport::SerialTransport`]) or a scripted
//!   mock ([`transport::MockTransport`]);
//! * [`protocol`]: pure framing functions (CRC, byte stuffing, packets);
//! * [`bus`]: ping, read, write, sync read and sync write with bounded, idempotent retries;
//! * [`actuation`]: joint vectors (mm, degrees) to motor ticks and back, with limit
//!   checks, for the joints of a robot file's `[actuation]` (`ctr_formats::ActuatedJoint`:
//!   `s1`, `theta1`, ...);
//! * [`rig`]: moves joints, reads them back and stops on faults;
//! * [`emulator`]: an in-process bus (four motors by default, any IDs) with fault
//!   injection, for tests and for `ctr-cli hw emulate`;
//! * [`control_table`]: the X-series control table's addresses, sizes and units that the
//!   rig and the emulator share.
//!
//! `ctr-cli hw` (`ping`, `home`, `move`, `run`, `emulate`) drives a robot file's
//! `[actuation]` through these layers; `run` writes the contract's recording row by row
//! into a journal (`ctr_formats::RecordingWriter`), so a stopped or killed run keeps
//! every completed row.
//!
//! ```
//! use ctr_hw::emulator::{Emulator, EmulatorConfig};
//! use ctr_hw::bus::{Bus, BusConfig};
//! use ctr_hw::transport::SerialTransport;
//!
//! let pty = Emulator::new(EmulatorConfig::default()).serve_pty()?;
//! let link = SerialTransport::open(pty.path(), 1_000_000)?;
//! let mut bus = Bus::new(link, BusConfig::default());
//! assert_eq!(bus.ping(1)?.model, ctr_hw::control_table::MODEL_XM430_W350);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod actuation;
pub mod bus;
pub mod control_table;
pub mod emulator;
pub mod protocol;
pub mod rig;
pub mod transport;

/// The rig set-up shared with the integration tests.
#[cfg(test)]
#[path = "../tests/common/mod.rs"]
mod test_rigs;

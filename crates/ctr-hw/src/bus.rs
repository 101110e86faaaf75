//! Request/response exchanges on a Dynamixel bus, generic over the [`Transport`].
//!
//! # Retry rule (idempotency)
//!
//! A packet is sent again only when there is evidence that the earlier copy was **not**
//! applied, and at most [`BusConfig::max_attempts`] copies of it are ever sent:
//!
//! * **Ping, read, sync read** have no side effects. They are resent when the reply times
//!   out, fails its CRC or has the wrong length.
//! * **Write**: when a valid status comes back the write is never resent, whatever the
//!   status says (an error code means "not applied", and the error is returned; a status
//!   without error code means "applied"). When no valid status comes back, the written
//!   register is read back first (a read, itself retried as above):
//!   * it already holds the written bytes: the write was applied, its status got lost;
//!     success, nothing is resent;
//!   * it does not, and *nothing at all* came back: the write was lost on its way; it is
//!     resent;
//!   * it does not, and *something* came back (a corrupt or truncated status): the device
//!     heard the write and did not apply it; the error is returned, nothing is resent;
//!   * the read-back fails: [`BusError::Unconfirmed`], nothing is resent.
//! * **Sync write** is a broadcast: devices never answer it. [`Bus::sync_write`] sends it
//!   once, reads the written range back from every device (sync read, falling back to
//!   one read per device) and, for each device whose register does not hold its bytes,
//!   sends the same data as a unicast write under the write rule above. A device whose
//!   register already holds its bytes is never written again, so no command is applied
//!   twice and none is dropped silently.
//!
//! Before each packet the input is discarded (stale replies, noise). While waiting for a
//! status, frames that are not a status from the addressed ID (an adapter's echo, a late
//! reply to an earlier packet) are skipped.
//!
//! The read-back rule assumes that the written register reads back what was written,
//! which holds for the control-table entries this crate writes (torque enable, goal
//! position, profile velocity and acceleration).
//!
//! ```
//! use ctr_hw::bus::{Bus, BusConfig};
//! use ctr_hw::protocol::{StatusPacket, StatusError};
//! use ctr_hw::transport::MockTransport;
//!
//! let mut link = MockTransport::new();
//! link.push_silence(); // the first read gets no answer...
//! link.push_reply(StatusPacket::new(1, StatusError::OK, 2048i32.to_le_bytes().to_vec()).encode()?);
//! let mut bus = Bus::new(link, BusConfig::default());
//! assert_eq!(bus.read(1, 132, 4)?, 2048i32.to_le_bytes()); // ...so it is sent again
//! assert_eq!(bus.transport().written().len(), 2);
//! assert_eq!(bus.stats().retries, 1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt;
use std::time::{Duration, Instant};

use crate::protocol::{
    hex, instruction, Decoder, Packet, ProtocolError, StatusError, StatusPacket, BROADCAST_ID,
    MAX_DEVICE_ID,
};
use crate::transport::{Transport, TransportError};

/// Timing and retry settings of a [`Bus`].
///
/// ```
/// use ctr_hw::bus::BusConfig;
/// use std::time::Duration;
/// let fast = BusConfig { response_timeout: Duration::from_millis(30), ..BusConfig::default() };
/// assert_eq!(fast.max_attempts, 3);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BusConfig {
    /// How long to wait for each status packet, counted from the end of the write; it
    /// must cover the device's return delay and the transmission time of the reply.
    pub response_timeout: Duration,
    /// The most copies of one packet ever sent (1 means no retry).
    pub max_attempts: u32,
}

impl Default for BusConfig {
    fn default() -> Self {
        Self {
            response_timeout: Duration::from_millis(100),
            max_attempts: 3,
        }
    }
}

/// A packet as sent, for error reports: its target, instruction and bytes.
///
/// ```
/// use ctr_hw::bus::Request;
/// use ctr_hw::protocol::Packet;
/// let r = Request::from_packet(&Packet::ping(1)).unwrap();
/// assert_eq!(r.to_string(), "PING to ID 1 [FF FF FD 00 01 03 00 01 19 4E]");
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    /// The addressed ID ([`BROADCAST_ID`] for sync instructions).
    pub id: u8,
    /// The instruction code.
    pub instruction: u8,
    /// The encoded packet.
    pub bytes: Vec<u8>,
}

impl Request {
    /// Encodes a packet into a request.
    ///
    /// ```
    /// use ctr_hw::bus::Request;
    /// use ctr_hw::protocol::Packet;
    /// assert!(Request::from_packet(&Packet::ping(0xFF)).is_err());
    /// ```
    pub fn from_packet(packet: &Packet) -> Result<Self, ProtocolError> {
        Ok(Self {
            id: packet.id,
            instruction: packet.instruction,
            bytes: packet.encode()?,
        })
    }
}

impl fmt::Display for Request {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = instruction::name(self.instruction);
        if self.id == BROADCAST_ID {
            write!(f, "{name} (broadcast) [{}]", hex(&self.bytes))
        } else {
            write!(f, "{name} to ID {} [{}]", self.id, hex(&self.bytes))
        }
    }
}

/// What went wrong on the bus. Every variant that involves a packet names the request
/// ([`Request`]: instruction, ID and bytes) and carries the raw bytes received.
///
/// ```
/// use ctr_hw::bus::{Bus, BusConfig, BusError};
/// use ctr_hw::transport::MockTransport;
/// let mut bus = Bus::new(MockTransport::new(), BusConfig::default());
/// let err = bus.ping(3).unwrap_err();
/// assert!(matches!(err, BusError::Timeout { id: 3, attempts: 3, .. }));
/// assert_eq!(err.id(), Some(3));
/// ```
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BusError {
    /// The request makes no sense (broadcast unicast write, duplicate IDs, ...); nothing
    /// was sent.
    #[error("invalid request: {reason}")]
    InvalidRequest {
        /// Why.
        reason: String,
    },
    /// The packet could not be encoded; nothing was sent.
    #[error("cannot encode packet: {0}")]
    Encode(#[from] ProtocolError),
    /// The link failed (not a timeout).
    #[error("transport failed during {request}: {source}")]
    Transport {
        /// The packet being exchanged.
        request: Request,
        /// The transport's error.
        source: TransportError,
    },
    /// No complete status came back in time, after every allowed attempt.
    #[error("no status from ID {id} for {request} after {attempts} attempt(s); received [{}]", hex(.received))]
    Timeout {
        /// The ID expected to answer.
        id: u8,
        /// The packet sent.
        request: Request,
        /// How many copies were sent.
        attempts: u32,
        /// The bytes received during the last wait (partial frames, skipped frames).
        received: Vec<u8>,
    },
    /// A frame came back but is unusable (CRC mismatch, bad length, not a status).
    #[error("corrupt reply from ID {id} to {request} after {attempts} attempt(s): {error}; received [{}]", hex(.received))]
    Corrupt {
        /// The ID expected to answer.
        id: u8,
        /// The packet sent.
        request: Request,
        /// How many copies were sent.
        attempts: u32,
        /// What is wrong with the frame.
        error: ProtocolError,
        /// The bytes received during the last wait, the bad frame included.
        received: Vec<u8>,
    },
    /// A valid status without error carries the wrong number of data bytes.
    #[error("status from ID {id} to {request} has {got} data bytes, expected {expected}; status [{}]", hex(.status))]
    UnexpectedLength {
        /// The ID that answered.
        id: u8,
        /// The packet sent.
        request: Request,
        /// How many copies were sent.
        attempts: u32,
        /// Expected data length.
        expected: usize,
        /// Received data length.
        got: usize,
        /// The status packet as received.
        status: Vec<u8>,
    },
    /// The device answered with an error code: the instruction was not processed.
    #[error("ID {id} answered {request} with {error}; status [{}]", hex(.status))]
    Device {
        /// The ID that answered.
        id: u8,
        /// The packet sent.
        request: Request,
        /// The error byte.
        error: StatusError,
        /// The status packet as received.
        status: Vec<u8>,
    },
    /// The device processed the instruction but raised its hardware alert (overload,
    /// overheating, ...; read the hardware error status for details). `params` holds the
    /// data it returned.
    #[error("ID {id} raised a hardware alert answering {request}; status [{}]", hex(.status))]
    Alert {
        /// The ID that answered.
        id: u8,
        /// The packet sent.
        request: Request,
        /// The status packet as received.
        status: Vec<u8>,
        /// The data returned with the alert.
        params: Vec<u8>,
    },
    /// A write got no valid status and reading its register back failed too: it may or
    /// may not have been applied, and it was not resent.
    #[error("write {request} to ID {id} unconfirmed after {attempts} attempt(s): {source}")]
    Unconfirmed {
        /// The written ID.
        id: u8,
        /// The write packet.
        request: Request,
        /// How many copies of the write were sent.
        attempts: u32,
        /// Why the read-back failed.
        source: Box<BusError>,
    },
}

impl BusError {
    /// The device ID the error is about, if any.
    ///
    /// ```
    /// use ctr_hw::bus::BusError;
    /// assert_eq!(BusError::InvalidRequest { reason: "x".into() }.id(), None);
    /// ```
    pub fn id(&self) -> Option<u8> {
        match self {
            Self::InvalidRequest { .. } | Self::Encode(_) => None,
            Self::Transport { request, .. } => Some(request.id),
            Self::Timeout { id, .. }
            | Self::Corrupt { id, .. }
            | Self::UnexpectedLength { id, .. }
            | Self::Device { id, .. }
            | Self::Alert { id, .. }
            | Self::Unconfirmed { id, .. } => Some(*id),
        }
    }

    /// The packet whose exchange failed, if one was sent.
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::transport::MockTransport;
    /// let mut bus = Bus::new(MockTransport::new(), BusConfig::default());
    /// let err = bus.read(2, 132, 4).unwrap_err();
    /// assert_eq!(err.request().unwrap().instruction, ctr_hw::protocol::instruction::READ);
    /// ```
    pub fn request(&self) -> Option<&Request> {
        match self {
            Self::InvalidRequest { .. } | Self::Encode(_) => None,
            Self::Transport { request, .. }
            | Self::Timeout { request, .. }
            | Self::Corrupt { request, .. }
            | Self::UnexpectedLength { request, .. }
            | Self::Device { request, .. }
            | Self::Alert { request, .. }
            | Self::Unconfirmed { request, .. } => Some(request),
        }
    }

    /// The raw bytes received that this error is about (empty if none).
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::transport::MockTransport;
    /// let mut bus = Bus::new(MockTransport::new(), BusConfig::default());
    /// assert!(bus.ping(1).unwrap_err().received().is_empty());
    /// ```
    pub fn received(&self) -> &[u8] {
        match self {
            Self::Timeout { received, .. } | Self::Corrupt { received, .. } => received,
            Self::UnexpectedLength { status, .. }
            | Self::Device { status, .. }
            | Self::Alert { status, .. } => status,
            Self::Unconfirmed { source, .. } => source.received(),
            Self::InvalidRequest { .. } | Self::Encode(_) | Self::Transport { .. } => &[],
        }
    }
}

/// What a device says about itself when pinged.
///
/// ```
/// use ctr_hw::bus::PingReply;
/// let p = PingReply { id: 1, model: 1020, firmware: 45 };
/// assert_eq!(p.model, 1020);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PingReply {
    /// The device ID.
    pub id: u8,
    /// Its model number (1020 for an XM430-W350).
    pub model: u16,
    /// Its firmware version.
    pub firmware: u8,
}

/// What [`Bus::sync_write`] had to do beyond the broadcast.
///
/// ```
/// let r = ctr_hw::bus::SyncWriteReport::default();
/// assert!(r.resent.is_empty());
/// ```
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SyncWriteReport {
    /// IDs whose register did not hold their data after the broadcast and which were
    /// written again by unicast.
    pub resent: Vec<u8>,
}

/// Counters of a [`Bus`].
///
/// ```
/// let s = ctr_hw::bus::BusStats::default();
/// assert_eq!(s.packets_sent, 0);
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BusStats {
    /// Packets written to the transport.
    pub packets_sent: u64,
    /// Packets sent again because an earlier copy failed (reads, and writes known lost).
    pub retries: u64,
    /// Writes whose status was lost but whose register read back as written.
    pub confirmed_by_read_back: u64,
    /// Sync-write entries written again by unicast after the read-back showed them
    /// missing.
    pub sync_write_repairs: u64,
}

/// Why one wait for a status failed (internal).
enum Failure {
    Timeout {
        received: Vec<u8>,
    },
    Corrupt {
        error: ProtocolError,
        received: Vec<u8>,
    },
    Length {
        expected: usize,
        got: usize,
        status: Vec<u8>,
    },
    Transport(TransportError),
}

impl Failure {
    fn into_error(self, id: u8, request: &Request, attempts: u32) -> BusError {
        let request = request.clone();
        match self {
            Self::Timeout { received } => BusError::Timeout {
                id,
                request,
                attempts,
                received,
            },
            Self::Corrupt { error, received } => BusError::Corrupt {
                id,
                request,
                attempts,
                error,
                received,
            },
            Self::Length {
                expected,
                got,
                status,
            } => BusError::UnexpectedLength {
                id,
                request,
                attempts,
                expected,
                got,
                status,
            },
            Self::Transport(source) => BusError::Transport { request, source },
        }
    }

    fn nothing_came_back(&self) -> bool {
        matches!(self, Self::Timeout { received } if received.is_empty())
    }
}

/// The verdict on a received status (internal).
enum Verdict {
    /// Data of a successful status.
    Ok(Vec<u8>),
    /// An error that must not lead to a retry.
    Final(BusError),
    /// A failure that allows a retry of a side-effect-free packet.
    Retryable(Failure),
}

/// A Dynamixel Protocol 2.0 master over a [`Transport`].
///
/// ```
/// use ctr_hw::bus::{Bus, BusConfig};
/// use ctr_hw::protocol::{StatusPacket, StatusError};
/// use ctr_hw::transport::MockTransport;
///
/// let mut link = MockTransport::new();
/// link.push_reply(StatusPacket::new(1, StatusError::OK, vec![]).encode()?);
/// let mut bus = Bus::new(link, BusConfig::default());
/// bus.write(1, 64, &[1])?; // torque on
/// assert_eq!(bus.transport().written().len(), 1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Bus<T: Transport> {
    transport: T,
    config: BusConfig,
    decoder: Decoder,
    stats: BusStats,
}

impl<T: Transport> Bus<T> {
    /// A bus over `transport`; `config.max_attempts` of 0 is taken as 1.
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// assert_eq!(bus.config().max_attempts, 3);
    /// ```
    pub fn new(transport: T, mut config: BusConfig) -> Self {
        config.max_attempts = config.max_attempts.max(1);
        Self {
            transport,
            config,
            decoder: Decoder::new(),
            stats: BusStats::default(),
        }
    }

    /// The settings in use.
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let cfg = BusConfig { max_attempts: 0, ..BusConfig::default() };
    /// assert_eq!(Bus::new(ctr_hw::transport::MockTransport::new(), cfg).config().max_attempts, 1);
    /// ```
    pub fn config(&self) -> &BusConfig {
        &self.config
    }

    /// Counters since creation.
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let mut bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let _ = bus.ping(1);
    /// assert_eq!(bus.stats().packets_sent, 3);
    /// ```
    pub fn stats(&self) -> BusStats {
        self.stats
    }

    /// The transport.
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// assert!(bus.transport().written().is_empty());
    /// ```
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The transport, mutably (e.g. to script more mock replies).
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let mut bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// bus.transport_mut().push_silence();
    /// ```
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// Gives the transport back.
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// let link = bus.into_transport();
    /// ```
    pub fn into_transport(self) -> T {
        self.transport
    }

    /// Pings one device (retried on failure).
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::protocol::{StatusPacket, StatusError};
    /// use ctr_hw::transport::MockTransport;
    /// let mut link = MockTransport::new();
    /// link.push_reply(StatusPacket::new(1, StatusError::OK, vec![0x06, 0x04, 0x26]).encode()?);
    /// let reply = Bus::new(link, BusConfig::default()).ping(1)?;
    /// assert_eq!((reply.model, reply.firmware), (1030, 0x26));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn ping(&mut self, id: u8) -> Result<PingReply, BusError> {
        check_unicast(id, "PING")?;
        let request = Request::from_packet(&Packet::ping(id))?;
        let params = self.query(&request, id, 3)?;
        Ok(PingReply {
            id,
            model: u16::from_le_bytes([params[0], params[1]]),
            firmware: params[2],
        })
    }

    /// Reads `length` bytes at `address` of device `id` (retried on failure).
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::protocol::{StatusPacket, StatusError};
    /// use ctr_hw::transport::MockTransport;
    /// let mut link = MockTransport::new();
    /// link.push_reply(StatusPacket::new(1, StatusError::OK, vec![1]).encode()?);
    /// assert_eq!(Bus::new(link, BusConfig::default()).read(1, 64, 1)?, [1]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn read(&mut self, id: u8, address: u16, length: u16) -> Result<Vec<u8>, BusError> {
        check_unicast(id, "READ")?;
        let request = Request::from_packet(&Packet::read(id, address, length))?;
        self.query(&request, id, usize::from(length))
    }

    /// Writes `data` at `address` of device `id`, under the write rule of the module
    /// documentation (resent only when known not applied).
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::protocol::{StatusPacket, StatusError};
    /// use ctr_hw::transport::MockTransport;
    /// let mut link = MockTransport::new();
    /// link.push_silence(); // the write's status is lost...
    /// // ...and the read-back shows the goal already holds 1000: not resent.
    /// link.push_reply(StatusPacket::new(1, StatusError::OK, 1000i32.to_le_bytes().to_vec()).encode()?);
    /// let mut bus = Bus::new(link, BusConfig::default());
    /// bus.write(1, 116, &1000i32.to_le_bytes())?;
    /// assert_eq!(bus.transport().written().len(), 2); // write + read-back
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn write(&mut self, id: u8, address: u16, data: &[u8]) -> Result<(), BusError> {
        check_unicast(id, "WRITE")?;
        let length =
            u16::try_from(data.len()).map_err(|_| ProtocolError::TooLong { length: data.len() })?;
        let request = Request::from_packet(&Packet::write(id, address, data))?;
        let mut attempts = 0;
        loop {
            attempts += 1;
            self.send(&request)?;
            let failure = match self.receive_status(id) {
                Ok((status, raw)) => match self.verdict(&request, status, raw, 0) {
                    Verdict::Ok(_) => return Ok(()),
                    Verdict::Final(error) => return Err(error),
                    Verdict::Retryable(failure) => failure,
                },
                Err(failure) => failure,
            };
            if let Failure::Transport(source) = failure {
                return Err(BusError::Transport { request, source });
            }
            // No valid status: was the write applied? Ask before deciding anything.
            let current = match self.read_back(id, address, length) {
                Ok(current) => current,
                Err(source) => {
                    return Err(BusError::Unconfirmed {
                        id,
                        request,
                        attempts,
                        source: Box::new(source),
                    })
                }
            };
            if current == data {
                self.stats.confirmed_by_read_back += 1;
                return Ok(());
            }
            if failure.nothing_came_back() && attempts < self.config.max_attempts {
                self.stats.retries += 1;
                continue;
            }
            return Err(failure.into_error(id, &request, attempts));
        }
    }

    /// Reads `length` bytes at `address` from each of `ids` with one sync read; the
    /// results come in the order of `ids`. The whole exchange is retried on failure.
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::protocol::{StatusPacket, StatusError};
    /// use ctr_hw::transport::MockTransport;
    /// let mut replies = StatusPacket::new(1, StatusError::OK, vec![0]).encode()?;
    /// replies.extend(StatusPacket::new(2, StatusError::OK, vec![1]).encode()?);
    /// let mut link = MockTransport::new();
    /// link.push_reply(replies);
    /// let values = Bus::new(link, BusConfig::default()).sync_read(&[1, 2], 122, 1)?;
    /// assert_eq!(values, [vec![0], vec![1]]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn sync_read(
        &mut self,
        ids: &[u8],
        address: u16,
        length: u16,
    ) -> Result<Vec<Vec<u8>>, BusError> {
        check_id_list(ids)?;
        if ids.is_empty() {
            return Ok(Vec::new());
        }
        let request = Request::from_packet(&Packet::sync_read(address, length, ids))?;
        let mut attempts = 0;
        'attempt: loop {
            attempts += 1;
            self.send(&request)?;
            let mut values = Vec::with_capacity(ids.len());
            for &id in ids {
                let failure = match self.receive_status(id) {
                    Ok((status, raw)) => {
                        match self.verdict(&request, status, raw, usize::from(length)) {
                            Verdict::Ok(data) => {
                                values.push(data);
                                continue;
                            }
                            Verdict::Final(error) => return Err(error),
                            Verdict::Retryable(failure) => failure,
                        }
                    }
                    Err(failure) => failure,
                };
                if matches!(failure, Failure::Transport(_)) || attempts >= self.config.max_attempts
                {
                    return Err(failure.into_error(id, &request, attempts));
                }
                self.stats.retries += 1;
                continue 'attempt;
            }
            return Ok(values);
        }
    }

    /// Writes `(id, data)` entries at `address` with one broadcast sync write, then
    /// verifies every entry by reading it back and rewrites (by unicast) only the entries
    /// that are missing; see the module documentation. Every entry must have the same
    /// length.
    ///
    /// Errors: the first failure among the repairs and read-backs, or the hardware alert
    /// seen during the read-back (after every entry was dealt with).
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::protocol::{StatusPacket, StatusError};
    /// use ctr_hw::transport::MockTransport;
    /// let mut link = MockTransport::new();
    /// link.push_silence(); // nobody answers a sync write
    /// let mut readback = StatusPacket::new(1, StatusError::OK, vec![1]).encode()?;
    /// readback.extend(StatusPacket::new(2, StatusError::OK, vec![1]).encode()?);
    /// link.push_reply(readback);
    /// let mut bus = Bus::new(link, BusConfig::default());
    /// let report = bus.sync_write(64, &[(1, &[1][..]), (2, &[1][..])])?;
    /// assert!(report.resent.is_empty());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn sync_write(
        &mut self,
        address: u16,
        entries: &[(u8, &[u8])],
    ) -> Result<SyncWriteReport, BusError> {
        let Some(request) = Self::sync_write_request(address, entries)? else {
            return Ok(SyncWriteReport::default());
        };
        self.send(&request)?;
        let mut report = SyncWriteReport::default();
        let length = entries[0].1.len() as u16; // checked by the encoder
        let ids: Vec<u8> = entries.iter().map(|&(id, _)| id).collect();
        let mut alert = None;
        let current: Vec<Result<Vec<u8>, BusError>> = match self.sync_read(&ids, address, length) {
            Ok(values) => values.into_iter().map(Ok).collect(),
            Err(error) => {
                // One device's alert or silence must not hide the others: ask one by one.
                if matches!(error, BusError::Alert { .. } | BusError::Device { .. }) {
                    alert = Some(error);
                }
                ids.iter()
                    .map(|&id| self.read_back(id, address, length))
                    .collect()
            }
        };
        let mut first_error = None;
        for (&(id, data), current) in entries.iter().zip(current) {
            match current {
                Ok(current) if current == data => {}
                Ok(_) => {
                    report.resent.push(id);
                    self.stats.sync_write_repairs += 1;
                    if let Err(error) = self.write(id, address, data) {
                        first_error.get_or_insert(error);
                    }
                }
                Err(source) => {
                    first_error.get_or_insert(BusError::Unconfirmed {
                        id,
                        request: request.clone(),
                        attempts: 1,
                        source: Box::new(source),
                    });
                }
            }
        }
        match first_error.or(alert) {
            Some(error) => Err(error),
            None => Ok(report),
        }
    }

    /// Sends one sync write and nothing else: no device answers, so nothing is known
    /// about its effect. Prefer [`Bus::sync_write`].
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// let mut bus = Bus::new(ctr_hw::transport::MockTransport::new(), BusConfig::default());
    /// bus.sync_write_unverified(116, &[(1, &[0, 8, 0, 0][..])]).unwrap();
    /// assert_eq!(bus.transport().written().len(), 1);
    /// ```
    pub fn sync_write_unverified(
        &mut self,
        address: u16,
        entries: &[(u8, &[u8])],
    ) -> Result<(), BusError> {
        match Self::sync_write_request(address, entries)? {
            Some(request) => self.send(&request),
            None => Ok(()),
        }
    }

    fn sync_write_request(
        address: u16,
        entries: &[(u8, &[u8])],
    ) -> Result<Option<Request>, BusError> {
        let ids: Vec<u8> = entries.iter().map(|&(id, _)| id).collect();
        check_id_list(&ids)?;
        if entries.is_empty() {
            return Ok(None);
        }
        Ok(Some(Request::from_packet(&Packet::sync_write(
            address, entries,
        )?)?))
    }

    /// A read used to settle whether a write was applied: an alert status still carries
    /// the register's value.
    fn read_back(&mut self, id: u8, address: u16, length: u16) -> Result<Vec<u8>, BusError> {
        match self.read(id, address, length) {
            Err(BusError::Alert { params, .. }) => Ok(params),
            other => other,
        }
    }

    /// Sends a side-effect-free request and waits for the status of `id`, retrying.
    fn query(&mut self, request: &Request, id: u8, expected: usize) -> Result<Vec<u8>, BusError> {
        let mut attempts = 0;
        loop {
            attempts += 1;
            self.send(request)?;
            let failure = match self.receive_status(id) {
                Ok((status, raw)) => match self.verdict(request, status, raw, expected) {
                    Verdict::Ok(data) => return Ok(data),
                    Verdict::Final(error) => return Err(error),
                    Verdict::Retryable(failure) => failure,
                },
                Err(failure) => failure,
            };
            if matches!(failure, Failure::Transport(_)) || attempts >= self.config.max_attempts {
                return Err(failure.into_error(id, request, attempts));
            }
            self.stats.retries += 1;
        }
    }

    fn verdict(
        &self,
        request: &Request,
        status: StatusPacket,
        raw: Vec<u8>,
        expected: usize,
    ) -> Verdict {
        let id = status.id;
        if status.error.code().is_some() {
            return Verdict::Final(BusError::Device {
                id,
                request: request.clone(),
                error: status.error,
                status: raw,
            });
        }
        if status.params.len() != expected {
            return Verdict::Retryable(Failure::Length {
                expected,
                got: status.params.len(),
                status: raw,
            });
        }
        if status.error.alert() {
            return Verdict::Final(BusError::Alert {
                id,
                request: request.clone(),
                status: raw,
                params: status.params,
            });
        }
        Verdict::Ok(status.params)
    }

    fn send(&mut self, request: &Request) -> Result<(), BusError> {
        let transport_error = |source| BusError::Transport {
            request: request.clone(),
            source,
        };
        self.decoder.clear();
        self.transport.discard_input().map_err(transport_error)?;
        self.transport
            .write_all(&request.bytes)
            .map_err(transport_error)?;
        self.stats.packets_sent += 1;
        Ok(())
    }

    /// Waits for one status packet from `id`, skipping other frames.
    fn receive_status(&mut self, id: u8) -> Result<(StatusPacket, Vec<u8>), Failure> {
        let deadline = Instant::now() + self.config.response_timeout;
        let mut received = Vec::new();
        let mut buf = [0u8; 256];
        loop {
            while let Some(frame) = self.decoder.next_frame() {
                let packet = match frame.result {
                    Ok(packet) => packet,
                    Err(error) => return Err(Failure::Corrupt { error, received }),
                };
                if packet.instruction != instruction::STATUS || packet.id != id {
                    continue; // an echo of our own packet, or a late reply to an earlier one
                }
                return match StatusPacket::from_packet(packet) {
                    Ok(status) => Ok((status, frame.raw)),
                    Err(error) => Err(Failure::Corrupt { error, received }),
                };
            }
            match self.transport.read(&mut buf, deadline) {
                Ok(n) => {
                    received.extend_from_slice(&buf[..n]);
                    self.decoder.push(&buf[..n]);
                }
                Err(error) if self.transport.is_timeout(&error) => {
                    return Err(Failure::Timeout { received })
                }
                Err(error) => return Err(Failure::Transport(error)),
            }
        }
    }
}

fn check_unicast(id: u8, what: &str) -> Result<(), BusError> {
    if id > MAX_DEVICE_ID {
        return Err(BusError::InvalidRequest {
            reason: format!("{what} needs a device ID (0..=252), got {id}"),
        });
    }
    Ok(())
}

fn check_id_list(ids: &[u8]) -> Result<(), BusError> {
    for (i, &id) in ids.iter().enumerate() {
        check_unicast(id, "a sync instruction")?;
        if ids[..i].contains(&id) {
            return Err(BusError::InvalidRequest {
                reason: format!("ID {id} appears twice"),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::ErrorCode;
    use crate::transport::MockTransport;

    fn status(id: u8, error: u8, params: &[u8]) -> Vec<u8> {
        StatusPacket::new(id, StatusError(error), params.to_vec())
            .encode()
            .unwrap()
    }

    fn bus(link: MockTransport) -> Bus<MockTransport> {
        Bus::new(link, BusConfig::default())
    }

    fn instructions(bus: &Bus<MockTransport>) -> Vec<u8> {
        bus.transport().written().iter().map(|w| w[7]).collect()
    }

    const W: u8 = instruction::WRITE;
    const R: u8 = instruction::READ;

    #[test]
    fn ping_reads_model_and_firmware() {
        let mut link = MockTransport::new();
        link.push_reply(status(1, 0, &[0xFC, 0x03, 0x2D]));
        let reply = bus(link).ping(1).unwrap();
        assert_eq!(
            reply,
            PingReply {
                id: 1,
                model: 1020,
                firmware: 45
            }
        );
    }

    #[test]
    fn read_survives_garbage_and_one_byte_reads() {
        let mut reply = vec![0x00, 0xFF, 0x13];
        reply.extend(status(2, 0, &[1, 2, 3, 4]));
        let mut link = MockTransport::new().with_chunk_size(1);
        link.push_reply(reply);
        let mut bus = bus(link);
        assert_eq!(bus.read(2, 132, 4).unwrap(), [1, 2, 3, 4]);
        assert_eq!(bus.stats().retries, 0);
    }

    #[test]
    fn read_skips_echo_and_stale_statuses() {
        let mut reply = Packet::read(2, 132, 4).encode().unwrap(); // adapter echo
        reply.extend(status(3, 0, &[9, 9, 9, 9])); // late reply of another ID
        reply.extend(status(2, 0, &[1, 2, 3, 4]));
        let mut link = MockTransport::new();
        link.push_reply(reply);
        assert_eq!(bus(link).read(2, 132, 4).unwrap(), [1, 2, 3, 4]);
    }

    #[test]
    fn read_retries_timeouts_and_bad_crc_and_stops_after_max_attempts() {
        let mut bad = status(1, 0, &[5, 0, 0, 0]);
        *bad.last_mut().unwrap() ^= 0xFF;
        let mut link = MockTransport::new();
        link.push_silence().push_reply(bad.clone()).push_silence();
        let mut bus = bus(link);
        let err = bus.read(1, 132, 4).unwrap_err();
        match &err {
            BusError::Timeout {
                id: 1,
                attempts: 3,
                received,
                ..
            } => assert!(received.is_empty()),
            other => panic!("unexpected {other:?}"),
        }
        assert_eq!(bus.transport().written().len(), 3);
        assert_eq!(bus.stats().retries, 2);

        // Same, ending with a good reply.
        let mut link = MockTransport::new();
        link.push_silence()
            .push_reply(bad)
            .push_reply(status(1, 0, &[5, 0, 0, 0]));
        let mut bus = super::tests::bus(link);
        assert_eq!(bus.read(1, 132, 4).unwrap(), [5, 0, 0, 0]);
        assert_eq!(bus.transport().written().len(), 3);
    }

    #[test]
    fn corrupt_reply_error_carries_the_bytes() {
        let mut bad = status(1, 0, &[5, 0, 0, 0]);
        *bad.last_mut().unwrap() ^= 0xFF;
        let mut link = MockTransport::new();
        link.push_reply(bad.clone());
        let config = BusConfig {
            max_attempts: 1,
            ..BusConfig::default()
        };
        let err = Bus::new(link, config).read(1, 132, 4).unwrap_err();
        assert!(matches!(
            err,
            BusError::Corrupt {
                error: ProtocolError::CrcMismatch { .. },
                ..
            }
        ));
        assert_eq!(err.received(), bad);
        assert!(err.to_string().contains("READ to ID 1"));
    }

    #[test]
    fn device_errors_are_not_retried() {
        let mut link = MockTransport::new();
        link.push_reply(status(1, 7, &[]));
        let mut bus = bus(link);
        let err = bus.read(1, 300, 4).unwrap_err();
        match err {
            BusError::Device { id, error, .. } => {
                assert_eq!(id, 1);
                assert_eq!(error.code(), Some(ErrorCode::Access));
            }
            other => panic!("unexpected {other:?}"),
        }
        assert_eq!(bus.transport().written().len(), 1);
    }

    #[test]
    fn alert_keeps_the_data() {
        let mut link = MockTransport::new();
        link.push_reply(status(4, 0x80, &[0x20]));
        let err = bus(link).read(4, 70, 1).unwrap_err();
        assert!(matches!(err, BusError::Alert { id: 4, ref params, .. } if params == &[0x20]));
    }

    #[test]
    fn wrong_length_is_retried_for_reads() {
        let mut link = MockTransport::new();
        link.push_reply(status(1, 0, &[1]))
            .push_reply(status(1, 0, &[1, 2, 3, 4]));
        let mut bus = bus(link);
        assert_eq!(bus.read(1, 132, 4).unwrap(), [1, 2, 3, 4]);
        assert_eq!(bus.stats().retries, 1);
    }

    #[test]
    fn write_with_status_is_sent_once() {
        let mut link = MockTransport::new();
        link.push_reply(status(1, 0, &[]));
        let mut bus = bus(link);
        bus.write(1, 116, &[0, 4, 0, 0]).unwrap();
        assert_eq!(instructions(&bus), [W]);
    }

    #[test]
    fn write_with_error_status_is_not_resent() {
        let mut link = MockTransport::new();
        link.push_reply(status(1, 6, &[]));
        let mut bus = bus(link);
        let err = bus.write(1, 116, &[0, 4, 0, 0]).unwrap_err();
        assert!(matches!(err, BusError::Device { .. }));
        assert_eq!(instructions(&bus), [W]);
    }

    #[test]
    fn lost_write_is_resent_after_the_read_back_shows_it_missing() {
        let mut link = MockTransport::new();
        link.push_silence()
            .push_reply(status(1, 0, &[0, 0, 0, 0]))
            .push_reply(status(1, 0, &[]));
        let mut bus = bus(link);
        bus.write(1, 116, &[0, 4, 0, 0]).unwrap();
        assert_eq!(instructions(&bus), [W, R, W]);
        assert_eq!(bus.stats().retries, 1);
    }

    #[test]
    fn write_whose_status_was_lost_is_not_resent() {
        let mut link = MockTransport::new();
        link.push_silence().push_reply(status(1, 0, &[0, 4, 0, 0]));
        let mut bus = bus(link);
        bus.write(1, 116, &[0, 4, 0, 0]).unwrap();
        assert_eq!(instructions(&bus), [W, R]);
        assert_eq!(bus.stats().confirmed_by_read_back, 1);
    }

    #[test]
    fn write_with_corrupt_status_is_never_resent() {
        let mut bad = status(1, 0, &[]);
        bad[9] ^= 1;
        let mut link = MockTransport::new();
        link.push_reply(bad.clone())
            .push_reply(status(1, 0, &[9, 9, 9, 9]));
        let mut bus = bus(link);
        let err = bus.write(1, 116, &[0, 4, 0, 0]).unwrap_err();
        assert!(matches!(err, BusError::Corrupt { attempts: 1, .. }));
        assert_eq!(err.received(), bad);
        assert_eq!(instructions(&bus), [W, R]);
    }

    #[test]
    fn write_is_unconfirmed_when_the_read_back_fails() {
        let mut bus = bus(MockTransport::new());
        let err = bus.write(1, 116, &[0, 4, 0, 0]).unwrap_err();
        match &err {
            BusError::Unconfirmed {
                attempts: 1,
                source,
                ..
            } => assert!(matches!(**source, BusError::Timeout { attempts: 3, .. })),
            other => panic!("unexpected {other:?}"),
        }
        assert_eq!(instructions(&bus), [W, R, R, R]);
    }

    #[test]
    fn write_retries_are_bounded() {
        let mut link = MockTransport::new();
        for _ in 0..3 {
            link.push_silence().push_reply(status(1, 0, &[0, 0, 0, 0]));
        }
        let mut bus = bus(link);
        let err = bus.write(1, 116, &[0, 4, 0, 0]).unwrap_err();
        assert!(matches!(err, BusError::Timeout { attempts: 3, .. }));
        assert_eq!(instructions(&bus), [W, R, W, R, W, R]);
    }

    #[test]
    fn sync_read_retries_the_whole_exchange() {
        let mut first = status(1, 0, &[1]);
        first.extend(&status(2, 0, &[2])[..6]); // truncated
        let mut second = status(1, 0, &[1]);
        second.extend(status(2, 0, &[2]));
        let mut link = MockTransport::new();
        link.push_reply(first).push_reply(second);
        let mut bus = bus(link);
        assert_eq!(bus.sync_read(&[1, 2], 122, 1).unwrap(), [vec![1], vec![2]]);
        assert_eq!(bus.stats().retries, 1);
        assert!(matches!(
            bus.sync_read(&[1, 1], 122, 1),
            Err(BusError::InvalidRequest { .. })
        ));
    }

    #[test]
    fn sync_write_repairs_only_missing_entries() {
        let goal_a = 100i32.to_le_bytes();
        let goal_b = 200i32.to_le_bytes();
        let mut readback = status(1, 0, &goal_a);
        readback.extend(status(2, 0, &[0, 0, 0, 0])); // ID 2 missed the broadcast
        let mut link = MockTransport::new();
        link.push_silence()
            .push_reply(readback)
            .push_reply(status(2, 0, &[]));
        let mut bus = bus(link);
        let report = bus
            .sync_write(116, &[(1, &goal_a[..]), (2, &goal_b[..])])
            .unwrap();
        assert_eq!(report.resent, [2]);
        assert_eq!(
            instructions(&bus),
            [instruction::SYNC_WRITE, instruction::SYNC_READ, W]
        );
        assert_eq!(bus.transport().written()[2][4], 2);
        assert_eq!(bus.stats().sync_write_repairs, 1);
    }

    #[test]
    fn sync_write_reports_an_alert_after_checking_everyone() {
        let goal = 100i32.to_le_bytes();
        let mut readback = status(1, 0x80, &goal);
        readback.extend(status(2, 0, &goal));
        let mut link = MockTransport::new();
        link.push_silence()
            .push_reply(readback)
            .push_reply(status(1, 0x80, &goal))
            .push_reply(status(2, 0, &goal));
        let mut bus = bus(link);
        let err = bus
            .sync_write(116, &[(1, &goal[..]), (2, &goal[..])])
            .unwrap_err();
        assert!(matches!(err, BusError::Alert { id: 1, .. }));
        assert_eq!(
            instructions(&bus),
            [instruction::SYNC_WRITE, instruction::SYNC_READ, R, R]
        );
    }

    #[test]
    fn sync_write_to_a_silent_motor_is_unconfirmed_and_names_the_sync_write() {
        let goal = 100i32.to_le_bytes();
        let mut link = MockTransport::new();
        link.push_silence();
        for _ in 0..3 {
            link.push_reply(status(1, 0, &goal)); // ID 2 never answers the sync read
        }
        link.push_reply(status(1, 0, &goal));
        let mut bus = bus(link);
        let err = bus
            .sync_write(116, &[(1, &goal[..]), (2, &goal[..])])
            .unwrap_err();
        match &err {
            BusError::Unconfirmed {
                id: 2,
                request,
                source,
                ..
            } => {
                assert_eq!(request.instruction, instruction::SYNC_WRITE);
                assert!(matches!(**source, BusError::Timeout { id: 2, .. }));
            }
            other => panic!("unexpected {other:?}"),
        }
        // sync write, 3 sync reads, then one read per motor (3 for the silent one).
        assert_eq!(bus.transport().written().len(), 1 + 3 + 1 + 3);
        assert_eq!(bus.stats().sync_write_repairs, 0);
    }

    #[test]
    fn invalid_requests_send_nothing() {
        let mut bus = bus(MockTransport::new());
        assert!(matches!(
            bus.write(BROADCAST_ID, 64, &[1]),
            Err(BusError::InvalidRequest { .. })
        ));
        assert!(matches!(
            bus.sync_write(116, &[(1, &[0, 0][..]), (2, &[0][..])]),
            Err(BusError::Encode(ProtocolError::EntryLength { .. }))
        ));
        assert!(bus.transport().written().is_empty());
    }
}

//! What goes wrong on the bus: the packet sent ([`Request`]), the errors that name it
//! ([`BusError`]), the failures of one wait for a status that the retry rule decides on,
//! and the checks that refuse a request before anything is sent.

use std::fmt;

use crate::protocol::{
    hex, instruction, Packet, ProtocolError, StatusError, BROADCAST_ID, MAX_DEVICE_ID,
};
use crate::transport::TransportError;

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

/// Why one wait for a status failed: what the retry rule decides on.
pub(super) enum Failure {
    /// No complete status before the deadline; the bytes that did come.
    Timeout { received: Vec<u8> },
    /// An unusable frame, or a frame that is not a status.
    Corrupt {
        error: ProtocolError,
        received: Vec<u8>,
    },
    /// A good status with the wrong number of data bytes.
    Length {
        expected: usize,
        got: usize,
        status: Vec<u8>,
    },
    /// The link itself failed: never retried.
    Transport(TransportError),
}

impl Failure {
    /// The error to report after `attempts` copies of `request` to `id`.
    pub(super) fn into_error(self, id: u8, request: &Request, attempts: u32) -> BusError {
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

    /// Whether the wait saw no byte at all: a write was lost on its way, not refused.
    pub(super) fn nothing_came_back(&self) -> bool {
        matches!(self, Self::Timeout { received } if received.is_empty())
    }
}

/// Refuses an ID that is not a single device for `what` (an instruction's name).
pub(super) fn check_unicast(id: u8, what: &str) -> Result<(), BusError> {
    if id > MAX_DEVICE_ID {
        return Err(BusError::InvalidRequest {
            reason: format!("{what} needs a device ID (0..={MAX_DEVICE_ID}), got {id}"),
        });
    }
    Ok(())
}

/// Refuses a list of IDs with a non-device ID or an ID twice.
pub(super) fn check_id_list(ids: &[u8]) -> Result<(), BusError> {
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

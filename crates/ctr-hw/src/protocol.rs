//! Dynamixel Protocol 2.0 framing as pure functions: CRC, byte stuffing, instruction
//! packets, status packets and a decoder that finds packets in a byte stream.
//!
//! # Packet layout
//!
//! All multi-byte fields are little-endian:
//!
//! ```text
//! FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAM ... | CRC_L CRC_H
//! ```
//!
//! * `ID` is 0..=252, or 254 ([`BROADCAST_ID`]).
//! * `LEN` counts the bytes after itself: the instruction, the (stuffed) parameters and the
//!   two CRC bytes, so it is at least 3.
//! * A status packet (the reply of a device) has `INST = 0x55` and its first parameter is
//!   the error byte ([`StatusError`]): bit 7 is the hardware alert, bits 0..=6 the error
//!   code (1 result fail, 2 instruction error, 3 CRC error, 4 data range, 5 data length,
//!   6 data limit, 7 access).
//! * Byte stuffing: wherever `FF FF FD` occurs in the instruction-and-parameter region an
//!   extra `FD` is inserted after it, so the header pattern `FF FF FD 00` never appears
//!   inside a packet. `LEN` and the CRC are computed over the stuffed bytes.
//! * CRC-16 with polynomial 0x8005, initial value 0, no reflection and no final XOR (the
//!   table-driven `update_crc` of the ROBOTIS e-manual), over every byte from the first
//!   header byte to the last parameter byte.
//!
//! Source: ROBOTIS e-manual, "DYNAMIXEL Protocol 2.0" and "CRC calculation".
//!
//! # Example
//!
//! ```
//! use ctr_hw::protocol::{Packet, StatusPacket, StatusError, Decoder};
//!
//! // The ping of ID 1, byte for byte as in the e-manual.
//! let ping = Packet::ping(1).encode().unwrap();
//! assert_eq!(ping, [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E]);
//!
//! // A status packet surrounded by line noise and split across two reads.
//! let status = StatusPacket::new(1, StatusError::OK, vec![0x06, 0x04, 0x26]).encode().unwrap();
//! let mut decoder = Decoder::new();
//! decoder.push(&[0x00, 0x42]);
//! decoder.push(&status[..5]);
//! assert!(decoder.next_frame().is_none());
//! decoder.push(&status[5..]);
//! let frame = decoder.next_frame().unwrap();
//! let reply = StatusPacket::from_packet(frame.result.unwrap()).unwrap();
//! assert_eq!(reply.params, [0x06, 0x04, 0x26]);
//! ```

use std::fmt;

/// The four bytes that open every packet.
///
/// ```
/// assert_eq!(ctr_hw::protocol::HEADER, [0xFF, 0xFF, 0xFD, 0x00]);
/// ```
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];

/// The ID that addresses every device at once (sync read/write, broadcast ping).
///
/// ```
/// assert_eq!(ctr_hw::protocol::BROADCAST_ID, 0xFE);
/// ```
pub const BROADCAST_ID: u8 = 0xFE;

/// The largest ID a single device may have (the robot file's largest `motor_id`).
///
/// ```
/// assert_eq!(ctr_hw::protocol::MAX_DEVICE_ID, 252);
/// ```
pub const MAX_DEVICE_ID: u8 = ctr_formats::MAX_MOTOR_ID;

/// Instruction codes of Protocol 2.0 (the subset this crate uses, plus the status code).
///
/// ```
/// use ctr_hw::protocol::instruction;
/// assert_eq!(instruction::name(instruction::SYNC_WRITE), "SYNC_WRITE");
/// ```
pub mod instruction {
    /// Ping: the device answers with its model number and firmware version.
    pub const PING: u8 = 0x01;
    /// Read `length` bytes of the control table from `address`.
    pub const READ: u8 = 0x02;
    /// Write bytes into the control table at `address`.
    pub const WRITE: u8 = 0x03;
    /// Reboot the device (clears a hardware error).
    pub const REBOOT: u8 = 0x08;
    /// The instruction code of a status packet (a device's reply).
    pub const STATUS: u8 = 0x55;
    /// Read the same range from several devices; each answers in turn.
    pub const SYNC_READ: u8 = 0x82;
    /// Write the same range on several devices in one broadcast packet; nobody answers.
    pub const SYNC_WRITE: u8 = 0x83;

    /// The e-manual name of an instruction code, `"UNKNOWN"` for others.
    ///
    /// ```
    /// use ctr_hw::protocol::instruction;
    /// assert_eq!(instruction::name(0x02), "READ");
    /// assert_eq!(instruction::name(0x77), "UNKNOWN");
    /// ```
    pub fn name(code: u8) -> &'static str {
        match code {
            PING => "PING",
            READ => "READ",
            WRITE => "WRITE",
            REBOOT => "REBOOT",
            STATUS => "STATUS",
            SYNC_READ => "SYNC_READ",
            SYNC_WRITE => "SYNC_WRITE",
            _ => "UNKNOWN",
        }
    }
}

/// What can be wrong with a packet that is built or received.
///
/// ```
/// use ctr_hw::protocol::{Packet, ProtocolError};
/// let err = Packet::new(0xFF, 0x01, vec![]).encode().unwrap_err();
/// assert_eq!(err, ProtocolError::InvalidId { id: 0xFF });
/// ```
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ProtocolError {
    /// The ID is neither a device ID (0..=252) nor the broadcast ID.
    #[error("invalid packet ID {id:#04X}")]
    InvalidId {
        /// The offending ID.
        id: u8,
    },
    /// The packet would not fit the 16-bit length field.
    #[error("packet too long: length field would be {length}")]
    TooLong {
        /// The length the field would need.
        length: usize,
    },
    /// Sync write entries must all carry `length` bytes.
    #[error("sync write entry for ID {id} has {got} bytes, expected {expected}")]
    EntryLength {
        /// The ID of the offending entry.
        id: u8,
        /// The common data length of the sync write.
        expected: usize,
        /// The data length of this entry.
        got: usize,
    },
    /// A received length field smaller than the minimum of 3.
    #[error("length field {length} is below the minimum of 3")]
    BadLength {
        /// The received length field.
        length: u16,
    },
    /// The CRC in the packet differs from the CRC of its bytes.
    #[error("CRC mismatch: packet carries {received:#06X}, bytes give {computed:#06X}")]
    CrcMismatch {
        /// The CRC computed over the received bytes.
        computed: u16,
        /// The CRC carried by the packet.
        received: u16,
    },
    /// A status packet was expected but the instruction byte is something else.
    #[error("expected a status packet (0x55), got instruction {instruction:#04X}")]
    NotStatus {
        /// The instruction byte received.
        instruction: u8,
    },
    /// A status packet without its error byte.
    #[error("status packet without an error byte")]
    MissingErrorByte,
}

const fn crc_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x8005
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// The 256-entry CRC table of the e-manual (polynomial 0x8005, MSB first), built at
/// compile time.
///
/// ```
/// let t = ctr_hw::protocol::CRC_TABLE;
/// assert_eq!(&t[..4], &[0x0000, 0x8005, 0x800F, 0x000A]);
/// ```
pub const CRC_TABLE: [u16; 256] = crc_table();

/// Continues a CRC over more bytes (the e-manual's `update_crc(crc_accum, data, size)`).
///
/// ```
/// use ctr_hw::protocol::{crc16, crc16_update};
/// let bytes = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01];
/// assert_eq!(crc16_update(crc16(&bytes[..3]), &bytes[3..]), crc16(&bytes));
/// ```
pub fn crc16_update(mut crc: u16, data: &[u8]) -> u16 {
    for &byte in data {
        let index = usize::from(((crc >> 8) as u8) ^ byte);
        crc = (crc << 8) ^ CRC_TABLE[index];
    }
    crc
}

/// The Protocol 2.0 CRC of `data` (initial value 0).
///
/// ```
/// // Ping of ID 1: the packet ends in 19 4E, i.e. CRC 0x4E19.
/// let body = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01];
/// assert_eq!(ctr_hw::protocol::crc16(&body), 0x4E19);
/// ```
pub fn crc16(data: &[u8]) -> u16 {
    crc16_update(0, data)
}

/// Byte-stuffs an instruction-and-parameter region: an `FD` is inserted after every
/// `FF FF FD`.
///
/// ```
/// use ctr_hw::protocol::stuff;
/// assert_eq!(stuff(&[0x03, 0xFF, 0xFF, 0xFD, 0x01]), [0x03, 0xFF, 0xFF, 0xFD, 0xFD, 0x01]);
/// assert_eq!(stuff(&[0xFF, 0xFF, 0x01]), [0xFF, 0xFF, 0x01]);
/// ```
pub fn stuff(payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(payload.len() + payload.len() / 3);
    // `run` is the length of the FF FF prefix seen just before the current byte (0..=2).
    let mut run = 0;
    for &byte in payload {
        out.push(byte);
        match byte {
            0xFF => run = (run + 1).min(2),
            0xFD if run == 2 => {
                out.push(0xFD);
                run = 0;
            }
            _ => run = 0,
        }
    }
    out
}

/// Removes byte stuffing: the `FD` following every `FF FF FD` is dropped.
///
/// Lenient: an `FF FF FD` not followed by the stuffing `FD` (which a correct sender never
/// produces) is kept as it is; the CRC, checked over the stuffed bytes, guards integrity.
///
/// ```
/// use ctr_hw::protocol::{stuff, unstuff};
/// let data = [0x55, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x07];
/// assert_eq!(unstuff(&stuff(&data)), data);
/// assert_eq!(unstuff(&[0xFF, 0xFF, 0xFD, 0xFD]), [0xFF, 0xFF, 0xFD]);
/// ```
pub fn unstuff(stuffed: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(stuffed.len());
    let mut run = 0;
    let mut expect_stuffing = false;
    for &byte in stuffed {
        if expect_stuffing {
            expect_stuffing = false;
            if byte == 0xFD {
                continue;
            }
        }
        out.push(byte);
        match byte {
            0xFF => run = (run + 1).min(2),
            0xFD if run == 2 => {
                expect_stuffing = true;
                run = 0;
            }
            _ => run = 0,
        }
    }
    out
}

/// A decoded packet: an instruction packet, or a status packet before its error byte is
/// split off (see [`StatusPacket::from_packet`]).
///
/// ```
/// use ctr_hw::protocol::{Packet, instruction};
/// let p = Packet::new(1, instruction::PING, vec![]);
/// assert_eq!(p.encode().unwrap(), Packet::ping(1).encode().unwrap());
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    /// Device ID (or [`BROADCAST_ID`]).
    pub id: u8,
    /// Instruction code (see [`instruction`]).
    pub instruction: u8,
    /// Parameters, unstuffed.
    pub params: Vec<u8>,
}

impl Packet {
    /// A packet from its parts.
    ///
    /// ```
    /// let p = ctr_hw::protocol::Packet::new(3, 0x02, vec![0x84, 0x00, 0x04, 0x00]);
    /// assert_eq!(p.id, 3);
    /// ```
    pub fn new(id: u8, instruction: u8, params: Vec<u8>) -> Self {
        Self {
            id,
            instruction,
            params,
        }
    }

    /// Ping of one device.
    ///
    /// ```
    /// let p = ctr_hw::protocol::Packet::ping(1);
    /// assert!(p.params.is_empty());
    /// ```
    pub fn ping(id: u8) -> Self {
        Self::new(id, instruction::PING, Vec::new())
    }

    /// Read `length` bytes from `address`.
    ///
    /// ```
    /// let p = ctr_hw::protocol::Packet::read(1, 132, 4);
    /// assert_eq!(p.params, [0x84, 0x00, 0x04, 0x00]);
    /// ```
    pub fn read(id: u8, address: u16, length: u16) -> Self {
        let mut params = Vec::with_capacity(4);
        params.extend_from_slice(&address.to_le_bytes());
        params.extend_from_slice(&length.to_le_bytes());
        Self::new(id, instruction::READ, params)
    }

    /// Write `data` at `address`.
    ///
    /// ```
    /// let p = ctr_hw::protocol::Packet::write(1, 116, &512i32.to_le_bytes());
    /// assert_eq!(p.params, [0x74, 0x00, 0x00, 0x02, 0x00, 0x00]);
    /// ```
    pub fn write(id: u8, address: u16, data: &[u8]) -> Self {
        let mut params = Vec::with_capacity(2 + data.len());
        params.extend_from_slice(&address.to_le_bytes());
        params.extend_from_slice(data);
        Self::new(id, instruction::WRITE, params)
    }

    /// Sync read of `length` bytes at `address` from `ids`, who answer in that order.
    ///
    /// ```
    /// let p = ctr_hw::protocol::Packet::sync_read(132, 4, &[1, 2]);
    /// assert_eq!(p.id, ctr_hw::protocol::BROADCAST_ID);
    /// assert_eq!(p.params, [0x84, 0x00, 0x04, 0x00, 0x01, 0x02]);
    /// ```
    pub fn sync_read(address: u16, length: u16, ids: &[u8]) -> Self {
        let mut params = Vec::with_capacity(4 + ids.len());
        params.extend_from_slice(&address.to_le_bytes());
        params.extend_from_slice(&length.to_le_bytes());
        params.extend_from_slice(ids);
        Self::new(BROADCAST_ID, instruction::SYNC_READ, params)
    }

    /// Sync write of `(id, data)` entries at `address`; every entry must carry the same
    /// number of bytes.
    ///
    /// ```
    /// use ctr_hw::protocol::Packet;
    /// let a = 150i32.to_le_bytes();
    /// let b = 170i32.to_le_bytes();
    /// let p = Packet::sync_write(116, &[(1, &a[..]), (2, &b[..])]).unwrap();
    /// assert_eq!(p.params[..4], [0x74, 0x00, 0x04, 0x00]);
    /// assert!(Packet::sync_write(116, &[(1, &a[..]), (2, &b[..2])]).is_err());
    /// ```
    pub fn sync_write(address: u16, entries: &[(u8, &[u8])]) -> Result<Self, ProtocolError> {
        let length = entries.first().map_or(0, |(_, data)| data.len());
        let length_field = u16::try_from(length).map_err(|_| ProtocolError::TooLong { length })?;
        let mut params = Vec::with_capacity(4 + entries.len() * (1 + length));
        params.extend_from_slice(&address.to_le_bytes());
        params.extend_from_slice(&length_field.to_le_bytes());
        for &(id, data) in entries {
            if data.len() != length {
                return Err(ProtocolError::EntryLength {
                    id,
                    expected: length,
                    got: data.len(),
                });
            }
            params.push(id);
            params.extend_from_slice(data);
        }
        Ok(Self::new(BROADCAST_ID, instruction::SYNC_WRITE, params))
    }

    /// The bytes on the wire: header, ID, length, stuffed instruction and parameters, CRC.
    ///
    /// ```
    /// use ctr_hw::protocol::Packet;
    /// // e-manual example: read 4 bytes at 132 (present position) from ID 1.
    /// assert_eq!(
    ///     Packet::read(1, 132, 4).encode().unwrap(),
    ///     [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15]
    /// );
    /// ```
    pub fn encode(&self) -> Result<Vec<u8>, ProtocolError> {
        if self.id > MAX_DEVICE_ID && self.id != BROADCAST_ID {
            return Err(ProtocolError::InvalidId { id: self.id });
        }
        let mut region = Vec::with_capacity(1 + self.params.len());
        region.push(self.instruction);
        region.extend_from_slice(&self.params);
        let stuffed = stuff(&region);
        let length = stuffed.len() + 2;
        let length_field = u16::try_from(length).map_err(|_| ProtocolError::TooLong { length })?;
        let mut out = Vec::with_capacity(7 + length);
        out.extend_from_slice(&HEADER);
        out.push(self.id);
        out.extend_from_slice(&length_field.to_le_bytes());
        out.extend_from_slice(&stuffed);
        let crc = crc16(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        Ok(out)
    }
}

/// An error code of a status packet (bits 0..=6 of the error byte).
///
/// ```
/// use ctr_hw::protocol::ErrorCode;
/// assert_eq!(ErrorCode::from_code(6), Some(ErrorCode::DataLimit));
/// assert_eq!(ErrorCode::DataLimit.code(), 6);
/// assert_eq!(ErrorCode::from_code(0), None);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ErrorCode {
    /// 1: the device failed to process the instruction.
    ResultFail,
    /// 2: undefined instruction, or an action without a registered write.
    InstructionError,
    /// 3: the CRC of the instruction packet did not match.
    CrcError,
    /// 4: the data to write is out of range.
    DataRange,
    /// 5: the data is shorter than the range requires.
    DataLength,
    /// 6: the data to write exceeds a limit of the control table.
    DataLimit,
    /// 7: write to a read-only or undefined address, read of a write-only one, or a write
    /// to EEPROM while torque is on.
    Access,
    /// Any other non-zero code.
    Unknown(u8),
}

impl ErrorCode {
    /// The code for a 7-bit error number; `None` for 0 (no error).
    ///
    /// ```
    /// assert_eq!(ctr_hw::protocol::ErrorCode::from_code(3), Some(ctr_hw::protocol::ErrorCode::CrcError));
    /// ```
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code & 0x7F {
            0 => return None,
            1 => Self::ResultFail,
            2 => Self::InstructionError,
            3 => Self::CrcError,
            4 => Self::DataRange,
            5 => Self::DataLength,
            6 => Self::DataLimit,
            7 => Self::Access,
            other => Self::Unknown(other),
        })
    }

    /// The 7-bit error number.
    ///
    /// ```
    /// assert_eq!(ctr_hw::protocol::ErrorCode::Access.code(), 7);
    /// ```
    pub fn code(self) -> u8 {
        match self {
            Self::ResultFail => 1,
            Self::InstructionError => 2,
            Self::CrcError => 3,
            Self::DataRange => 4,
            Self::DataLength => 5,
            Self::DataLimit => 6,
            Self::Access => 7,
            Self::Unknown(code) => code & 0x7F,
        }
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = match self {
            Self::ResultFail => "result fail",
            Self::InstructionError => "instruction error",
            Self::CrcError => "CRC error",
            Self::DataRange => "data range error",
            Self::DataLength => "data length error",
            Self::DataLimit => "data limit error",
            Self::Access => "access error",
            Self::Unknown(code) => return write!(f, "unknown error {code}"),
        };
        f.write_str(text)
    }
}

/// The error byte of a status packet: bit 7 is the hardware alert (the device has a
/// hardware error; the instruction itself was processed), bits 0..=6 an [`ErrorCode`]
/// (the instruction was not processed).
///
/// ```
/// use ctr_hw::protocol::{StatusError, ErrorCode};
/// let e = StatusError(0x80 | 7);
/// assert!(e.alert());
/// assert_eq!(e.code(), Some(ErrorCode::Access));
/// assert!(!e.is_ok());
/// assert!(StatusError::OK.is_ok());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct StatusError(pub u8);

impl StatusError {
    /// No error, no alert.
    ///
    /// ```
    /// assert_eq!(ctr_hw::protocol::StatusError::OK.0, 0);
    /// ```
    pub const OK: Self = Self(0);

    /// The alert bit.
    ///
    /// ```
    /// assert_eq!(ctr_hw::protocol::StatusError::ALERT_BIT, 0x80);
    /// ```
    pub const ALERT_BIT: u8 = 0x80;

    /// An error byte from an optional code and the alert flag.
    ///
    /// ```
    /// use ctr_hw::protocol::{StatusError, ErrorCode};
    /// assert_eq!(StatusError::from_parts(Some(ErrorCode::DataRange), true).0, 0x84);
    /// ```
    pub fn from_parts(code: Option<ErrorCode>, alert: bool) -> Self {
        let code = code.map_or(0, ErrorCode::code);
        Self(code | if alert { Self::ALERT_BIT } else { 0 })
    }

    /// Whether the hardware alert bit is set.
    ///
    /// ```
    /// assert!(ctr_hw::protocol::StatusError(0x80).alert());
    /// ```
    pub fn alert(self) -> bool {
        self.0 & Self::ALERT_BIT != 0
    }

    /// The error code, `None` when the instruction was processed.
    ///
    /// ```
    /// assert_eq!(ctr_hw::protocol::StatusError(0x80).code(), None);
    /// ```
    pub fn code(self) -> Option<ErrorCode> {
        ErrorCode::from_code(self.0)
    }

    /// No code and no alert.
    ///
    /// ```
    /// assert!(!ctr_hw::protocol::StatusError(0x01).is_ok());
    /// ```
    pub fn is_ok(self) -> bool {
        self.0 == 0
    }
}

impl fmt::Display for StatusError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.code(), self.alert()) {
            (None, false) => f.write_str("no error"),
            (None, true) => f.write_str("hardware alert"),
            (Some(code), false) => write!(f, "{code}"),
            (Some(code), true) => write!(f, "{code} with hardware alert"),
        }
    }
}

/// A device's reply: its ID, the error byte and the returned data.
///
/// ```
/// use ctr_hw::protocol::{StatusPacket, StatusError};
/// // e-manual example: ID 1 answers a read of present position with 166.
/// let bytes = StatusPacket::new(1, StatusError::OK, 166i32.to_le_bytes().to_vec()).encode().unwrap();
/// assert_eq!(
///     bytes,
///     [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x55, 0x00, 0xA6, 0x00, 0x00, 0x00, 0x8C, 0xC0]
/// );
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StatusPacket {
    /// The ID of the device that answered.
    pub id: u8,
    /// The error byte.
    pub error: StatusError,
    /// The returned data (after the error byte).
    pub params: Vec<u8>,
}

impl StatusPacket {
    /// A status packet from its parts.
    ///
    /// ```
    /// let s = ctr_hw::protocol::StatusPacket::new(2, Default::default(), vec![]);
    /// assert!(s.error.is_ok());
    /// ```
    pub fn new(id: u8, error: StatusError, params: Vec<u8>) -> Self {
        Self { id, error, params }
    }

    /// Interprets a decoded packet as a status packet.
    ///
    /// ```
    /// use ctr_hw::protocol::{Packet, StatusPacket, ProtocolError};
    /// let status = StatusPacket::from_packet(Packet::new(1, 0x55, vec![0x80])).unwrap();
    /// assert!(status.error.alert());
    /// assert_eq!(
    ///     StatusPacket::from_packet(Packet::ping(1)),
    ///     Err(ProtocolError::NotStatus { instruction: 0x01 })
    /// );
    /// ```
    pub fn from_packet(packet: Packet) -> Result<Self, ProtocolError> {
        if packet.instruction != instruction::STATUS {
            return Err(ProtocolError::NotStatus {
                instruction: packet.instruction,
            });
        }
        let mut params = packet.params;
        if params.is_empty() {
            return Err(ProtocolError::MissingErrorByte);
        }
        let error = StatusError(params.remove(0));
        Ok(Self::new(packet.id, error, params))
    }

    /// The generic packet (error byte first among the parameters).
    ///
    /// ```
    /// use ctr_hw::protocol::{StatusPacket, StatusError};
    /// let p = StatusPacket::new(1, StatusError(0x80), vec![5]).to_packet();
    /// assert_eq!(p.params, [0x80, 5]);
    /// ```
    pub fn to_packet(&self) -> Packet {
        let mut params = Vec::with_capacity(1 + self.params.len());
        params.push(self.error.0);
        params.extend_from_slice(&self.params);
        Packet::new(self.id, instruction::STATUS, params)
    }

    /// The bytes on the wire.
    ///
    /// ```
    /// use ctr_hw::protocol::{StatusPacket, StatusError};
    /// // e-manual example: status of a write to ID 1.
    /// assert_eq!(
    ///     StatusPacket::new(1, StatusError::OK, vec![]).encode().unwrap(),
    ///     [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x55, 0x00, 0xA1, 0x0C]
    /// );
    /// ```
    pub fn encode(&self) -> Result<Vec<u8>, ProtocolError> {
        self.to_packet().encode()
    }
}

/// The result of looking for a packet at the start of a byte buffer.
///
/// ```
/// use ctr_hw::protocol::{scan, Scan, Packet};
/// let mut bytes = vec![0x12, 0x34];
/// bytes.extend(Packet::ping(1).encode().unwrap());
/// match scan(&bytes) {
///     Scan::Frame { garbage, len, result } => {
///         assert_eq!((garbage, len), (2, 10));
///         assert_eq!(result.unwrap(), Packet::ping(1));
///     }
///     Scan::Incomplete { .. } => unreachable!(),
/// }
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Scan {
    /// No complete packet yet. The first `garbage` bytes cannot start a packet and may be
    /// dropped; the rest may be the beginning of one.
    Incomplete {
        /// Leading bytes that cannot belong to a packet.
        garbage: usize,
    },
    /// A complete frame occupies `buf[garbage..garbage + len]`.
    Frame {
        /// Leading bytes before the header.
        garbage: usize,
        /// The frame length in bytes (for a bad length field: the 4 header bytes only, so
        /// that scanning resumes after them).
        len: usize,
        /// The decoded packet, or why the frame is unusable (bad length, CRC mismatch).
        result: Result<Packet, ProtocolError>,
    },
}

fn header_position(buf: &[u8]) -> Option<usize> {
    buf.windows(HEADER.len()).position(|w| w == HEADER)
}

/// Finds the first packet in `buf`, skipping garbage before the header; never panics.
///
/// ```
/// use ctr_hw::protocol::{scan, Scan, Packet, ProtocolError};
/// let mut bytes = Packet::ping(1).encode().unwrap();
/// assert!(matches!(scan(&bytes[..6]), Scan::Incomplete { garbage: 0 }));
/// bytes[8] ^= 0x01; // corrupt the CRC
/// assert!(matches!(
///     scan(&bytes),
///     Scan::Frame { result: Err(ProtocolError::CrcMismatch { .. }), .. }
/// ));
/// ```
pub fn scan(buf: &[u8]) -> Scan {
    let Some(start) = header_position(buf) else {
        // Keep a tail that could still grow into a header.
        let keep = (1..HEADER.len())
            .rev()
            .find(|&n| buf.len() >= n && buf[buf.len() - n..] == HEADER[..n])
            .unwrap_or(0);
        return Scan::Incomplete {
            garbage: buf.len() - keep,
        };
    };
    let frame = &buf[start..];
    if frame.len() < 7 {
        return Scan::Incomplete { garbage: start };
    }
    let length = u16::from_le_bytes([frame[5], frame[6]]);
    if length < 3 {
        return Scan::Frame {
            garbage: start,
            len: HEADER.len(),
            result: Err(ProtocolError::BadLength { length }),
        };
    }
    let total = 7 + usize::from(length);
    if frame.len() < total {
        return Scan::Incomplete { garbage: start };
    }
    let frame = &frame[..total];
    let received = u16::from_le_bytes([frame[total - 2], frame[total - 1]]);
    let computed = crc16(&frame[..total - 2]);
    let result = if received != computed {
        Err(ProtocolError::CrcMismatch { computed, received })
    } else {
        let region = unstuff(&frame[7..total - 2]);
        Ok(Packet::new(frame[4], region[0], region[1..].to_vec()))
    };
    Scan::Frame {
        garbage: start,
        len: total,
        result,
    }
}

/// A frame cut from a byte stream by [`Decoder::next_frame`].
///
/// ```
/// use ctr_hw::protocol::{Decoder, Packet};
/// let bytes = Packet::ping(7).encode().unwrap();
/// let mut d = Decoder::new();
/// d.push(&bytes);
/// let frame = d.next_frame().unwrap();
/// assert_eq!(frame.raw, bytes);
/// assert_eq!(frame.result.unwrap().id, 7);
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// The frame's bytes as received (stuffed, with header and CRC).
    pub raw: Vec<u8>,
    /// The decoded packet or why the frame is unusable.
    pub result: Result<Packet, ProtocolError>,
}

/// Accumulates received bytes and cuts them into frames, dropping garbage between them.
///
/// ```
/// use ctr_hw::protocol::{Decoder, Packet};
/// let mut d = Decoder::new();
/// for byte in Packet::ping(1).encode().unwrap() {
///     d.push(&[byte]); // one byte per read
/// }
/// assert_eq!(d.next_frame().unwrap().result.unwrap(), Packet::ping(1));
/// assert!(d.next_frame().is_none());
/// ```
#[derive(Debug, Clone, Default)]
pub struct Decoder {
    buf: Vec<u8>,
    garbage_bytes: u64,
}

impl Decoder {
    /// An empty decoder.
    ///
    /// ```
    /// assert!(ctr_hw::protocol::Decoder::new().pending().is_empty());
    /// ```
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends received bytes.
    ///
    /// ```
    /// let mut d = ctr_hw::protocol::Decoder::new();
    /// d.push(&[0xFF, 0xFF]);
    /// assert_eq!(d.pending(), [0xFF, 0xFF]);
    /// ```
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// The next complete frame, if any; garbage before it is dropped (and counted).
    ///
    /// ```
    /// let mut d = ctr_hw::protocol::Decoder::new();
    /// d.push(&[1, 2, 3]);
    /// assert!(d.next_frame().is_none());
    /// assert_eq!(d.garbage_bytes(), 3);
    /// ```
    pub fn next_frame(&mut self) -> Option<Frame> {
        match scan(&self.buf) {
            Scan::Incomplete { garbage } => {
                self.drop_front(garbage);
                None
            }
            Scan::Frame {
                garbage,
                len,
                result,
            } => {
                self.drop_front(garbage);
                let raw: Vec<u8> = self.buf.drain(..len).collect();
                Some(Frame { raw, result })
            }
        }
    }

    /// Bytes received but not yet cut into a frame.
    ///
    /// ```
    /// let d = ctr_hw::protocol::Decoder::new();
    /// assert_eq!(d.pending().len(), 0);
    /// ```
    pub fn pending(&self) -> &[u8] {
        &self.buf
    }

    /// Total bytes dropped as garbage so far.
    ///
    /// ```
    /// assert_eq!(ctr_hw::protocol::Decoder::new().garbage_bytes(), 0);
    /// ```
    pub fn garbage_bytes(&self) -> u64 {
        self.garbage_bytes
    }

    /// Drops every pending byte and returns them.
    ///
    /// ```
    /// let mut d = ctr_hw::protocol::Decoder::new();
    /// d.push(&[0xFF]);
    /// assert_eq!(d.clear(), [0xFF]);
    /// assert!(d.pending().is_empty());
    /// ```
    pub fn clear(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.buf)
    }

    fn drop_front(&mut self, n: usize) {
        if n > 0 {
            self.buf.drain(..n);
            self.garbage_bytes += n as u64;
        }
    }
}

/// Formats bytes as upper-case hex pairs separated by spaces (`"FF FF FD 00"`).
///
/// ```
/// assert_eq!(ctr_hw::protocol::hex(&[0xFF, 0x01]), "FF 01");
/// ```
pub fn hex(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len() * 3);
    for (i, byte) in bytes.iter().enumerate() {
        if i > 0 {
            out.push(' ');
        }
        out.push_str(&format!("{byte:02X}"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Test vectors from the Protocol 2.0 page of the ROBOTIS e-manual.
    const PING_ID1: [u8; 10] = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E];
    const PING_STATUS_ID1: [u8; 14] = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D,
    ];
    const READ_ID1: [u8; 14] = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15,
    ];
    const READ_STATUS_ID1: [u8; 15] = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x55, 0x00, 0xA6, 0x00, 0x00, 0x00, 0x8C, 0xC0,
    ];
    const WRITE_ID1: [u8; 16] = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03, 0x74, 0x00, 0x00, 0x02, 0x00, 0x00, 0xCA,
        0x89,
    ];
    const WRITE_STATUS_ID1: [u8; 11] = [
        0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x55, 0x00, 0xA1, 0x0C,
    ];
    const SYNC_READ_1_2: [u8; 16] = [
        0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00, 0x82, 0x84, 0x00, 0x04, 0x00, 0x01, 0x02, 0xCE,
        0xFA,
    ];
    const SYNC_WRITE_1_2: [u8; 24] = [
        0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x11, 0x00, 0x83, 0x74, 0x00, 0x04, 0x00, 0x01, 0x96, 0x00,
        0x00, 0x00, 0x02, 0xAA, 0x00, 0x00, 0x00, 0x82, 0x87,
    ];

    #[test]
    fn crc_table_matches_the_e_manual() {
        assert_eq!(
            CRC_TABLE[..8],
            [0x0000, 0x8005, 0x800F, 0x000A, 0x801B, 0x001E, 0x0014, 0x8011]
        );
        assert_eq!(CRC_TABLE[253..], [0x820D, 0x8207, 0x0202]);
    }

    #[test]
    fn crc_of_the_ping_packet() {
        assert_eq!(crc16(&PING_ID1[..8]), 0x4E19);
        assert_eq!(crc16(&[]), 0);
    }

    #[test]
    fn crc_of_every_e_manual_example() {
        for packet in [
            &PING_ID1[..],
            &PING_STATUS_ID1,
            &READ_ID1,
            &READ_STATUS_ID1,
            &WRITE_ID1,
            &WRITE_STATUS_ID1,
            &SYNC_READ_1_2,
            &SYNC_WRITE_1_2,
        ] {
            let n = packet.len();
            let crc = u16::from_le_bytes([packet[n - 2], packet[n - 1]]);
            assert_eq!(crc16(&packet[..n - 2]), crc, "packet {}", hex(packet));
        }
    }

    #[test]
    fn encodes_instruction_packets() {
        assert_eq!(Packet::ping(1).encode().unwrap(), PING_ID1);
        assert_eq!(Packet::read(1, 132, 4).encode().unwrap(), READ_ID1);
        assert_eq!(
            Packet::write(1, 116, &512i32.to_le_bytes())
                .encode()
                .unwrap(),
            WRITE_ID1
        );
        assert_eq!(
            Packet::sync_read(132, 4, &[1, 2]).encode().unwrap(),
            SYNC_READ_1_2
        );
        let a = 150i32.to_le_bytes();
        let b = 170i32.to_le_bytes();
        assert_eq!(
            Packet::sync_write(116, &[(1, &a[..]), (2, &b[..])])
                .unwrap()
                .encode()
                .unwrap(),
            SYNC_WRITE_1_2
        );
    }

    #[test]
    fn rejects_invalid_ids_and_mismatched_sync_entries() {
        for id in [0xFD, 0xFF] {
            assert_eq!(
                Packet::ping(id).encode(),
                Err(ProtocolError::InvalidId { id })
            );
        }
        assert!(Packet::ping(BROADCAST_ID).encode().is_ok());
        assert_eq!(
            Packet::sync_write(116, &[(1, &[1, 2][..]), (2, &[1][..])]),
            Err(ProtocolError::EntryLength {
                id: 2,
                expected: 2,
                got: 1
            })
        );
    }

    #[test]
    fn rejects_packets_longer_than_the_length_field() {
        let data = vec![0u8; 70_000];
        assert!(matches!(
            Packet::write(1, 0, &data).encode(),
            Err(ProtocolError::TooLong { .. })
        ));
    }

    #[test]
    fn parses_status_packets() {
        let ping = StatusPacket::from_packet(decode_one(&PING_STATUS_ID1)).unwrap();
        assert_eq!(
            ping,
            StatusPacket::new(1, StatusError::OK, vec![0x06, 0x04, 0x26])
        );
        let read = StatusPacket::from_packet(decode_one(&READ_STATUS_ID1)).unwrap();
        assert_eq!(read.params, 166i32.to_le_bytes());
        let write = StatusPacket::from_packet(decode_one(&WRITE_STATUS_ID1)).unwrap();
        assert!(write.params.is_empty() && write.error.is_ok());
        assert_eq!(
            StatusPacket::new(1, StatusError::OK, vec![0x06, 0x04, 0x26])
                .encode()
                .unwrap(),
            PING_STATUS_ID1
        );
    }

    #[test]
    fn error_byte_alert_and_codes() {
        let names = [
            (1, ErrorCode::ResultFail),
            (2, ErrorCode::InstructionError),
            (3, ErrorCode::CrcError),
            (4, ErrorCode::DataRange),
            (5, ErrorCode::DataLength),
            (6, ErrorCode::DataLimit),
            (7, ErrorCode::Access),
        ];
        for (code, expected) in names {
            let plain = StatusError(code);
            assert_eq!(plain.code(), Some(expected));
            assert!(!plain.alert());
            let alerted = StatusError(code | 0x80);
            assert_eq!(alerted.code(), Some(expected));
            assert!(alerted.alert());
            assert_eq!(StatusError::from_parts(Some(expected), true), alerted);
        }
        assert_eq!(StatusError(0x80).code(), None);
        assert!(StatusError(0x80).alert());
        assert_eq!(StatusError(0x09).code(), Some(ErrorCode::Unknown(9)));
        assert_eq!(
            StatusError(0x86).to_string(),
            "data limit error with hardware alert"
        );
    }

    #[test]
    fn status_parsing_errors_are_errors() {
        assert_eq!(
            StatusPacket::from_packet(Packet::new(1, 0x55, vec![])),
            Err(ProtocolError::MissingErrorByte)
        );
        assert_eq!(
            StatusPacket::from_packet(Packet::ping(1)),
            Err(ProtocolError::NotStatus { instruction: 1 })
        );
    }

    #[test]
    fn stuffing_vectors() {
        let cases: [(&[u8], &[u8]); 7] = [
            (&[0, 0, 0], &[0, 0, 0]),
            (&[0xFF, 0xFF, 0xFD], &[0xFF, 0xFF, 0xFD, 0xFD]),
            (&[0xFF, 0xFF, 0xFD, 0x00], &[0xFF, 0xFF, 0xFD, 0xFD, 0x00]),
            (&[0xFF, 0xFF, 0xFD, 0xFD], &[0xFF, 0xFF, 0xFD, 0xFD, 0xFD]),
            (&[0xFF, 0xFF, 0xFF, 0xFD], &[0xFF, 0xFF, 0xFF, 0xFD, 0xFD]),
            (&[0xFF, 0x01, 0xFF, 0xFD], &[0xFF, 0x01, 0xFF, 0xFD]),
            (
                &[0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD],
                &[0xFF, 0xFF, 0xFD, 0xFD, 0xFF, 0xFF, 0xFD, 0xFD],
            ),
        ];
        for (plain, stuffed) in cases {
            assert_eq!(stuff(plain), stuffed, "stuff {}", hex(plain));
            assert_eq!(unstuff(stuffed), plain, "unstuff {}", hex(stuffed));
        }
    }

    #[test]
    fn stuffing_round_trips_every_short_sequence_of_ff_fd_and_00() {
        let alphabet = [0xFF, 0xFD, 0x00];
        for n in 0..=7u32 {
            for mut k in 0..3usize.pow(n) {
                let mut data = Vec::new();
                for _ in 0..n {
                    data.push(alphabet[k % 3]);
                    k /= 3;
                }
                let stuffed = stuff(&data);
                assert_eq!(unstuff(&stuffed), data);
                // No header pattern survives inside a stuffed region.
                assert!(header_position(&stuffed).is_none() || header_position(&data).is_some());
            }
        }
    }

    #[test]
    fn stuffed_packets_round_trip_through_the_decoder() {
        // Writing FF FF FD as data must be stuffed; length counts the stuffed bytes.
        let packet = Packet::write(3, 200, &[0xFF, 0xFF, 0xFD, 0x01]);
        let bytes = packet.encode().unwrap();
        assert_eq!(
            bytes[..13],
            [0xFF, 0xFF, 0xFD, 0x00, 0x03, 0x0A, 0x00, 0x03, 0xC8, 0x00, 0xFF, 0xFF, 0xFD]
        );
        assert_eq!(bytes[13], 0xFD);
        assert_eq!(bytes.len(), 7 + 0x0A);
        assert_eq!(decode_one(&bytes), packet);
    }

    #[test]
    fn decoder_skips_garbage_and_waits_for_partial_reads() {
        let mut stream = vec![0xFF, 0x00, 0xFF, 0xFF, 0xFD, 0x01, 0xAA];
        stream.extend_from_slice(&PING_STATUS_ID1);
        stream.extend_from_slice(&[0xFF, 0xFF]);
        stream.extend_from_slice(&WRITE_STATUS_ID1);
        // Feed in awkward chunks.
        let mut decoder = Decoder::new();
        let mut frames = Vec::new();
        for chunk in stream.chunks(3) {
            decoder.push(chunk);
            while let Some(frame) = decoder.next_frame() {
                frames.push(frame);
            }
        }
        assert_eq!(frames.len(), 2);
        assert_eq!(frames[0].raw, PING_STATUS_ID1);
        assert_eq!(frames[1].raw, WRITE_STATUS_ID1);
        assert_eq!(decoder.garbage_bytes(), 9);
        assert!(decoder.pending().is_empty());
    }

    #[test]
    fn partial_header_at_the_end_is_kept() {
        for keep in 1..4 {
            let mut bytes = vec![0x11, 0x22];
            bytes.extend_from_slice(&HEADER[..keep]);
            assert_eq!(scan(&bytes), Scan::Incomplete { garbage: 2 });
        }
        assert_eq!(scan(&[]), Scan::Incomplete { garbage: 0 });
        assert_eq!(scan(&[0xFF, 0xFD]), Scan::Incomplete { garbage: 2 });
    }

    #[test]
    fn wrong_crc_is_an_error_and_the_stream_recovers() {
        let mut bad = READ_STATUS_ID1;
        bad[9] ^= 0x40; // flip a data bit
        let mut decoder = Decoder::new();
        decoder.push(&bad);
        decoder.push(&WRITE_STATUS_ID1);
        let first = decoder.next_frame().unwrap();
        assert_eq!(first.raw, bad);
        assert!(matches!(
            first.result,
            Err(ProtocolError::CrcMismatch {
                received: 0xC08C,
                ..
            })
        ));
        let second = decoder.next_frame().unwrap();
        assert_eq!(second.result.unwrap().id, 1);
    }

    #[test]
    fn bad_length_field_is_an_error_and_scanning_resumes() {
        let mut bytes = vec![0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x02, 0x00];
        bytes.extend_from_slice(&PING_ID1);
        let mut decoder = Decoder::new();
        decoder.push(&bytes);
        let first = decoder.next_frame().unwrap();
        assert_eq!(first.result, Err(ProtocolError::BadLength { length: 2 }));
        let second = decoder.next_frame().unwrap();
        assert_eq!(second.result.unwrap(), Packet::ping(1));
    }

    #[test]
    fn truncated_and_random_input_never_panics() {
        // Every prefix of every example, and a deterministic pseudo-random stream.
        for packet in [&PING_ID1[..], &READ_STATUS_ID1, &SYNC_WRITE_1_2] {
            for n in 0..packet.len() {
                assert!(matches!(scan(&packet[..n]), Scan::Incomplete { .. }));
            }
        }
        let mut state = 0x1234_5678u32;
        let mut decoder = Decoder::new();
        for _ in 0..20_000 {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            // Bias towards header bytes so that frames actually start.
            let byte = match state % 8 {
                0..=2 => 0xFF,
                3 => 0xFD,
                4 => 0x00,
                _ => (state >> 8) as u8,
            };
            decoder.push(&[byte]);
            while decoder.next_frame().is_some() {}
        }
    }

    fn decode_one(bytes: &[u8]) -> Packet {
        match scan(bytes) {
            Scan::Frame {
                garbage: 0,
                len,
                result,
            } if len == bytes.len() => result.unwrap(),
            other => panic!("unexpected scan {other:?}"),
        }
    }
}

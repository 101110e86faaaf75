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
//!
//! # Layout
//!
//! One file per part, everything re-exported here: `crc` (the checksum, [`crc16`]),
//! `stuffing` (keeping the header out of the data, [`stuff`]), `packet` (instruction
//! packets and their bytes, [`Packet`]), `status` (a device's reply and its error byte,
//! [`StatusPacket`]) and `decoder` (frames cut from a byte stream, [`Decoder`]).

mod crc;
mod decoder;
mod packet;
mod status;
mod stuffing;

pub use crc::{crc16, crc16_update, CRC_TABLE};
pub use decoder::{scan, Decoder, Frame, Scan};
pub use packet::Packet;
pub use status::{ErrorCode, StatusError, StatusPacket};
pub use stuffing::{stuff, unstuff};

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

/// Offset of the ID byte in a packet, after the header.
pub(crate) const ID_OFFSET: usize = 4;
/// Offset of the two-byte length field.
const LENGTH_OFFSET: usize = 5;
/// Offset of the instruction byte: the header, the ID and the length field come first.
pub(crate) const INSTRUCTION_OFFSET: usize = 7;
/// Bytes of the CRC that ends every packet.
const CRC_LEN: usize = 2;
/// The smallest length field: the instruction byte and the CRC.
const MIN_LENGTH_FIELD: u16 = 3;

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

/// Where the header pattern first occurs in `buf`, if anywhere.
fn header_position(buf: &[u8]) -> Option<usize> {
    buf.windows(HEADER.len()).position(|w| w == HEADER)
}

/// The e-manual's example packets, for the tests of every part.
#[cfg(test)]
mod vectors;

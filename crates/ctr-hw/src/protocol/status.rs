//! A device's reply: the status packet, its error byte (hardware alert and error code)
//! and the error codes of the e-manual.

use std::fmt;

use super::packet::Packet;
use super::{instruction, ProtocolError};

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::decoder::decode_one;
    use crate::protocol::vectors::*;

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
}

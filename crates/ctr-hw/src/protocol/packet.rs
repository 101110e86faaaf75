//! Instruction packets: their parts, the constructors of the instructions this crate
//! sends, and their bytes on the wire.

use super::crc::crc16;
use super::stuffing::stuff;
use super::{
    instruction, ProtocolError, BROADCAST_ID, CRC_LEN, HEADER, INSTRUCTION_OFFSET, MAX_DEVICE_ID,
};

/// A decoded packet: an instruction packet, or a status packet before its error byte is
/// split off (see [`StatusPacket::from_packet`](super::StatusPacket::from_packet)).
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
        let length = stuffed.len() + CRC_LEN;
        let length_field = u16::try_from(length).map_err(|_| ProtocolError::TooLong { length })?;
        let mut out = Vec::with_capacity(INSTRUCTION_OFFSET + length);
        out.extend_from_slice(&HEADER);
        out.push(self.id);
        out.extend_from_slice(&length_field.to_le_bytes());
        out.extend_from_slice(&stuffed);
        let crc = crc16(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::vectors::*;

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
}

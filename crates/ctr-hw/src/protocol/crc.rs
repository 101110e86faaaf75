//! The Protocol 2.0 CRC: CRC-16 with polynomial 0x8005, initial value 0, no reflection
//! and no final XOR (the table-driven `update_crc` of the ROBOTIS e-manual, "CRC
//! calculation"), over every byte of a packet from the header to the last parameter.

/// The CRC-16 polynomial of Protocol 2.0.
const POLYNOMIAL: u16 = 0x8005;

const fn crc_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ POLYNOMIAL
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::hex;
    use crate::protocol::vectors::*;

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
}

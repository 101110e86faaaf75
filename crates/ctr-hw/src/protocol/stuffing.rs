//! Byte stuffing: wherever `FF FF FD` occurs in the instruction-and-parameter region an
//! extra `FD` is inserted after it, so that the header `FF FF FD 00` never appears inside
//! a packet.

/// The byte that completes the header pattern `FF FF FD` and is doubled by stuffing.
const STUFFED: u8 = 0xFD;

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
            STUFFED if run == 2 => {
                out.push(STUFFED);
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
            if byte == STUFFED {
                continue;
            }
        }
        out.push(byte);
        match byte {
            0xFF => run = (run + 1).min(2),
            STUFFED if run == 2 => {
                expect_stuffing = true;
                run = 0;
            }
            _ => run = 0,
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{header_position, hex};

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
}

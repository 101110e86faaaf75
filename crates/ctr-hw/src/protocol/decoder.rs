//! Cutting packets out of a byte stream: [`scan`] finds the first frame in a buffer,
//! [`Decoder`] keeps the bytes between reads and drops the garbage between frames.

use super::crc::crc16;
use super::packet::Packet;
use super::stuffing::unstuff;
use super::{
    header_position, ProtocolError, CRC_LEN, HEADER, ID_OFFSET, INSTRUCTION_OFFSET, LENGTH_OFFSET,
    MIN_LENGTH_FIELD,
};

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
    if frame.len() < INSTRUCTION_OFFSET {
        return Scan::Incomplete { garbage: start };
    }
    let length = u16::from_le_bytes([frame[LENGTH_OFFSET], frame[LENGTH_OFFSET + 1]]);
    if length < MIN_LENGTH_FIELD {
        return Scan::Frame {
            garbage: start,
            len: HEADER.len(),
            result: Err(ProtocolError::BadLength { length }),
        };
    }
    let total = INSTRUCTION_OFFSET + usize::from(length);
    if frame.len() < total {
        return Scan::Incomplete { garbage: start };
    }
    let (body, crc) = frame[..total].split_at(total - CRC_LEN);
    let received = u16::from_le_bytes([crc[0], crc[1]]);
    let computed = crc16(body);
    let result = if received != computed {
        Err(ProtocolError::CrcMismatch { computed, received })
    } else {
        let region = unstuff(&body[INSTRUCTION_OFFSET..]);
        Ok(Packet::new(
            body[ID_OFFSET],
            region[0],
            region[1..].to_vec(),
        ))
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

/// The packet that makes up all of `bytes` (for tests).
#[cfg(test)]
pub(super) fn decode_one(bytes: &[u8]) -> Packet {
    match scan(bytes) {
        Scan::Frame {
            garbage: 0,
            len,
            result,
        } if len == bytes.len() => result.unwrap(),
        other => panic!("unexpected scan {other:?}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::vectors::*;

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
}

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
//!
//! # Layout
//!
//! This file holds the bus and its exchanges (ping, read, sync read, and the wait for a
//! status that every exchange shares); `write` the writes under the rule above; `error`
//! the packet sent ([`Request`]) and what can go wrong ([`BusError`]).

mod error;
mod write;

pub use error::{BusError, Request};
pub use write::SyncWriteReport;

use std::time::{Duration, Instant};

use crate::protocol::{instruction, Decoder, Packet, StatusPacket};
use crate::transport::Transport;
use error::{check_id_list, check_unicast, Failure};

/// Data bytes of a ping's status: the model number (2) and the firmware version (1).
const PING_REPLY_LEN: usize = 3;

/// The outcome of one wait for a status that leaves the exchange open: the status's
/// data, or a failure that allows another attempt.
type Attempt = Result<Vec<u8>, Failure>;

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
        let params = self.query(&request, id, PING_REPLY_LEN)?;
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

    /// Reads like [`Bus::read`], but an alert status (the device has a hardware error yet
    /// processed the read) still gives the data it carries: what it takes to settle
    /// whether a write was applied, or to read a motor's state after an overload.
    ///
    /// ```
    /// use ctr_hw::bus::{Bus, BusConfig};
    /// use ctr_hw::protocol::{StatusPacket, StatusError};
    /// use ctr_hw::transport::MockTransport;
    /// let mut link = MockTransport::new();
    /// link.push_reply(StatusPacket::new(1, StatusError(0x80), vec![0x20]).encode()?);
    /// assert_eq!(Bus::new(link, BusConfig::default()).read_despite_alert(1, 70, 1)?, [0x20]);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn read_despite_alert(
        &mut self,
        id: u8,
        address: u16,
        length: u16,
    ) -> Result<Vec<u8>, BusError> {
        match self.read(id, address, length) {
            Err(BusError::Alert { params, .. }) => Ok(params),
            other => other,
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
                match self.await_status(&request, id, usize::from(length))? {
                    Ok(data) => values.push(data),
                    Err(failure) => {
                        self.count_retry(failure, id, &request, attempts)?;
                        continue 'attempt;
                    }
                }
            }
            return Ok(values);
        }
    }

    /// Sends a side-effect-free request and waits for the status of `id`, retrying.
    fn query(&mut self, request: &Request, id: u8, expected: usize) -> Result<Vec<u8>, BusError> {
        let mut attempts = 0;
        loop {
            attempts += 1;
            self.send(request)?;
            match self.await_status(request, id, expected)? {
                Ok(data) => return Ok(data),
                Err(failure) => self.count_retry(failure, id, request, attempts)?,
            }
        }
    }

    /// Counts a retry after `failure`, or gives it up as the error when no attempt is left
    /// or the link itself failed.
    fn count_retry(
        &mut self,
        failure: Failure,
        id: u8,
        request: &Request,
        attempts: u32,
    ) -> Result<(), BusError> {
        if matches!(failure, Failure::Transport(_)) || attempts >= self.config.max_attempts {
            return Err(failure.into_error(id, request, attempts));
        }
        self.stats.retries += 1;
        Ok(())
    }

    /// Waits for the status of `id` to `request` and judges it: an error code or an alert
    /// ends the exchange (`Err`); a good status gives its `expected` data bytes; no status,
    /// a corrupt one or one of the wrong length is a failure that allows another attempt.
    fn await_status(
        &mut self,
        request: &Request,
        id: u8,
        expected: usize,
    ) -> Result<Attempt, BusError> {
        let (status, raw) = match self.receive_status(id) {
            Ok(received) => received,
            Err(failure) => return Ok(Err(failure)),
        };
        if status.error.code().is_some() {
            return Err(BusError::Device {
                id,
                request: request.clone(),
                error: status.error,
                status: raw,
            });
        }
        if status.params.len() != expected {
            return Ok(Err(Failure::Length {
                expected,
                got: status.params.len(),
                status: raw,
            }));
        }
        if status.error.alert() {
            return Err(BusError::Alert {
                id,
                request: request.clone(),
                status: raw,
                params: status.params,
            });
        }
        Ok(Ok(status.params))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::{ErrorCode, ProtocolError, StatusError, INSTRUCTION_OFFSET};
    use crate::transport::MockTransport;

    pub(super) fn status(id: u8, error: u8, params: &[u8]) -> Vec<u8> {
        StatusPacket::new(id, StatusError(error), params.to_vec())
            .encode()
            .unwrap()
    }

    pub(super) fn bus(link: MockTransport) -> Bus<MockTransport> {
        Bus::new(link, BusConfig::default())
    }

    pub(super) fn instructions(bus: &Bus<MockTransport>) -> Vec<u8> {
        bus.transport()
            .written()
            .iter()
            .map(|w| w[INSTRUCTION_OFFSET])
            .collect()
    }

    pub(super) const W: u8 = instruction::WRITE;
    pub(super) const R: u8 = instruction::READ;

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
}

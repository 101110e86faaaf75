//! Writes that are applied exactly once: a write is resent only when there is evidence
//! that it was not applied, a sync write is verified by reading it back and repaired
//! entry by entry (the write rule of [the bus](super)).

use super::error::{check_id_list, check_unicast, Failure};
use super::{Bus, BusError, Request};
use crate::protocol::{Packet, ProtocolError};
use crate::transport::Transport;

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

impl<T: Transport> Bus<T> {
    /// Writes `data` at `address` of device `id`, under the write rule of the
    /// [bus](crate::bus) (resent only when known not applied).
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
            let failure = match self.await_status(&request, id, 0)? {
                Ok(_) => return Ok(()),
                Err(failure) => failure,
            };
            if let Failure::Transport(source) = failure {
                return Err(BusError::Transport { request, source });
            }
            // No valid status: was the write applied? Ask before deciding anything.
            let current = match self.read_despite_alert(id, address, length) {
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
                    .map(|&id| self.read_despite_alert(id, address, length))
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
}

#[cfg(test)]
mod tests {
    use crate::bus::tests::{bus, instructions, status, R, W};
    use crate::bus::BusError;
    use crate::protocol::{instruction, ProtocolError, BROADCAST_ID};
    use crate::transport::MockTransport;

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

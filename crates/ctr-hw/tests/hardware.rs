//! Tests against a real bus. They run only with the `hardware` feature and a port:
//!
//! ```text
//! CTR_HW_PORT=/dev/ttyUSB0 CTR_HW_BAUD=57600 CTR_HW_IDS=1,2,3,4 \
//!     cargo test -p ctr-hw --features hardware --test hardware -- --test-threads=1
//! ```
//!
//! They only ping and read: nothing is written, no motor moves.
#![cfg(feature = "hardware")]

use std::time::Duration;

use ctr_hw::bus::{Bus, BusConfig};
use ctr_hw::control_table as ct;
use ctr_hw::transport::SerialTransport;

/// The bus named by the environment, or `None` (test skipped) without `CTR_HW_PORT`.
fn bus_from_env() -> Option<(Bus<SerialTransport>, Vec<u8>)> {
    let Ok(port) = std::env::var("CTR_HW_PORT") else {
        eprintln!("CTR_HW_PORT is not set: skipping the hardware test");
        return None;
    };
    let baud = std::env::var("CTR_HW_BAUD")
        .ok()
        .map(|b| b.parse().expect("CTR_HW_BAUD must be a number"))
        .unwrap_or(57_600);
    let ids = std::env::var("CTR_HW_IDS")
        .unwrap_or_else(|_| "1,2,3,4".into())
        .split(',')
        .map(|id| id.trim().parse().expect("CTR_HW_IDS: comma-separated IDs"))
        .collect();
    let link = SerialTransport::open(&port, baud).expect("open CTR_HW_PORT");
    let config = BusConfig {
        response_timeout: Duration::from_millis(50),
        max_attempts: 3,
    };
    Some((Bus::new(link, config), ids))
}

#[test]
fn every_motor_answers_ping() {
    let Some((mut bus, ids)) = bus_from_env() else {
        return;
    };
    for id in ids {
        let reply = bus.ping(id).unwrap_or_else(|e| panic!("ping {id}: {e}"));
        eprintln!("ID {id}: model {} firmware {}", reply.model, reply.firmware);
    }
}

#[test]
fn present_positions_and_hardware_status_read_back() {
    let Some((mut bus, ids)) = bus_from_env() else {
        return;
    };
    let positions = bus
        .sync_read(&ids, ct::PRESENT_POSITION, ct::PRESENT_POSITION_LEN)
        .expect("sync read of present positions");
    for (id, bytes) in ids.iter().zip(&positions) {
        let ticks = i32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        let status = bus
            .read(*id, ct::HARDWARE_ERROR_STATUS, 1)
            .unwrap_or_else(|e| panic!("hardware status of {id}: {e}"));
        eprintln!(
            "ID {id}: present position {ticks} ticks, hardware status {:#04X}",
            status[0]
        );
    }
}

//! End-to-end tests: the bus and the rig over a pseudo-terminal pair, against the
//! emulator serving the other side from its thread, with every injected fault.

use std::time::{Duration, Instant};

use ctr_hw::actuation::Actuation;
use ctr_hw::bus::{Bus, BusConfig, BusError, BusStats};
use ctr_hw::control_table as ct;
use ctr_hw::emulator::{Emulator, EmulatorConfig, Fault, PtyEmulator};
use ctr_hw::protocol::{instruction, ProtocolError};
use ctr_hw::rig::{Rig, RigConfig, RigError};
use ctr_hw::transport::SerialTransport;

mod common;

/// Long enough for a loaded 2-core machine, short enough to keep timeouts cheap.
const TIMEOUT: Duration = Duration::from_millis(100);

fn start(time_scale: f64) -> PtyEmulator {
    Emulator::new(EmulatorConfig {
        time_scale,
        ..EmulatorConfig::default()
    })
    .serve_pty()
    .expect("pseudo-terminal")
}

fn connect(pty: &PtyEmulator) -> Bus<SerialTransport> {
    let link = SerialTransport::open(pty.path(), 1_000_000).expect("open slave side");
    Bus::new(
        link,
        BusConfig {
            response_timeout: TIMEOUT,
            max_attempts: 3,
        },
    )
}

/// A bus on the pseudo-terminal of an emulator running at `time_scale`, and a handle on
/// the emulator (the server stops when the first element is dropped).
fn emulated_bus(time_scale: f64) -> (PtyEmulator, Emulator, Bus<SerialTransport>) {
    let pty = start(time_scale);
    let emu = pty.emulator().clone();
    let bus = connect(&pty);
    (pty, emu, bus)
}

/// A rig of [`four_joints`] on the pseudo-terminal of an emulator running at
/// `time_scale`, and a handle on the emulator.
fn emulated_rig(
    time_scale: f64,
    config: RigConfig,
) -> (PtyEmulator, Emulator, Rig<SerialTransport>) {
    let (pty, emu, bus) = emulated_bus(time_scale);
    (pty, emu, Rig::new(bus, four_joints(), config))
}

/// Writes `data` at `address` of motor `id` with `fault` injected for it; the write
/// must succeed. Returns how often the register was written and the bus's counters.
fn write_despite(fault: Fault, id: u8, address: u16, data: &[u8]) -> (usize, BusStats) {
    let (_pty, emu, mut bus) = emulated_bus(1.0);
    emu.inject(Some(id), fault);
    bus.write(id, address, data).unwrap();
    (writes_of(&emu, id, address).len(), bus.stats())
}

/// Feeds at 40 mm/s, rotations at 360 degrees/s.
fn four_joints() -> Actuation {
    Actuation::new(common::two_tubes(40.0, 360.0)).unwrap()
}

/// Applied writes of `address` on motor `id`.
fn writes_of(emu: &Emulator, id: u8, address: u16) -> Vec<Vec<u8>> {
    emu.write_log()
        .into_iter()
        .filter(|w| w.id == id && w.address == address)
        .map(|w| w.data)
        .collect()
}

#[test]
fn pings_all_four_motors_and_reconnects() {
    let pty = start(1.0);
    for _ in 0..2 {
        let mut bus = connect(&pty);
        for id in 1..=4 {
            let reply = bus.ping(id).unwrap();
            assert_eq!(reply.model, ct::MODEL_XM430_W350);
        }
        assert_eq!(bus.stats().retries, 0);
    } // the client closes; the emulator keeps serving the next one
    pty.stop().unwrap();
}

#[test]
fn rig_moves_and_reads_back() {
    let (_pty, emu, mut rig) = emulated_rig(20.0, RigConfig::default());
    rig.enable().unwrap();
    let targets = [-8.0, 90.0, -4.0, -45.0];
    let ticks = rig.move_to(&targets).unwrap();
    assert_eq!(ticks, [-4096, 1024, -2048, -512]);
    let reached = rig.wait_until_still(Duration::from_secs(5)).unwrap();
    assert_eq!(reached, targets);
    for (id, goal) in (1..=4).zip(ticks) {
        assert_eq!(emu.present_position(id), Some(goal));
        assert_eq!(writes_of(&emu, id, ct::GOAL_POSITION).len(), 2); // enable + move
    }
    assert_eq!(rig.bus().stats().retries, 0);
    assert!(rig.fault().is_none());
}

#[test]
fn lost_write_is_resent_once_and_applied_once() {
    let (_pty, emu, mut bus) = emulated_bus(1.0);
    emu.inject(Some(1), Fault::DropInstruction);
    bus.write(1, ct::GOAL_POSITION, &1000i32.to_le_bytes())
        .unwrap();
    assert_eq!(
        writes_of(&emu, 1, ct::GOAL_POSITION),
        [1000i32.to_le_bytes()]
    );
    assert_eq!(emu.stats().instructions_dropped, 1);
    // write (lost), read-back, write again.
    assert_eq!(bus.stats().packets_sent, 3);
    assert_eq!(bus.stats().retries, 1);
}

#[test]
fn write_whose_status_is_lost_is_not_resent() {
    let (applied, stats) =
        write_despite(Fault::NoReply, 2, ct::GOAL_POSITION, &777i32.to_le_bytes());
    assert_eq!(applied, 1);
    assert_eq!(stats.packets_sent, 2); // write + read-back
    assert_eq!(stats.confirmed_by_read_back, 1);
}

#[test]
fn write_with_corrupt_status_is_not_resent() {
    let (applied, stats) = write_despite(
        Fault::CorruptReplyCrc,
        3,
        ct::GOAL_POSITION,
        &(-300i32).to_le_bytes(),
    );
    assert_eq!(applied, 1);
    assert_eq!(stats.packets_sent, 2);
    assert_eq!(stats.confirmed_by_read_back, 1);
}

#[test]
fn write_with_truncated_status_is_not_resent() {
    let (applied, stats) = write_despite(
        Fault::DropReplyBytes(2),
        4,
        ct::PROFILE_VELOCITY,
        &50u32.to_le_bytes(),
    );
    assert_eq!(applied, 1);
    assert_eq!(stats.packets_sent, 2);
}

#[test]
fn reads_are_retried_after_dropped_bytes_and_bad_crc() {
    let (_pty, emu, mut bus) = emulated_bus(1.0);
    emu.inject(Some(1), Fault::DropReplyBytes(3));
    emu.inject(Some(1), Fault::CorruptReplyCrc);
    let value = bus
        .read(1, ct::PRESENT_POSITION, ct::PRESENT_POSITION_LEN)
        .unwrap();
    assert_eq!(value, [0, 0, 0, 0]);
    assert_eq!(bus.stats().retries, 2);
    assert_eq!(emu.pending_faults(), 0);
}

#[test]
fn corrupt_reply_error_names_packet_and_bytes() {
    let (_pty, emu, mut bus) = emulated_bus(1.0);
    for _ in 0..3 {
        emu.inject(Some(2), Fault::CorruptReplyCrc);
    }
    let err = bus.ping(2).unwrap_err();
    match &err {
        BusError::Corrupt {
            id: 2,
            attempts: 3,
            error: ProtocolError::CrcMismatch { .. },
            request,
            received,
        } => {
            assert_eq!(request.instruction, instruction::PING);
            assert_eq!(received.len(), 14);
            assert_eq!(received[..5], [0xFF, 0xFF, 0xFD, 0x00, 0x02]);
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().contains("PING to ID 2"));
}

#[test]
fn retries_are_bounded_when_a_motor_stays_silent() {
    let (_pty, emu, mut bus) = emulated_bus(1.0);
    for _ in 0..10 {
        emu.inject(Some(3), Fault::NoReply);
    }
    let start = Instant::now();
    let err = bus.ping(3).unwrap_err();
    assert!(matches!(
        err,
        BusError::Timeout {
            id: 3,
            attempts: 3,
            ..
        }
    ));
    assert!(err.received().is_empty());
    assert_eq!(emu.stats().instructions_received, 3);
    assert_eq!(emu.pending_faults(), 7);
    assert!(start.elapsed() < 10 * TIMEOUT);

    // A silent write: read-backs fail too, so it is reported unconfirmed and never resent.
    emu.clear_faults();
    for _ in 0..10 {
        emu.inject(Some(3), Fault::NoReply);
    }
    let err = bus
        .write(3, ct::GOAL_POSITION, &5i32.to_le_bytes())
        .unwrap_err();
    assert!(matches!(err, BusError::Unconfirmed { attempts: 1, .. }));
    assert_eq!(writes_of(&emu, 3, ct::GOAL_POSITION).len(), 1);
}

#[test]
fn lost_sync_write_is_repaired_once_per_motor() {
    let (_pty, emu, mut bus) = emulated_bus(1.0);
    emu.inject(None, Fault::DropInstruction);
    let goals: Vec<[u8; 4]> = (1..=4).map(|i| (i * 100i32).to_le_bytes()).collect();
    let entries: Vec<(u8, &[u8])> = (1..=4u8).zip(&goals).map(|(id, g)| (id, &g[..])).collect();
    let report = bus.sync_write(ct::GOAL_POSITION, &entries).unwrap();
    assert_eq!(report.resent, [1, 2, 3, 4]);
    for (id, goal) in (1..=4u8).zip(&goals) {
        assert_eq!(writes_of(&emu, id, ct::GOAL_POSITION), [goal.to_vec()]);
    }
}

#[test]
fn overload_stops_the_rig_holds_and_switches_torque_off() {
    let config = RigConfig {
        torque_off_on_fault: true,
        ..RigConfig::default()
    };
    let (_pty, emu, mut rig) = emulated_rig(20.0, config);
    rig.enable().unwrap();
    rig.move_to(&[-50.0, 170.0, -25.0, 170.0]).unwrap();
    std::thread::sleep(Duration::from_millis(20));
    emu.inject(Some(2), Fault::Overload);
    let err = rig.positions().unwrap_err();
    let RigError::Fault(fault) = &err else {
        panic!("unexpected {err:?}")
    };
    // The report names the motor, the packet and the raw status.
    assert!(matches!(&fault.cause, BusError::Alert { id: 2, .. }));
    let request = fault.cause.request().unwrap();
    assert_eq!(request.instruction, instruction::SYNC_READ);
    let status = fault.cause.received();
    assert_eq!(status[4], 2);
    assert_eq!(status[8] & 0x80, 0x80);
    assert_eq!(fault.hardware_errors, [(2, ct::HW_ERROR_OVERLOAD)]);
    assert!(fault.torque_disabled);
    assert_eq!(fault.held.len(), 4);
    // Every motor holds: goal = present, and nothing moves any more.
    for (id, position) in &fault.held {
        assert_eq!(emu.goal_position(*id), Some(*position));
        assert_eq!(emu.torque_enabled(*id), Some(false));
    }
    assert!(err.to_string().contains("overload"));
    assert!(matches!(rig.move_to(&[0.0; 4]), Err(RigError::Faulted(_))));
}

#[test]
fn every_goal_is_applied_exactly_once_under_mixed_faults() {
    let (_pty, emu, mut rig) = emulated_rig(50.0, RigConfig::default());
    rig.enable().unwrap();
    let faults = [
        (None, Fault::DropInstruction),
        (Some(1), Fault::NoReply),
        (Some(2), Fault::CorruptReplyCrc),
        (Some(3), Fault::DropReplyBytes(4)),
        (Some(4), Fault::DropInstruction),
    ];
    let before: Vec<usize> = (1..=4)
        .map(|id| writes_of(&emu, id, ct::GOAL_POSITION).len())
        .collect();
    let mut sent = Vec::new();
    for step in 0..10 {
        let (motor, fault) = faults[step % faults.len()];
        emu.inject(motor, fault);
        // Every goal differs from the one before it, so each must be applied.
        let s = (step + 1) as f64;
        let targets = [-2.0 * s, 10.0 * s, -s - 0.5, -10.0 * s];
        sent.push(rig.move_to(&targets).unwrap());
    }
    rig.wait_until_still(Duration::from_secs(5)).unwrap();
    for (index, id) in (1..=4u8).enumerate() {
        let goals: Vec<i32> = writes_of(&emu, id, ct::GOAL_POSITION)[before[index]..]
            .iter()
            .map(|d| i32::from_le_bytes([d[0], d[1], d[2], d[3]]))
            .collect();
        let expected: Vec<i32> = sent.iter().map(|ticks| ticks[index]).collect();
        assert_eq!(goals, expected, "motor {id}");
        assert_eq!(emu.present_position(id), expected.last().copied());
    }
    assert!(rig.fault().is_none());
}

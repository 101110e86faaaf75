//! The firmware check of ctr-core on a Cortex-M4F (`thumbv7em-none-eabihf`).
//!
//! It links every kind of solve request ([`every_request`]) with no global allocator:
//! the link fails the moment anything in ctr-core allocates. Run on QEMU's
//! `mps2-an386` (`run-qemu.sh`), it solves the shared reference configurations
//! ([`reference`]) in `f64` and in `f32`, prints one line per tip over semihosting:
//!
//! ```text
//! tip <f64|f32> <model> <row> <x_mm> <y_mm> <z_mm> <qw> <qx> <qy> <qz> <status>
//! ```
//!
//! then the stack's high-water mark ([`stack`]) and a last line
//! `done <configurations> solved, <failed> failed`; it exits through semihosting with
//! status 0 when every solve converged.
#![no_std]
#![no_main]

mod every_request;
mod reference;
mod stack;

use core::panic::PanicInfo;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use ctr_core::{Real, Status};

/// The board this firmware is linked for (`memory.x`).
const BOARD: &str = "mps2-an386 (Cortex-M4F)";

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    halt()
}

/// Stops here (only reached where no debugger ends the run).
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

/// Solves every reference table in `T` (`name`: `f64` or `f32`), printing each tip;
/// returns (rows solved, rows that did not converge).
fn solve_all<T: Real>(name: &str) -> (usize, usize) {
    let robot = match reference::robot::<T>() {
        Ok(r) => r,
        Err(e) => {
            hprintln!("error {name}: the reference robot is invalid: {:?}", e);
            return (0, 1);
        }
    };
    let (mut solved, mut failed) = (0, 0);
    for table in &reference::TABLES {
        reference::solve_table::<T>(&robot, table, |row, tip| {
            solved += 1;
            match tip {
                Ok(t) => {
                    let [x, y, z] = t.position_mm;
                    let [qw, qx, qy, qz] = t.orientation;
                    hprintln!(
                        "tip {} {} {} {} {} {} {} {} {} {} {:?}",
                        name,
                        table.model,
                        row,
                        x,
                        y,
                        z,
                        qw,
                        qx,
                        qy,
                        qz,
                        t.status
                    );
                    if t.status != Status::Converged {
                        failed += 1;
                    }
                }
                Err(e) => {
                    hprintln!("error {} {} {} {:?}", name, table.model, row, e);
                    failed += 1;
                }
            }
        });
    }
    (solved, failed)
}

#[entry]
fn main() -> ! {
    hprintln!(
        "ctr-core firmware check on {}: robot nitinol3, {} tubes",
        BOARD,
        reference::N_TUBES
    );
    // a sum over every kind of request, so that none is optimised away (NaN where a
    // solve ended without converging and left its outputs NaN)
    let sum = every_request::run();
    let exercise = stack::high_water_mark();
    hprintln!("every kind of request: sum {}", sum);
    stack::repaint();
    let (solved64, failed64) = solve_all::<f64>("f64");
    let reference64 = stack::high_water_mark();
    stack::repaint();
    let (solved32, failed32) = solve_all::<f32>("f32");
    let reference32 = stack::high_water_mark();
    hprintln!(
        "stack high-water mark: {} bytes (every kind of request), {} bytes (reference \
         tables, f64), {} bytes (f32), of {} bytes",
        exercise.used_bytes,
        reference64.used_bytes,
        reference32.used_bytes,
        exercise.size_bytes
    );
    let failed = failed64 + failed32;
    hprintln!("done {} solved, {} failed", solved64 + solved32, failed);
    debug::exit(if failed == 0 {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    halt()
}

//! One libFuzzer target for every parser: the first byte chooses the reader, the rest is
//! the file. Each must return (a value or a located error on one line), never panic.
#![no_main]

use ctr_formats::{AnyRobot, JointTable, Recording, RobotSpec, TargetTable};
use libfuzzer_sys::fuzz_target;

/// A valid three-tube robot for the joint reader (the seed's tubes).
const ROBOT: &str = include_str!("../../tests/data/shared/robots/nitinol3.toml");

/// An error's message stays on one line (a located error: file, line, field).
fn located(message: String) {
    assert!(!message.contains('\n'), "an error spans lines: {message:?}");
}

fuzz_target!(|data: &[u8]| {
    let Some((&which, file)) = data.split_first() else {
        return;
    };
    match which % 5 {
        0 => {
            if let Ok(text) = std::str::from_utf8(file) {
                if let Err(e) = RobotSpec::from_toml_str(text, "fuzz.toml") {
                    located(e.to_string());
                }
            }
        }
        1 => {
            let robot: AnyRobot = RobotSpec::from_toml_str(ROBOT, "robot.toml")
                .expect("the bundled robot reads")
                .robot;
            if let Err(e) = JointTable::read(file, "fuzz.csv", &robot) {
                located(e.to_string());
            }
        }
        2 => {
            if let Err(e) = TargetTable::read(file, "fuzz.csv", which & 0x80 != 0) {
                located(e.to_string());
            }
        }
        3 => {
            let n_tubes = usize::from(which >> 5 & 3) + 1;
            if let Err(e) = Recording::read(file, "fuzz.csv", n_tubes) {
                located(e.to_string());
            }
        }
        _ => {
            let _ = ctr_hw::protocol::scan(file);
        }
    }
});

//! Regression tests of what the fuzzed readers (`fuzz_parsers.rs`) found, one per fix;
//! the inputs are also in `tests/corpus/table/`.
use ctr_core::TubeParams;
use ctr_formats::{AnyRobot, JointTable};

fn robot() -> AnyRobot {
    AnyRobot::new(&[TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33)]).unwrap()
}

/// A quoted cell holding a line break that is not a number was echoed as it was, and
/// the one-line error took two lines. Errors now write line breaks as `\n`, `\r`.
#[test]
fn errors_quoting_a_line_break_stay_one_line() {
    let csv = "s1_mm,theta1_deg\n10,0\n\"1\r\n2\",0\n";
    let err = JointTable::read(csv.as_bytes(), "j.csv", &robot()).unwrap_err();
    assert_eq!(
        err.to_string(),
        "j.csv:3: column s1_mm: \"1\\r\\n2\" is not a number"
    );
}

//! Regression tests of what the fuzzed readers (`fuzz_parsers.rs`) found, one per fix;
//! the inputs are also in `tests/corpus/table/`.
use ctr_core::TubeParams;
use ctr_formats::{AnyRobot, JointTable};

fn robot() -> AnyRobot {
    AnyRobot::new(&[TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33)]).unwrap()
}

/// A row with quotes whose first field opens with U+FEFF (a carried label written by
/// the tip writer) lost the mark: each quoted row was read by a csv reader of its own,
/// which strips a byte order mark opening its input. The csv crate strips it at the
/// start of a file only; the row now keeps it, and the rows after it are read as before.
#[test]
fn a_quoted_row_opening_with_a_byte_order_mark_keeps_it() {
    let csv = "label,s1_mm,theta1_deg,note\na,10,0,x\n\u{feff}b,20,0,\"q,\"\"r\"\"\"\nc,30,0,y\n";
    let t = JointTable::read(csv.as_bytes(), "j.csv", &robot()).unwrap();
    let rows: Vec<Vec<&str>> = (0..t.len()).map(|r| t.fields(r).collect()).collect();
    let mut theirs = csv::Reader::from_reader(csv.as_bytes());
    let want: Vec<Vec<String>> = theirs
        .records()
        .map(|r| r.unwrap().iter().map(String::from).collect())
        .collect();
    assert_eq!(rows, want);
    assert_eq!(rows[1][0], "\u{feff}b");
    assert_eq!(t.all_joints(), [10.0, 0.0, 20.0, 0.0, 30.0, 0.0]);
    assert_eq!((t.line(1), t.line(2)), (3, 4));
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

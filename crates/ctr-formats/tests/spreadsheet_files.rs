//! Files saved by spreadsheets and Windows editors: a UTF-8 byte-order mark before the
//! first byte and CRLF line ends. Every reader gives the same output for such a file as
//! for the plain one (issue 17, part 4).

use ctr_formats::{JointTable, Recording, RobotFile, RobotSpec, TargetTable};
use std::path::{Path, PathBuf};

/// The UTF-8 encoding of U+FEFF, what "CSV UTF-8" in a spreadsheet writes first.
const BOM: &[u8] = b"\xEF\xBB\xBF";

fn repo_file(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(path)
}

/// The plain text of a bundled file and its three spreadsheet variants: BOM, CRLF, both.
fn variants(path: &str) -> (Vec<u8>, [(&'static str, Vec<u8>); 3]) {
    let plain = std::fs::read(repo_file(path)).unwrap();
    assert!(
        !plain.starts_with(BOM) && !plain.contains(&b'\r'),
        "{path} is plain"
    );
    let crlf: Vec<u8> = plain
        .split_inclusive(|&b| b == b'\n')
        .flat_map(|line| match line.strip_suffix(b"\n") {
            Some(body) => [body, b"\r\n"].concat(),
            None => line.to_vec(),
        })
        .collect();
    let with_bom = |text: &[u8]| [BOM, text].concat();
    let all = [
        ("BOM", with_bom(&plain)),
        ("CRLF", crlf.clone()),
        ("BOM + CRLF", with_bom(&crlf)),
    ];
    (plain, all)
}

fn robot() -> RobotSpec {
    RobotSpec::from_path(&repo_file("data/robots/liu2023.toml")).unwrap()
}

/// Writes `bytes` to a temporary file named `name` (for the `from_path` readers).
fn temp_file(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn joint_files_with_a_bom_or_crlf_read_as_the_plain_file() {
    let spec = robot();
    let (plain, variants) = variants("data/examples/liu2023-joints.csv");
    let expected = JointTable::read(&plain[..], "j.csv", &spec.robot).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (what, bytes) in variants {
        let by_reader = JointTable::read(&bytes[..], "j.csv", &spec.robot)
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        let by_bytes = JointTable::from_bytes(bytes.clone(), "j.csv", &spec.robot, 2).unwrap();
        let by_path =
            JointTable::from_path(&temp_file(&dir, "j.csv", &bytes), &spec.robot).unwrap();
        for t in [&by_reader, &by_bytes, &by_path] {
            assert_eq!(t.header(), expected.header(), "{what}");
            assert_eq!(t.all_joints(), expected.all_joints(), "{what}");
            assert_eq!(t.len(), expected.len(), "{what}");
            for row in 0..t.len() {
                assert_eq!(t.line(row), expected.line(row), "{what}");
                assert!(t.fields(row).eq(expected.fields(row)), "{what} row {row}");
                assert_eq!(t.plain_line(row), expected.plain_line(row), "{what}");
            }
        }
    }
}

#[test]
fn target_files_with_a_bom_or_crlf_read_as_the_plain_file() {
    let (plain, variants) = variants("data/examples/liu2023-targets.csv");
    let expected = TargetTable::read(&plain[..], "t.csv", false).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (what, bytes) in variants {
        let by_reader =
            TargetTable::read(&bytes[..], "t.csv", false).unwrap_or_else(|e| panic!("{what}: {e}"));
        let by_bytes = TargetTable::from_bytes(bytes.clone(), "t.csv", false, 2).unwrap();
        let by_path = TargetTable::from_path(&temp_file(&dir, "t.csv", &bytes), false).unwrap();
        for t in [&by_reader, &by_bytes, &by_path] {
            assert_eq!(t.header(), expected.header(), "{what}");
            assert_eq!(t.targets(), expected.targets(), "{what}");
            for row in 0..t.len() {
                assert!(t.fields(row).eq(expected.fields(row)), "{what} row {row}");
            }
        }
    }
}

#[test]
fn recordings_with_a_bom_or_crlf_read_as_the_plain_file() {
    let (plain, variants) = variants("data/examples/liu2023-recording.csv");
    let expected = Recording::read(&plain[..], "r.csv", 2).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (what, bytes) in variants {
        let by_reader =
            Recording::read(&bytes[..], "r.csv", 2).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert!(by_reader == expected, "{what}: differs from the plain file");
        let path = temp_file(&dir, "r.csv", &bytes);
        let by_path = Recording::from_path(&path, 2).unwrap();
        assert!(
            by_path.rows == expected.rows && by_path.runs == expected.runs,
            "{what}"
        );
    }
}

#[test]
fn robot_files_with_a_bom_or_crlf_read_as_the_plain_file() {
    let (plain, variants) = variants("data/robots/liu2023.toml");
    let text = String::from_utf8(plain.clone()).unwrap();
    let expected = RobotSpec::from_toml_str(&text, "r.toml").unwrap();
    let expected_file = RobotFile::parse(&text, "r.toml").unwrap();
    let dir = tempfile::tempdir().unwrap();
    for (what, bytes) in variants {
        let by_bytes = RobotSpec::from_bytes(bytes.clone(), "r.toml")
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        let by_path = RobotSpec::from_path(&temp_file(&dir, "r.toml", &bytes)).unwrap();
        let text = String::from_utf8(bytes).unwrap();
        let by_text = RobotSpec::from_toml_str(&text, "r.toml").unwrap();
        for spec in [&by_bytes, &by_path, &by_text] {
            assert_eq!(spec, &expected, "{what}");
        }
        assert_eq!(
            RobotFile::parse(&text, "r.toml").unwrap(),
            expected_file,
            "{what}"
        );
    }
}

#[test]
fn errors_in_spreadsheet_files_keep_their_lines_and_columns() {
    let spec = robot();
    // a BOM before a bad header names the column without the mark
    let joints = b"\xEF\xBB\xBFs1_mm,theta1_deg,s2_mm\r\n45,0,77\r\n";
    let e = JointTable::read(&joints[..], "j.csv", &spec.robot).unwrap_err();
    assert_eq!(
        e.to_string(),
        "j.csv:1: missing column theta2_deg (the header needs s1_mm,theta1_deg,s2_mm,theta2_deg)"
    );
    let joints = b"\xEF\xBB\xBFs1_mm,theta1_deg,s2_mm,theta2_deg\r\n45,0,77,0\r\n45,x,77,0\r\n";
    let e = JointTable::read(&joints[..], "j.csv", &spec.robot).unwrap_err();
    assert_eq!(
        e.to_string(),
        "j.csv:3: column theta1_deg: \"x\" is not a number"
    );
    let rec = b"\xEF\xBB\xBFs1_mm,theta1_deg,s2_mm,theta2_deg,x_mm,y_mm,z_mm\r\n45,0,77,0,1,2,3\r\n45,0,77,0,1,2,z\r\n";
    let e = Recording::read(&rec[..], "r.csv", 2).unwrap_err();
    assert!(e.to_string().starts_with("r.csv:3: column z_mm"), "{e}");
    // TOML: the line and column of a bad value are those an editor shows
    let toml = "\u{feff}name = \"x\"\r\n[[tube]]\r\nouter_diameter_mm = \"six\"\r\n";
    let e = RobotSpec::from_toml_str(toml, "r.toml").unwrap_err();
    assert!(e.to_string().starts_with("r.toml:3:21: "), "{e}");
}

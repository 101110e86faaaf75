//! `run_fk` streams the joint file through the workers in pieces: the output is what
//! reading the whole file and solving it in one batch gives, byte for byte, for any
//! thread count; errors come as if every row had been read first.

use ctr_analysis::batch::{batch_fk, BatchOptions};
use ctr_analysis::job::{run_fk, FkJob, Input, OnError, Output};
use ctr_analysis::model::ModelSpec;
use ctr_formats::{tip_header, write_header, write_tip_row, Carried, ErrorKind, JointTable};
use ctr_formats::{Batch, ColumnType, ParquetOutput, TargetTable};
use std::path::{Path, PathBuf};

mod common;

/// Rows of the generated joint file: more than one piece of the stream (512 rows)
/// and more than one block of its reader (1 MiB) at about 130 bytes a row.
const ROWS: usize = 9000;

/// A joint file of nitinol3 in its stable ranges with what a reader must get right:
/// a byte-order mark, CRLF and LF line ends, blank lines, quoted labels holding commas,
/// quotes and line breaks; a smooth path with jumps now and then.
fn joint_file(rows: usize) -> Vec<u8> {
    let mut rng = common::Rng(7);
    let mut text =
        b"\xEF\xBB\xBFlabel,s1_mm,theta1_deg,s2_mm,theta2_deg,s3_mm,theta3_deg\r\n".to_vec();
    let mut q = [30.0, 0.0, 30.0, 0.0, 30.0, 0.0];
    for k in 0..rows {
        if k % 997 == 0 {
            // a jump: scattered configurations between smooth stretches
            for i in 0..3 {
                q[2 * i] = 10.0 + 40.0 * rng.uniform();
                q[2 * i + 1] = 360.0 * rng.uniform() - 180.0;
            }
        }
        for i in 0..3 {
            q[2 * i] = (q[2 * i] + 0.01 * (rng.uniform() - 0.5)).clamp(10.0, 50.0);
            q[2 * i + 1] += 0.05;
        }
        let mut s = 0.0;
        let cells: Vec<String> = (0..6)
            .map(|j| {
                if j % 2 == 0 {
                    s += q[j];
                    format!("{s}")
                } else {
                    format!("{}", q[j])
                }
            })
            .collect();
        let label = match k % 7 {
            0 => format!("\"r{k}, quoted\""),
            1 => format!("\"say \"\"{k}\"\"\""),
            2 => format!("\"two\nlines {k}\""),
            _ => format!("r{k}"),
        };
        let end: &[u8] = if k % 3 == 0 { b"\r\n" } else { b"\n" };
        text.extend_from_slice(format!("{label},{}", cells.join(",")).as_bytes());
        text.extend_from_slice(end);
        if k % 101 == 0 {
            text.extend_from_slice(b"\n\r\n");
        }
    }
    text
}

/// The tips of `joints` as the whole file read at once and solved in one batch give
/// them, formatted as `ctr-cli fk` writes them.
fn whole_file_tips(robot: &Path, joints: &[u8]) -> Vec<u8> {
    let spec = ctr_formats::RobotSpec::from_path(robot).unwrap();
    let table = JointTable::from_bytes(joints.to_vec(), "j.csv", &spec.robot, 1).unwrap();
    let model = ModelSpec::from_spec(&spec).rows().unwrap();
    let options = BatchOptions {
        threads: 1,
        ..Default::default()
    };
    let tips = batch_fk(&model, table.all_joints(), None, &options, &()).unwrap();
    let mut out = Vec::new();
    write_header(&mut out, &tip_header(table.header(), false).unwrap());
    for (row, fk) in tips.iter().enumerate() {
        let carried = match table.plain_line(row) {
            Some(line) => Carried::Line(line),
            None => Carried::Fields(table.fields(row)),
        };
        write_tip_row(&mut out, carried, fk.as_ref().unwrap(), false);
    }
    out
}

fn job(robot: &Path, joints: &Path, out: PathBuf, threads: usize) -> FkJob {
    FkJob {
        robot: Input::Path(robot.to_path_buf()),
        joints: Input::Path(joints.to_path_buf()),
        output: Output::Path(out),
        model: None,
        on_error: OnError::Fail,
        threads,
        margin: false,
        warn_margin: None,
    }
}

#[test]
fn a_streamed_job_writes_what_the_whole_file_gives_on_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let robot = common::shared().join("robots/nitinol3.toml");
    let joints = dir.path().join("joints.csv");
    let data = joint_file(ROWS);
    assert!(data.len() > 1 << 20, "{} bytes: one block only", data.len());
    std::fs::write(&joints, &data).unwrap();
    let want = whole_file_tips(&robot, &data);
    for threads in [1, 2, 3] {
        let out = dir.path().join(format!("tips-{threads}.csv"));
        let summary = run_fk(&job(&robot, &joints, out.clone(), threads), &()).unwrap();
        assert_eq!((summary.rows, summary.written), (ROWS, ROWS));
        let got = std::fs::read(&out).unwrap();
        assert!(
            got == want,
            "{threads} threads: the output differs from the whole file's"
        );
    }
}

#[test]
fn the_first_bad_row_wins_over_errors_found_before_it_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let robot = common::shared().join("robots/nitinol3.toml");
    let joints = dir.path().join("joints.csv");
    let mut data = joint_file(3000);
    data.extend_from_slice(b"late,20,0,40,0,60,abc\n");
    std::fs::write(&joints, &data).unwrap();
    let bad_line = 1 + String::from_utf8_lossy(&data).lines().count();
    let is_bad_row = |e: &ctr_formats::Error| {
        matches!(e.kind(), ErrorKind::NotANumber { column, .. } if column == "theta3_deg")
            && e.location().line == Some(bad_line - 1)
    };
    // a missing output directory is found before solving, but reported after the rows
    let nowhere = dir.path().join("missing/tips.csv");
    for threads in [1, 2] {
        let e = run_fk(&job(&robot, &joints, nowhere.clone(), threads), &()).unwrap_err();
        assert!(is_bad_row(&e), "{threads} threads: {e}");
    }
    // a row the robot cannot take is refused when read: the first bad row either way
    let mut early = data.clone();
    let at = early.iter().position(|&b| b == b'\n').unwrap() + 1;
    early.splice(at..at, b"early,20,0,10,0,60,0\n".iter().copied());
    std::fs::write(&joints, &early).unwrap();
    let out = dir.path().join("tips.csv");
    let e = run_fk(&job(&robot, &joints, out.clone(), 2), &()).unwrap_err();
    assert_eq!(e.location().line, Some(2), "{e}");
    assert!(!out.exists(), "no output for a bad input");
}

#[test]
fn rows_that_do_not_converge_are_counted_over_the_whole_file_but_a_bad_row_comes_first() {
    let dir = tempfile::tempdir().unwrap();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/cli/snap");
    let robot = fixtures.join("robot.toml");
    let snap = std::fs::read_to_string(fixtures.join("joints.csv")).unwrap();
    let mut lines = snap.lines();
    let header = lines.next().unwrap();
    let rows: Vec<&str> = lines.collect();
    // the fixture's rows, line 5 does not converge; then many copies of its first row
    let mut text = format!("{header}\n{}\n", rows.join("\n"));
    for _ in 0..2000 {
        text += rows[0];
        text += "\n";
    }
    let joints = dir.path().join("joints.csv");
    std::fs::write(&joints, &text).unwrap();
    let out = dir.path().join("tips.csv");
    let e = run_fk(&job(&robot, &joints, out.clone(), 2), &()).unwrap_err();
    assert!(
        matches!(e.kind(), ErrorKind::SolverFailed { failed: 1, rows, .. } if *rows == 2006),
        "{e}"
    );
    assert_eq!(e.location().line, Some(5));
    // the same with a bad cell on the last line: that comes first
    let fields = rows[0].split(',').count();
    text += &vec!["x"; fields].join(",");
    text += "\n";
    std::fs::write(&joints, &text).unwrap();
    let e = run_fk(&job(&robot, &joints, out, 2), &()).unwrap_err();
    assert!(matches!(e.kind(), ErrorKind::NotANumber { .. }), "{e}");
    assert_eq!(e.location().line, Some(2008), "{e}");
}

#[test]
fn parquet_in_and_out_give_the_csv_run_s_tips() {
    let dir = tempfile::tempdir().unwrap();
    let robot_path = common::shared().join("robots/nitinol3.toml");
    let data = joint_file(2000);
    let joints = dir.path().join("joints.csv");
    std::fs::write(&joints, &data).unwrap();
    // the same rows as Parquet: the label as text, the joints as doubles
    let spec = ctr_formats::RobotSpec::from_path(&robot_path).unwrap();
    let table = JointTable::from_bytes(data, "j.csv", &spec.robot, 1).unwrap();
    let joints_parquet = dir.path().join("joints.parquet");
    let mut types = vec![ColumnType::text("label")];
    types.extend(table.header()[1..].iter().map(|c| ColumnType::double(c)));
    let mut out = ParquetOutput::create(&joints_parquet, types).unwrap();
    let mut batch = Batch::default();
    let labels: Vec<String> = (0..table.len())
        .map(|r| table.fields(r).next().unwrap().to_owned())
        .collect();
    batch.push_texts(labels.iter().map(String::as_str));
    for j in 0..6 {
        batch.push_doubles((0..table.len()).map(|r| table.joints(r)[j]).collect());
    }
    out.write(batch).unwrap();
    out.commit().unwrap();

    let run = |input: &Path, out: &str| {
        let out = dir.path().join(out);
        run_fk(&job(&robot_path, input, out.clone(), 2), &()).unwrap();
        out
    };
    let csv = std::fs::read(run(&joints, "tips.csv")).unwrap();
    // Parquet in, CSV out: the CSV run's bytes (the label quoted as CSV needs it, the
    // joints in shortest round-trip form as the generated file has them)
    let from_parquet = std::fs::read(run(&joints_parquet, "tips-from-parquet.csv")).unwrap();
    assert!(
        csv == from_parquet,
        "Parquet in, CSV out differs from the CSV run"
    );
    // Parquet out, from either input: the same tips as the CSV run's, to the bit
    let want = TargetTable::from_path(&dir.path().join("tips.csv"), false).unwrap();
    for input in [&joints, &joints_parquet] {
        let tips = TargetTable::from_path(&run(input, "tips.parquet"), false).unwrap();
        assert_eq!(tips.header(), want.header());
        assert!(tips.targets() == want.targets(), "{}", input.display());
    }
}

//! Parquet joint, target and recording files: read as their CSV twins are (the same
//! numbers, the input's columns carried with their own types), in pieces whatever the
//! row groups; bad files refused with the file, row and column named.

use ctr_core::TubeParams;
use ctr_formats::TargetTable;
use ctr_formats::{AnyRobot, Batch, ColumnType, JointStream, ParquetOutput, Recording};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int32Type, Int64Type};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::parser::parse_message_type;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A one-tube robot: s1 in [0, 180] mm.
fn robot() -> AnyRobot {
    let t = TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    AnyRobot::new(&[t]).unwrap()
}

/// The values of one column for [`write`].
enum Cells {
    Doubles(Vec<Option<f64>>),
    Ints(Vec<i32>),
    Longs(Vec<i64>),
    Texts(Vec<&'static str>),
}

/// Writes a Parquet file with the schema `message` (the parquet crate's text form)
/// and the columns `cells`, in row groups of `group` rows.
fn write(path: &Path, message: &str, cells: &[Cells], group: usize) {
    let schema = Arc::new(parse_message_type(message).unwrap());
    let props = Arc::new(WriterProperties::builder().build());
    let file = std::fs::File::create(path).unwrap();
    let mut w = SerializedFileWriter::new(file, schema, props).unwrap();
    let rows = match &cells[0] {
        Cells::Doubles(v) => v.len(),
        Cells::Ints(v) => v.len(),
        Cells::Longs(v) => v.len(),
        Cells::Texts(v) => v.len(),
    };
    for start in (0..rows).step_by(group.max(1)) {
        let end = (start + group).min(rows);
        let mut g = w.next_row_group().unwrap();
        for c in cells {
            let mut col = g.next_column().unwrap().unwrap();
            match c {
                Cells::Doubles(v) => {
                    let v = &v[start..end];
                    let present: Vec<f64> = v.iter().flatten().copied().collect();
                    let def: Vec<i16> = v.iter().map(|x| i16::from(x.is_some())).collect();
                    let optional = col.typed::<DoubleType>().get_descriptor().max_def_level() > 0;
                    let def = optional.then_some(&def[..]);
                    col.typed::<DoubleType>()
                        .write_batch(&present, def, None)
                        .unwrap();
                }
                Cells::Ints(v) => {
                    col.typed::<Int32Type>()
                        .write_batch(&v[start..end], None, None)
                        .unwrap();
                }
                Cells::Longs(v) => {
                    col.typed::<Int64Type>()
                        .write_batch(&v[start..end], None, None)
                        .unwrap();
                }
                Cells::Texts(v) => {
                    let v: Vec<ByteArray> = v[start..end].iter().map(|s| (*s).into()).collect();
                    col.typed::<ByteArrayType>()
                        .write_batch(&v, None, None)
                        .unwrap();
                }
            }
            col.close().unwrap();
        }
        g.close().unwrap();
    }
    w.close().unwrap();
}

fn temp(dir: &tempfile::TempDir, name: &str) -> PathBuf {
    dir.path().join(name)
}

/// The error of reading joint file `path` for the one-tube robot, whole.
fn joint_error(path: &Path) -> String {
    let robot = robot();
    let mut s = match JointStream::from_path(path, &robot) {
        Ok(s) => s,
        Err(e) => return e.to_string(),
    };
    let parser = s.parser(false);
    while let Some(piece) = s.next_piece(2) {
        if let Err(e) = piece.parse(&parser) {
            return e.to_string();
        }
    }
    panic!("{} read without error", path.display())
}

#[test]
fn joints_in_pieces_across_row_groups_equal_the_csv_twin() {
    let dir = tempfile::tempdir().unwrap();
    let n = 23;
    let s1: Vec<Option<f64>> = (0..n).map(|k| Some(10.0 + 0.1 * k as f64)).collect();
    let theta: Vec<i32> = (0..n).map(|k| k as i32 - 5).collect();
    let labels: Vec<&'static str> = (0..n)
        .map(|k| if k % 2 == 0 { "a,b" } else { "c" })
        .collect();
    let path = temp(&dir, "j.parquet");
    write(
        &path,
        "message m { REQUIRED BYTE_ARRAY label (UTF8); OPTIONAL DOUBLE s1_mm; REQUIRED INT32 theta1_deg; }",
        &[Cells::Texts(labels.clone()), Cells::Doubles(s1.clone()), Cells::Ints(theta.clone())],
        5,
    );
    let csv: String = std::iter::once("label,s1_mm,theta1_deg\n".to_owned())
        .chain((0..n).map(|k| format!("\"{}\",{},{}\n", labels[k], s1[k].unwrap(), theta[k])))
        .collect();
    let robot = robot();
    let read_all = |mut s: JointStream<'_>| {
        let parser = s.parser(false);
        let mut joints = Vec::new();
        let mut carried = Vec::new();
        while let Some(piece) = s.next_piece(7) {
            let rows = piece.parse(&parser).unwrap();
            joints.extend_from_slice(rows.all_joints());
            for r in 0..rows.len() {
                let fields: Vec<String> = (0..3).map(|c| rows.field(r, c).into_owned()).collect();
                carried.push(fields);
            }
        }
        (joints, carried)
    };
    let from_parquet = read_all(JointStream::from_path(&path, &robot).unwrap());
    let from_csv = read_all(JointStream::from_reader(csv.as_bytes(), "j.csv", &robot).unwrap());
    assert_eq!(from_parquet.0, from_csv.0);
    // the cells read as the CSV's (the integers as integers)
    assert_eq!(from_parquet.1, from_csv.1);
    assert_eq!(from_parquet.0.len(), 2 * n);
}

#[test]
fn bad_joint_files_name_the_file_row_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| temp(&dir, name);
    let ok_theta = || Cells::Doubles(vec![Some(0.0), Some(1.0), Some(2.0)]);
    // a misspelt column
    write(
        &p("misspelt.parquet"),
        "message m { REQUIRED DOUBLE s1_mm; REQUIRED DOUBLE theta1; }",
        &[Cells::Doubles(vec![Some(10.0); 3]), ok_theta()],
        3,
    );
    assert_eq!(
        joint_error(&p("misspelt.parquet")),
        format!(
            "{}: missing column theta1_deg (found \"theta1\": did you mean theta1_deg?)",
            p("misspelt.parquet").display()
        )
    );
    // text where numbers are wanted
    write(
        &p("text.parquet"),
        "message m { REQUIRED BYTE_ARRAY s1_mm (UTF8); REQUIRED DOUBLE theta1_deg; }",
        &[Cells::Texts(vec!["10"; 3]), ok_theta()],
        3,
    );
    assert_eq!(
        joint_error(&p("text.parquet")),
        format!(
            "{}: column s1_mm: BYTE_ARRAY (UTF8), wanted numbers (DOUBLE, FLOAT, INT32 or INT64)",
            p("text.parquet").display()
        )
    );
    // a timestamp is not a number of mm
    write(
        &p("time.parquet"),
        "message m { REQUIRED INT64 s1_mm (TIMESTAMP(MILLIS,true)); REQUIRED DOUBLE theta1_deg; }",
        &[Cells::Longs(vec![10; 3]), ok_theta()],
        3,
    );
    assert!(joint_error(&p("time.parquet")).contains("column s1_mm: INT64 (TIMESTAMP"));
    // NaN on the third row (in the second row group), a null on the second
    write(
        &p("nan.parquet"),
        "message m { REQUIRED DOUBLE s1_mm; REQUIRED DOUBLE theta1_deg; }",
        &[
            Cells::Doubles(vec![Some(10.0), Some(11.0), Some(f64::NAN)]),
            ok_theta(),
        ],
        2,
    );
    assert_eq!(
        joint_error(&p("nan.parquet")),
        format!(
            "{}: row 3: column s1_mm: \"NaN\" is not a finite number",
            p("nan.parquet").display()
        )
    );
    write(
        &p("null.parquet"),
        "message m { REQUIRED DOUBLE s1_mm; OPTIONAL DOUBLE theta1_deg; }",
        &[
            Cells::Doubles(vec![Some(10.0); 3]),
            Cells::Doubles(vec![Some(0.0), None, Some(2.0)]),
        ],
        3,
    );
    assert_eq!(
        joint_error(&p("null.parquet")),
        format!(
            "{}: row 2: column theta1_deg: no value (null)",
            p("null.parquet").display()
        )
    );
    // joints the robot cannot take
    write(
        &p("long.parquet"),
        "message m { REQUIRED DOUBLE s1_mm; REQUIRED DOUBLE theta1_deg; }",
        &[
            Cells::Doubles(vec![Some(10.0), Some(200.0), Some(10.0)]),
            ok_theta(),
        ],
        3,
    );
    let e = joint_error(&p("long.parquet"));
    assert!(
        e.starts_with(&format!("{}: row 2: ", p("long.parquet").display())),
        "{e}"
    );
    // not Parquet at all
    std::fs::write(p("not.parquet"), "s1_mm,theta1_deg\n10,0\n").unwrap();
    assert_eq!(
        joint_error(&p("not.parquet")),
        format!("{}: not a Parquet file (it does not start with PAR1; it looks like text or another format)", p("not.parquet").display())
    );
    // a damaged file
    let mut cut = std::fs::read(p("nan.parquet")).unwrap();
    cut.truncate(cut.len() - 12);
    std::fs::write(p("cut.parquet"), &cut).unwrap();
    assert!(joint_error(&p("cut.parquet"))
        .starts_with(&format!("{}: read: ", p("cut.parquet").display())));
}

#[test]
fn a_parquet_file_under_another_name_or_on_a_stream_reads_as_parquet() {
    let dir = tempfile::tempdir().unwrap();
    let path = temp(&dir, "j.parquet");
    write(
        &path,
        "message m { REQUIRED DOUBLE s1_mm; REQUIRED DOUBLE theta1_deg; }",
        &[
            Cells::Doubles(vec![Some(10.0), Some(20.0)]),
            Cells::Doubles(vec![Some(1.0), Some(2.0)]),
        ],
        2,
    );
    let misnamed = temp(&dir, "j.csv");
    std::fs::copy(&path, &misnamed).unwrap();
    let robot = robot();
    for mut s in [
        JointStream::from_path(&misnamed, &robot).unwrap(),
        JointStream::from_reader(std::fs::File::open(&path).unwrap(), "<stdin>", &robot).unwrap(),
    ] {
        let parser = s.parser(false);
        let rows = s.next_piece(10).unwrap().parse(&parser).unwrap();
        assert_eq!(rows.all_joints(), [10.0, 1.0, 20.0, 2.0]);
        assert!(rows.is_rows());
    }
}

#[test]
fn targets_and_recordings_read_from_parquet_as_from_csv() {
    let dir = tempfile::tempdir().unwrap();
    let targets = temp(&dir, "t.parquet");
    let mut out = ParquetOutput::create(
        &targets,
        ["label", "x_mm", "y_mm", "z_mm"]
            .iter()
            .map(|c| {
                if *c == "label" {
                    ColumnType::text(c)
                } else {
                    ColumnType::double(c)
                }
            })
            .collect(),
    )
    .unwrap();
    let mut b = Batch::default();
    b.push_texts(["p", "q"]);
    b.push_doubles(vec![1.0, 2.0]);
    b.push_doubles(vec![3.0, 4.0]);
    b.push_doubles(vec![90.0, 91.5]);
    out.write(b).unwrap();
    out.commit().unwrap();
    let t = TargetTable::from_path(&targets, false).unwrap();
    let csv = TargetTable::read(
        "label,x_mm,y_mm,z_mm\np,1,3,90\nq,2,4,91.5\n".as_bytes(),
        "t.csv",
        false,
    )
    .unwrap();
    assert_eq!(t.targets(), csv.targets());
    assert_eq!((t.line(1), t.is_rows()), (2, true));

    let rec = temp(&dir, "r.parquet");
    write(
        &rec,
        "message m { REQUIRED DOUBLE t_s; REQUIRED BYTE_ARRAY run (UTF8); REQUIRED DOUBLE s1_mm; \
         REQUIRED DOUBLE theta1_deg; REQUIRED DOUBLE x_mm; REQUIRED DOUBLE y_mm; OPTIONAL DOUBLE z_mm; }",
        &[
            Cells::Doubles(vec![Some(0.0), Some(1.0), Some(0.0)]),
            Cells::Texts(vec!["a", "a", "b"]),
            Cells::Doubles(vec![Some(10.0), Some(11.0), Some(12.0)]),
            Cells::Doubles(vec![Some(0.0); 3]),
            Cells::Doubles(vec![Some(0.0); 3]),
            Cells::Doubles(vec![Some(0.0); 3]),
            Cells::Doubles(vec![Some(10.0), Some(11.0), Some(12.0)]),
        ],
        2,
    );
    let from_parquet = Recording::from_path(&rec, 1).unwrap();
    let csv = "t_s,run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n0,a,10,0,0,0,10\n1,a,11,0,0,0,11\n0,b,12,0,0,0,12\n";
    let from_csv = Recording::read(csv.as_bytes(), "r.csv", 1).unwrap();
    assert_eq!(from_parquet.runs, from_csv.runs);
    let q = |r: &Recording| {
        r.rows
            .iter()
            .map(|x| (x.t_s, x.q.clone(), x.p))
            .collect::<Vec<_>>()
    };
    assert_eq!(q(&from_parquet), q(&from_csv));
    // rows, not lines: the first row is row 1
    assert_eq!(from_parquet.rows[2].line, 3);
    // a null tip is refused with its row
    write(
        &rec,
        "message m { REQUIRED DOUBLE s1_mm; REQUIRED DOUBLE theta1_deg; REQUIRED DOUBLE x_mm; \
         REQUIRED DOUBLE y_mm; OPTIONAL DOUBLE z_mm; }",
        &[
            Cells::Doubles(vec![Some(10.0), Some(11.0)]),
            Cells::Doubles(vec![Some(0.0); 2]),
            Cells::Doubles(vec![Some(0.0); 2]),
            Cells::Doubles(vec![Some(0.0); 2]),
            Cells::Doubles(vec![Some(10.0), None]),
        ],
        2,
    );
    let e = Recording::from_path(&rec, 1).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("{}: row 2: column z_mm: no value (null)", rec.display())
    );
}

//! Reading and writing the files of a forward-kinematics job, per row, on one thread,
//! CSV and Parquet side by side in one run (compare the ratios: the machine is shared):
//!
//! - `cut`: the serial part of reading a CSV joint file: finding where the pieces of
//!   rows end (`JointStream::next_piece`), without parsing them;
//! - `read`: cutting and parsing every piece (fields, numbers, the robot's check), CSV
//!   and Parquet (the same rows, written by `ParquetOutput`);
//! - `write`: the tip rows of a solved file, CSV (`write_tip_row_for`: the input's line,
//!   then the pose in shortest round-trip form) and Parquet (`tip_batch`, the input's
//!   columns, `ParquetOutput`), each to a file as `ctr-cli fk` writes it (a temporary
//!   file beside it, synced and renamed).
//!
//! Run: `cargo bench --bench io` (`taskset -c 1` for one core). The rows: 100,000 of a
//! smooth nitinol3 trajectory with a text label, as `scripts/bench.sh` generates them.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use ctr_core::{Joints, Model, Request, Solver};
use ctr_formats::{tip_batch, tip_column_types, write_tip_row_for, AnyRobot, Batch};
use ctr_formats::{ColumnType, FkResult, JointRows, JointStream, ParquetOutput, TipColumns};
use ctr_suite::robot;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

/// Rows of the benchmark's joint file.
const ROWS: usize = 100_000;

/// Rows a piece of the stream holds (as `ctr-cli fk` cuts them).
const PIECE_ROWS: usize = 512;

/// The joint file as CSV text: a label and the joints of a slow motion sampled at
/// 1 kHz inside nitinol3's stable ranges (`scripts/bench.sh`'s trajectory).
fn joint_csv(rows: usize) -> Vec<u8> {
    let mut text = String::from("label,s1_mm,theta1_deg,s2_mm,theta2_deg,s3_mm,theta3_deg\n");
    for k in 0..rows {
        let t = 2.0 * std::f64::consts::PI * (k as f64 / 20_000.0);
        let mut s = 0.0;
        let mut cells = Vec::with_capacity(6);
        for i in 0..3 {
            let f = 1.0 + i as f64;
            s += 30.0 + 16.0 * (f * t + 0.3 * f).sin();
            cells.push(format!("{s}"));
            cells.push(format!("{}", 170.0 * (0.5 * f * t + f).sin()));
        }
        text += &format!("r{k},{}\n", cells.join(","));
    }
    text.into_bytes()
}

/// Every piece of a joint stream, parsed.
fn read_all(mut stream: JointStream<'_>) -> Vec<JointRows> {
    let parser = stream.parser(false);
    let mut pieces = Vec::new();
    while let Some(piece) = stream.next_piece(PIECE_ROWS) {
        pieces.push(piece.parse(&parser).unwrap());
    }
    pieces
}

/// The tips of every row, solved warm along the file.
fn tips(pieces: &[JointRows]) -> Vec<FkResult> {
    let robot = robot::<3>("nitinol3");
    let mut solver = Solver::default();
    let mut out = Vec::new();
    for rows in pieces {
        for r in 0..rows.len() {
            let q = rows.joints(r);
            let j = Joints::from_mm_deg([q[0], q[2], q[4]], [q[1], q[3], q[5]]);
            let sol = solver
                .solve(&robot, Request::new(j, Model::Torsion))
                .unwrap();
            out.push(FkResult::from_solution(&sol, f64::NAN));
        }
    }
    out
}

/// Writes the joint rows (`csv`, read as `pieces`) as a Parquet file at `path`.
fn write_joints_parquet(path: &Path, header: &[String], pieces: &[JointRows]) {
    let mut types = vec![ColumnType::text(&header[0])];
    types.extend(header[1..].iter().map(|c| ColumnType::double(c)));
    let mut out = ParquetOutput::create(path, types).unwrap();
    for rows in pieces {
        let mut batch = Batch::default();
        let labels: Vec<String> = (0..rows.len())
            .map(|r| rows.field(r, 0).into_owned())
            .collect();
        batch.push_texts(labels.iter().map(String::as_str));
        for j in 0..6 {
            batch.push_doubles((0..rows.len()).map(|r| rows.joints(r)[j]).collect());
        }
        out.write(batch).unwrap();
    }
    out.commit().unwrap();
}

fn io(c: &mut Criterion) {
    let spec =
        ctr_formats::RobotSpec::from_path(&ctr_suite::shared_data().join("robots/nitinol3.toml"))
            .unwrap();
    let robot: AnyRobot = spec.robot;
    let csv = joint_csv(ROWS);
    let dir = tempfile::tempdir().unwrap();
    let pieces = read_all(JointStream::from_reader(&csv[..], "j.csv", &robot).unwrap());
    let header = JointStream::from_reader(&csv[..], "j.csv", &robot)
        .unwrap()
        .header()
        .to_vec();
    let joints_parquet = dir.path().join("j.parquet");
    write_joints_parquet(&joints_parquet, &header, &pieces);
    let parquet_pieces = read_all(JointStream::from_path(&joints_parquet, &robot).unwrap());
    let tips = tips(&pieces);

    let mut group = c.benchmark_group("io");
    group
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(10)
        .throughput(Throughput::Elements(ROWS as u64));
    group.bench_function("cut/csv", |b| {
        b.iter(|| {
            let mut s = JointStream::from_reader(&csv[..], "j.csv", &robot).unwrap();
            let mut n = 0;
            while let Some(piece) = s.next_piece(PIECE_ROWS) {
                n += black_box(piece).first_row();
            }
            n
        })
    });
    group.bench_function("read/csv", |b| {
        b.iter(|| read_all(JointStream::from_reader(&csv[..], "j.csv", &robot).unwrap()))
    });
    group.bench_function("read/parquet", |b| {
        b.iter(|| read_all(JointStream::from_path(&joints_parquet, &robot).unwrap()))
    });
    let extra = TipColumns::default();
    group.bench_function("write/csv", |b| {
        b.iter(|| {
            let mut out = Vec::with_capacity(ROWS * 200);
            let mut k = 0;
            for rows in &pieces {
                for r in 0..rows.len() {
                    write_tip_row_for(&mut out, rows.carried(r), &tips[k], extra);
                    k += 1;
                }
            }
            // written as fk writes it: a temporary file, synced, renamed into place
            let mut file = ctr_formats::AtomicFile::create(&dir.path().join("t.csv")).unwrap();
            file.write_through(&out).unwrap();
            file.commit().unwrap();
        })
    });
    group.bench_function("write/parquet", |b| {
        b.iter(|| {
            let mut types = JointStream::from_path(&joints_parquet, &robot)
                .unwrap()
                .column_types();
            types.extend(tip_column_types(extra));
            let mut out = ParquetOutput::create(&dir.path().join("t.parquet"), types).unwrap();
            let mut k = 0;
            for rows in &parquet_pieces {
                let all: Vec<usize> = (0..rows.len()).collect();
                let mut batch = rows.batch(&all);
                batch.append(tip_batch(&tips[k..k + rows.len()], extra));
                k += rows.len();
                out.write(batch).unwrap();
            }
            out.commit().unwrap();
        })
    });
    group.finish();
}

criterion_group!(benches, io);
criterion_main!(benches);

//! End-to-end tests of `ctr-cli hw`: the real binary serves an emulated bus on a
//! pseudo-terminal (`hw emulate`, a child process) and drives it (`hw ping`, `move`,
//! `home`, `run`), with faults injected by `--fault`.
//!
//! The emulator runs 50 times faster than real time so that moves take milliseconds.
//! Every child is killed when its test ends (and `hw emulate` also exits when its
//! standard input, a pipe held by the test, closes); every wait has a generous deadline
//! for a loaded machine.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, ChildStdin, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

mod common;
use common::{cli, repo, spawn, stderr, table};

/// Longest any single command may take before the test fails (and kills it).
const DEADLINE: Duration = Duration::from_secs(60);

fn rig_toml() -> String {
    repo("tests/cli/hw/rig.toml").display().to_string()
}

fn trajectory() -> String {
    repo("tests/cli/hw/trajectory.csv").display().to_string()
}

/// `ctr-cli hw emulate ...` running in the background; killed on drop.
struct Emulator {
    child: Child,
    stdin: Option<ChildStdin>,
    port: String,
}

impl Emulator {
    /// `hw emulate --tubes 2 --time-scale 50 EXTRA...`.
    fn start(extra: &[&str]) -> Emulator {
        Emulator::start_at("50", extra)
    }

    fn start_at(time_scale: &str, extra: &[&str]) -> Emulator {
        let mut child = cli()
            .args(["hw", "emulate", "--tubes", "2", "--time-scale", time_scale])
            .args(extra)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let stdin = child.stdin.take();
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = BufReader::new(stdout).read_line(&mut line);
            let _ = tx.send(line);
        });
        let mut emulator = Emulator {
            child,
            stdin,
            port: String::new(),
        };
        let line = rx
            .recv_timeout(DEADLINE)
            .expect("hw emulate prints its port");
        emulator.port = line.trim().to_owned();
        assert!(emulator.port.starts_with("/dev/"), "port {line:?}");
        emulator
    }

    /// `ctr-cli hw COMMAND --port PORT --robot rig.toml ARGS...`.
    fn hw(&self, command: &str, args: &[&str]) -> Output {
        let rig = rig_toml();
        let mut all = vec![
            "hw",
            command,
            "--port",
            &self.port,
            "--robot",
            &rig,
            "--timeout-ms",
            "250",
        ];
        all.extend_from_slice(args);
        run(&all)
    }

    /// [`Emulator::hw`], checked to succeed: its standard output.
    fn hw_ok(&self, command: &str, args: &[&str]) -> String {
        let o = self.hw(command, args);
        assert_ok(&o);
        stdout(&o)
    }

    /// `hw run --joints JOINTS -o RECORDING EXTRA...`.
    fn run_to(&self, joints: &str, recording: &str, extra: &[&str]) -> Output {
        let mut args = vec!["--joints", joints, "-o", recording];
        args.extend_from_slice(extra);
        self.hw("run", &args)
    }

    /// `hw run` of the rig's trajectory (`tests/cli/hw/trajectory.csv`) into `recording`.
    fn record(&self, recording: &str, extra: &[&str]) -> Output {
        self.run_to(&trajectory(), recording, extra)
    }
}

/// A temporary directory for a test's files, removed when dropped.
struct Scratch(tempfile::TempDir);

impl Scratch {
    fn new() -> Scratch {
        Scratch(tempfile::tempdir().unwrap())
    }

    /// The path of `name` in the directory, as an argument.
    fn file(&self, name: &str) -> String {
        self.0.path().join(name).to_str().unwrap().to_owned()
    }

    /// Writes `text` to `name` and returns its path.
    fn write(&self, name: &str, text: &str) -> String {
        let path = self.file(name);
        std::fs::write(&path, text).unwrap();
        path
    }
}

/// Plays the rig's trajectory on an emulator with `--fault` for each of `faults`: the
/// emulator (to look at the motors afterwards), the run's output and the recording.
fn run_with_faults(faults: &[&str], extra: &[&str]) -> (Emulator, Output, String) {
    let specs: Vec<&str> = faults.iter().flat_map(|f| ["--fault", f]).collect();
    let emulator = Emulator::start(&specs);
    let dir = Scratch::new();
    let recording = dir.file("recording.csv");
    let o = emulator.record(&recording, extra);
    let text = std::fs::read_to_string(&recording).unwrap();
    (emulator, o, text)
}

/// Checks that a command failed with `code` and one line on stderr containing every
/// part; returns that line.
fn one_line_failure(o: &Output, code: i32, parts: &[&str]) -> String {
    assert_eq!(o.status.code(), Some(code), "{}", stderr(o));
    let err = stderr(o);
    assert_eq!(err.lines().count(), 1, "{err}");
    for part in parts {
        assert!(err.contains(part), "`{part}` not in: {err}");
    }
    err
}

/// Checks that a command succeeded.
fn assert_ok(o: &Output) {
    assert_eq!(o.status.code(), Some(0), "{}", stderr(o));
}

impl Drop for Emulator {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs `ctr-cli ARGS` to completion, killing it if it outlives [`DEADLINE`].
fn run(args: &[&str]) -> Output {
    common::wait_within(
        spawn(args, Stdio::null()),
        DEADLINE,
        &format!("ctr-cli {args:?}"),
    )
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn num(s: &str) -> f64 {
    s.parse()
        .unwrap_or_else(|_| panic!("{s:?} is not a number"))
}

/// Half an encoder tick of the rig's joints: 8 mm per 4096 ticks, 360 degrees per 4096.
fn half_tick(column: &str) -> f64 {
    if column.starts_with('s') {
        0.5 * 8.0 / 4096.0
    } else {
        0.5 * 360.0 / 4096.0
    }
}

const JOINTS: [&str; 4] = ["s1_mm", "theta1_deg", "s2_mm", "theta2_deg"];
const RECORDING_HEADER: &str = "t_s,run,s1_mm,theta1_deg,s2_mm,theta2_deg,\
    s1_read_mm,theta1_read_deg,s2_read_mm,theta2_read_deg,x_mm,y_mm,z_mm";

/// Checks a recording: the header, complete rows, time order, the commanded joints of
/// `expected` (trajectory rows) and read-backs within half a tick of them.
fn check_recording(text: &str, label: &str, expected: &[[f64; 4]]) {
    assert!(text.ends_with('\n'), "a row is cut short:\n{text}");
    let (header, rows) = table(text);
    assert_eq!(header.join(","), RECORDING_HEADER);
    assert_eq!(rows.len(), expected.len(), "{text}");
    let mut t_prev = 0.0;
    for (row, want) in rows.iter().zip(expected) {
        assert_eq!(row.len(), 13, "{row:?}");
        let t = num(&row[0]);
        assert!(t >= t_prev, "time goes back: {text}");
        t_prev = t;
        assert_eq!(row[1], label);
        for (k, column) in JOINTS.iter().enumerate() {
            let commanded = num(&row[2 + k]);
            let read = num(&row[6 + k]);
            assert_eq!(commanded, want[k], "{column} in {row:?}");
            assert!(
                (read - commanded).abs() <= half_tick(column),
                "{column}: read {read}, commanded {commanded}"
            );
        }
        assert_eq!(&row[10..], ["", "", ""], "tip columns are left empty");
    }
}

fn trajectory_rows() -> Vec<[f64; 4]> {
    let text = std::fs::read_to_string(trajectory()).unwrap();
    let (_, rows) = table(&text);
    rows.iter()
        .map(|r| [num(&r[1]), num(&r[2]), num(&r[3]), num(&r[4])])
        .collect()
}

/// `hw ping` rows as (joint, torque, hardware_error, position).
fn ping(emulator: &Emulator) -> Vec<(String, String, String, f64)> {
    let (header, rows) = table(&emulator.hw_ok("ping", &[]));
    assert_eq!(
        header.join(","),
        "joint,motor_id,model,firmware,torque,hardware_error,position"
    );
    rows.into_iter()
        .map(|r| {
            assert_eq!(r[2], "1020", "XM430-W350");
            (r[0].clone(), r[4].clone(), r[5].clone(), num(&r[6]))
        })
        .collect()
}

#[test]
fn ping_move_run_and_home_against_the_emulator() {
    let emulator = Emulator::start(&[]);
    let motors = ping(&emulator);
    let names: Vec<&str> = motors.iter().map(|m| m.0.as_str()).collect();
    assert_eq!(names, ["s1", "theta1", "s2", "theta2"]);
    assert!(motors.iter().all(|m| m.1 == "off" && m.2.is_empty()));
    // theta2's motor starts at 0 ticks, half a turn from theta2 = 0 (zero_offset_ticks)
    let start: Vec<f64> = motors.iter().map(|m| m.3).collect();
    assert_eq!(start, [0.0, 0.0, 0.0, -180.0]);

    // move, by name=value
    assert_eq!(
        emulator.hw_ok("move", &["--joints", "s1=20,theta1=90,s2_mm=70,theta2=-45"]),
        "s1_mm,theta1_deg,s2_mm,theta2_deg\n20,90,70,-45\n"
    );

    // move, by a one-row joint file
    let dir = Scratch::new();
    let one_row = dir.write(
        "one.csv",
        "theta2_deg,s2_mm,theta1_deg,s1_mm\n10,60,-30,15\n",
    );
    let (_, rows) = table(&emulator.hw_ok("move", &["--joints", &one_row]));
    let reached: Vec<f64> = rows[0].iter().map(|v| num(v)).collect();
    for ((got, want), column) in reached.iter().zip([15.0, -30.0, 60.0, 10.0]).zip(JOINTS) {
        assert!((got - want).abs() <= half_tick(column), "{column}: {got}");
    }

    // run a trajectory
    let recording = dir.file("recording.csv");
    let o = emulator.record(&recording, &[]);
    assert_ok(&o);
    assert!(o.stdout.is_empty() && o.stderr.is_empty());
    let text = std::fs::read_to_string(&recording).unwrap();
    check_recording(&text, "trajectory", &trajectory_rows());

    // a recording is never replaced by accident
    let o = emulator.record(&recording, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("exists already"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&recording).unwrap(), text);

    // the motors hold the last row, torque on
    let motors = ping(&emulator);
    assert!(motors.iter().all(|m| m.1 == "on" && m.2.is_empty()));
    let last = *trajectory_rows().last().unwrap();
    for (m, (want, column)) in motors.iter().zip(last.iter().zip(JOINTS)) {
        assert!((m.3 - want).abs() <= half_tick(column), "{m:?}");
    }

    // home
    assert_eq!(
        emulator.hw_ok("home", &[]),
        "s1_mm,theta1_deg,s2_mm,theta2_deg\n0,0,0,0\n"
    );
}

#[test]
fn a_parquet_recording_holds_the_rows_a_csv_recording_holds() {
    let emulator = Emulator::start(&[]);
    let dir = Scratch::new();
    let recording = dir.file("recording.parquet");
    let o = emulator.record(&recording, &[]);
    assert_ok(&o);
    let bytes = std::fs::read(&recording).unwrap();
    assert!(bytes.starts_with(b"PAR1") && bytes.ends_with(b"PAR1"));
    let left: Vec<_> = std::fs::read_dir(dir.0.path()).unwrap().collect();
    assert_eq!(left.len(), 1, "the journal is gone: {left:?}");
    // the recording's columns, read back: the commanded joints of the trajectory, the
    // run label, the tip left empty (null) for the tracker
    let spec = ctr_formats::RobotSpec::from_path(Path::new(&rig_toml())).unwrap();
    let mut s = ctr_formats::JointStream::from_path(Path::new(&recording), &spec.robot).unwrap();
    let header: Vec<&str> = s.header().iter().map(String::as_str).collect();
    assert_eq!(header.join(","), RECORDING_HEADER.replace(' ', ""));
    let parser = s.parser(false);
    let rows = s.next_piece(1000).unwrap().parse(&parser).unwrap();
    let want = trajectory_rows();
    assert_eq!(rows.len(), want.len());
    for (r, q) in want.iter().enumerate() {
        assert_eq!(rows.joints(r), q);
        assert_eq!(rows.field(r, 1), "trajectory");
        assert_eq!(rows.field(r, 10), "", "x_mm is null");
    }
    // a recording from the tracker needs its tip: the null is named with its row
    let e = ctr_formats::Recording::from_path(Path::new(&recording), 2).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("{recording}: row 1: column x_mm: no value (null)")
    );
}

#[test]
fn timed_trajectory_follows_t_s_and_writes_to_stdout() {
    let emulator = Emulator::start(&[]);
    let dir = Scratch::new();
    let timed = dir.write(
        "timed.csv",
        "t_s,s1_mm,theta1_deg,s2_mm,theta2_deg\n\
         1.0,20,0,70,0\n\
         1.3,21,10,71,-10\n\
         1.6,22,20,72,-20\n",
    );
    let started = Instant::now();
    let o = emulator.run_to(&timed, "-", &["--run", "timed, 1"]);
    assert_ok(&o);
    assert!(started.elapsed() >= Duration::from_millis(600));
    let text = stdout(&o);
    check_recording(
        &text,
        "timed, 1",
        &[
            [20.0, 0.0, 70.0, 0.0],
            [21.0, 10.0, 71.0, -10.0],
            [22.0, 20.0, 72.0, -20.0],
        ],
    );
    // each row is read back when the next row is due (the last once still): t_s counts
    // from the first goal
    let (_, rows) = table(&text);
    let t: Vec<f64> = rows.iter().map(|r| num(&r[0])).collect();
    assert!(t[0] >= 0.3 && t[1] >= 0.6 && t[2] >= 0.6, "{t:?}");
}

#[test]
fn overload_stops_the_rig_names_the_packet_and_keeps_the_recording() {
    // Motor 2 (theta1) overloads with its fourth goal: the hold at enable is the first,
    // so during the third row.
    let (emulator, o, text) = run_with_faults(&["overload:2@4"], &[]);
    one_line_failure(
        &o,
        1,
        &[
            "error: ",
            "trajectory.csv:4: rig stopped: ID 2 raised a hardware alert answering SYNC_READ (broadcast) [FF FF FD 00 FE ",
            "; status [FF FF FD 00 02 ",
            "; ID 2 hardware error 0x20 (overload); holding IDs 1, 2, 3, 4",
            "recording.csv keeps 2 rows)",
        ],
    );
    check_recording(&text, "trajectory", &trajectory_rows()[..2]);
    // Held, not switched off: torque stays on except on the overloaded motor.
    let torque: Vec<(String, String, String)> = ping(&emulator)
        .into_iter()
        .map(|m| (m.0, m.1, m.2))
        .collect();
    assert_eq!(
        torque,
        [
            ("s1".into(), "on".into(), "".into()),
            ("theta1".into(), "off".into(), "overload".into()),
            ("s2".into(), "on".into(), "".into()),
            ("theta2".into(), "on".into(), "".into()),
        ]
    );
}

#[test]
fn torque_off_on_fault_switches_every_motor_off() {
    let (emulator, o, text) = run_with_faults(&["overload:3@2"], &["--torque-off-on-fault"]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(
        err.contains("trajectory.csv:2: rig stopped: ID 3 raised a hardware alert"),
        "{err}"
    );
    assert!(
        err.contains("; holding IDs 1, 2, 3, 4; torque off (")
            && err.trim_end().ends_with("recording.csv keeps 0 rows)"),
        "{err}"
    );
    check_recording(&text, "", &[]);
    assert!(ping(&emulator).iter().all(|m| m.1 == "off"));
}

#[test]
fn a_silent_motor_stops_the_rig_after_bounded_retries() {
    // Motor 3 (s2) stops answering after its third goal (the second row's).
    let (_emulator, o, text) = run_with_faults(&["no-reply:3@3x99"], &[]);
    one_line_failure(
        &o,
        1,
        &[
            "trajectory.csv:3: rig stopped: write SYNC_WRITE (broadcast) [FF FF FD 00 FE ",
            "to ID 3 unconfirmed",
            "no status from ID 3 for READ to ID 3 [FF FF FD 00 03 ",
            "after 3 attempt(s)",
            "holding IDs 1, 2, 4; could not hold ID 3",
            "recording.csv keeps 1 row)",
        ],
    );
    check_recording(&text, "trajectory", &trajectory_rows()[..1]);
}

#[test]
fn transient_wire_faults_are_retried_without_losing_or_repeating_a_row() {
    let faults = [
        "corrupt-crc:1@2x2",
        "drop-instruction:4@3",
        "drop-reply-bytes=4:2@4",
        "no-reply:3@5x2",
    ];
    let (_emulator, o, text) = run_with_faults(&faults, &["--run", "retried"]);
    assert_ok(&o);
    check_recording(&text, "retried", &trajectory_rows());
}

#[test]
fn motors_that_do_not_come_to_rest_are_held() {
    // 0.01 x real time: a move takes 100 times longer than at max_speed (5 s here),
    // and the wait allows twice that time at max_speed with --settle-margin 0.
    let emulator = Emulator::start_at("0.01", &[]);
    let o = emulator.hw(
        "move",
        &[
            "--joints",
            "s1=0.3,theta1=0,s2=0.3,theta2=-180",
            "--settle-margin",
            "0",
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("joints still moving after"), "{err}");
    assert!(err.contains("rig stopped: holding every motor"), "{err}");
    let motors = ping(&emulator);
    assert!(motors[0].3 > 0.0 && motors[0].3 < 0.3, "{motors:?}");
}

#[test]
fn nothing_is_sent_for_joints_beyond_the_limits() {
    let emulator = Emulator::start(&[]);
    let o = emulator.hw("move", &["--joints", "s1=20,theta1=0,s2=160,theta2=0"]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        stderr(&o),
        "error: --joints: joint s2: 160 mm is above its max limit 150 mm\n"
    );
    let dir = Scratch::new();
    let late = dir.write(
        "late.csv",
        "s1_mm,theta1_deg,s2_mm,theta2_deg\n20,0,70,0\n20,190,70,0\n",
    );
    let recording = dir.file("recording.csv");
    let o = emulator.run_to(&late, &recording, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("late.csv:3: joint theta1: 190 deg is above its max limit 180 deg"),
        "{}",
        stderr(&o)
    );
    assert!(!Path::new(&recording).exists());
    // the motors never moved nor got torque
    let motors = ping(&emulator);
    assert!(motors.iter().all(|m| m.1 == "off"));
    assert_eq!(
        motors.iter().map(|m| m.3).collect::<Vec<_>>(),
        [0.0, 0.0, 0.0, -180.0]
    );
}

#[test]
fn the_emulator_exits_when_its_standard_input_closes() {
    let mut emulator = Emulator::start(&[]);
    drop(emulator.stdin.take());
    let started = Instant::now();
    loop {
        if let Some(status) = emulator.child.try_wait().unwrap() {
            assert!(status.success(), "{status:?}");
            break;
        }
        assert!(started.elapsed() < DEADLINE, "hw emulate still running");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn bad_fault_specs_exit_2_and_missing_ports_exit_1() {
    let o = run(&["hw", "emulate", "--fault", "overheat:2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("unknown fault \"overheat\""),
        "{}",
        stderr(&o)
    );
    let o = run(&["hw", "emulate", "--tubes", "1", "--fault", "no-reply:3@2"]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(
        stderr(&o),
        "error: --fault: motor 3 is not on the bus (motors 1..2 with --tubes 1)\n"
    );
    // a port that cannot be opened is a hardware failure, not bad input
    let rig = rig_toml();
    let o = run(&["hw", "ping", "--port", "/nonexistent/tty", "--robot", &rig]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).starts_with("error: serial port /nonexistent/tty: "),
        "{}",
        stderr(&o)
    );
}

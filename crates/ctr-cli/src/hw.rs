//! `ctr-cli hw`: the servo rig on a serial port (`ping`, `home`, `move`, `run`) and the
//! emulated bus on a pseudo-terminal (`emulate`).
//!
//! Order of work for the rig commands: read the robot (its `[actuation]` is required)
//! and the joints, check every joint value against the contract, the robot's `[limits]`
//! and the actuation limits, and only then open the port. Nothing is sent for bad
//! input (exit 2). Once connected, any failure stops the rig ([`ctr_hw::rig`]: hold,
//! optionally torque off) and is reported as one line naming the packet (exit 1).

use crate::cli::{
    Connection, EmulateArgs, HomeArgs, HwCommand, Motion, MoveArgs, PingArgs, RunArgs,
};
use crate::Failure;
use ctr_formats::{JointId, JointTable, RecordingWriter, RobotSpec};
use ctr_hw::actuation::Actuation;
use ctr_hw::bus::{Bus, BusConfig, BusError};
use ctr_hw::control_table as ct;
use ctr_hw::emulator::{Emulator, EmulatorConfig};
use ctr_hw::rig::{Rig, RigConfig, RigError};
use ctr_hw::transport::SerialTransport;
use std::io::{IsTerminal, Read, Write};
use std::path::Path;
use std::time::{Duration, Instant};

/// Runs one `hw` subcommand.
pub fn run(command: HwCommand) -> Result<(), Failure> {
    match command {
        HwCommand::Emulate(args) => emulate(args),
        HwCommand::Ping(args) => ping(args),
        HwCommand::Home(args) => home(args),
        HwCommand::Move(args) => move_joints(args),
        HwCommand::Run(args) => play(args),
    }
}

fn input(message: impl Into<String>) -> Failure {
    Failure::Input(message.into())
}

fn hardware(message: impl Into<String>) -> Failure {
    Failure::Hardware(message.into())
}

/// `hw emulate`: serve an emulated bus until killed or standard input closes.
fn emulate(args: EmulateArgs) -> Result<(), Failure> {
    let motors = 2 * args.tubes;
    for spec in &args.fault {
        if let Some(id) = spec.motor.filter(|&id| id == 0 || id > motors) {
            return Err(input(format!(
                "--fault: motor {id} is not on the bus (motors 1..{motors} with --tubes {})",
                args.tubes
            )));
        }
    }
    let emulator = Emulator::new(EmulatorConfig {
        ids: (1..=motors).collect(),
        time_scale: args.time_scale,
        ..EmulatorConfig::default()
    });
    for spec in &args.fault {
        for _ in 0..spec.count {
            emulator.inject_after_goals(spec.motor, spec.fault, spec.after_goals);
        }
    }
    let pty = emulator
        .serve_pty()
        .map_err(|e| hardware(format!("cannot open a pseudo-terminal: {e}")))?;
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "{}", pty.path())
        .and_then(|()| stdout.flush())
        .map_err(|e| hardware(format!("<stdout>: cannot write: {e}")))?;
    drop(stdout);
    if !args.ignore_stdin && !std::io::stdin().is_terminal() {
        std::thread::spawn(|| {
            let mut sink = [0u8; 256];
            let mut stdin = std::io::stdin().lock();
            while matches!(stdin.read(&mut sink), Ok(n) if n > 0) {}
            std::process::exit(0);
        });
    }
    pty.wait()
        .map_err(|e| hardware(format!("emulator stopped: {e}")))
}

/// The robot file with its actuation, as the rig needs it.
struct RigRobot {
    spec: RobotSpec,
    actuation: Actuation,
}

impl RigRobot {
    fn load(path: &Path) -> Result<RigRobot, Failure> {
        let spec = RobotSpec::from_path(path).map_err(|e| input(e.to_string()))?;
        let file = path.display().to_string();
        let Some(joints) = spec.actuation.clone() else {
            return Err(input(format!(
                "{file}: no [actuation] section; hw commands need one [[actuation.joint]] per joint (s1, theta1, ...; see data/FORMATS-EXTENSION.md)"
            )));
        };
        // The reader validated the joints by the same rules: this cannot fail.
        let actuation = Actuation::new(joints).map_err(|e| input(format!("{file}: {e}")))?;
        Ok(RigRobot { spec, actuation })
    }

    fn n_tubes(&self) -> usize {
        self.spec.robot.n_tubes()
    }

    /// Checks joints (joint-vector order) against the robot's `[limits]` and the
    /// actuation limits; `at` locates them in messages. The contract's own rules are
    /// checked where the joints are read.
    fn check(&self, joints: &[f64], at: &str) -> Result<(), Failure> {
        if let Some(limits) = &self.spec.limits {
            let mut s_prev = 0.0;
            for (i, tube) in limits.iter().enumerate() {
                let (s, theta) = (joints[2 * i], joints[2 * i + 1]);
                if let Some((key, value)) = tube.violation(s, theta, s_prev) {
                    let range = match key {
                        "s_mm" => tube.s_mm,
                        "increment_mm" => tube.increment_mm,
                        _ => tube.theta_deg,
                    }
                    .unwrap_or([f64::NAN; 2]);
                    return Err(input(format!(
                        "{at}: tube {}: {key} = {value} is outside the robot's [limits] range [{}, {}]",
                        i + 1,
                        range[0],
                        range[1]
                    )));
                }
                s_prev = s;
            }
        }
        self.actuation
            .to_ticks(joints)
            .map(|_| ())
            .map_err(|e| input(format!("{at}: {e}")))
    }
}

/// Opens the port and wraps it in a rig; nothing is sent yet.
fn connect(
    connection: &Connection,
    robot: &RigRobot,
    motion: Option<&Motion>,
) -> Result<Rig<SerialTransport>, Failure> {
    let link = SerialTransport::open(&connection.port, connection.baud)
        .map_err(|e| hardware(e.to_string()))?;
    let bus = Bus::new(
        link,
        BusConfig {
            response_timeout: Duration::from_millis(connection.timeout_ms),
            ..BusConfig::default()
        },
    );
    let config = RigConfig {
        torque_off_on_fault: motion.is_some_and(|m| m.torque_off_on_fault),
        ..RigConfig::default()
    };
    Ok(Rig::new(bus, robot.actuation.clone(), config))
}

/// `hw ping`: one CSV row per joint with its motor's identity and state.
fn ping(args: PingArgs) -> Result<(), Failure> {
    let robot = RigRobot::load(&args.connection.robot)?;
    let mut rig = connect(&args.connection, &robot, None)?;
    let mut text = String::from("joint,motor_id,model,firmware,torque,hardware_error,position\n");
    let mut failures = Vec::new();
    for joint in robot.actuation.joints() {
        let id = joint.motor_id;
        let bus = rig.bus_mut();
        let identity = match bus.ping(id) {
            Ok(reply) => Ok((reply.model, reply.firmware)),
            Err(BusError::Alert { params, .. }) if params.len() == 3 => {
                Ok((u16::from_le_bytes([params[0], params[1]]), params[2]))
            }
            Err(e) => Err(e),
        };
        let state = identity.and_then(|(model, firmware)| {
            let torque = bus.read_despite_alert(id, ct::TORQUE_ENABLE, 1)?[0];
            let error = bus.read_despite_alert(id, ct::HARDWARE_ERROR_STATUS, 1)?[0];
            let p = bus.read_despite_alert(id, ct::PRESENT_POSITION, ct::PRESENT_POSITION_LEN)?;
            let ticks = i32::from_le_bytes([p[0], p[1], p[2], p[3]]);
            Ok((
                model,
                firmware,
                torque,
                error,
                joint.from_ticks(ticks) + 0.0,
            ))
        });
        match state {
            Ok((model, firmware, torque, error, position)) => {
                text.push_str(&format!(
                    "{},{id},{model},{firmware},{},{},{position}\n",
                    joint.name,
                    if torque == 1 { "on" } else { "off" },
                    ct::hardware_error_names(error).join("+"),
                ));
            }
            Err(e) => {
                text.push_str(&format!("{},{id},,,,,\n", joint.name));
                failures.push(e);
            }
        }
    }
    print_stdout(&text)?;
    match failures.first() {
        None => Ok(()),
        Some(e) => Err(hardware(format!(
            "{e} ({} of {} motors did not answer)",
            failures.len(),
            robot.actuation.len()
        ))),
    }
}

fn print_stdout(text: &str) -> Result<(), Failure> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| hardware(format!("<stdout>: cannot write: {e}")))
}

/// `hw home`: every joint to zero.
fn home(args: HomeArgs) -> Result<(), Failure> {
    let robot = RigRobot::load(&args.connection.robot)?;
    let zeros = vec![0.0; 2 * robot.n_tubes()];
    robot
        .spec
        .robot
        .validate_joints(&zeros)
        .map_err(|e| input(format!("home: {e}")))?;
    robot.check(&zeros, "home")?;
    go_to(&args.connection, &args.motion, &robot, &zeros)
}

/// `hw move`: every joint to the values given.
fn move_joints(args: MoveArgs) -> Result<(), Failure> {
    let robot = RigRobot::load(&args.connection.robot)?;
    let (joints, at) = if args.joints.contains('=') {
        let joints = parse_assignments(&args.joints, robot.n_tubes())?;
        robot
            .spec
            .robot
            .validate_joints(&joints)
            .map_err(|e| input(format!("--joints: {e}")))?;
        (joints, "--joints".to_owned())
    } else {
        let table = read_joints(&args.joints, &robot)?;
        if table.len() != 1 {
            return Err(input(format!(
                "{}: {} rows; hw move takes one (hw run plays a trajectory)",
                table.file(),
                table.len()
            )));
        }
        let at = format!("{}:{}", table.file(), table.line(0));
        (table.joints(0).to_vec(), at)
    };
    robot.check(&joints, &at)?;
    go_to(&args.connection, &args.motion, &robot, &joints)
}

/// Parses `s1=20,theta1=90,...` (names with or without their unit suffix, `s1_mm`);
/// every joint must be given once.
fn parse_assignments(text: &str, n_tubes: usize) -> Result<Vec<f64>, Failure> {
    let mut values: Vec<Option<f64>> = vec![None; 2 * n_tubes];
    for item in text.split(',') {
        let (name, value) = item
            .split_once('=')
            .ok_or_else(|| input(format!("--joints: {item:?} is not NAME=VALUE")))?;
        let name = name.trim();
        let id = JointId::parse(name)
            .or_else(|| {
                JointId::parse(name.strip_suffix("_mm")?)
                    .filter(|j| j.kind == ctr_formats::ActuatorKind::Feed)
            })
            .or_else(|| {
                JointId::parse(name.strip_suffix("_deg")?)
                    .filter(|j| j.kind == ctr_formats::ActuatorKind::Rotation)
            })
            .filter(|j| j.tube <= n_tubes)
            .ok_or_else(|| {
                input(format!(
                    "--joints: {name:?} is not a joint of this {n_tubes}-tube robot (s1..s{n_tubes}, theta1..theta{n_tubes})"
                ))
            })?;
        let v: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| {
                input(format!(
                    "--joints: {name}: {value:?} is not a finite number"
                ))
            })?;
        if values[id.index()].replace(v).is_some() {
            return Err(input(format!("--joints: {} is given twice", id.name())));
        }
    }
    let missing: Vec<String> = JointId::all(n_tubes)
        .filter(|j| values[j.index()].is_none())
        .map(JointId::name)
        .collect();
    if !missing.is_empty() {
        return Err(input(format!(
            "--joints: no value for {} (every joint needs one)",
            missing.join(", ")
        )));
    }
    Ok(values.into_iter().flatten().collect())
}

fn read_joints(path: &str, robot: &RigRobot) -> Result<JointTable, Failure> {
    if path == "-" {
        JointTable::read(std::io::stdin().lock(), "<stdin>", &robot.spec.robot)
    } else {
        JointTable::from_path(Path::new(path), &robot.spec.robot)
    }
    .map_err(|e| input(e.to_string()))
}

/// Moves to `joints` (checked already), waits until still and prints the joints read
/// back as a one-row joint CSV.
fn go_to(
    connection: &Connection,
    motion: &Motion,
    robot: &RigRobot,
    joints: &[f64],
) -> Result<(), Failure> {
    let mut rig = connect(connection, robot, Some(motion))?;
    let mut session = Session {
        rig: &mut rig,
        motion,
    };
    let reached = session
        .start()
        .and_then(|from| session.move_and_settle(&from, joints))
        .map_err(hardware)?;
    let header: Vec<String> = JointId::all(robot.n_tubes()).map(JointId::column).collect();
    let values: Vec<String> = tidy(reached).iter().map(|v| v.to_string()).collect();
    print_stdout(&format!("{}\n{}\n", header.join(","), values.join(",")))
}

/// A connected rig and how to move it; errors are one-line messages, the rig stopped.
struct Session<'a> {
    rig: &'a mut Rig<SerialTransport>,
    motion: &'a Motion,
}

impl Session<'_> {
    /// Pings every motor, enables torque (holding where they are) and returns the joints.
    fn start(&mut self) -> Result<Vec<f64>, String> {
        self.rig.ping_all().map_err(|e| self.stopped(e))?;
        self.rig.enable().map_err(|e| self.stopped(e))?;
        self.rig.positions().map_err(|e| self.stopped(e))
    }

    /// Sends the goals and waits until the motors are still; returns the joints then.
    fn move_and_settle(&mut self, from: &[f64], to: &[f64]) -> Result<Vec<f64>, String> {
        self.rig.move_to(to).map_err(|e| self.stopped(e))?;
        let timeout = self.settle_timeout(from, to);
        self.rig
            .wait_until_still(timeout)
            .map_err(|e| self.stopped(e))
    }

    /// Twice the time the slowest joint needs at its max_speed, plus the margin.
    fn settle_timeout(&self, from: &[f64], to: &[f64]) -> Duration {
        let slowest = self
            .rig
            .actuation()
            .joints()
            .iter()
            .zip(from.iter().zip(to))
            .map(|(j, (a, b))| (b - a).abs() / j.max_speed)
            .fold(0.0, f64::max);
        Duration::try_from_secs_f64(2.0 * slowest + self.motion.settle_margin)
            .unwrap_or(Duration::MAX)
    }

    /// The message for a failed rig operation, after making sure the rig is stopped: a
    /// fault has stopped it already; motors that do not come to rest are told to hold.
    fn stopped(&mut self, error: RigError) -> String {
        match error {
            RigError::StillMoving { waited } => {
                let mut message = format!(
                    "joints still moving after {:.1} s; rig stopped",
                    waited.as_secs_f64()
                );
                match self.rig.hold() {
                    Ok(_) => message.push_str(": holding every motor"),
                    Err(e) => message.push_str(&format!(": could not hold: {e}")),
                }
                if self.motion.torque_off_on_fault {
                    match self.rig.torque_off() {
                        Ok(()) => message.push_str("; torque off"),
                        Err(e) => message.push_str(&format!("; could not switch torque off: {e}")),
                    }
                }
                message
            }
            other => other.to_string(),
        }
    }
}

/// `hw run`: play a trajectory, record what the rig did.
fn play(args: RunArgs) -> Result<(), Failure> {
    let robot = RigRobot::load(&args.connection.robot)?;
    let joints_path = args.joints.display().to_string();
    let table = read_joints(&joints_path, &robot)?;
    for row in 0..table.len() {
        robot.check(
            table.joints(row),
            &format!("{}:{}", table.file(), table.line(row)),
        )?;
    }
    let times = trajectory_times(&table)?;
    let to_stdout = args.output == Path::new("-");
    if !to_stdout {
        if !args.overwrite && args.output.exists() {
            return Err(input(format!(
                "{}: exists already; a recording is never replaced unless --overwrite",
                args.output.display()
            )));
        }
        RecordingWriter::check_path(&args.output).map_err(|e| input(e.to_string()))?;
    }
    let label = args.run.clone().unwrap_or_else(|| {
        args.joints
            .file_stem()
            .filter(|_| joints_path != "-")
            .map_or_else(|| "stdin".to_owned(), |s| s.to_string_lossy().into_owned())
    });
    let mut rig = connect(&args.connection, &robot, Some(&args.motion))?;
    let mut session = Session {
        rig: &mut rig,
        motion: &args.motion,
    };
    let from = session.start().map_err(hardware)?;
    let n = robot.n_tubes();
    let player = Player {
        table: &table,
        times: times.as_deref(),
        label: &label,
    };
    if to_stdout {
        let mut rec = RecordingWriter::new(std::io::stdout().lock(), "<stdout>", n)
            .map_err(|e| hardware(e.to_string()))?;
        player.play(&mut session, from, &mut rec)
    } else {
        // the rows go to a journal beside the recording, renamed to it when the run
        // ends, also on a fault: a kill leaves the recording's path as it was and every
        // completed row in the journal (ctr_formats::recording)
        let mut rec = RecordingWriter::create(&args.output, n, args.overwrite)
            .map_err(|e| hardware(e.to_string()))?;
        let journal = rec.journal_path().display().to_string();
        let result = player.play(&mut session, from, &mut rec);
        let finished = rec
            .finish()
            .map_err(|e| format!("{e}; its rows are kept in {journal}"));
        match (result, finished) {
            (Ok(()), finished) => finished.map_err(hardware),
            (Err(Failure::Hardware(stop)), Err(unfinished)) => {
                Err(hardware(format!("{stop}; but {unfinished}")))
            }
            (Err(stop), _) => Err(stop),
        }
    }
}

/// The longest timed trajectory played, in seconds (a year).
const MAX_RUN_SECONDS: f64 = 3.2e7;

/// The optional `t_s` column: finite, non-decreasing seconds.
fn trajectory_times(table: &JointTable) -> Result<Option<Vec<f64>>, Failure> {
    let Some(column) = table.header().iter().position(|h| h.trim() == "t_s") else {
        return Ok(None);
    };
    let mut times = Vec::with_capacity(table.len());
    for row in 0..table.len() {
        let at = format!("{}:{}", table.file(), table.line(row));
        let cell = table.fields(row).nth(column).unwrap_or("");
        let t: f64 = cell
            .trim()
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite())
            .ok_or_else(|| input(format!("{at}: column t_s: {cell:?} is not a finite number")))?;
        if let Some(&before) = times.last() {
            if t < before {
                return Err(input(format!(
                    "{at}: column t_s: {t} is before the previous row's {before}; rows are played in time order"
                )));
            }
        }
        if let Some(&first) = times.first() {
            if t - first > MAX_RUN_SECONDS {
                return Err(input(format!(
                    "{at}: column t_s: {t} is more than {MAX_RUN_SECONDS} s after the first row's {first}"
                )));
            }
        }
        times.push(t);
    }
    Ok(Some(times))
}

/// A trajectory being played.
struct Player<'a> {
    table: &'a JointTable,
    times: Option<&'a [f64]>,
    label: &'a str,
}

impl Player<'_> {
    fn play<W: Write>(
        &self,
        session: &mut Session<'_>,
        mut from: Vec<f64>,
        rec: &mut RecordingWriter<W>,
    ) -> Result<(), Failure> {
        let start = Instant::now();
        let t0 = self.times.and_then(|t| t.first().copied()).unwrap_or(0.0);
        let at_time = |t: f64| start + Duration::from_secs_f64((t - t0).max(0.0));
        let rows = self.table.len();
        for row in 0..rows {
            let goal = self.table.joints(row);
            let stop = |message: String, rec: &RecordingWriter<W>| {
                hardware(format!(
                    "{}:{}: {message} ({} keeps {} row{})",
                    self.table.file(),
                    self.table.line(row),
                    rec.file(),
                    rec.rows(),
                    if rec.rows() == 1 { "" } else { "s" }
                ))
            };
            if let Some(times) = self.times {
                sleep_until(at_time(times[row]));
            }
            let next_time = self.times.filter(|_| row + 1 < rows).map(|t| t[row + 1]);
            let read = match next_time {
                Some(next) => session.rig.move_to(goal).map(|_| ()).and_then(|()| {
                    sleep_until(at_time(next));
                    session.rig.positions()
                }),
                None => session.rig.move_to(goal).map(|_| ()).and_then(|()| {
                    let timeout = session.settle_timeout(&from, goal);
                    session.rig.wait_until_still(timeout)
                }),
            };
            let read = match read {
                Ok(read) => tidy(read),
                Err(e) => {
                    let message = session.stopped(e);
                    return Err(stop(message, rec));
                }
            };
            let t = start.elapsed().as_secs_f64();
            rec.write_row(t, self.label, goal, &read).map_err(|e| {
                let message = format!("{e}; rig left holding this row's goals");
                stop(message, rec)
            })?;
            from = read;
        }
        Ok(())
    }
}

/// Joint values as written: `-0` (a zero read back through `direction = -1`) as `0`.
fn tidy(values: Vec<f64>) -> Vec<f64> {
    values.into_iter().map(|v| v + 0.0).collect()
}

fn sleep_until(deadline: Instant) {
    if let Some(wait) = deadline.checked_duration_since(Instant::now()) {
        std::thread::sleep(wait);
    }
}

//! Command-line options (clap derive), all in one place.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Parser, Subcommand, ValueEnum};
use ctr_analysis::batch::IK_CHUNK_ROWS;
use ctr_analysis::ik::IkOptions;
use ctr_analysis::margin::DEFAULT_WARN_MARGIN;
use ctr_formats::{ModelKind, ORIENTATION_TOLERANCE_DEG};
use ctr_hw::emulator::Fault;
use std::path::PathBuf;

const FK_EXAMPLE: &str = "\
Example:
  ctr-cli fk --robot data/robots/liu2023.toml --joints data/examples/liu2023-joints.csv -o tips.csv

Output: every input column as read, then x_mm,y_mm,z_mm (tip position in W, mm) and
qw,qx,qy,qz (tip orientation, unit quaternion with qw >= 0); with --on-error mark also
status,residual_per_mm. Floats are written in shortest round-trip form.

Parquet: a joint file or output named *.parquet is Parquet, with the CSV's column names
(joints DOUBLE, FLOAT, INT32 or INT64; tips DOUBLE; the input's other columns carried
with their own types, a CSV file's numbers of the contract as DOUBLE, the rest as text).
Errors in a Parquet file name its row (1-based) and column. The joint file is read and
the output written a piece at a time: memory does not grow with the rows (standard
output excepted: it is written at the end).

Model: the robot file's [model] kind (or --model) with every table of [model.effects]:
joint offsets, scaled stiffness and precurvature, clearance kinks or gravity, and the
tip as measured (sensor offset, registration: then x_mm,...,qz are in the measuring
frame). Time effects (latency, friction) act along the rows in file order: a t_s
column gives their times (seconds, non-decreasing within a run; latency needs it), a
run column cuts them into runs (contiguous rows with one label, each simulated on its
own); without t_s the row order stands for time.

Exit status: 0 success, 1 solves did not converge (--on-error fail), 2 bad input.";

const MAIN_EXAMPLE: &str = "\
Example:
  ctr-cli fk --robot data/robots/liu2023.toml --joints data/examples/liu2023-joints.csv -o tips.csv
  ctr-cli ik --robot data/robots/liu2023.toml --targets data/examples/liu2023-targets.csv -o joints.csv

Exit status: 0 success, 1 solves did not converge (fk --on-error fail), targets not
reached (ik --fail-unreachable) or the rig failed (hw), 2 bad input.";

const IK_HELP: &str = "\
Example:
  ctr-cli ik --robot data/robots/liu2023.toml --targets data/examples/liu2023-targets.csv -o joints.csv

Targets: the contract's tip file: x_mm,y_mm,z_mm (tip position in W, mm) and optionally
qw,qx,qy,qz (tip orientation, a unit quaternion: the targets are then poses;
--position-only ignores them). The tip file `ctr-cli fk` writes is a target file.

Model: as `ctr-cli fk` solves it, with the robot file's static [model.effects] (joint
offsets: the joints found are the commanded ones; scaled tubes; clearance or gravity;
sensor offset and registration: targets are in the measuring frame). Time effects
(latency, friction with a non-zero play) cannot be inverted target by target: refused.

Output: the input's other columns as read, then s1_mm,theta1_deg,... (the joints,
within the core's ranges and the robot file's [limits]), the tip reached there
reached_x_mm,reached_y_mm,reached_z_mm (for poses also reached_qw,...,reached_qz),
residual_mm, its distance to the target (for poses also orientation_residual_deg), and
status: reached, unreachable (no start came within the tolerance: the closest point
found is written), iteration_limit, fk_failed or unreachable_with_margin (not reached
with --min-margin holding the solve back: the closest point found within the margin).
Input columns named like an output column (the joints of the fk run that made the tips,
an earlier ik run's columns) are replaced by the output's own. `ctr-cli fk` reads the
output as a joint file. Floats are written in shortest round-trip form.

Stability margin: with --min-margin M no joints written have a stability margin below
M (the margin `fk --margin` writes; where the tubes are bistable, both the equilibrium
the solve followed and the one a cold solve finds must clear it). Each step keeps the
margin, linearised, above M, and a step whose solved margin falls below is refused; a
start below M first raises it. Limits that hold no sampled joints that stable are
refused (exit 2).

Rows are a trajectory: each row starts from the joints of the row before (--cold: every
row from the seed table, independently). To run in parallel the rows are cut into fixed
chunks (--chunk-rows, default 32): the first row of every chunk is solved first, in
order, each from the first row of the chunk before; then the chunks, in parallel, each
row from the row before. The output depends on --chunk-rows, never on --threads. The
rows on either side of a chunk boundary come from two warm-start paths: on a smooth
trajectory both stay on one branch of solutions, but a redundant robot (more joints than
target coordinates) can take a small step in its joints there that the tip does not
show. For a trajectory to be played on the rig, --chunk-rows 0 warm-starts every row
from the one before (one thread).

Exit status: 0 success, also when targets were unreachable (see the status column and
the warnings), unless --fail-unreachable: then 1 if any target was not reached (the
output is still written); 2 bad input (nothing is written).";

/// Batch kinematics of concentric tube robots, and the servo rig that drives them.
#[derive(Debug, Parser)]
#[command(name = "ctr-cli", version, after_help = MAIN_EXAMPLE)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Forward kinematics: joint CSV in, tip CSV out.
    #[command(after_help = FK_EXAMPLE)]
    Fk(FkArgs),
    /// Inverse kinematics: tip target CSV in, joint CSV out (within the robot's limits).
    #[command(after_help = IK_HELP)]
    Ik(IkArgs),
    /// The servo rig: Dynamixel 2.0 motors on a serial port, or an emulated bus.
    #[command(subcommand)]
    Hw(HwCommand),
    /// Where a model and a recording disagree, which left-out physics explains it,
    /// fitted and checked on held-out rows.
    #[command(after_help = DIAGNOSE_HELP)]
    Diagnose(crate::diagnose::DiagnoseArgs),
    /// Fits the parameters of named effects (no search), e.g. a clearance profile or
    /// the stiffness from hung weights.
    #[command(after_help = CALIBRATE_HELP)]
    Calibrate(crate::diagnose::CalibrateArgs),
    /// Mean and largest tip error per run for one or more models (the seed's Table 2).
    #[command(after_help = EVALUATE_HELP)]
    Evaluate(crate::diagnose::EvaluateArgs),
}

const DIAGNOSE_HELP: &str = "\
Example:
  ctr-cli diagnose --robot data/robots/liu2023.toml --recording data/examples/liu2023-recording.csv \\
      --report report.json --out fitted.toml --plots plots/ --html report.html

It prints where the error sits, the effects the model leaves out (of torsion, friction,
clearance, gravity, registration, joint_offset, stiffness, precurvature, latency,
sensor_offset) with their fitted values and the error before and after on held-out rows,
and whether what is left is measurement noise. --report writes the JSON report of
docs/formats.md (with this project's additions: noise, split, located, tried),
--out the fitted model as a robot file `ctr-cli fk` reads as is, --html one page with
all of it and the plots that opens offline.

Exit status: 0 success (also when nothing is found), 2 bad input.";

const CALIBRATE_HELP: &str = "\
Examples:
  ctr-cli calibrate --robot robot.toml --recording turns.csv --fit clearance --out fitted.toml
  ctr-cli calibrate --robot robot.toml --recording turns.csv --fit clearance --table 24
  ctr-cli calibrate --robot robot.toml --recording weights.csv --fit stiffness

A recording with fx_n,fy_n,fz_n columns (known tip forces in W, N, e.g. hung weights)
identifies the bending stiffness from the tip deflections.

Exit status: 0 success, 2 bad input.";

const EVALUATE_HELP: &str = "\
Example:
  ctr-cli evaluate --robot robot.toml --robot fitted.toml --recording rec.csv

Prints one row per run (and `all`) with each model's mean and largest tip error, mm.

Exit status: 0 success, 2 bad input.";

const HW_EXAMPLE: &str = "\
Example (the robot file needs an [actuation] section; `ctr-cli hw emulate` in another
terminal prints the port of an emulated bus, e.g. /dev/pts/5):
  ctr-cli hw ping --port /dev/pts/5 --robot rig.toml
  ctr-cli hw move --port /dev/pts/5 --robot rig.toml --joints s1=20,theta1=90,s2=60,theta2=0
  ctr-cli hw run --port /dev/pts/5 --robot rig.toml --joints trajectory.csv -o recording.csv

Exit status: 0 success, 1 the port, the bus or the rig failed (the rig is stopped and the
recording keeps every completed row), 2 bad input (nothing was sent).";

const EMULATE_HELP: &str = "\
The emulator has motors 1..2N (X-series, extended position mode, 4096 ticks per
revolution), all at position 0 with torque off. It prints the pseudo-terminal's path on
stdout (one line) and serves until killed or, when standard input is not a terminal,
until standard input closes.

Faults (--fault, repeatable): KIND[:ID][@GOALS][xCOUNT]
  KIND   overload          hardware error (overload): torque off, alert in every status
         no-reply          the status packet is lost (the instruction is applied)
         corrupt-crc       the status packet's CRC is wrong (the instruction is applied)
         drop-reply-bytes[=N]  N bytes (default 3) of the status packet are lost
         drop-instruction  the instruction packet is lost: not applied, not answered
  ID     the motor (default: any motor)
  GOALS  strike once the motor has applied this many goal positions (default 0: now);
         enabling the rig sets one goal per motor and every move one more, so @1 strikes
         right after enabling and @K+1 during the K-th move
  COUNT  the wire fault strikes this many times in a row (default 1; not for overload)
Example: --fault overload:2@5 overloads motor 2 during the fourth move.";

/// `ctr-cli hw ...`.
#[derive(Debug, Subcommand)]
pub enum HwCommand {
    /// Serve an emulated servo bus on a pseudo-terminal and print its path.
    #[command(after_help = EMULATE_HELP)]
    Emulate(EmulateArgs),
    /// Ping every motor of the robot's [actuation] and list them (CSV on stdout).
    #[command(after_help = HW_EXAMPLE)]
    Ping(PingArgs),
    /// Move every joint to zero (s_i = 0 mm, theta_i = 0 deg) and print where they are.
    #[command(after_help = HW_EXAMPLE)]
    Home(HomeArgs),
    /// Move the joints to the values given and print where they are.
    #[command(after_help = HW_EXAMPLE)]
    Move(MoveArgs),
    /// Play a joint trajectory and record what the rig did.
    #[command(after_help = RUN_HELP)]
    Run(RunArgs),
}

const RUN_HELP: &str = "\
The trajectory has the joint columns s1_mm,theta1_deg,... (other columns are ignored)
and optionally t_s (seconds, non-decreasing). Every row is checked against the contract,
the robot's [limits] and the [actuation] limits before anything is sent. Then, row by
row: send the goals; without t_s wait until the motors are still, with t_s wait until
the next row's time (the last row: until still); read the positions back; append the
row to the recording.

Recording (CSV, one flushed line per completed row; a recording named *.parquet is
written as Parquet from that journal when the run ends):
  t_s,run,s1_mm,theta1_deg,...,s1_read_mm,theta1_read_deg,...,x_mm,y_mm,z_mm
t_s: seconds since the first goal was sent, taken when the positions were read; the
joint columns: the goals in force then; the _read_ columns: the positions read back;
x_mm,y_mm,z_mm: empty, for the tracker.

On a fault the rig holds position (--torque-off-on-fault also switches torque off),
the fault and the packet that caused it are reported on stderr, the recording keeps
every completed row, and the exit status is 1.

The rows go to a journal beside the recording, RECORDING.csv.XXXXXX.partial, renamed to
RECORDING.csv when the run ends (also on a fault): a killed run leaves RECORDING.csv as
it was and every completed row in its journal.";

/// Options of `ctr-cli hw emulate`.
#[derive(Debug, clap::Args)]
pub struct EmulateArgs {
    /// Tubes of the robot: the bus has motors 1..2N.
    #[arg(long, value_name = "N", default_value_t = 2, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub tubes: u8,

    /// Simulated seconds per second (motion runs this much faster than real time).
    #[arg(long, value_name = "X", default_value_t = 1.0, value_parser = parse_positive)]
    pub time_scale: f64,

    /// A fault to inject: KIND[:ID][@GOALS][xCOUNT] (see below); repeatable.
    #[arg(long, value_name = "SPEC", value_parser = parse_fault)]
    pub fault: Vec<FaultSpec>,

    /// Serve until killed, even when standard input closes.
    #[arg(long)]
    pub ignore_stdin: bool,
}

/// A fault to inject into the emulator (`--fault`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultSpec {
    /// What happens.
    pub fault: Fault,
    /// To which motor (any when `None`).
    pub motor: Option<u8>,
    /// After how many goal positions applied to it.
    pub after_goals: usize,
    /// How many times in a row.
    pub count: usize,
}

/// Parses `KIND[:ID][@GOALS][xCOUNT]` (see `ctr-cli hw emulate --help`).
pub fn parse_fault(spec: &str) -> Result<FaultSpec, String> {
    fn number<T: std::str::FromStr>(s: &str, what: &str) -> Result<T, String> {
        s.parse()
            .map_err(|_| format!("{what} {s:?} is not a whole number"))
    }
    let mut rest = spec;
    let mut count = 1;
    if let Some((head, n)) = rest.rsplit_once('x') {
        if !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) {
            count = number(n, "count")?;
            if count == 0 {
                return Err("count must be at least 1".into());
            }
            rest = head;
        }
    }
    let mut after_goals = 0;
    if let Some((head, n)) = rest.rsplit_once('@') {
        after_goals = number(n, "goal count")?;
        rest = head;
    }
    let mut motor = None;
    if let Some((head, id)) = rest.rsplit_once(':') {
        motor = Some(number::<u8>(id, "motor ID")?);
        rest = head;
    }
    let fault = match rest.split_once('=') {
        Some(("drop-reply-bytes", n)) => Fault::DropReplyBytes(number(n, "byte count")?),
        None if rest == "drop-reply-bytes" => Fault::DropReplyBytes(3),
        None if rest == "overload" => Fault::Overload,
        None if rest == "no-reply" => Fault::NoReply,
        None if rest == "corrupt-crc" => Fault::CorruptReplyCrc,
        None if rest == "drop-instruction" => Fault::DropInstruction,
        _ => {
            return Err(format!(
                "unknown fault {rest:?} in {spec:?}: expected KIND[:ID][@GOALS][xCOUNT] with KIND one of overload, no-reply, corrupt-crc, drop-reply-bytes[=N], drop-instruction"
            ))
        }
    };
    if fault == Fault::Overload && count != 1 {
        return Err("an overload strikes once: no xCOUNT".into());
    }
    Ok(FaultSpec {
        fault,
        motor,
        after_goals,
        count,
    })
}

/// How to reach the rig, and which robot it is.
#[derive(Debug, clap::Args)]
pub struct Connection {
    /// Serial port of the servo bus (e.g. /dev/ttyUSB0, or the path `hw emulate` prints).
    #[arg(long, value_name = "PATH")]
    pub port: String,

    /// Robot description with an [actuation] section (TOML).
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot: PathBuf,

    /// Baud rate of the serial line.
    #[arg(long, value_name = "B", default_value_t = 57_600)]
    pub baud: u32,

    /// How long to wait for each status packet, in milliseconds (3 attempts at most).
    #[arg(long, value_name = "MS", default_value_t = 100, value_parser = clap::value_parser!(u64).range(1..=60_000))]
    pub timeout_ms: u64,
}

/// What to do when moving.
#[derive(Debug, clap::Args)]
pub struct Motion {
    /// On a fault, switch torque off after telling the motors to hold (default: keep
    /// torque on and hold position).
    #[arg(long)]
    pub torque_off_on_fault: bool,

    /// Extra seconds allowed for the motors to come to rest, beyond twice the time the
    /// move takes at the joints' max_speed.
    #[arg(long, value_name = "S", default_value_t = 5.0, value_parser = parse_seconds)]
    pub settle_margin: f64,
}

fn parse_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err(format!("{s:?} is not a number of seconds")),
    }
}

/// Options of `ctr-cli hw ping`.
#[derive(Debug, clap::Args)]
pub struct PingArgs {
    #[command(flatten)]
    pub connection: Connection,
}

/// Options of `ctr-cli hw home`.
#[derive(Debug, clap::Args)]
pub struct HomeArgs {
    #[command(flatten)]
    pub connection: Connection,
    #[command(flatten)]
    pub motion: Motion,
}

/// Options of `ctr-cli hw move`.
#[derive(Debug, clap::Args)]
pub struct MoveArgs {
    #[command(flatten)]
    pub connection: Connection,
    #[command(flatten)]
    pub motion: Motion,

    /// Every joint's goal, as s1=MM,theta1=DEG,... (an argument with `=`), or a joint
    /// CSV file with one row (`-` reads standard input).
    #[arg(long, value_name = "s1=..,theta1=..|JOINTS.csv")]
    pub joints: String,
}

/// Options of `ctr-cli hw run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub connection: Connection,
    #[command(flatten)]
    pub motion: Motion,

    /// Joint trajectory (CSV with s1_mm,theta1_deg,... and optionally t_s); `-` reads
    /// standard input.
    #[arg(long, value_name = "TRAJECTORY.csv")]
    pub joints: PathBuf,

    /// The recording to write (must not exist, unless --overwrite); `-` writes standard
    /// output.
    #[arg(short, long, value_name = "RECORDING.csv")]
    pub output: PathBuf,

    /// Replace an existing recording.
    #[arg(long)]
    pub overwrite: bool,

    /// The recording's run label (default: the trajectory's file name without extension).
    #[arg(long, value_name = "LABEL")]
    pub run: Option<String>,
}

/// Options of `ctr-cli fk`.
#[derive(Debug, clap::Args)]
pub struct FkArgs {
    /// Robot description (TOML); `-` reads standard input.
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot: PathBuf,

    /// Joint file (CSV with s1_mm,theta1_deg,... columns, or Parquet: *.parquet); `-`
    /// reads standard input.
    #[arg(long, value_name = "JOINTS.csv")]
    pub joints: PathBuf,

    /// Tip file to write, CSV or Parquet (*.parquet) (replaced only if the whole run
    /// succeeds); `-` or absent writes CSV on standard output.
    #[arg(short, long, value_name = "TIPS.csv")]
    pub output: Option<PathBuf>,

    /// Mechanics; overrides `kind` in the robot file's `[model]` (default torsion).
    #[arg(long, value_parser = model_parser())]
    pub model: Option<ModelKind>,

    /// Rows whose solve does not converge: fail (exit 1, write nothing), skip them, or
    /// mark them in added status,residual_per_mm columns.
    #[arg(long, value_enum, default_value_t = OnErrorArg::Fail)]
    pub on_error: OnErrorArg,

    /// Worker threads (default: all cores); the output does not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,

    /// Append a stability_margin column: each row's distance to the nearest snap in joint
    /// space over 20 degrees or mm, capped at 1 (0 at a snap, negative on an unstable
    /// branch; docs/snap-through.md).
    #[arg(long)]
    pub margin: bool,

    /// Warn once per run of consecutive rows whose stability margin is below X (with the
    /// run's lines and its smallest margin; 0.05: about a degree or a millimetre from a
    /// snap); 0 turns the warnings off.
    #[arg(long, value_name = "X", default_value_t = DEFAULT_WARN_MARGIN)]
    pub warn_margin: f64,

    /// Print where the time went to stderr: setting up, reading the joint file, the
    /// workers (parsing, solving, formatting), writing, finishing; wall and CPU times.
    #[arg(long)]
    pub profile: bool,
}

/// Options of `ctr-cli ik`.
#[derive(Debug, clap::Args)]
pub struct IkArgs {
    /// Robot description (TOML); its [limits] bound the joints. `-` reads standard input.
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot: PathBuf,

    /// Target file (CSV with x_mm,y_mm,z_mm and optionally qw,qx,qy,qz columns, or
    /// Parquet: *.parquet); `-` reads standard input.
    #[arg(long, value_name = "TARGETS.csv")]
    pub targets: PathBuf,

    /// Joint file to write, CSV or Parquet (*.parquet) (replaced only if the whole run
    /// succeeds); `-` or absent writes CSV on standard output.
    #[arg(short, long, value_name = "JOINTS.csv")]
    pub output: Option<PathBuf>,

    /// Exit with status 1 if any target was not reached (the output is still written).
    #[arg(long)]
    pub fail_unreachable: bool,

    /// Solve every target cold from the seed table instead of warm from the row before
    /// (for scattered targets).
    #[arg(long)]
    pub cold: bool,

    /// Rows per chunk of the warm-started trajectory (see below); 0: one chunk, every
    /// row warm-started from the row before, on one thread.
    #[arg(long, value_name = "N", default_value_t = IK_CHUNK_ROWS)]
    pub chunk_rows: usize,

    /// Position targets only: qw,qx,qy,qz columns, if any, are carried through unread.
    #[arg(long)]
    pub position_only: bool,

    /// Reached when the tip is this close to the target position, mm.
    #[arg(long, value_name = "MM", default_value_t = IkOptions::default().tolerance_mm, value_parser = parse_positive)]
    pub tolerance_mm: f64,

    /// ... and, for a pose target, this close in orientation, degrees.
    #[arg(long, value_name = "DEG", default_value_t = ORIENTATION_TOLERANCE_DEG, value_parser = parse_positive)]
    pub orientation_tolerance_deg: f64,

    /// Weight W_E of the position error, per mm^2.
    #[arg(long, value_name = "W", default_value_t = IkOptions::default().position_weight, value_parser = parse_positive)]
    pub position_weight: f64,

    /// Weight W_E of the orientation error, per rad^2 (100: 1 rad weighs as 10 mm).
    #[arg(long, value_name = "W", default_value_t = IkOptions::default().orientation_weight, value_parser = parse_non_negative)]
    pub orientation_weight: f64,

    /// Damping W_N on each feed (mm^2 of tip error per mm^2 of feed step).
    #[arg(long, value_name = "W", default_value_t = IkOptions::default().damping_feed, value_parser = parse_positive)]
    pub damping_feed: f64,

    /// Damping W_N on each rotation (mm^2 of tip error per rad^2 of rotation step), for
    /// a rotation that moves the tip 10 mm or more per radian; one with a shorter lever
    /// arm gets this times the square of its lever over 10 mm.
    #[arg(long, value_name = "W", default_value_t = IkOptions::default().damping_rotation, value_parser = parse_positive)]
    pub damping_rotation: f64,

    /// Further starts from the seed table when a start does not reach the target.
    #[arg(long, value_name = "N", default_value_t = IkOptions::default().restarts)]
    pub restarts: u32,

    /// Most Levenberg-Marquardt steps per start.
    #[arg(long, value_name = "N", default_value_t = IkOptions::default().max_iterations, value_parser = clap::value_parser!(u32).range(1..))]
    pub max_iterations: u32,

    /// Mechanics; overrides `kind` in the robot file's `[model]` (default torsion).
    #[arg(long, value_parser = model_parser())]
    pub model: Option<ModelKind>,

    /// Smallest stability margin of the joints written (dimensionless, as `fk --margin`
    /// writes it: 1 with no snap within about 20 degrees or mm, 0 at one). A constraint of every step: a
    /// target reachable only less stable gets the closest point found within it, with
    /// status unreachable_with_margin.
    #[arg(long, value_name = "M", value_parser = parse_finite)]
    pub min_margin: Option<f64>,

    /// Worker threads (default: all cores); the output does not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
}

fn parse_positive(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("{s:?} is not a positive number")),
    }
}

fn parse_finite(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(format!("{s:?} is not a finite number")),
    }
}

fn parse_non_negative(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err(format!("{s:?} is not a number >= 0")),
    }
}

/// `--model`: the names of [`ModelKind`] (the one table of them), each with its help.
fn model_parser() -> impl TypedValueParser<Value = ModelKind> {
    let values = ModelKind::ALL.map(|k| {
        PossibleValue::new(k.name()).help(match k {
            ModelKind::Rigid => "Torsionally rigid tubes",
            ModelKind::Torsion => "Torsionally compliant tubes",
        })
    });
    PossibleValuesParser::new(values).try_map(|s| s.parse::<ModelKind>())
}

/// `--on-error`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OnErrorArg {
    /// Exit 1 and write nothing.
    Fail,
    /// Leave the rows out.
    Skip,
    /// Keep them, with status and residual columns.
    Mark,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_specs() {
        let spec = |fault, motor, after_goals, count| FaultSpec {
            fault,
            motor,
            after_goals,
            count,
        };
        assert_eq!(
            parse_fault("overload:2@5"),
            Ok(spec(Fault::Overload, Some(2), 5, 1))
        );
        assert_eq!(
            parse_fault("no-reply"),
            Ok(spec(Fault::NoReply, None, 0, 1))
        );
        assert_eq!(
            parse_fault("corrupt-crc@3x2"),
            Ok(spec(Fault::CorruptReplyCrc, None, 3, 2))
        );
        assert_eq!(
            parse_fault("drop-reply-bytes=4:1x3"),
            Ok(spec(Fault::DropReplyBytes(4), Some(1), 0, 3))
        );
        assert_eq!(
            parse_fault("drop-reply-bytes:4"),
            Ok(spec(Fault::DropReplyBytes(3), Some(4), 0, 1))
        );
        assert_eq!(
            parse_fault("drop-instruction:3@1"),
            Ok(spec(Fault::DropInstruction, Some(3), 1, 1))
        );
        for bad in [
            "",
            "overheat",
            "overload:x",
            "overload:300",
            "overload@",
            "no-reply x0",
            "no-replyx0",
            "overload:1x2",
            "drop-reply-bytes=many",
            "no-reply:1@2@3",
        ] {
            assert!(parse_fault(bad).is_err(), "{bad:?} accepted");
        }
    }
}

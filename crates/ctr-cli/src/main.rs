//! `ctr-cli`: batch kinematics of concentric tube robots (`fk`, `ik`), the diagnosis,
//! calibration and evaluation of models against recordings (`diagnose`, `calibrate`,
//! `evaluate`: [`diagnose`]), and the servo rig (`hw`: [`hw`]).
//!
//! The work is the libraries': `ctr_analysis::job` runs `fk` and `ik` files to files,
//! `ctr_diagnosis` the diagnosis, `ctr_hw` the rig; this crate parses the options
//! ([`cli`], all of them in one place), prints, and shows a progress bar on a terminal
//! ([`progress`]).
//!
//! `main` parses the options ([`cli`]), runs the command and maps the outcome to an exit
//! status: 0 success, 1 solves that did not converge under `--on-error fail`, targets
//! not reached under `ik --fail-unreachable`, or a rig, bus or port failure, 2 bad input
//! or usage. Every error is one line on stderr.

// The options' doc comments are their `--help` text, which names TOML sections the
// user writes (`[actuation]`, `[limits]`) and fault syntax (`[@GOALS][xCOUNT]`):
// they are not links, and rewriting them for rustdoc would change the help.
#![allow(rustdoc::broken_intra_doc_links)]

mod cli;
mod diagnose;
mod hw;
mod progress;

use clap::Parser;
use cli::{Cli, Command, FkArgs, IkArgs, OnErrorArg};
use ctr_analysis::ik::IkOptions;
use ctr_analysis::job::Output;
use ctr_analysis::job::{run_fk, run_ik, FkJob, FkSummary, IkJob, Input, LowMargin, OnError};
use ctr_core::Model;
use ctr_formats::status_name;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Rows listed one by one on stderr before the rest are summed up.
const MAX_WARNINGS: usize = 20;

/// Why a run failed, and its exit status.
enum Failure {
    /// Bad input or usage: exit 2.
    Input(String),
    /// Solves did not converge: exit 1.
    Solver(String),
    /// The serial port, the bus or the rig failed (the rig is stopped): exit 1.
    Hardware(String),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(e),
    };
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Solver(msg) | Failure::Hardware(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(1)
        }
        Err(Failure::Input(msg)) => {
            eprintln!("error: {msg}");
            ExitCode::from(2)
        }
    }
}

/// Help and version go to stdout with status 0; usage errors become one line, status 2.
fn usage_error(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(
        e.kind(),
        ErrorKind::DisplayHelp
            | ErrorKind::DisplayVersion
            | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
    ) {
        let _ = e.print();
        return if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
            ExitCode::from(2)
        } else {
            ExitCode::SUCCESS
        };
    }
    let text = e.render().to_string();
    let line = text
        .lines()
        .map(str::trim)
        .take_while(|l| !l.starts_with("Usage:") && !l.starts_with("For more information"))
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ");
    let line = line.strip_prefix("error: ").unwrap_or(&line);
    eprintln!("error: {line} (see ctr-cli --help)");
    ExitCode::from(2)
}

fn run(cli: Cli) -> Result<(), Failure> {
    match cli.command {
        Command::Fk(args) => fk(args),
        Command::Ik(args) => ik(args),
        Command::Hw(command) => hw::run(command),
        Command::Diagnose(args) => diagnose::diagnose(args),
        Command::Calibrate(args) => diagnose::calibrate(args),
        Command::Evaluate(args) => diagnose::evaluate(args),
    }
}

fn input(path: &Path) -> Input {
    if path == Path::new("-") {
        Input::Stdin
    } else {
        Input::Path(path.to_path_buf())
    }
}

/// The robot file's input and the data file's (`--joints`, `--targets`: `flag`); at
/// most one of them reads standard input.
fn inputs(robot: &Path, data: &Path, flag: &str) -> Result<(Input, Input), Failure> {
    let (robot, data) = (input(robot), input(data));
    if robot == Input::Stdin && data == Input::Stdin {
        return Err(Failure::Input(format!(
            "--robot and {flag} cannot both read standard input (-)"
        )));
    }
    Ok((robot, data))
}

fn output(path: Option<PathBuf>) -> Output {
    match path {
        Some(p) if p != Path::new("-") => Output::Path(p),
        _ => Output::Stdout,
    }
}

fn ik(args: IkArgs) -> Result<(), Failure> {
    let (robot, targets) = inputs(&args.robot, &args.targets, "--targets")?;
    let job = IkJob {
        robot,
        targets,
        output: output(args.output),
        model: args.model.map(Model::from),
        options: IkOptions {
            position_weight: args.position_weight,
            orientation_weight: args.orientation_weight,
            damping_feed: args.damping_feed,
            damping_rotation: args.damping_rotation,
            tolerance_mm: args.tolerance_mm,
            orientation_tolerance_rad: args.orientation_tolerance_deg.to_radians(),
            max_iterations: args.max_iterations,
            restarts: args.restarts,
            min_margin: args.min_margin,
            ..IkOptions::default()
        },
        position_only: args.position_only,
        warm: !args.cold,
        chunk_rows: args.chunk_rows,
        threads: args.threads.map_or(0, usize::from),
    };
    let summary =
        run_ik(&job, &progress::Bar::default()).map_err(|e| Failure::Input(e.to_string()))?;
    for f in summary.not_reached.iter().take(MAX_WARNINGS) {
        let angle = f.orientation_residual_rad.map_or(String::new(), |a| {
            format!(", orientation_residual_deg = {}", a.to_degrees())
        });
        eprintln!(
            "warning: {}: target {}: residual_mm = {}{angle}",
            located(&summary.targets_file, f.line, summary.lines_are_rows),
            f.status.name(),
            f.residual_mm,
        );
    }
    let missed = summary.not_reached.len();
    if missed > MAX_WARNINGS {
        eprintln!(
            "warning: {}: {} more targets not reached ({missed} of {} in all)",
            summary.targets_file,
            missed - MAX_WARNINGS,
            summary.rows
        );
    }
    if args.fail_unreachable && missed > 0 {
        let first = &summary.not_reached[0];
        return Err(Failure::Solver(format!(
            "{}: {missed} of {} target{} not reached (first: {}, residual_mm = {}); the output was written",
            located(&summary.targets_file, first.line, summary.lines_are_rows),
            summary.rows,
            if summary.rows == 1 { "" } else { "s" },
            first.status.name(),
            first.residual_mm
        )));
    }
    Ok(())
}

fn fk(args: FkArgs) -> Result<(), Failure> {
    let (robot, joints) = inputs(&args.robot, &args.joints, "--joints")?;
    let job = FkJob {
        robot,
        joints,
        output: output(args.output),
        model: args.model.map(Model::from),
        on_error: match args.on_error {
            OnErrorArg::Fail => OnError::Fail,
            OnErrorArg::Skip => OnError::Skip,
            OnErrorArg::Mark => OnError::Mark,
        },
        threads: args.threads.map_or(0, usize::from),
        margin: args.margin,
        warn_margin: (args.warn_margin > 0.0).then_some(args.warn_margin),
    };
    let started = std::time::Instant::now();
    let bar = progress::Bar::profiled(args.profile);
    let summary = run_fk(&job, &bar).map_err(|e| {
        if e.is_solver_failure() {
            Failure::Solver(format!(
                "{e} (--on-error skip or mark writes the other rows)"
            ))
        } else {
            Failure::Input(e.to_string())
        }
    })?;
    if args.profile {
        let threads = ctr_formats::parallel::resolve_threads(job.threads);
        eprint!("{}", bar.profile(summary.rows, threads, started.elapsed()));
    }
    let what = if job.on_error == OnError::Skip {
        "skipped"
    } else {
        "marked"
    };
    for f in summary.failures.iter().take(MAX_WARNINGS) {
        eprintln!(
            "warning: {}: {what}: solve ended with status {} (residual_per_mm = {})",
            place(&summary, f.line, f.line),
            status_name(f.status),
            f.residual_per_mm
        );
    }
    if summary.failures.len() > MAX_WARNINGS {
        eprintln!(
            "warning: {}: {} more rows {what} ({} of {} rows did not converge)",
            summary.joints_file,
            summary.failures.len() - MAX_WARNINGS,
            summary.failures.len(),
            summary.rows
        );
    }
    for run in summary.low_margin.iter().take(MAX_WARNINGS) {
        eprintln!(
            "warning: {}",
            low_margin_words(&summary, run, args.warn_margin)
        );
    }
    if summary.low_margin.len() > MAX_WARNINGS {
        eprintln!(
            "warning: {}: {} more runs of rows with a stability margin below {}",
            summary.joints_file,
            summary.low_margin.len() - MAX_WARNINGS,
            args.warn_margin
        );
    }
    Ok(())
}

/// Where line `line` of `file` is (`file:line`), or row `line` of a Parquet file
/// (`file: row line`).
fn located(file: &str, line: usize, rows: bool) -> String {
    if rows {
        format!("{file}: row {line}")
    } else {
        format!("{file}:{line}")
    }
}

/// Where lines `first` to `last` of the joint file are: `file:first-last`, or
/// `file: rows first-last` for a Parquet file.
fn place(summary: &FkSummary, first: usize, last: usize) -> String {
    let file = &summary.joints_file;
    let span = if first == last {
        format!("{first}")
    } else {
        format!("{first}-{last}")
    };
    match (summary.lines_are_rows, first == last) {
        (false, _) => format!("{file}:{span}"),
        (true, true) => format!("{file}: row {span}"),
        (true, false) => format!("{file}: rows {span}"),
    }
}

/// One warning for a run of rows below the warning margin.
fn low_margin_words(summary: &FkSummary, run: &LowMargin, below: f64) -> String {
    let (first, last) = run.lines;
    let lines = place(summary, first, last);
    let line = if summary.lines_are_rows {
        "row"
    } else {
        "line"
    };
    let what = if run.min.0 < 0.0 {
        "on an unstable branch: the robot would snap"
    } else {
        "close to a snap"
    };
    format!(
        "{lines}: stability margin below {below} on {} row{} ({what}; smallest {:.4} at {line} {})",
        run.rows,
        if run.rows == 1 { "" } else { "s" },
        run.min.0,
        run.min.1
    )
}

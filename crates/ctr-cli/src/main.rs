//! `ctr-cli`: batch kinematics of concentric tube robots, and the servo rig ([`hw`]).
//!
//! `main` parses the options ([`cli`]), runs the command and maps the outcome to an exit
//! status: 0 success, 1 solves that did not converge under `--on-error fail` or a rig,
//! bus or port failure, 2 bad input or usage. Every error is one line on stderr.

mod cli;
mod hw;
mod progress;

use clap::Parser;
use cli::{Cli, Command, FkArgs, ModelArg, OnErrorArg};
use ctr_analysis::job::{run_fk, FkJob, Input, OnError, Output};
use ctr_analysis::status_name;
use ctr_core::Model;
use std::path::Path;
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
        Command::Hw(command) => hw::run(command),
    }
}

fn input(path: &Path) -> Input {
    if path == Path::new("-") {
        Input::Stdin
    } else {
        Input::Path(path.to_path_buf())
    }
}

fn fk(args: FkArgs) -> Result<(), Failure> {
    let robot = input(&args.robot);
    let joints = input(&args.joints);
    if robot == Input::Stdin && joints == Input::Stdin {
        return Err(Failure::Input(
            "--robot and --joints cannot both read standard input (-)".into(),
        ));
    }
    let output = match args.output {
        Some(p) if p != Path::new("-") => Output::Path(p),
        _ => Output::Stdout,
    };
    let job = FkJob {
        robot,
        joints,
        output,
        model: args.model.map(|m| match m {
            ModelArg::Rigid => Model::Rigid,
            ModelArg::Torsion => Model::Torsion,
        }),
        on_error: match args.on_error {
            OnErrorArg::Fail => OnError::Fail,
            OnErrorArg::Skip => OnError::Skip,
            OnErrorArg::Mark => OnError::Mark,
        },
        threads: args.threads.map_or(0, usize::from),
    };
    let summary = run_fk(&job, &progress::Bar::default()).map_err(|e| {
        if e.is_solver_failure() {
            Failure::Solver(format!(
                "{e} (--on-error skip or mark writes the other rows)"
            ))
        } else {
            Failure::Input(e.to_string())
        }
    })?;
    let what = if job.on_error == OnError::Skip {
        "skipped"
    } else {
        "marked"
    };
    for f in summary.failures.iter().take(MAX_WARNINGS) {
        eprintln!(
            "warning: {}:{}: {what}: solve ended with status {} (residual_per_mm = {})",
            summary.joints_file,
            f.line,
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
    Ok(())
}

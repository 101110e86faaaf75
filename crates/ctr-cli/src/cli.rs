//! Command-line options (clap derive), all in one place.

use clap::{Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

const FK_EXAMPLE: &str = "\
Example:
  ctr-cli fk --robot data/robots/liu2023.toml --joints data/examples/liu2023-joints.csv -o tips.csv

Output: every input column as read, then x_mm,y_mm,z_mm (tip position in W, mm) and
qw,qx,qy,qz (tip orientation, unit quaternion with qw >= 0); with --on-error mark also
status,residual_per_mm. Floats are written in shortest round-trip form.

Exit status: 0 success, 1 solves did not converge (--on-error fail), 2 bad input.";

/// Batch kinematics of concentric tube robots.
#[derive(Debug, Parser)]
#[command(name = "ctr-cli", version, after_help = FK_EXAMPLE)]
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
}

/// Options of `ctr-cli fk`.
#[derive(Debug, clap::Args)]
pub struct FkArgs {
    /// Robot description (TOML); `-` reads standard input.
    #[arg(long, value_name = "ROBOT.toml")]
    pub robot: PathBuf,

    /// Joint file (CSV with s1_mm,theta1_deg,... columns); `-` reads standard input.
    #[arg(long, value_name = "JOINTS.csv")]
    pub joints: PathBuf,

    /// Tip file to write (replaced only if the whole run succeeds); `-` or absent writes
    /// standard output.
    #[arg(short, long, value_name = "TIPS.csv")]
    pub output: Option<PathBuf>,

    /// Mechanics; overrides `kind` in the robot file's `[model]` (default torsion).
    #[arg(long, value_enum)]
    pub model: Option<ModelArg>,

    /// Rows whose solve does not converge: fail (exit 1, write nothing), skip them, or
    /// mark them in added status,residual_per_mm columns.
    #[arg(long, value_enum, default_value_t = OnErrorArg::Fail)]
    pub on_error: OnErrorArg,

    /// Worker threads (default: all cores); the output does not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
}

/// `--model`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    /// Torsionally rigid tubes.
    Rigid,
    /// Torsionally compliant tubes.
    Torsion,
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

//! Whole jobs, files to files: forward kinematics ([`run_fk`], what `ctr-cli fk` runs)
//! and inverse kinematics ([`run_ik`], `ctr-cli ik`).
//!
//! Order of work: read and validate the robot, read the input's header, check the
//! output header, open the output (a temporary file beside it, so a missing directory
//! fails before any solving), then read, solve and format in parallel, piece by piece,
//! writing the pieces in order as they are done; apply the [`OnError`] policy, and only
//! then rename the output into place. Any error before the rename leaves an existing
//! output untouched (the temporary file is removed); standard output is written only at
//! the end. Errors come as if every input row had been read and checked before any
//! solving: the first bad row of the input wins over a missing output directory or a
//! solve that failed (see [`run_fk`]).

mod fk;
mod ik;
mod time;

pub use fk::{run_fk, FkJob, FkSummary, LowMargin, RowFailure};
pub use ik::{run_ik, IkJob, IkRowFailure, IkSummary};

use crate::model::ModelError;
use ctr_formats::{AtomicFile, RobotSpec};
use ctr_formats::{Error, ErrorKind, Location};
use std::io::{Read, Write};
use std::path::PathBuf;

/// Where an input comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Input {
    /// Standard input (named `<stdin>` in errors).
    Stdin,
    /// A file.
    Path(PathBuf),
}

/// Where the output goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Output {
    /// Standard output (written after all rows are solved).
    Stdout,
    /// A file, replaced atomically.
    Path(PathBuf),
}

/// What to do with rows whose solve did not converge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OnError {
    /// Write nothing and fail ([`ErrorKind::SolverFailed`] at the first such row).
    #[default]
    Fail,
    /// Leave those rows out of the output.
    Skip,
    /// Keep every row and add the `status` and `residual_per_mm` columns.
    Mark,
}

fn read_input(input: &Input) -> Result<(String, Vec<u8>), Error> {
    let (name, result) = match input {
        Input::Stdin => {
            let mut buf = Vec::new();
            let r = std::io::stdin().lock().read_to_end(&mut buf).map(|_| buf);
            ("<stdin>".to_owned(), r)
        }
        Input::Path(p) => (p.display().to_string(), std::fs::read(p)),
    };
    match result {
        Ok(bytes) => Ok((name, bytes)),
        Err(source) => Err(Error::new(
            Location::file(name),
            ErrorKind::Io {
                action: "read",
                source,
            },
        )),
    }
}

/// Reads and validates the robot file.
fn read_robot(input: &Input) -> Result<RobotSpec, Error> {
    let (name, bytes) = read_input(input)?;
    RobotSpec::from_bytes(bytes, &name)
}

/// The name an input has in messages.
fn input_name(input: &Input) -> String {
    match input {
        Input::Stdin => "<stdin>".to_owned(),
        Input::Path(p) => p.display().to_string(),
    }
}

/// A model that cannot be built, located at the robot file.
fn model_error(robot: &str, e: ModelError) -> Error {
    let kind = match e {
        ModelError::Robot(e) => ErrorKind::Robot(e),
        other => ErrorKind::Effect {
            message: other.to_string(),
        },
    };
    Error::new(Location::file(robot), kind)
}

/// Where a job's output goes until it is complete: a temporary file beside the target,
/// or a buffer for standard output (written only when the job succeeded).
enum Sink {
    File(AtomicFile, String),
    Stdout(Vec<u8>),
}

impl Sink {
    /// Opens the output (a missing directory fails here, before any solving).
    fn open(output: &Output) -> Result<Sink, Error> {
        Ok(match output {
            Output::Path(p) => Sink::File(AtomicFile::create(p)?, p.display().to_string()),
            Output::Stdout => Sink::Stdout(Vec::new()),
        })
    }

    fn name(&self) -> &str {
        match self {
            Sink::File(_, name) => name,
            Sink::Stdout(_) => "<stdout>",
        }
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Error> {
        let result = match self {
            Sink::File(f, _) => f.write_through(bytes),
            Sink::Stdout(buf) => {
                buf.extend_from_slice(bytes);
                Ok(())
            }
        };
        result.map_err(|source| self.error(source))
    }

    /// Reserves `bytes` of a file ahead of the writes ([`AtomicFile::reserve`]).
    fn reserve(&mut self, bytes: u64) {
        if let Sink::File(f, _) = self {
            f.reserve(bytes);
        }
    }

    fn error(&self, source: std::io::Error) -> Error {
        Error::new(
            Location::file(self.name()),
            ErrorKind::Io {
                action: "write",
                source,
            },
        )
    }

    /// Renames the file into place, or writes the buffer to standard output.
    fn commit(self) -> Result<(), Error> {
        match self {
            Sink::File(f, _) => f.commit(),
            Sink::Stdout(buf) => {
                let mut stdout = std::io::stdout().lock();
                stdout
                    .write_all(&buf)
                    .and_then(|()| stdout.flush())
                    .map_err(|source| {
                        Error::new(
                            Location::file("<stdout>"),
                            ErrorKind::Io {
                                action: "write",
                                source,
                            },
                        )
                    })
            }
        }
    }
}

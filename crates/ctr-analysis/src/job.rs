//! A whole forward-kinematics job, files to files: what `ctr-cli fk` runs.
//!
//! Order of work: read and validate the robot, read and check every joint row, check the
//! output header, open the output (a temporary file beside it, so a missing directory
//! fails before any solving), solve in parallel, apply the [`OnError`] policy, write,
//! and only then rename the output into place. Any error before the rename leaves an
//! existing output untouched.

use crate::batch::{batch_fk, BatchOptions, Progress, WARM_CHUNK_ROWS};
use crate::error::{Error, ErrorKind, Location};
use crate::formats::{tip_header, AtomicFile, JointTable, RobotSpec, TipWriter};
use ctr_core::{Model, Status};
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

/// A forward-kinematics job.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FkJob {
    /// The robot TOML.
    pub robot: Input,
    /// The joint CSV.
    pub joints: Input,
    /// The tip CSV.
    pub output: Output,
    /// Overrides the robot file's `[model] kind`.
    pub model: Option<Model>,
    /// Policy for rows that did not converge.
    pub on_error: OnError,
    /// Worker threads, 0 = all cores (the output does not depend on it).
    pub threads: usize,
}

/// A row whose solve did not converge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowFailure {
    /// 1-based line in the joint file.
    pub line: usize,
    /// How the solve ended.
    pub status: Status,
    /// Its residual, rad/mm.
    pub residual_per_mm: f64,
}

/// What a finished job did.
#[derive(Clone, Debug, PartialEq)]
pub struct FkSummary {
    /// The joint file's name as used in messages.
    pub joints_file: String,
    /// Rows solved.
    pub rows: usize,
    /// Rows written.
    pub written: usize,
    /// Rows that did not converge (skipped or marked), in input order.
    pub failures: Vec<RowFailure>,
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

/// Runs a job; see the module docs for the order of work.
pub fn run_fk(job: &FkJob, progress: &dyn Progress) -> Result<FkSummary, Error> {
    let spec = {
        let (name, bytes) = read_input(&job.robot)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            Error::new(
                Location::file(&name),
                ErrorKind::Io {
                    action: "read",
                    source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
                },
            )
        })?;
        RobotSpec::from_toml_str(&text, &name)?
    };
    let model = job.model.unwrap_or(spec.model);
    let table = match &job.joints {
        Input::Path(p) => JointTable::from_path(p, &spec.robot)?,
        Input::Stdin => {
            let (name, bytes) = read_input(&job.joints)?;
            JointTable::read(bytes.as_slice(), &name, &spec.robot)?
        }
    };
    let mark = job.on_error == OnError::Mark;
    let header = tip_header(table.header(), mark)
        .map_err(|kind| Error::new(Location::line(table.file(), 1), kind))?;
    let mut file = match &job.output {
        Output::Path(p) => Some(AtomicFile::create(p)?),
        Output::Stdout => None,
    };
    let options = BatchOptions {
        model,
        threads: job.threads,
        chunk_rows: WARM_CHUNK_ROWS,
    };
    let results = batch_fk(&spec.robot, table.all_joints(), &options, progress);
    let mut solved = Vec::with_capacity(results.len());
    let mut failures = Vec::new();
    for (row, r) in results.into_iter().enumerate() {
        let fk = r.map_err(|e| {
            Error::new(
                Location::line(table.file(), table.line(row)),
                ErrorKind::Joint(e),
            )
        })?;
        if fk.status != Status::Converged {
            failures.push(RowFailure {
                line: table.line(row),
                status: fk.status,
                residual_per_mm: fk.residual_per_mm,
            });
        }
        solved.push(fk);
    }
    if job.on_error == OnError::Fail {
        if let Some(first) = failures.first() {
            return Err(Error::new(
                Location::line(table.file(), first.line),
                ErrorKind::SolverFailed {
                    status: first.status,
                    residual_per_mm: first.residual_per_mm,
                    failed: failures.len(),
                    rows: solved.len(),
                },
            ));
        }
    }
    let out_name = match &job.output {
        Output::Path(p) => p.display().to_string(),
        Output::Stdout => "<stdout>".to_owned(),
    };
    let out_error = |kind| Error::new(Location::file(&out_name), kind);
    let mut buffer = Vec::new();
    let sink: &mut dyn Write = match &mut file {
        Some(f) => f,
        None => &mut buffer,
    };
    let mut writer = TipWriter::new(sink, &header, mark).map_err(out_error)?;
    let mut written = 0;
    for (row, fk) in solved.iter().enumerate() {
        if job.on_error == OnError::Skip && fk.status != Status::Converged {
            continue;
        }
        writer.write_row(table.fields(row), fk).map_err(out_error)?;
        written += 1;
    }
    writer.finish().map_err(out_error)?;
    match file {
        Some(f) => f.commit()?,
        None => {
            let mut stdout = std::io::stdout().lock();
            stdout
                .write_all(&buffer)
                .and_then(|()| stdout.flush())
                .map_err(|source| {
                    out_error(ErrorKind::Io {
                        action: "write",
                        source,
                    })
                })?;
        }
    }
    Ok(FkSummary {
        joints_file: table.file().to_owned(),
        rows: solved.len(),
        written,
        failures,
    })
}

//! Whole jobs, files to files: forward kinematics ([`run_fk`], what `ctr-cli fk` runs)
//! and inverse kinematics ([`run_ik`], `ctr-cli ik`).
//!
//! Order of work: read and validate the robot, read and check every joint row, check the
//! output header, open the output (a temporary file beside it, so a missing directory
//! fails before any solving), then solve and format in parallel, chunk by chunk
//! ([`for_each_chunk`]: the warm-start chunks of [`crate::batch`]), writing the chunks
//! in order as they are done; apply the [`OnError`] policy, and only then rename the
//! output into place. Any error before the rename leaves an existing output untouched
//! (the temporary file is removed); standard output is written only at the end.

use crate::batch::{batch_ik, branch_changed, solve_rows, IkBatchOptions, Rows, WARM_CHUNK_ROWS};
use crate::ik::{Ik, IkOptions, IkStatus};
use crate::margin::Margins;
use crate::model::{ModelError, ModelSpec, RowModel, RowSolver, EMPIRICAL};
use ctr_core::{Model, SolveError, Status};
use ctr_formats::parallel::{for_each_chunk, Progress};
use ctr_formats::{ik_output_columns, tip_header_for, AtomicFile, JointTable, RobotSpec};
use ctr_formats::{write_header, write_ik_row, write_tip_row_for, Carried, IkRow, TargetTable};
use ctr_formats::{Error, ErrorKind, Location};
use ctr_formats::{FkResult, TipColumns};
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
#[derive(Clone, Debug, PartialEq)]
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
    /// Append the `stability_margin` column.
    pub margin: bool,
    /// Report the runs of rows whose stability margin is below this
    /// ([`FkSummary::low_margin`]).
    pub warn_margin: Option<f64>,
}

/// A run of consecutive rows whose stability margin is below the warning margin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LowMargin {
    /// 1-based lines of the run's first and last row in the joint file.
    pub lines: (usize, usize),
    /// Rows in the run.
    pub rows: usize,
    /// The smallest margin in the run, and its line.
    pub min: (f64, usize),
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
    /// Runs of rows below [`FkJob::warn_margin`], in input order.
    pub low_margin: Vec<LowMargin>,
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

/// Warm-start chunks a worker of [`run_fk`] takes at a time.
const UNIT_CHUNKS: usize = 16;

/// Runs a job; see the module docs for the order of work.
///
/// The robot file's whole model is solved ([`RowModel`]: `[model] kind`, or
/// `job.model`, and every table of `[model.effects]`). With time effects (latency,
/// friction with a non-zero play) the rows are time series: a `t_s` column gives their
/// times, a `run` column cuts them into runs (contiguous rows with the same label; the
/// whole file without it), each simulated on its own in file order; without `t_s` the
/// row order stands for time, and latency is refused.
pub fn run_fk(job: &FkJob, progress: &dyn Progress) -> Result<FkSummary, Error> {
    let (robot_name, spec) = (input_name(&job.robot), read_robot(&job.robot)?);
    let fkm = {
        let mut m = ModelSpec::from_spec(&spec);
        m.model = job.model.unwrap_or(spec.model);
        m.rows().map_err(|e| model_error(&robot_name, e))?
    };
    let table = {
        let (name, bytes) = read_input(&job.joints)?;
        JointTable::from_bytes(bytes, &name, &spec.robot, job.threads)?
    };
    let actual = if fkm.needs_time() {
        Some(time_series(&table, &fkm, &robot_name)?)
    } else {
        None
    };
    let mark = job.on_error == OnError::Mark;
    let skip = job.on_error == OnError::Skip;
    let columns = TipColumns {
        status: mark,
        margin: job.margin,
    };
    let header = tip_header_for(table.header(), columns)
        .map_err(|kind| Error::new(Location::line(table.file(), 1), kind))?;
    let mut sink = Sink::open(&job.output)?;
    let mut head = Vec::new();
    write_header(&mut head, &header);
    sink.write(&head)?;

    /// One chunk's rows, formatted, and the solver they left.
    struct Chunk<'m> {
        text: Vec<u8>,
        written: usize,
        failures: Vec<RowFailure>,
        row_error: Option<(usize, SolveError)>,
        /// each row's margin, in order
        margins: Vec<f64>,
        first: Option<FkResult>,
        end: Option<RowSolver<'m>>,
    }
    let joints = match &actual {
        Some((a, t_s)) => Rows::Actual {
            actual: a,
            commanded: table.all_joints(),
            t_s: t_s.as_deref(),
        },
        None => Rows::Commanded(table.all_joints()),
    };
    // one lifetime for the solvers a chunk starts after and ends with: the model's
    fn tie<'m, F>(_: &'m RowModel, f: F) -> F
    where
        F: Fn(std::ops::Range<usize>, Option<&RowSolver<'m>>) -> Chunk<'m>,
    {
        f
    }
    let solve = tie(
        &fkm,
        |rows: std::ops::Range<usize>, after: Option<&RowSolver<'_>>| {
            let mut chunk = Chunk {
                text: Vec::with_capacity(rows.len() * (table.header().len() * 12 + 180)),
                written: 0,
                failures: Vec::new(),
                row_error: None,
                margins: Vec::with_capacity(rows.len()),
                first: None,
                end: None,
            };
            let start = rows.start;
            // the column wants every margin, a warning only those below it
            let margins = match (job.margin, job.warn_margin) {
                (true, _) => Margins::Exact,
                (false, Some(x)) => Margins::Below(x),
                (false, None) => Margins::Off,
            };
            let end = solve_rows(
                &fkm,
                joints,
                rows,
                WARM_CHUNK_ROWS,
                margins,
                after,
                |row, solved| {
                    let fk = match solved {
                        Ok(fk) => fk,
                        Err(e) => {
                            chunk.row_error = Some((row, e));
                            return false;
                        }
                    };
                    if row == start {
                        chunk.first = Some(fk);
                    }
                    // a row that did not converge has no margin to warn of
                    let converged = fk.status == Status::Converged;
                    chunk.margins.push(if converged {
                        fk.stability_margin
                    } else {
                        f64::NAN
                    });
                    if fk.status != Status::Converged {
                        chunk.failures.push(RowFailure {
                            line: table.line(row),
                            status: fk.status,
                            residual_per_mm: fk.residual_per_mm,
                        });
                        if skip {
                            return true;
                        }
                    }
                    let carried = match table.plain_line(row) {
                        Some(line) => Carried::Line(line),
                        None => Carried::Fields(table.fields(row)),
                    };
                    write_tip_row_for(&mut chunk.text, carried, &fk, columns);
                    chunk.written += 1;
                    true
                },
            );
            chunk.end = Some(end);
            chunk
        },
    );
    let mut failures = Vec::new();
    let mut written = 0;
    let mut failed: Option<Error> = None;
    let mut low = LowRuns::new(job.warn_margin);
    let mut last: Option<RowSolver<'_>> = None;
    // a worker takes UNIT_CHUNKS warm-start chunks at a time (fewer hand-overs), each
    // solved as batch_fk does: the same numbers (a unit whose first row lies on another
    // branch from where the unit before ended is solved again after it, see solve_rows)
    for_each_chunk(
        table.len(),
        WARM_CHUNK_ROWS * UNIT_CHUNKS,
        job.threads,
        progress,
        || (),
        |(), rows| solve(rows, None),
        |rows, mut chunk| {
            if let (Some(after), Some(first)) = (&last, &chunk.first) {
                let first = Ok(*first);
                if branch_changed(&fkm, joints, rows.start, WARM_CHUNK_ROWS, after, &first) {
                    chunk = solve(rows.clone(), Some(after));
                }
            }
            last = chunk.end.take();
            if let Some((row, e)) = chunk.row_error {
                failed = Some(Error::new(
                    Location::line(table.file(), table.line(row)),
                    fkm.row_error(e),
                ));
                return false;
            }
            for (k, m) in chunk.margins.iter().enumerate() {
                low.row(rows.start + k, table.line(rows.start + k), *m);
            }
            failures.extend(chunk.failures);
            if job.on_error == OnError::Fail && !failures.is_empty() {
                // nothing will be written: keep solving only to count the failures
                return true;
            }
            written += chunk.written;
            sink.write_or_stop(&chunk.text, &mut failed)
        },
    );
    if let Some(e) = failed {
        return Err(e);
    }
    if job.on_error == OnError::Fail {
        if let Some(first) = failures.first() {
            return Err(Error::new(
                Location::line(table.file(), first.line),
                ErrorKind::SolverFailed {
                    status: first.status,
                    residual_per_mm: first.residual_per_mm,
                    failed: failures.len(),
                    rows: table.len(),
                },
            ));
        }
    }
    sink.commit()?;
    Ok(FkSummary {
        joints_file: table.file().to_owned(),
        rows: table.len(),
        written,
        failures,
        low_margin: low.finish(),
    })
}

/// Gathers the runs of consecutive rows whose margin is below a warning margin.
struct LowRuns {
    below: Option<f64>,
    runs: Vec<LowMargin>,
    /// the row after the open run's last
    next: usize,
}

impl LowRuns {
    fn new(below: Option<f64>) -> Self {
        LowRuns {
            below,
            runs: Vec::new(),
            next: usize::MAX,
        }
    }

    /// Row `row` (at `line`) has margin `m`; rows come in order.
    fn row(&mut self, row: usize, line: usize, m: f64) {
        let Some(below) = self.below else { return };
        // a NaN margin (a row that did not solve) is not a low one
        if m.is_nan() || m >= below {
            return;
        }
        match self.runs.last_mut() {
            Some(run) if self.next == row => {
                run.lines.1 = line;
                run.rows += 1;
                if m < run.min.0 {
                    run.min = (m, line);
                }
            }
            _ => self.runs.push(LowMargin {
                lines: (line, line),
                rows: 1,
                min: (m, line),
            }),
        }
        self.next = row + 1;
    }

    fn finish(self) -> Vec<LowMargin> {
        self.runs
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

/// The actual joints of a joint file's rows under the model's time effects: `t_s`
/// (when the file has it) the rows' times, `run` (when it has it) their runs; see
/// [`run_fk`].
fn time_series(
    table: &JointTable,
    fkm: &RowModel,
    robot: &str,
) -> Result<(Vec<f64>, Option<Vec<f64>>), Error> {
    let file = table.file();
    let t_col = table.column("t_s");
    if t_col.is_none() {
        if let Some(effect) = fkm.needs_times() {
            let message = if effect == EMPIRICAL {
                format!(
                    "{robot}'s model.empirical has a term in t: it needs a t_s column \
                     (seconds); add one, or remove the term"
                )
            } else {
                let tau = fkm.effects().latency.map_or(0.0, |l| l.tau_s);
                format!(
                    "{effect} needs a t_s column (seconds; rows of a run in time order) to \
                     delay the commands by model.effects.{effect}.tau_s = {tau} s of \
                     {robot}; add one, or remove the table"
                )
            };
            return Err(Error::new(
                Location::line(file, table.header_line()),
                ErrorKind::Effect { message },
            ));
        }
    }
    let run_col = table.column("run");
    let mut times = Vec::with_capacity(if t_col.is_some() { table.len() } else { 0 });
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    let mut label_of_run: &str = "";
    for row in 0..table.len() {
        let at = |kind| Error::new(Location::line(file, table.line(row)), kind);
        let label = run_col.map_or("", |c| table.field(row, c).trim());
        let same_run = row > 0 && label == label_of_run;
        if let Some(c) = t_col {
            let cell = table.field(row, c);
            let t: f64 = cell.trim().parse().map_err(|_| {
                at(ErrorKind::NotANumber {
                    column: "t_s".into(),
                    found: cell.to_owned(),
                })
            })?;
            if !t.is_finite() {
                return Err(at(ErrorKind::NotFinite {
                    column: "t_s".into(),
                    found: cell.to_owned(),
                }));
            }
            if let (true, Some(&prev)) = (same_run, times.last()) {
                if t < prev {
                    let run = if run_col.is_some() {
                        format!(" in run {label}")
                    } else {
                        String::new()
                    };
                    return Err(at(ErrorKind::Csv {
                        message: format!(
                            "column t_s: {t} is earlier than the previous row's {prev}{run}; \
                             the rows of a run must be in time order (model.effects of {robot} \
                             act along time)"
                        ),
                    }));
                }
            }
            times.push(t);
        }
        match runs.last_mut() {
            Some(r) if same_run => r.end = row + 1,
            _ => {
                runs.push(row..row + 1);
                label_of_run = label;
            }
        }
    }
    let actual = fkm
        .actual_joints(table.all_joints(), t_col.map(|_| &times[..]), &runs)
        .map_err(|e| {
            Error::new(
                Location::line(file, table.header_line()),
                ErrorKind::Effect {
                    message: e.to_string(),
                },
            )
        })?;
    Ok((actual, t_col.map(|_| times)))
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
            Sink::File(f, _) => f.write_all(bytes),
            Sink::Stdout(buf) => {
                buf.extend_from_slice(bytes);
                Ok(())
            }
        };
        result.map_err(|source| self.error(source))
    }

    /// Writes `bytes` for a batch's `consume`: `true` to go on, or `false` with the
    /// error kept in `failed`.
    fn write_or_stop(&mut self, bytes: &[u8], failed: &mut Option<Error>) -> bool {
        match self.write(bytes) {
            Ok(()) => true,
            Err(e) => {
                *failed = Some(e);
                false
            }
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

/// An inverse-kinematics job: what `ctr-cli ik` runs.
///
/// Order of work: read and validate the robot, build the solver (its limits and start
/// table), read and check every target row, check the output header, open the output,
/// solve ([`batch_ik`]: warm along the rows in fixed chunks, or cold), writing the
/// chunks in order as they are done, and rename the output into place. Every target
/// gets a row: an unreachable one the closest point found, with its status and
/// residual; the caller decides whether that is a failure.
#[derive(Clone, Debug, PartialEq)]
pub struct IkJob {
    /// The robot TOML (its `[limits]` bound the joints).
    pub robot: Input,
    /// The target CSV.
    pub targets: Input,
    /// The joint CSV to write.
    pub output: Output,
    /// Overrides the robot file's `[model] kind`.
    pub model: Option<Model>,
    /// Solver settings.
    pub options: IkOptions,
    /// Read `qw,qx,qy,qz` as ordinary columns (position targets only).
    pub position_only: bool,
    /// Warm start along the rows (`true`) or solve every target cold.
    pub warm: bool,
    /// Rows per warm-started chunk ([`batch_ik`]); 0: the whole file is one chunk.
    pub chunk_rows: usize,
    /// Worker threads, 0 = all cores (the output does not depend on it).
    pub threads: usize,
}

/// A target that was not reached.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkRowFailure {
    /// 1-based line in the target file.
    pub line: usize,
    /// How the solve ended.
    pub status: IkStatus,
    /// Distance from the closest point found to the target, mm.
    pub residual_mm: f64,
    /// Angle to the target orientation, rad (pose targets).
    pub orientation_residual_rad: Option<f64>,
}

/// What a finished IK job did.
#[derive(Clone, Debug, PartialEq)]
pub struct IkSummary {
    /// The target file's name as used in messages.
    pub targets_file: String,
    /// Rows solved (all written).
    pub rows: usize,
    /// Targets not reached, in input order.
    pub not_reached: Vec<IkRowFailure>,
}

/// Runs an IK job; see [`IkJob`] for the order of work.
pub fn run_ik(job: &IkJob, progress: &dyn Progress) -> Result<IkSummary, Error> {
    let (robot_name, spec) = {
        let name = match &job.robot {
            Input::Stdin => "<stdin>".to_owned(),
            Input::Path(p) => p.display().to_string(),
        };
        (name, read_robot(&job.robot)?)
    };
    let model = job.model.unwrap_or(spec.model);
    let ik = Ik::for_spec(&spec, model, job.options)
        .map_err(|e| Error::new(Location::file(&robot_name), ErrorKind::Ik(Box::new(e))))?;
    let table = {
        let (name, bytes) = read_input(&job.targets)?;
        TargetTable::from_bytes(bytes, &name, job.position_only, job.threads)?
    };
    let pose = table.has_orientation();
    let columns = ik_output_columns(table.header(), spec.robot.n_tubes(), pose);
    let mut sink = Sink::open(&job.output)?;
    let mut head = Vec::new();
    write_header(&mut head, &columns.header);
    sink.write(&head)?;
    let targets = table.targets();
    let options = IkBatchOptions {
        threads: job.threads,
        chunk_rows: if job.chunk_rows == 0 {
            targets.len().max(1)
        } else {
            job.chunk_rows
        },
        warm: job.warm,
    };
    let mut not_reached = Vec::new();
    let mut failed = None;
    let mut text = Vec::new();
    batch_ik(&ik, &targets, &options, progress, |range, results| {
        text.clear();
        for (row, r) in range.zip(&results) {
            if r.status != IkStatus::Reached {
                not_reached.push(IkRowFailure {
                    line: table.line(row),
                    status: r.status,
                    residual_mm: r.residual_mm,
                    orientation_residual_rad: r.orientation_residual_rad,
                });
            }
            let joints = ik.to_file_units(&r.q);
            let out = IkRow {
                joints: &joints,
                tip: &r.tip,
                residual_mm: r.residual_mm,
                orientation_residual_rad: r.orientation_residual_rad,
                status: r.status.name(),
            };
            write_ik_row(&mut text, table.carried(row, &columns.carried), &out, pose);
        }
        sink.write_or_stop(&text, &mut failed)
    });
    if let Some(e) = failed {
        return Err(e);
    }
    sink.commit()?;
    Ok(IkSummary {
        targets_file: table.file().to_owned(),
        rows: table.len(),
        not_reached,
    })
}

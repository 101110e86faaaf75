//! The forward-kinematics job ([`run_fk`]): the joint file streamed through the workers
//! in pieces, the tips written in order as they come.

use super::time::{self, Series};
use super::{input_name, model_error, read_robot, Input, OnError, Output, Sink};
use crate::batch::{branch_changed, solve_rows, Rows, WARM_CHUNK_ROWS};
use crate::margin::Margins;
use crate::model::{ModelSpec, RowModel, RowSolver};
use ctr_core::{Model, SolveError, Status};
use ctr_formats::parallel::{stream, Progress};
use ctr_formats::{is_parquet, tip_batch, tip_column_types, Batch, ParquetOutput};
use ctr_formats::{tip_header_for, write_header, write_tip_row_for, JointRows, RobotSpec};
use ctr_formats::{Error, ErrorKind, Location};
use ctr_formats::{FkResult, JointParser, JointPiece, JointStream, TipColumns};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

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
    /// The `line`s above are 1-based rows of a Parquet joint file, not lines.
    pub lines_are_rows: bool,
}

/// Warm-start chunks of the batch in a piece of rows a worker takes at a time (the
/// output does not depend on it: see [`run_fk`]).
const PIECE_CHUNKS: usize = 64;

/// Rows in a piece.
const PIECE_ROWS: usize = WARM_CHUNK_ROWS * PIECE_CHUNKS;

/// The part of its estimated size a CSV output's reserved size has in excess
/// (1 / this), for an estimate a little short.
const RESERVE_MARGIN: usize = 20;

/// Pieces between the reader and the writer at once, per worker thread: what bounds
/// the memory of a job (with [`PIECE_ROWS`] and the reader's block).
const PIECES_PER_THREAD: usize = 4;

/// Runs a job; see the module docs for the order of work.
///
/// The robot file's whole model is solved ([`RowModel`]: `[model] kind`, or
/// `job.model`, and every table of `[model.effects]`). With time effects (latency,
/// friction with a non-zero play) the rows are time series: a `t_s` column gives their
/// times, a `run` column cuts them into runs (contiguous rows with the same label; the
/// whole file without it), each simulated on its own in file order; without `t_s` the
/// row order stands for time, and latency is refused.
///
/// Without time effects the joint file is streamed: a reader cuts it into pieces of
/// whole warm-start chunks ([`crate::batch::solve_rows`]), the workers parse, check,
/// solve and format a piece each, and the pieces are written in order: memory stays
/// bounded whatever the file's size (with a file as output; standard output is
/// written at the end). The result is the same, bit for bit, for any thread count and
/// as if the file had been read whole: a piece whose first row lies on another branch
/// than the piece before ended on is solved again after it. With time effects every row
/// is read first (the effects act along the rows).
///
/// Errors are those of reading every row before solving any: the first bad row of the
/// file, else a bad time series, a clashing output column or output path, a row the
/// model cannot solve, a failed write, and last the rows that did not converge (under
/// [`OnError::Fail`]).
pub fn run_fk(job: &FkJob, progress: &dyn Progress) -> Result<FkSummary, Error> {
    let started = Instant::now();
    let robot_name = input_name(&job.robot);
    let spec = read_robot(&job.robot)?;
    let fkm = fk_model(job, &spec, &robot_name)?;
    let mut joints = open_joints(&job.joints, &spec)?;
    let parquet_out = matches!(&job.output, Output::Path(p) if is_parquet(p));
    let parser = joints.parser(parquet_out);
    let mut run = Run::new(job, &joints);
    if fkm.needs_time() {
        let pieces = read_every_row(&mut joints, &parser, job.threads)?;
        let rows = time::Rows {
            pieces: &pieces,
            file: joints.file(),
            header: joints.header(),
            header_at: joints.header_location(),
        };
        let series = time::time_series(&rows, &fkm, &robot_name)?;
        run.open(&joints, &job.output)?;
        let ctx = Context::new(job, &fkm, &parser, run.columns, Some(&series));
        progress.start(pieces.iter().map(JointRows::len).sum());
        run.streaming = Some(started.elapsed());
        let mut pieces = pieces.into_iter();
        run.solve(&ctx, || pieces.next().map(Item::Parsed), progress);
    } else {
        let ctx = Context::new(job, &fkm, &parser, run.columns, None);
        if let Err(e) = run.open(&joints, &job.output) {
            // reported only when every row reads well
            run.fail(&ctx, e);
        }
        progress.start(joints.estimated_rows().unwrap_or(0));
        run.streaming = Some(started.elapsed());
        run.solve(
            &ctx,
            || joints.next_piece(PIECE_ROWS).map(Item::Raw),
            progress,
        );
    }
    progress.finish();
    let before = run.streaming.unwrap_or_default();
    let streamed = Instant::now();
    let result = run.finish();
    if let Some(stages) = progress.stages() {
        stages.add_around(before, streamed.elapsed());
    }
    result
}

/// The row model a job solves: the robot file's, with `job.model` for its kind.
fn fk_model(job: &FkJob, spec: &RobotSpec, robot_name: &str) -> Result<RowModel, Error> {
    let mut m = ModelSpec::from_spec(spec);
    m.model = job.model.unwrap_or(spec.model);
    m.rows().map_err(|e| model_error(robot_name, e))
}

/// Starts reading the joint file (its header is checked here).
fn open_joints(input: &Input, spec: &RobotSpec) -> Result<JointStream<'static>, Error> {
    match input {
        Input::Stdin => JointStream::from_reader(std::io::stdin(), "<stdin>", &spec.robot),
        Input::Path(p) => JointStream::from_path(p, &spec.robot),
    }
}

/// Every row of the joint file, parsed and checked in parallel, in pieces in file
/// order; the error is the file's first.
fn read_every_row(
    joints: &mut JointStream<'_>,
    parser: &JointParser,
    threads: usize,
) -> Result<Vec<JointRows>, Error> {
    let mut pieces = Vec::new();
    let mut first_error = None;
    let in_flight = PIECES_PER_THREAD * ctr_formats::parallel::resolve_threads(threads);
    stream(
        threads,
        in_flight,
        None,
        || joints.next_piece(PIECE_ROWS),
        || (),
        |(), piece: JointPiece| piece.parse(parser),
        |rows| match rows {
            Ok(rows) => {
                pieces.push(rows);
                true
            }
            Err(e) => {
                first_error = Some(e);
                false
            }
        },
    );
    match first_error {
        Some(e) => Err(e),
        None => Ok(pieces),
    }
}

/// What a worker is given: a piece to parse, or rows read already.
enum Item {
    Raw(JointPiece),
    Parsed(JointRows),
}

/// What the workers share.
struct Context<'a> {
    job: &'a FkJob,
    fkm: &'a RowModel,
    parser: &'a JointParser,
    columns: TipColumns,
    /// the output is Parquet: rows are gathered as columns
    columns_out: bool,
    /// the rows' actual joints and times, for a model with time effects
    series: Option<&'a Series>,
    /// set once the job has failed: the workers only parse (the first bad row of the
    /// file still comes first)
    stop: AtomicBool,
}

/// A piece of rows worked on: parsed, and solved and formatted unless the job had
/// failed by then.
struct Done<'m> {
    rows: Result<JointRows, Error>,
    chunk: Option<Chunk<'m>>,
}

/// One piece's rows, formatted, and the solver they left.
struct Chunk<'m> {
    /// the rows as CSV text, or as columns (a Parquet output)
    text: Vec<u8>,
    batch: Option<Batch>,
    written: usize,
    failures: Vec<RowFailure>,
    /// the first row (of the piece) the model could not solve
    row_error: Option<(usize, SolveError)>,
    /// each row's margin, in order
    margins: Vec<f64>,
    first: Option<FkResult>,
    end: Option<RowSolver<'m>>,
}

impl<'a> Context<'a> {
    fn new(
        job: &'a FkJob,
        fkm: &'a RowModel,
        parser: &'a JointParser,
        columns: TipColumns,
        series: Option<&'a Series>,
    ) -> Self {
        Context {
            job,
            fkm,
            parser,
            columns,
            columns_out: matches!(&job.output, Output::Path(p) if is_parquet(p)),
            series,
            stop: AtomicBool::new(false),
        }
    }

    /// Parses (if need be), solves and formats one piece.
    fn work(&self, item: Item) -> Done<'a> {
        let rows = match item {
            Item::Raw(piece) => piece.parse(self.parser),
            Item::Parsed(rows) => Ok(rows),
        };
        let chunk = match &rows {
            Ok(rows) if !self.stop.load(Ordering::Relaxed) => Some(self.solve(rows, None)),
            _ => None,
        };
        Done { rows, chunk }
    }

    /// The joints of `rows` as the batch solves them: commanded, or actual under time
    /// effects.
    fn joints<'r>(&'r self, rows: &'r JointRows) -> Rows<'r> {
        match self.series {
            Some(series) => {
                let w = 2 * self.fkm.robot().n_tubes();
                let span = rows.first_row()..rows.first_row() + rows.len();
                Rows::Actual {
                    actual: &series.actual[span.start * w..span.end * w],
                    commanded: rows.all_joints(),
                    t_s: series.t_s.as_ref().map(|t| &t[span]),
                }
            }
            None => Rows::Commanded(rows.all_joints()),
        }
    }

    /// `fk`, the tip of the file's row `row`, with the model's learned discrepancy
    /// added (`[model.discrepancy]`, along the rows' runs: [`Series::discrepancy`]).
    fn corrected(&self, row: usize, mut fk: FkResult) -> FkResult {
        if let Some(d) = self.series.and_then(|s| s.discrepancy.as_ref()) {
            for (p, c) in fk.position.iter_mut().zip(d[row]) {
                *p += c;
            }
        }
        fk
    }

    /// Solves and formats `rows`, after `after` (the solver the piece before ended
    /// with) or from a fresh start.
    fn solve(&self, rows: &JointRows, after: Option<&RowSolver<'a>>) -> Chunk<'a> {
        let job = self.job;
        let text_bytes = match self.columns_out {
            true => 0,
            false => rows.len() * (self.parser.columns() * 12 + 180),
        };
        let mut chunk = Chunk {
            text: Vec::with_capacity(text_bytes),
            batch: None,
            written: 0,
            failures: Vec::new(),
            row_error: None,
            margins: Vec::with_capacity(rows.len()),
            first: None,
            end: None,
        };
        // the column wants every margin, a warning only those below it
        let margins = match (job.margin, job.warn_margin) {
            (true, _) => Margins::Exact,
            (false, Some(x)) => Margins::Below(x),
            (false, None) => Margins::Off,
        };
        // a Parquet output's rows: which were kept, their tips
        let mut kept: Vec<(usize, FkResult)> = Vec::new();
        let all = 0..rows.len();
        let end = solve_rows(
            self.fkm,
            self.joints(rows),
            all,
            WARM_CHUNK_ROWS,
            margins,
            after,
            |r, solved| {
                let fk = match solved {
                    Ok(fk) => fk,
                    Err(e) => {
                        chunk.row_error = Some((r, e));
                        return false;
                    }
                };
                if chunk.keeps(rows, r, &fk, job.on_error == OnError::Skip) {
                    let fk = self.corrected(rows.first_row() + r, fk);
                    if self.columns_out {
                        kept.push((r, fk));
                    } else {
                        write_tip_row_for(&mut chunk.text, rows.carried(r), &fk, self.columns);
                    }
                    chunk.written += 1;
                }
                true
            },
        );
        if self.columns_out {
            let (kept, tips): (Vec<usize>, Vec<FkResult>) = kept.into_iter().unzip();
            let mut batch = rows.batch(&kept);
            batch.append(tip_batch(&tips, self.columns));
            chunk.batch = Some(batch);
        }
        chunk.end = Some(end);
        chunk
    }
}

impl Chunk<'_> {
    /// Notes row `r` of `rows` solved as `fk` (its margin, whether it converged) and
    /// says whether it is written (`skip`: rows that did not converge are not).
    fn keeps(&mut self, rows: &JointRows, r: usize, fk: &FkResult, skip: bool) -> bool {
        if r == 0 {
            self.first = Some(*fk);
        }
        // a row that did not converge has no margin to warn of
        let converged = fk.status == Status::Converged;
        self.margins.push(if converged {
            fk.stability_margin
        } else {
            f64::NAN
        });
        if !converged {
            self.failures.push(RowFailure {
                line: rows.line(r),
                status: fk.status,
                residual_per_mm: fk.residual_per_mm,
            });
        }
        converged || !skip
    }
}

/// Where the tips go: CSV (a file or standard output) or a Parquet file.
enum Out {
    Csv(Sink),
    Parquet(Box<ParquetOutput>),
}

/// The job's state as the pieces come back in order.
struct Run<'j> {
    job: &'j FkJob,
    file: String,
    /// the joint file is Parquet: its rows have no lines
    rows_not_lines: bool,
    /// about how many rows the joint file has, until a CSV output's size is reserved
    /// from it
    estimate: Option<usize>,
    columns: TipColumns,
    sink: Option<Out>,
    /// rows read
    rows: usize,
    written: usize,
    failures: Vec<RowFailure>,
    low: LowRuns,
    /// the first bad row of the input: ends the job
    bad_row: Option<Error>,
    /// when the stream started (after setting up), for the stages' times
    streaming: Option<Duration>,
    /// a clashing output header or output path (reported once every row has been
    /// read), a row the model could not solve, or a failed write
    failed: Option<Error>,
}

impl<'j> Run<'j> {
    fn new(job: &'j FkJob, joints: &JointStream<'_>) -> Self {
        Run {
            job,
            file: joints.file().to_owned(),
            rows_not_lines: joints.is_parquet(),
            estimate: joints.estimated_rows(),
            columns: TipColumns {
                status: job.on_error == OnError::Mark,
                margin: job.margin,
            },
            sink: None,
            rows: 0,
            written: 0,
            failures: Vec::new(),
            low: LowRuns::new(job.warn_margin),
            bad_row: None,
            streaming: None,
            failed: None,
        }
    }

    /// Checks the output header and opens the output (writing a CSV file's header).
    fn open(&mut self, joints: &JointStream<'_>, output: &Output) -> Result<(), Error> {
        let header = tip_header_for(joints.header(), self.columns).map_err(|kind| {
            let at = if joints.is_parquet() {
                Location::file(&self.file)
            } else {
                Location::line(&self.file, 1)
            };
            Error::new(at, kind)
        })?;
        self.sink = Some(match output {
            Output::Path(p) if is_parquet(p) => {
                let mut types = joints.column_types();
                types.extend(tip_column_types(self.columns));
                Out::Parquet(Box::new(ParquetOutput::create(p, types)?))
            }
            _ => {
                let mut sink = Sink::open(output)?;
                let mut head = Vec::new();
                write_header(&mut head, &header);
                sink.write(&head)?;
                Out::Csv(sink)
            }
        });
        Ok(())
    }

    /// Streams the items of `source` through the workers and takes their pieces in
    /// order.
    fn solve<'a>(
        &mut self,
        ctx: &Context<'a>,
        source: impl FnMut() -> Option<Item> + Send,
        progress: &dyn Progress,
    ) {
        let threads = ctr_formats::parallel::resolve_threads(self.job.threads);
        let mut last: Option<RowSolver<'a>> = None;
        stream(
            threads,
            PIECES_PER_THREAD * threads,
            progress.stages(),
            source,
            || (),
            |(), item| ctx.work(item),
            |done| {
                let rows = done.rows.as_ref().map_or(0, JointRows::len);
                let more = self.take(ctx, done, &mut last);
                progress.advance(rows);
                more
            },
        );
    }

    /// Takes the next piece in order: checks its branch against the piece before,
    /// gathers its warnings and writes it. `false` ends the stream (a bad row).
    fn take<'a>(
        &mut self,
        ctx: &Context<'a>,
        done: Done<'a>,
        last: &mut Option<RowSolver<'a>>,
    ) -> bool {
        let rows = match done.rows {
            Ok(rows) => rows,
            Err(e) => {
                self.bad_row = Some(e);
                return false;
            }
        };
        self.rows += rows.len();
        let Some(mut chunk) = done.chunk.filter(|_| self.failed.is_none()) else {
            return true;
        };
        if let (Some(after), Some(first)) = (&*last, &chunk.first) {
            let first = Ok(*first);
            if branch_changed(
                ctx.fkm,
                ctx.joints(&rows),
                0,
                WARM_CHUNK_ROWS,
                after,
                &first,
            ) {
                chunk = ctx.solve(&rows, Some(after));
            }
        }
        *last = chunk.end.take();
        if let Some((r, e)) = chunk.row_error {
            let at = rows.location(&self.file, r);
            self.fail(ctx, Error::new(at, ctx.fkm.row_error(e)));
            return true;
        }
        for (k, m) in chunk.margins.iter().enumerate() {
            self.low.row(rows.first_row() + k, rows.line(k), *m);
        }
        self.failures.extend(chunk.failures);
        if self.job.on_error == OnError::Fail && !self.failures.is_empty() {
            // nothing will be written: keep solving only to count the failures
            return true;
        }
        self.written += chunk.written;
        let written = match (self.sink.as_mut(), chunk.batch) {
            (Some(Out::Csv(sink)), _) => {
                // the file's size, reserved from its first rows and the rows expected
                if let (Some(rows), true) = (self.estimate.take(), chunk.written > 0) {
                    let per_row = chunk.text.len() / chunk.written;
                    sink.reserve((rows * per_row + rows * per_row / RESERVE_MARGIN) as u64);
                }
                sink.write(&chunk.text)
            }
            (Some(Out::Parquet(out)), Some(batch)) => out.write(batch),
            _ => Ok(()),
        };
        if let Err(e) = written {
            self.fail(ctx, e);
        }
        true
    }

    /// The job failed (the output, a row the model cannot solve, a write): the rest
    /// is only read.
    fn fail(&mut self, ctx: &Context<'_>, e: Error) {
        self.failed = Some(e);
        ctx.stop.store(true, Ordering::Relaxed);
    }

    /// The job's outcome, the errors in order (see [`run_fk`]); on success the output
    /// is put in place.
    fn finish(self) -> Result<FkSummary, Error> {
        if let Some(e) = self.bad_row.or(self.failed) {
            return Err(e);
        }
        if self.job.on_error == OnError::Fail {
            if let Some(first) = self.failures.first() {
                let at = if self.rows_not_lines {
                    Location::row(&self.file, first.line)
                } else {
                    Location::line(&self.file, first.line)
                };
                return Err(Error::new(
                    at,
                    ErrorKind::SolverFailed {
                        status: first.status,
                        residual_per_mm: first.residual_per_mm,
                        failed: self.failures.len(),
                        rows: self.rows,
                    },
                ));
            }
        }
        match self.sink {
            Some(Out::Csv(sink)) => sink.commit()?,
            Some(Out::Parquet(out)) => out.commit()?,
            None => {}
        }
        Ok(FkSummary {
            joints_file: self.file,
            rows: self.rows,
            written: self.written,
            failures: self.failures,
            low_margin: self.low.finish(),
            lines_are_rows: self.rows_not_lines,
        })
    }
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

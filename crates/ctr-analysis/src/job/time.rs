//! The rows of a joint file as time series: the times of `t_s`, the runs of `run`, and
//! the actual joints the model's time effects (latency, friction) make of the commands.

use crate::learned::along_commands;
use crate::model::{RowModel, EMPIRICAL};
use ctr_formats::{Error, ErrorKind, JointRows, Location};

/// A joint file's rows under the model's time effects, all of them in file order.
pub(super) struct Series {
    /// The actual joints, row after row ([`RowModel::actual_joints`]).
    pub actual: Vec<f64>,
    /// Each row's time, s, when the file has `t_s`.
    pub t_s: Option<Vec<f64>>,
    /// Each row's correction by the model's learned discrepancy, mm, when it has one
    /// (run by run, along the commanded joints: `crate::discrepancy`).
    pub discrepancy: Option<Vec<[f64; 3]>>,
}

/// What a time series is read from: the joint file's pieces in order, its name, header
/// and where the header is.
pub(super) struct Rows<'a> {
    pub pieces: &'a [JointRows],
    pub file: &'a str,
    pub header: &'a [String],
    pub header_at: Location,
}

impl Rows<'_> {
    /// The index of the column named `name` (header names trimmed), if present.
    fn column(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h.trim() == name)
    }

    /// Every row as (its piece, its index in the piece), in file order.
    fn each(&self) -> impl Iterator<Item = (&JointRows, usize)> {
        self.pieces
            .iter()
            .flat_map(|p| (0..p.len()).map(move |r| (p, r)))
    }
}

/// The actual joints of a joint file's rows under the model's time effects: `t_s`
/// (when the file has it) the rows' times, `run` (when it has it) their runs; see
/// [`run_fk`](super::run_fk).
pub(super) fn time_series(rows: &Rows<'_>, fkm: &RowModel, robot: &str) -> Result<Series, Error> {
    let file = rows.file;
    let t_col = rows.column("t_s");
    if t_col.is_none() {
        if let Some(effect) = fkm.needs_times() {
            let message = missing_times(effect, fkm, robot);
            return Err(Error::new(
                rows.header_at.clone(),
                ErrorKind::Effect { message },
            ));
        }
    }
    let run_col = rows.column("run");
    let mut times = Vec::new();
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    let mut label_of_run = String::new();
    for (row, (piece, r)) in rows.each().enumerate() {
        let cell = run_col.map(|c| piece.field(r, c));
        let label = cell.as_deref().map_or("", str::trim);
        let same_run = row > 0 && label == label_of_run;
        if let Some(c) = t_col {
            let at = |kind| Error::new(piece.location(file, r), kind);
            let t = time_of(&piece.field(r, c)).map_err(at)?;
            if let (true, Some(&prev)) = (same_run, times.last()) {
                if t < prev {
                    return Err(at(time_goes_back(t, prev, run_col.map(|_| label), robot)));
                }
            }
            times.push(t);
        }
        match runs.last_mut() {
            Some(range) if same_run => range.end = row + 1,
            _ => {
                runs.push(row..row + 1);
                label_of_run = label.to_owned();
            }
        }
    }
    let commanded: Vec<f64> = rows
        .pieces
        .iter()
        .flat_map(|p| p.all_joints().iter().copied())
        .collect();
    let actual = fkm
        .actual_joints(&commanded, t_col.map(|_| &times[..]), &runs)
        .map_err(|e| {
            Error::new(
                rows.header_at.clone(),
                ErrorKind::Effect {
                    message: e.to_string(),
                },
            )
        })?;
    let t_s = t_col.map(|_| times);
    let discrepancy = fkm.spec().discrepancy.is_some().then(|| {
        let w = 2 * fkm.robot().n_tubes();
        runs.iter()
            .flat_map(|run| {
                let times = t_s.as_ref().map(|t| &t[run.clone()]);
                along_commands(fkm.spec(), &commanded[run.start * w..run.end * w], times)
                    .unwrap_or_default()
            })
            .map(|(c, _)| c)
            .collect()
    });
    Ok(Series {
        actual,
        t_s,
        discrepancy,
    })
}

/// Why a file without `t_s` cannot be solved under `effect`.
fn missing_times(effect: &str, fkm: &RowModel, robot: &str) -> String {
    if effect == EMPIRICAL {
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
    }
}

/// A `t_s` cell as a finite number of seconds.
fn time_of(cell: &str) -> Result<f64, ErrorKind> {
    let t: f64 = cell.trim().parse().map_err(|_| ErrorKind::NotANumber {
        column: "t_s".into(),
        found: cell.to_owned(),
    })?;
    if !t.is_finite() {
        return Err(ErrorKind::NotFinite {
            column: "t_s".into(),
            found: cell.to_owned(),
        });
    }
    Ok(t)
}

/// A row of a run earlier than the row before it (in run `label`, when the file has
/// runs).
fn time_goes_back(t: f64, prev: f64, label: Option<&str>, robot: &str) -> ErrorKind {
    let run = label.map_or(String::new(), |l| format!(" in run {l}"));
    ErrorKind::Csv {
        message: format!(
            "column t_s: {t} is earlier than the previous row's {prev}{run}; \
             the rows of a run must be in time order (model.effects of {robot} \
             act along time)"
        ),
    }
}

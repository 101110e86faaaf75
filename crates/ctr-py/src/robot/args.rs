//! Reading and checking the arguments of `Robot`'s calls, as `ctr-cli` reads and checks
//! its files: the model name, joint rows (finite, then the core's ranges), the rows'
//! times for time effects, IK targets, the thread count.

use super::Robot;
use crate::arrays::{self, Rows};
use crate::errors::{self, Fail};
use ctr_analysis::model::RowModel;
use ctr_core::Model;
use ctr_formats::{Error, ErrorKind, IkTarget, ModelKind, ORIENTATION_COLUMNS, TARGET_COLUMNS};
use pyo3::prelude::*;

/// Most worker threads a call may ask for (each is an OS thread).
pub(crate) const MAX_THREADS: usize = 1024;

/// `threads` checked: 0 (all cores) to [`MAX_THREADS`].
pub(crate) fn check_threads(threads: usize) -> PyResult<usize> {
    if threads > MAX_THREADS {
        return Err(errors::input(format!(
            "threads: {threads} is not in 0..={MAX_THREADS} (0 = all cores)"
        )));
    }
    Ok(threads)
}

/// The `threads` argument (absent: 0, all cores): an integer, checked by
/// [`check_threads`].
pub(crate) fn threads_arg(threads: Option<&Bound<'_, PyAny>>) -> PyResult<usize> {
    let Some(threads) = threads else {
        return Ok(0);
    };
    let t = count_arg(
        threads,
        "threads",
        0,
        MAX_THREADS as u64,
        " (0 = all cores)",
    )?;
    check_threads(t as usize)
}

/// An integer argument `name` in `lo..=hi`; anything else (a negative or huge number,
/// a float, a string) is an `InputError` naming it, as the other arguments' errors are
/// (not the `OverflowError` or `TypeError` of Python's conversion).
pub(crate) fn count_arg(
    value: &Bound<'_, PyAny>,
    name: &str,
    lo: u64,
    hi: u64,
    note: &str,
) -> PyResult<u64> {
    let text = || {
        value
            .repr()
            .map(|r| r.to_string())
            .unwrap_or_else(|_| "?".into())
    };
    // bool is an int in Python: refused like any other non-count
    if value.is_instance_of::<pyo3::types::PyBool>() {
        return Err(errors::input(format!(
            "{name}: {} is not an integer",
            text()
        )));
    }
    match value.extract::<i128>() {
        Ok(v) if v >= i128::from(lo) && v <= i128::from(hi) => Ok(v as u64),
        Ok(_) => Err(errors::input(format!(
            "{name}: {} is not in {lo}..={hi}{note}",
            text()
        ))),
        Err(_) => Err(errors::input(format!(
            "{name}: {} is not an integer",
            text()
        ))),
    }
}

impl Robot {
    /// `model` (a [`ModelKind`] name) or the file's.
    pub(super) fn model_arg(&self, model: Option<&str>) -> PyResult<Model> {
        match model {
            None => Ok(self.spec.model),
            Some(name) => name
                .parse::<ModelKind>()
                .map(Model::from)
                .map_err(|e| errors::input(format!("model: {e}"))),
        }
    }

    /// Reads joint rows (shape `(2n,)` or `(m, 2n)`).
    pub(super) fn read_joints(&self, obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Rows> {
        let n = self.spec.robot.n_tubes();
        let what = format!(
            "{} for a {n}-tube robot",
            self.spec.robot.joint_columns().join(", ")
        );
        arrays::read_rows(obj, name, &[2 * n], &what)
    }

    /// The checks `ctr-cli fk` makes on every joint row, in the same order: every value
    /// finite, then the core's ranges; the first bad row is the error.
    pub(super) fn check_joints(&self, rows: &Rows, name: &str) -> Result<(), Error> {
        let columns = self.spec.robot.joint_columns();
        for i in 0..rows.rows {
            let q = rows.row(i);
            let at = || errors::at(name, i, rows.batched);
            if let Some(k) = q.iter().position(|v| !v.is_finite()) {
                return Err(Error::new(
                    at(),
                    ErrorKind::NotFinite {
                        column: columns[k].clone(),
                        found: arrays::nonfinite_text(q[k]),
                    },
                ));
            }
            self.spec
                .robot
                .validate_joints(q)
                .map_err(|e| Error::new(at(), ErrorKind::Joint(e)))?;
        }
        Ok(())
    }

    /// The times of the rows for the model's time effects: `t_s` (one per row,
    /// finite, non-decreasing); required when the model has time effects (latency,
    /// friction with a non-zero play), ignored (but checked) otherwise.
    pub(super) fn times_arg(
        &self,
        fkm: &RowModel,
        t_s: Option<&Bound<'_, PyAny>>,
        rows: &Rows,
    ) -> PyResult<Option<Vec<f64>>> {
        let Some(obj) = t_s else {
            if let Some(effect) = fkm.time_effect() {
                return Err(errors::input(format!(
                    "{}: model.effects.{effect} acts along time: pass t_s= (the rows' times, \
                     seconds, non-decreasing; the rows are then one run in order)",
                    self.source
                )));
            }
            return Ok(None);
        };
        let obj = obj
            .py()
            .import("numpy")?
            .call_method1("atleast_1d", (obj,))?;
        let t = arrays::read_rows(&obj, "t_s", &[rows.rows], "one time per row of q, seconds")?;
        if t.batched || (rows.batched && t.rows != 1) {
            // a (m,) vector reads as one row of width m; a scalar per single q as (1,)
            return Err(errors::input(format!(
                "t_s: wanted shape ({},), one time per row of q",
                rows.rows
            )));
        }
        let t = t.data;
        for (i, &v) in t.iter().enumerate() {
            let at = errors::at("t_s", i, rows.batched);
            if !v.is_finite() {
                return Err(errors::input(format!(
                    "{at}: {} is not a finite number",
                    arrays::nonfinite_text(v)
                )));
            }
            if i > 0 && v < t[i - 1] {
                return Err(errors::input(format!(
                    "{at}: {v} is earlier than the previous row's {}; the rows are one run \
                     and must be in time order",
                    t[i - 1]
                )));
            }
        }
        Ok(Some(t))
    }

    /// Reads IK targets: positions `(3,)`/`(m, 3)` or poses `(7,)`/`(m, 7)`.
    pub(super) fn targets(rows: &Rows) -> Result<Vec<IkTarget>, Fail> {
        (0..rows.rows)
            .map(|i| {
                let t = rows.row(i);
                let at = || errors::at("targets", i, rows.batched);
                if let Some(k) = t.iter().position(|v| !v.is_finite()) {
                    let column = TARGET_COLUMNS.iter().chain(&ORIENTATION_COLUMNS).nth(k);
                    return Err(Fail::Ctr(Error::new(
                        at(),
                        ErrorKind::NotFinite {
                            column: column.map_or_else(String::new, |c| (*c).to_owned()),
                            found: arrays::nonfinite_text(t[k]),
                        },
                    )));
                }
                // as `ctr-cli ik` reads a targets file's row
                IkTarget::from_values(t).map_err(|kind| Fail::Ctr(Error::new(at(), kind)))
            })
            .collect()
    }
}

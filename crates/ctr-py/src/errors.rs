//! `ctr-analysis` errors as the `ctr_py` exceptions.
//!
//! The classes live in Python (`python/ctr_py/_errors.py`) because they inherit from
//! two built-ins each (`InputError(CtrError, ValueError)`, ...), which an exception
//! class made in Rust cannot. The message is the error's one-line display, the line
//! `ctr-cli` prints after `error: `. Errors about arrays name the argument and row
//! (`q[41]`) where the CLI names the file and line (`joints.csv:43`).

use ctr_formats::{Error, ErrorKind, Location};
use pyo3::PyErr;

pyo3::import_exception!(ctr_py._errors, InputError);
pyo3::import_exception!(ctr_py._errors, InputTypeError);
pyo3::import_exception!(ctr_py._errors, FileError);
pyo3::import_exception!(ctr_py._errors, SolverError);

/// The Python exception for `e`: `FileError` for I/O, `SolverError` for solves that
/// did not converge, `InputError` for everything else (bad files, bad values).
pub fn to_py(e: &Error) -> PyErr {
    let message = e.to_string();
    match e.kind() {
        ErrorKind::Io { .. } | ErrorKind::OutputDirectory { .. } => FileError::new_err(message),
        ErrorKind::SolverFailed { .. } => SolverError::new_err(message),
        _ => InputError::new_err(message),
    }
}

/// Where in an argument: `name` for a single vector, `name[row]` for a row of a batch.
pub fn at(name: &str, row: usize, batched: bool) -> Location {
    if batched {
        Location::file(format!("{name}[{row}]"))
    } else {
        Location::file(name)
    }
}

/// An `InputError` (a `ValueError`) with `message`.
pub fn input(message: String) -> PyErr {
    InputError::new_err(message)
}

/// An `InputTypeError` (a `TypeError` and an `InputError`) with `message`.
pub fn input_type(message: String) -> PyErr {
    InputTypeError::new_err(message)
}

/// A `SolverError` (a `RuntimeError`) with `message`.
pub fn solver(message: String) -> PyErr {
    SolverError::new_err(message)
}

/// Why a call failed, made while the GIL is released; [`Fail::into_py`] once it is
/// held again.
#[derive(Debug)]
pub enum Fail {
    /// An error `ctr-cli` reports the same way.
    Ctr(Error),
    /// Bad input with a message of the wheel's own (`InputError`).
    Input(String),
    /// A solve that did not converge, with a message of the wheel's own (`SolverError`).
    Solver(String),
}

impl From<Error> for Fail {
    fn from(e: Error) -> Self {
        Fail::Ctr(e)
    }
}

impl Fail {
    /// The Python exception.
    pub fn into_py(self) -> PyErr {
        match self {
            Fail::Ctr(e) => to_py(&e),
            Fail::Input(m) => input(m),
            Fail::Solver(m) => solver(m),
        }
    }
}

//! `ctr_py._ctr`: the compiled half of the `ctr-py` wheel (import `ctr_py`).
//!
//! A thin layer over `ctr-analysis`, with no numerics of its own: array-likes in are
//! checked for dtype and shape and copied into row-major `f64` rows (module `arrays`);
//! each call checks the rows as the CLI checks a joint file, then calls the std
//! layer (batch FK, IK, the Jacobian, the backbone) with the GIL released, on all
//! cores; results go back as numpy arrays. Errors become the `ctr_py` exception
//! hierarchy (module `errors`) with the CLI's one-line messages.
//!
//! The Python package (`python/ctr_py`) re-exports this module's classes beside its
//! pure-Python exception classes; `_ctr.pyi` there documents the Python API.
//! `Robot` (module `robot`) holds a validated robot file with its model: batch `fk`
//! (with margins, the time effects along `t_s`, the learned discrepancy and its band)
//! and `ik` equal to `ctr-cli fk` and `ctr-cli ik` bit for bit, `jacobian`,
//! `backbone`. Recordings, diagnosis, calibration and evaluation
//! (`ctr_py.read_recording`, `ctr_py.diagnose`, `ctr_py.calibrate`, `ctr_py.evaluate`)
//! are module functions in modules `recording` and `diagnosis`, over `ctr_diagnosis`,
//! as `ctr-cli diagnose` calls it; a `Report` keeps the report parsed once (module
//! `json`) and gives its JSON, summary, HTML page and fitted robots. Robots,
//! recordings and reports pickle, for worker processes (Dask).
//!
//! Rust tests here never start an interpreter (see the toolchain notes): the Python
//! side is tested with pytest under `tests/python/`.

use pyo3::prelude::*;

mod arrays;
mod diagnosis;
mod errors;
mod json;
mod recording;
mod robot;

/// The extension module `ctr_py._ctr`.
#[pymodule(name = "_ctr")]
fn ctr_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<robot::Robot>()?;
    m.add_class::<recording::Recording>()?;
    m.add_class::<diagnosis::Report>()?;
    m.add_function(wrap_pyfunction!(recording::read_recording, m)?)?;
    m.add_function(wrap_pyfunction!(diagnosis::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(diagnosis::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(diagnosis::evaluate, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

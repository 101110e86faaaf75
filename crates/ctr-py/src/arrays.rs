//! numpy arrays in and out.
//!
//! Inputs are any array-like (numpy arrays of any memory order or strides, lists,
//! tuples): converted with `numpy.asarray`, accepted when the dtype is a real number
//! type (`float*`, `int*`, `uint*`; converted to `float64`), refused with
//! `InputTypeError` otherwise (bool, complex, strings, objects), and copied into
//! row-major rows, so the solves run on plain slices with the GIL released and no
//! Python object is touched meanwhile.

use crate::errors;
use numpy::ndarray::IxDyn;
use numpy::{PyArray, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyList;

/// A 1-D input (one row) or a 2-D input (`rows` rows), values row after row.
#[derive(Clone, Debug, PartialEq)]
pub struct Rows {
    /// `rows * width` values, row-major.
    pub data: Vec<f64>,
    /// Number of rows (1 for a 1-D input).
    pub rows: usize,
    /// Values per row.
    pub width: usize,
    /// True for a 2-D input: results keep the row axis.
    pub batched: bool,
}

impl Rows {
    /// Row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.width..(i + 1) * self.width]
    }
}

/// `(a, b)` the way Python prints a shape.
fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Reads argument `name` as rows of one of the `widths` (`what` describes a row in
/// errors, e.g. "s1_mm, theta1_deg, ... for a 3-tube robot").
pub fn read_rows(
    obj: &Bound<'_, PyAny>,
    name: &str,
    widths: &[usize],
    what: &str,
) -> PyResult<Rows> {
    let py = obj.py();
    let np = py.import("numpy")?;
    let arr = np.call_method1("asarray", (obj,)).map_err(|e| {
        errors::input(format!(
            "{name}: not an array of numbers ({})",
            e.value(py).str().map(|s| s.to_string()).unwrap_or_default()
        ))
    })?;
    let dtype = arr.getattr("dtype")?;
    let kind: String = dtype.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "f" | "i" | "u") {
        return Err(errors::input_type(format!(
            "{name}: dtype {} is not a real number type (wanted float64; integer and other float arrays are converted)",
            dtype.str()?
        )));
    }
    let arr = np
        .call_method1("asarray", (arr, "float64"))?
        .cast_into::<PyArrayDyn<f64>>()
        .map_err(PyErr::from)?;
    let view = arr
        .try_readonly()
        .map_err(|e| errors::input(format!("{name}: {e}")))?;
    let shape = view.shape().to_vec();
    let wanted = || {
        let list = widths
            .iter()
            .map(|w| format!("({w},) or (m, {w})"))
            .collect::<Vec<_>>()
            .join(", or ");
        format!(
            "{name}: shape {} is not {list} ({what})",
            shape_text(&shape)
        )
    };
    let (rows, width, batched) = match shape[..] {
        [w] => (1, w, false),
        [m, w] => (m, w, true),
        _ => return Err(errors::input(wanted())),
    };
    if !widths.contains(&width) {
        return Err(errors::input(wanted()));
    }
    // `as_slice` also accepts Fortran order (memory order, not row-major): only a
    // C-contiguous array is copied as is; the rest (Fortran order, slices with steps,
    // negative strides) element by element in logical order
    let data = match view.as_slice() {
        Ok(s) if view.is_c_contiguous() => s.to_vec(),
        _ => view.as_array().iter().copied().collect(),
    };
    Ok(Rows {
        data,
        rows,
        width,
        batched,
    })
}

/// A float64 array of `shape` (row-major) holding `data`.
pub fn array<'py>(py: Python<'py>, data: Vec<f64>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    let a = numpy::ndarray::Array::from_shape_vec(IxDyn(shape), data)
        .map_err(|e| errors::input(format!("internal: {e}")))?;
    Ok(PyArray::from_owned_array(py, a).into_any())
}

/// A numpy array of strings.
pub fn strings<'py>(py: Python<'py>, items: &[&str]) -> PyResult<Bound<'py, PyAny>> {
    let list = PyList::new(py, items)?;
    let np = py.import("numpy")?;
    np.call_method1("array", (list, "str"))
}

/// The text of a non-finite value as Python prints it (`nan`, `inf`, `-inf`).
pub fn nonfinite_text(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v > 0.0 {
        "inf".into()
    } else {
        "-inf".into()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn shapes_print_like_python() {
        assert_eq!(super::shape_text(&[3]), "(3,)");
        assert_eq!(super::shape_text(&[2, 6]), "(2, 6)");
        assert_eq!(super::shape_text(&[]), "()");
    }
}

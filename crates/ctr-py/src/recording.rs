//! `ctr_py.read_recording` and `ctr_py.Recording`: a recording (`docs/formats.md`)
//! read by `ctr-analysis`'s reader, its columns as numpy arrays.
//!
//! The file is read exactly as `ctr-cli diagnose --recording` reads it (the robot gives
//! the tube count, hence the joint columns), with the same error messages. A
//! `Recording` pickles as its rows (every value exact), not as a path.

use crate::arrays;
use crate::errors;
use crate::robot::Robot;
use ctr_formats::{RecordedRow, Run};
use pyo3::prelude::*;
use pyo3::types::{PyList, PySlice, PyTuple};
use std::path::PathBuf;

/// Most tubes a robot (and so a recording's joint columns) can have.
const MAX_TUBES: usize = 4;

/// A recording: commanded joints and measured tips, row by row, in runs.
#[pyclass(frozen, module = "ctr_py", name = "Recording")]
pub struct Recording {
    pub(crate) rec: ctr_formats::Recording,
}

/// What a pickled `Recording` holds: file, tube count, whether it has times and
/// forces, then per row its line, time, joints, tip, quaternion (if recorded) and
/// force, the runs as (label, first row, end row), and last the tangents (if
/// recorded) with a static set's poses (label, first row, end row) and frames
/// (`n_frames`, `spread_mm` per row), if any.
type State = (
    String,
    usize,
    bool,
    bool,
    Vec<usize>,
    Vec<f64>,
    Vec<f64>,
    Vec<f64>,
    Option<Vec<f64>>,
    Vec<f64>,
    Vec<(String, usize, usize)>,
    (
        Option<Vec<f64>>,
        Option<Vec<(String, usize, usize)>>,
        Option<Vec<(u32, f64)>>,
    ),
);

/// A `(m, k)` array of one value block per row.
fn column<'py, const K: usize>(
    py: Python<'py>,
    rows: &[RecordedRow],
    f: impl Fn(&RecordedRow) -> [f64; K],
) -> PyResult<Bound<'py, PyAny>> {
    let data = rows.iter().flat_map(f).collect();
    arrays::array(py, data, &[rows.len(), K])
}

/// The recording's tube count, from `robot` or `n_tubes` (at least one of them).
fn tube_count(robot: Option<&Bound<'_, PyAny>>, n_tubes: Option<i64>) -> PyResult<usize> {
    let from_robot = match robot {
        None => None,
        Some(r) => Some(
            r.cast::<Robot>()
                .map_err(|_| {
                    errors::input_type(format!(
                        "robot: a {} is not a ctr_py.Robot (the robot gives the joint columns; \
                         or pass n_tubes=)",
                        r.get_type()
                            .name()
                            .map(|n| n.to_string())
                            .unwrap_or_default()
                    ))
                })?
                .get()
                .spec()
                .robot
                .n_tubes(),
        ),
    };
    let given = match n_tubes {
        None => None,
        Some(n) if (1..=MAX_TUBES as i64).contains(&n) => Some(n as usize),
        Some(n) => {
            return Err(errors::input(format!(
                "n_tubes: {n} is not in 1..={MAX_TUBES}"
            )))
        }
    };
    match (from_robot, given) {
        (Some(a), Some(b)) if a != b => Err(errors::input(format!(
            "n_tubes: {b}, but the robot has {a} tubes (give one of them)"
        ))),
        (Some(n), _) | (None, Some(n)) => Ok(n),
        (None, None) => Err(errors::input(
            "read_recording: give the robot (or n_tubes=): its tubes name the joint columns".into(),
        )),
    }
}

/// Reads a recording file with `n` tubes' joint columns, as `ctr-cli` reads it.
pub fn read(py: Python<'_>, path: &std::path::Path, n: usize) -> PyResult<ctr_formats::Recording> {
    py.detach(|| ctr_formats::Recording::from_path(path, n))
        .map_err(|e| errors::to_py(&e))
}

/// Reads a recording file; see `_ctr.pyi`.
#[pyfunction]
#[pyo3(signature = (path, robot = None, *, n_tubes = None))]
pub fn read_recording(
    py: Python<'_>,
    path: PathBuf,
    robot: Option<&Bound<'_, PyAny>>,
    n_tubes: Option<i64>,
) -> PyResult<Recording> {
    let n = tube_count(robot, n_tubes)?;
    Ok(Recording {
        rec: read(py, &path, n)?,
    })
}

impl Recording {
    fn check_state(s: &State) -> Result<ctr_formats::Recording, String> {
        let (
            file,
            n_tubes,
            has_time,
            has_force,
            lines,
            t_s,
            q,
            p,
            quaternion,
            force,
            runs,
            (tangent, poses, frames),
        ) = s;
        let (n, m) = (*n_tubes, lines.len());
        if !(1..=MAX_TUBES).contains(&n) {
            return Err(format!("n_tubes {n} is not in 1..={MAX_TUBES}"));
        }
        let w = 2 * n;
        if m == 0
            || t_s.len() != m
            || q.len() != w * m
            || p.len() != 3 * m
            || force.len() != 3 * m
            || quaternion.as_ref().is_some_and(|v| v.len() != 4 * m)
            || tangent.as_ref().is_some_and(|v| v.len() != 3 * m)
            || frames.as_ref().is_some_and(|v| v.len() != m)
        {
            return Err("the columns' lengths do not agree".into());
        }
        let mut end = 0;
        for (_, a, b) in runs {
            if *a != end || b <= a || *b > m {
                return Err("the runs do not cover the rows in order".into());
            }
            end = *b;
        }
        if end != m {
            return Err("the runs do not cover the rows in order".into());
        }
        check_static(poses.as_deref(), frames.as_deref(), runs, m)?;
        let mut rows = Vec::with_capacity(m);
        for (k, (_, a, b)) in runs.iter().enumerate() {
            for i in *a..*b {
                rows.push(RecordedRow {
                    line: lines[i],
                    t_s: t_s[i],
                    run: k,
                    q: q[w * i..w * (i + 1)].to_vec(),
                    p: [p[3 * i], p[3 * i + 1], p[3 * i + 2]],
                    quaternion: quaternion
                        .as_ref()
                        .map(|v| [v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3]]),
                    tangent: tangent
                        .as_ref()
                        .map(|v| [v[3 * i], v[3 * i + 1], v[3 * i + 2]]),
                    force_n: [force[3 * i], force[3 * i + 1], force[3 * i + 2]],
                    frames: frames.as_ref().map(|v| ctr_formats::Frames {
                        n: v[i].0,
                        spread_mm: v[i].1,
                    }),
                });
            }
        }
        Ok(ctr_formats::Recording {
            file: file.clone(),
            n_tubes: n,
            rows,
            runs: runs
                .iter()
                .map(|(label, a, b)| Run {
                    label: label.clone(),
                    rows: *a..*b,
                })
                .collect(),
            has_time: *has_time,
            has_force: *has_force,
            poses: poses.as_ref().map(|v| {
                v.iter()
                    .map(|(label, a, b)| ctr_formats::Pose {
                        label: label.clone(),
                        rows: *a..*b,
                    })
                    .collect()
            }),
            angular: None,
        })
    }
}

/// Checks a pickled static set's `poses` (label, first row, end row) and `frames`
/// (`n_frames`, `spread_mm` per row) against its `runs` and `m` rows.
#[allow(clippy::type_complexity)]
fn check_static(
    poses: Option<&[(String, usize, usize)]>,
    frames: Option<&[(u32, f64)]>,
    runs: &[(String, usize, usize)],
    m: usize,
) -> Result<(), String> {
    if let Some(poses) = poses {
        let run_of = |r: usize| runs.iter().position(|(_, x, y)| (*x..*y).contains(&r));
        let mut end = 0;
        for (_, a, b) in poses {
            if *a != end || b <= a || *b > m || run_of(*a) != run_of(*b - 1) {
                return Err("the poses do not cover the rows in order within runs".into());
            }
            end = *b;
        }
        if end != m {
            return Err("the poses do not cover the rows in order within runs".into());
        }
    }
    let bad = |(n, s): &(u32, f64)| *n == 0 || !(s.is_finite() && *s >= 0.0);
    if frames.is_some_and(|f| f.iter().any(bad)) {
        return Err("a row's frames are not n_frames >= 1 with spread_mm >= 0".into());
    }
    Ok(())
}

#[pymethods]
impl Recording {
    /// Rebuilds a pickled recording.
    #[staticmethod]
    fn _from_state(state: State) -> PyResult<Self> {
        Recording::check_state(&state)
            .map(|rec| Recording { rec })
            .map_err(|m| errors::input(format!("Recording state: {m}")))
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, (State,))> {
        let r = &slf.get().rec;
        let state: State = (
            r.file.clone(),
            r.n_tubes,
            r.has_time,
            r.has_force,
            r.rows.iter().map(|x| x.line).collect(),
            r.rows.iter().map(|x| x.t_s).collect(),
            r.rows.iter().flat_map(|x| x.q.iter().copied()).collect(),
            r.rows.iter().flat_map(|x| x.p).collect(),
            r.rows
                .iter()
                .map(|x| x.quaternion)
                .collect::<Option<Vec<_>>>()
                .map(|v| v.into_iter().flatten().collect()),
            r.rows.iter().flat_map(|x| x.force_n).collect(),
            r.runs
                .iter()
                .map(|x| (x.label.clone(), x.rows.start, x.rows.end))
                .collect(),
            (
                r.rows
                    .iter()
                    .map(|x| x.tangent)
                    .collect::<Option<Vec<_>>>()
                    .map(|v| v.into_iter().flatten().collect()),
                r.poses.as_ref().map(|v| {
                    v.iter()
                        .map(|x| (x.label.clone(), x.rows.start, x.rows.end))
                        .collect()
                }),
                r.rows
                    .iter()
                    .map(|x| x.frames.map(|f| (f.n, f.spread_mm)))
                    .collect::<Option<Vec<_>>>(),
            ),
        );
        Ok((slf.get_type().getattr("_from_state")?, (state,)))
    }

    fn __len__(&self) -> usize {
        self.rec.rows.len()
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<Recording>()
            .is_ok_and(|o| o.get().rec == self.rec)
    }

    fn __repr__(&self) -> String {
        format!(
            "Recording(file='{}', rows={}, runs={}, n_tubes={})",
            self.rec.file,
            self.rec.rows.len(),
            self.rec.runs.len(),
            self.rec.n_tubes
        )
    }

    /// The file name errors give (the path as given).
    #[getter]
    fn file(&self) -> &str {
        &self.rec.file
    }

    /// Number of tubes of the joint columns.
    #[getter]
    fn n_tubes(&self) -> usize {
        self.rec.n_tubes
    }

    /// Whether the file has a `t_s` column.
    #[getter]
    fn has_time(&self) -> bool {
        self.rec.has_time
    }

    /// Times, s, shape `(m,)` (the row index without a `t_s` column).
    #[getter]
    fn t_s<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let t = self.rec.rows.iter().map(|r| r.t_s).collect();
        arrays::array(py, t, &[self.rec.rows.len()])
    }

    /// Commanded joints, `(m, 2n)`, file order and units.
    #[getter]
    fn joints<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let data = self
            .rec
            .rows
            .iter()
            .flat_map(|r| r.q.iter().copied())
            .collect();
        arrays::array(py, data, &[self.rec.rows.len(), 2 * self.rec.n_tubes])
    }

    /// Measured tips, `(m, 3)`, mm.
    #[getter]
    fn tip<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        column(py, &self.rec.rows, |r| r.p)
    }

    /// Measured orientations `(m, 4)` (`qw, qx, qy, qz`), or `None` if not recorded.
    #[getter]
    fn quaternion<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        if self.rec.rows.iter().any(|r| r.quaternion.is_none()) {
            return Ok(None);
        }
        column(py, &self.rec.rows, |r| {
            r.quaternion.unwrap_or([f64::NAN; 4])
        })
        .map(Some)
    }

    /// Measured unit tangents of the tip `(m, 3)` (`tx, ty, tz`), or `None` if not
    /// recorded.
    #[getter]
    fn tangent<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        if self.rec.rows.iter().any(|r| r.tangent.is_none()) {
            return Ok(None);
        }
        column(py, &self.rec.rows, |r| r.tangent.unwrap_or([f64::NAN; 3])).map(Some)
    }

    /// Known tip forces `(m, 3)`, N, or `None` if not recorded.
    #[getter]
    fn force_n<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        if !self.rec.has_force {
            return Ok(None);
        }
        column(py, &self.rec.rows, |r| r.force_n).map(Some)
    }

    /// The run label of every row, a str array `(m,)`.
    #[getter]
    fn run<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let labels: Vec<&str> = self
            .rec
            .rows
            .iter()
            .map(|r| self.rec.runs[r.run].label.as_str())
            .collect();
        arrays::strings(py, &labels)
    }

    /// The runs in file order: `(label, slice)` pairs, the slice selecting its rows.
    #[getter]
    fn runs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let items = self
            .rec
            .runs
            .iter()
            .map(|r| {
                let s = PySlice::new(py, r.rows.start as isize, r.rows.end as isize, 1);
                PyTuple::new(
                    py,
                    [r.label.clone().into_pyobject(py)?.into_any(), s.into_any()],
                )
            })
            .collect::<PyResult<Vec<_>>>()?;
        PyList::new(py, items)
    }

    /// The 1-based line of every row in the file (the header is line 1), `(m,)` ints.
    #[getter]
    fn lines<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let lines: Vec<i64> = self.rec.rows.iter().map(|r| r.line as i64).collect();
        Ok(numpy::PyArray1::from_vec(py, lines).into_any())
    }

    /// Joint column names in file order.
    #[getter]
    fn joint_columns(&self) -> Vec<String> {
        ctr_formats::joint_columns(self.rec.n_tubes)
    }
}

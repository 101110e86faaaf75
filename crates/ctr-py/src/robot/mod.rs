//! `ctr_py.Robot`: a robot file's robot, model and limits, and the calls on it.
//!
//! Every call reads its array arguments ([`arrays::read_rows`]), releases the GIL,
//! checks the rows as `ctr-cli` checks a joint file (finite, then the core's joint
//! ranges; the first bad row is reported), runs the std layer's function and builds
//! numpy arrays from the results. Joints are in file units (`s1_mm, theta1_deg, ...`).

mod args;
mod solve;

pub(crate) use args::{check_threads, count_arg, threads_arg, MAX_THREADS};

use crate::arrays::{self, Rows};
use crate::errors::{self, Fail};
use ctr_analysis::batch::IK_CHUNK_ROWS;
use ctr_analysis::ik::{Ik, IkError, IkOptions};
use ctr_analysis::model::{ModelError, ModelSpec, RowModel};
use ctr_core::Model;
use ctr_formats::{Error, ErrorKind, Location, ModelKind, RobotSpec, ORIENTATION_TOLERANCE_DEG};
use pyo3::prelude::*;
use pyo3::types::{PyTuple, PyType};
use pyo3::IntoPyObjectExt;
use solve::Inverse;
use std::path::PathBuf;
use std::sync::OnceLock;

/// The z value of a two-sided 95 % band (`fk(band=True)`, `ctr-cli fk --band`).
const BAND_Z: f64 = 1.959_963_984_540_054;

/// A robot read from a robot TOML file (tubes, `[model]`, `[limits]`, `[actuation]`).
#[pyclass(frozen, module = "ctr_py", name = "Robot")]
pub struct Robot {
    spec: RobotSpec,
    /// The file name errors give (the path as given, or the name passed with the text).
    source: String,
    /// IK solvers with `ctr-cli ik`'s default settings, within the file's limits, built
    /// on first use: rigid, torsion.
    ik: [OnceLock<Result<Ik, String>>; 2],
}

/// The IK settings `ctr-cli ik` uses by default.
pub(super) fn cli_ik_options() -> IkOptions {
    IkOptions {
        orientation_tolerance_rad: ORIENTATION_TOLERANCE_DEG.to_radians(),
        ..IkOptions::default()
    }
}

fn model_index(model: Model) -> usize {
    match model {
        Model::Rigid => 0,
        Model::Torsion => 1,
    }
}

/// What a model that cannot be built or run is, as `ctr-cli fk` reports it.
pub(super) fn model_kind(e: ModelError) -> ErrorKind {
    match e {
        ModelError::Robot(e) => ErrorKind::Robot(e),
        other => ErrorKind::Effect {
            message: other.to_string(),
        },
    }
}

impl Robot {
    /// A robot of `spec`; errors name the file `source`.
    pub(crate) fn new(spec: RobotSpec, source: String) -> Self {
        Robot {
            spec,
            source,
            ik: Default::default(),
        }
    }

    /// The robot file's contents.
    pub(crate) fn spec(&self) -> &RobotSpec {
        &self.spec
    }

    /// The file name errors give.
    pub(crate) fn source_name(&self) -> &str {
        &self.source
    }

    /// The file's whole model solved with `model` (see `ctr_analysis::model`); refused
    /// as `ctr-cli fk` refuses it, located at the robot file.
    fn row_model(&self, model: Model) -> PyResult<RowModel> {
        let mut m = ModelSpec::from_spec(&self.spec);
        m.model = model;
        m.rows()
            .map_err(|e| errors::to_py(&Error::new(Location::file(&self.source), model_kind(e))))
    }

    fn n_joints(&self) -> usize {
        2 * self.spec.robot.n_tubes()
    }

    /// An IK solver of `model` within the file's limits, or the message of why not.
    fn build_ik(&self, model: Model, options: IkOptions) -> Result<Ik, String> {
        Ik::for_spec(&self.spec, model, options).map_err(|e| match e {
            // located at the robot file, as `ctr-cli ik` does
            IkError::Limits(_) | IkError::Effect(_) => format!("{}: {e}", self.source),
            _ => e.to_string(),
        })
    }

    /// The IK solver of `model` with `ctr-cli ik`'s default settings (within the
    /// file's limits), built on first use.
    fn solver(&self, model: Model) -> Result<&Ik, Fail> {
        self.ik[model_index(model)]
            .get_or_init(|| self.build_ik(model, cli_ik_options()))
            .as_ref()
            .map_err(|m| Fail::Input(m.clone()))
    }
}

/// One value per row: a Python scalar for a single input, an array for a batch.
fn per_row<'py, T>(
    py: Python<'py>,
    batched: bool,
    values: Vec<T>,
    array: impl FnOnce(Python<'py>, Vec<T>) -> PyResult<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>>
where
    T: IntoPyObject<'py> + Clone,
{
    if batched {
        array(py, values)
    } else {
        values[0].clone().into_bound_py_any(py)
    }
}

/// `shape` for a batch of `rows`, or `shape` without the row axis for one input.
fn shape(rows: &Rows, item: &[usize]) -> Vec<usize> {
    if rows.batched {
        std::iter::once(rows.rows)
            .chain(item.iter().copied())
            .collect()
    } else {
        item.to_vec()
    }
}

#[pymethods]
impl Robot {
    /// Reads a robot TOML file; errors name `path` as given.
    #[classmethod]
    fn from_toml(_cls: &Bound<'_, PyType>, py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let name = path.display().to_string();
        py.detach(|| {
            // as `ctr-cli fk` reads it: bytes, then UTF-8 and TOML
            let bytes = std::fs::read(&path).map_err(|source| {
                Error::new(
                    Location::file(&name),
                    ErrorKind::Io {
                        action: "read",
                        source,
                    },
                )
            })?;
            RobotSpec::from_bytes(bytes, &name)
        })
        .map(|spec| Robot::new(spec, name.clone()))
        .map_err(|e| errors::to_py(&e))
    }

    /// Parses robot TOML text; errors name the file `name`.
    #[classmethod]
    #[pyo3(signature = (text, name = "<string>"))]
    fn from_toml_str(_cls: &Bound<'_, PyType>, text: &str, name: &str) -> PyResult<Self> {
        RobotSpec::from_toml_str(text, name)
            .map(|spec| Robot::new(spec, name.to_owned()))
            .map_err(|e| errors::to_py(&e))
    }

    /// The robot file's TOML text (with an explicit `[model]`).
    fn to_toml(&self) -> String {
        self.spec.to_toml()
    }

    /// Number of tubes.
    #[getter]
    fn n_tubes(&self) -> usize {
        self.spec.robot.n_tubes()
    }

    /// The robot's `name`, if the file has one.
    #[getter]
    fn name(&self) -> Option<String> {
        self.spec.name.clone()
    }

    /// The file's `[model] kind`: `"rigid"` or `"torsion"`.
    #[getter]
    fn model(&self) -> &'static str {
        ModelKind::from(self.spec.model).name()
    }

    /// Joint names in file order: `s1_mm, theta1_deg, ...`.
    #[getter]
    fn joint_columns(&self) -> Vec<String> {
        self.spec.robot.joint_columns()
    }

    /// The file name errors give.
    #[getter]
    fn source(&self) -> &str {
        &self.source
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot(name={}, n_tubes={}, model='{}', source='{}')",
            self.spec
                .name
                .as_ref()
                .map_or("None".to_owned(), |n| format!("{n:?}")),
            self.n_tubes(),
            self.model(),
            self.source
        )
    }

    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<Robot>()
            .is_ok_and(|o| o.get().spec == self.spec)
    }

    /// Pickles as its TOML text (and file name).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, (String, String))> {
        let r = slf.get();
        Ok((
            slf.get_type().getattr("from_toml_str")?,
            (r.spec.to_toml(), r.source.clone()),
        ))
    }

    /// Tip forward kinematics of joint rows; see `_ctr.pyi`.
    #[pyo3(signature = (q, model = None, *, on_error = "fail", threads = None, t_s = None, margin = false, band = false))]
    #[allow(clippy::too_many_arguments)]
    fn fk<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        model: Option<&str>,
        on_error: &str,
        threads: Option<&Bound<'py, PyAny>>,
        t_s: Option<&Bound<'py, PyAny>>,
        margin: bool,
        band: bool,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let model = self.model_arg(model)?;
        let fkm = self.row_model(model)?;
        let threads = threads_arg(threads)?;
        let mark = match on_error {
            "fail" => false,
            "mark" => true,
            other => {
                return Err(errors::input(format!(
                    "on_error: \"{other}\" is not fail or mark"
                )))
            }
        };
        let rows = self.read_joints(q, "q")?;
        let times = self.times_arg(&fkm, t_s, &rows)?;
        let tips = py
            .detach(|| self.tips(&fkm, &rows, times.as_deref(), threads, mark, margin))
            .map_err(|e| errors::to_py(&e))?;
        let (positions, quaternions) = (tips.positions, tips.quaternions);
        let (statuses, residuals) = (tips.statuses, tips.residuals);
        let mut out = vec![
            arrays::array(py, positions, &shape(&rows, &[3]))?,
            arrays::array(py, quaternions, &shape(&rows, &[4]))?,
        ];
        if mark {
            out.push(per_row(py, rows.batched, statuses, |py, v| {
                arrays::strings(py, &v)
            })?);
            let m = rows.rows;
            out.push(per_row(py, rows.batched, residuals, |py, v| {
                arrays::array(py, v, &[m])
            })?);
        }
        if margin {
            let m = rows.rows;
            out.push(per_row(py, rows.batched, tips.margins, |py, v| {
                arrays::array(py, v, &[m])
            })?);
        }
        if band {
            let along =
                ctr_analysis::learned::along_commands(fkm.spec(), &rows.data, times.as_deref())
                    .ok_or_else(|| {
                        errors::input(
                    "band=True: the robot has no [model.discrepancy] (a learned discrepancy, \
                     written by ctr-cli diagnose --with-empirical)"
                        .into(),
                )
                    })?;
            let half: Vec<f64> = along.iter().map(|(_, sd)| BAND_Z * sd).collect();
            let m = rows.rows;
            out.push(per_row(py, rows.batched, half, |py, v| {
                arrays::array(py, v, &[m])
            })?);
        }
        PyTuple::new(py, out)
    }

    /// Backbone points of one joint vector; see `_ctr.pyi`.
    #[pyo3(signature = (q, model = None))]
    fn backbone<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        model: Option<&str>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let model = self.model_arg(model)?;
        let fkm = self.row_model(model)?;
        if let Some(effect) = fkm.time_effect() {
            return Err(errors::input(format!(
                "{}: model.effects.{effect}: backbone solves one joint vector, and this time \
                 effect makes the shape depend on the rows before it; use fk with t_s for the \
                 tip along a run",
                self.source
            )));
        }
        let rows = self.read_joints(q, "q")?;
        if rows.batched {
            return Err(errors::input(format!(
                "q: backbone takes one joint vector of shape ({},), not a batch of {}",
                rows.width, rows.rows
            )));
        }
        let points = py
            .detach(|| self.backbone_points(&fkm, &rows))
            .map_err(|e| errors::to_py(&e))?;
        let k = points.len() / 3;
        arrays::array(py, points, &[k, 3])
    }

    /// Tip Jacobian(s) per file unit; see `_ctr.pyi`.
    #[pyo3(signature = (q, model = None, *, threads = None))]
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        model: Option<&str>,
        threads: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let model = self.model_arg(model)?;
        let threads = threads_arg(threads)?;
        let fkm = self.row_model(model)?;
        let rows = self.read_joints(q, "q")?;
        let n = self.n_joints();
        let data = py
            .detach(|| self.jacobians(&fkm, &rows, threads))
            .map_err(Fail::into_py)?;
        arrays::array(py, data, &shape(&rows, &[6, n]))
    }

    /// Inverse kinematics; see `_ctr.pyi`.
    #[pyo3(signature = (
        targets,
        q0 = None,
        *,
        model = None,
        cold = false,
        chunk_rows = None,
        tolerance_mm = IkOptions::default().tolerance_mm,
        orientation_tolerance_deg = ORIENTATION_TOLERANCE_DEG,
        position_weight = IkOptions::default().position_weight,
        orientation_weight = IkOptions::default().orientation_weight,
        damping_feed = IkOptions::default().damping_feed,
        damping_rotation = IkOptions::default().damping_rotation,
        restarts = None,
        max_iterations = None,
        min_margin = None,
        threads = None,
    ))]
    fn ik<'py>(
        &self,
        py: Python<'py>,
        targets: &Bound<'py, PyAny>,
        q0: Option<&Bound<'py, PyAny>>,
        model: Option<&str>,
        cold: bool,
        chunk_rows: Option<&Bound<'py, PyAny>>,
        tolerance_mm: f64,
        orientation_tolerance_deg: f64,
        position_weight: f64,
        orientation_weight: f64,
        damping_feed: f64,
        damping_rotation: f64,
        restarts: Option<&Bound<'py, PyAny>>,
        max_iterations: Option<&Bound<'py, PyAny>>,
        min_margin: Option<f64>,
        threads: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let model = self.model_arg(model)?;
        let threads = threads_arg(threads)?;
        let defaults = IkOptions::default();
        let chunk_rows = match chunk_rows {
            None => IK_CHUNK_ROWS,
            Some(v) => count_arg(v, "chunk_rows", 0, u32::MAX.into(), "")? as usize,
        };
        let restarts = match restarts {
            None => defaults.restarts,
            Some(v) => count_arg(v, "restarts", 0, u32::MAX.into(), "")? as u32,
        };
        let max_iterations = match max_iterations {
            None => defaults.max_iterations,
            Some(v) => count_arg(v, "max_iterations", 0, u32::MAX.into(), "")? as u32,
        };
        if max_iterations == 0 {
            return Err(errors::input("max_iterations: 0 must be >= 1".into()));
        }
        let options = IkOptions {
            position_weight,
            orientation_weight,
            damping_feed,
            damping_rotation,
            tolerance_mm,
            orientation_tolerance_rad: orientation_tolerance_deg.to_radians(),
            max_iterations,
            restarts,
            min_margin,
            ..IkOptions::default()
        };
        let t = arrays::read_rows(
            targets,
            "targets",
            &[3, 7],
            "x_mm, y_mm, z_mm or x_mm, y_mm, z_mm, qw, qx, qy, qz",
        )?;
        let q0 = q0.map(|o| self.read_joints(o, "q0")).transpose()?;
        if let Some(q0) = &q0 {
            if q0.batched && !cold {
                return Err(errors::input(format!(
                    "q0: one start per target needs cold=True (independent targets); a warm trajectory starts from one joint vector of shape ({},)",
                    q0.width
                )));
            }
            if q0.batched && q0.rows != t.rows {
                return Err(errors::input(format!(
                    "q0: {} rows for {} target{} (give one start, or one per target)",
                    q0.rows,
                    t.rows,
                    if t.rows == 1 { "" } else { "s" }
                )));
            }
        }
        let n = self.n_joints();
        let Inverse {
            q,
            residuals,
            statuses,
        } = py
            .detach(|| self.inverse(model, options, &t, q0.as_ref(), cold, chunk_rows, threads))
            .map_err(Fail::into_py)?;
        let m = t.rows;
        let out = [
            arrays::array(py, q, &shape(&t, &[n]))?,
            per_row(py, t.batched, residuals, |py, v| arrays::array(py, v, &[m]))?,
            per_row(py, t.batched, statuses, |py, v| arrays::strings(py, &v))?,
        ];
        PyTuple::new(py, out)
    }
}

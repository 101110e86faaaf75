//! `ctr_py.Robot`: a robot file's robot, model and limits, and the calls on it.
//!
//! Every call reads its array arguments ([`arrays::read_rows`]), releases the GIL,
//! checks the rows as `ctr-cli` checks a joint file (finite, then the core's joint
//! ranges; the first bad row is reported), runs the std layer's function and builds
//! numpy arrays from the results. Joints are in file units (`s1_mm, theta1_deg, ...`).

use crate::arrays::{self, Rows};
use crate::errors::{self, Fail};
use crate::parallel;
use ctr_analysis::batch::{
    batch_fk_model, batch_ik, BatchOptions, IkBatchOptions, IK_CHUNK_ROWS, WARM_CHUNK_ROWS,
};
use ctr_analysis::ik::{Ik, IkError, IkOptions};
use ctr_analysis::model::{FkModel, ModelError};
use ctr_core::{
    JointError, Joints, Model, Request, Robot as CoreRobot, SolveError, Solver, Status,
};
use ctr_formats::IkTarget;
use ctr_formats::RobotSpec;
use ctr_formats::{status_name, AnyRobot, Error, ErrorKind, Location};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use pyo3::prelude::*;
use pyo3::types::{PyTuple, PyType};
use pyo3::IntoPyObjectExt;
use std::path::PathBuf;
use std::sync::OnceLock;

/// Names of the target columns, as in a targets file.
const TARGET_COLUMNS: [&str; 7] = ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"];
/// `ctr-cli ik --orientation-tolerance-deg`'s default.
const CLI_ORIENTATION_TOLERANCE_DEG: f64 = 0.0057;
/// Most worker threads a call may ask for (each is an OS thread).
pub(crate) const MAX_THREADS: usize = 1024;
/// How far from 1 a target quaternion's norm may be (it is then normalised).
const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// A robot read from a robot TOML file (tubes, `[model]`, `[limits]`, `[actuation]`).
#[pyclass(frozen, module = "ctr_py", name = "Robot")]
pub struct Robot {
    spec: RobotSpec,
    /// The file name errors give (the path as given, or the name passed with the text).
    source: String,
    /// IK solvers with `ctr-cli ik`'s default settings, within the file's limits, built
    /// on first use: rigid, torsion.
    ik: [OnceLock<Result<Ik, String>>; 2],
    /// Jacobian solvers within the core's joint ranges (no start table): rigid, torsion.
    jacobian: [OnceLock<Result<Ik, String>>; 2],
}

/// The IK settings `ctr-cli ik` uses by default.
fn cli_ik_options() -> IkOptions {
    IkOptions {
        orientation_tolerance_rad: CLI_ORIENTATION_TOLERANCE_DEG.to_radians(),
        ..IkOptions::default()
    }
}

/// `threads` checked: 0 (all cores) to [`MAX_THREADS`].
pub(crate) fn threads_arg(threads: usize) -> PyResult<usize> {
    if threads > MAX_THREADS {
        return Err(errors::input(format!(
            "threads: {threads} is not in 0..={MAX_THREADS} (0 = all cores)"
        )));
    }
    Ok(threads)
}

fn model_index(model: Model) -> usize {
    match model {
        Model::Rigid => 0,
        Model::Torsion => 1,
    }
}

fn model_name(model: Model) -> &'static str {
    match model {
        Model::Rigid => "rigid",
        Model::Torsion => "torsion",
    }
}

/// `Joints` from a file-order slice (mm, degrees).
fn joints_of<const N: usize>(q: &[f64]) -> Joints<f64, N> {
    Joints::from_mm_deg(
        core::array::from_fn(|i| q[2 * i]),
        core::array::from_fn(|i| q[2 * i + 1]),
    )
}

/// A cold solve of `q` with its backbone: status, residual, points (x, y, z, ...).
fn backbone_of<const N: usize>(
    robot: &CoreRobot<f64, N>,
    q: &[f64],
    model: Model,
) -> Result<(Status, f64, Vec<f64>), JointError> {
    let joints = joints_of::<N>(q);
    let mut points = vec![Vector3::zeros(); 256];
    loop {
        let request = Request::new(joints, model).backbone(&mut points);
        let sol = match Solver::default().solve(robot, request) {
            Ok(sol) => sol,
            Err(SolveError::Joint(e)) => return Err(e),
            // an unloaded request of the core's models has no other error
            Err(e) => unreachable!("{e}"),
        };
        let n = sol.backbone_points;
        if n <= points.len() {
            let xyz = points[..n].iter().flat_map(|p| [p.x, p.y, p.z]).collect();
            return Ok((sol.status, sol.residual_per_mm, xyz));
        }
        points.resize(n, Vector3::zeros());
    }
}

/// What a model that cannot be built or run is, as `ctr-cli fk` reports it.
fn model_kind(e: ModelError) -> ErrorKind {
    match e {
        ModelError::Robot(e) => ErrorKind::Robot(e),
        other => ErrorKind::Effect {
            message: other.to_string(),
        },
    }
}

/// The failure `ctr-cli fk --on-error fail` reports: the first failed row, and counts.
fn solver_failed(
    location: Location,
    status: Status,
    residual_per_mm: f64,
    failed: usize,
    rows: usize,
) -> Error {
    Error::new(
        location,
        ErrorKind::SolverFailed {
            status,
            residual_per_mm,
            failed,
            rows,
        },
    )
}

impl Robot {
    /// A robot of `spec`; errors name the file `source`.
    pub(crate) fn new(spec: RobotSpec, source: String) -> Self {
        Robot {
            spec,
            source,
            ik: Default::default(),
            jacobian: Default::default(),
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

    fn n_joints(&self) -> usize {
        2 * self.spec.robot.n_tubes()
    }

    /// `model` or the file's.
    fn model_arg(&self, model: Option<&str>) -> PyResult<Model> {
        match model {
            None => Ok(self.spec.model),
            Some("rigid") => Ok(Model::Rigid),
            Some("torsion") => Ok(Model::Torsion),
            Some(other) => Err(errors::input(format!(
                "model: \"{other}\" is not a model (rigid or torsion)"
            ))),
        }
    }

    /// Reads joint rows (shape `(2n,)` or `(m, 2n)`).
    fn read_joints(&self, obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Rows> {
        let n = self.spec.robot.n_tubes();
        let what = format!(
            "{} for a {n}-tube robot",
            self.spec.robot.joint_columns().join(", ")
        );
        arrays::read_rows(obj, name, &[2 * n], &what)
    }

    /// The checks `ctr-cli fk` makes on every joint row, in the same order: every value
    /// finite, then the core's ranges; the first bad row is the error.
    fn check_joints(&self, rows: &Rows, name: &str) -> Result<(), Error> {
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

    /// The file's whole model solved with `model` (see `ctr_analysis::model`); refused
    /// as `ctr-cli fk` refuses it, located at the robot file.
    fn fk_model(&self, model: Model) -> PyResult<FkModel> {
        FkModel::from_spec(&self.spec, Some(model))
            .map_err(|e| errors::to_py(&Error::new(Location::file(&self.source), model_kind(e))))
    }

    /// The times of the rows for the model's time effects: `t_s` (one per row,
    /// finite, non-decreasing); required when the model has time effects (latency,
    /// friction with a non-zero play), ignored (but checked) otherwise.
    fn times_arg(
        &self,
        fkm: &FkModel,
        t_s: Option<&Bound<'_, PyAny>>,
        rows: &Rows,
    ) -> PyResult<Option<Vec<f64>>> {
        let Some(obj) = t_s else {
            if fkm.needs_time() {
                let effect = if fkm.needs_times().is_some() {
                    "latency"
                } else {
                    "friction"
                };
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

    /// An IK solver of `model` within the file's limits, or the message of why not.
    fn build_ik(&self, model: Model, options: IkOptions) -> Result<Ik, String> {
        Ik::with_effects(
            &self.spec.robot,
            model,
            &self.spec.effects,
            self.spec.limits.as_deref(),
            options,
        )
        .map_err(|e| match e {
            // located at the robot file, as `ctr-cli ik` does
            IkError::Limits(_) | IkError::Effect(_) => format!("{}: {e}", self.source),
            _ => e.to_string(),
        })
    }

    /// The IK solver of `model` with `ctr-cli ik`'s default settings (within the
    /// file's limits), or the Jacobian's (within the core's ranges only, no start
    /// table), built on first use.
    fn solver(&self, model: Model, for_jacobian: bool) -> Result<&Ik, Fail> {
        let slots = if for_jacobian {
            &self.jacobian
        } else {
            &self.ik
        };
        slots[model_index(model)]
            .get_or_init(|| {
                if for_jacobian {
                    let options = IkOptions {
                        seed_samples: 0,
                        ..IkOptions::default()
                    };
                    Ik::with_effects(&self.spec.robot, model, &self.spec.effects, None, options)
                        .map_err(|e| match e {
                            IkError::Effect(_) => format!("{}: {e}", self.source),
                            _ => e.to_string(),
                        })
                } else {
                    self.build_ik(model, cli_ik_options())
                }
            })
            .as_ref()
            .map_err(|m| Fail::Input(m.clone()))
    }

    /// Reads IK targets: positions `(3,)`/`(m, 3)` or poses `(7,)`/`(m, 7)`.
    fn targets(rows: &Rows) -> Result<Vec<IkTarget>, Fail> {
        (0..rows.rows)
            .map(|i| {
                let t = rows.row(i);
                let at = || errors::at("targets", i, rows.batched);
                if let Some(k) = t.iter().position(|v| !v.is_finite()) {
                    return Err(Fail::Ctr(Error::new(
                        at(),
                        ErrorKind::NotFinite {
                            column: TARGET_COLUMNS[k].to_owned(),
                            found: arrays::nonfinite_text(t[k]),
                        },
                    )));
                }
                let position = [t[0], t[1], t[2]];
                if t.len() == 3 {
                    return Ok(IkTarget::position(position));
                }
                // as `ctr-cli ik` reads a targets file: a unit quaternion within 1e-3,
                // then normalised
                let q = [t[3], t[4], t[5], t[6]];
                let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
                if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
                    return Err(Fail::Input(format!(
                        "{}: qw,qx,qy,qz = {}, {}, {}, {} has norm {norm}: expected a unit quaternion (norm 1 within 1e-3)",
                        at(),
                        q[0],
                        q[1],
                        q[2],
                        q[3]
                    )));
                }
                let q = Quaternion::new(q[0], q[1], q[2], q[3]);
                Ok(IkTarget::pose(position, UnitQuaternion::from_quaternion(q)))
            })
            .collect()
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
            // as `ctr-cli` reads it: bytes, then UTF-8, then TOML
            let bytes = std::fs::read(&path).map_err(|source| {
                Error::new(
                    Location::file(&name),
                    ErrorKind::Io {
                        action: "read",
                        source,
                    },
                )
            })?;
            let text = String::from_utf8(bytes).map_err(|e| {
                Error::new(
                    Location::file(&name),
                    ErrorKind::Io {
                        action: "read",
                        source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
                    },
                )
            })?;
            RobotSpec::from_toml_str(&text, &name)
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
        model_name(self.spec.model)
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
    #[pyo3(signature = (q, model = None, *, on_error = "fail", threads = 0, t_s = None))]
    fn fk<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        model: Option<&str>,
        on_error: &str,
        threads: usize,
        t_s: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let model = self.model_arg(model)?;
        let fkm = self.fk_model(model)?;
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
        let options = BatchOptions {
            model,
            threads,
            chunk_rows: WARM_CHUNK_ROWS,
        };
        let (positions, quaternions, statuses, residuals) = py
            .detach(|| -> Result<_, Error> {
                self.check_joints(&rows, "q")?;
                let results = batch_fk_model(&fkm, &rows.data, times.as_deref(), &options, &())
                    .map_err(|e| Error::new(Location::file("t_s"), model_kind(e)))?;
                let m = rows.rows;
                let mut positions = Vec::with_capacity(3 * m);
                let mut quaternions = Vec::with_capacity(4 * m);
                let mut statuses = Vec::with_capacity(if mark { m } else { 0 });
                let mut residuals = Vec::with_capacity(if mark { m } else { 0 });
                let mut failed = 0;
                let mut first_failure = None;
                for (i, r) in results.into_iter().enumerate() {
                    let at = || errors::at("q", i, rows.batched);
                    let fk = r.map_err(|e| Error::new(at(), fkm.row_error(e)))?;
                    if fk.status != Status::Converged {
                        failed += 1;
                        first_failure.get_or_insert((at(), fk.status, fk.residual_per_mm));
                    }
                    positions.extend_from_slice(&fk.position);
                    quaternions.extend_from_slice(&fk.quaternion);
                    if mark {
                        statuses.push(status_name(fk.status));
                        residuals.push(fk.residual_per_mm);
                    }
                }
                if let (false, Some((at, status, residual))) = (mark, first_failure) {
                    return Err(solver_failed(at, status, residual, failed, m));
                }
                Ok((positions, quaternions, statuses, residuals))
            })
            .map_err(|e| errors::to_py(&e))?;
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
        let fkm = self.fk_model(model)?;
        let effects = fkm.effects();
        for (effect, on) in [
            ("clearance", effects.clearance.is_some()),
            ("gravity", effects.gravity.is_some()),
            ("latency", fkm.needs_times().is_some()),
            ("friction", fkm.needs_time()),
        ] {
            if on {
                return Err(errors::input(format!(
                    "{}: model.effects.{effect}: backbone solves the static mechanics only \
                     (joint offsets, stiffness, precurvature, registration); use fk for the tip \
                     with this effect",
                    self.source
                )));
            }
        }
        let rows = self.read_joints(q, "q")?;
        if rows.batched {
            return Err(errors::input(format!(
                "q: backbone takes one joint vector of shape ({},), not a batch of {}",
                rows.width, rows.rows
            )));
        }
        let points = py
            .detach(|| -> Result<Vec<f64>, Error> {
                self.check_joints(&rows, "q")?;
                // the commanded joints plus the offsets, on the scaled tubes
                let q: Vec<f64> = if fkm.shifts_joints() {
                    fkm.actual_joints(rows.row(0), None, std::slice::from_ref(&(0..1)))
                        .map_err(|e| Error::new(Location::file("q"), model_kind(e)))?
                } else {
                    rows.row(0).to_vec()
                };
                let q = &q[..];
                let solved = match fkm.robot() {
                    AnyRobot::One(r) => backbone_of(r, q, model),
                    AnyRobot::Two(r) => backbone_of(r, q, model),
                    AnyRobot::Three(r) => backbone_of(r, q, model),
                    AnyRobot::Four(r) => backbone_of(r, q, model),
                };
                let (status, residual, mut points) = solved.map_err(|e| {
                    Error::new(
                        Location::file("q"),
                        fkm.row_error(ctr_core::SolveError::Joint(e)),
                    )
                })?;
                if let Some(r) = fkm.effects().registration {
                    // in the measuring frame, as fk's tips
                    let axis = if r.rotation_axis.iter().all(|&x| x == 0.0) {
                        [0.0, 0.0, 1.0]
                    } else {
                        r.rotation_axis
                    };
                    let reg = ctr_core::effects::Registration::from_axis_angle(
                        axis,
                        r.rotation_deg.to_radians(),
                        r.translation_mm,
                    );
                    for p in points.chunks_exact_mut(3) {
                        let m = reg.apply_point(&Vector3::new(p[0], p[1], p[2]));
                        p.copy_from_slice(&[m.x, m.y, m.z]);
                    }
                }
                if status != Status::Converged {
                    return Err(solver_failed(Location::file("q"), status, residual, 1, 1));
                }
                Ok(points)
            })
            .map_err(|e| errors::to_py(&e))?;
        let k = points.len() / 3;
        arrays::array(py, points, &[k, 3])
    }

    /// Tip Jacobian(s) per file unit; see `_ctr.pyi`.
    #[pyo3(signature = (q, model = None, *, threads = 0))]
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        model: Option<&str>,
        threads: usize,
    ) -> PyResult<Bound<'py, PyAny>> {
        let model = self.model_arg(model)?;
        let threads = threads_arg(threads)?;
        let rows = self.read_joints(q, "q")?;
        let n = self.n_joints();
        let data = py
            .detach(|| -> Result<Vec<f64>, Fail> {
                self.check_joints(&rows, "q")?;
                let ik = self.solver(model, true)?;
                let jacobians = parallel::map(
                    rows.rows,
                    threads,
                    || (),
                    |(), i| ik.tip_jacobian(rows.row(i)),
                );
                let mut data = Vec::with_capacity(rows.rows * 6 * n);
                for (i, j) in jacobians.into_iter().enumerate() {
                    let Some(j) = j else {
                        return Err(Fail::Solver(format!(
                            "{}: no Jacobian: the forward kinematics does not converge there",
                            errors::at("q", i, rows.batched)
                        )));
                    };
                    for r in 0..6 {
                        data.extend(j.iter().map(|column| column[r]));
                    }
                }
                Ok(data)
            })
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
        chunk_rows = IK_CHUNK_ROWS,
        tolerance_mm = IkOptions::default().tolerance_mm,
        orientation_tolerance_deg = CLI_ORIENTATION_TOLERANCE_DEG,
        position_weight = IkOptions::default().position_weight,
        orientation_weight = IkOptions::default().orientation_weight,
        damping_feed = IkOptions::default().damping_feed,
        damping_rotation = IkOptions::default().damping_rotation,
        restarts = IkOptions::default().restarts,
        max_iterations = IkOptions::default().max_iterations,
        threads = 0,
    ))]
    fn ik<'py>(
        &self,
        py: Python<'py>,
        targets: &Bound<'py, PyAny>,
        q0: Option<&Bound<'py, PyAny>>,
        model: Option<&str>,
        cold: bool,
        chunk_rows: usize,
        tolerance_mm: f64,
        orientation_tolerance_deg: f64,
        position_weight: f64,
        orientation_weight: f64,
        damping_feed: f64,
        damping_rotation: f64,
        restarts: u32,
        max_iterations: u32,
        threads: usize,
    ) -> PyResult<Bound<'py, PyTuple>> {
        let model = self.model_arg(model)?;
        let threads = threads_arg(threads)?;
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
        let (q, residuals, statuses) = py
            .detach(|| -> Result<_, Fail> {
                let targets = Robot::targets(&t)?;
                if let Some(rows) = &q0 {
                    self.check_joints(rows, "q0")?;
                }
                let built;
                let ik = if options == cli_ik_options() {
                    self.solver(model, false)?
                } else {
                    built = self.build_ik(model, options).map_err(Fail::Input)?;
                    &built
                };
                let results = match &q0 {
                    // the CLI's modes: warm along the rows in chunks, or cold
                    None => {
                        let batch = IkBatchOptions {
                            threads,
                            chunk_rows: if chunk_rows == 0 {
                                targets.len().max(1)
                            } else {
                                chunk_rows
                            },
                            warm: !cold,
                        };
                        let mut all = Vec::with_capacity(targets.len());
                        batch_ik(ik, &targets, &batch, &(), |_, r| {
                            all.extend(r);
                            true
                        });
                        all
                    }
                    // a trajectory from a known start: one chain, in order
                    Some(start) if !cold => ik
                        .clone()
                        .solve_trajectory(&targets, Some(&ik.from_file_units(start.row(0)))),
                    // independent targets, each from its start
                    Some(start) => {
                        let starts: Vec<Vec<f64>> = (0..start.rows)
                            .map(|i| ik.from_file_units(start.row(i)))
                            .collect();
                        parallel::map(
                            targets.len(),
                            threads,
                            || ik.clone(),
                            |ik, i| ik.solve(&targets[i], Some(&starts[i.min(starts.len() - 1)])),
                        )
                    }
                };
                let mut q = Vec::with_capacity(n * results.len());
                let mut residuals = Vec::with_capacity(results.len());
                let mut statuses = Vec::with_capacity(results.len());
                for r in &results {
                    q.extend(ik.to_file_units(&r.q));
                    residuals.push(r.residual_mm);
                    statuses.push(r.status.name());
                }
                Ok((q, residuals, statuses))
            })
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

//! A recording's prediction that moves without solving again: what a fit's Jacobian
//! needs for the effects that act on the joints or on the measurement alone.
//!
//! A fit moves effect parameters a small step at a time and asks how the predicted
//! tips move. Two kinds of effect leave the mechanics alone:
//!
//! - on the joints (`joint_offset`, `latency`, `friction`): they change each row's
//!   actual joints `a` and nothing else, so to first order the tip frame moves with
//!   the joint Jacobian `J = [J_p; J_w]` at the row:
//!
//!   ```text
//!   p' = p + J_p (a' - a),    R' = exp([J_w (a' - a)]x) R
//!   ```
//!
//!   (`J_w` the tip frame's angular velocity in W per unit of each joint);
//! - on the measurement (`sensor_offset`, `sensor_rotation`, `registration`): they
//!   map the tip frame to the measured one after the mechanics (the core's
//!   `Effects::measured`, `p = R_reg (p_tip + R_tip d) + t`), exactly.
//!
//! Two effects change the mechanics by a scale of each tube, and the core has their
//! analytic derivatives too (its parameter Jacobian, unloaded rows only): `stiffness`
//! (E I and G J of tube i times `f_i`) and `precurvature` (the curvature radius times
//! `r_i`, so the curvature `k_i` times `1 / r_i`). With the columns `J_f`, `J_k` of the
//! tip in the relative stiffness and curvature scales at the factors `f0`, `r0` solved
//! at, to first order
//!
//! ```text
//! p' = p + J_f (f - f0) / f0 - J_k (r - r0) / r0
//! ```
//!
//! ([`Moving`] says which of these a linearisation carries; the measurement always.)
//!
//! [`Linearised::new`] solves the rows of a model once without its measurement, in
//! order along each run as a simulation does, then takes the core's analytic Jacobians
//! at each row's solution on every thread ([`crate::model::RowSolver::derivatives_at`];
//! under a load, where the core has none, central differences of warm solves);
//! [`Linearised::predict`] then gives the prediction of any model that differs from it
//! only in those six effects, at the cost of the time effects along the runs and no
//! solve. The central difference of two such predictions is the chain rule
//! `J_tip da/dx` (the actual joints' change from the time effects themselves, exact
//! in the measurement): the diagnosis's fits take these columns of their Jacobian
//! from here instead of two solves of every row per parameter.

use crate::model::{Kept, ModelSpec, RowModel, RowSolver};
use crate::simulate::{row_error, shifted_joints, Prediction, SimError};
use crate::timeline::TimeEffects;
use ctr_core::{Frame, SolveError};
use ctr_formats::{canonical_quaternion, FkResult, Recording};
use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector3};

/// The mechanics of `model`: without the effects on the joints and the measurement.
fn mechanics(model: &ModelSpec) -> ModelSpec {
    let mut m = without_measurement(model);
    m.effects.joint_offset = None;
    m.effects.latency = None;
    m.effects.friction = None;
    m
}

/// `model` without its measurement (sensor offset and rotation, registration).
fn without_measurement(model: &ModelSpec) -> ModelSpec {
    let mut m = model.clone();
    m.effects.sensor_offset = None;
    m.effects.sensor_rotation = None;
    m.effects.registration = None;
    m
}

/// What a [`Linearised`] moves without solving, besides the measurement (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Moving {
    /// The measurement alone: the rows solved plainly.
    Measurement,
    /// The effects on the joints (joint offsets, latency, friction): the joint
    /// Jacobian.
    Joints,
    /// The tubes' stiffness and precurvature factors: the parameter Jacobian
    /// (unloaded rows only). Where the friction grows with the contact moment the
    /// factors move the actual joints too, and the rows are linearised as
    /// [`Moving::Both`].
    Scales,
    /// Both the joints and the scales.
    Both,
}

impl Moving {
    /// Whether the joint effects move.
    pub fn joints(self) -> bool {
        matches!(self, Moving::Joints | Moving::Both)
    }

    /// Whether the stiffness and precurvature factors move.
    pub fn scales(self) -> bool {
        matches!(self, Moving::Scales | Moving::Both)
    }
}

/// The rows of a model solved once, unmeasured, with their joint Jacobians (module
/// doc).
#[derive(Clone, Debug)]
pub struct Linearised {
    /// What moves without solving.
    moving: Moving,
    /// What every model [`predict`](Self::predict) is given must share.
    mechanics: ModelSpec,
    /// The stiffness and precurvature radius factors solved at, per tube.
    factors: (Vec<f64>, Vec<f64>),
    /// Per recording row: `width` columns in the stiffness scales then the curvature
    /// scales (when the scales move).
    scales: Vec<[f64; 6]>,
    /// The effects on the joints solved at: a model with the same ones moves only its
    /// measurement.
    time: TimeEffects,
    /// Joints per row (`2 n`).
    width: usize,
    /// The runs simulated (indices into the recording's runs).
    runs: Vec<usize>,
    /// Which recording rows were solved.
    solved: Vec<bool>,
    /// Per recording row: the actual joints solved at (file units), `width` values.
    actual: Vec<f64>,
    /// Per recording row: the tip frame before the measurement (identity where not
    /// solved).
    tip: Vec<Frame<f64>>,
    /// Per recording row: `width` Jacobian columns (file units; position, then
    /// angular velocity in W).
    jacobian: Vec<[f64; 6]>,
}

impl Linearised {
    /// The rows `rows` (ascending; their runs simulated whole for the time effects, as
    /// [`crate::simulate::predict_rows`] does) of `model` solved without its
    /// measurement, with their joint Jacobians: the core's analytic one, or under a
    /// load (gravity, a recorded tip force), where the core has none, central
    /// differences of warm solves at [`PROBE_MM`] / [`PROBE_DEG`] (one-sided where a
    /// probe leaves the robot's ranges). `Ok(None)` where the model is more than
    /// mechanics, joints and measurement: a learned discrepancy or an empirical
    /// correction (on the commanded joints, after the measurement). The runs on
    /// `threads` workers (the same result at any count).
    ///
    /// ```
    /// use ctr_analysis::{linearised::Linearised, model::ModelSpec, simulate::predict};
    /// use ctr_formats::{JointOffset, Recording, RobotSpec};
    /// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
    ///     length_mm = 260.0\ncurved_length_mm = 90.0\ncurvature_radius_mm = 100.0\n\
    ///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
    /// let rec = Recording::read("s1_mm,theta1_deg,x_mm,y_mm,z_mm\n150,0,0,0,150\n".as_bytes(), "rec.csv", 1)?;
    /// let m = ModelSpec::from_spec(&spec);
    /// let lin = Linearised::new(&m, &rec, &[0], 1)?.expect("unloaded: the core has a Jacobian");
    /// // fed 0.001 mm further: to first order, as a solve says
    /// let mut moved = m.clone();
    /// moved.effects.joint_offset = Some(JointOffset { feed_mm: vec![1e-3], rotation_deg: vec![0.0] });
    /// let (near, solved) = (lin.predict(&moved, &rec)?.unwrap(), predict(&moved, &rec, &[0])?);
    /// assert!((0..3).all(|a| (near.p[0][a] - solved.p[0][a]).abs() < 1e-8));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn new(
        model: &ModelSpec,
        rec: &Recording,
        rows: &[usize],
        threads: usize,
    ) -> Result<Option<Self>, SimError> {
        Self::moving(model, rec, rows, threads, Moving::Joints)
    }

    /// [`new`](Self::new) with `moving` saying what moves without solving: with
    /// [`Moving::Scales`] or [`Moving::Both`] the rows get the core's analytic
    /// derivatives in each tube's stiffness and precurvature factors too, which
    /// loaded rows do not have (`Ok(None)` there), and with [`Moving::Measurement`]
    /// the rows are solved plainly (a model with other joint effects or factors is
    /// then not predicted).
    ///
    /// ```
    /// use ctr_analysis::{linearised::{Linearised, Moving}, model::ModelSpec, simulate::predict};
    /// use ctr_formats::{Precurvature, Recording, RobotSpec};
    /// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
    ///     length_mm = 260.0\ncurved_length_mm = 90.0\ncurvature_radius_mm = 100.0\n\
    ///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
    /// let rec = Recording::read("s1_mm,theta1_deg,x_mm,y_mm,z_mm\n150,0,0,0,150\n".as_bytes(), "rec.csv", 1)?;
    /// let m = ModelSpec::from_spec(&spec);
    /// let lin = Linearised::moving(&m, &rec, &[0], 1, Moving::Scales)?.expect("unloaded");
    /// // the radius 0.01 % longer: to first order, as a solve says
    /// let mut moved = m.clone();
    /// moved.effects.precurvature = Some(Precurvature { radius_factor: vec![1.0001] });
    /// let (near, solved) = (lin.predict(&moved, &rec)?.unwrap(), predict(&moved, &rec, &[0])?);
    /// assert!((0..3).all(|a| (near.p[0][a] - solved.p[0][a]).abs() < 1e-6));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn moving(
        model: &ModelSpec,
        rec: &Recording,
        rows: &[usize],
        threads: usize,
        moving: Moving,
    ) -> Result<Option<Self>, SimError> {
        if learned(model) {
            return Ok(None);
        }
        let moving = carried(model, moving);
        let loaded = loaded(model, rec, rows);
        if loaded && moving.scales() {
            return Ok(None);
        }
        let unmeasured = without_measurement(model);
        let row_model = unmeasured.rows().map_err(SimError::Model)?;
        let width = 2 * model.robot.n_tubes();
        let n = rec.rows.len();
        let mut solved = vec![false; n];
        for &r in rows {
            solved[r] = true;
        }
        let runs = crate::simulate::runs_holding(rec, rows);
        let mut out = Linearised {
            moving,
            mechanics: compared(model, moving),
            factors: factors(model),
            scales: Vec::new(),
            time: row_model.time_effects().clone(),
            width,
            runs,
            solved,
            actual: vec![f64::NAN; n * width],
            tip: vec![Frame::identity(); n],
            jacobian: vec![[0.0; 6]; if moving.joints() { n * width } else { 0 }],
        };
        if moving.scales() {
            out.scales = vec![[0.0; 6]; n * width];
        }
        let threads = threads.max(1);
        // the runs solved in order, warm, each on a thread; then each row's derivatives
        // at its solution, on every thread (a run's chain cannot be split, its
        // derivatives can: the same numbers as within the solve)
        let parts = ctr_formats::parallel::map(&out.runs, threads, |&run| {
            run_linearised(&row_model, rec, run, &out.solved, loaded, moving)
        });
        let mut rows = Vec::new();
        for part in parts {
            let Some(part) = part? else {
                return Ok(None);
            };
            rows.extend(part);
        }
        if !loaded && moving != Moving::Measurement {
            let done = ctr_formats::parallel::map_rows(
                rows.len(),
                DERIVATIVE_ROWS,
                threads,
                || row_model.solver(),
                |solver, i| derivatives(solver, &rows[i], moving),
            );
            for (row, columns) in rows.iter_mut().zip(done) {
                let Some((joints, scales)) = columns else {
                    return Ok(None);
                };
                (row.joints, row.scales) = (joints, scales);
            }
        }
        for row in rows {
            let at = row.row * width..(row.row + 1) * width;
            out.actual[at.clone()].copy_from_slice(&row.actual);
            if moving.joints() {
                out.jacobian[at.clone()].copy_from_slice(&row.joints);
            }
            if moving.scales() {
                out.scales[at].copy_from_slice(&row.scales);
            }
            out.tip[row.row] = row.tip;
        }
        Ok(Some(out))
    }

    /// What [`moving`](Self::moving) costs per row with `moving`, in solves of the row
    /// (measured on the real three-tube recording: [`ANALYTIC_SOLVES`],
    /// [`SCALES_SOLVES`], [`BOTH_SOLVES`]; under a load the joints' probes, `1 + 4 n`);
    /// `None` where it is not linearised that way (a learned term; the scales under a
    /// load). A fit's Jacobian linearises only where this is below the two solves per
    /// parameter it saves.
    ///
    /// ```
    /// use ctr_analysis::linearised::{Linearised, Moving, ANALYTIC_SOLVES};
    /// use ctr_analysis::model::ModelSpec;
    /// use ctr_formats::{Recording, RobotSpec};
    /// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
    ///     length_mm = 260.0\ncurved_length_mm = 90.0\ncurvature_radius_mm = 100.0\n\
    ///     youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
    /// let rec = Recording::read("s1_mm,theta1_deg,x_mm,y_mm,z_mm\n150,0,0,0,150\n".as_bytes(), "rec.csv", 1)?;
    /// let m = ModelSpec::from_spec(&spec);
    /// assert_eq!(Linearised::cost_per_row(&m, &rec, &[0], Moving::Joints), Some(ANALYTIC_SOLVES));
    /// assert_eq!(Linearised::cost_per_row(&m, &rec, &[0], Moving::Measurement), Some(1.0));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn cost_per_row(
        model: &ModelSpec,
        rec: &Recording,
        rows: &[usize],
        moving: Moving,
    ) -> Option<f64> {
        if learned(model) {
            return None;
        }
        let loaded = loaded(model, rec, rows);
        match carried(model, moving) {
            Moving::Measurement => Some(1.0),
            Moving::Joints if loaded => Some((1 + 2 * 2 * model.robot.n_tubes()) as f64),
            Moving::Joints => Some(ANALYTIC_SOLVES),
            _ if loaded => None,
            Moving::Scales => Some(SCALES_SOLVES),
            Moving::Both => Some(BOTH_SOLVES),
        }
    }

    /// The prediction of `model` on the rows solved: their actual joints from its own
    /// joint effects along each run, the tip moved to first order by the joint
    /// Jacobian, then its measurement, exactly (module doc). `Ok(None)` when `model`
    /// differs from the linearised one in more than its joint and measurement effects;
    /// [`SimError::Joint`] where its actual joints leave the robot's ranges, as a solve
    /// would say. Every row not solved is `NaN`; margins are `NaN`.
    pub fn predict(
        &self,
        model: &ModelSpec,
        rec: &Recording,
    ) -> Result<Option<Prediction>, SimError> {
        if compared(model, self.moving) != self.mechanics {
            return Ok(None);
        }
        let scaled = self.scale_changes(model);
        let n = rec.rows.len();
        let row_model = model.rows().map_err(SimError::Model)?;
        let measurement = model.effects.core_effects::<1>();
        let mut out = Prediction {
            p: vec![[f64::NAN; 3]; n],
            q: vec![[f64::NAN; 4]; n],
            failed: 0,
            margin: vec![f64::NAN; n],
        };
        let w = self.width;
        // the same joint effects: the rows' actual joints are those solved at
        let same_joints = *row_model.time_effects() == self.time;
        if !same_joints && !self.moving.joints() {
            return Ok(None);
        }
        for &run in &self.runs {
            let range = rec.runs[run].rows.clone();
            let shifted = if same_joints {
                None
            } else {
                shifted_joints(&row_model, rec, run)
            };
            for (k, row) in range.enumerate() {
                if !self.solved[row] {
                    continue;
                }
                let tip = &self.tip[row];
                if same_joints && scaled.is_none() {
                    let measured = measurement.measured(tip);
                    out.p[row] = measured.position.into();
                    out.q[row] = canonical_quaternion(&measured.orientation());
                    continue;
                }
                let (mut dp, mut omega) = (Vector3::zeros(), Vector3::zeros());
                if !same_joints {
                    let a = shifted.as_ref().map_or(&rec.rows[row].q[..], |v| v.row(k));
                    row_model
                        .robot()
                        .validate_joints(a)
                        .map_err(|error| SimError::Joint { row, error })?;
                    let at = &self.actual[row * w..(row + 1) * w];
                    let da = a.iter().zip(at).map(|(a, at)| a - at);
                    add_moves(&mut dp, &mut omega, &self.jacobian[row * w..], da);
                }
                if let Some(change) = &scaled {
                    let ds = change.iter().copied();
                    add_moves(&mut dp, &mut omega, &self.scales[row * w..], ds);
                }
                let moved = Frame {
                    rotation: Rotation3::new(omega).into_inner() * tip.rotation,
                    position: tip.position + dp,
                };
                let measured = measurement.measured(&moved);
                out.p[row] = measured.position.into();
                out.q[row] = canonical_quaternion(&measured.orientation());
            }
        }
        Ok(Some(out))
    }
}

/// Adds to the tip's move `(dp, omega)` each of `columns` times its change in
/// `changes` (as many columns as changes are used).
fn add_moves(
    dp: &mut Vector3<f64>,
    omega: &mut Vector3<f64>,
    columns: &[[f64; 6]],
    changes: impl Iterator<Item = f64>,
) {
    for (col, d) in columns.iter().zip(changes) {
        *dp += Vector3::new(col[0], col[1], col[2]) * d;
        *omega += Vector3::new(col[3], col[4], col[5]) * d;
    }
}

impl Linearised {
    /// The relative changes of `model`'s stiffness scales then curvature scales from
    /// those solved at (module doc: `(f - f0) / f0`, `-(r - r0) / r0`), `None` where
    /// there is none.
    fn scale_changes(&self, model: &ModelSpec) -> Option<Vec<f64>> {
        if !self.moving.scales() {
            return None;
        }
        let (f, r) = factors(model);
        let (f0, r0) = &self.factors;
        let change: Vec<f64> = f
            .iter()
            .zip(f0)
            .map(|(f, f0)| (f - f0) / f0)
            .chain(r.iter().zip(r0).map(|(r, r0)| -(r - r0) / r0))
            .collect();
        change.iter().any(|&d| d != 0.0).then_some(change)
    }
}

/// Cost of a row solved with the core's analytic joint Jacobian, in plain solves
/// (measured: 3.0-3.2x on the real three-tube and a generated recording).
pub const ANALYTIC_SOLVES: f64 = 3.0;
/// Cost of a row solved with the core's analytic parameter Jacobian (stiffness and
/// curvature scales), in plain solves (measured: 4.9-5.1x on the real three-tube
/// recording, a loop over its rows).
pub const SCALES_SOLVES: f64 = 4.9;
/// Cost of a row solved with both Jacobians from one derivative pass, in plain solves
/// (measured: 6.9-7.0x there; 7.9x as two passes).
pub const BOTH_SOLVES: f64 = 7.0;

/// What a linearisation compares of two models: their mechanics, without the
/// stiffness and precurvature factors when `moving` moves them.
fn compared(model: &ModelSpec, moving: Moving) -> ModelSpec {
    let mut m = mechanics(model);
    if moving.scales() {
        m.effects.stiffness = None;
        m.effects.precurvature = None;
    }
    m
}

/// `model`'s stiffness factors and precurvature radius factors per tube (1 where it
/// has none).
fn factors(model: &ModelSpec) -> (Vec<f64>, Vec<f64>) {
    let n = model.robot.n_tubes();
    let each = |v: Option<&Vec<f64>>| -> Vec<f64> {
        (0..n)
            .map(|i| v.and_then(|v| v.get(i)).copied().unwrap_or(1.0))
            .collect()
    };
    (
        each(model.effects.stiffness.as_ref().map(|s| &s.factor)),
        each(
            model
                .effects
                .precurvature
                .as_ref()
                .map(|p| &p.radius_factor),
        ),
    )
}
/// Probe step of a feed under a load, mm: the central difference's truncation
/// (relative ~1e-6 on millimetre-scale curvature) and the solver's residual over the
/// step (~1e-9) both far below what a fit's step needs.
pub const PROBE_MM: f64 = 1e-3;
/// Probe step of a rotation under a load, degrees (as [`PROBE_MM`]).
pub const PROBE_DEG: f64 = 1e-3;

/// What a linearisation of `model` must carry to move as `moving` says: where its
/// friction grows with the contact moment, the moment is the scaled tubes' (the
/// timeline's [`crate::contact::Contact`]), so a change of the stiffness or
/// precurvature factors moves each row's actual joints too, and the scales come with
/// the joint Jacobian ([`Moving::Both`]).
fn carried(model: &ModelSpec, moving: Moving) -> Moving {
    let contact = model
        .effects
        .friction
        .as_ref()
        .is_some_and(|f| f.grows_with_contact());
    match moving {
        Moving::Scales if contact => Moving::Both,
        other => other,
    }
}

/// Whether `model` has a learned discrepancy or an empirical correction: terms on the
/// commanded joints after the measurement, which are not linearised.
fn learned(model: &ModelSpec) -> bool {
    model.discrepancy.is_some() || model.empirical.is_some()
}

/// Whether the rows `rows` of `model` are solved under a load (gravity, a tip force).
fn loaded(model: &ModelSpec, rec: &Recording, rows: &[usize]) -> bool {
    model.effects.gravity.is_some()
        || rows
            .iter()
            .any(|&r| rec.rows[r].force_n.iter().any(|&f| f != 0.0))
}

/// The row `a` (actual joints, file units) under the tip force `force` solved by
/// `solver` (which moves on to it), with the joint Jacobian of its tip in `columns`
/// by central differences of warm solves from it (one-sided where a probe leaves the
/// robot's ranges; a zero column where both do).
fn probed(
    solver: &mut RowSolver,
    a: &[f64],
    force: [f64; 3],
    columns: &mut Vec<[f64; 6]>,
) -> Result<FkResult, SolveError> {
    let tip = solver.fk_actual(a, force)?;
    let at = frame_of(tip.position, tip.quaternion);
    columns.clear();
    let mut q = a.to_vec();
    for k in 0..a.len() {
        let step = if k % 2 == 0 { PROBE_MM } else { PROBE_DEG };
        let mut probe = |d: f64| -> Option<Frame<f64>> {
            q[k] = a[k] + d;
            let moved = solver.clone().fk_actual(&q, force).ok();
            q[k] = a[k];
            moved.map(|t| frame_of(t.position, t.quaternion))
        };
        let (up, down) = (probe(step), probe(-step));
        let span = step * f64::from(u8::from(up.is_some()) + u8::from(down.is_some()));
        let (up, down) = (up.unwrap_or(at), down.unwrap_or(at));
        columns.push(if span > 0.0 {
            let dp = (up.position - down.position) / span;
            let w = Rotation3::from_matrix_unchecked(up.rotation * down.rotation.transpose())
                .scaled_axis()
                / span;
            [dp.x, dp.y, dp.z, w.x, w.y, w.z]
        } else {
            [0.0; 6]
        });
    }
    Ok(tip)
}

/// A linearised row: its index, actual joints, unmeasured tip, the core's solution
/// there (where its derivatives come later), and its columns in the joints and in the
/// scales (empty where they do not move).
struct RowLinearised {
    row: usize,
    actual: Vec<f64>,
    tip: Frame<f64>,
    kept: Option<Kept>,
    joints: Vec<[f64; 6]>,
    scales: Vec<[f64; 6]>,
}

/// Derivative columns of a row, `(dp, omega)` each.
type Columns = Vec<[f64; 6]>;

/// Rows of one job of [`Linearised::moving`]'s derivatives.
const DERIVATIVE_ROWS: usize = 16;

/// The rows `solved` of run `run` solved along it, warm, as a simulation does: their
/// solutions kept for their analytic derivatives, or under a load (`loaded`) the joint
/// columns probed here where `moving` moves the joints; `Ok(None)` where the core has
/// no Jacobian for them.
fn run_linearised(
    row_model: &RowModel,
    rec: &Recording,
    run: usize,
    solved: &[bool],
    loaded: bool,
    moving: Moving,
) -> Result<Option<Vec<RowLinearised>>, SimError> {
    let range = rec.runs[run].rows.clone();
    let shifted = shifted_joints(row_model, rec, run);
    let mut solver = row_model.solver();
    let mut joints = Vec::new();
    let mut out = Vec::new();
    for (k, row) in range.enumerate() {
        if !solved[row] {
            continue;
        }
        let a = shifted.as_ref().map_or(&rec.rows[row].q[..], |v| v.row(k));
        let force = rec.rows[row].force_n;
        let solve = if loaded && moving.joints() {
            probed(&mut solver, a, force, &mut joints).map(|tip| (tip, None))
        } else {
            solver
                .fk_kept(a, force)
                .map(|(tip, kept)| (tip, Some(kept)))
        };
        let (tip, kept) = match solve {
            Ok(solved) => solved,
            Err(SolveError::Unsupported(_)) => return Ok(None),
            Err(error) => return Err(row_error(row, error)),
        };
        out.push(RowLinearised {
            row,
            actual: a.to_vec(),
            tip: frame_of(tip.position, tip.quaternion),
            kept,
            joints: joints.clone(),
            scales: Vec::new(),
        });
    }
    Ok(Some(out))
}

/// The joint and scale columns `moving` asks for of a row solved along its run, at its
/// kept solution (`solver`: any of the model's); `None` where the core has none.
fn derivatives(
    solver: &mut RowSolver,
    row: &RowLinearised,
    moving: Moving,
) -> Option<(Columns, Columns)> {
    let (mut joints, mut scales) = (Vec::new(), Vec::new());
    solver
        .derivatives_at(
            &row.actual,
            row.kept.as_ref()?,
            moving.joints().then_some(&mut joints),
            moving.scales().then_some(&mut scales),
        )
        .ok()?;
    Some((joints, scales))
}

/// The frame of a position and a unit quaternion `w, x, y, z`.
fn frame_of(p: [f64; 3], q: [f64; 4]) -> Frame<f64> {
    let rotation: Matrix3<f64> =
        UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
            .to_rotation_matrix()
            .into_inner();
    Frame {
        rotation,
        position: Vector3::from(p),
    }
}

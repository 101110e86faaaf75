//! The measurement profiled out of a fit (variable projection).
//!
//! Three effects of the vocabulary map the tip frame `(P, A)` the mechanics give (in
//! W) to the frame the tracker measures, after the mechanics and without changing them
//! (the core's `Effects::measured`):
//!
//! ```text
//! p = R (P + A d) + t,    Q = R A S
//! ```
//!
//! with the registration `(R, t)` (the tracker's frame), the sensor offset `d` and the
//! sensor's rotation `S` (both in the tip frame). Given the mechanics' tips, the fit's
//! cost is a function of these twelve numbers alone, cheap to evaluate (no solve): a
//! fit whose blocks hold any of them solves them at every point it tries
//! ([`profile`]), so that the other parameters' steps never see them (Golub and
//! Pereyra's variable projection; the steps are Kaufman's, the Schur complement of
//! the measurement in the normal equations, [`crate::levenberg`]). A re-framed
//! recording (every measured tip and angle turned by `R'` and shifted by `t'`) then
//! gives the same fit of everything else, and the registration `R' R`, `R' t + t'`:
//! the diagnosis commutes with the tracker's frame.
//!
//! The solve starts from the better of the point's own values and the closed form of
//! the frame, weighted Kabsch / Umeyama (the rotation from the SVD of the weighted
//! cross-covariance of the tips, with the measured tangents or orientation axes as
//! direction pairs beside them, weighted as the residual weighs them), then takes
//! Gauss-Newton steps of the robust cost (the IRLS weights of Huber's cost, analytic
//! Jacobians of small rotations applied on the left of `R` and on the right of `S`)
//! while they lower it.

use crate::candidates::EffectId;
use crate::levenberg::huber;
use crate::start::angular;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::Prediction;
use ctr_formats::{
    canonical_quaternion, AngularColumns, Recording, Registration, SensorOffset, SensorRotation,
};
use nalgebra::{DMatrix, DVector, Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector3};

/// The effects on the measurement, which a fit profiles.
pub(crate) const MEASUREMENT: [EffectId; 3] = [
    EffectId::Registration,
    EffectId::SensorOffset,
    EffectId::SensorRotation,
];

/// Most Gauss-Newton steps of a profile.
const MAX_STEPS: usize = 30;
/// A profile ends when a step lowers the cost by less than this share of it.
const RELATIVE_GAIN_END: f64 = 1e-13;

/// `model` without its measurement: the tip frames in W.
pub(crate) fn without(model: &ModelSpec) -> ModelSpec {
    let mut m = model.clone();
    m.effects.registration = None;
    m.effects.sensor_offset = None;
    m.effects.sensor_rotation = None;
    m
}

/// Which of the measurement's parameters a profile moves, and where they sit in the
/// fit's parameter vector.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Free {
    /// The registration's block (translation mm, rotation vector deg), if fitted.
    pub registration: Option<usize>,
    /// The sensor offset's block (mm), if fitted.
    pub offset: Option<usize>,
    /// The sensor rotation's block (rotation vector deg), if fitted.
    pub rotation: Option<usize>,
}

impl Free {
    /// Whether nothing is profiled.
    pub(crate) fn none(&self) -> bool {
        self.registration.is_none() && self.offset.is_none() && self.rotation.is_none()
    }

    /// The columns of the local parameters moved: the registration's rotation and
    /// translation, the sensor offset, the sensor rotation (3 each).
    fn groups(&self) -> Vec<Group> {
        let mut g = Vec::new();
        if self.registration.is_some() {
            g.extend([Group::Turn, Group::Shift]);
        }
        if self.offset.is_some() {
            g.push(Group::Offset);
        }
        if self.rotation.is_some() {
            g.push(Group::Sensor);
        }
        g
    }
}

/// A group of three local parameters of a profile's steps.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Group {
    /// A small rotation applied on the left of `R`, rad.
    Turn,
    /// A change of `t`, mm.
    Shift,
    /// A change of `d`, mm.
    Offset,
    /// A small rotation applied on the right of `S`, rad.
    Sensor,
}

/// A measurement: `p = R (P + A d) + t`, `Q = R A S` (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Measurement {
    r: Rotation3<f64>,
    t: Vector3<f64>,
    d: Vector3<f64>,
    s: Rotation3<f64>,
}

impl Measurement {
    /// The measurement of `model` (identity where it has none).
    pub(crate) fn of(model: &ModelSpec) -> Self {
        let e = &model.effects;
        let r = e.registration.map_or(Rotation3::identity(), |r| {
            Rotation3::new(Vector3::from(r.rotation_vector_deg()).map(f64::to_radians))
        });
        Measurement {
            r,
            t: Vector3::from(e.registration.map_or([0.0; 3], |r| r.translation_mm)),
            d: Vector3::from(e.sensor_offset.map_or([0.0; 3], |s| s.offset_mm)),
            s: e.sensor_rotation.map_or(Rotation3::identity(), |s| {
                Rotation3::new(Vector3::from(s.rotation_vector_deg).map(f64::to_radians))
            }),
        }
    }

    /// The registration's rotation `R`.
    pub(crate) fn turn(&self) -> Rotation3<f64> {
        self.r
    }

    /// Writes the profiled parts into the fit's parameters `x` (blocks at `free`),
    /// within `bounds` of each parameter (the sensor offset and rotation have some).
    fn write(&self, free: &Free, x: &mut [f64], bounds: impl Fn(usize) -> (f64, f64)) {
        let deg = |v: Vector3<f64>| v.map(f64::to_degrees);
        let mut put = |at: usize, v: Vector3<f64>| {
            for k in 0..3 {
                let (lo, hi) = bounds(at + k);
                x[at + k] = v[k].clamp(lo, hi);
            }
        };
        if let Some(at) = free.registration {
            put(at, self.t);
            put(at + 3, deg(self.r.scaled_axis()));
        }
        if let Some(at) = free.offset {
            put(at, self.d);
        }
        if let Some(at) = free.rotation {
            put(at, deg(self.s.scaled_axis()));
        }
    }

    /// The measured point and frame of a tip at `p` turned by `a` (W).
    fn apply(&self, p: &Vector3<f64>, a: &Rotation3<f64>) -> (Vector3<f64>, Rotation3<f64>) {
        (self.r * (p + a * self.d) + self.t, self.r * a * self.s)
    }

    /// This measurement moved by the local step `dx` over `groups`.
    fn moved(&self, groups: &[Group], dx: &DVector<f64>) -> Self {
        let mut m = *self;
        for (k, g) in groups.iter().enumerate() {
            let v = Vector3::new(dx[3 * k], dx[3 * k + 1], dx[3 * k + 2]);
            match g {
                Group::Turn => m.r = Rotation3::new(v) * m.r,
                Group::Shift => m.t += v,
                Group::Offset => m.d += v,
                Group::Sensor => m.s *= Rotation3::new(v),
            }
        }
        m
    }
}

/// The tips a profile fits: the mechanics' tip frame of each counted row, and what the
/// residual compares them with.
pub(crate) struct Tips<'a> {
    rec: &'a Recording,
    rows: &'a [usize],
    /// Tip position in W per counted row.
    p: Vec<Vector3<f64>>,
    /// Tip rotation in W per counted row.
    a: Vec<Rotation3<f64>>,
    huber_mm: f64,
}

impl<'a> Tips<'a> {
    /// The counted `rows` of `bare` (a prediction of a model without its measurement)
    /// against `rec`, with the fit's Huber threshold; `None` where a tip is missing.
    pub(crate) fn new(
        rec: &'a Recording,
        rows: &'a [usize],
        bare: &Prediction,
        huber_mm: f64,
    ) -> Option<Self> {
        let mut p = Vec::with_capacity(rows.len());
        let mut a = Vec::with_capacity(rows.len());
        for &r in rows {
            let q = bare.q[r];
            if !(bare.p[r].iter().chain(&q).all(|v| v.is_finite())) {
                return None;
            }
            p.push(Vector3::from(bare.p[r]));
            let u = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
            a.push(u.to_rotation_matrix());
        }
        Some(Tips {
            rec,
            rows,
            p,
            a,
            huber_mm,
        })
    }

    /// The measured prediction of every recording row under `m` (`NaN` where `bare`
    /// has none), as a solve of the model with that measurement gives it.
    pub(crate) fn measured(&self, m: &Measurement, bare: &Prediction) -> Prediction {
        let n = self.rec.rows.len();
        let mut out = Prediction {
            p: vec![[f64::NAN; 3]; n],
            q: vec![[f64::NAN; 4]; n],
            failed: bare.failed,
            margin: bare.margin.clone(),
        };
        for (k, &r) in self.rows.iter().enumerate() {
            let (p, q) = m.apply(&self.p[k], &self.a[k]);
            out.p[r] = p.into();
            out.q[r] = canonical_quaternion(&UnitQuaternion::from_rotation_matrix(&q));
        }
        out
    }

    /// Row `k`'s position error and angular error (mm-equivalent; zeros without
    /// weighted angular columns) under `m`, with the measured frame.
    fn errors(&self, m: &Measurement, k: usize) -> ([f64; 3], [f64; 3], Rotation3<f64>) {
        let row = &self.rec.rows[self.rows[k]];
        let (p, q) = m.apply(&self.p[k], &self.a[k]);
        let pos = [p.x - row.p[0], p.y - row.p[1], p.z - row.p[2]];
        let ang = match self.rec.angular {
            Some(w) => {
                let quat = canonical_quaternion(&UnitQuaternion::from_rotation_matrix(&q));
                angular::rotation(w.columns, row, &quat).map(|v| v * w.mm_per_rad())
            }
            None => [0.0; 3],
        };
        (pos, ang, q)
    }

    /// The robust cost under `m` (the fit's: Huber's on each row's position error and
    /// on its angular error).
    pub(crate) fn cost(&self, m: &Measurement) -> f64 {
        let mut e = Vec::with_capacity(6 * self.rows.len());
        for k in 0..self.rows.len() {
            let (pos, ang, _) = self.errors(m, k);
            e.extend(pos);
            if self.rec.angular.is_some() {
                e.extend(ang);
            }
        }
        huber(&e, self.huber_mm).0
    }
}

/// The measurement that minimises the robust cost of `tips` over the parts `free`
/// moves, from `m0` (module doc), and its cost.
pub(crate) fn profile(tips: &Tips, m0: Measurement, free: &Free) -> (Measurement, f64) {
    let groups = free.groups();
    let mut now = m0;
    let mut cost = tips.cost(&now);
    if groups.is_empty() || !cost.is_finite() {
        return (now, cost);
    }
    if free.registration.is_some() {
        let start = kabsch(tips, &now);
        let c = tips.cost(&start);
        if c < cost {
            (now, cost) = (start, c);
        }
    }
    let np = 3 * groups.len();
    let mut lambda = 1e-9;
    for _ in 0..MAX_STEPS {
        let (h, g) = normal_equations(tips, &now, &groups);
        let dmax = (0..np).map(|j| h[(j, j)]).fold(0.0, f64::max);
        if dmax <= 0.0 {
            break;
        }
        let mut stepped = false;
        for _ in 0..8 {
            let mut a = h.clone();
            for j in 0..np {
                a[(j, j)] += lambda * dmax + 1e-12 * dmax;
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let next = now.moved(&groups, &chol.solve(&(-&g)));
            let c = tips.cost(&next);
            if c < cost {
                let gain = (cost - c) / cost.max(f64::MIN_POSITIVE);
                (now, cost) = (next, c);
                lambda = (lambda / 10.0).max(1e-12);
                stepped = gain > RELATIVE_GAIN_END;
                break;
            }
            lambda *= 10.0;
        }
        if !stepped {
            break;
        }
    }
    (now, cost)
}

/// The IRLS normal equations of `tips` under `m` in the local parameters of `groups`.
fn normal_equations(
    tips: &Tips,
    m: &Measurement,
    groups: &[Group],
) -> (DMatrix<f64>, DVector<f64>) {
    let np = 3 * groups.len();
    let mut h = DMatrix::<f64>::zeros(np, np);
    let mut g = DVector::<f64>::zeros(np);
    let c = tips.huber_mm;
    let weight = |e: &[f64; 3]| crate::levenberg::huber_weight(e, c);
    let mut block = DMatrix::<f64>::zeros(3, np);
    let mut add = |block: &DMatrix<f64>, e: &[f64; 3], w: f64| {
        let ev = Vector3::from(*e);
        g.gemv_tr(w, block, &ev, 1.0);
        h.gemm_tr(w, block, block, 1.0);
    };
    let angular = tips.rec.angular;
    for k in 0..tips.rows.len() {
        let (pos, ang, q) = tips.errors(m, k);
        // the position block
        let arm = m.r * (tips.p[k] + tips.a[k] * m.d);
        for (i, grp) in groups.iter().enumerate() {
            let cols: Matrix3<f64> = match grp {
                Group::Turn => -arm.cross_matrix(),
                Group::Shift => Matrix3::identity(),
                Group::Offset => *(m.r * tips.a[k]).matrix(),
                Group::Sensor => Matrix3::zeros(),
            };
            block.fixed_view_mut::<3, 3>(0, 3 * i).copy_from(&cols);
        }
        add(&block, &pos, weight(&pos));
        let Some(w) = angular else { continue };
        let row = &tips.rec.rows[tips.rows[k]];
        let measured = match w.columns {
            AngularColumns::Orientation => row.quaternion.is_some(),
            AngularColumns::Tangent => row.tangent.is_some(),
        };
        if !measured {
            continue;
        }
        // the angular block: a turn on the left of the measured frame moves its error by
        // itself (a tangent's by its part normal to the tangent)
        let normal = match w.columns {
            AngularColumns::Orientation => Matrix3::identity(),
            AngularColumns::Tangent => {
                let t = q * Vector3::z();
                Matrix3::identity() - t * t.transpose()
            }
        };
        let s = w.mm_per_rad();
        for (i, grp) in groups.iter().enumerate() {
            let cols: Matrix3<f64> = match grp {
                Group::Turn => normal * s,
                Group::Sensor => normal * q.matrix() * s,
                Group::Shift | Group::Offset => Matrix3::zeros(),
            };
            block.fixed_view_mut::<3, 3>(0, 3 * i).copy_from(&cols);
        }
        add(&block, &ang, weight(&ang));
    }
    (h, g)
}

/// `m` with the registration of weighted Kabsch: the rotation and translation that
/// best map the tracked points (with `m`'s sensor offset and rotation) onto the
/// measured ones, the measured directions (tangents, or an orientation's axes)
/// beside them, each weighted as `m`'s residual weighs its row (module doc).
fn kabsch(tips: &Tips, m: &Measurement) -> Measurement {
    let c = tips.huber_mm;
    let weight = |e: &[f64; 3]| crate::levenberg::huber_weight(e, c);
    let n = tips.rows.len();
    let mut src = Vec::with_capacity(n);
    let mut wts = Vec::with_capacity(n);
    let mut dirs: Vec<(Vector3<f64>, Vector3<f64>, f64)> = Vec::new();
    for k in 0..n {
        let (pos, ang, _) = tips.errors(m, k);
        let v = tips.p[k] + tips.a[k] * m.d;
        src.push(v);
        wts.push(weight(&pos));
        let Some(w) = tips.rec.angular else { continue };
        let row = &tips.rec.rows[tips.rows[k]];
        let frame = tips.a[k] * m.s;
        let s2 = w.mm_per_rad().powi(2) * weight(&ang);
        match (w.columns, row.tangent, row.quaternion) {
            (AngularColumns::Tangent, Some(t), _) => {
                dirs.push((frame * Vector3::z(), Vector3::from(t), s2));
            }
            (AngularColumns::Orientation, _, Some(q)) => {
                let meas = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
                // the three axes: their chords add to twice the angle's square
                for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
                    dirs.push((frame * axis, meas * axis, 0.5 * s2));
                }
            }
            _ => {}
        }
    }
    let total: f64 = wts.iter().sum();
    if total <= 0.0 {
        return *m;
    }
    let centre = |pts: &mut dyn Iterator<Item = Vector3<f64>>| -> Vector3<f64> {
        pts.zip(&wts).map(|(p, w)| p * *w).sum::<Vector3<f64>>() / total
    };
    let sc = centre(&mut src.iter().copied());
    let mc = centre(&mut tips.rows.iter().map(|&r| Vector3::from(tips.rec.rows[r].p)));
    let mut cov = Matrix3::<f64>::zeros();
    for (k, &r) in tips.rows.iter().enumerate() {
        let mp = Vector3::from(tips.rec.rows[r].p) - mc;
        cov += (src[k] - sc) * mp.transpose() * wts[k];
    }
    for (a, b, w) in &dirs {
        cov += a * b.transpose() * *w;
    }
    let svd = cov.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return *m;
    };
    let v = vt.transpose();
    let mut fix = Matrix3::identity();
    fix[(2, 2)] = (v * u.transpose()).determinant().signum();
    let r = Rotation3::from_matrix_unchecked(v * fix * u.transpose());
    Measurement {
        r,
        t: mc - r * sc,
        ..*m
    }
}

/// The parts of `free` profiled at the fit's parameters `x` against `tips`, written
/// into `x` (within `bounds`), and the measured prediction there; `model` is the
/// fit's model at `x` and `bare` its prediction without the measurement.
pub(crate) fn profiled(
    tips: &Tips,
    model: &ModelSpec,
    bare: &Prediction,
    free: &Free,
    x: &mut [f64],
    bounds: impl Fn(usize) -> (f64, f64),
) -> Prediction {
    let (m, _) = profile(tips, Measurement::of(model), free);
    m.write(free, x, &bounds);
    // as the parameters written say (a bound may have clipped one)
    tips.measured(&Measurement::of(&clipped(model, free, x)), bare)
}

/// `model` with the profiled parts as `x` holds them.
fn clipped(model: &ModelSpec, free: &Free, x: &[f64]) -> ModelSpec {
    let mut m = model.clone();
    let v3 = |at: usize| [x[at], x[at + 1], x[at + 2]];
    if let Some(at) = free.registration {
        m.effects.registration = Some(Registration::from_rotation_vector(v3(at + 3), v3(at)));
    }
    if let Some(at) = free.offset {
        m.effects.sensor_offset = Some(SensorOffset { offset_mm: v3(at) });
    }
    if let Some(at) = free.rotation {
        m.effects.sensor_rotation = Some(SensorRotation {
            rotation_vector_deg: v3(at),
        });
    }
    m
}

/// `m` with the common turn of its rotation offsets moved into its frame: turning
/// every tube by `d` about W's z axis (the insertion axis) turns the robot, its tips and
/// their frames about that axis, which the frame turned by `d` about it does as well
/// (`R -> R Rz(d)`), so the data see only their sum. The frame takes it (a nuisance
/// with no nominal to keep), the offsets keep only what tells the tubes apart (their
/// mean turn 0): the same tips, and checks that judge the offsets on what the data see
/// of them. Gravity fitted (not the user's) turns with them (`g -> Rz(-d) g` in W);
/// nothing is moved under a load the turn does not carry along (a recorded tip force,
/// the user's gravity), or where the model lacks either effect.
pub(crate) fn gauged(m: &mut ModelSpec, user: &ModelSpec, loaded: bool) {
    let (Some(reg), Some(offsets)) = (m.effects.registration, m.effects.joint_offset.as_mut())
    else {
        return;
    };
    let fixed_load = user.effects.gravity.is_some();
    if loaded || fixed_load || offsets.rotation_deg.is_empty() {
        return;
    }
    let mean = offsets.rotation_deg.iter().sum::<f64>() / offsets.rotation_deg.len() as f64;
    if mean == 0.0 {
        return;
    }
    for o in &mut offsets.rotation_deg {
        // the same turn within the fits' bounds (+/-180 deg, where it wraps)
        *o = (*o - mean + 180.0).rem_euclid(360.0) - 180.0;
    }
    let r =
        nalgebra::Rotation3::new(
            nalgebra::Vector3::from(reg.rotation_vector_deg()).map(f64::to_radians),
        ) * nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), mean.to_radians());
    let v = r.scaled_axis().map(f64::to_degrees);
    m.effects.registration = Some(ctr_formats::Registration::from_rotation_vector(
        v.into(),
        reg.translation_mm,
    ));
    if let Some(g) = m.effects.gravity.as_mut() {
        let back =
            nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), -mean.to_radians());
        g.direction_w = (back * nalgebra::Vector3::from(g.direction_w)).into();
    }
}

#[cfg(test)]
mod tests {
    use crate::candidates::EffectId;
    use crate::fit::{Problem, MAX_FIT_ITERATIONS};
    use crate::synth::{generate, Ranges, Reframe, SynthSpec};
    use ctr_analysis::model::ModelSpec;
    use ctr_formats::{AngularColumns, AngularWeight, Latency};

    fn world() -> (ModelSpec, Ranges) {
        let text = include_str!("../../../data/robots/nitinol2.toml");
        let spec = ctr_formats::RobotSpec::from_toml_str(text, "nitinol2.toml").unwrap();
        let mut m = ModelSpec::from_spec(&spec);
        m.effects.latency = Some(Latency { tau_s: 0.3 });
        let ranges = Ranges {
            increments_mm: vec![[10.0, 60.0], [10.0, 80.0]],
            theta_deg: [-180.0, 180.0],
        };
        (m, ranges)
    }

    /// A recording re-framed by a large turn and shift (with measured tangents that
    /// turn with it): a fit of the latency with the frame profiled ends where it ends on
    /// the recording as it was, and its frame is the turn composed with the first.
    #[test]
    fn a_profiled_fit_commutes_with_the_tracker_frame() {
        let (world, ranges) = world();
        let synth = SynthSpec {
            angular: Some(AngularColumns::Tangent),
            walk_rows: 100,
            ..SynthSpec::default()
        };
        let mut rec = generate(&world, &ranges, &synth).unwrap().recording;
        rec.angular = Some(AngularWeight {
            columns: AngularColumns::Tangent,
            sigma_rad: 0.3f64.to_radians(),
            sigma_mm: 0.2,
        });
        let turn = [20.0, -35.0, 10.0];
        let shift = [40.0, -25.0, 8.0];
        let moved = Reframe::Frame {
            rotation_vector_deg: turn,
            translation_mm: shift,
        }
        .apply(&rec)
        .unwrap()
        .recording;
        let mut user = world.clone();
        user.effects.latency = None;
        let blocks = vec![EffectId::Latency, EffectId::Registration];
        let fit = |r: &ctr_formats::Recording| {
            let p = Problem::for_test(user.clone(), blocks.clone(), r, 2);
            let f = p.fit(&[0.0; 7], MAX_FIT_ITERATIONS).unwrap();
            (f.x, f.cost)
        };
        let (x0, c0) = fit(&rec);
        let (x1, c1) = fit(&moved);
        assert!((x0[0] - 0.3).abs() < 0.01, "latency {}", x0[0]);
        assert!(
            (x1[0] - x0[0]).abs() < 1e-6,
            "latency {} vs {}",
            x1[0],
            x0[0]
        );
        assert!((c1 - c0).abs() < 1e-6 * c0, "cost {c1} vs {c0}");
        // the frame found is the turn (the first is the identity, to the noise)
        let r1 = nalgebra::Rotation3::new(
            nalgebra::Vector3::new(x1[4], x1[5], x1[6]).map(f64::to_radians),
        );
        let want = nalgebra::Rotation3::new(nalgebra::Vector3::from(turn).map(f64::to_radians));
        assert!((r1 * want.inverse()).angle().to_degrees() < 0.05);
        for a in 0..3 {
            assert!(
                (x1[1 + a] - shift[a]).abs() < 0.3,
                "shift {a}: {}",
                x1[1 + a]
            );
        }
    }
}

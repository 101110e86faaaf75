//! The angular columns of a recording (`qw,qx,qy,qz` or `tx,ty,tz`) as part of the
//! residual: each row's angular error, their noise estimated from the data as the
//! positions' is, and the weight that whitens them against the positions.
//!
//! A row's angular error is the small rotation `omega` (rad, a 3-vector in the
//! measuring frame) that takes the measured to the predicted:
//!
//! ```text
//! orientation:  omega = log(q_pred q_meas^-1)            (3 components)
//! tangent:      omega = atan2(|t_m x t_p|, t_m . t_p) (t_m x t_p) / |t_m x t_p|
//!                                                        (2 components: normal to t_m)
//! ```
//!
//! with `t_p` the predicted tip frame's z axis. Its noise `sigma_rad` per component is
//! estimated like the positions' (`crate::start::noise`): the second differences of the user
//! model's `omega` along each run leave `6 sigma^2` of white noise per component (a
//! tangent's projected on the plane normal to the measured tangent, where its noise
//! lies), and the median absolute deviation of them is robust to reversals and
//! outliers. A row's error then counts `omega * sigma_mm / sigma_rad` in mm beside its
//! position error: both enter whitened by their own noise, the positions keeping their
//! weight, so one residual serves the fits, the screen, the held-out figures, the
//! outliers and the intervals alike (`crate::start::weighting` sets the weight,
//! `crate::residual` forms the residual). With an orientation, a tangent is not used
//! again (the orientation holds it: its z axis).

use crate::robust::sigma_of_second_differences;
use ctr_analysis::simulate::Prediction;
use ctr_formats::{AngularColumns, RecordedRow, Recording};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// The small rotation (rad, measuring frame) from row `r`'s measured angular column
/// set `columns` to the predicted tip frame `q_pred` (`w, x, y, z`); zeros when the
/// row has no such measurement, NaN when the prediction is missing.
pub(crate) fn rotation(columns: AngularColumns, r: &RecordedRow, q_pred: &[f64; 4]) -> [f64; 3] {
    let pred = UnitQuaternion::from_quaternion(Quaternion::new(
        q_pred[0], q_pred[1], q_pred[2], q_pred[3],
    ));
    let v = match columns {
        AngularColumns::Orientation => {
            let Some(m) = r.quaternion else {
                return [0.0; 3];
            };
            let meas = UnitQuaternion::from_quaternion(Quaternion::new(m[0], m[1], m[2], m[3]));
            let d = pred * meas.inverse();
            // the shorter way round: q and -q are the same rotation
            let (w, v) = if d.w < 0.0 {
                (-d.w, -d.imag())
            } else {
                (d.w, d.imag())
            };
            axis_angle(v, w, 2.0)
        }
        AngularColumns::Tangent => {
            let Some(m) = r.tangent else {
                return [0.0; 3];
            };
            let tm = Vector3::from(m);
            let tp = pred * Vector3::z();
            axis_angle(tm.cross(&tp), tm.dot(&tp), 1.0)
        }
    };
    [v.x, v.y, v.z]
}

/// `factor atan2(|v|, c) v / |v|` (zero for `v = 0`): a rotation vector from a sine
/// part `v` and cosine part `c`, accurate for tiny angles (no `acos`).
fn axis_angle(v: Vector3<f64>, c: f64, factor: f64) -> Vector3<f64> {
    let s = v.norm();
    if s == 0.0 {
        return v;
    }
    v * (factor * s.atan2(c) / s)
}

/// Every row's angular error, rad (see [`rotation`]).
pub(crate) fn rotations(
    rec: &Recording,
    columns: AngularColumns,
    pred: &Prediction,
) -> Vec<[f64; 3]> {
    rec.rows
        .iter()
        .zip(&pred.q)
        .map(|(r, q)| rotation(columns, r, q))
        .collect()
}

/// Noise per angular component, rad, from the second differences of `omega` along
/// each run (of a static set, from its repeats: [`crate::start::repeats`], the
/// components in the measured tangent's normal plane for a tangent), and the number of
/// row triples (rows of a static set) it used.
pub(crate) fn estimate(
    rec: &Recording,
    columns: AngularColumns,
    omega: &[[f64; 3]],
) -> (f64, usize) {
    if rec.is_static() {
        let repeats = crate::start::repeats::Repeats::of(rec);
        // one plane per configuration: its first row's measured tangent's
        let first: Vec<usize> = crate::start::repeats::companions(rec)
            .iter()
            .enumerate()
            .map(|(r, c)| c.iter().copied().fold(r, usize::min))
            .collect();
        let in_plane = |r: usize| -> [f64; 3] {
            let d = Vector3::from(omega[r]);
            match (columns, rec.rows[first[r]].tangent) {
                (AngularColumns::Tangent, Some(t)) => {
                    let t = Vector3::from(t);
                    let u = t.cross(&least_aligned(&t)).normalize();
                    let w = t.cross(&u);
                    [d.dot(&u), d.dot(&w), f64::NAN]
                }
                _ => omega[r],
            }
        };
        return match repeats {
            // averaged frames say nothing of their angles' scatter
            crate::start::repeats::Repeats::Averaged => (f64::NAN, 0),
            _ => (repeats.sigma(rec, in_plane).0, rec.rows.len()),
        };
    }
    let mut d2 = Vec::new();
    let mut triples = 0;
    for run in &rec.runs {
        for k in run.rows.start + 1..run.rows.end.saturating_sub(1) {
            let d = Vector3::from_fn(|a, _| omega[k - 1][a] - 2.0 * omega[k][a] + omega[k + 1][a]);
            if !d.iter().all(|v| v.is_finite()) {
                continue;
            }
            triples += 1;
            match (columns, rec.rows[k].tangent) {
                (AngularColumns::Tangent, Some(t)) => {
                    // the plane normal to the measured tangent, where its noise lies
                    let t = Vector3::from(t);
                    let u = t.cross(&least_aligned(&t)).normalize();
                    let w = t.cross(&u);
                    d2.extend([d.dot(&u), d.dot(&w)]);
                }
                _ => d2.extend(d.iter().copied()),
            }
        }
    }
    (sigma_of_second_differences(&d2), triples)
}

/// The axis of the measuring frame least aligned with `t`.
fn least_aligned(t: &Vector3<f64>) -> Vector3<f64> {
    let a = t.iamin();
    Vector3::from_fn(|i, _| f64::from(u8::from(i == a)))
}

/// The generator's tracker (`synth`): sets `row`'s measured `columns` from the true tip
/// frame `q` (`w, x, y, z`) turned by a Gaussian rotation `n` of `sigma` rad per
/// component: three for an orientation (`q_meas = exp(n) q`, so [`rotation`] gives
/// `-n`), two normal to the tangent for a tangent.
#[cfg(feature = "synth")]
pub(crate) fn measure(
    row: &mut RecordedRow,
    columns: AngularColumns,
    q: &[f64; 4],
    sigma: f64,
    rng: &mut ctr_analysis::rng::Rng,
) {
    let truth = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
    match columns {
        AngularColumns::Orientation => {
            let n = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * sigma;
            let m = UnitQuaternion::from_scaled_axis(n) * truth;
            row.quaternion = Some([m.w, m.i, m.j, m.k]);
        }
        AngularColumns::Tangent => {
            let t = truth * Vector3::z();
            let (u, v) = (truth * Vector3::x(), truth * Vector3::y());
            let n = (u * rng.normal() + v * rng.normal()) * sigma;
            let m = UnitQuaternion::from_scaled_axis(n) * t;
            row.tangent = Some([m.x, m.y, m.z]);
        }
    }
}

//! The angular columns of a recording weighted against its positions: both noises
//! estimated on the user model's error, the recording given the weight
//! ([`AngularWeight`]) that makes its residual whiten them alike (`crate::start::angular`).

use crate::residual::{errors, positions};
use crate::start::angular;
use crate::start::noise::estimate_noise;
use ctr_analysis::simulate::Prediction;
use ctr_formats::{AngularWeight, Recording};
use std::borrow::Cow;

/// `rec` with its angular columns weighted for the residual (see the module docs),
/// their noise estimated on the user model's prediction `pred` of every run: `rec`
/// itself when it has no angular column, is weighted already, or a noise cannot be
/// estimated (then only its positions count).
pub(crate) fn weighted<'a>(rec: &'a Recording, pred: &Prediction) -> Cow<'a, Recording> {
    let Some(columns) = rec.angular_columns() else {
        return Cow::Borrowed(rec);
    };
    if rec.angular.is_some() {
        return Cow::Borrowed(rec);
    }
    let e = errors(rec, pred);
    let sigma_mm = estimate_noise(rec, &positions(&e)).sigma_mm_per_axis;
    let (sigma_rad, _) = angular::estimate(rec, columns, &angular::rotations(rec, columns, pred));
    let usable = |s: f64| s.is_finite() && s > 0.0;
    if !usable(sigma_mm) || !usable(sigma_rad) {
        return Cow::Borrowed(rec);
    }
    let mut out = rec.clone();
    out.angular = Some(AngularWeight {
        columns,
        sigma_rad,
        sigma_mm,
    });
    Cow::Owned(out)
}

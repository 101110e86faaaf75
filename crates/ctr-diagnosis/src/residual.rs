//! The residual: every row's error vector (predicted - measured) and its figures on the
//! fit and held-out rows.
//!
//! A row's error ([`RowError`]) is its tip position's error, mm, then its angular error
//! in mm-equivalent (`crate::start::angular`: the rotation from measured to predicted, times
//! the recording's [`AngularWeight::mm_per_rad`](ctr_formats::AngularWeight::mm_per_rad);
//! zeros when the recording's angular columns are not weighted). This is the one place
//! the angular columns enter: the figures, the noise comparison, the outliers and the
//! fits ([`crate::fit::Problem`], which takes its angular rows from [`angular_errors`])
//! all see the same residual, and they decide on it. What a user reads keeps the units
//! apart ([`figures`]): the tip positions in mm, the tip angles in degrees, and the
//! weighted whole, the fits' basis, labelled as such. Without angular columns every
//! figure is the position's alone, bit for bit.

use crate::report::{AngularFigures, Figures};
use crate::start::angular;
use ctr_analysis::simulate::Prediction;
use ctr_formats::Recording;

/// Components of a row's error: position `x, y, z` (mm), then the angular error's
/// three (mm-equivalent).
pub(crate) const WIDTH: usize = 6;
/// A row's error vector (see the module docs).
pub(crate) type RowError = [f64; WIDTH];

/// Error vectors (predicted - measured) of every row.
pub(crate) fn errors(rec: &Recording, pred: &Prediction) -> Vec<RowError> {
    let ang = angular_errors(rec, pred);
    rec.rows
        .iter()
        .zip(&pred.p)
        .zip(&ang)
        .map(|((r, p), a)| {
            [
                p[0] - r.p[0],
                p[1] - r.p[1],
                p[2] - r.p[2],
                a[0],
                a[1],
                a[2],
            ]
        })
        .collect()
}

/// The angular errors of every row, mm-equivalent: zeros when `rec`'s angular columns
/// are not weighted.
pub(crate) fn angular_errors(rec: &Recording, pred: &Prediction) -> Vec<[f64; 3]> {
    match rec.angular {
        Some(w) => {
            let s = w.mm_per_rad();
            angular::rotations(rec, w.columns, pred)
                .into_iter()
                .map(|v| v.map(|c| c * s))
                .collect()
        }
        None => vec![[0.0; 3]; rec.rows.len()],
    }
}

/// Independent components of a row's error: 3, plus the weighted angular ones.
pub(crate) fn components(rec: &Recording) -> usize {
    3 + rec.angular.map_or(0, |w| w.columns.components())
}

/// The position part of error vectors.
pub(crate) fn positions(e: &[RowError]) -> Vec<[f64; 3]> {
    e.iter().map(|v| [v[0], v[1], v[2]]).collect()
}

/// Error vectors with positions `p` and the angular parts of `e`.
pub(crate) fn with_angles(p: &[[f64; 3]], e: &[RowError]) -> Vec<RowError> {
    p.iter()
        .zip(e)
        .map(|(p, v)| [p[0], p[1], p[2], v[3], v[4], v[5]])
        .collect()
}

/// The modelled tips of every row: the measured tip plus the error `e`.
pub(crate) fn tips(rec: &Recording, e: &[RowError]) -> Vec<[f64; 3]> {
    rec.rows
        .iter()
        .zip(e)
        .map(|(r, v)| [r.p[0] + v[0], r.p[1] + v[1], r.p[2] + v[2]])
        .collect()
}

/// The squared size of a row's error (the position's first, so that without angles it
/// is the position's bit for bit).
pub(crate) fn size2(v: &RowError) -> f64 {
    v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + (v[3] * v[3] + v[4] * v[4] + v[5] * v[5])
}

/// The figures of error vectors `e` of `rec`'s rows on the split `held`: RMS and largest
/// over the fit rows, RMS over the held-out rows, of the tip positions in mm and, when
/// `rec` weighs angular columns, of the tip angles in degrees and of the whole weighted
/// error (the fits' basis) beside them.
pub(crate) fn figures(rec: &Recording, e: &[RowError], held: &[bool]) -> Figures {
    let positions = Sums::of(e, held, |v| v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    let angular = rec.angular.map(|w| {
        let deg2 = (1.0 / w.mm_per_rad()).to_degrees().powi(2);
        let angles = Sums::of(e, held, |v| {
            deg2 * (v[3] * v[3] + v[4] * v[4] + v[5] * v[5])
        });
        let weighted = Sums::of(e, held, size2);
        AngularFigures {
            rms_deg: angles.rms(),
            max_deg: angles.max,
            heldout_rms_deg: angles.heldout_rms(),
            weighted_rms_mm_eq: weighted.rms(),
            weighted_heldout_rms_mm_eq: weighted.heldout_rms(),
        }
    });
    Figures {
        rms_mm: positions.rms(),
        max_mm: positions.max,
        heldout_rms_mm: positions.heldout_rms(),
        angular,
    }
}

/// Sums of a row's squared size over the fit and the held-out rows.
struct Sums {
    fit: f64,
    fit_rows: usize,
    held: f64,
    held_rows: usize,
    /// The largest size over the fit rows.
    max: f64,
}

impl Sums {
    fn of(e: &[RowError], held: &[bool], size2: impl Fn(&RowError) -> f64) -> Self {
        let mut s = Sums {
            fit: 0.0,
            fit_rows: 0,
            held: 0.0,
            held_rows: 0,
            max: 0.0,
        };
        for (v, h) in e.iter().zip(held) {
            let d2 = size2(v);
            if *h {
                s.held += d2;
                s.held_rows += 1;
            } else {
                s.fit += d2;
                s.fit_rows += 1;
                s.max = s.max.max(d2.sqrt());
            }
        }
        s
    }

    fn rms(&self) -> f64 {
        (self.fit / self.fit_rows.max(1) as f64).sqrt()
    }

    fn heldout_rms(&self) -> f64 {
        (self.held / self.held_rows.max(1) as f64).sqrt()
    }
}

/// Figures without the outlier rows.
pub(crate) fn inlier_figures(
    rec: &Recording,
    e: &[RowError],
    held: &[bool],
    outliers: &[usize],
) -> Figures {
    let keep: Vec<usize> = (0..e.len())
        .filter(|r| outliers.binary_search(r).is_err())
        .collect();
    let e: Vec<RowError> = keep.iter().map(|&r| e[r]).collect();
    let held: Vec<bool> = keep.iter().map(|&r| held[r]).collect();
    figures(rec, &e, &held)
}

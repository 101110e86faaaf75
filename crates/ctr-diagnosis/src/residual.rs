//! The residual: every row's error vector (predicted - measured) and its figures on the
//! fit and held-out rows.
//!
//! A row's error ([`RowError`]) is its tip position's error, mm, then its angular error
//! in mm-equivalent (`crate::start::angular`: the rotation from measured to predicted, times
//! the recording's [`AngularWeight::mm_per_rad`](ctr_formats::AngularWeight::mm_per_rad);
//! zeros when the recording's angular columns are not weighted). This is the one place
//! the angular columns enter: the figures, the noise comparison, the outliers and the
//! fits ([`crate::fit::Problem`], which takes its angular rows from [`angular_errors`])
//! all see the same residual. Without angular columns every figure is the position's
//! alone, bit for bit.

use crate::report::Figures;
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

/// RMS and largest error over the fit rows, RMS over the held-out rows (`held`).
pub(crate) fn figures(e: &[RowError], held: &[bool]) -> Figures {
    let (mut sf, mut nf, mut sh, mut nh, mut max) = (0.0, 0usize, 0.0, 0usize, 0.0f64);
    for (v, h) in e.iter().zip(held) {
        let d2 = size2(v);
        if *h {
            sh += d2;
            nh += 1;
        } else {
            sf += d2;
            nf += 1;
            max = max.max(d2.sqrt());
        }
    }
    Figures {
        rms_mm: (sf / nf.max(1) as f64).sqrt(),
        max_mm: max,
        heldout_rms_mm: (sh / nh.max(1) as f64).sqrt(),
    }
}

/// Figures without the outlier rows.
pub(crate) fn inlier_figures(e: &[RowError], held: &[bool], outliers: &[usize]) -> Figures {
    let keep: Vec<usize> = (0..e.len())
        .filter(|r| outliers.binary_search(r).is_err())
        .collect();
    let e: Vec<RowError> = keep.iter().map(|&r| e[r]).collect();
    let held: Vec<bool> = keep.iter().map(|&r| held[r]).collect();
    figures(&e, &held)
}

//! The residual: every row's error vector (predicted - measured) and its figures on the
//! fit and held-out rows.

use crate::report::Figures;
use ctr_formats::Recording;

/// Error vectors (predicted - measured) of every row.
pub(crate) fn errors(rec: &Recording, p: &[[f64; 3]]) -> Vec<[f64; 3]> {
    rec.rows
        .iter()
        .zip(p)
        .map(|(r, p)| [p[0] - r.p[0], p[1] - r.p[1], p[2] - r.p[2]])
        .collect()
}

/// The modelled tips of every row: the measured tip plus the error `e`.
pub(crate) fn tips(rec: &Recording, e: &[[f64; 3]]) -> Vec<[f64; 3]> {
    rec.rows
        .iter()
        .zip(e)
        .map(|(r, v)| [r.p[0] + v[0], r.p[1] + v[1], r.p[2] + v[2]])
        .collect()
}

/// RMS and largest error over the fit rows, RMS over the held-out rows (`held`).
pub(crate) fn figures(e: &[[f64; 3]], held: &[bool]) -> Figures {
    let (mut sf, mut nf, mut sh, mut nh, mut max) = (0.0, 0usize, 0.0, 0usize, 0.0f64);
    for (v, h) in e.iter().zip(held) {
        let d2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
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
pub(crate) fn inlier_figures(e: &[[f64; 3]], held: &[bool], outliers: &[usize]) -> Figures {
    let keep: Vec<usize> = (0..e.len())
        .filter(|r| outliers.binary_search(r).is_err())
        .collect();
    let e: Vec<[f64; 3]> = keep.iter().map(|&r| e[r]).collect();
    let held: Vec<bool> = keep.iter().map(|&r| held[r]).collect();
    figures(&e, &held)
}

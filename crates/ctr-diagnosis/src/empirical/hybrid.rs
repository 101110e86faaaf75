//! The labelled empirical term of the hybrid model: what no physics of the vocabulary
//! explains, fitted on top of the physical model as a correction linear in the
//! [`empirical`] basis, and reported apart from the findings.
//!
//! How many terms it gets is chosen by cross-validation on the fit rows only: the fit
//! rows are cut into contiguous blocks dealt round robin into [`FOLDS`] folds; for each
//! size on a grid up to [`MAX_TERMS`], the terms are picked by matching pursuit and
//! fitted on the other folds and scored on the fold left out. The size with the lowest
//! total validation error wins (ties to the smaller), and the correction of that size
//! is fitted on all fit rows. The held-out rows never take part: the held-out RMS with
//! the term is the honest figure of what it adds. The same correction, as the robot
//! file's `[model.empirical]` ([`Correction`]), is what `ctr-cli diagnose --with-empirical`
//! writes and `ctr-cli fk` applies.

use crate::empirical::{self, Basis, Field};
use crate::report::{Empirical, Term};
use crate::residual::{figures, positions, tips, with_angles, RowError};
use ctr_formats::Recording;
use ctr_formats::{Correction, Term as CorrectionTerm};

/// Folds of the cross-validation.
pub const FOLDS: usize = 5;
/// Most terms the correction may have.
pub const MAX_TERMS: usize = 24;
/// Rows of one contiguous block of the cross-validation's folds.
const FOLD_BLOCK_ROWS: usize = 10;
/// Sizes tried by the cross-validation.
const SIZES: [usize; 11] = [0, 1, 2, 3, 4, 6, 8, 10, 14, 18, 24];
/// Dominant terms the report lists.
const DOMINANT_TERMS: usize = 5;

/// The empirical term fitted to the physical model's errors `e_row` (of the tip
/// positions; the angular errors are left as they are) (held-out rows
/// `held`, robust weights from `huber_mm`), and the errors it leaves on every row; the
/// cross-validation on `threads`.
pub(crate) fn fit(
    rec: &Recording,
    e_row: &[RowError],
    held: &[bool],
    huber_mm: f64,
    threads: usize,
) -> (Empirical, Correction, Vec<RowError>) {
    let fit_mask: Vec<bool> = held.iter().map(|h| !h).collect();
    let basis = Basis::new(rec, &tips(rec, e_row), &fit_mask);
    let fields = basis.fields();
    // the correction is of the tip position; the angular errors stay as they are
    let e = &positions(e_row);
    let w = empirical::weights(e, &fit_mask, huber_mm);
    let terms = choose_size(&fields, e, &w, threads);
    let chosen = empirical::pursue(&fields, e, &w, terms);
    let left = with_angles(&empirical::subtract(&fields, &chosen, e), e_row);
    let fig = figures(rec, &left, held);
    let mut dominant: Vec<Term> = chosen
        .iter()
        .map(|&(i, c)| {
            let (j, a) = (i / 3, i % 3);
            let rms = (fields[i].iter().map(|v| (c * v[a]).powi(2)).sum::<f64>()
                / e.len().max(1) as f64)
                .sqrt();
            Term {
                feature: basis.features[j].name(),
                axis: ["x", "y", "z"][a].into(),
                coefficient_mm: -c,
                rms_mm: rms,
            }
        })
        .collect();
    dominant.sort_by(|a, b| b.rms_mm.total_cmp(&a.rms_mm));
    dominant.truncate(DOMINANT_TERMS);
    let correction = Correction {
        note: format!(
            "empirical, not physics: fitted by ctr-cli diagnose on {} ({} terms by {FOLDS}-fold \
             cross-validation on the fit rows)",
            rec.file,
            chosen.len()
        ),
        terms: chosen
            .iter()
            .map(|&(i, c)| {
                let j = i / 3;
                let (mean, scale) = basis.standard[j];
                CorrectionTerm {
                    feature: basis.features[j],
                    axis: i % 3,
                    mean,
                    scale,
                    coefficient_mm: -c,
                }
            })
            .collect(),
    };
    (
        Empirical {
            method: format!(
                "linear in a constant, the feeds, one harmonic of each rotation and relative \
                 rotation, the time and the modelled tip position (standardised on the fit \
                 rows), one coefficient per term and axis; {terms} terms chosen by {FOLDS}-fold \
                 cross-validation on the fit rows; not physics"
            ),
            terms: chosen.len(),
            rms_mm: fig.rms_mm,
            heldout_rms_mm: fig.heldout_rms_mm,
            dominant,
            inputs: Vec::new(),
            band: None,
        },
        correction,
        left,
    )
}

/// The number of terms with the lowest cross-validated error on the rows weighted in
/// `w` (ties to the smaller); the folds side by side on `threads` (the same result at
/// any count: each fold's errors are added in fold order).
pub(crate) fn choose_size(fields: &[Field], e: &[[f64; 3]], w: &[f64], threads: usize) -> usize {
    let fit_rows: Vec<usize> = (0..e.len()).filter(|&r| w[r] > 0.0).collect();
    let fold_of = |k: usize| (k / FOLD_BLOCK_ROWS) % FOLDS;
    let folds: Vec<usize> = (0..FOLDS).collect();
    let per_fold = ctr_formats::parallel::map(&folds, threads, |&fold| {
        let mut train = w.to_vec();
        let mut test = vec![false; e.len()];
        for (k, &r) in fit_rows.iter().enumerate() {
            if fold_of(k) == fold {
                train[r] = 0.0;
                test[r] = true;
            }
        }
        let order = empirical::path(fields, e, &train, MAX_TERMS);
        SIZES.map(|size| {
            let chosen = &order[..size.min(order.len())];
            let terms = empirical::coefficients(fields, chosen, e, &train);
            let left = empirical::subtract(fields, &terms, e);
            left.iter()
                .zip(&test)
                .zip(w)
                .filter(|((_, t), _)| **t)
                .map(|((v, _), w)| w * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
                .sum::<f64>()
        })
    });
    let mut sse = [0.0; SIZES.len()];
    for fold in per_fold {
        for (total, v) in sse.iter_mut().zip(fold) {
            *total += v;
        }
    }
    let best = (0..SIZES.len())
        .min_by(|&a, &b| sse[a].total_cmp(&sse[b]).then(a.cmp(&b)))
        .unwrap_or(0);
    SIZES[best]
}

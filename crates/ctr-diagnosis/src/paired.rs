//! A paired comparison of two models' held-out errors: is one lower beyond chance?
//! Consecutive rows share their errors (a tracker's wander, a structure left along a
//! run), so the rows are compared in blocks and each block counts once.

use crate::quantiles::Z975;
use crate::residual::{size2, RowError};

/// Held-out rows of one block of the paired comparison of [`clearly_lower`]
/// (consecutive rows share their errors; the cross-validation's blocks are as long).
const PAIRED_BLOCK_ROWS: usize = 10;

/// Whether the held-out squared errors of `a` are lower than those of `b` beyond
/// chance: the mean paired difference `|b|^2 - |a|^2` over the held-out rows exceeds
/// [`Z975`] times its standard error, taken over blocks of up to
/// [`PAIRED_BLOCK_ROWS`] consecutive held-out rows (so errors correlated along a run
/// count once per block).
pub(crate) fn clearly_lower(a: &[RowError], b: &[RowError], held: &[bool]) -> bool {
    let mut blocks: Vec<(f64, usize)> = Vec::new();
    let mut open = false;
    for (r, h) in held.iter().enumerate() {
        if !h {
            open = false;
            continue;
        }
        let d = size2(&b[r]) - size2(&a[r]);
        match blocks.last_mut() {
            Some((sum, n)) if open && *n < PAIRED_BLOCK_ROWS => {
                *sum += d;
                *n += 1;
            }
            _ => blocks.push((d, 1)),
        }
        open = true;
    }
    let g = blocks.len();
    let rows: usize = blocks.iter().map(|b| b.1).sum();
    if g < 2 {
        return false;
    }
    let mean = blocks.iter().map(|b| b.0).sum::<f64>() / rows as f64;
    let var = blocks
        .iter()
        .map(|&(sum, n)| (sum - n as f64 * mean).powi(2))
        .sum::<f64>()
        * g as f64
        / (g - 1) as f64;
    mean > Z975 * var.sqrt() / rows as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clearly_lower_needs_more_than_chance() {
        let mut rng = ctr_analysis::rng::Rng::new(3);
        let noise: Vec<RowError> = (0..400)
            .map(|_| [0, 1, 2, 3, 4, 5].map(|a| if a < 3 { 0.2 * rng.normal() } else { 0.0 }))
            .collect();
        let held: Vec<bool> = (0..400).map(|r| (r / 20) % 4 == 3).collect();
        let shifted = |d: f64| -> Vec<RowError> {
            noise
                .iter()
                .map(|v| [v[0] + d, v[1], v[2], 0.0, 0.0, 0.0])
                .collect()
        };
        // the same errors: not lower; a clear shift on top: lower
        assert!(!clearly_lower(&noise, &noise, &held));
        assert!(clearly_lower(&noise, &shifted(0.3), &held));
        assert!(!clearly_lower(&shifted(0.3), &noise, &held));
    }
}

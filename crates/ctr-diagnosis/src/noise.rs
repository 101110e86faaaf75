//! The noise estimated from the data (not from the model) and the tracker outliers it
//! sets apart.

use crate::report::Noise;
use ctr_formats::Recording;

/// What is left counts as noise when its RMS is at most this many times the noise
/// estimate's.
pub(crate) const NOISE_TOLERANCE: f64 = 1.15;
/// A row the final model misses by more than this many noise standard deviations (per
/// axis) is a tracker outlier (a 3-D Gaussian error exceeds 6 sigma once in 10^7).
pub const OUTLIER_SIGMAS: f64 = 6.0;
/// Robust standard deviation from a median absolute deviation.
const MAD_TO_SIGMA: f64 = 1.4826;

/// Noise per axis from the second differences of `e` along each run.
pub fn estimate_noise(rec: &Recording, e: &[[f64; 3]]) -> Noise {
    let mut d2 = Vec::new();
    for run in &rec.runs {
        for k in run.rows.start + 1..run.rows.end.saturating_sub(1) {
            for a in 0..3 {
                d2.push(e[k - 1][a] - 2.0 * e[k][a] + e[k + 1][a]);
            }
        }
    }
    let sigma = if d2.len() >= 9 {
        let med = median(&mut d2.clone());
        let mut dev: Vec<f64> = d2.iter().map(|v| (v - med).abs()).collect();
        MAD_TO_SIGMA * median(&mut dev) / 6f64.sqrt()
    } else {
        f64::NAN
    };
    Noise {
        sigma_mm_per_axis: sigma,
        rms_mm: 3f64.sqrt() * sigma,
        method: format!(
            "median absolute deviation of the residual's second differences along the runs \
             ({} triples of rows)",
            d2.len() / 3
        ),
    }
}

/// The median of `v` (sorted in place).
pub(crate) fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Rows whose error exceeds [`OUTLIER_SIGMAS`] noise standard deviations.
pub(crate) fn outlier_rows(e: &[[f64; 3]], noise: &Noise) -> Vec<usize> {
    if noise.sigma_mm_per_axis.is_nan() || noise.sigma_mm_per_axis <= 0.0 {
        return Vec::new();
    }
    let limit = OUTLIER_SIGMAS * noise.sigma_mm_per_axis;
    e.iter()
        .enumerate()
        .filter(|(_, v)| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() > limit)
        .map(|(r, _)| r)
        .collect()
}

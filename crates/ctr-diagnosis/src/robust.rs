//! Robust statistics of the noise estimates and the outlier rule.

/// Robust standard deviation from a median absolute deviation (Gaussian noise).
pub(crate) const MAD_TO_SIGMA: f64 = 1.4826;

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

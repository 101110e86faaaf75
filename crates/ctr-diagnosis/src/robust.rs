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

/// Fewest second differences (components) a noise estimate is made from.
const MIN_SECOND_DIFFERENCES: usize = 9;

/// The standard deviation of white noise whose second differences along a run are `d2`
/// (`x[k-1] - 2 x[k] + x[k+1]` per component, of variance `6 sigma^2`): the median
/// absolute deviation of them, robust to reversals and outliers; NaN from fewer than
/// [`MIN_SECOND_DIFFERENCES`].
pub(crate) fn sigma_of_second_differences(d2: &[f64]) -> f64 {
    if d2.len() < MIN_SECOND_DIFFERENCES {
        return f64::NAN;
    }
    let med = median(&mut d2.to_vec());
    let mut dev: Vec<f64> = d2.iter().map(|v| (v - med).abs()).collect();
    MAD_TO_SIGMA * median(&mut dev) / 6f64.sqrt()
}

//! Quantiles of the distributions the intervals and tests use.

/// The 97.5 % quantile of the standard normal distribution.
pub(crate) const Z975: f64 = 1.959_963_985;

/// The 97.5 % quantile of Student's t with `dof` degrees of freedom (exact to 3
/// decimals below 6, a Cornish-Fisher expansion beyond).
pub(crate) fn t975(dof: usize) -> f64 {
    const SMALL: [f64; 5] = [12.706, 4.303, 3.182, 2.776, 2.571];
    const Z: f64 = Z975;
    match dof {
        0 => f64::INFINITY,
        1..=5 => SMALL[dof - 1],
        _ => {
            let v = dof as f64;
            let z2 = Z * Z;
            Z + (z2 * Z + Z) / (4.0 * v)
                + (5.0 * z2 * z2 * Z + 16.0 * z2 * Z + 3.0 * Z) / (96.0 * v * v)
                + (3.0 * z2 * z2 * z2 * Z + 19.0 * z2 * z2 * Z + 17.0 * z2 * Z - 15.0 * Z)
                    / (384.0 * v * v * v)
        }
    }
}

/// The 95 % quantile of the chi-square distribution with `k` degrees of freedom (table
/// below 11, the Wilson-Hilferty approximation beyond: within 0.5 % there).
pub(crate) fn chi2_95(k: usize) -> f64 {
    const SMALL: [f64; 10] = [
        3.841, 5.991, 7.815, 9.488, 11.070, 12.592, 14.067, 15.507, 16.919, 18.307,
    ];
    const Z95: f64 = 1.644_853_627;
    match k {
        0 => 0.0,
        1..=10 => SMALL[k - 1],
        _ => {
            let v = k as f64;
            let a = 2.0 / (9.0 * v);
            v * (1.0 - a + Z95 * a.sqrt()).powi(3)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_square_quantile_matches_tables() {
        // 95 %: 1 -> 3.841, 12 -> 21.026, 30 -> 43.773 (Wilson-Hilferty beyond 10)
        for (k, want) in [(1, 3.841), (12, 21.026), (30, 43.773)] {
            assert!(
                (chi2_95(k) / want - 1.0).abs() < 5e-3,
                "{k}: {}",
                chi2_95(k)
            );
        }
    }

    #[test]
    fn t_quantile_matches_tables() {
        // Student's t, 97.5 %: 10 -> 2.228, 30 -> 2.042, 120 -> 1.980
        for (dof, want) in [(3, 3.182), (10, 2.228), (30, 2.042), (120, 1.980)] {
            assert!((t975(dof) - want).abs() < 2e-3, "{dof}: {}", t975(dof));
        }
        assert!((t975(100_000) - 1.95996).abs() < 1e-4);
    }
}

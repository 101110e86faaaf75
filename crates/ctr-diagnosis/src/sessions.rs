//! Sessions that disagree: runs of one recording that measured the same commanded
//! joints at tips farther apart than the noise allows (issue 41, item 4), whatever the
//! model. A lab's sessions days apart are not always one robot (tubes relax, a tracker
//! is re-registered), and what is fitted on one session then makes another worse; the
//! report names it instead of averaging over it.
//!
//! For runs `a` and `b` and each commanded joint vector both ran (bit for bit: a pose
//! list run again, a cycle repeated), `d = mean_b(p) - mean_a(p)`, the means over the
//! rows of each run at those joints. Under noise alone `E |d|^2 = 3 sigma^2 (1/n_a +
//! 1/n_b)` (`sigma` the noise per axis). The runs disagree when at least
//! [`MIN_SHARED`] configurations are shared and `RMS |d|` exceeds
//! [`DISAGREE_SIGMAS`] times its noise-alone value. Nothing is said where the noise is
//! unknown. (A per-session refit of the parameters is not made yet.)

use crate::report::{Noise, SessionChange};
use ctr_formats::Recording;
use std::collections::HashMap;

/// Fewest configurations two runs must share to be compared.
pub const MIN_SHARED: usize = 3;
/// Runs disagree when their tips at shared joints differ by more than this many times
/// what the noise alone would give (RMS).
pub const DISAGREE_SIGMAS: f64 = 3.0;

/// A run's commanded joint vectors (their bits) with the mean measured tip there and
/// the rows it averages.
type Configurations = HashMap<Vec<u64>, ([f64; 3], usize)>;

/// The pairs of runs of `rec` that disagree at the joints both commanded, the noise
/// being `noise` (none where it is unknown).
pub(crate) fn disagreeing(rec: &Recording, noise: &Noise) -> Vec<SessionChange> {
    let sigma = noise.sigma_mm_per_axis;
    if !(sigma.is_finite() && sigma > 0.0) || rec.runs.len() < 2 {
        return Vec::new();
    }
    // each run's configurations: the mean measured tip and the rows it averages
    let means: Vec<Configurations> = rec
        .runs
        .iter()
        .map(|run| {
            let mut m = Configurations::new();
            for r in run.rows.clone() {
                let row = &rec.rows[r];
                let key = row.q.iter().map(|v| v.to_bits()).collect();
                let (sum, n) = m.entry(key).or_insert(([0.0; 3], 0));
                (0..3).for_each(|a| sum[a] += row.p[a]);
                *n += 1;
            }
            m.values_mut()
                .for_each(|(s, n)| s.iter_mut().for_each(|v| *v /= *n as f64));
            m
        })
        .collect();
    let mut out = Vec::new();
    for a in 0..rec.runs.len() {
        for b in a + 1..rec.runs.len() {
            let (mut d2, mut expected, mut shared) = (0.0, 0.0, 0usize);
            for (q, (pa, na)) in &means[a] {
                let Some((pb, nb)) = means[b].get(q) else {
                    continue;
                };
                d2 += (0..3).map(|k| (pb[k] - pa[k]).powi(2)).sum::<f64>();
                expected += 3.0 * sigma * sigma * (1.0 / *na as f64 + 1.0 / *nb as f64);
                shared += 1;
            }
            if shared < MIN_SHARED {
                continue;
            }
            let rms_mm = (d2 / shared as f64).sqrt();
            let noise_rms_mm = (expected / shared as f64).sqrt();
            if rms_mm > DISAGREE_SIGMAS * noise_rms_mm {
                let (la, lb) = (&rec.runs[a].label, &rec.runs[b].label);
                out.push(SessionChange {
                    runs: [la.clone(), lb.clone()],
                    configurations: shared,
                    rms_mm,
                    noise_rms_mm,
                    statement: format!(
                        "the robot or its tracker changed between runs {la} and {lb}: at the \
                         {shared} configurations both commanded, the measured tips differ by \
                         {rms_mm:.3} mm RMS where the noise alone gives {noise_rms_mm:.3} mm; \
                         one model fitted to both averages over the change"
                    ),
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(sigma: f64) -> Noise {
        Noise {
            sigma_mm_per_axis: sigma,
            rms_mm: 3f64.sqrt() * sigma,
            weighted_rms: 3f64.sqrt() * sigma,
            method: String::new(),
            angular: None,
        }
    }

    #[test]
    fn the_same_joints_measured_apart_are_named_and_within_noise_are_not() {
        let mut csv = String::from("run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n");
        for (run, shift) in [("day1", 0.0), ("day2", 0.0), ("day3", 2.0)] {
            for k in 0..5 {
                let z = 10.0 + k as f64;
                csv += &format!("{run},{z},{},{shift},0,{z}\n", 10 * k);
            }
        }
        let rec = Recording::read(csv.as_bytes(), "s.csv", 1).unwrap();
        let found = disagreeing(&rec, &noise(0.1));
        let pairs: Vec<[String; 2]> = found.iter().map(|c| c.runs.clone()).collect();
        let day = |a: &str, b: &str| [a.to_owned(), b.to_owned()];
        assert_eq!(pairs, [day("day1", "day3"), day("day2", "day3")]);
        assert!((found[0].rms_mm - 2.0).abs() < 1e-12);
        assert!(disagreeing(&rec, &noise(f64::NAN)).is_empty());
    }
}

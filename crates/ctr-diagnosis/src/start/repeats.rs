//! The noise of a static configuration set (`ctr_formats::poses`), from its repeats.
//!
//! Neighbouring rows of a static set are unrelated configurations: their second
//! differences measure the model's error between poses, not the tracker. What measures
//! the tracker is a configuration measured more than once:
//! - **frames kept whole** (rows of one `pose`): the tracker's scatter about the pose;
//! - else **the same joints commanded again within a run** (a pose visited again);
//! - else **averaged frames** (`n_frames,spread_mm`): each row's spread says its frames'
//!   scatter, and the mean of `n` frames scatters `sqrt(n)` times less.
//!
//! For a group of `n` rows of one configuration, `sqrt(n / (n - 1)) (x_i - mean)` has
//! the noise's variance per component; the standard deviation is
//! [`MAD_TO_SIGMA`] x the median of their absolute values (a glitched frame moves it
//! little). Averaged frames pool `spread^2 / 3` over their `n - 1` degrees of freedom,
//! and a row's noise is the frame's over `sqrt(n)` (`n` the rows' harmonic mean). Where
//! nothing repeats the noise is unknown: NaN, and the verdict says it cannot tell.

use crate::robust::{median, MAD_TO_SIGMA};
use ctr_formats::Recording;
use std::collections::HashMap;

/// Fewest deviations (components) a noise estimate from repeats is made from.
const MIN_DEVIATIONS: usize = 9;

/// Where a static set's noise comes from.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Repeats {
    /// Groups of rows measuring one configuration (a pose's frames, or the same joints
    /// commanded again within a run), each of at least two rows.
    Groups {
        /// the groups' rows
        groups: Vec<Vec<usize>>,
        /// whether they are poses' frames (else joints commanded again)
        frames: bool,
    },
    /// Rows that average frames (`n_frames,spread_mm`), some of more than one.
    Averaged,
    /// Nothing repeats.
    Nothing,
}

impl Repeats {
    /// What repeats in `rec` (a static set).
    pub(crate) fn of(rec: &Recording) -> Self {
        let frames: Vec<Vec<usize>> = rec
            .poses
            .iter()
            .flatten()
            .filter(|p| p.rows.len() >= 2)
            .map(|p| p.rows.clone().collect())
            .collect();
        if !frames.is_empty() {
            return Repeats::Groups {
                groups: frames,
                frames: true,
            };
        }
        let mut again = Vec::new();
        for run in &rec.runs {
            let mut by_joints: HashMap<Vec<u64>, Vec<usize>> = HashMap::new();
            for r in run.rows.clone() {
                let key = rec.rows[r].q.iter().map(|v| v.to_bits()).collect();
                by_joints.entry(key).or_default().push(r);
            }
            let mut groups: Vec<Vec<usize>> =
                by_joints.into_values().filter(|g| g.len() >= 2).collect();
            groups.sort_unstable();
            again.extend(groups);
        }
        if !again.is_empty() {
            return Repeats::Groups {
                groups: again,
                frames: false,
            };
        }
        if rec.rows.iter().any(|r| r.frames.is_some_and(|f| f.n >= 2)) {
            Repeats::Averaged
        } else {
            Repeats::Nothing
        }
    }

    /// The noise's standard deviation per component of `value` (a row's `K`
    /// components), and in words how it was found; NaN where nothing repeats.
    pub(crate) fn sigma<const K: usize>(
        &self,
        rec: &Recording,
        value: impl Fn(usize) -> [f64; K],
    ) -> (f64, String) {
        match self {
            Repeats::Groups { groups, frames } => {
                let mut dev = Vec::new();
                for g in groups {
                    let n = g.len() as f64;
                    let v: Vec<[f64; K]> = g.iter().map(|&r| value(r)).collect();
                    for a in 0..K {
                        let mean = v.iter().map(|x| x[a]).sum::<f64>() / n;
                        let scale = (n / (n - 1.0)).sqrt();
                        dev.extend(
                            v.iter()
                                .map(|x| scale * (x[a] - mean))
                                .filter(|d| d.is_finite())
                                .map(f64::abs),
                        );
                    }
                }
                let sigma = if dev.len() < MIN_DEVIATIONS {
                    f64::NAN
                } else {
                    MAD_TO_SIGMA * median(&mut dev)
                };
                let rows: usize = groups.iter().map(Vec::len).sum();
                let what = if *frames {
                    "the frames of each pose"
                } else {
                    "rows commanding the same joints again within a run"
                };
                (
                    sigma,
                    format!(
                        "from repeats: median absolute deviation of {what} about their mean \
                         ({} configurations, {rows} rows; a static set, so not from \
                         neighbouring rows, which are other configurations)",
                        groups.len()
                    ),
                )
            }
            Repeats::Averaged => {
                let (mut pooled, mut dof, mut inverse_n, mut rows) = (0.0, 0.0, 0.0, 0.0);
                for f in rec.rows.iter().filter_map(|r| r.frames) {
                    let n = f64::from(f.n);
                    pooled += (n - 1.0) * f.spread_mm * f.spread_mm / 3.0;
                    dof += n - 1.0;
                    inverse_n += 1.0 / n;
                    rows += 1.0;
                }
                let frame = (pooled / dof).sqrt();
                (
                    frame * (inverse_n / rows).sqrt(),
                    format!(
                        "from the averaged frames: each row's spread_mm over its n_frames \
                         pooled ({frame:.4} mm per axis per frame), over sqrt(n) for a row's \
                         mean of n frames ({rows} rows)"
                    ),
                )
            }
            Repeats::Nothing => (
                f64::NAN,
                "unknown: a static set in which nothing repeats (no pose's frames kept whole, \
                 no joints commanded again within a run, no n_frames,spread_mm): neighbouring \
                 rows are other configurations, and their differences would measure the \
                 model's error, not the tracker"
                    .into(),
            ),
        }
    }
}

/// The noise per axis of a static set's positions `e` (one row each; the rows of one
/// configuration share their model error, so their spread is the tracker's), and how it
/// was found.
pub(crate) fn position_sigma(rec: &Recording, e: &[[f64; 3]]) -> (f64, String) {
    let repeats = Repeats::of(rec);
    match repeats {
        Repeats::Averaged => repeats.sigma(rec, |r| rec.rows[r].p),
        _ => repeats.sigma(rec, |r| e[r]),
    }
}

/// The configuration each row of a static set belongs to, for the outlier rule: the
/// other rows of its group ([`Repeats::of`]), none for a row measured once.
pub(crate) fn companions(rec: &Recording) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new(); rec.rows.len()];
    if let Repeats::Groups { groups, .. } = Repeats::of(rec) {
        for g in groups {
            for &r in &g {
                out[r] = g.iter().copied().filter(|&k| k != r).collect();
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(csv: &str) -> Recording {
        Recording::read(csv.as_bytes(), "set.csv", 1).unwrap()
    }

    #[test]
    fn frames_kept_whole_give_their_scatter() {
        // 6 poses of 4 frames, scatter +-0.1 mm on each axis in turn
        let mut csv = String::from("pose,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n");
        for p in 0..6 {
            for f in 0..4 {
                let d = if f % 2 == 0 { 0.1 } else { -0.1 };
                let z = 10.0 * p as f64;
                csv += &format!("p{p},{z},0,{d},{},{}\n", -d, z + d);
            }
        }
        let rec = read(&csv);
        let e: Vec<[f64; 3]> = rec.rows.iter().map(|r| r.p).collect();
        let (sigma, how) = position_sigma(&rec, &e);
        // deviations +-0.1, scaled by sqrt(4/3)
        let want = MAD_TO_SIGMA * 0.1 * (4.0f64 / 3.0).sqrt();
        assert!((sigma - want).abs() < 1e-12, "{sigma} {how}");
        assert!(how.contains("frames of each pose"), "{how}");
    }

    #[test]
    fn nothing_repeated_is_unknown_and_averages_are_pooled() {
        let rec =
            read("pose,s1_mm,theta1_deg,x_mm,y_mm,z_mm\na,1,0,0,0,1\nb,2,0,0,0,2\nc,3,0,0,0,3\n");
        let e: Vec<[f64; 3]> = rec.rows.iter().map(|r| r.p).collect();
        let (sigma, how) = position_sigma(&rec, &e);
        assert!(
            sigma.is_nan() && how.starts_with("unknown"),
            "{sigma} {how}"
        );
        // two rows of 5 frames, spread sqrt(3) * 0.2 mm: 0.2 mm per axis per frame
        let spread = 3f64.sqrt() * 0.2;
        let rec = read(&format!(
            "s1_mm,theta1_deg,x_mm,y_mm,z_mm,n_frames,spread_mm\n1,0,0,0,1,5,{spread}\n2,0,0,0,2,5,{spread}\n"
        ));
        assert!(rec.is_static());
        let (sigma, _) = position_sigma(&rec, &e[..2]);
        assert!((sigma - 0.2 / 5f64.sqrt()).abs() < 1e-12, "{sigma}");
    }
}

//! The noise estimated from the data (not from the model) and the tracker outliers it
//! sets apart.

use crate::report::{AngularNoise, Noise};
use crate::residual::{components, RowError, WIDTH};
pub(crate) use crate::robust::median;
use crate::robust::{sigma_of_second_differences, MAD_TO_SIGMA};
use crate::start::repeats;
use ctr_formats::{AngularColumns, Recording};

/// What is left counts as noise when its RMS is at most this many times the noise
/// estimate's.
pub const NOISE_TOLERANCE: f64 = 1.15;
/// A row whose final error lies more than this many robust standard deviations (per
/// axis, of the final residual itself) from the residual's median is a tracker outlier
/// (a 3-D Gaussian error exceeds 6 sigma once in 10^7).
pub const OUTLIER_SIGMAS: f64 = 6.0;

/// Noise per axis from the second differences of the position errors of `e` along
/// each run (of a static set, from its repeats: `crate::start::repeats`; NaN where
/// nothing repeats). Its `rms_mm` is that of a row's position: `sqrt(3) sigma`; weighted
/// angular columns have their own beside it (`angular`), and the whole row's,
/// `sqrt(3 sigma^2 + k sigma_w^2)` with `k` angular components (`sigma_w` the position
/// noise they were weighted against: `crate::start::angular`), is
/// `Noise::weighted_rms`.
pub fn estimate_noise(rec: &Recording, e: &[[f64; 3]]) -> Noise {
    let in_plane = match rec.angular_columns() {
        Some(AngularColumns::Tangent) => ", in the plane normal to the measured tangent",
        _ => "",
    };
    let (sigma, method, angular_method) = if rec.is_static() {
        let (sigma, method) = repeats::position_sigma(rec, e);
        let angular = format!(
            "{} of the user model's angular error{in_plane}",
            method.split(':').next().unwrap_or("from repeats")
        );
        (sigma, method, angular)
    } else {
        let mut d2 = Vec::new();
        for run in &rec.runs {
            for k in run.rows.start + 1..run.rows.end.saturating_sub(1) {
                for a in 0..3 {
                    d2.push(e[k - 1][a] - 2.0 * e[k][a] + e[k + 1][a]);
                }
            }
        }
        let triples = d2.len() / 3;
        (
            sigma_of_second_differences(&d2),
            format!(
                "median absolute deviation of the residual's second differences along the \
                 runs ({triples} triples of rows)"
            ),
            format!(
                "median absolute deviation of the user model's angular error's second \
                 differences along the runs ({triples} triples of rows{in_plane})"
            ),
        )
    };
    let rms_mm = 3f64.sqrt() * sigma;
    let weighted_rms = match rec.angular {
        None => rms_mm,
        Some(w) => {
            (3.0 * sigma * sigma + (components(rec) - 3) as f64 * w.sigma_mm * w.sigma_mm).sqrt()
        }
    };
    Noise {
        sigma_mm_per_axis: sigma,
        rms_mm,
        weighted_rms,
        method,
        angular: angular_report(rec, &angular_method),
    }
}

/// The tracker outliers of a final residual `e` (rows of `rec`, angular parts
/// included): the rows farther than [`OUTLIER_SIGMAS`] robust standard deviations both from the residual's median and
/// from the median of their neighbours in the run ([`NEIGHBOURS`] on each side). The
/// deviation is taken per axis from the residual's own median absolute deviation, not
/// from the noise estimate; and a row that moves with its neighbours is structure that
/// is left, not a tracker's jump. The rows, ascending, and the threshold, mm (infinite
/// when the spread cannot be estimated).
pub(crate) fn outlier_rows(rec: &Recording, e: &[RowError]) -> (Vec<usize>, f64) {
    if e.len() < MIN_ROWS_FOR_OUTLIERS {
        return (Vec::new(), f64::INFINITY);
    }
    // the spread per independent component (an unweighted angular part is all zeros)
    let dof = components(rec) as f64;
    let mut centre = [0.0; WIDTH];
    let mut var = 0.0;
    for a in 0..WIDTH {
        let mut v: Vec<f64> = e.iter().map(|r| r[a]).collect();
        centre[a] = median(&mut v);
        let mut dev: Vec<f64> = v.iter().map(|x| (x - centre[a]).abs()).collect();
        var += (MAD_TO_SIGMA * median(&mut dev)).powi(2) / dof;
    }
    let limit = OUTLIER_SIGMAS * var.sqrt();
    if limit.is_nan() || limit <= 0.0 {
        return (Vec::new(), f64::INFINITY);
    }
    let dist = |v: &RowError, c: &RowError| -> f64 {
        (0..WIDTH)
            .map(|a| (v[a] - c[a]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    // a static set's neighbouring rows are other configurations: a row is compared with
    // the other rows of its own (`repeats::companions`), if it has any
    let companions = rec.is_static().then(|| repeats::companions(rec));
    let mut rows = Vec::new();
    for run in &rec.runs {
        for r in run.rows.clone() {
            if dist(&e[r], &centre) <= limit {
                continue;
            }
            let lo = r.saturating_sub(NEIGHBOURS).max(run.rows.start);
            let hi = (r + NEIGHBOURS + 1).min(run.rows.end);
            let near: Vec<usize> = match &companions {
                Some(c) => c[r].clone(),
                None => (lo..hi).filter(|&k| k != r).collect(),
            };
            let local = if near.is_empty() {
                centre
            } else {
                std::array::from_fn(|a| {
                    median(&mut near.iter().map(|&k| e[k][a]).collect::<Vec<_>>())
                })
            };
            if dist(&e[r], &local) > limit {
                rows.push(r);
            }
        }
    }
    rows.sort_unstable();
    (rows, limit)
}

/// Neighbours on each side of a row that its error is compared with.
pub const NEIGHBOURS: usize = 2;

/// Fewest rows for a robust spread.
const MIN_ROWS_FOR_OUTLIERS: usize = 9;

/// The outlier rule in words, for the report on `rec`.
pub(crate) fn outlier_rule(rec: &Recording) -> String {
    let near = if rec.is_static() {
        "the other rows measuring its configuration (a static set's neighbouring rows are \
         other configurations; a configuration measured once: the residual's median alone)"
            .to_owned()
    } else {
        format!("its {NEIGHBOURS} neighbours on each side in its run")
    };
    format!(
        "a row is a tracker outlier when its final error (after the physics and the empirical \
         term) lies more than {OUTLIER_SIGMAS} robust standard deviations (per axis, \
         {MAD_TO_SIGMA} x the median absolute deviation of that residual) both from the \
         residual's median and from the median of {near}"
    )
}

/// The report's account of the angular columns of `rec` (`how`: how their noise was
/// estimated); `None` when it has none.
fn angular_report(rec: &Recording, how: &str) -> Option<AngularNoise> {
    let columns = rec.angular_columns()?;
    Some(match rec.angular {
        Some(w) => AngularNoise {
            columns: columns.names().into(),
            components: columns.components(),
            sigma_deg: w.sigma_rad.to_degrees(),
            rms_deg: (columns.components() as f64).sqrt() * w.sigma_rad.to_degrees(),
            mm_per_deg: w.mm_per_rad().to_radians(),
            method: format!(
                "{how}; each angular \
                 component enters the residual as mm_per_deg x its error in degrees (the \
                 position noise over the angular noise): the fits weigh positions and angles \
                 whitened alike, and the report's figures keep them apart (mm of tip \
                 position, degrees of tip angle)"
            ),
        },
        None => AngularNoise {
            columns: columns.names().into(),
            components: 0,
            sigma_deg: f64::NAN,
            rms_deg: f64::NAN,
            mm_per_deg: 0.0,
            method: "not used: their noise (or the positions') cannot be estimated from the \
                     data (too few rows along the runs, or none at all; of a static set, \
                     nothing repeats)"
                .into(),
        },
    })
}

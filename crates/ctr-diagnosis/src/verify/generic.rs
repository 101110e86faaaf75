//! Check 1 of a finding: it beats a generic correction of its size (see the module
//! docs of [`crate::verify`]).

use super::{Context, Failure, ModelFrame, MIN_GAIN_OVER_EMPIRICAL};
use crate::candidates::EffectId;
use crate::empirical::hybrid;
use crate::empirical::{self, Field};
use crate::paired::clearly_lower;
use crate::report::Figures;
use crate::residual::{positions, with_angles, RowError};
use crate::start::noise::NOISE_TOLERANCE;
use ctr_analysis::model::ModelSpec;
use nalgebra::{DMatrix, DVector};

impl Context<'_> {
    /// Check 1: the figures of the generic correction in `c`'s place (`e_without`:
    /// `m`'s errors with `c` taken out), and the failure when it does as well as `c`
    /// (`e`: `m`'s errors; `at_noise`: `m` leaves only noise on the held-out rows);
    /// the errors in `m`'s W (`frame`); `directions`: `c`'s tip directions
    /// ([`Context::directions`]), `None` where they cannot be had.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn against_generic(
        &self,
        m: &ModelSpec,
        frame: &ModelFrame,
        directions: Option<&[Field]>,
        e: &[RowError],
        e_without: &[RowError],
        c: EffectId,
        at_noise: bool,
    ) -> (Figures, Option<Failure>) {
        let k = c.n_params(m.robot.n_tubes());
        let h = self.figures(e).heldout_score();
        // the yardstick is generic in the joints and time and, always, linear in the
        // modelled tip position (the stretches and shears a tracker's scale or
        // calibration error makes, which no effect of the vocabulary is and many can
        // mimic: a precurvature, a clearance, a sensor offset along the tip), unless
        // `c`'s own form is such a map (a registration): it is not measured against
        // itself
        let tip = directions.is_some_and(|d| !affine_in_tip(d, &frame.tips(self.rec, e)));
        let fields = |err: &[RowError]| -> Vec<Field> {
            let mut fields = self.yardstick.clone();
            if tip {
                fields.extend(non_rigid(&frame.tips(self.rec, err), &self.fit));
            }
            fields
        };
        // both sides get the generic term that what `M` leaves asks for (size by
        // cross-validation), the side without `c` k terms more: `c` must explain
        // something a generic term cannot, not just something else that is left
        let with_fields = fields(e);
        let size = if at_noise {
            0
        } else {
            self.generic_size(&with_fields, e)
        };
        let h_with = if size == 0 {
            h
        } else {
            self.figures(&self.generic_left(&with_fields, e, size))
                .heldout_score()
        };
        let left_emp = self.generic_left(&fields(e_without), e_without, size + k);
        let fig_emp = self.figures(&left_emp);
        let h_emp = fig_emp.heldout_score();
        // where the generic correction too leaves only noise, both explain the data and
        // clearly also means beyond chance
        let both_at_noise = h_emp <= NOISE_TOLERANCE * self.noise_rms;
        let beaten = h_with >= (1.0 - MIN_GAIN_OVER_EMPIRICAL) * h_emp
            || (tip && both_at_noise && !clearly_lower(e, &left_emp, self.held));
        let failure = (self.checks.beats_generic && (!at_noise || tip) && beaten)
            .then_some(Failure::Empirical { fig: fig_emp, tip });
        (fig_emp, failure)
    }

    /// What `e` leaves after the best `k` terms of `fields` fitted to its positions on
    /// the fit rows, every row (the angular errors stay).
    fn generic_left(&self, fields: &[Field], e_row: &[RowError], k: usize) -> Vec<RowError> {
        let e = &positions(e_row);
        let w = empirical::weights(e, &self.fit, self.huber_mm);
        let terms = empirical::pursue(fields, e, &w, k);
        with_angles(&empirical::subtract(fields, &terms, e), e_row)
    }

    /// The size of the generic correction (of `fields`) that cross-validation on the
    /// fit rows gives `e`: what is left that a generic term takes, whatever it is.
    fn generic_size(&self, fields: &[Field], e_row: &[RowError]) -> usize {
        let e = &positions(e_row);
        let w = empirical::weights(e, &self.fit, self.huber_mm);
        hybrid::choose_size(fields, e, &w, self.threads)
    }
}

/// The linear maps of the tip position `p` that no rigid motion makes, as fields over
/// the rows (each coordinate centred and scaled on the `fit` rows, `u`): the three
/// stretches along an axis (`u_a` on axis `a`), the same stretch on every axis (a
/// tracker's scale: one term, where the three stretches would take three) and the three
/// symmetric shears (`u_b` on `a` and `u_a` on `b`). A tracker's scale or calibration
/// error is a sum of them; a
/// rotation (antisymmetric) or a translation, a registration's, is not: that belongs to
/// the vocabulary.
fn non_rigid(p: &[[f64; 3]], fit: &[bool]) -> Vec<Field> {
    let n = fit.iter().filter(|f| **f).count().max(1) as f64;
    let (u, spread): (Vec<[f64; 3]>, [f64; 3]) = {
        let mut centre = [0.0; 3];
        let mut spread = [0.0; 3];
        for a in 0..3 {
            centre[a] = p
                .iter()
                .zip(fit)
                .filter(|(_, f)| **f)
                .map(|(v, _)| v[a])
                .sum::<f64>()
                / n;
            let var = p
                .iter()
                .zip(fit)
                .filter(|(_, f)| **f)
                .map(|(v, _)| (v[a] - centre[a]).powi(2))
                .sum::<f64>()
                / n;
            spread[a] = if var > 0.0 { var.sqrt() } else { 1.0 };
        }
        let u = p
            .iter()
            .map(|v| [0, 1, 2].map(|a| (v[a] - centre[a]) / spread[a]))
            .collect();
        (u, spread)
    };
    let mut fields: Vec<Field> = (0..3)
        .map(|a| {
            u.iter()
                .map(|v| {
                    let mut f = [0.0; 3];
                    f[a] = v[a];
                    f
                })
                .collect()
        })
        .collect();
    // the same stretch on every axis (a tracker's scale, one number) as one field:
    // the centred tip position over its RMS spread
    let overall = (spread.iter().map(|s| s * s).sum::<f64>() / 3.0).sqrt();
    fields.push(
        u.iter()
            .map(|v| [0, 1, 2].map(|a| v[a] * spread[a] / overall))
            .collect(),
    );
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        fields.push(
            u.iter()
                .map(|v| {
                    let mut f = [0.0; 3];
                    f[a] = v[b];
                    f[b] = v[a];
                    f
                })
                .collect(),
        );
    }
    fields
}

/// Share of a parameter direction's squared size an affine map of the tip position
/// may leave for the effect to count as itself such a map.
const AFFINE_LEFT: f64 = 1e-2;

/// Whether every parameter direction `J_c,j` of an effect (over the rows, modelled tips
/// `tips`) is, axis by axis, an affine function of the tip position to within
/// [`AFFINE_LEFT`] of its squared size: a registration's are (a translation and a
/// rotation of the tip positions), a sensor offset's, which turn with the tip, are not.
/// Directions that move no tip count as affine.
fn affine_in_tip(directions: &[Field], tips: &[[f64; 3]]) -> bool {
    let rows = tips.len();
    let a = DMatrix::from_fn(rows, 4, |r, j| if j == 0 { 1.0 } else { tips[r][j - 1] });
    let svd = a.clone().svd(true, true);
    directions.iter().all(|d| {
        let (mut total, mut left) = (0.0, 0.0);
        for axis in 0..3 {
            let b = DVector::from_fn(rows, |r, _| d[r][axis]);
            let Ok(coef) = svd.solve(&b, 1e-12) else {
                return false;
            };
            let res = &b - &a * coef;
            total += b.norm_squared();
            left += res.norm_squared();
        }
        left <= AFFINE_LEFT * total
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tips spread over a box, as a workspace's.
    fn box_tips() -> Vec<[f64; 3]> {
        (0..200)
            .map(|i| {
                let f = f64::from(i);
                [
                    20.0 * (0.37 * f).sin(),
                    15.0 * (0.23 * f).cos(),
                    100.0 + 30.0 * (0.11 * f).sin(),
                ]
            })
            .collect()
    }

    /// Squared error left by the best `k` of `fields` fitted to `e`, as a share.
    fn left_share(fields: &[Field], e: &[[f64; 3]], k: usize) -> f64 {
        let w = vec![1.0; e.len()];
        let terms = empirical::pursue(fields, e, &w, k);
        let left = empirical::subtract(fields, &terms, e);
        let sq = |v: &[[f64; 3]]| v.iter().flatten().map(|x| x * x).sum::<f64>();
        sq(&left) / sq(e)
    }

    #[test]
    fn the_non_rigid_maps_take_a_scale_error_not_a_rotation() {
        let p = box_tips();
        let fit = vec![true; p.len()];
        let fields = non_rigid(&p, &fit);
        let mean: Vec<f64> = (0..3)
            .map(|a| p.iter().map(|v| v[a]).sum::<f64>() / p.len() as f64)
            .collect();
        // a tracker's scale error about the workspace's centre: all of it
        let scale: Vec<[f64; 3]> = p
            .iter()
            .map(|v| {
                [
                    0.01 * (v[0] - mean[0]),
                    -0.008 * (v[1] - mean[1]),
                    0.006 * (v[2] - mean[2]),
                ]
            })
            .collect();
        assert!(left_share(&fields, &scale, 3) < 1e-20);
        // the same scale on every axis (a tracker's scale about W's origin: about the
        // centre, plus a translation the frame takes): one term
        let iso: Vec<[f64; 3]> = p
            .iter()
            .map(|v| [0, 1, 2].map(|a| 0.015 * (v[a] - mean[a])))
            .collect();
        assert!(left_share(&fields, &iso, 1) < 1e-20);
        // a rotation of 2 deg about z (a registration's): half of it stays, whatever
        // the terms
        let w = 2f64.to_radians();
        let rotation: Vec<[f64; 3]> = p
            .iter()
            .map(|v| [-w * (v[1] - mean[1]), w * (v[0] - mean[0]), 0.0])
            .collect();
        assert!(left_share(&fields, &rotation, 6) > 0.3);
        // a registration's directions are affine in the tip; a direction that turns with
        // a joint is not
        let translation: Vec<[f64; 3]> = p.iter().map(|_| [1.0, 0.0, 0.0]).collect();
        assert!(affine_in_tip(&[rotation.clone(), translation], &p));
        let turning: Vec<[f64; 3]> = (0..p.len())
            .map(|i| [(0.5 * i as f64).cos(), (0.5 * i as f64).sin(), 0.0])
            .collect();
        assert!(!affine_in_tip(&[rotation, turning], &p));
    }
}

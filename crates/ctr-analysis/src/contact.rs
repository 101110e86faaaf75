//! The friction a pair of tubes meets where the outer one ends, and how far it lets
//! the pair's relative rotation lag: the part of the rotation play that grows with the
//! contact moment (`friction.rotation_friction_coefficient`).
//!
//! # Physics
//!
//! Where tube `j` ends (its tip at exposed length `s_j`) the tubes that go on leave it
//! through a concentrated contact that carries tube `j`'s bending moment
//!
//! ```text
//! M_j = E I_j (u - k_j e_j),      u = sum_i E I_i k_i e_i / sum_i E I_i
//! ```
//!
//! over the tubes present just before `s_j` (the torsion-free equilibrium at the
//! actual angles: `e_i = (cos theta_i, sin theta_i)`, `k_i` tube `i`'s precurvature
//! there, zero on its straight part). Friction at the contact resists the pair's
//! relative rotation with the moment `tau_j = mu'_j |M_j|` (Liu et al. 2023, Sensors
//! 23:3709, eq. 10; `mu'` lumps the friction coefficient and the ratio of the tube's
//! radius to the contact forces' lever arm: dimensionless). Until it slips, the
//! actuators wind that moment up through both tubes, tube `j` from its actuator to its
//! tip (`L_j`) and tube `j+1` from its actuator to the contact
//! (`L_{j+1} - s_{j+1} + s_j`), so the relative rotation lags the commanded one by up to
//!
//! ```text
//! w_j = mu'_j |M_j| (L_j / G J_j + (L_{j+1} - s_{j+1} + s_j) / G J_{j+1})     (rad)
//! ```
//!
//! the play operator's half-width ([`ctr_core::friction::play`]), added to the constant
//! `rotation_play_deg`. The seed applies the moment at the boundary of the twist
//! problem ([`ctr_core::friction::BoundaryMoment`]); this is its wind-up read as a play,
//! which keeps the memory of where the pair stuck. The moment is the rigid one (the
//! tubes' twist left out), computed along the delayed commanded path.

use ctr_formats::{with_robot, AnyRobot};

/// One tube's terms of the contact moment and the wind-up.
#[derive(Clone, Copy, Debug, PartialEq)]
struct TubeTerms {
    /// Bending stiffness `E I`, N mm^2.
    bending: f64,
    /// Torsional stiffness `G J`, N mm^2.
    torsional: f64,
    /// Signed precurvature of the curved part, 1/mm.
    curvature: f64,
    /// Length from the actuator to the tip, mm.
    length_mm: f64,
    /// Length of the precurved distal part, mm.
    curved_mm: f64,
}

/// The contact friction of a robot: its tubes' terms and each pair's coefficient `mu'`
/// ([module doc](self)).
///
/// ```
/// use ctr_analysis::contact::Contact;
/// use ctr_core::TubeParams;
/// let outer = TubeParams { curvature_radius_mm: Some(200.0), ..TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33) };
/// let inner = TubeParams { curvature_radius_mm: Some(100.0), ..TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33) };
/// let contact = Contact::of(&ctr_formats::AnyRobot::new(&[outer, inner]).unwrap(), &[0.1]);
/// let mut w = [0.0];
/// contact.half_width_deg(&[40.0, 90.0], &[0.0, 0.0], &mut w);
/// let aligned = w[0];
/// contact.half_width_deg(&[40.0, 90.0], &[0.0, 180.0], &mut w);
/// assert!(w[0] > aligned && aligned > 0.0); // opposed curvatures press harder
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Contact {
    tubes: Vec<TubeTerms>,
    /// `mu'` of each neighbouring pair (missing ones zero).
    coefficient: Vec<f64>,
}

impl Contact {
    /// The contact friction of `robot`'s tubes (scaled ones: stiffness and precurvature
    /// factors applied) with coefficient `mu'` per neighbouring pair.
    pub fn of(robot: &AnyRobot, coefficient: &[f64]) -> Self {
        let tubes = with_robot!(robot, r => r
            .tubes()
            .iter()
            .map(|t| TubeTerms {
                bending: t.bending_stiffness_nmm2(),
                torsional: t.torsional_stiffness_nmm2(),
                curvature: t.curvature_per_mm(),
                length_mm: t.params().length_mm,
                curved_mm: t.params().curved_length_mm,
            })
            .collect());
        Contact {
            tubes,
            coefficient: coefficient.to_vec(),
        }
    }

    /// The half-width each pair's coefficient adds to its rotation play, degrees, into
    /// `out` (one per pair), at exposed lengths `s` (mm) and angles `theta_deg`.
    pub fn half_width_deg(&self, s: &[f64], theta_deg: &[f64], out: &mut [f64]) {
        let n = self.tubes.len().min(s.len()).min(theta_deg.len());
        for (j, w) in out.iter_mut().enumerate().take(n.saturating_sub(1)) {
            let m = self.coefficient.get(j).copied().unwrap_or(0.0);
            *w = if m > 0.0 {
                (m * self.moment(j, s, theta_deg) * self.compliance(j, s)).to_degrees()
            } else {
                0.0
            };
        }
    }

    /// `|M_j|`, N mm: the bending moment tube `j` carries just before its tip.
    fn moment(&self, j: usize, s: &[f64], theta_deg: &[f64]) -> f64 {
        let at = s[j];
        let (mut sum, mut stiffness) = ([0.0; 2], 0.0);
        let mut own = [0.0; 2];
        for (i, t) in self.tubes.iter().enumerate() {
            // present just before s_j: the tubes that reach at least as far
            if s[i] < at {
                continue;
            }
            let curved = at > s[i] - t.curved_mm;
            let k = if curved { t.curvature } else { 0.0 };
            let (sin, cos) = theta_deg[i].to_radians().sin_cos();
            let ke = [k * cos, k * sin];
            sum[0] += t.bending * ke[0];
            sum[1] += t.bending * ke[1];
            stiffness += t.bending;
            if i == j {
                own = ke;
            }
        }
        if stiffness <= 0.0 {
            return 0.0;
        }
        let d = [sum[0] / stiffness - own[0], sum[1] / stiffness - own[1]];
        self.tubes[j].bending * d[0].hypot(d[1])
    }

    /// The pair's wind-up compliance, rad per N mm: tube `j` over its length, tube
    /// `j+1` from its actuator to `s_j`.
    fn compliance(&self, j: usize, s: &[f64]) -> f64 {
        let (outer, inner) = (&self.tubes[j], &self.tubes[j + 1]);
        let inner_mm = (inner.length_mm - s[j + 1] + s[j]).max(0.0);
        outer.length_mm / outer.torsional + inner_mm / inner.torsional
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ctr_core::TubeParams;

    /// Outer and inner tube of the tests: diameters (mm) and length (mm).
    const OUTER: (f64, f64, f64) = (1.8, 1.5, 200.0);
    const INNER: (f64, f64, f64) = (1.2, 0.9, 260.0);

    /// A nitinol tube (diameters and length) with a precurved distal part of `curved_mm` at
    /// `radius_mm`.
    fn tube((od, id, length): (f64, f64, f64), radius_mm: f64, curved_mm: f64) -> TubeParams<f64> {
        TubeParams {
            curvature_radius_mm: Some(radius_mm),
            ..TubeParams::new(od, id, length, curved_mm, 60000.0, 0.3)
        }
    }

    /// Two fully overlapped tubes of curvature `k`, anti-aligned: `u` is the
    /// stiffness-weighted difference, so `|M_1| = 2 E I_1 E I_2 k / (E I_1 + E I_2)`;
    /// aligned, `u = k e`: no moment. The half-width is `mu |M_1|` times
    /// `L_1 / G J_1 + (L_2 - s_2 + s_1) / G J_2`.
    #[test]
    fn the_moment_and_wind_up_of_two_tubes() {
        let (outer, inner) = (tube(OUTER, 100.0, 150.0), tube(INNER, 100.0, 150.0));
        let robot = AnyRobot::new(&[outer, inner]).unwrap();
        let mu = 0.05;
        let contact = Contact::of(&robot, &[mu]);
        let (o, i) = (outer.validate(1).unwrap(), inner.validate(2).unwrap());
        let (ei1, ei2) = (o.bending_stiffness_nmm2(), i.bending_stiffness_nmm2());
        let (gj1, gj2) = (o.torsional_stiffness_nmm2(), i.torsional_stiffness_nmm2());
        let moment = 2.0 * ei1 * ei2 / 100.0 / (ei1 + ei2);
        let mut w = [0.0];
        let want = |inner_mm: f64| (mu * moment * (200.0 / gj1 + inner_mm / gj2)).to_degrees();
        contact.half_width_deg(&[100.0, 100.0], &[10.0, 190.0], &mut w);
        assert!(
            (w[0] - want(260.0)).abs() < 1e-9 * w[0],
            "{} vs {}",
            w[0],
            want(260.0)
        );
        contact.half_width_deg(&[100.0, 100.0], &[10.0, 10.0], &mut w);
        assert!(w[0].abs() < 1e-12, "{}", w[0]);
        // the inner tube out by 30 mm: its actuator 30 mm nearer the contact
        contact.half_width_deg(&[100.0, 130.0], &[10.0, 190.0], &mut w);
        assert!(
            (w[0] - want(230.0)).abs() < 1e-9 * w[0],
            "{} vs {}",
            w[0],
            want(230.0)
        );
        // zero coefficient: nothing
        Contact::of(&robot, &[0.0]).half_width_deg(&[100.0, 130.0], &[10.0, 190.0], &mut w);
        assert_eq!(w[0], 0.0);
    }

    /// Along a run, a pair turned one way lags its command by the constant play plus
    /// what the contact moment winds up at the row's joints; turned back, it holds
    /// until the lag has flipped (the play operator with that half-width).
    #[test]
    fn a_run_lags_by_the_play_plus_the_wound_up_moment() {
        use crate::timeline::{actual_joints_flat, TimeEffects};
        let robot = AnyRobot::new(&[tube(OUTER, 150.0, 150.0), tube(INNER, 80.0, 100.0)]).unwrap();
        let effects = ctr_formats::Effects {
            friction: Some(ctr_formats::Friction {
                rotation_play_deg: vec![1.5],
                rotation_friction_coefficient: vec![0.02],
                ..Default::default()
            }),
            ..Default::default()
        };
        let time = TimeEffects::of(&effects, &robot);
        // theta2 from 0 to 120 deg and back to 60, one degree a row
        let path: Vec<f64> = (0..=120).chain((60..120).rev()).map(f64::from).collect();
        let q: Vec<f64> = path.iter().flat_map(|&a| [40.0, 0.0, 90.0, a]).collect();
        let t: Vec<f64> = (0..path.len()).map(|k| k as f64).collect();
        let actual = actual_joints_flat(&t, &q, 4, &time);
        let contact = Contact::of(&robot, &[0.02]);
        let lag_at = |a: f64| {
            let mut w = [0.0];
            contact.half_width_deg(&[40.0, 90.0], &[0.0, a], &mut w);
            1.5 + w[0]
        };
        let top = 120;
        let lag = lag_at(120.0);
        assert!(lag > 3.0, "the moment adds a few degrees here: {lag}");
        assert!((actual[4 * top + 3] - (120.0 - lag)).abs() < 1e-9);
        // one degree back: still inside the play, the pair holds
        assert_eq!(actual[4 * (top + 1) + 3], actual[4 * top + 3]);
        // at 60 deg on the way back it leads by that row's half-width
        let last = path.len() - 1;
        assert!((actual[4 * last + 3] - (60.0 + lag_at(60.0))).abs() < 1e-9);
    }
}

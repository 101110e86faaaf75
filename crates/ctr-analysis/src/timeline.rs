//! Effects that need a run's time series: `latency`, and how it composes with the joint
//! offsets and the play-operator friction of [`ctr_core::friction`].
//!
//! Conventions (those of the recordings in `tests/data/shared/recordings`):
//!
//! 1. `joint_offset`: actual = commanded + offset.
//! 2. `latency` (`tau_s`, > 0 a lag): the joints at a row's time `t` are the commanded
//!    ones at `t - tau`, linear in time between the run's commanded samples; the first
//!    command holds before the run's first sample, the last after its last.
//! 3. `friction` acts on that continuous delayed path. The play operator only needs a
//!    piecewise-linear input's corners, so the corners that fall between two rows (the
//!    commanded samples, shifted to `t_j + tau`) enter it in order before the row's own
//!    value. Its memory starts centred at the run's first command.
//!
//! Joints here are in file order and units (`s1_mm, theta1_deg, ...`). A rotation
//! play's half-width is the constant `rotation_play_deg` plus what the contact moment
//! winds up at the row's delayed joints ([`crate::contact`]).

use crate::contact::Contact;
use ctr_formats::AnyRobot;

/// Time-dependent effect parameters for one robot (file units).
///
/// ```
/// let e = ctr_analysis::timeline::TimeEffects::none(2);
/// assert_eq!(e.latency_s, 0.0);
/// assert_eq!(e.rotation_play_deg.len(), 1);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct TimeEffects {
    /// Added to the commanded joints, file order (mm, degrees).
    pub joint_offset: Vec<f64>,
    /// Delay of the actual joints behind the commands, s (negative: a lead).
    pub latency_s: f64,
    /// Half-width of the rotation play of each neighbouring pair, degrees.
    pub rotation_play_deg: Vec<f64>,
    /// Half-width of the feed play of each tube, mm.
    pub feed_play_mm: Vec<f64>,
    /// The seed's contact friction: each pair's rotation play grows by what the contact
    /// moment winds up ([`crate::contact`]; `None`: no coefficient).
    pub contact: Option<Contact>,
}

impl TimeEffects {
    /// The effects of a robot file's `[model.effects]` that act along a run's time
    /// series, for `robot` (the scaled tubes: the contact friction's moments use them).
    ///
    /// ```
    /// use ctr_formats::{AnyRobot, Effects, Latency};
    /// let t = ctr_core::TubeParams::<f64>::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33);
    /// let robot = AnyRobot::new(&[t]).unwrap();
    /// let e = Effects { latency: Some(Latency { tau_s: 0.2 }), ..Default::default() };
    /// assert_eq!(ctr_analysis::timeline::TimeEffects::of(&e, &robot).latency_s, 0.2);
    /// ```
    pub fn of(effects: &ctr_formats::Effects, robot: &AnyRobot) -> Self {
        let n = robot.n_tubes();
        let mut t = TimeEffects::none(n);
        if let Some(o) = &effects.joint_offset {
            for i in 0..n {
                t.joint_offset[2 * i] = o.feed_mm.get(i).copied().unwrap_or(0.0);
                t.joint_offset[2 * i + 1] = o.rotation_deg.get(i).copied().unwrap_or(0.0);
            }
        }
        if let Some(l) = effects.latency {
            t.latency_s = l.tau_s;
        }
        if let Some(f) = &effects.friction {
            for (i, w) in f
                .rotation_play_deg
                .iter()
                .enumerate()
                .take(t.rotation_play_deg.len())
            {
                t.rotation_play_deg[i] = *w;
            }
            for (i, w) in f.feed_play_mm.iter().enumerate().take(n) {
                t.feed_play_mm[i] = *w;
            }
            if f.grows_with_contact() {
                t.contact = Some(Contact::of(robot, &f.rotation_friction_coefficient));
            }
        }
        t
    }

    /// No time effects for a robot of `n` tubes.
    ///
    /// ```
    /// let e = ctr_analysis::timeline::TimeEffects::none(3);
    /// assert_eq!(e.joint_offset, vec![0.0; 6]);
    /// ```
    pub fn none(n: usize) -> Self {
        TimeEffects {
            joint_offset: vec![0.0; 2 * n],
            latency_s: 0.0,
            rotation_play_deg: vec![0.0; n.saturating_sub(1)],
            feed_play_mm: vec![0.0; n],
            contact: None,
        }
    }
}

/// The commanded path of a run at time `t` (linear between samples, held at the ends);
/// `q` holds the run's rows one after another, `out.len()` values each.
fn path_at(t_s: &[f64], q: &[f64], t: f64, out: &mut [f64]) {
    let width = out.len();
    let row = |k: usize| &q[k * width..(k + 1) * width];
    let last = t_s.len() - 1;
    let k = if t <= t_s[0] {
        out.copy_from_slice(row(0));
        return;
    } else if t >= t_s[last] {
        out.copy_from_slice(row(last));
        return;
    } else {
        // first sample strictly after t
        t_s.partition_point(|&x| x <= t)
    };
    let (t0, t1) = (t_s[k - 1], t_s[k]);
    let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 1.0 };
    let (a, b) = (row(k - 1), row(k));
    for (j, o) in out.iter_mut().enumerate() {
        *o = a[j] + (b[j] - a[j]) * f;
    }
}

/// Actual joints of one run's rows (times `t_s`, ascending; commanded joints `q` in file
/// order) under offsets, latency and friction.
///
/// ```
/// use ctr_analysis::timeline::{actual_joints, TimeEffects};
/// let t = [0.0, 1.0, 2.0];
/// let q = vec![vec![10.0, 0.0, 50.0, 0.0], vec![10.0, 0.0, 50.0, 10.0], vec![10.0, 0.0, 50.0, 20.0]];
/// let mut e = TimeEffects::none(2);
/// e.latency_s = 0.5;
/// let a = actual_joints(&t, &q, &e);
/// assert_eq!(a[1][3], 5.0); // half a sample behind
/// ```
pub fn actual_joints(t_s: &[f64], q: &[Vec<f64>], effects: &TimeEffects) -> Vec<Vec<f64>> {
    let Some(width) = q.first().map(Vec::len) else {
        return Vec::new();
    };
    let flat: Vec<f64> = q.iter().flatten().copied().collect();
    actual_joints_flat(t_s, &flat, width, effects)
        .chunks(width.max(1))
        .map(<[f64]>::to_vec)
        .collect()
}

/// [`actual_joints`] on flat rows: `q` holds the run's commanded rows one after another,
/// `width` values each (`2 n`), and so does the result (one allocation per run instead
/// of one per row: a fit computes this for every prediction).
///
/// ```
/// use ctr_analysis::timeline::{actual_joints_flat, TimeEffects};
/// let q = [10.0, 0.0, 50.0, 0.0, 10.0, 0.0, 50.0, 10.0];
/// let mut e = TimeEffects::none(2);
/// e.joint_offset[3] = 1.0;
/// assert_eq!(actual_joints_flat(&[0.0, 1.0], &q, 4, &e)[7], 11.0);
/// ```
pub fn actual_joints_flat(t_s: &[f64], q: &[f64], width: usize, effects: &TimeEffects) -> Vec<f64> {
    if t_s.is_empty() || width == 0 || q.len() < t_s.len() * width {
        return Vec::new();
    }
    let n = width / 2;
    let cmd: Vec<f64> = q[..t_s.len() * width]
        .iter()
        .enumerate()
        .map(|(i, v)| v + effects.joint_offset.get(i % width).copied().unwrap_or(0.0))
        .collect();
    let tau = effects.latency_s;
    let contact = effects.contact.as_ref();
    let friction = effects.rotation_play_deg.iter().any(|&w| w > 0.0)
        || effects.feed_play_mm.iter().any(|&w| w > 0.0)
        || contact.is_some();
    let mut half_width = effects.rotation_play_deg.clone();
    let mut grown = vec![0.0; half_width.len()];
    let mut rotation = vec![0.0; n.saturating_sub(1)];
    let mut feed = vec![0.0; n];
    let (mut s, mut theta) = (vec![0.0; n], vec![0.0; n]);
    let split = |row: &[f64], s: &mut [f64], theta: &mut [f64]| {
        for i in 0..n {
            s[i] = row[2 * i];
            theta[i] = row[2 * i + 1];
        }
    };
    if friction {
        // memory centred on the first command
        split(&cmd[..width], &mut s, &mut theta);
        feed.copy_from_slice(&s);
        for i in 0..rotation.len() {
            rotation[i] = theta[i + 1] - theta[i];
        }
    }
    let mut step = |row: &[f64], out: &mut [f64]| {
        split(row, &mut s, &mut theta);
        if let Some(c) = contact {
            c.half_width_deg(&s, &theta, &mut grown);
            for ((w, play), g) in half_width
                .iter_mut()
                .zip(&effects.rotation_play_deg)
                .zip(&grown)
            {
                *w = play + g;
            }
        }
        if friction {
            ctr_core::friction::play_step(
                &mut rotation,
                &mut feed,
                &half_width,
                &effects.feed_play_mm,
                &mut s,
                &mut theta,
            );
        }
        for i in 0..n {
            out[2 * i] = s[i];
            out[2 * i + 1] = theta[i];
        }
    };
    let mut value = vec![0.0; width];
    let mut scratch = vec![0.0; width];
    let mut next_corner = 0;
    let mut out = vec![0.0; t_s.len() * width];
    for (k, &t) in t_s.iter().enumerate() {
        if friction {
            // corners of the delayed path up to this row's time, in order
            while next_corner < t_s.len() && t_s[next_corner] + tau <= t {
                step(
                    &cmd[next_corner * width..(next_corner + 1) * width],
                    &mut scratch,
                );
                next_corner += 1;
            }
        }
        path_at(t_s, &cmd, t - tau, &mut value);
        step(&value, &mut out[k * width..(k + 1) * width]);
    }
    out
}

//! Friction between tubes: hysteresis of the relative rotation (and feed).
//!
//! Friction opposes relative rotation, so what reaches the distal end of a tube lags the
//! actuator until the friction moment is overcome, and the lag changes sign with the
//! direction of motion: hysteresis. Here it is the play (backlash) operator on each
//! neighbouring pair's relative rotation, the memory-carrying form of the seed's
//! boundary friction moment (Liu et al. 2023, eq. 10: `beta'(L) = mu' |M| (1/k_2z -
//! 1/k_1z)`, sign set by the direction of relative rotation): the actual relative
//! rotation `y` follows the commanded one `x = theta_{i+1} - theta_i` only once `x`
//! has moved `w` past it,
//!
//! ```text
//! y <- min(x + w, max(x - w, y))
//! ```
//!
//! with half-width `w` (rad) growing with the friction coefficient. Tube 1 turns as
//! commanded; tube i+1 turns to `theta_i(actual) + y_i`. Feed friction is the same
//! operator on each exposed length `s_i` (half-width in mm). The state starts centred at
//! the first command of a run ([`PlayFriction::reset`]).

use crate::joints::Joints;
use crate::real::Real;

/// Play-operator friction parameters and memory for a robot of `N` tubes.
///
/// ```
/// use ctr_core::{friction::PlayFriction, Joints};
/// let mut f = PlayFriction::<f64, 2>::new([0.1, 0.0], [0.0; 2]);
/// let q = |t: f64| Joints::new([10.0, 50.0], [0.0, t]);
/// f.reset(&q(0.0));
/// assert_eq!(f.apply(&q(0.05)).theta_rad[1], 0.0);          // inside the play: no motion
/// assert!((f.apply(&q(0.3)).theta_rad[1] - 0.2).abs() < 1e-15); // dragged, lagging by w
/// assert!((f.apply(&q(0.25)).theta_rad[1] - 0.2).abs() < 1e-15); // reversal: stays
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlayFriction<T, const N: usize> {
    /// Half-width of the rotation play of pair (i, i+1), rad; the last entry is unused.
    pub rotation_half_width_rad: [T; N],
    /// Half-width of the feed play of each tube, mm.
    pub feed_half_width_mm: [T; N],
    rotation: [T; N],
    feed: [T; N],
}

impl<T: Real, const N: usize> PlayFriction<T, N> {
    /// Friction with the given half-widths, state centred at zero.
    ///
    /// ```
    /// let f = ctr_core::friction::PlayFriction::<f64, 3>::new([0.1; 3], [0.0; 3]);
    /// assert_eq!(f.rotation_half_width_rad[0], 0.1);
    /// ```
    pub fn new(rotation_half_width_rad: [T; N], feed_half_width_mm: [T; N]) -> Self {
        PlayFriction {
            rotation_half_width_rad,
            feed_half_width_mm,
            rotation: [T::zero(); N],
            feed: [T::zero(); N],
        }
    }

    /// Centres the memory on a command (the start of a run).
    ///
    /// ```
    /// # use ctr_core::{friction::PlayFriction, Joints};
    /// let mut f = PlayFriction::<f64, 2>::new([0.1, 0.0], [0.0; 2]);
    /// f.reset(&Joints::new([10.0, 50.0], [0.0, 1.0]));
    /// assert_eq!(f.apply(&Joints::new([10.0, 50.0], [0.0, 1.0])).theta_rad[1], 1.0);
    /// ```
    pub fn reset(&mut self, q: &Joints<T, N>) {
        for i in 0..N {
            self.feed[i] = q.s_mm[i];
            if i + 1 < N {
                self.rotation[i] = q.theta_rad[i + 1] - q.theta_rad[i];
            }
        }
    }

    /// Steps the memory to a new command and returns the actual joints.
    pub fn apply(&mut self, q: &Joints<T, N>) -> Joints<T, N> {
        let mut out = *q;
        play_step(
            &mut self.rotation,
            &mut self.feed,
            &self.rotation_half_width_rad,
            &self.feed_half_width_mm,
            &mut out.s_mm,
            &mut out.theta_rad,
        );
        out
    }
}

/// One step of the play-operator friction on slices (any number of tubes): moves the
/// memories `rotation` (per pair) and `feed` (per tube) to the command in `s` and
/// `theta` and overwrites those with the actual joints. [`PlayFriction::apply`] is this
/// on arrays; the std layer calls it for robots whose size is known at run time.
///
/// ```
/// let (mut rot, mut feed) = ([0.0_f64], [10.0, 50.0]);
/// let (mut s, mut theta) = ([10.0, 50.0], [0.0, 0.3]);
/// ctr_core::friction::play_step(&mut rot, &mut feed, &[0.1], &[0.0, 0.0], &mut s, &mut theta);
/// assert!((theta[1] - 0.2).abs() < 1e-15);
/// ```
pub fn play_step<T: Real>(
    rotation: &mut [T],
    feed: &mut [T],
    rotation_half_width: &[T],
    feed_half_width: &[T],
    s: &mut [T],
    theta: &mut [T],
) {
    let n = s
        .len()
        .min(theta.len())
        .min(feed.len())
        .min(feed_half_width.len());
    for i in 0..n {
        feed[i] = play(feed[i], s[i], feed_half_width[i]);
        s[i] = feed[i];
    }
    let pairs = n
        .saturating_sub(1)
        .min(rotation.len())
        .min(rotation_half_width.len());
    // commanded relative rotations first: the loop below overwrites theta
    let mut prev_cmd = if n > 0 { theta[0] } else { T::zero() };
    for i in 0..pairs {
        let x = theta[i + 1] - prev_cmd;
        prev_cmd = theta[i + 1];
        rotation[i] = play(rotation[i], x, rotation_half_width[i]);
        theta[i + 1] = theta[i] + rotation[i];
    }
    // feeds must keep their order even where plays differ
    for i in 1..n {
        if s[i] < s[i - 1] {
            s[i] = s[i - 1];
        }
    }
}

/// The play operator: output `y` follows input `x` once it is `w` away.
#[inline]
pub fn play<T: Real>(y: T, x: T, w: T) -> T {
    (x + w).min((x - w).max(y))
}

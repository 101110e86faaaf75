//! The stability margin: how far a configuration is from a snap, in joint space.
//!
//! # What it measures
//!
//! The core gives every torsion solve its softest mode `sigma`
//! ([`ctr_core::Solution::softest_mode`]): the smallest singular value of the shooting
//! Jacobian, the stiffness of the softest twist mode relative to uncoupled tubes, signed
//! with the Jacobian's determinant. It is zero where the robot snaps (a fold of the
//! twist boundary-value problem), but it does not rank danger: near a fold it goes as
//! the square root of the joint distance left, `sigma ~ c sqrt(d)`, with a `c` that
//! differs from configuration to configuration, so one sweep reads 0.25 a degree before
//! its snap while another, that never snaps, dips to 0.12.
//!
//! The margin is the distance to the fold instead. `sigma^2` is linear in the joints
//! near a fold (`sigma^2 ~ c^2 d`), so one Newton step on it from the current joints,
//! `d = sigma^2 / |grad sigma^2| = |sigma| / (2 |grad sigma|)`, is the joint distance to
//! the nearest fold to first order, whatever `c` is (at a symmetric pitchfork, where
//! `sigma` falls linearly with the feed, it is half of it: on the safe side). The
//! gradient is over all joints, a degree of rotation weighing as a millimetre of feed,
//! by forward differences of warm solves
//! ([`PROBE_STEP`]); the margin is that distance over [`REFERENCE_DISTANCE`], capped at
//! 1, with the sign of `sigma`:
//!
//! ```text
//! margin = sign(sigma) min(1, |sigma| / (2 |grad sigma| D)),   D = 20 (mm or deg)
//! ```
//!
//! So 1 means no snap within about 20 degrees of rotation or 20 mm of feed, 0.05 within
//! about a degree, 0 at the snap; a negative margin is an unstable equilibrium (past a
//! fold). Where `|sigma|` is at least [`FAR_SOFTEST`] the tubes are far from any fold
//! and the margin is `sign(sigma)` without probing: that keeps the cost off rows that
//! are nowhere near a snap. So that the margin has no step there (the inverse
//! kinematics follows its gradient), it fades linearly from the distance to 1 as
//! `|sigma|` goes from [`FADE_FROM`] to [`FAR_SOFTEST`]:
//!
//! ```text
//! t = clamp((|sigma| - FADE_FROM) / (FAR_SOFTEST - FADE_FROM), 0, 1)
//! margin = sign(sigma) ((1 - t) min(1, d / D) + t)
//! ```
//!
//! Its gradient over the joints ([`Margin::gradient`]) is that of this formula with
//! `|grad sigma|` held fixed: `grad sigma` times a positive factor, exact at the fold,
//! where `sigma` is zero and the margin's gradient is `grad sigma / (2 |grad sigma| D)`,
//! a constant length: the margin is a distance.
//!
//! # Screening
//!
//! A warning needs the exact margin only where it may be below the warning margin `X`
//! ([`Margins::Below`]). Rows whose `sigma` alone puts the fade's weight at or above
//! `X` ([`Margin::at_least`]) are cleared without more; on the others (on nitinol3 about
//! 7 % of a smooth trajectory's rows and 8 % of random rows) the core's analytic
//! gradient of the softest mode ([`ctr_core::Solver::softest_mode_gradient`]: its
//! singular vectors and two sensitivity passes: about one and a half solves' work on
//! nitinol3, against the `4 n + 2` solves of the probes) gives the same formula's
//! margin, and a row is cleared where that is at least [`SCREEN_FACTOR`] `X`. The
//! warnings stay those of the exact margins, row for row:
//!
//! - the exact margin's forward differences of step [`PROBE_STEP`] are that gradient
//!   plus their truncation (`h/2` times the second derivative: near a fold, where
//!   `sigma ~ c sqrt(d)`, a relative `h / (4 d)`, 2.5e-4 a millimetre from it) as long
//!   as every probe lies where the solver's discrete map is smooth (no cut passing
//!   another, no section changing its step count), which the screen checks
//!   ([`ctr_core::SoftestModeGradient::smooth_within_mm`]), else it leaves the row to
//!   the probes;
//! - the gradient itself is that of the twist equations, within 2.2e-4 of central
//!   differences of solves (`ctr-core/tests/softest.rs`), and the probes' softest modes
//!   are settled solves of the same equations;
//! - so the two margins differ by far less than the factor's 10 %: by at most 5.5e-5
//!   (relative) over the rows that reach the screen in `tests/snap.rs` (snapping sweeps,
//!   random and smooth nitinol3 rows) and over the 28,500 of 200,000 smooth and 200,000
//!   random nitinol3 rows. Where the analytic margin is at least `1.1 X` the exact one
//!   is at least `X`: the row is no warning either way, and every row that may be one
//!   gets its exact margin (`tests/snap.rs` compares screened and exact margins row for
//!   row).
//!
//! The test suite holds it against an independent continuation of the seed's two-tube
//! robot with 100 mm longer transmissions (`tests/snap.rs`): along 2-degree sweeps it is
//! at most 0.05 in the last step before every snap, and lower there than anywhere along
//! sweeps that do not snap.
//!
//! ```
//! use ctr_analysis::margin::{from_gradient, Margin, REFERENCE_DISTANCE};
//! // sigma 0.1 falling 0.05 per degree: a degree from the fold
//! let m = from_gradient(0.1, &[0.0, 0.05]);
//! assert!((m - 1.0 / REFERENCE_DISTANCE).abs() < 1e-12);
//! assert_eq!(from_gradient(-0.3, &[0.0, 0.0]), -1.0); // unstable, nothing to go by
//! assert_eq!(from_gradient(0.9, &[0.001, 0.0]), 1.0); // far: capped
//! // its gradient points along sigma's, a margin of 1 per 2 D of joint motion at the fold
//! let m = Margin::new(0.01, &[0.0, -0.05]);
//! assert!((m.gradient[1] + 1.0 / (2.0 * REFERENCE_DISTANCE)).abs() < 1e-12);
//! ```

use ctr_core::MAX_TUBES;

/// The joint distance a margin of 1 stands for: mm of feed or degrees of rotation.
pub const REFERENCE_DISTANCE: f64 = 20.0;

/// A softest mode at least this large (in magnitude, dimensionless) is far from any
/// fold: the margin is 1 (with its sign) without probing.
pub const FAR_SOFTEST: f64 = 1.0;

/// From this softest mode (magnitude, dimensionless) up to [`FAR_SOFTEST`] the margin
/// fades from the distance to the fold to 1, so that it has no step at [`FAR_SOFTEST`].
pub const FADE_FROM: f64 = 0.5;

/// The default warning margin (`ctr-cli fk --warn-margin`, and `diagnose` and `evaluate`
/// marking rows near a snap): a margin this small is about a degree of rotation or a
/// millimetre of feed from a snap (module doc); on 2-degree sweeps of the seed's
/// robot with long transmissions it flags the last row before every snap and no row of
/// the sweeps that do not snap (`docs/snap-through.md`).
pub const DEFAULT_WARN_MARGIN: f64 = 0.05;

/// Step of the margin's forward differences (backward where the forward probe crosses the
/// fold): mm on feeds, degrees on rotations.
pub const PROBE_STEP: f64 = 1e-3;

/// How far above the warning margin (a factor, dimensionless) the margin from the
/// softest mode's analytic gradient must be for [`Margins::Below`] to clear a row
/// without the exact margin's probes ("Screening" in the module doc): 10 % against the
/// two margins' difference, under 1e-3 (5e-5 measured on nitinol3).
pub const SCREEN_FACTOR: f64 = 1.1;

/// Most joints a margin has a gradient over (`2 MAX_TUBES`).
pub const MAX_JOINTS: usize = 2 * MAX_TUBES;

/// Which rows a solver computes the margin of.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Margins {
    /// None: the margin is NaN (a solve costs nothing more).
    #[default]
    Off,
    /// Exactly where it may be below `X` (a warning margin); elsewhere a lower bound of
    /// it, at least `X`, without probing: the fade's from `sigma` alone
    /// ([`Margin::at_least`]), or the margin from the softest mode's analytic gradient
    /// over [`SCREEN_FACTOR`] (module doc, "Screening"). Enough to tell the rows below
    /// `X`, bit for bit as [`Margins::Exact`] gives them, at a fraction of the cost.
    Below(f64),
    /// Every row's, exactly.
    Exact,
}

/// A stability margin and its gradient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Margin {
    /// The margin (dimensionless; see the [module doc](self)); NaN where the softest
    /// mode is unknown.
    pub value: f64,
    /// Its gradient over the joints in the order the softest mode's gradient was given
    /// (per mm on feeds, per degree on rotations), `|grad sigma|` held fixed; zero
    /// beyond them, where the margin is capped, and where it is NaN.
    pub gradient: [f64; MAX_JOINTS],
}

impl Margin {
    /// The margin of a softest mode `softest` whose gradient over the joints is
    /// `gradient` (at most [`MAX_JOINTS`] of them, per mm on feeds, per degree on
    /// rotations, any order): see the [module doc](self). An empty gradient is that of
    /// a mode far from any fold (or of one whose probes all failed).
    pub fn new(softest: f64, gradient: &[f64]) -> Self {
        let mut out = Margin {
            value: softest,
            gradient: [0.0; MAX_JOINTS],
        };
        if softest.is_nan() || softest == 0.0 {
            return out;
        }
        let size = softest.abs();
        let sign = softest.signum();
        // (a fold from +0: the sum of no terms is -0, whose reciprocal is -inf)
        let norm = gradient.iter().fold(0.0, |acc, g| acc + g * g).sqrt();
        let distance = size / (2.0 * norm * REFERENCE_DISTANCE);
        let (near, near_slope) = if distance.is_nan() || distance >= 1.0 {
            (1.0, 0.0)
        } else {
            (distance, 1.0 / (2.0 * norm * REFERENCE_DISTANCE))
        };
        let band = FAR_SOFTEST - FADE_FROM;
        let t = fade(size);
        let t_slope = if t > 0.0 && t < 1.0 { 1.0 / band } else { 0.0 };
        out.value = sign * ((1.0 - t) * near + t);
        // d margin / d sigma, |grad sigma| fixed: the sign cancels (the margin is odd)
        let factor = (1.0 - t) * near_slope + (1.0 - near) * t_slope;
        for (o, g) in out.gradient.iter_mut().zip(gradient) {
            *o = factor * g;
        }
        out
    }
}

impl Margin {
    /// What the softest mode alone says of the margin: its magnitude is at least the
    /// fade's weight `t` (module doc), whatever the gradient; this is that bound, with
    /// the sign of `softest` and a zero gradient (the margin itself where `|sigma|` is
    /// at least [`FAR_SOFTEST`]).
    ///
    /// ```
    /// use ctr_analysis::margin::Margin;
    /// assert_eq!(Margin::at_least(-0.75).value, -0.5);
    /// assert!(Margin::new(0.75, &[0.3, 0.2]).value >= Margin::at_least(0.75).value);
    /// ```
    pub fn at_least(softest: f64) -> Self {
        Margin {
            value: if softest.is_nan() {
                softest
            } else {
                softest.signum() * fade(softest.abs())
            },
            gradient: [0.0; MAX_JOINTS],
        }
    }
}

/// The fade's weight `t` at a softest mode of magnitude `size` (module doc).
fn fade(size: f64) -> f64 {
    ((size - FADE_FROM) / (FAR_SOFTEST - FADE_FROM)).clamp(0.0, 1.0)
}

/// The margin of a softest mode `softest` whose gradient over the joints is `gradient`
/// ([`Margin::new`]'s value). NaN in, NaN out.
pub fn from_gradient(softest: f64, gradient: &[f64]) -> f64 {
    Margin::new(softest, gradient).value
}

/// Whether a softest mode is far from any fold ([`FAR_SOFTEST`]): its margin is its
/// sign, without probing.
pub fn is_far(softest: f64) -> bool {
    softest.abs() >= FAR_SOFTEST
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The margin as a function of `sigma` alone, along a gradient of fixed length.
    fn along(sigma: f64, slope: f64) -> Margin {
        Margin::new(sigma, &[slope, 0.0])
    }

    /// No step where probing starts or the fade ends; odd in `sigma`; within [-1, 1].
    #[test]
    fn the_margin_is_continuous_odd_and_bounded() {
        const EPS: f64 = 1e-9;
        for slope in [0.005, 0.02, 0.1, 1.0] {
            for edge in [FADE_FROM, FAR_SOFTEST] {
                let (lo, hi) = (along(edge - EPS, slope), along(edge + EPS, slope));
                assert!(
                    (lo.value - hi.value).abs() < 1e-6,
                    "{slope} {edge}: {lo:?} {hi:?}"
                );
            }
            let mut s = -2.0;
            while s <= 2.0 {
                let m = along(s, slope).value;
                assert!(m.abs() <= 1.0 && m.signum() == s.signum(), "{s}: {m}");
                assert_eq!(along(-s, slope).value, -m);
                s += 0.01;
            }
        }
    }

    /// The gradient is that of the formula with `|grad sigma|` fixed: central
    /// differences of the value in `sigma`, times `grad sigma`.
    #[test]
    fn the_gradient_is_the_formulas() {
        const H: f64 = 1e-7;
        for slope in [0.005, 0.02, 0.1] {
            for s in [-0.9, -0.3, 0.001, 0.05, 0.3, 0.6, 0.75, 0.99, 1.5] {
                let d = (along(s + H, slope).value - along(s - H, slope).value) / (2.0 * H);
                let g = along(s, slope).gradient;
                assert!(
                    (g[0] - d * slope).abs() < 1e-5,
                    "{slope} {s}: {} vs {}",
                    g[0],
                    d * slope
                );
                assert_eq!(g[1], 0.0);
            }
        }
        assert_eq!(Margin::new(f64::NAN, &[1.0]).gradient, [0.0; MAX_JOINTS]);
        assert!(Margin::new(f64::NAN, &[1.0]).value.is_nan());
    }
}

//! The joint ranges the inverse kinematics keeps: the core's own
//! (`0 <= s_1 <= ... <= s_n`, `s_i <= length_i`) and the robot file's `[limits]`, in the
//! solver's units (mm and rad).
//!
//! The feed ranges form a chain: a box per feed and a range per increment
//! `s_i - s_(i-1)`. [`JointLimits::project`] moves a joint vector onto the set with
//! comparisons done exactly as [`TubeLimits::violation`] and the core's
//! `Joints::validate` do them, so a projected vector passes both bit for bit.
//!
//! A rotation range at least a full turn wide is periodic: the kinematics are
//! 2 pi-periodic in every `theta_i`, so the solver moves the angle freely and wraps it
//! back into the range (no constraint, no false boundary at +-180 degrees). A
//! narrower range is a hard bound. A tube without a rotation range is periodic over
//! `[-pi, pi]`.

use ctr_formats::TubeLimits;
use std::f64::consts::{PI, TAU};

/// A rotation range in radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RotationRange {
    /// At least a full turn: angles wrap into `[lo, lo + 2 pi)`, then clamp to `hi`.
    Periodic {
        /// lower end, rad
        lo: f64,
        /// upper end, rad (`hi - lo >= 2 pi` up to rounding)
        hi: f64,
    },
    /// Less than a full turn: a hard bound.
    Bounded {
        /// lower end, rad
        lo: f64,
        /// upper end, rad
        hi: f64,
    },
}

impl RotationRange {
    /// The range `[lo, hi]` in radians.
    pub fn bounds(&self) -> [f64; 2] {
        match *self {
            RotationRange::Periodic { lo, hi } | RotationRange::Bounded { lo, hi } => [lo, hi],
        }
    }
}

/// Why limits cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LimitsError {
    /// `[limits]` has a different number of tubes than the robot.
    #[error("[limits] has {found} tube tables, the robot has {expected} tubes")]
    Count {
        /// tubes of the robot
        expected: usize,
        /// tube tables in `[limits]`
        found: usize,
    },
    /// A range is not finite or has `min > max`.
    #[error("[limits] tube {tube}: {key} must be a finite [min, max] with min <= max")]
    Range {
        /// tube number from 1
        tube: usize,
        /// the key
        key: &'static str,
    },
    /// No joint vector satisfies all ranges together with the feed order and lengths.
    #[error("[limits] tube {tube}: no feed satisfies the feed ranges, increments, tube lengths and feed order together")]
    Empty {
        /// tube number from 1 (the first found empty)
        tube: usize,
    },
}

/// Joint limits of an `n`-tube robot in the solver's units: joint vectors are
/// `s_1 (mm), theta_1 (rad), ..., s_n, theta_n`.
#[derive(Clone, Debug, PartialEq)]
pub struct JointLimits {
    /// per tube `[a, b]`: `max(0, s_mm min)` to `min(length, s_mm max)`; tube 1's
    /// increment range (`s_1 - 0`) is merged in
    feed: Vec<[f64; 2]>,
    /// per tube `[c, d]` for `s_i - s_(i-1)`, `c >= 0` (feed order); unused for tube 1
    increment: Vec<[f64; 2]>,
    /// per tube: the feeds from which the inner tubes can still be placed
    reach: Vec<[f64; 2]>,
    rotation: Vec<RotationRange>,
    /// `[limits] theta_deg` as given (for clamping after conversion to degrees)
    theta_deg: Vec<Option<[f64; 2]>>,
}

fn intersect(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0].max(b[0]), a[1].min(b[1])]
}

impl JointLimits {
    /// Limits for tubes of the given lengths (mm, outermost first) and an optional
    /// `[limits]` section (one entry per tube).
    ///
    /// ```
    /// use ctr_formats::TubeLimits;
    /// use ctr_analysis::limits::JointLimits;
    /// let t = TubeLimits { increment_mm: Some([10.0, 50.0]), ..Default::default() };
    /// let l = JointLimits::new(&[160.0, 220.0], Some(&[t, t])).unwrap();
    /// assert!(l.contains(&[20.0, 0.0, 30.0, 3.0]));
    /// assert!(!l.contains(&[20.0, 0.0, 25.0, 0.0])); // increment 5 < 10
    /// ```
    pub fn new(lengths: &[f64], limits: Option<&[TubeLimits]>) -> Result<Self, LimitsError> {
        let n = lengths.len();
        if let Some(l) = limits {
            if l.len() != n {
                return Err(LimitsError::Count {
                    expected: n,
                    found: l.len(),
                });
            }
        }
        let free = TubeLimits::default();
        let tube = |i: usize| limits.map_or(&free, |l| &l[i]);
        let mut feed = Vec::with_capacity(n);
        let mut increment = Vec::with_capacity(n);
        let mut rotation = Vec::with_capacity(n);
        let mut theta_deg = Vec::with_capacity(n);
        for (i, &length) in lengths.iter().enumerate() {
            let t = tube(i);
            for (key, r) in [
                ("s_mm", t.s_mm),
                ("increment_mm", t.increment_mm),
                ("theta_deg", t.theta_deg),
            ] {
                if let Some([lo, hi]) = r {
                    if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                        return Err(LimitsError::Range { tube: i + 1, key });
                    }
                }
            }
            let inf = f64::INFINITY;
            let mut f = intersect([0.0, length], t.s_mm.unwrap_or([-inf, inf]));
            let mut inc = intersect([0.0, inf], t.increment_mm.unwrap_or([-inf, inf]));
            if i == 0 {
                // s_1 - s_0 with s_0 = 0 is s_1 itself, exactly
                f = intersect(f, inc);
                inc = [-inf, inf];
            }
            if f[0] > f[1] || inc[0] > inc[1] {
                return Err(LimitsError::Empty { tube: i + 1 });
            }
            feed.push(f);
            increment.push(inc);
            rotation.push(match t.theta_deg {
                None => RotationRange::Periodic { lo: -PI, hi: PI },
                Some([lo, hi]) => {
                    let (lo, hi) = (lo.to_radians(), hi.to_radians());
                    if hi - lo >= TAU * (1.0 - 1e-12) {
                        RotationRange::Periodic { lo, hi }
                    } else {
                        RotationRange::Bounded { lo, hi }
                    }
                }
            });
            theta_deg.push(t.theta_deg);
        }
        // backward pass: the feeds of tube i-1 that leave room for tubes i..n
        let mut reach = feed.clone();
        for i in (1..n).rev() {
            let [lo, hi] = reach[i];
            let [c, d] = increment[i];
            reach[i - 1] = intersect(reach[i - 1], [lo - d, hi - c]);
            if reach[i - 1][0] > reach[i - 1][1] {
                return Err(LimitsError::Empty { tube: i });
            }
        }
        Ok(JointLimits {
            feed,
            increment,
            reach,
            rotation,
            theta_deg,
        })
    }

    /// The number of tubes.
    pub fn n_tubes(&self) -> usize {
        self.feed.len()
    }

    /// Tube `i`'s (from 0) feed box `[min, max]`, mm (lengths and `s_mm` merged; for
    /// tube 1 also its `increment_mm`).
    pub fn feed(&self, i: usize) -> [f64; 2] {
        self.feed[i]
    }

    /// Tube `i`'s (from 1 on) increment range `[min, max]` for `s_i - s_(i-1)`, mm;
    /// the minimum is at least 0 (feed order). Tube 0's is unbounded (merged into its feed).
    pub fn increment(&self, i: usize) -> [f64; 2] {
        self.increment[i]
    }

    /// Tube `i`'s rotation range.
    pub fn rotation(&self, i: usize) -> RotationRange {
        self.rotation[i]
    }

    /// True when `q` (mm, rad) satisfies every range, compared exactly as the file
    /// checks and the core do.
    pub fn contains(&self, q: &[f64]) -> bool {
        assert_eq!(q.len(), 2 * self.n_tubes());
        (0..self.n_tubes()).all(|i| {
            let (s, th) = (q[2 * i], q[2 * i + 1]);
            let [a, b] = self.feed[i];
            let feed_ok = s.is_finite() && a <= s && s <= b;
            let inc_ok = i == 0 || {
                let [c, d] = self.increment[i];
                let ds = s - q[2 * i - 2];
                c <= ds && ds <= d && s >= q[2 * i - 2]
            };
            let [lo, hi] = self.rotation[i].bounds();
            feed_ok && inc_ok && th.is_finite() && lo <= th && th <= hi
        })
    }

    /// As [`contains`](Self::contains), but periodic angles may take any finite value
    /// (the kinematics do not see the difference): where FK may be evaluated.
    pub(crate) fn admits(&self, q: &[f64]) -> bool {
        let mut w = q.to_vec();
        for i in 0..self.n_tubes() {
            if let RotationRange::Periodic { .. } = self.rotation[i] {
                if !w[2 * i + 1].is_finite() {
                    return false;
                }
                w[2 * i + 1] = self.wrap(i, w[2 * i + 1]);
            }
        }
        self.contains(&w)
    }

    /// Moves `q` onto the limits: feeds clamped in order from the outermost tube (each
    /// within the range that leaves room for the inner ones), periodic angles wrapped,
    /// bounded ones clamped. A `q` inside moves only by angle wraps of 2 pi. Non-finite
    /// values are replaced by the middle of their range.
    pub fn project(&self, q: &mut [f64]) {
        assert_eq!(q.len(), 2 * self.n_tubes());
        for i in 0..self.n_tubes() {
            let [mut lo, mut hi] = self.reach[i];
            if i > 0 {
                let prev = q[2 * i - 2];
                let [c, d] = self.increment[i];
                lo = lo.max(prev + c);
                hi = hi.min(prev + d);
            }
            let s = &mut q[2 * i];
            if !s.is_finite() {
                *s = 0.5 * (lo + hi);
            }
            *s = s.clamp(lo.min(hi), hi);
            if i > 0 {
                // rounding of prev + c: nudge until the difference itself is in range
                let prev = q[2 * i - 2];
                let [c, d] = self.increment[i];
                let [a, b] = self.feed[i];
                let s = &mut q[2 * i];
                for _ in 0..8 {
                    if *s - prev < c && *s < b {
                        *s = s.next_up();
                    } else if *s - prev > d && *s > a {
                        *s = s.next_down();
                    } else {
                        break;
                    }
                }
            }
            q[2 * i + 1] = self.wrap(i, q[2 * i + 1]);
        }
    }

    /// Tube `i`'s angle moved into its range: wrapped when periodic, clamped otherwise.
    pub fn wrap(&self, i: usize, theta: f64) -> f64 {
        match self.rotation[i] {
            RotationRange::Periodic { lo, hi } => {
                if !theta.is_finite() {
                    return 0.0_f64.clamp(lo, hi);
                }
                if (lo..=hi).contains(&theta) {
                    return theta;
                }
                (lo + (theta - lo).rem_euclid(TAU)).clamp(lo, hi)
            }
            RotationRange::Bounded { lo, hi } => {
                if theta.is_finite() {
                    theta.clamp(lo, hi)
                } else {
                    0.0_f64.clamp(lo, hi)
                }
            }
        }
    }

    /// A point inside the limits from `2 n` numbers in `[0, 1)`: each feed placed at
    /// its fraction of the range left by the outer tubes, each angle at its fraction of
    /// its range. Fractions of 0.5 give the middle of the limits.
    pub fn point(&self, u: &[f64]) -> Vec<f64> {
        let n = self.n_tubes();
        assert_eq!(u.len(), 2 * n);
        let mut q = vec![0.0; 2 * n];
        for i in 0..n {
            let [mut lo, mut hi] = self.reach[i];
            if i > 0 {
                let [c, d] = self.increment[i];
                lo = lo.max(q[2 * i - 2] + c);
                hi = hi.min(q[2 * i - 2] + d);
            }
            q[2 * i] = lo + (hi - lo) * u[2 * i];
            let [tlo, thi] = self.rotation[i].bounds();
            q[2 * i + 1] = tlo + (thi - tlo) * u[2 * i + 1];
        }
        self.project(&mut q);
        q
    }

    /// The middle of the limits, with angles at 0 where 0 is inside.
    pub fn center(&self) -> Vec<f64> {
        let mut q = self.point(&vec![0.5; 2 * self.n_tubes()]);
        for i in 0..self.n_tubes() {
            let [lo, hi] = self.rotation[i].bounds();
            if lo <= 0.0 && 0.0 <= hi {
                q[2 * i + 1] = 0.0;
            }
        }
        q
    }

    /// Joints in file units (mm, degrees) from solver units, with each angle clamped to
    /// its `theta_deg` range against the rounding of the conversion.
    pub fn to_file_units(&self, q: &[f64]) -> Vec<f64> {
        assert_eq!(q.len(), 2 * self.n_tubes());
        let mut out = q.to_vec();
        for i in 0..self.n_tubes() {
            let mut d = q[2 * i + 1].to_degrees();
            if let Some([lo, hi]) = self.theta_deg[i] {
                d = d.clamp(lo, hi);
            }
            out[2 * i + 1] = d;
        }
        out
    }

    /// Joints in solver units (mm, rad) from file units (mm, degrees).
    pub fn from_file_units(&self, joints: &[f64]) -> Vec<f64> {
        assert_eq!(joints.len(), 2 * self.n_tubes());
        let mut q = joints.to_vec();
        for i in 0..self.n_tubes() {
            q[2 * i + 1] = joints[2 * i + 1].to_radians();
        }
        q
    }

    /// The linear constraints `lo <= a . q <= hi` that describe the limits (periodic
    /// angles excluded), for the step QP.
    pub(crate) fn rows(&self) -> Vec<Row> {
        let mut rows = Vec::new();
        for i in 0..self.n_tubes() {
            let [a, b] = self.feed[i];
            rows.push(Row {
                terms: vec![(2 * i, 1.0)],
                lo: a,
                hi: b,
            });
            if i > 0 {
                let [c, d] = self.increment[i];
                rows.push(Row {
                    terms: vec![(2 * i, 1.0), (2 * i - 2, -1.0)],
                    lo: c,
                    hi: d,
                });
            }
            if let RotationRange::Bounded { lo, hi } = self.rotation[i] {
                rows.push(Row {
                    terms: vec![(2 * i + 1, 1.0)],
                    lo,
                    hi,
                });
            }
        }
        rows
    }
}

/// One linear constraint `lo <= sum(coef * q[index]) <= hi` (ends may be infinite).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Row {
    pub terms: Vec<(usize, f64)>,
    pub lo: f64,
    pub hi: f64,
}

impl Row {
    pub fn value(&self, q: &[f64]) -> f64 {
        self.terms.iter().map(|&(j, a)| a * q[j]).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits3() -> JointLimits {
        let t = TubeLimits {
            increment_mm: Some([10.0, 50.0]),
            theta_deg: Some([-180.0, 180.0]),
            ..Default::default()
        };
        JointLimits::new(&[160.0, 220.0, 280.0], Some(&[t, t, t])).unwrap()
    }

    #[test]
    fn projection_lands_inside_and_keeps_inside_points() {
        let l = limits3();
        let mut state = 7_u64;
        let mut u = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..2000 {
            let mut q: Vec<f64> = (0..6).map(|_| 400.0 * u() - 100.0).collect();
            l.project(&mut q);
            assert!(l.contains(&q), "{q:?}");
            let before = q.clone();
            l.project(&mut q);
            assert_eq!(q, before);
            let p = l.point(&(0..6).map(|_| u()).collect::<Vec<_>>());
            assert!(l.contains(&p), "{p:?}");
        }
    }

    #[test]
    fn narrow_rotation_is_bounded_and_wide_is_periodic() {
        let t = TubeLimits {
            theta_deg: Some([-90.0, 90.0]),
            ..Default::default()
        };
        let l = JointLimits::new(&[100.0], Some(&[t])).unwrap();
        assert!(matches!(l.rotation(0), RotationRange::Bounded { .. }));
        assert_eq!(l.wrap(0, 3.0), 90f64.to_radians());
        let l = JointLimits::new(&[100.0], None).unwrap();
        assert!((l.wrap(0, 3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-15);
    }

    #[test]
    fn empty_limits_are_refused() {
        let t = TubeLimits {
            increment_mm: Some([60.0, 70.0]),
            ..Default::default()
        };
        // s_2 >= 120 but tube 2 is 100 long
        let e = JointLimits::new(&[100.0, 100.0], Some(&[t, t])).unwrap_err();
        assert!(matches!(e, LimitsError::Empty { .. }));
    }
}

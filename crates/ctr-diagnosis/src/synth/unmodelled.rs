//! Effects outside the contract's vocabulary that [`crate::synth`] can put in a world:
//! what a real robot holds beyond any model's effects (a wrong gear, a tracker that
//! creeps, scales or wanders), for blind tests of what the diagnosis says then.

use ctr_analysis::rng::Rng;

/// An effect outside the contract's vocabulary, for blind tests of what the diagnosis
/// says when no effect it knows is the cause.
#[derive(Clone, Debug, PartialEq)]
pub enum Unmodelled {
    /// A wrong lead-screw pitch: the actual feed is `gain` x the commanded.
    FeedGain {
        /// The tube, 0-based (0 the outermost).
        tube: usize,
        /// Actual over commanded feed.
        gain: f64,
    },
    /// A wrong gear ratio: the actual rotation is `gain` x the commanded.
    RotationGain {
        /// The tube, 0-based.
        tube: usize,
        /// Actual over commanded rotation.
        gain: f64,
    },
    /// A gear with a once-per-turn error: the actual rotation is the commanded `theta`
    /// plus `amplitude_deg sin(theta + phase_deg)`.
    GearRunout {
        /// The tube, 0-based.
        tube: usize,
        /// Amplitude of the error, degrees.
        amplitude_deg: f64,
        /// Its phase, degrees.
        phase_deg: f64,
    },
    /// A coupling that slips once: from `at_s` on, the actual rotation of `tube` is the
    /// commanded plus `jump_deg` (a set screw that gave, a belt that skipped a tooth).
    RotationSlip {
        /// The tube, 0-based.
        tube: usize,
        /// When it slips, s (the recording's `t_s`).
        at_s: f64,
        /// How far the rotation jumps then, degrees.
        jump_deg: f64,
    },
    /// A tracker whose frame creeps: measured += `t_s` x `velocity_mm_s`.
    TrackerDrift {
        /// Creep of the tracker's frame, mm/s per axis.
        velocity_mm_s: [f64; 3],
    },
    /// A miscalibrated tracker: each measured axis scaled by `1 + scale_error[a]`.
    TrackerScale {
        /// Relative scale error per axis.
        scale_error: [f64; 3],
    },
    /// A tracker whose reading wanders slowly (a field distortion that moves, a sensor
    /// warming up): measured += a smooth random function of time per axis, the sum of
    /// [`WANDER_COMPONENTS`] sinusoids with periods between `period_s` and
    /// [`WANDER_PERIOD_SPAN`] x `period_s` and phases drawn from `seed`. Errors that
    /// are not white along a run, and that no effect of the vocabulary makes.
    TrackerWander {
        /// RMS of the wander per axis, mm.
        rms_mm: f64,
        /// Shortest period of its components, s.
        period_s: f64,
        /// Seed of its periods and phases.
        seed: u64,
    },
}

/// Sinusoids per axis of [`Unmodelled::TrackerWander`].
pub const WANDER_COMPONENTS: usize = 6;
/// Longest over shortest period of [`Unmodelled::TrackerWander`]'s components.
pub const WANDER_PERIOD_SPAN: f64 = 4.0;

impl Unmodelled {
    /// The actual joints (file order and units) for the commanded `q` at time `t_s`.
    pub(crate) fn actuate(&self, q: &mut [f64], t_s: f64) {
        match *self {
            Unmodelled::FeedGain { tube, gain } => q[2 * tube] *= gain,
            Unmodelled::RotationGain { tube, gain } => q[2 * tube + 1] *= gain,
            Unmodelled::GearRunout {
                tube,
                amplitude_deg,
                phase_deg,
            } => {
                let theta = q[2 * tube + 1];
                q[2 * tube + 1] = theta + amplitude_deg * (theta + phase_deg).to_radians().sin();
            }
            Unmodelled::RotationSlip {
                tube,
                at_s,
                jump_deg,
            } => {
                if t_s >= at_s {
                    q[2 * tube + 1] += jump_deg;
                }
            }
            Unmodelled::TrackerDrift { .. }
            | Unmodelled::TrackerScale { .. }
            | Unmodelled::TrackerWander { .. } => {}
        }
    }

    /// The tracker's reading of the tip `p` at time `t_s`.
    pub(crate) fn measure(&self, p: &mut [f64; 3], t_s: f64) {
        match *self {
            Unmodelled::TrackerDrift { velocity_mm_s } => {
                for a in 0..3 {
                    p[a] += t_s * velocity_mm_s[a];
                }
            }
            Unmodelled::TrackerScale { scale_error } => {
                for a in 0..3 {
                    p[a] *= 1.0 + scale_error[a];
                }
            }
            Unmodelled::TrackerWander {
                rms_mm,
                period_s,
                seed,
            } => {
                // each sinusoid's RMS is amplitude / sqrt(2)
                let amplitude = rms_mm * (2.0 / WANDER_COMPONENTS as f64).sqrt();
                let mut rng = Rng::new(seed);
                for v in p.iter_mut() {
                    for _ in 0..WANDER_COMPONENTS {
                        let period = period_s * (1.0 + (WANDER_PERIOD_SPAN - 1.0) * rng.uniform());
                        let phase = std::f64::consts::TAU * rng.uniform();
                        *v += amplitude * (std::f64::consts::TAU * t_s / period + phase).sin();
                    }
                }
            }
            _ => {}
        }
    }
}

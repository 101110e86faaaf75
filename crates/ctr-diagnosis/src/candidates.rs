//! The effects of the contract's vocabulary as parameter blocks a fit can turn on and
//! tune: how each is written into a model, where its parameters start, their scales
//! (finite-difference steps) and bounds.
//!
//! | effect | parameters (units) |
//! |---|---|
//! | `torsion` | none: the base model becomes the torsion model |
//! | `friction` | rotation play half-width per neighbouring pair (deg), feed play per tube (mm), the seed's friction coefficient per pair (the play's growth with the contact moment, `ctr_analysis::contact`; this project's extension) |
//! | `clearance` | per pair: largest kink (deg) and the relative angle where it peaks (deg) |
//! | `gravity` | gravity vector in W (m/s^2): direction and size (absorbs a density error) |
//! | `registration` | translation (mm) and rotation vector (deg) of the tracker frame |
//! | `joint_offset` | feed (mm) and rotation (deg) zero of every tube |
//! | `stiffness` | ln of each tube's modulus factor |
//! | `precurvature` | ln of each tube's curvature-radius factor |
//! | `latency` | delay of the robot behind its commands (s) |
//! | `sensor_offset` | tracked point in the tip frame (mm) |
//! | `sensor_rotation` | rotation vector of the sensor's frame in the tip frame (deg); this project's extension, seen only by orientation or tangent columns |

use ctr_analysis::linearised::Moving;
use ctr_analysis::model::ModelSpec;
use ctr_core::Model;
use ctr_formats::{
    Clearance, Friction, Gravity, JointOffset, Latency, Precurvature, Recording, Registration,
    SensorOffset, SensorRotation, Stiffness,
};
use serde::Serialize;

/// An effect id of the contract (`docs/formats.md`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectId {
    /// Tubes twist along their length.
    Torsion,
    /// Friction between tubes (hysteresis).
    Friction,
    /// Clearance kinks at the tubes' exits.
    Clearance,
    /// The tubes' weight.
    Gravity,
    /// Tracker frame offset from W.
    Registration,
    /// Actuator zero offsets.
    JointOffset,
    /// Stiffness scale factors.
    Stiffness,
    /// Precurvature scale factors.
    Precurvature,
    /// Time lag of the robot behind its commands.
    Latency,
    /// Tracked point offset from the tip.
    SensorOffset,
    /// The tracked sensor's frame turned in the tip frame (this project's extension).
    SensorRotation,
}

impl EffectId {
    /// All eleven: the contract's ten in its order, then this project's
    /// `sensor_rotation`.
    pub const ALL: [EffectId; 11] = [
        EffectId::Torsion,
        EffectId::Friction,
        EffectId::Clearance,
        EffectId::Gravity,
        EffectId::Registration,
        EffectId::JointOffset,
        EffectId::Stiffness,
        EffectId::Precurvature,
        EffectId::Latency,
        EffectId::SensorOffset,
        EffectId::SensorRotation,
    ];

    /// The contract's id.
    ///
    /// ```
    /// assert_eq!(ctr_diagnosis::EffectId::JointOffset.as_str(), "joint_offset");
    /// ```
    pub fn as_str(self) -> &'static str {
        match self {
            EffectId::Torsion => "torsion",
            EffectId::Friction => "friction",
            EffectId::Clearance => "clearance",
            EffectId::Gravity => "gravity",
            EffectId::Registration => "registration",
            EffectId::JointOffset => "joint_offset",
            EffectId::Stiffness => "stiffness",
            EffectId::Precurvature => "precurvature",
            EffectId::Latency => "latency",
            EffectId::SensorOffset => "sensor_offset",
            EffectId::SensorRotation => "sensor_rotation",
        }
    }

    /// Parses a contract id.
    ///
    /// ```
    /// use ctr_diagnosis::EffectId;
    /// assert_eq!(EffectId::parse("latency"), Some(EffectId::Latency));
    /// assert_eq!(EffectId::parse("lag"), None);
    /// ```
    pub fn parse(s: &str) -> Option<Self> {
        EffectId::ALL.into_iter().find(|e| e.as_str() == s)
    }

    /// Parses a contract id (surrounding blanks ignored), with a message listing the
    /// ids for an unknown one: what `ctr-cli` and `ctr_py` say.
    ///
    /// ```
    /// use ctr_diagnosis::EffectId;
    /// assert_eq!(EffectId::from_id(" latency"), Ok(EffectId::Latency));
    /// assert!(EffectId::from_id("lag").unwrap_err().starts_with("unknown effect \"lag\""));
    /// ```
    pub fn from_id(s: &str) -> Result<Self, String> {
        EffectId::parse(s.trim()).ok_or_else(|| {
            format!(
                "unknown effect {s:?}; the contract's ids are {}",
                EffectId::ALL.map(EffectId::as_str).join(", ")
            )
        })
    }

    /// True when the model already has the effect.
    pub fn present_in(self, m: &ModelSpec) -> bool {
        let e = &m.effects;
        match self {
            EffectId::Torsion => m.model == Model::Torsion,
            EffectId::Friction => e.friction.is_some(),
            EffectId::Clearance => e.clearance.is_some(),
            EffectId::Gravity => e.gravity.is_some(),
            EffectId::Registration => e.registration.is_some(),
            EffectId::JointOffset => e.joint_offset.is_some(),
            EffectId::Stiffness => e.stiffness.is_some(),
            EffectId::Precurvature => e.precurvature.is_some(),
            EffectId::Latency => e.latency.is_some(),
            EffectId::SensorOffset => e.sensor_offset.is_some(),
            EffectId::SensorRotation => e.sensor_rotation.is_some(),
        }
    }

    /// `m` with this effect taken out (the rigid model for torsion).
    pub(crate) fn remove(self, m: &mut ModelSpec) {
        let e = &mut m.effects;
        match self {
            EffectId::Torsion => m.model = Model::Rigid,
            EffectId::Friction => e.friction = None,
            EffectId::Clearance => e.clearance = None,
            EffectId::Gravity => e.gravity = None,
            EffectId::Registration => e.registration = None,
            EffectId::JointOffset => e.joint_offset = None,
            EffectId::Stiffness => e.stiffness = None,
            EffectId::Precurvature => e.precurvature = None,
            EffectId::Latency => e.latency = None,
            EffectId::SensorOffset => e.sensor_offset = None,
            EffectId::SensorRotation => e.sensor_rotation = None,
        }
    }

    /// What a linearisation of the rows must carry to move this effect's predictions
    /// without solving ([`ctr_analysis::linearised`]): the measurement (sensor offset
    /// and rotation, registration), the joints (joint offsets, latency, the play
    /// friction) or the tubes' scales (stiffness, precurvature); `None` for the effects
    /// that are solved (clearance, gravity, torsion). A fit's Jacobian takes these
    /// columns from the linearisation where it costs fewer solves.
    pub(crate) fn linearised_as(self) -> Option<Moving> {
        match self {
            EffectId::Registration | EffectId::SensorOffset | EffectId::SensorRotation => {
                Some(Moving::Measurement)
            }
            EffectId::Friction | EffectId::JointOffset | EffectId::Latency => Some(Moving::Joints),
            EffectId::Stiffness | EffectId::Precurvature => Some(Moving::Scales),
            EffectId::Torsion | EffectId::Clearance | EffectId::Gravity => None,
        }
    }

    /// Number of parameters for a robot of `n` tubes.
    pub fn n_params(self, n: usize) -> usize {
        let pairs = n.saturating_sub(1);
        match self {
            EffectId::Torsion => 0,
            EffectId::Friction => 2 * pairs + n,
            EffectId::Clearance => 2 * pairs,
            EffectId::Gravity => 3,
            EffectId::Registration => 6,
            EffectId::JointOffset => 2 * n,
            EffectId::Stiffness | EffectId::Precurvature => n,
            EffectId::Latency => 1,
            EffectId::SensorOffset | EffectId::SensorRotation => 3,
        }
    }

    /// What parameter `i` is, in words, with its unit, and whether it is the natural
    /// log of a factor (the file writes `exp` of it).
    pub(crate) fn label(self, n: usize, i: usize) -> Label {
        let pairs = n.saturating_sub(1);
        let axis = |k: usize| ["x", "y", "z"][k % 3];
        let plain = |name: String, unit: &'static str| Label {
            name,
            unit,
            log: false,
        };
        match self {
            EffectId::Torsion => plain("torsion".into(), ""),
            EffectId::Friction if i < pairs => {
                plain(format!("rotation play of tubes {}-{}", i + 1, i + 2), "deg")
            }
            EffectId::Friction if i < pairs + n => {
                plain(format!("feed play of tube {}", i - pairs + 1), "mm")
            }
            EffectId::Friction => plain(
                format!(
                    "friction coefficient of tubes {}-{}",
                    i - pairs - n + 1,
                    i - pairs - n + 2
                ),
                "",
            ),
            EffectId::Clearance if i.is_multiple_of(2) => plain(
                format!("clearance kink of tubes {}-{}", i / 2 + 1, i / 2 + 2),
                "deg",
            ),
            EffectId::Clearance => plain(
                format!("clearance peak angle of tubes {}-{}", i / 2 + 1, i / 2 + 2),
                "deg",
            ),
            EffectId::Gravity => plain(format!("gravity {}", axis(i)), "m/s^2"),
            EffectId::Registration if i < 3 => {
                plain(format!("registration translation {}", axis(i)), "mm")
            }
            EffectId::Registration => plain(format!("registration rotation {}", axis(i)), "deg"),
            EffectId::JointOffset if i < n => plain(format!("feed offset of tube {}", i + 1), "mm"),
            EffectId::JointOffset => plain(format!("rotation offset of tube {}", i - n + 1), "deg"),
            EffectId::Stiffness => Label {
                name: format!("stiffness factor of tube {}", i + 1),
                unit: "",
                log: true,
            },
            EffectId::Precurvature => Label {
                name: format!("curvature radius factor of tube {}", i + 1),
                unit: "",
                log: true,
            },
            EffectId::Latency => plain("latency".into(), "s"),
            EffectId::SensorOffset => plain(format!("sensor offset {}", axis(i)), "mm"),
            EffectId::SensorRotation => {
                plain(format!("sensor rotation about tip {}", axis(i)), "deg")
            }
        }
    }

    /// Finite-difference step of parameter `i` (its natural scale).
    pub(crate) fn step(self, n: usize, i: usize) -> f64 {
        let pairs = n.saturating_sub(1);
        match self {
            EffectId::Torsion => 1.0,
            EffectId::Friction => {
                if i < pairs {
                    0.05
                } else if i < pairs + n {
                    0.005
                } else {
                    FRICTION_COEFFICIENT_STEP
                }
            }
            EffectId::Clearance => 0.05,
            EffectId::Gravity => 0.2,
            EffectId::Registration => 0.01,
            EffectId::JointOffset => {
                if i < n {
                    0.01
                } else {
                    0.05
                }
            }
            EffectId::Stiffness | EffectId::Precurvature => 1e-3,
            EffectId::Latency => 0.005,
            EffectId::SensorOffset => 0.01,
            EffectId::SensorRotation => 0.01,
        }
    }

    /// Whether parameter `i` is an angle whose bounds are where it wraps around (a
    /// joint's rotation offset, within +/-180 deg): a value there is a place on the
    /// circle, not a limit.
    pub(crate) fn wraps(self, n: usize, i: usize) -> bool {
        self == EffectId::JointOffset && i >= n
    }

    /// Bounds of parameter `i`.
    pub(crate) fn bounds(self, n: usize, i: usize) -> (f64, f64) {
        let pairs = n.saturating_sub(1);
        const FREE: (f64, f64) = (f64::NEG_INFINITY, f64::INFINITY);
        match self {
            EffectId::Torsion => FREE,
            EffectId::Friction => {
                if i < pairs {
                    (0.0, MAX_ROTATION_PLAY_DEG)
                } else if i < pairs + n {
                    (0.0, MAX_FEED_PLAY_MM)
                } else {
                    (0.0, MAX_FRICTION_COEFFICIENT)
                }
            }
            EffectId::Clearance => {
                if i.is_multiple_of(2) {
                    (0.0, MAX_KINK_DEG)
                } else {
                    FREE
                }
            }
            EffectId::Gravity => (-MAX_GRAVITY_M_S2, MAX_GRAVITY_M_S2),
            EffectId::Registration => FREE,
            EffectId::JointOffset => {
                if i < n {
                    (-MAX_FEED_OFFSET_MM, MAX_FEED_OFFSET_MM)
                } else {
                    (-180.0, 180.0)
                }
            }
            EffectId::Stiffness | EffectId::Precurvature => (-MAX_LN_FACTOR, MAX_LN_FACTOR),
            EffectId::Latency => (-MAX_LATENCY_S, MAX_LATENCY_S),
            EffectId::SensorOffset => (-MAX_SENSOR_OFFSET_MM, MAX_SENSOR_OFFSET_MM),
            EffectId::SensorRotation => (-MAX_SENSOR_ROTATION_DEG, MAX_SENSOR_ROTATION_DEG),
        }
    }

    /// Starting points of a fit of this effect alone (several where the fit is not
    /// convex in a parameter: the peak angle of a clearance profile, the latency).
    pub(crate) fn starts(self, n: usize, sample_period_s: f64) -> Vec<Vec<f64>> {
        let pairs = n.saturating_sub(1);
        let k = self.n_params(n);
        match self {
            EffectId::Friction => {
                let mut x = vec![0.0; k];
                for v in &mut x[..pairs] {
                    *v = 1.0;
                }
                vec![x]
            }
            EffectId::Clearance => [0.0, 90.0, 180.0, 270.0]
                .into_iter()
                .map(|peak| (0..pairs).flat_map(|_| [1.0, peak]).collect())
                .collect(),
            EffectId::Latency => {
                let dt = if sample_period_s.is_finite() && sample_period_s > 0.0 {
                    sample_period_s
                } else {
                    0.1
                };
                vec![vec![0.0], vec![dt], vec![-dt], vec![3.0 * dt]]
            }
            _ => vec![vec![0.0; k]],
        }
    }

    /// Whether parameter `i` of the effect means, at zero, that the effect is not
    /// there (its [`read`](Self::read) of a model without it): every parameter but a
    /// clearance's peak angle, which places a deflection rather than sizing it.
    pub(crate) fn absence_of(self, i: usize) -> bool {
        !(self == EffectId::Clearance && i % 2 == 1)
    }

    /// The effect's parameters as the model holds them (zeros when absent).
    pub(crate) fn read(self, m: &ModelSpec) -> Vec<f64> {
        let n = m.robot.n_tubes();
        let pairs = n.saturating_sub(1);
        let e = &m.effects;
        let or0 = |v: &[f64], len: usize| -> Vec<f64> {
            (0..len).map(|i| v.get(i).copied().unwrap_or(0.0)).collect()
        };
        match self {
            EffectId::Torsion => vec![],
            EffectId::Friction => e.friction.as_ref().map_or(vec![0.0; 2 * pairs + n], |f| {
                let mut x = or0(&f.rotation_play_deg, pairs);
                x.extend(or0(&f.feed_play_mm, n));
                x.extend(or0(&f.rotation_friction_coefficient, pairs));
                x
            }),
            EffectId::Clearance => e.clearance.as_ref().map_or(vec![0.0; 2 * pairs], |c| {
                (0..pairs)
                    .flat_map(|i| {
                        [
                            c.max_deflection_deg.get(i).copied().unwrap_or(0.0),
                            c.peak_deg.get(i).copied().unwrap_or(0.0),
                        ]
                    })
                    .collect()
            }),
            EffectId::Gravity => e.gravity.as_ref().map_or(vec![0.0; 3], |g| {
                g.direction_w.iter().map(|d| d * g.g_m_s2).collect()
            }),
            EffectId::Registration => e.registration.map_or(vec![0.0; 6], |r| {
                let mut x = r.translation_mm.to_vec();
                x.extend(r.rotation_vector_deg());
                x
            }),
            EffectId::JointOffset => e.joint_offset.as_ref().map_or(vec![0.0; 2 * n], |o| {
                let mut x = or0(&o.feed_mm, n);
                x.extend(or0(&o.rotation_deg, n));
                x
            }),
            EffectId::Stiffness => e
                .stiffness
                .as_ref()
                .map_or(vec![0.0; n], |s| s.factor.iter().map(|f| f.ln()).collect()),
            EffectId::Precurvature => e.precurvature.as_ref().map_or(vec![0.0; n], |p| {
                p.radius_factor.iter().map(|f| f.ln()).collect()
            }),
            EffectId::Latency => vec![e.latency.map_or(0.0, |l| l.tau_s)],
            EffectId::SensorOffset => e
                .sensor_offset
                .map_or(vec![0.0; 3], |s| s.offset_mm.to_vec()),
            EffectId::SensorRotation => e
                .sensor_rotation
                .map_or(vec![0.0; 3], |s| s.rotation_vector_deg.to_vec()),
        }
    }

    /// Writes the effect with parameters `x` into the model (turning it on).
    pub(crate) fn write(self, m: &mut ModelSpec, x: &[f64]) {
        let n = m.robot.n_tubes();
        let pairs = n.saturating_sub(1);
        let e = &mut m.effects;
        match self {
            EffectId::Torsion => m.model = Model::Torsion,
            EffectId::Friction => {
                let coefficient = &x[pairs + n..2 * pairs + n];
                e.friction = Some(Friction {
                    rotation_play_deg: x[..pairs].to_vec(),
                    feed_play_mm: x[pairs..pairs + n].to_vec(),
                    // none written where none is fitted: the file stays the contract's
                    rotation_friction_coefficient: if coefficient.iter().any(|&m| m != 0.0) {
                        coefficient.to_vec()
                    } else {
                        Vec::new()
                    },
                })
            }
            EffectId::Clearance => {
                e.clearance = Some(Clearance {
                    max_deflection_deg: (0..pairs).map(|i| x[2 * i]).collect(),
                    peak_deg: (0..pairs).map(|i| x[2 * i + 1].rem_euclid(360.0)).collect(),
                    table_deg: vec![],
                })
            }
            EffectId::Gravity => {
                let g = nalgebra::Vector3::new(x[0], x[1], x[2]);
                let size = g.norm();
                e.gravity = Some(if size > 0.0 {
                    Gravity {
                        direction_w: (g / size).into(),
                        g_m_s2: size,
                    }
                } else {
                    Gravity {
                        direction_w: [-1.0, 0.0, 0.0],
                        g_m_s2: 0.0,
                    }
                })
            }
            EffectId::Registration => {
                e.registration = Some(Registration::from_rotation_vector(
                    [x[3], x[4], x[5]],
                    [x[0], x[1], x[2]],
                ))
            }
            EffectId::JointOffset => {
                e.joint_offset = Some(JointOffset {
                    feed_mm: x[..n].to_vec(),
                    rotation_deg: x[n..2 * n].to_vec(),
                })
            }
            EffectId::Stiffness => {
                e.stiffness = Some(Stiffness {
                    factor: x.iter().map(|v| v.exp()).collect(),
                })
            }
            EffectId::Precurvature => {
                e.precurvature = Some(Precurvature {
                    radius_factor: x.iter().map(|v| v.exp()).collect(),
                })
            }
            EffectId::Latency => e.latency = Some(Latency { tau_s: x[0] }),
            EffectId::SensorOffset => {
                e.sensor_offset = Some(SensorOffset {
                    offset_mm: [x[0], x[1], x[2]],
                })
            }
            EffectId::SensorRotation => {
                e.sensor_rotation = Some(SensorRotation {
                    rotation_vector_deg: [x[0], x[1], x[2]],
                })
            }
        }
    }
}

/// A fitted parameter in words (see [`EffectId::label`]).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Label {
    /// What it is (`stiffness factor of tube 2`).
    pub name: String,
    /// Its unit in the file (empty for a factor).
    pub unit: &'static str,
    /// True when the fit's parameter is the natural log of the file's factor.
    pub log: bool,
}

/// Largest rotation play half-width a fit may reach, deg.
const MAX_ROTATION_PLAY_DEG: f64 = 45.0;
/// Largest feed play half-width, mm.
const MAX_FEED_PLAY_MM: f64 = 5.0;
/// Largest friction coefficient `mu'` of the contact moment (dimensionless; on a
/// nitinol robot of usual size, 0.5 winds up tens of degrees).
const MAX_FRICTION_COEFFICIENT: f64 = 0.5;
/// Finite-difference step of a friction coefficient (a few hundredths of a degree of
/// play on a nitinol robot of usual size).
const FRICTION_COEFFICIENT_STEP: f64 = 5e-4;
/// Largest clearance kink, deg.
const MAX_KINK_DEG: f64 = 20.0;
/// Largest gravity component, m/s^2 (three times standard gravity: a density error).
const MAX_GRAVITY_M_S2: f64 = 30.0;
/// Largest feed offset, mm.
const MAX_FEED_OFFSET_MM: f64 = 15.0;
/// Largest |ln factor| of stiffness and radius factors (a factor of e^2 either way).
const MAX_LN_FACTOR: f64 = 2.0;
/// Largest |latency|, s.
const MAX_LATENCY_S: f64 = 5.0;
/// Largest sensor offset component, mm.
const MAX_SENSOR_OFFSET_MM: f64 = 50.0;
/// Largest component of a sensor's rotation vector, deg (a sensor mounted turned by
/// more is a wrong sensor axis, not a calibration).
const MAX_SENSOR_ROTATION_DEG: f64 = 45.0;

/// Why a candidate cannot be tried on this model and recording, if so.
pub(crate) fn not_applicable(
    effect: EffectId,
    model: &ModelSpec,
    rec: &Recording,
) -> Option<String> {
    let densities = model
        .robot
        .tube_params()
        .iter()
        .all(|p| p.density_kg_m3.is_some());
    match effect {
        EffectId::Latency if rec.is_static() => Some(
            "not tried: a static configuration set (its rows are held poses, not a time \
             series): latency cannot be seen"
                .into(),
        ),
        EffectId::Latency if !rec.has_time => {
            Some("the recording has no t_s column: latency cannot be seen".into())
        }
        EffectId::Gravity if !densities => {
            Some("not tried: the robot file gives no density_kg_m3 for every tube".into())
        }
        EffectId::Gravity if model.model == Model::Rigid => Some(
            "not tried on a rigid model: the loaded solver models torsion too, so a gravity \
             fit would also bring torsion in (torsion is tried first)"
                .into(),
        ),
        EffectId::Gravity if model.effects.clearance.is_some() => {
            Some("not tried: gravity together with clearance is not modelled".into())
        }
        EffectId::Clearance if model.effects.gravity.is_some() => {
            Some("not tried: clearance together with gravity is not modelled".into())
        }
        EffectId::SensorRotation if rec.angular.is_none() => Some(
            "not tried: a sensor's rotation shows only in orientation or tangent columns, \
             and the recording has none (or their noise cannot be estimated)"
                .into(),
        ),
        EffectId::Clearance | EffectId::Friction if model.robot.n_tubes() < 2 => {
            Some("not tried: one tube has no neighbour".into())
        }
        _ => None,
    }
}

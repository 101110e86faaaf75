//! `[model.effects]`: the effects of the formats contract as typed tables, in file units
//! (mm, degrees, seconds, scale factors).
//!
//! ```toml
//! [model.effects.joint_offset]      # actual = commanded + offset
//! feed_mm = [0.0, 0.4]              # per tube (default zeros)
//! rotation_deg = [0.0, -3.0]        # per tube (default zeros)
//!
//! [model.effects.latency]
//! tau_s = 0.1                       # > 0: the robot lags the commands
//!
//! [model.effects.friction]          # play operators (hysteresis)
//! rotation_play_deg = [8.0]         # half-width per neighbouring pair, theta_{i+1} - theta_i
//! feed_play_mm = [0.0, 0.0]         # half-width per tube (optional, default zeros)
//! rotation_friction_coefficient = [0.0]  # per pair (optional): the seed's mu', adds
//!                                   # mu' |M| (wind-up compliance) to the half-width
//!
//! [model.effects.clearance]         # kink where tube i+1 leaves tube i, per pair
//! max_deflection_deg = [2.5]        # delta = max (1 + cos(phi - peak)) / 2
//! peak_deg = [205.0]
//! # or a measured table per pair, evenly spaced over one turn from phi = 0:
//! # table_deg = [[0.0, 0.3, 1.2, ...]]
//!
//! [model.effects.gravity]
//! direction_W = [-1.0, 0.0, 0.0]    # unit direction of g in W
//! g_m_s2 = 9.81                     # default 9.81; needs every tube's density_kg_m3
//!
//! [model.effects.registration]      # p_measured = R p_W + t
//! translation_mm = [3.0, -2.0, 5.0]
//! rotation_axis = [0.3, 0.9, 0.3]   # normalised when read
//! rotation_deg = 2.0
//!
//! [model.effects.stiffness]         # each tube's E (so E I and G J) times factor
//! factor = [1.0, 1.1]
//!
//! [model.effects.precurvature]      # each tube's curvature radius times radius_factor
//! radius_factor = [1.0, 0.95]
//!
//! [model.effects.sensor_offset]     # tracked point in the tip frame
//! offset_mm = [0.0, 0.0, -2.0]
//!
//! [model.effects.sensor_rotation]   # sensor frame in the tip frame: R_measured = R_tip S
//! rotation_vector_deg = [3.0, 0.0, 0.0]   # axis times angle, in the tip frame
//! ```
//!
//! The order in which they act on a row: joint offsets, then latency along the run,
//! then friction on the delayed path (`ctr_analysis::timeline`); the mechanics with the
//! scaled tubes, clearance kinks and gravity; then the sensor offset, the sensor's
//! rotation (this project's extension of the vocabulary: it turns the measured
//! orientation and tangent only) and the registration (`docs/formats.md`'s conventions, those of
//! `tests/data/shared/recordings/*.truth.json`). Clearance and gravity together are not
//! modelled (the loaded solver has no kinks) and are refused.

use ctr_core::effects::{
    ClearanceProfile, Effects as CoreEffects, Registration as CoreRegistration,
    CLEARANCE_TABLE_CAPACITY,
};
use serde::{Deserialize, Serialize};

/// `[model.effects]`: one optional table per effect id of the formats contract.
///
/// ```
/// use ctr_formats::{Effects, Latency};
/// let e = Effects { latency: Some(Latency { tau_s: 0.1 }), ..Default::default() };
/// assert_eq!(e.present(), ["latency"]);
/// ```
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    /// `joint_offset`: actuator zero offsets.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_offset: Option<JointOffset>,
    /// `latency`: the robot lags the commands in time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency: Option<Latency>,
    /// `friction`: play (hysteresis) in relative rotation and feed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<Friction>,
    /// `clearance`: kinks where inner tubes leave outer tubes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clearance: Option<Clearance>,
    /// `gravity`: the tubes' own weight.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<Gravity>,
    /// `stiffness`: each tube's modulus scaled.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<Stiffness>,
    /// `precurvature`: each tube's curvature radius scaled.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub precurvature: Option<Precurvature>,
    /// `sensor_offset`: tracked point in the tip frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor_offset: Option<SensorOffset>,
    /// `sensor_rotation` (this project's extension): the tracked sensor's frame turned
    /// in the tip frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor_rotation: Option<SensorRotation>,
    /// `registration`: tracker frame offset from W.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub registration: Option<Registration>,
}

/// `[model.effects.joint_offset]`: actual = commanded + offset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointOffset {
    /// Feed offsets per tube, mm (default zeros).
    #[serde(default)]
    pub feed_mm: Vec<f64>,
    /// Rotation offsets per tube, degrees (default zeros).
    #[serde(default)]
    pub rotation_deg: Vec<f64>,
}

/// `[model.effects.latency]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Latency {
    /// Delay of the robot behind its commands, s (negative: a lead).
    pub tau_s: f64,
}

/// `[model.effects.friction]`: play operators on relative rotations and feeds.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    /// Half-width of the play of `theta_{i+1} - theta_i`, per neighbouring pair, degrees.
    #[serde(default)]
    pub rotation_play_deg: Vec<f64>,
    /// Half-width of the feed play per tube, mm (default zeros).
    #[serde(default)]
    pub feed_play_mm: Vec<f64>,
    /// The seed's boundary friction coefficient `mu'` per neighbouring pair
    /// (dimensionless, default zeros; this project's extension): the rotation play's
    /// half-width grows by `mu' |M|` times the pair's torsional compliance, `M` the
    /// bending moment the outer tube of the pair carries at its tip (Liu et al. 2023,
    /// eq. 10; `ctr_analysis::contact`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rotation_friction_coefficient: Vec<f64>,
}

impl Friction {
    /// Whether it acts at all: a play or a coefficient above zero (then the tip depends
    /// on the rows before it).
    ///
    /// ```
    /// use ctr_formats::Friction;
    /// assert!(!Friction::default().acts());
    /// assert!(Friction { rotation_friction_coefficient: vec![0.02], ..Friction::default() }.acts());
    /// ```
    pub fn acts(&self) -> bool {
        self.rotation_play_deg
            .iter()
            .chain(&self.feed_play_mm)
            .chain(&self.rotation_friction_coefficient)
            .any(|&w| w > 0.0)
    }

    /// Whether a pair's play grows with the contact moment (a coefficient above zero):
    /// then the play depends on the tubes' stiffness and precurvature too, through
    /// the moment they carry.
    ///
    /// ```
    /// use ctr_formats::Friction;
    /// let play = Friction { rotation_play_deg: vec![1.0], ..Friction::default() };
    /// assert!(!play.grows_with_contact());
    /// assert!(Friction { rotation_friction_coefficient: vec![0.02], ..play }.grows_with_contact());
    /// ```
    pub fn grows_with_contact(&self) -> bool {
        self.rotation_friction_coefficient.iter().any(|&m| m > 0.0)
    }
}

/// `[model.effects.clearance]`: per neighbouring pair, a cosine profile
/// (`max_deflection_deg`, `peak_deg`) or a table (`table_deg`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Clearance {
    /// Largest deflection per pair, degrees (cosine profile).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub max_deflection_deg: Vec<f64>,
    /// Relative angle of the largest deflection per pair, degrees (cosine profile).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub peak_deg: Vec<f64>,
    /// Deflection tables per pair, degrees, evenly spaced over one turn from 0.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub table_deg: Vec<Vec<f64>>,
}

/// How many values per pair a fitted clearance table may have: the range of `ctr-cli
/// calibrate --table` and of `ctr_py.calibrate(table=)` (a file's `table_deg` may hold
/// from 1 to [`CLEARANCE_TABLE_CAPACITY`]).
pub const CLEARANCE_FIT_TABLE_SIZES: std::ops::RangeInclusive<usize> = 3..=CLEARANCE_TABLE_CAPACITY;

/// `[model.effects.gravity]`: uniform gravity on the exposed tubes (needs each tube's
/// `density_kg_m3`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// Unit direction of gravity in W (`direction_W`).
    #[serde(rename = "direction_W", deserialize_with = "super::toml_doc::exact")]
    pub direction_w: [f64; 3],
    /// Acceleration, m/s^2 (default 9.81).
    #[serde(default = "standard_gravity")]
    pub g_m_s2: f64,
}

fn standard_gravity() -> f64 {
    ctr_core::STANDARD_GRAVITY_M_S2
}

/// `[model.effects.stiffness]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stiffness {
    /// Each tube's E (so E I and G J) is multiplied by its factor; > 0.
    pub factor: Vec<f64>,
}

/// `[model.effects.precurvature]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Precurvature {
    /// Each tube's curvature radius is multiplied by its factor; > 0.
    pub radius_factor: Vec<f64>,
}

/// `[model.effects.sensor_offset]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorOffset {
    /// The tracked point in the tip frame, mm.
    #[serde(deserialize_with = "super::toml_doc::exact")]
    pub offset_mm: [f64; 3],
}

/// `[model.effects.sensor_rotation]`: the tracked sensor's frame in the tip frame, `S`:
/// the rotation about `rotation_vector_deg` (in the tip frame) by its length in degrees.
/// The measured orientation is `R_tip S`, its tangent (z axis) `R_tip S z`: the hand-eye
/// part of a tracker's calibration; the tracked point stays where `sensor_offset` puts
/// it. (A rotation vector rather than an axis and an angle: a tangent sees no roll about
/// z, and each component then keeps its own interval.)
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorRotation {
    /// `S` as a rotation vector in the tip frame, deg (axis times angle).
    #[serde(deserialize_with = "super::toml_doc::exact")]
    pub rotation_vector_deg: [f64; 3],
}

impl SensorRotation {
    /// The rotation matrix `S`.
    ///
    /// ```
    /// let s = ctr_formats::SensorRotation { rotation_vector_deg: [90.0, 0.0, 0.0] };
    /// let m = s.matrix();
    /// assert!((m[(2, 1)] - 1.0).abs() < 1e-12); // y turns into z
    /// ```
    pub fn matrix(&self) -> nalgebra::Matrix3<f64> {
        let v = nalgebra::Vector3::from(self.rotation_vector_deg).map(f64::to_radians);
        *nalgebra::Rotation3::new(v).matrix()
    }
}

/// `[model.effects.registration]`: `p_measured = R p_W + t`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Registration {
    /// `t`, mm.
    #[serde(default, deserialize_with = "super::toml_doc::exact")]
    pub translation_mm: [f64; 3],
    /// Axis of `R` (normalised when used; default `[0, 0, 1]`).
    #[serde(default = "z_axis", deserialize_with = "super::toml_doc::exact")]
    pub rotation_axis: [f64; 3],
    /// Angle of `R` about the axis, degrees (default 0).
    #[serde(default)]
    pub rotation_deg: f64,
}

fn z_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

impl Registration {
    /// From a rotation vector (axis times angle, degrees) and a translation.
    ///
    /// ```
    /// let r = ctr_formats::Registration::from_rotation_vector([0.0, 0.0, 2.0], [1.0, 0.0, 0.0]);
    /// assert_eq!(r.rotation_deg, 2.0);
    /// assert_eq!(r.rotation_axis, [0.0, 0.0, 1.0]);
    /// ```
    pub fn from_rotation_vector(rotation_vector_deg: [f64; 3], translation_mm: [f64; 3]) -> Self {
        let v = nalgebra::Vector3::from(rotation_vector_deg);
        let angle = v.norm();
        let axis = if angle > 0.0 {
            v / angle
        } else {
            nalgebra::Vector3::z()
        };
        Registration {
            translation_mm,
            rotation_axis: axis.into(),
            rotation_deg: angle,
        }
    }

    /// The rotation vector (unit axis times angle, degrees).
    pub fn rotation_vector_deg(&self) -> [f64; 3] {
        let a = nalgebra::Vector3::from(self.rotation_axis);
        let n = a.norm();
        if n > 0.0 {
            (a * (self.rotation_deg / n)).into()
        } else {
            [0.0; 3]
        }
    }
}

/// What is wrong with an effect table: the key path below `model.effects` and a message.
pub type EffectProblem = (Vec<&'static str>, String);

fn check_len(
    effect: &'static str,
    key: &'static str,
    v: &[f64],
    want: usize,
    what: &str,
) -> Result<(), EffectProblem> {
    if v.len() != want {
        return Err((
            vec![effect, key],
            format!(
                "model.effects.{effect}.{key}: {} value{}, wanted {want} (one per {what})",
                v.len(),
                if v.len() == 1 { "" } else { "s" }
            ),
        ));
    }
    check_finite(effect, key, v)
}

fn check_finite(effect: &'static str, key: &'static str, v: &[f64]) -> Result<(), EffectProblem> {
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        return Err((
            vec![effect, key],
            format!("model.effects.{effect}.{key}: {x} is not a finite number"),
        ));
    }
    Ok(())
}

fn check_positive(effect: &'static str, key: &'static str, v: &[f64]) -> Result<(), EffectProblem> {
    if let Some(x) = v.iter().find(|x| x.is_nan() || **x <= 0.0) {
        return Err((
            vec![effect, key],
            format!("model.effects.{effect}.{key}: {x} must be positive"),
        ));
    }
    Ok(())
}

fn check_non_negative(
    effect: &'static str,
    key: &'static str,
    v: &[f64],
) -> Result<(), EffectProblem> {
    if let Some(x) = v.iter().find(|x| x.is_nan() || **x < 0.0) {
        return Err((
            vec![effect, key],
            format!("model.effects.{effect}.{key}: {x} must be zero or positive"),
        ));
    }
    Ok(())
}

/// `joint_offset` of a robot of `n` tubes: each list empty or one value per tube.
fn check_joint_offset(o: &JointOffset, n: usize) -> Result<(), EffectProblem> {
    if !o.feed_mm.is_empty() {
        check_len("joint_offset", "feed_mm", &o.feed_mm, n, "tube")?;
    }
    if !o.rotation_deg.is_empty() {
        check_len("joint_offset", "rotation_deg", &o.rotation_deg, n, "tube")?;
    }
    Ok(())
}

/// `friction` of a robot of `n` tubes: a rotation play per neighbouring pair (optional
/// beside the contact's coefficients, one per pair), feed plays per tube (optional), none
/// negative.
fn check_friction(f: &Friction, n: usize) -> Result<(), EffectProblem> {
    let pairs = n.saturating_sub(1);
    // the plays may be left out where the contact's coefficients give the friction
    if !f.rotation_play_deg.is_empty() || (pairs > 0 && f.rotation_friction_coefficient.is_empty())
    {
        check_len(
            "friction",
            "rotation_play_deg",
            &f.rotation_play_deg,
            pairs,
            "neighbouring pair of tubes",
        )?;
    }
    check_non_negative("friction", "rotation_play_deg", &f.rotation_play_deg)?;
    if !f.feed_play_mm.is_empty() {
        check_len("friction", "feed_play_mm", &f.feed_play_mm, n, "tube")?;
        check_non_negative("friction", "feed_play_mm", &f.feed_play_mm)?;
    }
    if !f.rotation_friction_coefficient.is_empty() {
        let mu = &f.rotation_friction_coefficient;
        let field = "rotation_friction_coefficient";
        check_len("friction", field, mu, pairs, "neighbouring pair of tubes")?;
        check_non_negative("friction", field, mu)?;
    }
    Ok(())
}

/// `clearance` with `pairs` neighbouring pairs of tubes: either the cosine profile
/// or a table per pair, not both.
fn check_clearance(c: &Clearance, pairs: usize) -> Result<(), EffectProblem> {
    let cosine = !c.max_deflection_deg.is_empty() || !c.peak_deg.is_empty();
    let table = !c.table_deg.is_empty();
    if cosine == table {
        return Err((
            vec!["clearance"],
            "model.effects.clearance: give either max_deflection_deg and peak_deg \
             (a cosine profile) or table_deg (a table per pair), not both or neither"
                .into(),
        ));
    }
    if cosine {
        let pair = "neighbouring pair of tubes";
        check_len(
            "clearance",
            "max_deflection_deg",
            &c.max_deflection_deg,
            pairs,
            pair,
        )?;
        return check_len("clearance", "peak_deg", &c.peak_deg, pairs, pair);
    }
    if c.table_deg.len() != pairs {
        return Err((
            vec!["clearance", "table_deg"],
            format!(
                "model.effects.clearance.table_deg: {} tables, wanted {pairs} \
                 (one per neighbouring pair of tubes)",
                c.table_deg.len()
            ),
        ));
    }
    for t in &c.table_deg {
        if t.is_empty() || t.len() > CLEARANCE_TABLE_CAPACITY {
            return Err((
                vec!["clearance", "table_deg"],
                format!(
                    "model.effects.clearance.table_deg: a table of {} values, \
                     wanted 1 to {CLEARANCE_TABLE_CAPACITY}",
                    t.len()
                ),
            ));
        }
        check_finite("clearance", "table_deg", t)?;
    }
    Ok(())
}

/// `gravity`: a finite, non-zero direction, every tube's density (`has_density`) to
/// weigh it, and no clearance beside it (`with_clearance`).
fn check_gravity(
    g: &Gravity,
    has_density: bool,
    with_clearance: bool,
) -> Result<(), EffectProblem> {
    check_finite("gravity", "direction_W", &g.direction_w)?;
    check_finite("gravity", "g_m_s2", &[g.g_m_s2])?;
    if g.direction_w.iter().all(|&x| x == 0.0) {
        return Err((
            vec!["gravity", "direction_W"],
            "model.effects.gravity.direction_W: [0, 0, 0] has no direction; wanted a \
             unit vector in W"
                .into(),
        ));
    }
    if !has_density {
        return Err((
            vec!["gravity"],
            "model.effects.gravity: every tube needs density_kg_m3 to weigh it".into(),
        ));
    }
    if with_clearance {
        return Err((
            vec!["gravity"],
            "model.effects.gravity: gravity together with clearance is not modelled \
             (the loaded solver has no clearance kinks); keep one of them"
                .into(),
        ));
    }
    Ok(())
}

/// `registration`: finite numbers, and an axis wherever there is a rotation.
fn check_registration(r: &Registration) -> Result<(), EffectProblem> {
    check_finite("registration", "translation_mm", &r.translation_mm)?;
    check_finite("registration", "rotation_axis", &r.rotation_axis)?;
    check_finite("registration", "rotation_deg", &[r.rotation_deg])?;
    if r.rotation_deg != 0.0 && r.rotation_axis.iter().all(|&x| x == 0.0) {
        return Err((
            vec!["registration", "rotation_axis"],
            "model.effects.registration.rotation_axis: [0, 0, 0] has no direction".into(),
        ));
    }
    Ok(())
}

impl Effects {
    /// The ids of the effects present, in the order they act.
    ///
    /// ```
    /// assert!(ctr_formats::Effects::default().present().is_empty());
    /// ```
    pub fn present(&self) -> Vec<&'static str> {
        let Effects {
            joint_offset,
            latency,
            friction,
            clearance,
            gravity,
            stiffness,
            precurvature,
            sensor_offset,
            sensor_rotation,
            registration,
        } = self;
        [
            ("joint_offset", joint_offset.is_some()),
            ("latency", latency.is_some()),
            ("friction", friction.is_some()),
            ("clearance", clearance.is_some()),
            ("gravity", gravity.is_some()),
            ("stiffness", stiffness.is_some()),
            ("precurvature", precurvature.is_some()),
            ("sensor_offset", sensor_offset.is_some()),
            ("sensor_rotation", sensor_rotation.is_some()),
            ("registration", registration.is_some()),
        ]
        .into_iter()
        .filter_map(|(id, on)| on.then_some(id))
        .collect()
    }

    /// True when no effect table is present.
    pub fn is_empty(&self) -> bool {
        self.present().is_empty()
    }

    /// True when an effect needs the rows' order and times (latency, friction).
    pub fn needs_time(&self) -> bool {
        self.latency.is_some_and(|l| l.tau_s != 0.0)
            || self.friction.as_ref().is_some_and(Friction::acts)
    }

    /// Checks every table against a robot of `n` tubes (lengths, finite and positive
    /// values, what the tube densities allow). `has_density` tells whether every tube has
    /// a density (gravity needs it).
    pub fn check(&self, n: usize, has_density: bool) -> Result<(), EffectProblem> {
        let pairs = n.saturating_sub(1);
        if let Some(o) = &self.joint_offset {
            check_joint_offset(o, n)?;
        }
        if let Some(l) = &self.latency {
            check_finite("latency", "tau_s", &[l.tau_s])?;
        }
        if let Some(f) = &self.friction {
            check_friction(f, n)?;
        }
        if let Some(c) = &self.clearance {
            check_clearance(c, pairs)?;
        }
        if let Some(g) = &self.gravity {
            check_gravity(g, has_density, self.clearance.is_some())?;
        }
        if let Some(s) = &self.stiffness {
            check_len("stiffness", "factor", &s.factor, n, "tube")?;
            check_positive("stiffness", "factor", &s.factor)?;
        }
        if let Some(p) = &self.precurvature {
            check_len("precurvature", "radius_factor", &p.radius_factor, n, "tube")?;
            check_positive("precurvature", "radius_factor", &p.radius_factor)?;
        }
        if let Some(s) = &self.sensor_offset {
            check_finite("sensor_offset", "offset_mm", &s.offset_mm)?;
        }
        if let Some(r) = &self.sensor_rotation {
            check_finite(
                "sensor_rotation",
                "rotation_vector_deg",
                &r.rotation_vector_deg,
            )?;
        }
        if let Some(r) = &self.registration {
            check_registration(r)?;
        }
        Ok(())
    }

    /// The core's per-solve effects: clearance kinks, sensor offset, registration (the
    /// joint offsets are applied along the time series instead, so they are zero here).
    ///
    /// ```
    /// use ctr_formats::{Effects, SensorOffset};
    /// let e = Effects { sensor_offset: Some(SensorOffset { offset_mm: [0.0, 0.0, 2.0] }), ..Default::default() };
    /// assert_eq!(e.core_effects::<2>().sensor_offset_mm, [0.0, 0.0, 2.0]);
    /// ```
    pub fn core_effects<const N: usize>(&self) -> CoreEffects<f64, N> {
        let mut e = CoreEffects::<f64, N>::default();
        if let Some(c) = &self.clearance {
            for i in 0..N.saturating_sub(1) {
                e.clearance[i] = if !c.table_deg.is_empty() {
                    let t: Vec<f64> = c.table_deg[i].iter().map(|d| d.to_radians()).collect();
                    ClearanceProfile::table(&t)
                } else {
                    let max = c.max_deflection_deg[i];
                    (max != 0.0).then(|| ClearanceProfile::Cosine {
                        max_deflection_rad: max.to_radians(),
                        peak_rad: c.peak_deg[i].to_radians(),
                    })
                };
            }
        }
        if let Some(s) = self.sensor_offset {
            e.sensor_offset_mm = s.offset_mm;
        }
        if let Some(s) = self.sensor_rotation {
            e.sensor_rotation = Some(s.matrix());
        }
        if let Some(r) = self.registration {
            e.registration = Some(CoreRegistration::from_axis_angle(
                if r.rotation_axis.iter().all(|&x| x == 0.0) {
                    z_axis()
                } else {
                    r.rotation_axis
                },
                r.rotation_deg.to_radians(),
                r.translation_mm,
            ));
        }
        e
    }

    /// Stiffness and radius factors per tube (ones where absent).
    pub fn scale_factors(&self, n: usize) -> (Vec<f64>, Vec<f64>) {
        let stiffness = self
            .stiffness
            .as_ref()
            .map_or(vec![1.0; n], |s| s.factor.clone());
        let radius = self
            .precurvature
            .as_ref()
            .map_or(vec![1.0; n], |p| p.radius_factor.clone());
        (stiffness, radius)
    }
}

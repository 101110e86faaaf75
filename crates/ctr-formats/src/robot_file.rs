//! The robot TOML: its serde mirror [`RobotFile`] and the validated [`RobotSpec`].
//!
//! The shape is documented in [the module above](super).

use super::actuation::{ActuatedJoint, ActuationSection};
use super::discrepancy::{Discrepancy, DiscrepancyFile};
use super::effects::Effects;
use super::empirical::{Correction, Empirical};
use super::toml_doc::{exact_opt, line_col, one_line, path_at, span_of, without_bom, Key};
use crate::error::{Error, ErrorKind, Location};
use crate::robot::AnyRobot;
use ctr_core::{Model, RobotError, TubeParams};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The robot TOML as written, before validation. Unknown keys are refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotFile {
    /// The robot's name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The tubes, outermost first (`[[tube]]`).
    pub tube: Vec<TubeFile>,
    /// `[model]`: which mechanics to solve with (extension; default `torsion`, no effects).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<ModelSection>,
    /// `[limits]`: joint ranges, one `[[limits.tube]]` per tube (extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limits: Option<LimitsSection>,
    /// `[actuation]`: the motor driving each joint, one `[[actuation.joint]]` per joint
    /// (extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actuation: Option<ActuationSection>,
}

/// One `[[tube]]` table: the fields of [`TubeParams`] plus an optional name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TubeFile {
    /// The tube's name (`outer`, `inner`, ...).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Outer diameter, mm.
    pub outer_diameter_mm: f64,
    /// Inner diameter, mm.
    pub inner_diameter_mm: f64,
    /// Whole length from actuator to tip, mm.
    pub length_mm: f64,
    /// Length of the precurved distal part, mm.
    pub curved_length_mm: f64,
    /// Signed radius of the precurved part, mm; absent for a straight tube.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub curvature_radius_mm: Option<f64>,
    /// Young's modulus, MPa.
    pub youngs_modulus_mpa: f64,
    /// Poisson ratio.
    pub poisson_ratio: f64,
    /// Measured bending stiffness E I, N mm^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bending_stiffness_nmm2: Option<f64>,
    /// Measured torsional stiffness G J, N mm^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torsional_stiffness_nmm2: Option<f64>,
    /// Density, kg/m^3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density_kg_m3: Option<f64>,
}

impl TubeFile {
    /// The core's parameters (the name is dropped).
    pub fn params(&self) -> TubeParams<f64> {
        TubeParams {
            outer_diameter_mm: self.outer_diameter_mm,
            inner_diameter_mm: self.inner_diameter_mm,
            length_mm: self.length_mm,
            curved_length_mm: self.curved_length_mm,
            curvature_radius_mm: self.curvature_radius_mm,
            youngs_modulus_mpa: self.youngs_modulus_mpa,
            poisson_ratio: self.poisson_ratio,
            bending_stiffness_nmm2: self.bending_stiffness_nmm2,
            torsional_stiffness_nmm2: self.torsional_stiffness_nmm2,
            density_kg_m3: self.density_kg_m3,
        }
    }

    /// A table from the core's parameters and a name.
    pub fn from_params(name: Option<String>, p: &TubeParams<f64>) -> Self {
        TubeFile {
            name,
            outer_diameter_mm: p.outer_diameter_mm,
            inner_diameter_mm: p.inner_diameter_mm,
            length_mm: p.length_mm,
            curved_length_mm: p.curved_length_mm,
            curvature_radius_mm: p.curvature_radius_mm,
            youngs_modulus_mpa: p.youngs_modulus_mpa,
            poisson_ratio: p.poisson_ratio,
            bending_stiffness_nmm2: p.bending_stiffness_nmm2,
            torsional_stiffness_nmm2: p.torsional_stiffness_nmm2,
            density_kg_m3: p.density_kg_m3,
        }
    }
}

/// `[model]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSection {
    /// `kind = "rigid" | "torsion"`, default `torsion`.
    #[serde(default)]
    pub kind: ModelKind,
    /// `[model.effects]`: effects beyond the base model.
    #[serde(default, skip_serializing_if = "Effects::is_empty")]
    pub effects: Effects,
    /// `[model.empirical]`: a labelled data-driven correction of the tip (not physics).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub empirical: Option<Empirical>,
    /// `[model.discrepancy]`: a learned discrepancy of the tip over the joints and
    /// their history (not physics).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub discrepancy: Option<DiscrepancyFile>,
}

/// The base model of `[model] kind`, and the one table of its names ([`name`](Self::name),
/// [`FromStr`](std::str::FromStr); serde's lowercase names are the same, see the test).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Torsionally rigid tubes.
    Rigid,
    /// Torsionally compliant tubes.
    #[default]
    Torsion,
}

impl ModelKind {
    /// Every kind, in the order messages list them.
    pub const ALL: [ModelKind; 2] = [ModelKind::Rigid, ModelKind::Torsion];

    /// The kind's name, as `[model] kind`, `ctr-cli --model` and `ctr_py`'s `model=`
    /// spell it: `rigid`, `torsion`.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Rigid => "rigid",
            ModelKind::Torsion => "torsion",
        }
    }
}

impl std::fmt::Display for ModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is not a [`ModelKind`]'s (exactly, case and spaces included).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownModelKind(pub String);

impl std::fmt::Display for UnknownModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<&str> = ModelKind::ALL.iter().map(|k| k.name()).collect();
        write!(f, "\"{}\" is not a model ({})", self.0, names.join(" or "))
    }
}

impl std::error::Error for UnknownModelKind {}

/// ```
/// use ctr_formats::ModelKind;
/// assert_eq!("rigid".parse(), Ok(ModelKind::Rigid));
/// let err = "Rigid".parse::<ModelKind>().unwrap_err();
/// assert_eq!(err.to_string(), "\"Rigid\" is not a model (rigid or torsion)");
/// ```
impl std::str::FromStr for ModelKind {
    type Err = UnknownModelKind;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ModelKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| UnknownModelKind(s.to_owned()))
    }
}

impl From<ModelKind> for Model {
    fn from(k: ModelKind) -> Model {
        match k {
            ModelKind::Rigid => Model::Rigid,
            ModelKind::Torsion => Model::Torsion,
        }
    }
}

impl From<Model> for ModelKind {
    fn from(m: Model) -> ModelKind {
        match m {
            Model::Rigid => ModelKind::Rigid,
            Model::Torsion => ModelKind::Torsion,
        }
    }
}

/// `[limits]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimitsSection {
    /// `[[limits.tube]]`, one per tube, outermost first.
    pub tube: Vec<TubeLimits>,
}

/// One `[[limits.tube]]`: closed `[min, max]` ranges, each optional (absent = free).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TubeLimits {
    /// Feed `s_i`, mm.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact_opt"
    )]
    pub s_mm: Option<[f64; 2]>,
    /// Increment `s_i - s_{i-1}` (with `s_0 = 0`), mm.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact_opt"
    )]
    pub increment_mm: Option<[f64; 2]>,
    /// Rotation `theta_i`, degrees.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "exact_opt"
    )]
    pub theta_deg: Option<[f64; 2]>,
}

impl TubeLimits {
    /// The first range this tube's joints leave, as `(key, value)`; `None` when inside all.
    /// `s_prev` is the enclosing tube's feed (0 for tube 1).
    ///
    /// ```
    /// use ctr_formats::TubeLimits;
    /// let l = TubeLimits { s_mm: Some([20.0, 70.0]), increment_mm: None, theta_deg: None };
    /// assert_eq!(l.violation(10.0, 0.0, 0.0), Some(("s_mm", 10.0)));
    /// assert_eq!(l.violation(30.0, 0.0, 0.0), None);
    /// ```
    pub fn violation(&self, s_mm: f64, theta_deg: f64, s_prev: f64) -> Option<(&'static str, f64)> {
        let outside =
            |r: Option<[f64; 2]>, v: f64| r.is_some_and(|[lo, hi]| !(lo..=hi).contains(&v));
        if outside(self.s_mm, s_mm) {
            Some(("s_mm", s_mm))
        } else if outside(self.increment_mm, s_mm - s_prev) {
            Some(("increment_mm", s_mm - s_prev))
        } else if outside(self.theta_deg, theta_deg) {
            Some(("theta_deg", theta_deg))
        } else {
            None
        }
    }
}

/// A validated robot description: the core robot, the model to solve with, the limits.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotSpec {
    /// The robot's name.
    pub name: Option<String>,
    /// Each tube's name, outermost first.
    pub tube_names: Vec<Option<String>>,
    /// The validated tubes.
    pub robot: AnyRobot,
    /// `[model] kind`.
    pub model: Model,
    /// `[model.effects]`, checked against the robot.
    pub effects: Effects,
    /// `[model.empirical]`, checked against the robot.
    pub empirical: Option<Correction>,
    /// `[model.discrepancy]`, checked against the robot.
    pub discrepancy: Option<Discrepancy>,
    /// `[limits]`, one entry per tube, every range finite with `min <= max`.
    pub limits: Option<Vec<TubeLimits>>,
    /// `[actuation]`, validated against the robot: exactly one feed and one rotation
    /// joint per tube, in joint-vector order (`s1, theta1, s2, theta2, ...`, the order
    /// of the joint columns).
    pub actuation: Option<Vec<ActuatedJoint>>,
}

impl RobotFile {
    /// Parses TOML text (a leading byte-order mark is skipped; CRLF line ends are TOML);
    /// `file` names it in errors, which carry line and column.
    pub fn parse(text: &str, file: &str) -> Result<RobotFile, Error> {
        let text = without_bom(text);
        toml::from_str(text).map_err(|e| {
            let mut location = Location::file(file);
            let mut message = one_line(e.message());
            if let Some(span) = e.span() {
                let (line, col) = line_col(text, span.start);
                location.line = Some(line);
                location.column = Some(col);
                if let Some(path) = path_at(text, span.start) {
                    message = format!("{path}: {message}");
                }
            }
            Error::new(location, ErrorKind::Toml { message })
        })
    }

    /// Serializes to TOML (tubes first, then `[model]`, `[limits]` and `[actuation]`).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a RobotFile always serializes")
    }

    /// Validates with the core; errors name `file` but no line (see
    /// [`RobotSpec::from_toml_str`] for errors with lines).
    pub fn validate(&self, file: &str) -> Result<RobotSpec, Error> {
        self.check()
            .map_err(|(kind, _)| Error::new(Location::file(file), kind))
    }

    /// Validates the tubes with the core, then `[model]`, `[limits]` and `[actuation]`
    /// against them; an error carries the key path it is about.
    fn check(&self) -> Result<RobotSpec, (ErrorKind, Vec<Key>)> {
        let params: Vec<TubeParams<f64>> = self.tube.iter().map(TubeFile::params).collect();
        let robot = AnyRobot::new(&params).map_err(|e| {
            let path = match robot_error_key(&e) {
                Some((tube, key)) => vec![Key::Name("tube"), Key::Index(tube - 1), Key::Name(key)],
                None => vec![],
            };
            (ErrorKind::Robot(e), path)
        })?;
        let section = self.model.clone().unwrap_or_default();
        let (empirical, discrepancy) = check_model(&section, &robot, &params)?;
        let limits = match &self.limits {
            None => None,
            Some(l) => Some(check_limits(l, params.len())?),
        };
        let actuation = match &self.actuation {
            None => None,
            Some(section) => Some(section.validate(params.len()).map_err(|e| {
                let message = e.to_string();
                (ErrorKind::Toml { message }, e.key_path())
            })?),
        };
        Ok(RobotSpec {
            name: self.name.clone(),
            tube_names: self.tube.iter().map(|t| t.name.clone()).collect(),
            robot,
            model: section.kind.into(),
            effects: section.effects,
            empirical,
            discrepancy,
            limits,
            actuation,
        })
    }
}

/// Checks `[model]` against the validated `robot` (of the tubes `params`): the
/// effects, the kind beside them, the empirical correction (returned, checked) and the
/// robot the scale factors make.
#[allow(clippy::type_complexity)]
fn check_model(
    section: &ModelSection,
    robot: &AnyRobot,
    params: &[TubeParams<f64>],
) -> Result<(Option<Correction>, Option<Discrepancy>), (ErrorKind, Vec<Key>)> {
    use Key::{Index, Name};
    let has_density = params.iter().all(|p| p.density_kg_m3.is_some());
    if let Err((keys, message)) = section.effects.check(params.len(), has_density) {
        let mut path = vec![Name("model"), Name("effects")];
        path.extend(keys.into_iter().map(Name));
        return Err((ErrorKind::Effect { message }, path));
    }
    if section.effects.gravity.is_some() && section.kind == ModelKind::Rigid {
        return Err((
            ErrorKind::Effect {
                message: "model.kind: \"rigid\" cannot be combined with \
                          model.effects.gravity (the loaded solver models torsion); use \
                          kind = \"torsion\""
                    .into(),
            },
            vec![Name("model"), Name("kind")],
        ));
    }
    let empirical = match &section.empirical {
        None => None,
        Some(e) => Some(
            Correction::check(e, params.len()).map_err(|((term, key), message)| {
                let path = vec![
                    Name("model"),
                    Name("empirical"),
                    Name("term"),
                    Index(term),
                    Name(key),
                ];
                (ErrorKind::Effect { message }, path)
            })?,
        ),
    };
    let discrepancy = match &section.discrepancy {
        None => None,
        Some(d) => Some(
            Discrepancy::check(d, params.len()).map_err(|(key, message)| {
                let path = vec![Name("model"), Name("discrepancy"), Name(key)];
                (ErrorKind::Effect { message }, path)
            })?,
        ),
    };
    let (stiffness, radius) = section.effects.scale_factors(params.len());
    if let Err(e) = robot.scaled(&stiffness, &radius) {
        return Err((ErrorKind::Robot(e), vec![Name("model"), Name("effects")]));
    }
    Ok((empirical, discrepancy))
}

/// Checks `[limits]`: one table per tube of `n`, every range finite with min <= max.
fn check_limits(l: &LimitsSection, n: usize) -> Result<Vec<TubeLimits>, (ErrorKind, Vec<Key>)> {
    use Key::{Index, Name};
    if l.tube.len() != n {
        return Err((
            ErrorKind::LimitsCount {
                expected: n,
                found: l.tube.len(),
            },
            vec![Name("limits")],
        ));
    }
    for (i, t) in l.tube.iter().enumerate() {
        for (key, range) in [
            ("s_mm", t.s_mm),
            ("increment_mm", t.increment_mm),
            ("theta_deg", t.theta_deg),
        ] {
            if let Some([min, max]) = range {
                if !(min.is_finite() && max.is_finite() && min <= max) {
                    return Err((
                        ErrorKind::BadLimit {
                            tube: i + 1,
                            key,
                            min,
                            max,
                        },
                        vec![Name("limits"), Name("tube"), Index(i), Name(key)],
                    ));
                }
            }
        }
    }
    Ok(l.tube.clone())
}

/// The tube number and TOML key a core error is about.
fn robot_error_key(e: &RobotError) -> Option<(usize, &'static str)> {
    Some(match *e {
        RobotError::NotFinite { tube, field } => (tube, field.key()),
        RobotError::NotPositive { tube, field, .. } => (tube, field.key()),
        RobotError::Negative { tube, field, .. } => (tube, field.key()),
        RobotError::WallNotPositive { tube, .. } => (tube, "outer_diameter_mm"),
        RobotError::DoNotNest { inner, .. } => (inner, "outer_diameter_mm"),
        RobotError::CurvedLongerThanTube { tube, .. } => (tube, "curved_length_mm"),
        RobotError::PoissonOutOfRange { tube, .. } => (tube, "poisson_ratio"),
        RobotError::ZeroRadius { tube } => (tube, "curvature_radius_mm"),
        RobotError::TubeCount { .. } => return None,
    })
}

impl RobotSpec {
    /// Parses and validates TOML text; `file` names it in errors, which carry the line
    /// and column of the offending value.
    ///
    /// ```
    /// let text = "[[tube]]\nouter_diameter_mm = 1.8\ninner_diameter_mm = 1.9\nlength_mm = 100.0\n\
    ///             curved_length_mm = 50.0\nyoungs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n";
    /// let err = ctr_formats::RobotSpec::from_toml_str(text, "r.toml").unwrap_err();
    /// assert_eq!(err.to_string(), "r.toml:2:21: tube 1: outer_diameter_mm = 1.8 must be larger than inner_diameter_mm = 1.9");
    /// ```
    pub fn from_toml_str(text: &str, file: &str) -> Result<RobotSpec, Error> {
        let text = without_bom(text);
        let parsed = RobotFile::parse(text, file)?;
        parsed.check().map_err(|(kind, path)| {
            let mut location = Location::file(file);
            if let Some(start) = span_of(text, &path) {
                let (line, col) = line_col(text, start);
                location.line = Some(line);
                location.column = Some(col);
            }
            Error::new(location, kind)
        })
    }

    /// Parses and validates a robot file's bytes, as `ctr-cli fk`/`ik` and `ctr_py` read
    /// them: UTF-8 (else an error reading `file`, at the first bad byte), then TOML
    /// ([`from_toml_str`](Self::from_toml_str)); `file` names it in errors.
    ///
    /// ```
    /// let err = ctr_formats::RobotSpec::from_bytes(b"name = \"x\xff\"".to_vec(), "r.toml").unwrap_err();
    /// assert_eq!(err.to_string(), "r.toml: cannot read: invalid utf-8 sequence of 1 bytes from index 9");
    /// ```
    pub fn from_bytes(bytes: Vec<u8>, file: &str) -> Result<RobotSpec, Error> {
        let text = String::from_utf8(bytes).map_err(|e| {
            Error::new(
                Location::file(file),
                ErrorKind::Io {
                    action: "read",
                    source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
                },
            )
        })?;
        RobotSpec::from_toml_str(&text, file)
    }

    /// Reads, parses and validates a robot file; errors name the path as given.
    pub fn from_path(path: &Path) -> Result<RobotSpec, Error> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| {
            Error::new(
                Location::file(&file),
                ErrorKind::Io {
                    action: "read",
                    source,
                },
            )
        })?;
        RobotSpec::from_toml_str(&text, &file)
    }

    /// Back to the file form (with an explicit `[model]`), e.g. to save a fitted robot.
    pub fn to_file(&self) -> RobotFile {
        RobotFile {
            name: self.name.clone(),
            tube: self
                .robot
                .tube_params()
                .iter()
                .enumerate()
                .map(|(i, p)| TubeFile::from_params(self.tube_names.get(i).cloned().flatten(), p))
                .collect(),
            model: Some(ModelSection {
                kind: self.model.into(),
                effects: self.effects.clone(),
                empirical: self.empirical.as_ref().map(Correction::to_file),
                discrepancy: self.discrepancy.as_ref().map(Discrepancy::to_file),
            }),
            limits: self.limits.clone().map(|tube| LimitsSection { tube }),
            actuation: self
                .actuation
                .clone()
                .map(|joint| ActuationSection { joint }),
        }
    }

    /// The robot file's TOML text.
    pub fn to_toml(&self) -> String {
        self.to_file().to_toml()
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    /// The file's names (serde's) are the names of `name` and `FromStr`.
    #[test]
    fn model_kind_names_are_the_file_names() {
        for k in ModelKind::ALL {
            let file: ModelSection = toml::from_str(&format!("kind = \"{}\"", k.name())).unwrap();
            assert_eq!(file.kind, k);
            assert_eq!(k.name().parse(), Ok(k));
            assert_eq!(k.to_string(), k.name());
        }
        assert_eq!(
            " torsion".parse::<ModelKind>(),
            Err(UnknownModelKind(" torsion".into()))
        );
    }
}

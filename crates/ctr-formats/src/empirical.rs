//! `[model.empirical]`: a labelled, data-driven correction of the modelled tip. Not
//! physics: `ctr-cli diagnose --with-empirical` writes it for what no effect of the
//! vocabulary explains, and `ctr-cli fk` adds it to the tip after the model and its
//! effects.
//!
//! ```toml
//! [model.empirical]
//! note = "ctr-cli diagnose on rec.csv: 18 terms, 5-fold cross-validation"
//! [[model.empirical.term]]
//! feature = "t"            # see below
//! axis = "x"               # the tip coordinate it corrects: x, y or z
//! mean = 250.0             # the feature's centre, its own unit (default 0)
//! scale = 140.0            # its spread, its own unit (default 1)
//! coefficient_mm = -0.5    # mm per unit of (feature - mean) / scale
//! ```
//!
//! Each term adds `coefficient_mm (f - mean) / scale` to one coordinate of the tip.
//! The features ([`Feature`]) are functions of a row's commanded joints, time and
//! modelled tip: `1`, `s<i>` (mm), `cos(theta<i>)`, `sin(theta<i>)`,
//! `cos(theta<i+1> - theta<i>)`, `sin(theta<i+1> - theta<i>)`, `t` (s, the row's `t_s`:
//! a correction with it needs the rows' times, as latency does) and `x`, `y`, `z` (mm,
//! the tip as the model puts it, in the measuring frame).

use serde::{Deserialize, Serialize};

/// One function of a row's features (see the module's list of names).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    /// 1.
    Constant,
    /// Tube `i`'s feed, mm (0-based).
    Feed(usize),
    /// cos or sin (`true`) of tube `i`'s rotation.
    Rotation(usize, bool),
    /// cos or sin of `theta_{i+1} - theta_i` (`i` the outer tube of the pair).
    Relative(usize, bool),
    /// The row's time, s.
    Time,
    /// An axis (0 x, 1 y, 2 z) of the modelled tip, mm.
    Tip(usize),
}

impl Feature {
    /// Every feature for `n` tubes, in a fixed order (with the tip position where
    /// `tip`).
    ///
    /// ```
    /// use ctr_formats::Feature;
    /// let names: Vec<String> = Feature::all(2, false).iter().map(|f| f.name()).collect();
    /// assert_eq!(names, ["1", "s1", "cos(theta1)", "sin(theta1)", "s2", "cos(theta2)",
    ///     "sin(theta2)", "cos(theta2 - theta1)", "sin(theta2 - theta1)", "t"]);
    /// ```
    pub fn all(n: usize, tip: bool) -> Vec<Feature> {
        let mut out = vec![Feature::Constant];
        for i in 0..n {
            out.push(Feature::Feed(i));
            out.push(Feature::Rotation(i, false));
            out.push(Feature::Rotation(i, true));
        }
        for i in 0..n.saturating_sub(1) {
            out.push(Feature::Relative(i, false));
            out.push(Feature::Relative(i, true));
        }
        out.push(Feature::Time);
        if tip {
            out.extend((0..3).map(Feature::Tip));
        }
        out
    }

    /// The feature named `name` for `n` tubes.
    ///
    /// ```
    /// use ctr_formats::Feature;
    /// assert_eq!(Feature::parse("cos(theta2 - theta1)", 2), Some(Feature::Relative(0, false)));
    /// assert_eq!(Feature::parse("s3", 2), None);
    /// ```
    pub fn parse(name: &str, n: usize) -> Option<Feature> {
        Feature::all(n, true).into_iter().find(|f| f.name() == name)
    }

    /// The value at a row with joints `q` (file order and units), time `t_s` and
    /// modelled tip `tip`.
    pub fn value(self, q: &[f64], t_s: f64, tip: &[f64; 3]) -> f64 {
        let angle = |i: usize| q[2 * i + 1].to_radians();
        let trig = |x: f64, sin: bool| if sin { x.sin() } else { x.cos() };
        match self {
            Feature::Constant => 1.0,
            Feature::Feed(i) => q[2 * i],
            Feature::Rotation(i, sin) => trig(angle(i), sin),
            Feature::Relative(i, sin) => trig(angle(i + 1) - angle(i), sin),
            Feature::Time => t_s,
            Feature::Tip(a) => tip[a],
        }
    }

    /// The feature's name, as `[model.empirical]` and the report write it.
    pub fn name(self) -> String {
        let trig = |sin: bool| if sin { "sin" } else { "cos" };
        match self {
            Feature::Constant => "1".into(),
            Feature::Feed(i) => format!("s{}", i + 1),
            Feature::Rotation(i, sin) => format!("{}(theta{})", trig(sin), i + 1),
            Feature::Relative(i, sin) => {
                format!("{}(theta{} - theta{})", trig(sin), i + 2, i + 1)
            }
            Feature::Time => "t".into(),
            Feature::Tip(a) => AXES[a].into(),
        }
    }
}

/// The tip coordinates' names.
pub const AXES: [&str; 3] = ["x", "y", "z"];

/// `[model.empirical]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Empirical {
    /// How it was made, in words.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub note: String,
    /// `[[model.empirical.term]]`.
    #[serde(default)]
    pub term: Vec<EmpiricalTerm>,
}

/// One `[[model.empirical.term]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmpiricalTerm {
    /// The feature's name.
    pub feature: String,
    /// `x`, `y` or `z`.
    pub axis: String,
    /// The feature's centre (default 0).
    #[serde(default)]
    pub mean: f64,
    /// The feature's spread (default 1; positive).
    #[serde(default = "one")]
    pub scale: f64,
    /// mm per unit of `(feature - mean) / scale`.
    pub coefficient_mm: f64,
}

fn one() -> f64 {
    1.0
}

/// A checked term: the feature, the axis and the affine map of the feature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Term {
    /// The feature.
    pub feature: Feature,
    /// The axis, 0 to 2.
    pub axis: usize,
    /// The feature's centre.
    pub mean: f64,
    /// Its spread.
    pub scale: f64,
    /// mm per unit of `(feature - mean) / scale`.
    pub coefficient_mm: f64,
}

/// The correction, checked against a robot of `n` tubes: what the row model applies.
///
/// ```
/// use ctr_formats::{Correction, Empirical, EmpiricalTerm};
/// let file = Empirical { note: String::new(), term: vec![EmpiricalTerm {
///     feature: "t".into(), axis: "y".into(), mean: 10.0, scale: 5.0, coefficient_mm: 2.0 }] };
/// let c = Correction::check(&file, 2)?;
/// assert!(c.uses_time());
/// let mut tip = [1.0, 2.0, 3.0];
/// c.apply(&[30.0, 0.0, 50.0, 0.0], 20.0, &mut tip);
/// assert_eq!(tip, [1.0, 2.0 + 2.0 * (20.0 - 10.0) / 5.0, 3.0]);
/// # Ok::<(), ((usize, &'static str), String)>(())
/// ```
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Correction {
    /// How it was made, in words.
    pub note: String,
    /// The terms.
    pub terms: Vec<Term>,
}

impl Correction {
    /// `file` checked for `n` tubes: known features, axes `x`/`y`/`z`, finite numbers, a
    /// positive scale. The error: the offending term's index and key under
    /// `[model.empirical]`, and the message (which names them).
    pub fn check(file: &Empirical, n: usize) -> Result<Self, ((usize, &'static str), String)> {
        let mut terms = Vec::with_capacity(file.term.len());
        for (k, t) in file.term.iter().enumerate() {
            let at = |key: &'static str, message: String| {
                (
                    (k, key),
                    format!("model.empirical.term[{k}].{key}: {message}"),
                )
            };
            let feature = Feature::parse(&t.feature, n).ok_or_else(|| {
                at(
                    "feature",
                    format!(
                        "unknown feature {:?} for {n} tubes; wanted one of {}",
                        t.feature,
                        Feature::all(n, true)
                            .iter()
                            .map(|f| f.name())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )
            })?;
            let axis = AXES
                .iter()
                .position(|a| *a == t.axis)
                .ok_or_else(|| at("axis", format!("axis {:?}: wanted x, y or z", t.axis)))?;
            for (key, v) in [("mean", t.mean), ("coefficient_mm", t.coefficient_mm)] {
                if !v.is_finite() {
                    return Err(at(key, format!("{v} is not finite")));
                }
            }
            if !(t.scale.is_finite() && t.scale > 0.0) {
                return Err(at(
                    "scale",
                    format!("scale {}: wanted a positive number", t.scale),
                ));
            }
            terms.push(Term {
                feature,
                axis,
                mean: t.mean,
                scale: t.scale,
                coefficient_mm: t.coefficient_mm,
            });
        }
        Ok(Correction {
            note: file.note.clone(),
            terms,
        })
    }

    /// True when a term needs the rows' times.
    pub fn uses_time(&self) -> bool {
        self.terms.iter().any(|t| t.feature == Feature::Time)
    }

    /// Adds the correction to `tip` (the model's, mm) at a row with commanded joints `q`
    /// and time `t_s`; the tip features are read before any term is added.
    pub fn apply(&self, q: &[f64], t_s: f64, tip: &mut [f64; 3]) {
        let model_tip = *tip;
        for t in &self.terms {
            tip[t.axis] +=
                t.coefficient_mm * (t.feature.value(q, t_s, &model_tip) - t.mean) / t.scale;
        }
    }

    /// The file's table.
    pub fn to_file(&self) -> Empirical {
        Empirical {
            note: self.note.clone(),
            term: self
                .terms
                .iter()
                .map(|t| EmpiricalTerm {
                    feature: t.feature.name(),
                    axis: AXES[t.axis].into(),
                    mean: t.mean,
                    scale: t.scale,
                    coefficient_mm: t.coefficient_mm,
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::RobotSpec;

    const TUBES: &str = "[[tube]]\nouter_diameter_mm = 1.8\ninner_diameter_mm = 1.5\n\
        length_mm = 180.0\ncurved_length_mm = 60.0\ncurvature_radius_mm = 200.0\n\
        youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n\
        [[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
        length_mm = 260.0\ncurved_length_mm = 90.0\ncurvature_radius_mm = 100.0\n\
        youngs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n";

    fn with_term(term: &str) -> Result<RobotSpec, crate::Error> {
        RobotSpec::from_toml_str(
            &format!("{TUBES}[model.empirical]\nnote = \"n\"\n[[model.empirical.term]]\n{term}"),
            "r.toml",
        )
    }

    /// A correction is read, checked, written and read back the same.
    #[test]
    fn round_trips_through_the_robot_file() {
        let spec = with_term(
            "feature = \"cos(theta2 - theta1)\"\naxis = \"z\"\nmean = 0.5\nscale = 2.0\n\
             coefficient_mm = -0.25\n",
        )
        .unwrap();
        let c = spec.empirical.clone().unwrap();
        assert_eq!(c.note, "n");
        assert_eq!(c.terms[0].feature, super::Feature::Relative(0, false));
        assert_eq!(c.terms[0].axis, 2);
        let back = RobotSpec::from_toml_str(&spec.to_toml(), "back.toml").unwrap();
        assert_eq!(back.empirical, spec.empirical);
        // defaults: mean 0, scale 1
        let d = with_term("feature = \"t\"\naxis = \"x\"\ncoefficient_mm = 1.0\n").unwrap();
        assert_eq!(
            (
                d.empirical.as_ref().unwrap().terms[0].mean,
                d.empirical.unwrap().terms[0].scale
            ),
            (0.0, 1.0)
        );
    }

    /// Bad terms are refused with the file, the key and what was wanted.
    #[test]
    fn bad_terms_are_located() {
        let e = with_term("feature = \"s3\"\naxis = \"x\"\ncoefficient_mm = 1.0\n").unwrap_err();
        let m = e.to_string();
        assert!(
            m.starts_with("r.toml:20:11:"),
            "located at the line of the value: {m}"
        );
        assert!(
            m.contains("model.empirical.term[0].feature: unknown feature \"s3\" for 2 tubes"),
            "{m}"
        );
        assert!(
            m.contains("sin(theta2 - theta1)"),
            "lists what is wanted: {m}"
        );
        let e = with_term("feature = \"t\"\naxis = \"w\"\ncoefficient_mm = 1.0\n").unwrap_err();
        assert!(
            e.to_string().contains("axis \"w\": wanted x, y or z"),
            "{e}"
        );
        let e = with_term("feature = \"t\"\naxis = \"x\"\nscale = 0.0\ncoefficient_mm = 1.0\n")
            .unwrap_err();
        assert!(
            e.to_string().contains("scale 0: wanted a positive number"),
            "{e}"
        );
        let e = with_term("feature = \"t\"\naxis = \"x\"\ncoefficient = 1.0\n").unwrap_err();
        assert!(
            e.to_string().contains("coefficient"),
            "unknown keys refused: {e}"
        );
    }
}

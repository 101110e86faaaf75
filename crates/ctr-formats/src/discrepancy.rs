//! `[model.discrepancy]`: a learned, labelled discrepancy of the modelled tip (not
//! physics): a Gaussian process over the joints and their history, fitted by
//! `ctr-cli diagnose` to what the physics leaves (Kennedy and O'Hagan's model
//! discrepancy), written by `ctr-cli diagnose --with-empirical`, added to the tip by
//! `ctr-cli fk` and `ctr_py` (which can also return its band).
//!
//! ```toml
//! [model.discrepancy]
//! note = "not physics: fitted by ctr-cli diagnose on rec.csv"
//! kind = "gaussian_process"
//! inputs = ["s3", "theta3 - theta2", "play(theta3 - theta2, 2)"]
//! mean = [200.0, 10.0, 0.0]           # each input's centre on the training rows
//! scale = [20.0, 60.0, 0.7]           # and spread (the GP sees (value - mean) / scale)
//! length_scales = [0.3, 0.5, 1.1]     # per input, in those standardised units
//! signal_mm = 1.0                     # the discrepancy's prior standard deviation
//! noise_mm = 0.13                     # the measurements' about it
//! train = [[201.0, 12.0, 0.4], ...]   # the training rows' inputs, as computed
//! target_mm = [[0.2, -1.1, 0.4], ...] # what the model left there: measured - modelled
//! ```
//!
//! The inputs are functions of a row's joints as the model takes them (the commanded
//! joints after the joint offsets, latency and friction of `[model.effects]`), in
//! file units: `s<i>` (mm), `theta<i>` (deg), `theta<j> - theta<i>` (deg, `j = i + 1`)
//! and `play(theta<j> - theta<i>, w)`: the state of a play (backlash) operator of
//! half-width `w` deg on that relative rotation, run along each run in time order from
//! its first row, as `(d - P_w(d)) / w` in `[-1, 1]`:
//!
//! ```text
//! P_0 = d_0,   P_k = min(d_k + w, max(d_k - w, P_(k-1)))
//! ```
//!
//! so a row's input remembers from which side the joint came: what tells the same joints
//! reached forwards from the same joints reached backwards (hysteresis).
//!
//! The process: a zero-mean Gaussian process per tip coordinate with one squared
//! exponential kernel over the standardised inputs `u`,
//! `k(u, u') = signal^2 exp(-1/2 sum_j (u_j - u'_j)^2 / l_j^2)`, and Gaussian noise of
//! `noise_mm`: the correction at a row is the posterior mean
//! `k(u)^T (K + noise^2 I)^-1 target`, its band the posterior standard deviation of a
//! measurement there, `sqrt(signal^2 - k(u)^T (K + noise^2 I)^-1 k(u) + noise^2)`
//! (`ctr_analysis::discrepancy` evaluates it).

use serde::{Deserialize, Serialize};

/// Smallest `noise_mm / signal_mm`: below it the training rows' kernel matrix is not
/// positive definite in double precision where rows repeat.
pub const MIN_NOISE_SHARE: f64 = 1e-6;

/// The one kind of discrepancy written today.
pub const GAUSSIAN_PROCESS: &str = "gaussian_process";

/// One input of the discrepancy (see the module docs for the names).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Input {
    /// Tube `i`'s feed, mm (0-based).
    Feed(usize),
    /// Tube `i`'s rotation, deg.
    Rotation(usize),
    /// `theta_(i+1) - theta_i`, deg (`i` the outer tube of the pair).
    Relative(usize),
    /// The play operator's state on `theta_(i+1) - theta_i`, half-width in deg.
    Play(usize, f64),
}

impl Input {
    /// Its name in the file.
    ///
    /// ```
    /// use ctr_formats::Input;
    /// assert_eq!(Input::Play(1, 2.0).name(), "play(theta3 - theta2, 2)");
    /// assert_eq!(Input::parse("play(theta3 - theta2, 2)", 3), Some(Input::Play(1, 2.0)));
    /// assert_eq!(Input::parse("theta4", 3), None);
    /// ```
    pub fn name(self) -> String {
        match self {
            Input::Feed(i) => format!("s{}", i + 1),
            Input::Rotation(i) => format!("theta{}", i + 1),
            Input::Relative(i) => format!("theta{} - theta{}", i + 2, i + 1),
            Input::Play(i, w) => format!("play(theta{} - theta{}, {w})", i + 2, i + 1),
        }
    }

    /// The input named `name` for `n` tubes (`None`: no such input).
    pub fn parse(name: &str, n: usize) -> Option<Input> {
        if let Some(inner) = name.strip_prefix("play(").and_then(|r| r.strip_suffix(')')) {
            let (rel, width) = inner.rsplit_once(',')?;
            let w: f64 = width.trim().parse().ok()?;
            let Some(Input::Relative(i)) = Input::parse(rel.trim(), n) else {
                return None;
            };
            return (w.is_finite() && w > 0.0).then_some(Input::Play(i, w));
        }
        (0..n)
            .flat_map(|i| [Input::Feed(i), Input::Rotation(i)])
            .chain((0..n.saturating_sub(1)).map(Input::Relative))
            .find(|input| input.name() == name)
    }

    /// The raw (not played) value of a row's joints `q` (file order and units).
    fn raw(self, q: &[f64]) -> f64 {
        match self {
            Input::Feed(i) => q[2 * i],
            Input::Rotation(i) => q[2 * i + 1],
            Input::Relative(i) | Input::Play(i, _) => q[2 * i + 3] - q[2 * i + 1],
        }
    }
}

/// The inputs' values along one run: `rows` the joints of its rows in time order (as
/// the model takes them, file units), each row's values in `inputs`' order.
///
/// ```
/// use ctr_formats::{inputs_along_run, Input};
/// let rows = [[0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 5.0], [0.0, 0.0, 0.0, 4.0]];
/// let rows: Vec<&[f64]> = rows.iter().map(|r| &r[..]).collect();
/// let v = inputs_along_run(&[Input::Relative(0), Input::Play(0, 2.0)], &rows);
/// // up by 5 deg: the play lags 2 deg behind (state +1); back 1 deg: it holds (0.5)
/// assert_eq!(v[1], vec![5.0, 1.0]);
/// assert_eq!(v[2], vec![4.0, 0.5]);
/// ```
pub fn inputs_along_run(inputs: &[Input], rows: &[&[f64]]) -> Vec<Vec<f64>> {
    let mut play: Vec<Option<f64>> = vec![None; inputs.len()];
    rows.iter()
        .map(|q| {
            inputs
                .iter()
                .zip(&mut play)
                .map(|(input, state)| {
                    let d = input.raw(q);
                    match *input {
                        Input::Play(_, w) => {
                            let p = state.map_or(d, |p| (d + w).min((d - w).max(p)));
                            *state = Some(p);
                            (d - p) / w
                        }
                        _ => d,
                    }
                })
                .collect()
        })
        .collect()
}

/// `[model.discrepancy]` as the file holds it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiscrepancyFile {
    /// What it is and where it comes from.
    #[serde(default)]
    pub note: String,
    /// `gaussian_process`.
    pub kind: String,
    /// The inputs' names.
    pub inputs: Vec<String>,
    /// Each input's centre.
    pub mean: Vec<f64>,
    /// Each input's spread (> 0).
    pub scale: Vec<f64>,
    /// Each input's length scale, standardised units (> 0).
    pub length_scales: Vec<f64>,
    /// The prior standard deviation, mm (> 0).
    pub signal_mm: f64,
    /// The measurement noise about it, mm (> 0).
    pub noise_mm: f64,
    /// The training rows' inputs.
    pub train: Vec<Vec<f64>>,
    /// The model's error there, measured - modelled, mm (x, y, z).
    pub target_mm: Vec<[f64; 3]>,
}

/// `[model.discrepancy]`, checked against the robot (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Discrepancy {
    /// What it is and where it comes from.
    pub note: String,
    /// The inputs.
    pub inputs: Vec<Input>,
    /// Each input's centre.
    pub mean: Vec<f64>,
    /// Each input's spread.
    pub scale: Vec<f64>,
    /// Each input's length scale, standardised units.
    pub length_scales: Vec<f64>,
    /// The prior standard deviation, mm.
    pub signal_mm: f64,
    /// The measurement noise, mm.
    pub noise_mm: f64,
    /// The training rows' inputs.
    pub train: Vec<Vec<f64>>,
    /// The model's error there, measured - modelled, mm.
    pub target_mm: Vec<[f64; 3]>,
}

impl Discrepancy {
    /// The file form checked for `n` tubes: the error names the key and what was
    /// wanted.
    ///
    /// ```
    /// use ctr_formats::{Discrepancy, DiscrepancyFile};
    /// let mut f = DiscrepancyFile { kind: "gaussian_process".into(), inputs: vec!["s1".into()],
    ///     mean: vec![0.0], scale: vec![1.0], length_scales: vec![1.0], signal_mm: 1.0,
    ///     noise_mm: 0.1, train: vec![vec![0.0]], target_mm: vec![[0.0; 3]], note: String::new() };
    /// assert!(Discrepancy::check(&f, 1).is_ok());
    /// f.inputs = vec!["s2".into()];
    /// assert_eq!(Discrepancy::check(&f, 1).unwrap_err().0, "inputs");
    /// ```
    pub fn check(file: &DiscrepancyFile, n: usize) -> Result<Self, (&'static str, String)> {
        if file.kind != GAUSSIAN_PROCESS {
            return Err((
                "kind",
                format!(
                    "model.discrepancy.kind: \"{}\", wanted \"{GAUSSIAN_PROCESS}\"",
                    file.kind
                ),
            ));
        }
        let inputs = parse_inputs(&file.inputs, n)?;
        let d = inputs.len();
        for (key, v) in [
            ("mean", &file.mean),
            ("scale", &file.scale),
            ("length_scales", &file.length_scales),
        ] {
            if v.len() != d || v.iter().any(|x| !x.is_finite()) {
                return Err((
                    key,
                    format!("model.discrepancy.{key}: wanted {d} finite values, one per input"),
                ));
            }
        }
        let positive = |key: &'static str, v: &[f64]| -> Result<(), (&'static str, String)> {
            if v.iter().all(|x| *x > 0.0) {
                Ok(())
            } else {
                Err((
                    key,
                    format!("model.discrepancy.{key}: every value must be > 0"),
                ))
            }
        };
        positive("scale", &file.scale)?;
        positive("length_scales", &file.length_scales)?;
        positive("signal_mm", &[file.signal_mm])?;
        positive("noise_mm", &[file.noise_mm])?;
        if file.noise_mm < MIN_NOISE_SHARE * file.signal_mm {
            return Err((
                "noise_mm",
                format!(
                    "model.discrepancy.noise_mm: {} mm is below {MIN_NOISE_SHARE} x signal_mm \
                     (the training kernel would not be positive definite in floating point)",
                    file.noise_mm
                ),
            ));
        }
        if file.train.len() != file.target_mm.len() || file.train.is_empty() {
            return Err((
                "target_mm",
                format!(
                    "model.discrepancy: {} training rows in train and {} in target_mm, wanted \
                     as many, at least one",
                    file.train.len(),
                    file.target_mm.len()
                ),
            ));
        }
        if let Some(k) = file
            .train
            .iter()
            .position(|r| r.len() != d || r.iter().any(|x| !x.is_finite()))
        {
            return Err((
                "train",
                format!(
                    "model.discrepancy.train: row {} wanted {d} finite values",
                    k + 1
                ),
            ));
        }
        if file.target_mm.iter().flatten().any(|x| !x.is_finite()) {
            return Err((
                "target_mm",
                "model.discrepancy.target_mm: every value must be finite".into(),
            ));
        }
        Ok(Discrepancy {
            note: file.note.clone(),
            inputs,
            mean: file.mean.clone(),
            scale: file.scale.clone(),
            length_scales: file.length_scales.clone(),
            signal_mm: file.signal_mm,
            noise_mm: file.noise_mm,
            train: file.train.clone(),
            target_mm: file.target_mm.clone(),
        })
    }

    /// Back to the file form.
    pub fn to_file(&self) -> DiscrepancyFile {
        DiscrepancyFile {
            note: self.note.clone(),
            kind: GAUSSIAN_PROCESS.into(),
            inputs: self.inputs.iter().map(|i| i.name()).collect(),
            mean: self.mean.clone(),
            scale: self.scale.clone(),
            length_scales: self.length_scales.clone(),
            signal_mm: self.signal_mm,
            noise_mm: self.noise_mm,
            train: self.train.clone(),
            target_mm: self.target_mm.clone(),
        }
    }
}

/// The inputs named `names` for `n` tubes, or the error naming the first unknown one.
fn parse_inputs(names: &[String], n: usize) -> Result<Vec<Input>, (&'static str, String)> {
    names
        .iter()
        .map(|name| {
            Input::parse(name, n).ok_or_else(|| {
                (
                    "inputs",
                    format!(
                        "model.discrepancy.inputs: \"{name}\" is no input for {n} tube(s) \
                         (s<i>, theta<i>, theta<j> - theta<i>, play(theta<j> - theta<i>, w))"
                    ),
                )
            })
        })
        .collect()
}

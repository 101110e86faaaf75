//! The learned discrepancy of `[model.discrepancy]` evaluated (its inputs read the
//! commanded joints delayed by the model's latency, `crate::learned`): a Gaussian process over
//! the joints and their history (the file form, its inputs and equations are
//! `ctr_formats::discrepancy`'s docs), prepared once (the training rows' kernel
//! factored) and added to the modelled tip row by row along each run.
//!
//! With `v = (u - mean) / (scale l)` the inputs standardised and divided by their length
//! scales, `k(v, v') = s^2 exp(-|v - v'|^2 / 2)` (`s` = `signal_mm`) and
//! `K = k(V, V) + n^2 I` over the training rows (`n` = `noise_mm`), a row's correction is
//! `k(v)^T K^-1 Y` (one column of `Y` per tip coordinate, the model's error there) and
//! the standard deviation of a measurement about it `sqrt(s^2 - k(v)^T K^-1 k(v) + n^2)`.

use ctr_formats::{inputs_along_run, Discrepancy};
use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

/// `[model.discrepancy]` prepared to evaluate (see the module docs).
#[derive(Clone, Debug)]
pub struct Gp {
    /// The file form it was prepared from.
    pub file: Discrepancy,
    /// The training rows' inputs, standardised and divided by the length scales: one
    /// column per row (contiguous).
    v: DMatrix<f64>,
    /// `K`'s Cholesky factor.
    chol: Cholesky<f64, Dyn>,
    /// `K^-1 Y`.
    alpha: DMatrix<f64>,
}

impl PartialEq for Gp {
    fn eq(&self, other: &Self) -> bool {
        self.file == other.file
    }
}

/// The squared exponential kernel of two rows of scaled inputs, over `s2` the signal's
/// variance.
pub fn kernel(a: &[f64], b: &[f64], s2: f64) -> f64 {
    let d2: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
    s2 * (-0.5 * d2).exp()
}

impl Gp {
    /// The process of `d`, its training kernel factored; an error (in words) when it
    /// is not positive definite.
    ///
    /// ```
    /// use ctr_analysis::discrepancy::Gp;
    /// use ctr_formats::{Discrepancy, Input};
    /// let d = Discrepancy { note: String::new(), inputs: vec![Input::Feed(0)], mean: vec![0.0],
    ///     scale: vec![1.0], length_scales: vec![1.0], signal_mm: 1.0, noise_mm: 0.01,
    ///     train: vec![vec![0.0], vec![1.0]], target_mm: vec![[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]] };
    /// let gp = Gp::new(&d).unwrap();
    /// let (mean, sd) = gp.at(&[0.0]);
    /// assert!((mean[0] - 1.0).abs() < 1e-3 && sd < 0.02); // at a training row: its target
    /// let (far, sd_far) = gp.at(&[50.0]);
    /// assert!(far[0].abs() < 1e-9 && (sd_far - 1.0).abs() < 1e-3); // far away: the prior
    /// ```
    pub fn new(d: &Discrepancy) -> Result<Gp, String> {
        let rows = d.train.len();
        let v = DMatrix::from_fn(d.inputs.len(), rows, |j, r| {
            (d.train[r][j] - d.mean[j]) / (d.scale[j] * d.length_scales[j])
        });
        let s2 = d.signal_mm * d.signal_mm;
        let k = DMatrix::from_fn(rows, rows, |a, b| {
            let ab = kernel(v.column(a).as_slice(), v.column(b).as_slice(), s2);
            if a == b {
                ab + d.noise_mm * d.noise_mm
            } else {
                ab
            }
        });
        let chol = k.cholesky().ok_or_else(|| {
            "model.discrepancy: the training rows' kernel is not positive definite (repeated \
             rows with a zero noise_mm?)"
                .to_string()
        })?;
        let y = DMatrix::from_fn(rows, 3, |r, a| d.target_mm[r][a]);
        let alpha = chol.solve(&y);
        Ok(Gp {
            file: d.clone(),
            v,
            chol,
            alpha,
        })
    }

    /// The correction (mm, x y z) at a row whose inputs are `u` (the file's order and
    /// units), and the standard deviation of a measurement about it (mm, each axis).
    pub fn at(&self, u: &[f64]) -> ([f64; 3], f64) {
        let d = &self.file;
        let v: Vec<f64> = u
            .iter()
            .enumerate()
            .map(|(j, x)| (x - d.mean[j]) / (d.scale[j] * d.length_scales[j]))
            .collect();
        let s2 = d.signal_mm * d.signal_mm;
        let k = DVector::from_fn(self.v.ncols(), |r, _| {
            kernel(&v, self.v.column(r).as_slice(), s2)
        });
        let mean = [0, 1, 2].map(|a| k.dot(&self.alpha.column(a)));
        let explained = k.dot(&self.chol.solve(&k));
        let var = (s2 - explained).max(0.0) + d.noise_mm * d.noise_mm;
        (mean, var.sqrt())
    }

    /// The correction and standard deviation of every row of one run, `rows` its joints
    /// as the model takes them, in time order (the play inputs run along them).
    pub fn along_run(&self, rows: &[&[f64]]) -> Vec<([f64; 3], f64)> {
        inputs_along_run(&self.file.inputs, rows)
            .iter()
            .map(|u| self.at(u))
            .collect()
    }
}

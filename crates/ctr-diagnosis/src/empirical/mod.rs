//! The generic empirical correction: what a data-driven term with no physics in it does
//! with the same residual, as the yardstick every physical finding must beat.
//!
//! The correction is linear in a fixed, low-order basis of the row's features,
//! standardised on the fit rows: a constant, each tube's feed `s_i`, one harmonic of
//! each tube's rotation `theta_i` and of each relative rotation `theta_{i+1} - theta_i`,
//! the recording time `t_s`, and the modelled tip position. A *term* is one basis
//! function on one axis of the tip error with one coefficient, so a correction of `k`
//! terms has `k` free parameters, as an effect with `k` parameters does.
//!
//! [`pursue`] picks the `k` terms by orthogonal matching pursuit on the fit rows (each
//! step adds the term whose part orthogonal to those chosen lowers the weighted squared
//! error most; [`path`]), then fits them together by least squares. Rows are weighted by the Huber weight of their
//! current error, `min(1, c / |e|)`, as the physical fits are, so tracker outliers do
//! not steer it.

pub(crate) mod gp;
pub(crate) mod hybrid;

use ctr_formats::{Feature, Recording};
use nalgebra::{DMatrix, DVector};

/// The basis evaluated at every row, each feature but the constant standardised to
/// zero mean and unit spread over the fit rows; features that do not vary there are
/// left out.
pub(crate) struct Basis {
    /// The features kept.
    pub(crate) features: Vec<Feature>,
    /// Column `j` holds feature `j` at every row.
    columns: Vec<Vec<f64>>,
    /// Each feature's centre and spread: column `j` is `(f_j - centre) / spread`.
    pub(crate) standard: Vec<(f64, f64)>,
}

impl Basis {
    /// The basis of `rec`'s rows with modelled tips `tips`, standardised on `fit`.
    pub(crate) fn new(rec: &Recording, tips: &[[f64; 3]], fit: &[bool]) -> Self {
        Self::with(rec, tips, fit, true)
    }

    /// The basis in the joints and time only, without the tip position: the yardstick
    /// of a finding, so that an effect that is itself a map of the tip position (the
    /// registration) is not measured against its own functional form.
    pub(crate) fn joints_and_time(rec: &Recording, fit: &[bool]) -> Self {
        Self::with(rec, &vec![[0.0; 3]; rec.rows.len()], fit, false)
    }

    /// The non-constant features of the full basis in their own units, not centred:
    /// a coefficient times such a feature is proportional to it (zero where it is
    /// zero), as a gain is.
    pub(crate) fn raw(rec: &Recording, tips: &[[f64; 3]]) -> Self {
        let features: Vec<Feature> = Feature::all(rec.n_tubes, true)
            .into_iter()
            .filter(|f| *f != Feature::Constant)
            .collect();
        let columns = features.iter().map(|f| column(rec, tips, *f)).collect();
        let standard = vec![(0.0, 1.0); features.len()];
        Basis {
            features,
            columns,
            standard,
        }
    }

    fn with(rec: &Recording, tips: &[[f64; 3]], fit: &[bool], tip: bool) -> Self {
        let mut features = Vec::new();
        let mut columns = Vec::new();
        let mut standard = Vec::new();
        for f in Feature::all(rec.n_tubes, tip) {
            let mut col = column(rec, tips, f);
            let mut centre_spread = (0.0, 1.0);
            if f != Feature::Constant {
                let (mut n, mut mean) = (0.0, 0.0);
                for (v, _) in col.iter().zip(fit).filter(|(_, m)| **m) {
                    n += 1.0;
                    mean += v;
                }
                mean /= n;
                let var = col
                    .iter()
                    .zip(fit)
                    .filter(|(_, m)| **m)
                    .map(|(v, _)| (v - mean).powi(2))
                    .sum::<f64>()
                    / n;
                if var.sqrt().is_nan() || var.sqrt() <= MIN_SPREAD {
                    continue;
                }
                let sd = var.sqrt();
                col.iter_mut().for_each(|v| *v = (*v - mean) / sd);
                centre_spread = (mean, sd);
            }
            features.push(f);
            columns.push(col);
            standard.push(centre_spread);
        }
        Basis {
            features,
            columns,
            standard,
        }
    }
}

/// Feature `f` at every row of `rec` (modelled tips `tips`), in its own units.
fn column(rec: &Recording, tips: &[[f64; 3]], f: Feature) -> Vec<f64> {
    rec.rows
        .iter()
        .zip(tips)
        .map(|(r, p)| f.value(&r.q, r.t_s, p))
        .collect()
}

/// Spread below which a feature counts as constant on the fit rows (its own units).
const MIN_SPREAD: f64 = 1e-9;

/// Huber weight of every row: `min(1, huber_mm / |e|)` on the fit rows, 0 elsewhere.
pub(crate) fn weights(e: &[[f64; 3]], fit: &[bool], huber_mm: f64) -> Vec<f64> {
    e.iter()
        .zip(fit)
        .map(|(v, m)| {
            if !m {
                return 0.0;
            }
            let size = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if size > huber_mm {
                huber_mm / size
            } else {
                1.0
            }
        })
        .collect()
}

/// A vector field over the rows: one 3-vector per row.
pub(crate) type Field = Vec<[f64; 3]>;

/// Weighted least squares of `e` on the fields `chosen`: the coefficients and the
/// weighted squared error left.
fn lsq(fields: &[Field], chosen: &[usize], e: &[[f64; 3]], w: &[f64]) -> (Vec<f64>, f64) {
    let k = chosen.len();
    let mut xtx = DMatrix::<f64>::zeros(k, k);
    let mut xty = DVector::<f64>::zeros(k);
    let mut yty = 0.0;
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for r in 0..e.len() {
        if w[r] == 0.0 {
            continue;
        }
        yty += w[r] * dot(&e[r], &e[r]);
        for (i, &ci) in chosen.iter().enumerate() {
            let fi = &fields[ci][r];
            xty[i] += w[r] * dot(fi, &e[r]);
            for (j, &cj) in chosen.iter().enumerate().skip(i) {
                xtx[(i, j)] += w[r] * dot(fi, &fields[cj][r]);
            }
        }
    }
    for i in 0..k {
        for j in 0..i {
            xtx[(i, j)] = xtx[(j, i)];
        }
    }
    let Some(beta) = xtx.cholesky().map(|c| c.solve(&xty)) else {
        return (vec![0.0; k], yty);
    };
    let left = yty - beta.dot(&xty);
    (beta.iter().copied().collect(), left.max(0.0))
}

/// The order in which orthogonal matching pursuit picks up to `k` of `fields` for the
/// errors `e` with row weights `w` (zero: not fitted): each step takes the field whose
/// part orthogonal to those already chosen lowers the weighted squared error most
/// (Gram-Schmidt, so a step costs one pass over the candidates).
pub(crate) fn path(fields: &[Field], e: &[[f64; 3]], w: &[f64], k: usize) -> Vec<usize> {
    // a row of weight zero adds exact zeros to every sum: left out, unless a value
    // there is not finite (which makes the sums NaN, as it must)
    let finite = |r: usize| {
        e[r].iter()
            .chain(fields.iter().flat_map(|f| &f[r]))
            .all(|v| v.is_finite())
    };
    let rows: Vec<usize> = (0..e.len())
        .filter(|&r| w[r] != 0.0 || !finite(r))
        .collect();
    let flat = |f: &[[f64; 3]]| -> Vec<f64> {
        rows.iter()
            .flat_map(|&r| {
                let (v, s) = (f[r], w[r].sqrt());
                [s * v[0], s * v[1], s * v[2]]
            })
            .collect()
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut r = flat(e);
    let mut cands: Vec<Vec<f64>> = fields.iter().map(|f| flat(f)).collect();
    let norms0: Vec<f64> = cands.iter().map(|c| dot(c, c)).collect();
    let mut chosen = Vec::new();
    for _ in 0..k.min(fields.len()) {
        let mut best: Option<(usize, f64)> = None;
        for (j, c) in cands.iter().enumerate() {
            let cc = dot(c, c);
            // a field (nearly) in the span of those chosen adds nothing
            if chosen.contains(&j) || cc.is_nan() || cc <= DEPENDENT * norms0[j] {
                continue;
            }
            let gain = dot(c, &r).powi(2) / cc;
            if best.is_none_or(|b| gain > b.1) {
                best = Some((j, gain));
            }
        }
        let Some((j, _)) = best else { break };
        chosen.push(j);
        let norm = dot(&cands[j], &cands[j]).sqrt();
        let q: Vec<f64> = cands[j].iter().map(|v| v / norm).collect();
        let qr = dot(&q, &r);
        r.iter_mut().zip(&q).for_each(|(x, y)| *x -= qr * y);
        for c in cands.iter_mut() {
            let qc = dot(&q, c);
            c.iter_mut().zip(&q).for_each(|(x, y)| *x -= qc * y);
        }
    }
    chosen
}

/// Whether a feature's column varies over the rows: a joint the recording never moves
/// (a tube held at one feed) is a constant by another name, and proportional to it
/// is constant.
fn varies(column: &[f64]) -> bool {
    let (lo, hi) = column
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    hi - lo > STILL * (1.0 + lo.abs().max(hi.abs()))
}

/// Relative spread below which a feature's column is constant over the rows.
const STILL: f64 = 1e-9;

/// Share of a field's own weighted norm squared below which what is left of it after
/// the chosen fields counts as dependent on them.
const DEPENDENT: f64 = 1e-10;

/// The best `k` of `fields` for the errors `e` (row weights `w`) by [`path`], with
/// their least-squares coefficients.
pub(crate) fn pursue(fields: &[Field], e: &[[f64; 3]], w: &[f64], k: usize) -> Vec<(usize, f64)> {
    let chosen = path(fields, e, w, k);
    let (beta, _) = lsq(fields, &chosen, e, w);
    chosen.into_iter().zip(beta).collect()
}

/// The least-squares coefficients of `chosen` for `e` (row weights `w`).
pub(crate) fn coefficients(
    fields: &[Field],
    chosen: &[usize],
    e: &[[f64; 3]],
    w: &[f64],
) -> Vec<(usize, f64)> {
    let (beta, _) = lsq(fields, chosen, e, w);
    chosen.iter().copied().zip(beta).collect()
}

/// `e` less the fields `terms` (field index, coefficient) of `fields`.
pub(crate) fn subtract(fields: &[Field], terms: &[(usize, f64)], e: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut out = e.to_vec();
    for &(j, c) in terms {
        for (o, f) in out.iter_mut().zip(&fields[j]) {
            for a in 0..3 {
                o[a] -= c * f[a];
            }
        }
    }
    out
}

impl Basis {
    /// Every term of the basis as a field: feature `j` on axis `a` at index `3 j + a`.
    pub(crate) fn fields(&self) -> Vec<Field> {
        let mut out = Vec::with_capacity(3 * self.columns.len());
        for col in &self.columns {
            for a in 0..3 {
                out.push(
                    col.iter()
                        .map(|v| {
                            let mut f = [0.0; 3];
                            f[a] = *v;
                            f
                        })
                        .collect(),
                );
            }
        }
        out
    }

    /// The non-constant features' columns (for coefficients that vary over the rows).
    pub(crate) fn varying(&self) -> impl Iterator<Item = (Feature, &[f64])> {
        self.features
            .iter()
            .zip(&self.columns)
            .filter(|(f, c)| **f != Feature::Constant && varies(c))
            .map(|(f, c)| (*f, c.as_slice()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ctr_formats::{RecordedRow, Run};

    fn recording(rows: usize) -> Recording {
        let rows: Vec<RecordedRow> = (0..rows)
            .map(|k| {
                let x = k as f64;
                RecordedRow {
                    line: k + 2,
                    t_s: 0.1 * x,
                    run: 0,
                    q: vec![
                        10.0 + (0.37 * x).sin() * 5.0,
                        7.0 * x,
                        40.0 + (0.11 * x).cos(),
                        3.0 * x,
                    ],
                    p: [0.0; 3],
                    quaternion: None,
                    tangent: None,
                    force_n: [0.0; 3],
                    frames: None,
                }
            })
            .collect();
        Recording {
            file: "test.csv".into(),
            n_tubes: 2,
            has_time: true,
            has_force: false,
            poses: None,
            angular: None,
            runs: vec![Run {
                label: "a".into(),
                rows: 0..rows.len(),
            }],
            rows,
        }
    }

    /// A joint the recording never moves gives no varying feature (proportional to it
    /// is constant); the joints that move do.
    #[test]
    fn a_joint_held_still_gives_no_varying_feature() {
        let mut rec = recording(100);
        for r in &mut rec.rows {
            r.q[2] = 40.0; // tube 2 held at one feed
        }
        let tips = vec![[1.0, 2.0, 3.0]; 100];
        let basis = Basis::raw(&rec, &tips);
        let varying: Vec<Feature> = basis.varying().map(|(f, _)| f).collect();
        assert!(!varying.contains(&Feature::Feed(1)), "{varying:?}");
        assert!(varying.contains(&Feature::Feed(0)), "{varying:?}");
        // the tips never move either
        assert!(basis.features.len() > varying.len() + 1);
    }

    /// An error made of two basis terms is found with two terms and removed exactly;
    /// with one term, the larger is found.
    #[test]
    fn matching_pursuit_finds_the_terms_an_error_is_made_of() {
        let rec = recording(300);
        let tips = vec![[0.0; 3]; 300];
        let fit = vec![true; 300];
        let basis = Basis::new(&rec, &tips, &fit);
        let t = basis
            .features
            .iter()
            .position(|f| *f == Feature::Time)
            .unwrap();
        let s = basis
            .features
            .iter()
            .position(|f| *f == Feature::Feed(1))
            .unwrap();
        let e: Vec<[f64; 3]> = (0..300)
            .map(|r| [0.0, 2.0 * basis.columns[t][r], -0.5 * basis.columns[s][r]])
            .collect();
        let w = vec![1.0; 300];
        let fields = basis.fields();
        let two = pursue(&fields, &e, &w, 2);
        let left = subtract(&fields, &two, &e);
        assert!(left.iter().flatten().all(|v| v.abs() < 1e-9));
        let one = pursue(&fields, &e, &w, 1);
        assert_eq!(one.len(), 1);
        // field 3 j + a is feature j on axis a
        assert_eq!((one[0].0 / 3, one[0].0 % 3), (t, 1));
        assert!((one[0].1 - 2.0).abs() < 1e-9);
    }
}

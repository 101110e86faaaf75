//! Where a tip error sits and what pattern it has.
//!
//! Every statement is a least-squares regression of the 3-D error vectors `e_k` on one
//! feature of the rows, with the share of the squared error it explains
//! (`R^2 = 1 - SSE_after / SSE`, SSE about zero, so a constant offset counts):
//!
//! - by run: each run's share of the squared error;
//! - constant offset: `e = a`;
//! - grows with a joint or an exposed length `f`: `e = a + b f`;
//! - periodic in a relative (or absolute) rotation `phi`: `e = a + b cos phi + c sin phi`,
//!   with the angle where the error's size `|e|` peaks (same regression on `|e|`);
//! - direction of motion: `e = a + b sign(d f / dt)` over the rows where `f` moves (a
//!   loop that opens when the motion reverses);
//! - position in the workspace: `e = a + B p` (p the modelled tip: a frame mismatch).

pub mod stability;

use ctr_formats::Recording;
use serde::Serialize;

/// One located pattern of an error.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Statement {
    /// Kind of pattern: `run`, `offset`, `grows_with`, `periodic`, `direction`, `workspace`.
    pub kind: String,
    /// The feature (`s2 - s1`, `theta2 - theta1`, a run's label, ...).
    pub feature: String,
    /// Share of the squared error the pattern explains, 0..1.
    pub explained: f64,
    /// The statement in words, with its statistic.
    pub text: String,
}

/// A scalar feature of every row.
struct Feature {
    name: String,
    values: Vec<f64>,
    periodic: bool,
}

fn features(rec: &Recording) -> Vec<Feature> {
    let n = rec.n_tubes;
    let col = |f: &dyn Fn(&[f64]) -> f64| rec.rows.iter().map(|r| f(&r.q)).collect::<Vec<_>>();
    let mut out = Vec::new();
    for i in 0..n {
        out.push(Feature {
            name: format!("s{}", i + 1),
            values: col(&|q| q[2 * i]),
            periodic: false,
        });
        if i > 0 {
            out.push(Feature {
                name: format!("s{} - s{}", i + 1, i),
                values: col(&|q| q[2 * i] - q[2 * i - 2]),
                periodic: false,
            });
        }
    }
    out.push(Feature {
        name: "time t_s".into(),
        values: rec.rows.iter().map(|r| r.t_s).collect(),
        periodic: false,
    });
    for i in 0..n {
        out.push(Feature {
            name: format!("theta{}", i + 1),
            values: col(&|q| q[2 * i + 1]),
            periodic: true,
        });
        if i > 0 {
            out.push(Feature {
                name: format!("theta{} - theta{}", i + 1, i),
                values: col(&|q| q[2 * i + 1] - q[2 * i - 1]),
                periodic: true,
            });
        }
    }
    out
}

/// The values over the rows of the feature a statement names (`s2`, `s2 - s1`,
/// `time t_s`, `theta2 - theta1`, ...; `None` for a run's label or the tip position):
/// what the plots draw the error against.
pub(crate) fn feature_values(rec: &Recording, name: &str) -> Option<Vec<f64>> {
    features(rec)
        .into_iter()
        .find(|f| f.name == name)
        .map(|f| f.values)
}

/// Least squares of the error vectors (3 columns) on the regressors `x` (rows with
/// `mask`): the squared error explained, as a share of the rows' SSE about zero.
fn explained(e: &[[f64; 3]], x: &[Vec<f64>], mask: &[bool]) -> f64 {
    let k = x.len();
    let mut xtx = nalgebra::DMatrix::<f64>::zeros(k, k);
    let mut xte = nalgebra::DMatrix::<f64>::zeros(k, 3);
    let mut sse = 0.0;
    for r in 0..e.len() {
        if !mask[r] {
            continue;
        }
        for a in 0..k {
            for b in 0..k {
                xtx[(a, b)] += x[a][r] * x[b][r];
            }
            for c in 0..3 {
                xte[(a, c)] += x[a][r] * e[r][c];
            }
        }
        sse += e[r].iter().map(|v| v * v).sum::<f64>();
    }
    if sse <= 0.0 {
        return 0.0;
    }
    let Some(beta) = xtx.clone().pseudo_inverse(1e-12).ok().map(|p| p * &xte) else {
        return 0.0;
    };
    // explained = sum over columns of beta^T X^T e
    let mut ex = 0.0;
    for c in 0..3 {
        for a in 0..k {
            ex += beta[(a, c)] * xte[(a, c)];
        }
    }
    (ex / sse).clamp(0.0, 1.0)
}

/// Angle (deg, 0..360) where `|e|` peaks as a function of `phi` (deg), by a
/// one-harmonic fit.
fn peak_deg(size: &[f64], phi: &[f64]) -> f64 {
    let (mut m, mut c, mut s) = (0.0, 0.0, 0.0);
    let n = size.len() as f64;
    for v in size {
        m += v / n;
    }
    for (v, p) in size.iter().zip(phi) {
        let r = p.to_radians();
        c += (v - m) * r.cos();
        s += (v - m) * r.sin();
    }
    s.atan2(c).to_degrees().rem_euclid(360.0)
}

/// Direction of motion of a feature along each run (+1, -1, 0 where it rests or at a
/// run's first row).
fn direction(rec: &Recording, f: &[f64]) -> Vec<f64> {
    let mut d = vec![0.0; f.len()];
    for run in &rec.runs {
        for k in run.rows.start + 1..run.rows.end {
            let delta = f[k] - f[k - 1];
            if delta.abs() > 1e-9 {
                d[k] = delta.signum();
            }
        }
    }
    d
}

/// The patterns of the error vectors `e` (one per recording row; rows with `mask`
/// false are left out), strongest first, and the share each explains. `tips` are the
/// modelled tips (for the workspace regression).
pub fn locate(rec: &Recording, e: &[[f64; 3]], mask: &[bool], tips: &[[f64; 3]]) -> Vec<Statement> {
    let errors = Errors::new(e, mask);
    if errors.sse <= 0.0 {
        return Vec::new();
    }
    let mut out = errors.by_run(rec);
    out.push(errors.offset());
    for f in features(rec) {
        out.extend(errors.feature_statement(&f));
        out.extend(errors.direction_statement(rec, &f));
    }
    out.push(errors.workspace(tips));
    out.sort_by(|a, b| b.explained.total_cmp(&a.explained));
    out
}

/// The error vectors a diagnosis locates, the rows that count, and what every
/// regression on them shares: the constant regressor, the error's size per row and
/// the squared error about zero.
struct Errors<'a> {
    e: &'a [[f64; 3]],
    mask: &'a [bool],
    /// The constant regressor (a one per row).
    ones: Vec<f64>,
    /// The error's size `|e|` per row.
    size: Vec<f64>,
    /// The squared error of the rows that count, about zero.
    sse: f64,
}

impl<'a> Errors<'a> {
    /// The errors `e` on the rows with `mask`.
    fn new(e: &'a [[f64; 3]], mask: &'a [bool]) -> Self {
        let rows = e.len();
        let sse: f64 = (0..rows)
            .filter(|&r| mask[r])
            .map(|r| e[r].iter().map(|v| v * v).sum::<f64>())
            .sum();
        let size: Vec<f64> = e
            .iter()
            .map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
            .collect();
        Errors {
            e,
            mask,
            ones: vec![1.0; rows],
            size,
            sse,
        }
    }

    /// By run: each run's share of the squared error, against its share of the rows.
    fn by_run(&self, rec: &Recording) -> Vec<Statement> {
        let (e, mask) = (self.e, self.mask);
        let mut out = Vec::new();
        for run in &rec.runs {
            let s: f64 = run
                .rows
                .clone()
                .filter(|&r| mask[r])
                .map(|r| e[r].iter().map(|v| v * v).sum::<f64>())
                .sum();
            let count = run.rows.clone().filter(|&r| mask[r]).count();
            if count == 0 {
                continue;
            }
            let share = s / self.sse;
            let rms = (s / count as f64).sqrt();
            out.push(Statement {
                kind: "run".into(),
                feature: run.label.clone(),
                explained: share,
                text: format!(
                    "run {}: {:.0}% of the squared error over {:.0}% of the rows (RMS {:.3} mm)",
                    run.label,
                    100.0 * share,
                    100.0 * count as f64 / mask.iter().filter(|m| **m).count() as f64,
                    rms
                ),
            });
        }
        out
    }

    /// A constant offset: `e = a`, with the mean error.
    fn offset(&self) -> Statement {
        let (e, mask) = (self.e, self.mask);
        let off = explained(e, std::slice::from_ref(&self.ones), mask);
        let mean = {
            let mut m = [0.0; 3];
            let c = mask.iter().filter(|m| **m).count() as f64;
            for r in (0..e.len()).filter(|&r| mask[r]) {
                for a in 0..3 {
                    m[a] += e[r][a] / c;
                }
            }
            m
        };
        Statement {
            kind: "offset".into(),
            feature: "constant".into(),
            explained: off,
            text: format!(
                "constant offset ({:.2}, {:.2}, {:.2}) mm: explains {:.0}% of the squared error",
                mean[0],
                mean[1],
                mean[2],
                100.0 * off
            ),
        }
    }

    /// The regression on one feature that varies over the rows: periodic in a rotation,
    /// or growing with a length or the time (`None` for a feature that stays put).
    fn feature_statement(&self, f: &Feature) -> Option<Statement> {
        let varies = spread_of(&f.values, self.mask) > 1e-6;
        varies.then(|| {
            if f.periodic {
                self.periodic(f)
            } else {
                self.grows_with(f)
            }
        })
    }

    /// Periodic in a rotation `phi`: `e = a + b cos phi + c sin phi`, with the angle
    /// where the error's size peaks.
    fn periodic(&self, f: &Feature) -> Statement {
        let (e, mask) = (self.e, self.mask);
        let c: Vec<f64> = f.values.iter().map(|v| v.to_radians().cos()).collect();
        let s: Vec<f64> = f.values.iter().map(|v| v.to_radians().sin()).collect();
        let ex = explained(e, &[self.ones.clone(), c, s], mask);
        let idx: Vec<usize> = (0..e.len()).filter(|&r| mask[r]).collect();
        let peak = peak_deg(
            &idx.iter().map(|&r| self.size[r]).collect::<Vec<_>>(),
            &idx.iter().map(|&r| f.values[r]).collect::<Vec<_>>(),
        );
        Statement {
            kind: "periodic".into(),
            feature: f.name.clone(),
            explained: ex,
            text: format!(
                "periodic in {} (one harmonic explains {:.0}% of the squared error; \
                 the error is largest near {:.0} deg)",
                f.name,
                100.0 * ex,
                peak
            ),
        }
    }

    /// Grows (or shrinks) with a joint, an exposed length or the time `f`:
    /// `e = a + b f`, with the correlation of the error's size with it.
    fn grows_with(&self, f: &Feature) -> Statement {
        let ex = explained(self.e, &[self.ones.clone(), f.values.clone()], self.mask);
        let r = pearson(&self.size, &f.values, self.mask);
        Statement {
            kind: "grows_with".into(),
            feature: f.name.clone(),
            explained: ex,
            text: format!(
                "{} with {} (linear fit explains {:.0}% of the squared error; \
                 correlation of the error's size with it r = {:.2})",
                if r >= 0.0 { "grows" } else { "shrinks" },
                f.name,
                100.0 * ex,
                r
            ),
        }
    }

    /// The direction of motion of a feature: `e = a + b sign(d f / dt)` over the rows
    /// where it moves, as a share of all the squared error (`None` unless it moves both
    /// ways on at least 10 rows).
    fn direction_statement(&self, rec: &Recording, f: &Feature) -> Option<Statement> {
        let (e, mask, ones) = (self.e, self.mask, &self.ones);
        let rows = e.len();
        let d = direction(rec, &f.values);
        let moving: Vec<bool> = (0..rows).map(|r| mask[r] && d[r] != 0.0).collect();
        let n_moving = moving.iter().filter(|m| **m).count();
        let both = d.iter().any(|v| *v > 0.0) && d.iter().any(|v| *v < 0.0);
        if n_moving < 10 || !both {
            return None;
        }
        let ex_dir = explained(e, &[ones.clone(), d.clone()], &moving)
            - explained(e, std::slice::from_ref(ones), &moving);
        // share of the whole error this opening carries
        let moving_sse: f64 = (0..rows)
            .filter(|&r| moving[r])
            .map(|r| e[r].iter().map(|v| v * v).sum::<f64>())
            .sum();
        let share = ex_dir.max(0.0) * moving_sse / self.sse;
        Some(Statement {
            kind: "direction".into(),
            feature: f.name.clone(),
            explained: share,
            text: format!(
                "depends on the direction of motion of {} (a loop that opens when it \
                 reverses: {:.0}% of the squared error of the rows where it moves, {:.0}% \
                 of all)",
                f.name,
                100.0 * ex_dir.max(0.0),
                100.0 * share
            ),
        })
    }

    /// Position in the workspace: `e = a + B p`, `p` the modelled tips (a frame
    /// mismatch).
    fn workspace(&self, tips: &[[f64; 3]]) -> Statement {
        let px: Vec<Vec<f64>> = (0..3)
            .map(|a| tips.iter().map(|p| p[a]).collect())
            .collect();
        let ws = explained(
            self.e,
            &[
                self.ones.clone(),
                px[0].clone(),
                px[1].clone(),
                px[2].clone(),
            ],
            self.mask,
        );
        Statement {
            kind: "workspace".into(),
            feature: "tip position".into(),
            explained: ws,
            text: format!(
                "varies linearly over the workspace (an affine map of the tip position explains \
                 {:.0}% of the squared error: a frame mismatch looks like this)",
                100.0 * ws
            ),
        }
    }
}

fn spread_of(v: &[f64], mask: &[bool]) -> f64 {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (x, m) in v.iter().zip(mask) {
        if *m {
            lo = lo.min(*x);
            hi = hi.max(*x);
        }
    }
    hi - lo
}

fn pearson(a: &[f64], b: &[f64], mask: &[bool]) -> f64 {
    let idx: Vec<usize> = (0..a.len()).filter(|&r| mask[r]).collect();
    let n = idx.len() as f64;
    let ma = idx.iter().map(|&r| a[r]).sum::<f64>() / n;
    let mb = idx.iter().map(|&r| b[r]).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for &r in &idx {
        sab += (a[r] - ma) * (b[r] - mb);
        saa += (a[r] - ma).powi(2);
        sbb += (b[r] - mb).powi(2);
    }
    if saa > 0.0 && sbb > 0.0 {
        sab / (saa * sbb).sqrt()
    } else {
        0.0
    }
}

/// Share of the squared error a pattern must explain to be named in a [`summary`]: one
/// that explains less (printed as 0 %) says nothing of where the error sits.
pub const NAMED_PATTERN_SHARE: f64 = 0.005;

/// A one-line summary of where a pattern of error sits: the runs that carry most of it
/// and its strongest non-run pattern (where that explains at least
/// [`NAMED_PATTERN_SHARE`]).
pub fn summary(statements: &[Statement]) -> String {
    let mut runs: Vec<&Statement> = statements.iter().filter(|s| s.kind == "run").collect();
    runs.sort_by(|a, b| b.explained.total_cmp(&a.explained));
    let mut acc = 0.0;
    let mut names = Vec::new();
    for r in runs {
        if acc >= 0.8 {
            break;
        }
        acc += r.explained;
        names.push(format!("{} ({:.0}%)", r.feature, 100.0 * r.explained));
    }
    let pattern = statements
        .iter()
        .filter(|s| s.kind != "run")
        .max_by(|a, b| a.explained.total_cmp(&b.explained))
        .filter(|p| p.explained >= NAMED_PATTERN_SHARE);
    let mut out = format!("runs {}", names.join(", "));
    if let Some(p) = pattern {
        out += "; ";
        out += &p.text;
    }
    out
}

/// What produces a pattern of error outside the contract's vocabulary, in words an
/// engineer acts on (for what no effect explains).
pub fn causes(s: &Statement) -> Option<String> {
    let f = &s.feature;
    let own_rotation = f.starts_with("theta") && !f.contains(" - ");
    Some(match s.kind.as_str() {
        "periodic" if own_rotation => format!(
            "an error once per turn of {f}'s own drive: gear or encoder runout, an \
             eccentric coupling, or a gear ratio that is off (check that rotation's drive)"
        ),
        "periodic" => format!(
            "an error that follows the relative rotation {f}: a tube's precurvature that is \
             not planar or not uniform, or anisotropic bending, neither in the model"
        ),
        "grows_with" if f == "time t_s" => "a drift in time: the tracker's frame creeping, \
             thermal expansion, or a mount that slips (check the tracker's reference)"
            .into(),
        "grows_with" => format!(
            "an error that grows with {f}: a wrong lead-screw pitch (feed gain) or a length \
             that is off on that feed (check its drive's calibration)"
        ),
        "workspace" => "an error linear in the tip position: a tracker scale or calibration \
             error (a registration is rigid and cannot take it)"
            .into(),
        "direction" => format!(
            "an error that opens when {f} reverses: backlash or friction beyond the play \
             model"
        ),
        "offset" => "a constant offset: a mounting or tracker offset".into(),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn statement(kind: &str, feature: &str, explained: f64) -> Statement {
        Statement {
            kind: kind.into(),
            feature: feature.into(),
            explained,
            text: format!("{kind} of {feature}"),
        }
    }

    /// The strongest pattern is named where it explains a share of the error, and left
    /// out where it explains next to nothing (it would print as 0 %).
    #[test]
    fn a_pattern_that_explains_nothing_is_not_named() {
        let runs = [statement("run", "a", 0.6), statement("run", "b", 0.4)];
        let with = |p: Statement| summary(&[runs[0].clone(), runs[1].clone(), p]);
        assert_eq!(
            with(statement("direction", "s3 - s2", 0.001)),
            "runs a (60%), b (40%)"
        );
        assert_eq!(
            with(statement("direction", "s3 - s2", 0.2)),
            "runs a (60%), b (40%); direction of s3 - s2"
        );
    }
}

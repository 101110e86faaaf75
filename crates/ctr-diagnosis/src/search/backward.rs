//! The search revisits what it added: an effect that entered early may stand in for
//! one that came later (a joint offset taking part of a precurvature, a frame taking a
//! common rotation of the joints), and forward selection never takes it back. So when
//! no candidate enters any more, every effect found is tested again as it had to enter,
//! against the model without it, refitted: the information criterion on the fit rows
//! and the held-out gain ([`MIN_HELDOUT_GAIN`], on the rows [`Scored`] counts). The
//! one that fails by most leaves and the rest are refitted together; then all are
//! tested again, until every effect pays its way.
//!
//! A refit per effect per pass would cost as much as the search; so each pass ranks the
//! effects by their test in the Gauss-Newton model of the fitted point (one Jacobian of
//! every effect's parameters on every row: an effect set to its nominal, the others
//! moved as the normal equations say, the fit rows' cost and the held-out rows' errors
//! predicted), and only the one the model says fails by most is refitted to confirm.

use super::MIN_HELDOUT_GAIN;
use crate::candidates::EffectId;
use crate::found::Found;
use crate::levenberg::{huber, robust_information};
use crate::report::{Trial, REMOVED};
use crate::residual::{components, RowError};
use crate::scored::Scored;
use crate::start::Start;
use crate::uncertainty::attach::problem_of;
use crate::verify::Removed;
use nalgebra::{DMatrix, DVector};

/// Most effects a revisit confirms by a refit that then stay (each costs a joint fit).
const MAX_CONFIRMED_KEPT: usize = 2;

/// `found` with the effects that no longer pay their way taken out (module doc), each
/// with a trial of round `round` saying so; the findings taken out, as they were, and
/// why.
pub(crate) fn revisit(start: &Start, found: &mut Found, round: usize) -> Vec<Removed> {
    let mut kept: Vec<EffectId> = Vec::new();
    let mut out = Vec::new();
    while !found.findings.is_empty() && kept.len() < MAX_CONFIRMED_KEPT {
        let Some(ranked) = linearised(start, found) else {
            return out;
        };
        let Some(&(c, _)) = ranked
            .iter()
            .find(|(c, pays)| !pays.is_finite_keep() && !kept.contains(c))
        else {
            return out;
        };
        if c == EffectId::Registration && found.frame_profiled {
            // the tracker's frame stays in the model whatever it is graded (the rest of
            // the account then does not depend on how the tracker was registered): only
            // its place among the findings is tested, against the others refitted with
            // the nominal frame
            let mut nominal = found.clone();
            nominal.findings.retain(|f| f.effect != c);
            nominal.frame_profiled = false;
            c.remove(&mut nominal.model);
            let test = nominal
                .refit(start)
                .then(|| Test::of(start, found, &nominal, c));
            match test {
                Some(t) if !t.keeps() => {
                    found.findings.retain(|f| f.effect != c);
                    found.tried.push(Trial {
                        round,
                        effect: c,
                        rms_mm: found.fig.rms_mm,
                        heldout_rms_mm: found.fig.heldout_rms_mm,
                        bic_change: t.bic,
                        added: false,
                        note: format!(
                            "no finding: {} against the others refitted with the nominal \
                             frame; kept in the model as the tracker's frame (solved in \
                             every fit)",
                            t.words()
                        ),
                    });
                    kept.clear();
                }
                _ => kept.push(c),
            }
            continue;
        }
        let mut without = found.clone();
        without.findings.retain(|f| f.effect != c);
        c.remove(&mut without.model);
        if !without.refit(start) {
            kept.push(c);
            continue;
        }
        let test = Test::of(start, found, &without, c);
        if test.keeps() {
            kept.push(c);
            continue;
        }
        let why = format!(
            "{} against the model without it, refitted, when the effects found were \
             revisited",
            test.words()
        );
        without.tried.push(Trial {
            round,
            effect: c,
            rms_mm: found.fig.rms_mm,
            heldout_rms_mm: found.fig.heldout_rms_mm,
            bic_change: test.bic,
            added: false,
            note: format!("{REMOVED}{why}"),
        });
        if let Some(finding) = found.findings.iter().find(|f| f.effect == c) {
            out.push(Removed {
                finding: finding.clone(),
                why,
            });
        }
        *found = without;
        kept.clear();
    }
    out
}

/// An effect's entry test against the model without it.
#[derive(Clone, Copy, Debug)]
struct Test {
    /// The information criterion's change with it (negative: it pays).
    bic: f64,
    /// Whether it gains on the held-out rows.
    gains: bool,
}

impl Test {
    /// The test of `c` in `with` against `without`.
    fn of(start: &Start, with: &Found, without: &Found, c: EffectId) -> Self {
        let scored = Scored::from(&without.e, &start.held);
        Test {
            bic: bic(start, with.cost, without.cost, c),
            gains: scored.score(start.rec, &with.e)
                < (1.0 - MIN_HELDOUT_GAIN) * scored.score(start.rec, &without.e),
        }
    }

    fn keeps(&self) -> bool {
        self.bic < 0.0 && self.gains
    }

    /// Whether it keeps its place (finite criterion and both tests).
    fn is_finite_keep(&self) -> bool {
        self.bic.is_finite() && self.keeps()
    }

    fn words(&self) -> &'static str {
        if self.bic >= 0.0 {
            "the information criterion rejects it"
        } else {
            "no gain on held-out rows"
        }
    }
}

/// The information criterion's change of `c` entering: `n ln(with / without) + k ln n`.
fn bic(start: &Start, with: f64, without: f64, c: EffectId) -> f64 {
    let n_obs = (components(start.rec) * start.fit_rows.len()) as f64;
    let k = c.n_params(start.user.robot.n_tubes()) as f64;
    n_obs * (with / without).ln() + k * n_obs.ln()
}

/// Every effect of `found` (torsion aside) with its test in the Gauss-Newton model of
/// the fitted point, those that fail by most (highest criterion) first; `None` where
/// the Jacobian cannot be had.
fn linearised(start: &Start, found: &Found) -> Option<Vec<(EffectId, Test)>> {
    let rec = start.rec;
    let n = rec.rows.len();
    let all: Vec<usize> = (0..n).collect();
    let effects = found.effects();
    let p = problem_of(
        rec,
        &found.model,
        &effects,
        &all,
        start.huber_mm(),
        start.threads,
    );
    let findings: Vec<EffectId> = found.findings.iter().map(|f| f.effect).collect();
    if p.blocks.is_empty() {
        return None;
    }
    let x = p.read(&found.model);
    let nominal = p.read(&start.user);
    let pred = p.predictions(&x)?;
    let e = p.errors(&pred);
    let jac = p.jacobian(&x, &pred)?;
    let np = x.len();
    // the residual's chunks of three: positions of every row, then angles of every row
    let chunks = e.len() / 3;
    let row_of = |i: usize| i % n;
    let fit_chunks: Vec<usize> = (0..chunks.min(2 * n))
        .filter(|&i| !start.held[row_of(i)])
        .collect();
    let sub = |idx: &[usize]| -> (DMatrix<f64>, Vec<f64>) {
        let mut j = DMatrix::<f64>::zeros(3 * idx.len(), np);
        let mut v = Vec::with_capacity(3 * idx.len());
        for (k, &i) in idx.iter().enumerate() {
            for a in 0..3 {
                j.set_row(3 * k + a, &jac.row(3 * i + a));
                v.push(e[3 * i + a]);
            }
        }
        (j, v)
    };
    let (jf, ef) = sub(&fit_chunks);
    let (cost, w) = huber(&ef, start.huber_mm());
    let h = robust_information(&jf, &w, &ef, np);
    let mut g = DVector::<f64>::zeros(np);
    for (k, wk) in w.iter().enumerate() {
        for a in 0..3 {
            let i = 3 * k + a;
            g.axpy(wk * ef[i], &jf.row(i).transpose(), 1.0);
        }
    }
    let e_with = row_errors(&e, None, n, chunks);
    let mut out = Vec::new();
    for &c in &findings {
        let idx: Vec<usize> = (0..np).filter(|&j| p.effect_of(j) == c).collect();
        if idx.is_empty() {
            continue;
        }
        let mut d = DVector::<f64>::zeros(np);
        for (i, &j) in idx.iter().enumerate() {
            if c.absence_of(i) {
                d[j] = nominal[j] - x[j];
            }
        }
        let d = others_moved(&h, &g, d, &idx)?;
        let increase = 2.0 * g.dot(&d) + (&h * &d).dot(&d);
        let moved = &jac * &d;
        let e_without = row_errors(&e, Some(moved.as_slice()), n, chunks);
        let scored = Scored::from(&e_without, &start.held);
        let test = Test {
            bic: bic(start, cost, cost + increase.max(0.0), c),
            gains: scored.score(rec, &e_with)
                < (1.0 - MIN_HELDOUT_GAIN) * scored.score(rec, &e_without),
        };
        out.push((c, test));
    }
    out.sort_by(|a, b| b.1.bic.total_cmp(&a.1.bic));
    Some(out)
}

/// The step `d` (set on the parameters `fixed`) with the other parameters moved as the
/// Gauss-Newton model of curvature `h` and gradient `g` says:
/// `H_oo d_o = -(g_o + H_of d_f)` (`None` where that cannot be solved).
fn others_moved(
    h: &DMatrix<f64>,
    g: &DVector<f64>,
    mut d: DVector<f64>,
    fixed: &[usize],
) -> Option<DVector<f64>> {
    let np = d.len();
    let others: Vec<usize> = (0..np).filter(|j| !fixed.contains(j)).collect();
    if others.is_empty() {
        return Some(d);
    }
    let dmax = (0..np).map(|j| h[(j, j)]).fold(0.0, f64::max);
    let k = others.len();
    let hoo = DMatrix::from_fn(k, k, |a, b| h[(others[a], others[b])])
        + DMatrix::identity(k, k) * (1e-9 * dmax.max(f64::MIN_POSITIVE));
    let rhs = DVector::from_fn(k, |a, _| {
        -(g[others[a]] + fixed.iter().map(|&j| h[(others[a], j)] * d[j]).sum::<f64>())
    });
    let sol = hoo.cholesky()?.solve(&rhs);
    for (a, &j) in others.iter().enumerate() {
        d[j] = sol[a];
    }
    Some(d)
}

/// The error vectors of every one of `n` rows from a residual `e` laid out as a fit's
/// (the positions of every row, then with `chunks >= 2 n` the angles of every row),
/// moved by `moved` where given.
fn row_errors(e: &[f64], moved: Option<&[f64]>, n: usize, chunks: usize) -> Vec<RowError> {
    let at = |i: usize, a: usize| {
        let k = 3 * i + a;
        e.get(k).copied().unwrap_or(0.0) + moved.and_then(|m| m.get(k)).copied().unwrap_or(0.0)
    };
    (0..n)
        .map(|r| {
            let ang = if chunks >= 2 * n {
                [0, 1, 2].map(|a| at(n + r, a))
            } else {
                [0.0; 3]
            };
            [at(r, 0), at(r, 1), at(r, 2), ang[0], ang[1], ang[2]]
        })
        .collect()
}

//! Robust bounded least squares of effect parameters against a recording.
//!
//! The residual of row i is `e_i = predicted_i - measured_i` (mm, 3 components), and
//! with weighted angular columns its angular error (mm-equivalent,
//! [`crate::residual::angular_errors`]) after all rows' positions. The cost is Huber's
//! on each of these 3-vectors' norm (quadratic up to `c`, linear beyond), so a
//! few tracker outliers cannot decide a fit:
//!
//! ```text
//! rho(|e|) = |e|^2 for |e| <= c,   2 c |e| - c^2 beyond
//! ```
//!
//! minimised by Levenberg-Marquardt on iteratively reweighted least squares (weights
//! `w_i = min(1, c / |e_i|)`, the gradient `J^T W e` exact). Its curvature is the
//! cost's own Gauss-Newton Hessian: a row within `c` weighs `J_i^T J_i`, a row beyond
//! weighs `w_i J_i^T (I - u_i u_i^T) J_i` (`u_i = e_i / |e_i|`), since `rho` grows
//! linearly along the error there and has no curvature in that direction. Reweighting
//! alone (`w_i J_i^T J_i`) would overstate that curvature, shorten every step along
//! the outliers' errors and converge only linearly (on a real recording whose rows
//! mostly lie beyond `c`, a third of the gain per step). The Jacobian of the
//! predictions with respect to the parameters comes from the simulator by central
//! differences at each parameter's natural scale (one-sided at a bound), its columns
//! computed in parallel ([`crate::jacobian`]: without solving for the effects that
//! leave the mechanics alone). Each step solves `(H + lambda D) d = -J^T W e` (`H`
//! that curvature, `D` its diagonal); when the step leaves the parameters' bounds it
//! is solved again as a box-constrained QP with clarabel.

use crate::candidates::EffectId;
use crate::residual::angular_errors;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::{predict_rows_on, Prediction};
use ctr_formats::Recording;
use nalgebra::{DMatrix, DVector};

/// A fit problem: which effects' parameters move, on which rows.
#[derive(Clone, Debug)]
pub(crate) struct Problem<'a> {
    /// The model with every effect that is not fitted.
    pub base: ModelSpec,
    /// The effects fitted, their parameters concatenated in this order.
    pub blocks: Vec<EffectId>,
    pub rec: &'a Recording,
    /// Rows whose residuals count, ascending (only they are solved).
    pub rows: Vec<usize>,
    /// Huber threshold on a row's error norm, mm.
    pub huber_mm: f64,
    /// Threads for the Jacobian's columns.
    pub threads: usize,
    /// Fit the clearance as a table of this many values per pair (the seed's measured
    /// "database") instead of the cosine profile; its roughness (periodic second
    /// differences) is penalised so the table stays smooth.
    pub clearance_table: Option<usize>,
}

/// Jacobians per fit.
pub(crate) const MAX_FIT_ITERATIONS: usize = 25;

/// Weight of a clearance table's roughness: one degree of second difference costs as
/// much as this many mm of tip error on one row.
const TABLE_SMOOTHNESS_MM_PER_DEG: f64 = 2.0;

impl Problem<'_> {
    pub(crate) fn table(&self, b: EffectId) -> Option<usize> {
        self.clearance_table.filter(|_| b == EffectId::Clearance)
    }

    /// Parameters of block `b`.
    pub fn block_len(&self, b: EffectId) -> usize {
        let n = self.n_tubes();
        match self.table(b) {
            Some(k) => k * n.saturating_sub(1),
            None => b.n_params(n),
        }
    }

    fn write_block(&self, b: EffectId, m: &mut ModelSpec, x: &[f64]) {
        match self.table(b) {
            Some(k) => {
                m.effects.clearance = Some(ctr_formats::Clearance {
                    max_deflection_deg: vec![],
                    peak_deg: vec![],
                    table_deg: x.chunks(k).map(<[f64]>::to_vec).collect(),
                })
            }
            None => b.write(m, x),
        }
    }

    /// Roughness rows of the clearance tables in `x`, mm-equivalent.
    fn roughness(&self, x: &[f64]) -> Vec<f64> {
        let mut out = Vec::new();
        let mut at = 0;
        for &b in &self.blocks {
            let len = self.block_len(b);
            if let Some(k) = self.table(b) {
                for t in x[at..at + len].chunks(k) {
                    for i in 0..k {
                        let d = t[(i + k - 1) % k] - 2.0 * t[i] + t[(i + 1) % k];
                        out.extend([TABLE_SMOOTHNESS_MM_PER_DEG * d, 0.0, 0.0]);
                    }
                }
            }
            at += len;
        }
        out
    }
}

/// Where a fit ended.
#[derive(Clone, Debug)]
pub(crate) struct Fitted {
    pub x: Vec<f64>,
    /// Robust cost (sum over rows of rho), mm^2.
    pub cost: f64,
    /// The fit stopped because the cost could not reach its target (see
    /// [`Problem::fit_until`]): `cost` is where it stopped, not a minimum.
    pub gave_up: bool,
    /// The fit ended where no step lowered the cost although the linearised problem
    /// promised a gain of more than [`STUCK_GAIN`] of the cost: not a minimum it can
    /// vouch for.
    pub stuck: bool,
}

/// Share of the cost the Gauss-Newton model's decrease may promise at the end of a fit
/// that found no lower cost, for the end to count as a minimum rather than stuck.
const STUCK_GAIN: f64 = 1e-6;

/// How many times the Gauss-Newton model's decrease the rest of a fit may still gain
/// before [`Problem::fit_until`] gives up on a target: the model is exact for a linear
/// problem within the Huber threshold and near a minimum, and this margin covers its
/// error further out (beyond the threshold, where the cost is linear along a row's
/// error, the model promises more than a step gains: giving up later, never wrongly).
const PROJECTED_GAIN_MARGIN: f64 = 4.0;

/// The smallest change of the information criterion (`n ln(cost ratio)`, `n` the
/// error components: twice a log-likelihood ratio, so 0.01 nats) a fit's step, scaled
/// up by its damping (`(1 + lambda)` times what it gained: about what the undamped step
/// would have; a step shortened by damping says little about the minimum), must gain
/// for the fit to go on. Near a minimum the robust Gauss-Newton steps shrink at least
/// geometrically, so what is left is of the same order: below any decision taken on
/// the cost (the criterion's penalty is `ln n`, about 8, per parameter; the learned
/// discrepancy's likelihood stops at the same 0.01 nats).
const CRITERION_RESOLUTION: f64 = 0.02;

impl Problem<'_> {
    pub fn n_tubes(&self) -> usize {
        self.base.robot.n_tubes()
    }

    /// The effect parameter `j` belongs to.
    pub fn effect_of(&self, j: usize) -> EffectId {
        let mut at = 0;
        for &b in &self.blocks {
            at += self.block_len(b);
            if j < at {
                return b;
            }
        }
        unreachable!("parameter index within the blocks")
    }

    /// Parameter `j` in words (a clearance table's value by its pair and index).
    pub fn label(&self, j: usize) -> crate::candidates::Label {
        let n = self.n_tubes();
        let mut at = 0;
        for &b in &self.blocks {
            let k = self.block_len(b);
            if j < at + k {
                return match self.table(b) {
                    Some(size) => crate::candidates::Label {
                        name: format!(
                            "clearance table value {} of tubes {}-{}",
                            (j - at) % size + 1,
                            (j - at) / size + 1,
                            (j - at) / size + 2
                        ),
                        unit: "deg",
                        log: false,
                    },
                    None => b.label(n, j - at),
                };
            }
            at += k;
        }
        unreachable!("parameter index within the blocks")
    }

    /// The parameters of the blocks as `m` holds them (a clearance table's values
    /// when fitted as a table).
    pub fn read(&self, m: &ModelSpec) -> Vec<f64> {
        let mut x = Vec::new();
        for &b in &self.blocks {
            match self.table(b) {
                // a table's values (zeros where the model has none)
                Some(k) => {
                    let pairs = self.n_tubes().saturating_sub(1);
                    let c = m.effects.clearance.as_ref();
                    for i in 0..pairs {
                        let t = c.and_then(|c| c.table_deg.get(i));
                        x.extend((0..k).map(|v| t.and_then(|t| t.get(v)).copied().unwrap_or(0.0)));
                    }
                }
                None => x.extend(b.read(m)),
            }
        }
        x
    }

    /// The model with parameters `x`.
    pub fn model(&self, x: &[f64]) -> ModelSpec {
        let mut m = self.base.clone();
        let mut at = 0;
        for &b in &self.blocks {
            let k = self.block_len(b);
            self.write_block(b, &mut m, &x[at..at + k]);
            at += k;
        }
        m
    }

    /// Natural scale (finite-difference step) and bounds of parameter `j`.
    pub fn scale(&self, j: usize) -> (f64, (f64, f64)) {
        let n = self.n_tubes();
        let mut at = 0;
        for &b in &self.blocks {
            let k = self.block_len(b);
            if j < at + k {
                if self.table(b).is_some() {
                    return (b.step(n, 0), b.bounds(n, 0));
                }
                return (b.step(n, j - at), b.bounds(n, j - at));
            }
            at += k;
        }
        unreachable!("parameter index within the blocks")
    }

    /// Predictions of the counted rows, 3 per row (only they are solved), then with
    /// weighted angular columns their angular errors, 3 per row (already relative to
    /// the measurement), then the roughness rows; `None` where the model cannot be
    /// simulated on them (joints pushed out of range, ...).
    pub fn predictions(&self, x: &[f64]) -> Option<Vec<f64>> {
        self.predictions_on(x, self.threads)
    }

    /// [`predictions`](Self::predictions) with the runs on `threads` workers (1 inside
    /// a job of the pool).
    pub(crate) fn predictions_on(&self, x: &[f64], threads: usize) -> Option<Vec<f64>> {
        let pred = predict_rows_on(&self.model(x), self.rec, &self.rows, threads).ok()?;
        self.assembled(&pred, x)
    }

    /// [`predictions`](Self::predictions) laid out from a prediction `pred` of the
    /// model at `x`.
    pub(crate) fn assembled(&self, pred: &Prediction, x: &[f64]) -> Option<Vec<f64>> {
        let mut out = Vec::with_capacity(3 * self.rows.len());
        for &r in &self.rows {
            out.extend_from_slice(&pred.p[r]);
        }
        if self.rec.angular.is_some() {
            let ang = angular_errors(self.rec, pred);
            for &r in &self.rows {
                out.extend_from_slice(&ang[r]);
            }
        }
        out.extend(self.roughness(x));
        out.iter().all(|v| v.is_finite()).then_some(out)
    }

    /// Errors (predicted - measured) of predictions `pred`, 3 per counted row, then the
    /// angular and roughness rows as they are.
    pub fn errors(&self, pred: &[f64]) -> Vec<f64> {
        let mut e = pred.to_vec();
        for (k, &r) in self.rows.iter().enumerate() {
            for a in 0..3 {
                e[3 * k + a] -= self.rec.rows[r].p[a];
            }
        }
        e
    }

    /// Robust cost and IRLS weights of the errors.
    pub fn cost(&self, e: &[f64]) -> (f64, Vec<f64>) {
        huber(e, self.huber_mm)
    }

    /// Robust cost at `x` (`None` if it cannot be simulated).
    pub fn cost_at(&self, x: &[f64]) -> Option<f64> {
        let p = self.predictions(x)?;
        Some(self.cost(&self.errors(&p)).0)
    }

    /// Levenberg-Marquardt from `x0` (clamped to the bounds) for at most `max_iter`
    /// Jacobians; `None` if the start cannot be simulated.
    pub fn fit(&self, x0: &[f64], max_iter: usize) -> Option<Fitted> {
        self.fit_until(x0, max_iter, None)
    }

    /// [`fit`](Self::fit) that gives up when the cost cannot come below `target`
    /// (mm^2): at each Jacobian, the weighted Gauss-Newton model's decrease
    /// `g^T H^-1 g` (`H` the robust curvature of [`normal_equations`], `g = J^T W e`) is what the linearised problem can
    /// still gain; when the cost less [`PROJECTED_GAIN_MARGIN`] times that stays above
    /// the target, going on would only confirm that it is not reached.
    pub fn fit_until(&self, x0: &[f64], max_iter: usize, target: Option<f64>) -> Option<Fitted> {
        let np = x0.len();
        let bounds: Vec<(f64, f64)> = (0..np).map(|j| self.scale(j).1).collect();
        let x: Vec<f64> = x0
            .iter()
            .zip(&bounds)
            .map(|(v, (lo, hi))| v.clamp(*lo, *hi))
            .collect();
        let start = self.iterate(x)?;
        if np == 0 {
            return Some(start.fitted(false));
        }
        let (mut now, gave_up) = self.descend(start, max_iter, target, &bounds);
        // Walled in at its start: every step the linearised problem asks for raised the
        // cost, as where a row a step away snaps to another branch of the mechanics (a
        // real robot's path near its stability limit). Once, from the point the
        // least damped step reached, descend again; the end counts where it is lower.
        if let Some(beyond) = now.beyond.take().and_then(|x| self.iterate(x)) {
            let (again, again_gave_up) = self.descend(beyond, max_iter, target, &bounds);
            if again.cost < now.cost {
                return Some(again.fitted(again_gave_up));
            }
        }
        Some(now.fitted(gave_up))
    }

    /// Levenberg-Marquardt from `now` within `bounds`, at most `max_iter` Jacobians:
    /// where it ended, and whether it gave up on `target` (see [`Self::fit_until`]).
    fn descend(
        &self,
        mut now: Iterate,
        max_iter: usize,
        target: Option<f64>,
        bounds: &[(f64, f64)],
    ) -> (Iterate, bool) {
        let np = now.x.len();
        let mut lambda: f64 = 1e-3;
        for _ in 0..max_iter {
            let (jac, blocked) = self.jacobian_and_blocked(&now.x, &now.p);
            let (h, g) = normal_equations(&jac, &now.w, &now.e, np);
            let dmax = (0..np).map(|j| h[(j, j)]).fold(0.0, f64::max);
            if dmax <= 0.0 {
                break;
            }
            if let Some(target) = target {
                if now.cost - PROJECTED_GAIN_MARGIN * projected_gain(&h, &g, dmax) > target {
                    return (now, true);
                }
            }
            // a side that cannot be simulated bounds this iteration's steps
            let step_bounds = held_at_blocked(bounds, &blocked, &now.x);
            match self.damped_step(&mut now, &h, &g, dmax, &step_bounds, &mut lambda) {
                Ok(true) => continue,
                Ok(false) => break,
                Err(tried) => {
                    now.stuck =
                        now.steps == 0 && projected_gain(&h, &g, dmax) > STUCK_GAIN * now.cost;
                    if now.stuck {
                        now.beyond = tried;
                    }
                    break;
                }
            }
        }
        (now, false)
    }

    /// The fit's state at parameters `x` (`None` if they cannot be simulated).
    fn iterate(&self, x: Vec<f64>) -> Option<Iterate> {
        let p = self.predictions(&x)?;
        let e = self.errors(&p);
        let (cost, w) = self.cost(&e);
        Some(Iterate {
            x,
            p,
            e,
            cost,
            w,
            steps: 0,
            stuck: false,
            beyond: None,
        })
    }

    /// One Levenberg-Marquardt step from `now` on the normal equations `(h, g)`
    /// (largest diagonal `dmax`): the damping `lambda` raised tenfold until a step
    /// within `bounds` lowers the cost (at most 12 tries), then eased threefold.
    /// Whether the fit goes on: a step was taken and it was not negligible (relative
    /// decrease below `1e-7`, every parameter moved less than `1e-3` of its scale, or a
    /// gain, scaled up by the damping, below [`CRITERION_RESOLUTION`]);
    /// `Err` when no step lowered the cost, with where the least damped step that could
    /// be simulated led.
    fn damped_step(
        &self,
        now: &mut Iterate,
        h: &DMatrix<f64>,
        g: &DVector<f64>,
        dmax: f64,
        bounds: &[(f64, f64)],
        lambda: &mut f64,
    ) -> Result<bool, Option<Vec<f64>>> {
        let np = now.x.len();
        let mut first_tried = None;
        for _ in 0..12 {
            let mut a = h.clone();
            for j in 0..np {
                a[(j, j)] += *lambda * h[(j, j)].max(1e-9 * dmax);
            }
            let Some(step) = solve_step(&a, g, &now.x, bounds) else {
                *lambda *= 10.0;
                continue;
            };
            let xn: Vec<f64> = now.x.iter().zip(&step).map(|(a, b)| a + b).collect();
            if let Some(next) = self.iterate(xn) {
                if next.cost < now.cost {
                    let rel = (now.cost - next.cost) / now.cost.max(f64::MIN_POSITIVE);
                    let small = step
                        .iter()
                        .enumerate()
                        .all(|(j, d)| d.abs() < 1e-3 * self.scale(j).0);
                    let steps = now.steps + 1;
                    *now = Iterate { steps, ..next };
                    // the information criterion's change, n ln(cost ratio), and what an
                    // undamped step would have gained, about (1 + lambda) times it
                    let gain = -(now.e.len() as f64) * (1.0 - rel).ln();
                    let creeping = gain * (1.0 + *lambda) < CRITERION_RESOLUTION;
                    *lambda = (*lambda / 3.0).max(1e-9);
                    return Ok(!(rel < 1e-7 || small || creeping));
                }
                first_tried.get_or_insert(next.x);
            }
            *lambda *= 10.0;
        }
        Err(first_tried)
    }
}

/// Where Levenberg-Marquardt stands: the parameters, their predictions and errors,
/// the robust cost and the IRLS weights.
struct Iterate {
    x: Vec<f64>,
    p: Vec<f64>,
    e: Vec<f64>,
    cost: f64,
    w: Vec<f64>,
    /// Steps taken to get here.
    steps: usize,
    /// Ended where no step lowered the cost though the linearised problem promised a
    /// gain (see [`Fitted::stuck`]).
    stuck: bool,
    /// Where the least damped of the steps tried then led (simulated, not lower): the
    /// point [`Problem::fit_until`] descends from once more.
    beyond: Option<Vec<f64>>,
}

impl Iterate {
    /// The fit ending here (`gave_up`: on its target).
    fn fitted(self, gave_up: bool) -> Fitted {
        Fitted {
            x: self.x,
            cost: self.cost,
            gave_up,
            stuck: self.stuck,
        }
    }
}

/// Huber's cost of errors `e` (3-vectors) at threshold `c`, and each 3-vector's IRLS
/// weight `min(1, c / |e_i|)`.
fn huber(e: &[f64], c: f64) -> (f64, Vec<f64>) {
    let mut cost = 0.0;
    let w = e
        .chunks(3)
        .map(|v| {
            let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if d <= c {
                cost += d * d;
                1.0
            } else {
                cost += 2.0 * c * d - c * c;
                c / d
            }
        })
        .collect();
    (cost, w)
}

/// `bounds` with each parameter held at its value `x` on a side where the model cannot
/// be simulated a step away (`blocked`: up, down).
fn held_at_blocked(bounds: &[(f64, f64)], blocked: &[[bool; 2]], x: &[f64]) -> Vec<(f64, f64)> {
    bounds
        .iter()
        .zip(blocked)
        .zip(x)
        .map(|(((lo, hi), [up, down]), &xj)| {
            (if *down { xj } else { *lo }, if *up { xj } else { *hi })
        })
        .collect()
}

/// The robust cost's normal equations `H = sum_i J_i^T W_i J_i`, `g = J^T W e` of
/// Jacobian `jac`, weights `w` (one per 3 rows of `jac`) and errors `e`, over `np`
/// parameters ([`robust_information`] and the weighted gradient).
fn normal_equations(
    jac: &DMatrix<f64>,
    w: &[f64],
    e: &[f64],
    np: usize,
) -> (DMatrix<f64>, DVector<f64>) {
    let mut g = DVector::<f64>::zeros(np);
    for (row, wr) in w.iter().enumerate() {
        for a in 0..3 {
            let i = 3 * row + a;
            let we = wr * e[i];
            for (c, gc) in g.iter_mut().enumerate() {
                *gc += jac[(i, c)] * we;
            }
        }
    }
    (robust_information(jac, w, e, np), g)
}

/// The Gauss-Newton curvature of Huber's cost, `H = sum_i J_i^T W_i J_i`, of Jacobian
/// `jac`, weights `w` (one per 3 rows of `jac`) and errors `e`, over `np` parameters:
/// `W_i = I` within the threshold (`w_i = 1`), `w_i (I - u_i u_i^T)` beyond it, `u_i`
/// the row's error direction (the cost grows only linearly along it; see the module
/// doc). The fit's steps and the intervals' information ([`crate::uncertainty`]) both
/// use it.
pub(crate) fn robust_information(
    jac: &DMatrix<f64>,
    w: &[f64],
    e: &[f64],
    np: usize,
) -> DMatrix<f64> {
    let mut h = DMatrix::<f64>::zeros(np, np);
    for (row, wr) in w.iter().enumerate() {
        for a in 0..3 {
            let ji = jac.row(3 * row + a);
            for c1 in 0..np {
                let v = wr * ji[c1];
                if v == 0.0 {
                    continue;
                }
                for c2 in c1..np {
                    h[(c1, c2)] += v * ji[c2];
                }
            }
        }
    }
    let mut along = vec![0.0; np];
    for (row, &wr) in w.iter().enumerate() {
        let er = &e[3 * row..3 * row + 3];
        let norm = (er[0] * er[0] + er[1] * er[1] + er[2] * er[2]).sqrt();
        if wr >= 1.0 || norm == 0.0 {
            continue;
        }
        // remove the curvature along the error: w (u^T J_i)^T (u^T J_i)
        for (c, a) in along.iter_mut().enumerate() {
            *a = (0..3).map(|k| er[k] / norm * jac[(3 * row + k, c)]).sum();
        }
        for c1 in 0..np {
            for c2 in c1..np {
                h[(c1, c2)] -= wr * along[c1] * along[c2];
            }
        }
    }
    for c1 in 0..np {
        for c2 in 0..c1 {
            h[(c1, c2)] = h[(c2, c1)];
        }
    }
    h
}

/// The Gauss-Newton model's decrease `g^T H^-1 g` of the weighted sum of squares
/// (`H` regularised by a relative `1e-9` of its largest diagonal where singular).
pub(crate) fn projected_gain(h: &DMatrix<f64>, g: &DVector<f64>, dmax: f64) -> f64 {
    let mut a = h.clone();
    for j in 0..a.nrows() {
        a[(j, j)] += 1e-9 * dmax;
    }
    a.cholesky().map_or(f64::INFINITY, |c| g.dot(&c.solve(g)))
}

/// The damped step `a d = -g`, inside the bounds (a box QP when the plain step leaves
/// them).
fn solve_step(
    a: &DMatrix<f64>,
    g: &DVector<f64>,
    x: &[f64],
    bounds: &[(f64, f64)],
) -> Option<Vec<f64>> {
    let d = a.clone().cholesky()?.solve(&(-g));
    let inside = d
        .iter()
        .zip(x)
        .zip(bounds)
        .all(|((d, x), (lo, hi))| x + d >= *lo && x + d <= *hi);
    if inside {
        return Some(d.iter().copied().collect());
    }
    box_qp(a, g, x, bounds)
}

/// `min 1/2 d^T a d + g^T d` subject to `lo - x <= d <= hi - x`, by clarabel.
fn box_qp(
    a: &DMatrix<f64>,
    g: &DVector<f64>,
    x: &[f64],
    bounds: &[(f64, f64)],
) -> Option<Vec<f64>> {
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{
        DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
    };
    let n = x.len();
    // upper triangle of a, column by column
    let mut colptr = vec![0usize];
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for c in 0..n {
        for r in 0..=c {
            rowval.push(r);
            nzval.push(a[(r, c)]);
        }
        colptr.push(rowval.len());
    }
    let p = CscMatrix::new(n, n, colptr, rowval, nzval);
    // finite bounds as rows: d_j <= hi - x_j and -d_j <= x_j - lo
    let mut rows: Vec<(usize, f64, f64)> = Vec::new();
    for (j, (lo, hi)) in bounds.iter().enumerate() {
        if hi.is_finite() {
            rows.push((j, 1.0, hi - x[j]));
        }
        if lo.is_finite() {
            rows.push((j, -1.0, x[j] - lo));
        }
    }
    let m = rows.len();
    let mut colptr = vec![0usize; n + 1];
    let mut entries: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    for (r, (j, s, _)) in rows.iter().enumerate() {
        entries[*j].push((r, *s));
    }
    let mut rowval = Vec::new();
    let mut nzval = Vec::new();
    for (j, col) in entries.iter().enumerate() {
        for (r, v) in col {
            rowval.push(*r);
            nzval.push(*v);
        }
        colptr[j + 1] = rowval.len();
    }
    let amat = CscMatrix::new(m, n, colptr, rowval, nzval);
    let b: Vec<f64> = rows.iter().map(|r| r.2.max(0.0)).collect();
    let q: Vec<f64> = g.iter().copied().collect();
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .build()
        .ok()?;
    let cones = [SupportedConeT::NonnegativeConeT(m)];
    let mut solver = DefaultSolver::new(&p, &q, &amat, &b, &cones, settings).ok()?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {
            // clip the interior-point solution onto the box exactly
            Some(
                solver
                    .solution
                    .x
                    .iter()
                    .zip(x)
                    .zip(bounds)
                    .map(|((d, x), (lo, hi))| (x + d).clamp(*lo, *hi) - x)
                    .collect(),
            )
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// For predictions linear in the parameters, `2 H` and `2 g` are the Huber cost's
    /// Hessian and gradient (central differences), with rows on both sides of the
    /// threshold: reweighting alone (`w_i J_i^T J_i`) misses the Hessian by the
    /// outliers' curvature along their errors.
    #[test]
    fn normal_equations_are_the_robust_costs_derivatives() {
        let (rows, np) = (7, 3);
        // a deterministic, well-spread Jacobian and measurement
        let jac = DMatrix::from_fn(3 * rows, np, |i, j| {
            ((i * 7 + j * 13) % 11) as f64 / 5.0 - 1.0
        });
        let meas: Vec<f64> = (0..3 * rows)
            .map(|i| ((i * 5) % 9) as f64 / 3.0 - 1.3)
            .collect();
        let x0 = [0.2, -0.1, 0.3];
        let errors = |x: &[f64]| -> Vec<f64> {
            (0..3 * rows)
                .map(|i| (0..np).map(|j| jac[(i, j)] * x[j]).sum::<f64>() - meas[i])
                .collect()
        };
        let e = errors(&x0);
        // the threshold halfway between the 3rd and 4th smallest row errors
        let mut norms: Vec<f64> = e
            .chunks(3)
            .map(|v| v.iter().map(|a| a * a).sum::<f64>().sqrt())
            .collect();
        norms.sort_by(f64::total_cmp);
        let c = 0.5 * (norms[2] + norms[3]);
        let (_, w) = huber(&e, c);
        assert!(w.iter().any(|&v| v < 1.0) && w.contains(&1.0));
        let (h, g) = normal_equations(&jac, &w, &e, np);
        let step = 1e-4;
        let cost = |x: &[f64]| huber(&errors(x), c).0;
        let moved = |j: usize, d: f64| {
            let mut x = x0;
            x[j] += d;
            x
        };
        for j in 0..np {
            let grad = (cost(&moved(j, step)) - cost(&moved(j, -step))) / (2.0 * step);
            assert!(
                (grad - 2.0 * g[j]).abs() < 1e-6,
                "gradient {j}: {grad} vs {}",
                2.0 * g[j]
            );
            for k in 0..np {
                let at = |dj: f64, dk: f64| {
                    let mut x = moved(j, dj);
                    x[k] += dk;
                    cost(&x)
                };
                let hess = (at(step, step) - at(step, -step) - at(-step, step) + at(-step, -step))
                    / (4.0 * step * step);
                assert!(
                    (hess - 2.0 * h[(j, k)]).abs() < 1e-5 * (1.0 + hess.abs()),
                    "Hessian ({j}, {k}): {hess} vs {}",
                    2.0 * h[(j, k)]
                );
            }
        }
    }

    /// A fit that stops on [`CRITERION_RESOLUTION`] leaves less than that much to gain:
    /// refitted from where it ended, the information criterion moves by less, and the
    /// parameters recovered are the world's. Generated two-tube recording with
    /// precurvature factors off by 6 % and 3 %, a 0.05 s latency, 0.2 mm noise and 30 %
    /// outliers far beyond the Huber threshold (a slow fit the rule ends: with a
    /// threshold 1000 times larger, refitting gains 0.58).
    #[test]
    fn a_fit_stops_where_little_is_left() {
        use crate::synth::{generate, Ranges, SynthSpec};
        let text = include_str!("../../../data/robots/liu2023.toml");
        let spec = ctr_formats::RobotSpec::from_toml_str(text, "liu2023.toml").unwrap();
        let user = ModelSpec::from_spec(&spec);
        let blocks = vec![EffectId::Precurvature, EffectId::Latency];
        let truth = [1.06, 0.97, 0.05];
        let mut world = user.clone();
        EffectId::Precurvature.write(&mut world, &truth[..2]);
        EffectId::Latency.write(&mut world, &truth[2..]);
        let ranges = Ranges {
            increments_mm: vec![[20.0, 70.0], [25.0, 95.0]],
            theta_deg: [-180.0, 180.0],
        };
        let synth = SynthSpec {
            seed: 11,
            outlier_fraction: 0.3,
            ..SynthSpec::default()
        };
        let rec = generate(&world, &ranges, &synth).unwrap().recording;
        let problem = Problem {
            base: user,
            blocks,
            rec: &rec,
            rows: (0..rec.rows.len()).collect(),
            huber_mm: 0.3,
            threads: 2,
            clearance_table: None,
        };
        let first = problem.fit(&[1.0, 1.0, 0.0], MAX_FIT_ITERATIONS).unwrap();
        let again = problem.fit(&first.x, MAX_FIT_ITERATIONS).unwrap();
        let n = (3 * rec.rows.len()) as f64;
        let left = n * (first.cost / again.cost).ln();
        assert!(
            (0.0..CRITERION_RESOLUTION).contains(&left),
            "refitting gained {left} on the criterion"
        );
        for (j, (fit, want)) in first.x.iter().zip(truth).enumerate() {
            assert!((fit - want).abs() < 0.01, "parameter {j}: {fit} vs {want}");
        }
    }
}

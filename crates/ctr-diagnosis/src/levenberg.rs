//! Levenberg-Marquardt on Huber's cost of any [`Residuals`]: the fit's
//! [`Problem`](crate::fit::Problem) (its physics and equations in [`crate::fit`]), or a
//! test's function.
//!
//! Each step solves `(H + lambda D) d = -J^T W e` with `H` the robust cost's Gauss-Newton
//! curvature ([`robust_information`]), `D` its diagonal, inside the parameters' bounds (a
//! box QP with clarabel where the plain step leaves them); `lambda` grows tenfold until a
//! step lowers the cost and eases threefold after. A fit ends on a negligible step
//! ([`CRITERION_RESOLUTION`]), on a target it cannot reach ([`PROJECTED_GAIN_MARGIN`]),
//! or where no step lowers the cost: walled in at its start ([`STUCK_GAIN`]), it descends
//! once more from where its least damped step led.

use nalgebra::{DMatrix, DVector};

/// What Levenberg-Marquardt asks of a problem: predictions of the parameters, their
/// errors and robust cost, the Jacobian, and each parameter's scale and bounds.
pub(crate) trait Residuals {
    /// The predictions at `x` (`None` where they cannot be simulated).
    fn predictions(&self, x: &[f64]) -> Option<Vec<f64>>;
    /// `x` with its inner parameters (see [`inner`](Self::inner)) solved for the
    /// others, and the predictions there; `x` and its predictions where it has none
    /// (`None` where they cannot be simulated).
    fn profiled(&self, x: Vec<f64>) -> Option<(Vec<f64>, Vec<f64>)> {
        let p = self.predictions(&x)?;
        Some((x, p))
    }
    /// Whether parameter `j` is inner: solved by [`profiled`](Self::profiled) at every
    /// point tried, so that a step moves only the others (variable projection); its
    /// part of a step is not damped, and it does not decide when a fit ends.
    fn inner(&self, _j: usize) -> bool {
        false
    }
    /// The errors of predictions `p` (3 per row).
    fn errors(&self, p: &[f64]) -> Vec<f64>;
    /// The robust cost of errors `e` and each row's IRLS weight ([`huber`]).
    fn cost(&self, e: &[f64]) -> (f64, Vec<f64>);
    /// The Jacobian of the predictions at `x` (predictions `p`), and for each parameter
    /// whether the problem cannot be simulated a step up / down from `x`.
    fn jacobian_and_blocked(&self, x: &[f64], p: &[f64]) -> (DMatrix<f64>, Vec<[bool; 2]>);
    /// Parameter `j`'s natural scale and bounds.
    fn scale(&self, j: usize) -> (f64, (f64, f64));
}

/// Where a fit ended.
#[derive(Clone, Debug)]
pub(crate) struct Fitted {
    pub x: Vec<f64>,
    /// Robust cost (sum over rows of rho), mm^2.
    pub cost: f64,
    /// The fit stopped because the cost could not reach its target (see
    /// [`fit_until`]): `cost` is where it stopped, not a minimum.
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
/// before [`fit_until`] gives up on a target: the model is exact for a linear
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
pub(crate) const CRITERION_RESOLUTION: f64 = 0.02;

/// Levenberg-Marquardt from `x0` (clamped to the bounds) for at most `max_iter`
/// Jacobians (`None` if the start cannot be simulated), giving up when the cost cannot come below `target`
/// (mm^2): at each Jacobian, the weighted Gauss-Newton model's decrease
/// `g^T H^-1 g` (`H` the robust curvature of [`normal_equations`], `g = J^T W e`) is what the linearised problem can
/// still gain; when the cost less [`PROJECTED_GAIN_MARGIN`] times that stays above
/// the target, going on would only confirm that it is not reached.
pub(crate) fn fit_until<R: Residuals + ?Sized>(
    r: &R,
    x0: &[f64],
    max_iter: usize,
    target: Option<f64>,
) -> Option<Fitted> {
    let np = x0.len();
    let bounds: Vec<(f64, f64)> = (0..np).map(|j| r.scale(j).1).collect();
    let x: Vec<f64> = x0
        .iter()
        .zip(&bounds)
        .map(|(v, (lo, hi))| v.clamp(*lo, *hi))
        .collect();
    let start = iterate(r, x)?;
    if (0..np).all(|j| r.inner(j)) {
        return Some(start.fitted(false));
    }
    let (mut now, gave_up) = descend(r, start, max_iter, target, &bounds);
    // Walled in at its start: every step the linearised problem asks for raised the
    // cost, as where a row a step away snaps to another branch of the mechanics (a
    // real robot's path near its stability limit). Once, from the point the
    // least damped step reached, descend again; the end counts where it is lower.
    if let Some(beyond) = now.beyond.take().and_then(|x| iterate(r, x)) {
        let (again, again_gave_up) = descend(r, beyond, max_iter, target, &bounds);
        if again.cost < now.cost {
            return Some(again.fitted(again_gave_up));
        }
    }
    Some(now.fitted(gave_up))
}

/// Levenberg-Marquardt from `now` within `bounds`, at most `max_iter` Jacobians:
/// where it ended, and whether it gave up on `target` (see [`fit_until`]).
fn descend<R: Residuals + ?Sized>(
    r: &R,
    mut now: Iterate,
    max_iter: usize,
    target: Option<f64>,
    bounds: &[(f64, f64)],
) -> (Iterate, bool) {
    let np = now.x.len();
    let mut lambda: f64 = 1e-3;
    for _ in 0..max_iter {
        let (jac, blocked) = r.jacobian_and_blocked(&now.x, &now.p);
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
        match damped_step(r, &mut now, &h, &g, dmax, &step_bounds, &mut lambda) {
            Ok(true) => continue,
            Ok(false) => break,
            Err(tried) => {
                now.stuck = now.steps == 0 && projected_gain(&h, &g, dmax) > STUCK_GAIN * now.cost;
                if now.stuck {
                    now.beyond = tried;
                }
                break;
            }
        }
    }
    (now, false)
}

/// The fit's state at parameters `x`, its inner parameters solved for the others (`None`
/// if they cannot be simulated).
fn iterate<R: Residuals + ?Sized>(r: &R, x: Vec<f64>) -> Option<Iterate> {
    let (x, p) = r.profiled(x)?;
    let e = r.errors(&p);
    let (cost, w) = r.cost(&e);
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
fn damped_step<R: Residuals + ?Sized>(
    r: &R,
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
            // an inner parameter is solved again at the point the step leads to: its
            // part of the step is the Schur complement's, undamped
            a[(j, j)] += if r.inner(j) {
                1e-9 * dmax
            } else {
                *lambda * h[(j, j)].max(1e-9 * dmax)
            };
        }
        let Some(step) = solve_step(&a, g, &now.x, bounds) else {
            *lambda *= 10.0;
            continue;
        };
        let xn: Vec<f64> = now.x.iter().zip(&step).map(|(a, b)| a + b).collect();
        if let Some(next) = iterate(r, xn) {
            if next.cost < now.cost {
                let rel = (now.cost - next.cost) / now.cost.max(f64::MIN_POSITIVE);
                let small = step
                    .iter()
                    .enumerate()
                    .all(|(j, d)| r.inner(j) || d.abs() < 1e-3 * r.scale(j).0);
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
    /// point [`fit_until`] descends from once more.
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
/// weight `min(1, c / |e_i|)` ([`huber_weight`]).
pub(crate) fn huber(e: &[f64], c: f64) -> (f64, Vec<f64>) {
    let mut cost = 0.0;
    let w = e
        .chunks(3)
        .map(|v| {
            let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            cost += if d <= c { d * d } else { 2.0 * c * d - c * c };
            huber_weight(v, c)
        })
        .collect();
    (cost, w)
}

/// The IRLS weight `min(1, c / |v|)` of a 3-vector error `v` at Huber threshold `c`.
pub(crate) fn huber_weight(v: &[f64], c: f64) -> f64 {
    let d = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if d <= c {
        1.0
    } else {
        c / d
    }
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
pub(crate) fn normal_equations(
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
/// the row's error direction (the cost grows only linearly along it; see
/// [`crate::fit`]'s module doc). The fit's steps and the intervals' information ([`crate::uncertainty`]) both
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

    /// A one-parameter problem walled in at its start: one row's error saturates
    /// (`h(x) = 1.5 tanh(8 x / 3)` against a target of 8, steep at 0, flat beyond) and
    /// another row snaps by 5 while `0 < x < 5`, as a tracked row that a small offset
    /// puts on another branch of the mechanics. From `x = 0` (cost 64) the Gauss-Newton
    /// step reaches 2 and every damped step lands inside the window, where the cost is
    /// at least 67.25; past it (`x >= 5`) it is 42.25.
    struct Walled;

    impl Walled {
        const TARGET: f64 = 8.0;
        const SNAP: f64 = 5.0;
        fn h(x: f64) -> f64 {
            1.5 * (8.0 * x / 3.0).tanh()
        }
        fn slope(x: f64) -> f64 {
            4.0 / (8.0 * x / 3.0).cosh().powi(2)
        }
    }

    impl Residuals for Walled {
        fn predictions(&self, x: &[f64]) -> Option<Vec<f64>> {
            let snapped = if x[0] > 0.0 && x[0] < Self::SNAP {
                Self::SNAP
            } else {
                0.0
            };
            Some(vec![Self::h(x[0]), 0.0, 0.0, snapped, 0.0, 0.0])
        }
        fn errors(&self, p: &[f64]) -> Vec<f64> {
            let mut e = p.to_vec();
            e[0] -= Self::TARGET;
            e
        }
        fn cost(&self, e: &[f64]) -> (f64, Vec<f64>) {
            huber(e, 100.0)
        }
        fn jacobian_and_blocked(&self, x: &[f64], _p: &[f64]) -> (DMatrix<f64>, Vec<[bool; 2]>) {
            let mut jac = DMatrix::zeros(6, 1);
            jac[(0, 0)] = Self::slope(x[0]);
            (jac, vec![[false; 2]])
        }
        fn scale(&self, _j: usize) -> (f64, (f64, f64)) {
            (1.0, (-10.0, 10.0))
        }
    }

    /// Walled in at its start, the fit descends once more from where its least damped
    /// step led and ends past the window, lower than where it began (without the second
    /// descent it stays at its start: the real recording's joint-offset fit, commit
    /// a6ffadd).
    #[test]
    fn a_fit_walled_in_at_its_start_goes_on_from_its_first_step() {
        let start_cost = Walled::TARGET.powi(2);
        let fitted = fit_until(&Walled, &[0.0], 25, None).unwrap();
        assert!(fitted.x[0] >= Walled::SNAP, "ended at {}", fitted.x[0]);
        let past = (Walled::h(fitted.x[0]) - Walled::TARGET).powi(2);
        assert!((fitted.cost - past).abs() < 1e-9 && fitted.cost < start_cost);
        assert!(!fitted.stuck);
        // every step from the start lands in the window and costs more
        let first = iterate(&Walled, vec![0.0]).unwrap();
        assert_eq!(first.cost, start_cost);
        for x in [0.01, 0.5, 1.0, 2.0, 4.99] {
            assert!(iterate(&Walled, vec![x]).unwrap().cost > start_cost, "{x}");
        }
    }
}

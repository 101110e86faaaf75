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
//! leave the mechanics alone). The steps, the damping and when a fit ends are
//! [`crate::levenberg`]'s, which this module's [`Problem`] feeds.

use crate::candidates::EffectId;
use crate::levenberg::{self, huber, Fitted, Residuals};
use crate::measurement::{self, Free, Tips, MEASUREMENT};
use crate::residual::angular_errors;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::{predict_rows_on, Prediction};
use ctr_formats::Recording;
use nalgebra::DMatrix;

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

    /// Whether the feed offsets at `x` keep the commanded feeds of every row in the
    /// robot's ranges where they were (in their order, within the tubes' lengths). A
    /// fit treats leaving them as a side that cannot be simulated: without friction
    /// the solve refuses such rows, but friction's plays hold the actual feeds in
    /// their order (a tube cannot pass the next), so an offset past that edge would
    /// be simulated with every row bent at it, and a fit parked on the bend (one-sided
    /// derivatives that disagree) stops where its steps promise much and gain nothing.
    pub(crate) fn feeds_in_range(&self, x: &[f64]) -> bool {
        let Some(at) = self.block_start(EffectId::JointOffset) else {
            return true;
        };
        let n = self.n_tubes();
        let robot = &self.base.robot;
        let mut moved = vec![0.0; 2 * n];
        self.rec.rows.iter().all(|row| {
            moved.copy_from_slice(&row.q);
            for i in 0..n {
                moved[2 * i] += x[at + i];
            }
            robot.validate_joints(&moved).is_ok() || robot.validate_joints(&row.q).is_err()
        })
    }

    /// Index of the first parameter of block `b`, if it is fitted.
    pub(crate) fn block_start(&self, b: EffectId) -> Option<usize> {
        let mut at = 0;
        for &c in &self.blocks {
            if c == b {
                return Some(at);
            }
            at += self.block_len(c);
        }
        None
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
        if !self.feeds_in_range(x) {
            return None;
        }
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

    /// The measurement's blocks this fit profiles ([`crate::measurement`]).
    pub(crate) fn profiled_blocks(&self) -> Free {
        Free {
            registration: self.block_start(EffectId::Registration),
            offset: self.block_start(EffectId::SensorOffset),
            rotation: self.block_start(EffectId::SensorRotation),
        }
    }

    /// `x` with the measurement's parameters it fits solved for the others'
    /// ([`crate::measurement`]), and the predictions there (as
    /// [`predictions`](Self::predictions) lays them out); `x` and its predictions as
    /// they are where the fit has none of them. `None` where the model cannot be
    /// simulated.
    pub(crate) fn profiled(&self, x: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
        let free = self.profiled_blocks();
        if free.none() {
            return Some((x.to_vec(), self.predictions(x)?));
        }
        if !self.feeds_in_range(x) {
            return None;
        }
        let model = self.model(x);
        let bare = predict_rows_on(
            &measurement::without(&model),
            self.rec,
            &self.rows,
            self.threads,
        )
        .ok()?;
        let tips = Tips::new(self.rec, &self.rows, &bare, self.huber_mm)?;
        let mut x = x.to_vec();
        let pred = measurement::profiled(&tips, &model, &bare, &free, &mut x, |j| self.scale(j).1);
        let out = self.assembled(&pred, &x)?;
        Some((x, out))
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
    /// (mm^2) ([`levenberg::fit_until`]).
    pub fn fit_until(&self, x0: &[f64], max_iter: usize, target: Option<f64>) -> Option<Fitted> {
        levenberg::fit_until(self, x0, max_iter, target)
    }
}

#[cfg(test)]
impl<'a> Problem<'a> {
    /// A test's problem: `blocks` over `base` against every `every`-th row of `rec`,
    /// the Huber threshold at 0.3 mm, two threads.
    pub(crate) fn for_test(
        base: ModelSpec,
        blocks: Vec<EffectId>,
        rec: &'a Recording,
        every: usize,
    ) -> Self {
        Problem {
            base,
            blocks,
            rec,
            rows: (0..rec.rows.len()).step_by(every).collect(),
            huber_mm: 0.3,
            threads: 2,
            clearance_table: None,
        }
    }
}

impl Residuals for Problem<'_> {
    fn predictions(&self, x: &[f64]) -> Option<Vec<f64>> {
        Problem::predictions(self, x)
    }

    fn profiled(&self, x: Vec<f64>) -> Option<(Vec<f64>, Vec<f64>)> {
        Problem::profiled(self, &x)
    }

    fn inner(&self, j: usize) -> bool {
        let b = self.effect_of(j);
        MEASUREMENT.contains(&b) && self.table(b).is_none()
    }

    fn errors(&self, p: &[f64]) -> Vec<f64> {
        Problem::errors(self, p)
    }

    fn cost(&self, e: &[f64]) -> (f64, Vec<f64>) {
        Problem::cost(self, e)
    }

    fn jacobian_and_blocked(&self, x: &[f64], p: &[f64]) -> (DMatrix<f64>, Vec<[bool; 2]>) {
        Problem::jacobian_and_blocked(self, x, p)
    }

    fn scale(&self, j: usize) -> (f64, (f64, f64)) {
        Problem::scale(self, j)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::levenberg::CRITERION_RESOLUTION;

    /// Friction's plays hold the actual feeds in their order, so a feed offset that
    /// pulls tube 2 behind tube 1 can be simulated (every such row bent at the edge);
    /// a fit's predictions treat it as the solve does without friction: not simulated
    /// (a side held), while an offset within the ranges is predicted as before.
    #[test]
    fn feed_offsets_past_the_feed_order_are_not_simulated_even_with_friction() {
        use crate::synth::{generate, Ranges, SynthSpec};
        use ctr_analysis::simulate::predict_rows;
        let text = include_str!("../../../data/robots/liu2023.toml");
        let spec = ctr_formats::RobotSpec::from_toml_str(text, "liu2023.toml").unwrap();
        let mut user = ModelSpec::from_spec(&spec);
        user.effects.friction = Some(ctr_formats::Friction {
            rotation_play_deg: vec![1.0],
            feed_play_mm: vec![0.2, 0.2],
            rotation_friction_coefficient: vec![],
        });
        let ranges = Ranges {
            increments_mm: vec![[20.0, 70.0], [25.0, 95.0]],
            theta_deg: [-180.0, 180.0],
        };
        let rec = generate(&user, &ranges, &SynthSpec::default())
            .unwrap()
            .recording;
        let problem = Problem::for_test(user, vec![EffectId::JointOffset], &rec, 5);
        // tube 2 pulled back 30 mm: behind tube 1 wherever its increment is below 30
        let behind = [0.0, -30.0, 0.0, 0.0];
        let clamped = predict_rows(&problem.model(&behind), &rec, &problem.rows);
        assert!(clamped.is_ok(), "the plays hold the feeds in order");
        assert!(problem.predictions(&behind).is_none());
        assert!(problem.predictions(&[0.0, -10.0, 0.0, 0.0]).is_some());
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
        let problem = Problem::for_test(user, blocks, &rec, 1);
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

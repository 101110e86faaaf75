//! One Levenberg-Marquardt run from one start (the method is in the [module
//! doc](super)): the weighted error, the damped step as a QP within the limits, the
//! gain-ratio rule for `lambda`, and when a start ends.

use super::margin::Guard;
use super::{Ik, IkTarget};
use crate::model::{log_so3, tip_jacobian, Jacobian, Solved, MAX_JOINTS};
use ctr_core::Frame;
use nalgebra::{SMatrix, SVector, Vector3, Vector6};

type Square = SMatrix<f64, MAX_JOINTS, MAX_JOINTS>;
type Joint = SVector<f64, MAX_JOINTS>;

/// Relative decrease of `E` below which an accepted step counts as no progress.
const STALL_DECREASE: f64 = 1e-4;
/// Accepted steps without progress in a row that end a start.
const STALL_STEPS: u32 = 3;
/// A step shorter than this (mm or rad, largest component) ends a start.
const MIN_STEP: f64 = 1e-11;
/// `lambda` beyond which no step can lower `E`: the start ends.
const MAX_LAMBDA: f64 = 1e12;
/// Smallest `lambda` (the constant damping stays underneath).
const MIN_LAMBDA: f64 = 1e-12;
/// Smallest `lambda` after a refused step: damping that starts from zero must grow.
const REFUSED_MIN_LAMBDA: f64 = 1e-6;

/// Nielsen's rule for a refused step: `lambda` grows by `nu`, which doubles. `false`
/// when the start must end (without adaptive damping, or beyond [`MAX_LAMBDA`]).
fn damp_harder(adaptive: bool, lambda: &mut f64, nu: &mut f64) -> bool {
    if !adaptive {
        return false;
    }
    *lambda = (*lambda * *nu).max(REFUSED_MIN_LAMBDA);
    *nu *= 2.0;
    *lambda <= MAX_LAMBDA
}

/// How one start ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum End {
    Reached,
    Stalled,
    IterationLimit,
    FkFailed,
}

/// One start's outcome: where it ended and how.
pub(super) struct Attempt {
    pub q: Vec<f64>,
    pub tip: Frame<f64>,
    pub cost: f64,
    pub iterations: u32,
    pub end: End,
    /// the margin at `q` on the branch the steps followed
    pub margin: f64,
    /// without a margin floor always; with one, whether `q` keeps it
    pub feasible: bool,
    /// the margin shaped the last steps
    pub held: bool,
}

impl Ik {
    /// The diagonal of `W_E` (orientation weights 0 for a position-only target).
    pub(super) fn weights(&self, target: &IkTarget) -> Vector6<f64> {
        let o = &self.options;
        let ow = if target.orientation.is_some() {
            o.orientation_weight
        } else {
            0.0
        };
        Vector6::new(
            o.position_weight,
            o.position_weight,
            o.position_weight,
            ow,
            ow,
            ow,
        )
    }

    /// The error `target - tip` (position, then orientation or zeros) and
    /// `E = 1/2 e^T W_E e`.
    pub(super) fn error(&self, target: &IkTarget, tip: &Frame<f64>) -> (Vector6<f64>, f64) {
        let w = self.weights(target);
        let mut e = Vector6::zeros();
        e.fixed_rows_mut::<3>(0)
            .copy_from(&(target.position - tip.position));
        if let Some(o) = &target.orientation {
            let r = o.to_rotation_matrix().into_inner() * tip.rotation.transpose();
            e.fixed_rows_mut::<3>(3).copy_from(&log_so3(&r));
        }
        let cost = 0.5 * e.component_mul(&e).dot(&w);
        (e, cost)
    }

    /// Position distance (mm) and orientation angle (rad) from the target.
    pub(super) fn residuals(&self, target: &IkTarget, tip: &Frame<f64>) -> (f64, Option<f64>) {
        let pos = (target.position - tip.position).norm();
        let ori = target.orientation.map(|o| {
            let r = o.to_rotation_matrix().into_inner() * tip.rotation.transpose();
            log_so3(&r).norm()
        });
        (pos, ori)
    }

    pub(super) fn reached(&self, target: &IkTarget, tip: &Frame<f64>) -> bool {
        let (pos, ori) = self.residuals(target, tip);
        pos <= self.options.tolerance_mm
            && ori.is_none_or(|a| a <= self.options.orientation_tolerance_rad)
    }

    /// One Levenberg-Marquardt run from `q` (inside the limits); with a margin floor,
    /// every iterate taken keeps it (restoring it first if the start is below).
    pub(super) fn run(
        &mut self,
        target: &IkTarget,
        q: Vec<f64>,
        observer: &mut dyn FnMut(&[f64]),
    ) -> Attempt {
        let w = self.weights(target);
        self.fk.reset();
        observer(&q);
        let Some(first) = self.fk.trial(&q) else {
            return self.fk_failed(q);
        };
        self.fk.accept();
        let mut lm = self.start(target, q, &first);
        let end = loop {
            if let Some(end) = self.iterate(target, &w, &mut lm, observer) {
                break end;
            }
        };
        self.finish(target, lm, end)
    }

    /// The attempt of a start whose first FK failed.
    fn fk_failed(&self, q: Vec<f64>) -> Attempt {
        Attempt {
            q,
            tip: nan_frame(),
            cost: f64::INFINITY,
            iterations: 0,
            end: End::FkFailed,
            margin: f64::NAN,
            // without a margin floor every point is within it
            feasible: self.options.min_margin.is_none(),
            held: false,
        }
    }

    /// The state at the start `q`, solved to `first`.
    fn start(&self, target: &IkTarget, q: Vec<f64>, first: &Solved) -> Lm {
        let o = &self.options;
        let guard = o.min_margin.map(|x| Guard::new(x, first));
        let (e, cost) = self.error(target, &first.tip);
        // the iterates within the margin, for the check of the result (`settle`)
        let mut kept: Vec<Kept> = Vec::new();
        if guard.is_some_and(|g| g.allows(first.margin)) {
            kept.push(Kept::new(&q, first.tip, cost, first.margin));
        }
        Lm {
            q,
            tip: first.tip,
            margin: first.margin,
            e,
            cost,
            guard,
            kept,
            lambda: o.initial_lambda,
            nu: 2.0,
            jac: Jacobian::zeros(),
            a: Square::zeros(),
            g: Joint::zeros(),
            fresh: false,
            stalls: 0,
            iterations: 0,
        }
    }

    /// One iteration: the checks that end the start, the step, its trial; `None` to go
    /// on.
    fn iterate(
        &mut self,
        target: &IkTarget,
        w: &Vector6<f64>,
        lm: &mut Lm,
        observer: &mut dyn FnMut(&[f64]),
    ) -> Option<End> {
        let restoring = lm.guard.is_some_and(|g| g.restoring());
        if !restoring && self.reached(target, &lm.tip) {
            return Some(End::Reached);
        }
        if lm.iterations >= self.options.max_iterations {
            return Some(End::IterationLimit);
        }
        lm.iterations += 1;
        if !lm.fresh && !self.normal_equations(w, lm) {
            return Some(End::Stalled);
        }
        let h = self.damped(lm);
        let (dq, cut) = match self.step(lm, &h, restoring) {
            Ok(step) => step,
            Err(next) => return next,
        };
        if let Some(gd) = &mut lm.guard {
            gd.held = cut;
        }
        let mut q_new: Vec<f64> = lm.q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
        self.limits.project(&mut q_new);
        if moved(&lm.q, &q_new) < MIN_STEP {
            return Some(End::Stalled);
        }
        observer(&q_new);
        self.judge(target, lm, q_new, &dq, restoring)
    }

    /// `J^T W_E J` and `g = J^T W_E e` at the current iterate; `false` when they are not
    /// finite.
    fn normal_equations(&self, w: &Vector6<f64>, lm: &mut Lm) -> bool {
        tip_jacobian(&*self.fk, &self.limits, &lm.q, &lm.tip, &mut lm.jac);
        let mut jw = lm.jac.transpose();
        for (c, wc) in w.iter().enumerate() {
            jw.column_mut(c).scale_mut(*wc);
        }
        lm.a = jw * lm.jac;
        lm.g = jw * lm.e;
        lm.fresh = true;
        lm.a.iter().all(|v| v.is_finite()) && lm.g.iter().all(|v| v.is_finite())
    }

    /// `H = J^T W_E J + W_N`: the constant damping plus, adaptive, `lambda M`. A
    /// rotation's constant damping scales with its lever arm ([`lever_fraction`]).
    fn damped(&self, lm: &Lm) -> Square {
        let o = &self.options;
        let n = lm.q.len();
        let mut h = lm.a;
        for k in n..MAX_JOINTS {
            // padding: an identity block gives a zero step there
            h[(k, k)] = 1.0;
        }
        for k in 0..n {
            let (base, metric) = if k % 2 == 0 {
                (o.damping_feed, 1.0)
            } else {
                let scale_sq = o.rotation_scale_mm * o.rotation_scale_mm;
                // the paper's plain step (no adaptive damping) keeps its constant W_N
                let fraction = if o.adaptive_damping {
                    lever_fraction(lm.a[(k, k)], scale_sq)
                } else {
                    1.0
                };
                (o.damping_rotation * fraction, scale_sq)
            };
            let adapt = if o.adaptive_damping {
                lm.lambda * metric
            } else {
                0.0
            };
            h[(k, k)] += base + adapt;
        }
        h
    }

    /// The damped step within the limits (and the margin's row) and whether the
    /// margin's row cut the free step; `Err` with what the iteration does instead when
    /// there is none (`None`: go on, damped harder or aiming lower).
    fn step(
        &mut self,
        lm: &mut Lm,
        h: &Square,
        restoring: bool,
    ) -> Result<(Joint, bool), Option<End>> {
        let n = lm.q.len();
        // the unconstrained minimizer is the QP's solution when it stays inside
        let free = h.cholesky().map(|c| c.solve(&lm.g));
        let cut = match (&free, &lm.guard) {
            (Some(dq), Some(gd)) => !gd.admits(dq),
            _ => false,
        };
        let inside = !cut
            && free.as_ref().is_some_and(|dq| {
                let trial: Vec<f64> = lm.q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
                self.limits.admits(&trial)
            });
        if let (Some(dq), true) = (free, inside) {
            return Ok((dq, cut));
        }
        let row = lm.guard.as_ref().map(Guard::row);
        let g = &lm.g;
        match self
            .qp
            .step(h, g, &lm.q, row.as_ref().map(|(a, b)| (a, *b)))
            .map(|dq| Joint::from_fn(|k, _| if k < n { dq[k] } else { 0.0 }))
        {
            // dq = 0 is feasible with model value 0: a solution must not be worse
            // (while restoring it is not feasible)
            Some(dq)
                if restoring
                    || 0.5 * dq.dot(&(h * dq)) - g.dot(&dq) <= 1e-12 * g.norm() * dq.norm() =>
            {
                Ok((dq, cut))
            }
            _ => Err(self.no_step(lm, restoring)),
        }
    }

    /// No step within the limits: while restoring aim lower, else (clarabel failed)
    /// damp harder, as for a refused step; `Some` when the start ends.
    fn no_step(&self, lm: &mut Lm, restoring: bool) -> Option<End> {
        if restoring {
            // no step raises the margin that far: aim lower
            if lm.guard.as_mut().is_some_and(Guard::no_step) {
                return None;
            }
            return Some(End::Stalled);
        }
        if !damp_harder(self.options.adaptive_damping, &mut lm.lambda, &mut lm.nu) {
            return Some(End::Stalled);
        }
        None
    }

    /// Solves the trial `q_new` (the step `dq`) and takes it or refuses it; `Some` when
    /// the start ends.
    fn judge(
        &mut self,
        target: &IkTarget,
        lm: &mut Lm,
        q_new: Vec<f64>,
        dq: &Joint,
        restoring: bool,
    ) -> Option<End> {
        let adaptive = self.options.adaptive_damping;
        let trial = self.fk.trial(&q_new);
        // the margin of a trial refused for it
        let mut low = None;
        let accepted = match trial {
            None => None,
            Some(t) => {
                let (e_new, cost_new) = self.error(target, &t.tip);
                match &lm.guard {
                    Some(gd) if !gd.accepts(t.margin) => {
                        low = Some(t.margin);
                        None
                    }
                    _ => (restoring || cost_new < lm.cost || !adaptive)
                        .then_some((t, e_new, cost_new)),
                }
            }
        };
        match accepted {
            Some((t, e_new, cost_new)) => self.take(lm, q_new, &t, e_new, cost_new, dq, restoring),
            None => {
                if let (Some(m), Some(gd)) = (low, &mut lm.guard) {
                    if !gd.refused(dq, m) {
                        return Some(End::Stalled);
                    }
                }
                if !damp_harder(adaptive, &mut lm.lambda, &mut lm.nu) {
                    return Some(End::Stalled);
                }
                None
            }
        }
    }

    /// Takes the step `dq` to `q_new`, solved to `t`: the gain-ratio rule for `lambda`
    /// and the progress rule; `Some` when the start ends.
    fn take(
        &mut self,
        lm: &mut Lm,
        q_new: Vec<f64>,
        t: &Solved,
        e_new: Vector6<f64>,
        cost_new: f64,
        dq: &Joint,
        restoring: bool,
    ) -> Option<End> {
        // predicted decrease of the Gauss-Newton model for this step
        let pred = lm.g.dot(dq) - 0.5 * dq.dot(&(lm.a * dq));
        let rho = if pred > 0.0 {
            (lm.cost - cost_new) / pred
        } else {
            1.0
        };
        let progress = (lm.cost - cost_new) / lm.cost;
        lm.q = q_new;
        lm.tip = t.tip;
        lm.margin = t.margin;
        lm.e = e_new;
        lm.cost = cost_new;
        self.fk.accept();
        lm.fresh = false;
        if let Some(gd) = &mut lm.guard {
            gd.took(t);
            if gd.allows(lm.margin) {
                lm.kept.push(Kept::new(&lm.q, lm.tip, lm.cost, lm.margin));
            }
        }
        if restoring {
            // steps up to the margin: no progress rule, lambda as it was
            return None;
        }
        if self.options.adaptive_damping {
            lm.lambda = (lm.lambda * (1.0_f64 / 3.0).max(1.0 - (2.0 * rho - 1.0_f64).powi(3)))
                .max(MIN_LAMBDA);
            lm.nu = 2.0;
        }
        if progress < STALL_DECREASE {
            lm.stalls += 1;
            if lm.stalls >= STALL_STEPS {
                return Some(End::Stalled);
            }
        } else {
            lm.stalls = 0;
        }
        None
    }

    /// The attempt where the start ended: with a margin floor its last iterate that
    /// clears it cold ([`Ik::settle`]), without one the margin of where it ended.
    fn finish(&mut self, target: &IkTarget, lm: Lm, end: End) -> Attempt {
        let mut attempt = Attempt {
            q: lm.q,
            tip: lm.tip,
            cost: lm.cost,
            iterations: lm.iterations,
            end,
            margin: lm.margin,
            feasible: true,
            held: false,
        };
        match lm.guard {
            Some(gd) => {
                attempt.held = gd.held;
                self.settle(&mut attempt, &lm.kept, gd.floor);
            }
            // without a floor the iterates have no margin: the result's, on its branch
            None => attempt.margin = self.fk.margin(&attempt.q),
        }
        if attempt.end != End::Reached && attempt.feasible && self.reached(target, &attempt.tip) {
            attempt.end = End::Reached;
        }
        attempt
    }

    /// With a margin floor: the attempt ends at its last iterate whose margin, solved
    /// cold as well (as a row of `ctr-cli fk` is), clears `floor` (the cold solve can
    /// land on another branch than the one the steps followed); `feasible` false when
    /// none does.
    fn settle(&mut self, attempt: &mut Attempt, kept: &[Kept], floor: f64) {
        for k in kept.iter().rev() {
            let cold = self.fk.cold(&k.q).map_or(f64::NAN, |s| s.margin);
            if cold >= floor {
                if k.q != attempt.q {
                    attempt.q.clone_from(&k.q);
                    attempt.tip = k.tip;
                    attempt.cost = k.cost;
                    attempt.margin = k.margin;
                    attempt.held = true;
                    if attempt.end == End::Reached {
                        attempt.end = End::Stalled;
                    }
                }
                return;
            }
        }
        attempt.feasible = false;
        if attempt.end == End::Reached {
            attempt.end = End::Stalled;
        }
    }
}

/// One start's Levenberg-Marquardt state: the iterate, what its steps are built from,
/// and the counts that end it.
struct Lm {
    q: Vec<f64>,
    tip: Frame<f64>,
    /// the margin at `q` on the branch the steps followed
    margin: f64,
    /// the error `target - tip` and `E`
    e: Vector6<f64>,
    cost: f64,
    /// the margin floor's constraint, with one
    guard: Option<Guard>,
    /// the iterates within the margin, for the check of the result (`settle`)
    kept: Vec<Kept>,
    lambda: f64,
    /// Nielsen's growth factor of `lambda`
    nu: f64,
    jac: Jacobian,
    /// `J^T W_E J` and `J^T W_E e` at `q`
    a: Square,
    g: Joint,
    /// `a` and `g` are those of `q`
    fresh: bool,
    /// accepted steps without progress in a row
    stalls: u32,
    iterations: u32,
}

/// Smallest [`lever_fraction`]: keeps `H` positive definite where a rotation does not
/// move the tip at all (a straight innermost tube's own rotation, position target).
const MIN_LEVER_FRACTION: f64 = 1e-12;

/// The fraction of [`IkOptions::damping_rotation`] a rotation gets: `(l / L)^2`, at
/// most 1, where `l^2 = (J^T W_E J)_kk` is the rotation's lever arm (the weighted tip
/// motion per radian, mm) and `L = rotation_scale_mm` (its square `scale_sq`).
///
/// The constant damping (mm^2 per rad^2) is set for rotations that move the tip by
/// about `L` per radian, where it is a millionth of their own curvature `l^2`. Held
/// fixed, it swamps a rotation whose lever arm is tiny: with the tip 0.00045 mm off a
/// one-tube robot's axis (`l^2` 2e-7 mm^2) each step took 0.2 % of the turn needed,
/// and the IK stopped at `iteration_limit` 0.00049 mm from a reachable target. Scaled
/// with `l^2`, it damps every rotation alike relative to its own effect.
///
/// [`IkOptions::damping_rotation`]: super::IkOptions::damping_rotation
fn lever_fraction(lever_sq: f64, scale_sq: f64) -> f64 {
    (lever_sq / scale_sq).clamp(MIN_LEVER_FRACTION, 1.0)
}

/// The largest joint move from `q` to `q_new` (mm or rad; a wrap of a full turn is no
/// move).
fn moved(q: &[f64], q_new: &[f64]) -> f64 {
    q.iter()
        .zip(q_new)
        .enumerate()
        .map(|(k, (a, b))| {
            let d = b - a;
            if k % 2 == 1 {
                // a wrap of a full turn is no move
                let t = std::f64::consts::TAU;
                (d - t * (d / t).round()).abs()
            } else {
                d.abs()
            }
        })
        .fold(0.0, f64::max)
}

/// An iterate kept for [`Ik::settle`].
struct Kept {
    q: Vec<f64>,
    tip: Frame<f64>,
    cost: f64,
    margin: f64,
}

impl Kept {
    fn new(q: &[f64], tip: Frame<f64>, cost: f64, margin: f64) -> Self {
        Kept {
            q: q.to_vec(),
            tip,
            cost,
            margin,
        }
    }
}

/// A tip of NaNs: the tip of a start whose first FK failed.
pub(super) fn nan_frame() -> Frame<f64> {
    Frame {
        rotation: nalgebra::Matrix3::from_element(f64::NAN),
        position: Vector3::from_element(f64::NAN),
    }
}

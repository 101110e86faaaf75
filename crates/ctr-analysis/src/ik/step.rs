//! One Levenberg-Marquardt run from one start (the method is in the [module
//! doc](super)): the weighted error, the damped step as a QP within the limits, the
//! gain-ratio rule for `lambda`, and when a start ends.

use super::margin::Guard;
use super::{Ik, IkTarget};
use crate::model::{log_so3, tip_jacobian, Jacobian, MAX_JOINTS};
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
        mut q: Vec<f64>,
        observer: &mut dyn FnMut(&[f64]),
    ) -> Attempt {
        let n = q.len();
        let o = self.options;
        let w = self.weights(target);
        self.fk.reset();
        observer(&q);
        let Some(first) = self.fk.trial(&q) else {
            return Attempt {
                q,
                tip: nan_frame(),
                cost: f64::INFINITY,
                iterations: 0,
                end: End::FkFailed,
                margin: f64::NAN,
                // without a margin floor every point is within it
                feasible: o.min_margin.is_none(),
                held: false,
            };
        };
        self.fk.accept();
        let mut tip = first.tip;
        let mut margin = first.margin;
        let mut guard = o.min_margin.map(|x| Guard::new(x, &first));
        let (mut e, mut cost) = self.error(target, &tip);
        // the iterates within the margin, for the check of the result (`settle`)
        let mut kept: Vec<Kept> = Vec::new();
        if guard.is_some_and(|g| g.allows(margin)) {
            kept.push(Kept::new(&q, tip, cost, margin));
        }
        let mut lambda = o.initial_lambda;
        let mut nu = 2.0;
        let mut jac = Jacobian::zeros();
        let mut a = Square::zeros();
        let mut g = Joint::zeros();
        let mut fresh = false;
        let mut stalls = 0;
        let mut iterations = 0;
        let end = loop {
            let restoring = guard.is_some_and(|g| g.restoring());
            if !restoring && self.reached(target, &tip) {
                break End::Reached;
            }
            if iterations >= o.max_iterations {
                break End::IterationLimit;
            }
            iterations += 1;
            if !fresh {
                tip_jacobian(&*self.fk, &self.limits, &q, &tip, &mut jac);
                let mut jw = jac.transpose();
                for (c, wc) in w.iter().enumerate() {
                    jw.column_mut(c).scale_mut(*wc);
                }
                a = jw * jac;
                g = jw * e;
                fresh = true;
                if !(a.iter().all(|v| v.is_finite()) && g.iter().all(|v| v.is_finite())) {
                    break End::Stalled;
                }
            }
            let mut h = a;
            for k in n..MAX_JOINTS {
                // padding: an identity block gives a zero step there
                h[(k, k)] = 1.0;
            }
            for k in 0..n {
                let (base, metric) = if k % 2 == 0 {
                    (o.damping_feed, 1.0)
                } else {
                    (
                        o.damping_rotation,
                        o.rotation_scale_mm * o.rotation_scale_mm,
                    )
                };
                let adapt = if o.adaptive_damping {
                    lambda * metric
                } else {
                    0.0
                };
                h[(k, k)] += base + adapt;
            }
            // the unconstrained minimizer is the QP's solution when it stays inside
            let free = h.cholesky().map(|c| c.solve(&g));
            let cut = match (&free, &guard) {
                (Some(dq), Some(gd)) => !gd.admits(dq),
                _ => false,
            };
            let inside = !cut
                && free.as_ref().is_some_and(|dq| {
                    let trial: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
                    self.limits.admits(&trial)
                });
            let row = guard.as_ref().map(Guard::row);
            let dq = match (free, inside) {
                (Some(dq), true) => dq,
                _ => match self
                    .qp
                    .step(&h, &g, &q, row.as_ref().map(|(a, b)| (a, *b)))
                    .map(|dq| Joint::from_fn(|k, _| if k < n { dq[k] } else { 0.0 }))
                {
                    // dq = 0 is feasible with model value 0: a solution must not be
                    // worse (while restoring it is not feasible)
                    Some(dq)
                        if restoring
                            || 0.5 * dq.dot(&(h * dq)) - g.dot(&dq)
                                <= 1e-12 * g.norm() * dq.norm() =>
                    {
                        dq
                    }
                    _ => {
                        if restoring {
                            // no step raises the margin that far: aim lower
                            if guard.as_mut().is_some_and(Guard::no_step) {
                                continue;
                            }
                            break End::Stalled;
                        }
                        // clarabel failed: damp harder, as for a refused step
                        if !damp_harder(o.adaptive_damping, &mut lambda, &mut nu) {
                            break End::Stalled;
                        }
                        continue;
                    }
                },
            };
            if let Some(gd) = &mut guard {
                gd.held = cut;
            }
            let mut q_new: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
            self.limits.project(&mut q_new);
            let moved = q
                .iter()
                .zip(&q_new)
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
                .fold(0.0, f64::max);
            if moved < MIN_STEP {
                break End::Stalled;
            }
            observer(&q_new);
            let trial = self.fk.trial(&q_new);
            // the margin of a trial refused for it
            let mut low = None;
            let accepted = match trial {
                None => None,
                Some(t) => {
                    let (e_new, cost_new) = self.error(target, &t.tip);
                    match &guard {
                        Some(gd) if !gd.accepts(t.margin) => {
                            low = Some(t.margin);
                            None
                        }
                        _ => (restoring || cost_new < cost || !o.adaptive_damping)
                            .then_some((t, e_new, cost_new)),
                    }
                }
            };
            match accepted {
                Some((t, e_new, cost_new)) => {
                    // predicted decrease of the Gauss-Newton model for this step
                    let pred = g.dot(&dq) - 0.5 * dq.dot(&(a * dq));
                    let rho = if pred > 0.0 {
                        (cost - cost_new) / pred
                    } else {
                        1.0
                    };
                    let progress = (cost - cost_new) / cost;
                    q = q_new;
                    tip = t.tip;
                    margin = t.margin;
                    e = e_new;
                    cost = cost_new;
                    self.fk.accept();
                    fresh = false;
                    if let Some(gd) = &mut guard {
                        gd.took(&t);
                        if gd.allows(margin) {
                            kept.push(Kept::new(&q, tip, cost, margin));
                        }
                    }
                    if restoring {
                        // steps up to the margin: no progress rule, lambda as it was
                        continue;
                    }
                    if o.adaptive_damping {
                        lambda = (lambda
                            * (1.0_f64 / 3.0).max(1.0 - (2.0 * rho - 1.0_f64).powi(3)))
                        .max(MIN_LAMBDA);
                        nu = 2.0;
                    }
                    if progress < STALL_DECREASE {
                        stalls += 1;
                        if stalls >= STALL_STEPS {
                            break End::Stalled;
                        }
                    } else {
                        stalls = 0;
                    }
                }
                None => {
                    if let (Some(m), Some(gd)) = (low, &mut guard) {
                        if !gd.refused(&dq, m) {
                            break End::Stalled;
                        }
                    }
                    if !damp_harder(o.adaptive_damping, &mut lambda, &mut nu) {
                        break End::Stalled;
                    }
                }
            }
        };
        let mut attempt = Attempt {
            q,
            tip,
            cost,
            iterations,
            end,
            margin,
            feasible: true,
            held: false,
        };
        match guard {
            Some(gd) => {
                attempt.held = gd.held;
                self.settle(&mut attempt, &kept, gd.floor);
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

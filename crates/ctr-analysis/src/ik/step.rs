//! One Levenberg-Marquardt run from one start (the method is in the [module
//! doc](super)): the weighted error, the damped step as a QP within the limits, the
//! gain-ratio rule for `lambda`, and when a start ends.

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

    /// One Levenberg-Marquardt run from `q` (inside the limits).
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
        let Some(mut tip) = self.fk.trial(&q) else {
            return Attempt {
                q,
                tip: nan_frame(),
                cost: f64::INFINITY,
                iterations: 0,
                end: End::FkFailed,
            };
        };
        self.fk.accept();
        let (mut e, mut cost) = self.error(target, &tip);
        let mut lambda = o.initial_lambda;
        let mut nu = 2.0;
        let mut jac = Jacobian::zeros();
        let mut a = Square::zeros();
        let mut g = Joint::zeros();
        let mut fresh = false;
        let mut stalls = 0;
        let mut iterations = 0;
        let end = loop {
            if self.reached(target, &tip) {
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
            let inside = free.as_ref().is_some_and(|dq| {
                let trial: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
                self.limits.admits(&trial)
            });
            let dq = match (free, inside) {
                (Some(dq), true) => dq,
                _ => match self
                    .qp
                    .step(&h, &g, &q)
                    .map(|dq| Joint::from_fn(|k, _| if k < n { dq[k] } else { 0.0 }))
                {
                    // dq = 0 is feasible with model value 0: a solution must not be worse
                    Some(dq)
                        if 0.5 * dq.dot(&(h * dq)) - g.dot(&dq) <= 1e-12 * g.norm() * dq.norm() =>
                    {
                        dq
                    }
                    _ => {
                        // clarabel failed: damp harder, as for a refused step
                        if !damp_harder(o.adaptive_damping, &mut lambda, &mut nu) {
                            break End::Stalled;
                        }
                        continue;
                    }
                },
            };
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
            let accepted = match trial {
                None => None,
                Some(t) => {
                    let (e_new, cost_new) = self.error(target, &t);
                    (cost_new < cost || !o.adaptive_damping).then_some((t, e_new, cost_new))
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
                    tip = t;
                    e = e_new;
                    cost = cost_new;
                    self.fk.accept();
                    fresh = false;
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
                    if !damp_harder(o.adaptive_damping, &mut lambda, &mut nu) {
                        break End::Stalled;
                    }
                }
            }
        };
        let end = if end != End::Reached && self.reached(target, &tip) {
            End::Reached
        } else {
            end
        };
        Attempt {
            q,
            tip,
            cost,
            iterations,
            end,
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

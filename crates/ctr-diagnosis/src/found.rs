//! What a diagnosis has found so far: the user's model with the effects added, fitted,
//! its error on every row, and the record of every candidate tried. The search builds
//! it round by round, the checks take findings out of it, and the report is written
//! from it.

use crate::candidates::EffectId;
use crate::fit::MAX_FIT_ITERATIONS;
use crate::report::prose::{explain, parameters};
use crate::report::{Figures, Finding, Trial};
use crate::residual::{errors, figures, RowError};
use crate::start::Start;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict_on;

/// The model found so far (see the module docs).
#[derive(Clone, Debug)]
pub(crate) struct Found {
    /// The user's model with the effects found, fitted.
    pub model: ModelSpec,
    /// One per effect found, in the order added.
    pub findings: Vec<Finding>,
    /// The model's figures on the split.
    pub fig: Figures,
    /// The model's robust cost on the fit rows, mm^2.
    pub cost: f64,
    /// The model's error vectors, every row.
    pub e: Vec<RowError>,
    /// Every candidate tried, round by round, and the findings taken out after.
    pub tried: Vec<Trial>,
    /// Whether the registration is the tracker's frame solved in every fit, a
    /// nuisance in the model from the start (`crate::search::frame`): always in the
    /// model (the last of [`effects`](Self::effects) where it is no finding).
    pub frame_profiled: bool,
}

impl Found {
    /// The user's model of `start`, nothing found yet; `None` when it cannot be
    /// simulated on the fit rows.
    pub(crate) fn user(start: &Start) -> Option<Self> {
        let cost = start.problem(start.user.clone(), vec![]).cost_at(&[])?;
        Some(Found {
            model: start.user.clone(),
            findings: Vec::new(),
            fig: start.baseline,
            cost,
            e: start.e0.clone(),
            tried: Vec::new(),
            frame_profiled: false,
        })
    }

    /// The effects in the model: those found, in the order added, then the tracker's
    /// frame where it is in the model without being a finding.
    pub(crate) fn effects(&self) -> Vec<EffectId> {
        let mut v: Vec<EffectId> = self.findings.iter().map(|f| f.effect).collect();
        let frame = EffectId::Registration;
        if self.frame_profiled && !v.contains(&frame) {
            v.push(frame);
        }
        v
    }

    /// Whether `c` is in the model: among the effects found, or the tracker's frame.
    pub(crate) fn has(&self, c: EffectId) -> bool {
        self.effects().contains(&c)
    }

    /// The parameters of every effect in the model ([`effects`](Self::effects)),
    /// concatenated in that order, as `m` holds them.
    pub(crate) fn parameters_in(&self, m: &ModelSpec) -> Vec<f64> {
        self.effects().iter().flat_map(|c| c.read(m)).collect()
    }

    /// Takes `m` (whose error vectors are `e`) as the model found, and reads every
    /// finding's parameters and words again from it (a joint refit moves them all).
    pub(crate) fn take(&mut self, start: &Start, mut m: ModelSpec, e: Vec<RowError>) {
        // the same tips with the offsets' common turn in the tracker's frame
        if self.frame_profiled {
            crate::measurement::gauged(&mut m, &start.user, start.rec.has_force);
        }
        self.fig = figures(start.rec, &e, &start.held);
        self.e = e;
        for f in &mut self.findings {
            f.parameters = parameters(f.effect, &m);
            f.explanation = explain(f.effect, &m);
        }
        self.model = m;
    }
}

impl Found {
    /// The findings refitted together on the user's model from their values: whether
    /// it took (`self` unchanged where the fit or its simulation fails).
    pub(crate) fn refit(&mut self, start: &Start) -> bool {
        let effects = self.effects();
        let (m, cost) = if effects.is_empty() {
            let Some(cost) = start.problem(start.user.clone(), vec![]).cost_at(&[]) else {
                return false;
            };
            (start.user.clone(), cost)
        } else {
            let x0 = self.parameters_in(&self.model);
            let p = start.problem(start.user.clone(), effects);
            let Some(f) = p.fit(&x0, MAX_FIT_ITERATIONS) else {
                return false;
            };
            (p.model(&f.x), f.cost)
        };
        let Some(e) = simulate(start, &m) else {
            return false;
        };
        self.take(start, m, e);
        self.cost = cost;
        true
    }
}

/// `m`'s error vectors on every row of `start`'s recording (`None` when it cannot be
/// simulated).
pub(crate) fn simulate(start: &Start, m: &ModelSpec) -> Option<Vec<RowError>> {
    let pred = predict_on(m, start.rec, &start.all_runs, start.threads).ok()?;
    Some(errors(start.rec, &pred))
}

//! What a diagnosis has found so far: the user's model with the effects added, fitted,
//! its error on every row, and the record of every candidate tried. The search builds
//! it round by round, the checks take findings out of it, and the report is written
//! from it.

use crate::candidates::EffectId;
use crate::report::prose::{explain, parameters};
use crate::report::{Figures, Finding, Trial};
use crate::residual::{errors, figures, RowError};
use crate::start::Start;
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;

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
        })
    }

    /// The effects found, in the order added.
    pub(crate) fn effects(&self) -> Vec<EffectId> {
        self.findings.iter().map(|f| f.effect).collect()
    }

    /// Whether `c` is among the effects found.
    pub(crate) fn has(&self, c: EffectId) -> bool {
        self.findings.iter().any(|f| f.effect == c)
    }

    /// The parameters of every effect found, concatenated in the order added, as
    /// `m` holds them.
    pub(crate) fn parameters_in(&self, m: &ModelSpec) -> Vec<f64> {
        self.findings
            .iter()
            .flat_map(|f| f.effect.read(m))
            .collect()
    }

    /// Takes `m` (whose error vectors are `e`) as the model found, and reads every
    /// finding's parameters and words again from it (a joint refit moves them all).
    pub(crate) fn take(&mut self, start: &Start, m: ModelSpec, e: Vec<RowError>) {
        self.fig = figures(start.rec, &e, &start.held);
        self.e = e;
        for f in &mut self.findings {
            f.parameters = parameters(f.effect, &m);
            f.explanation = explain(f.effect, &m);
        }
        self.model = m;
    }
}

/// `m`'s error vectors on every row of `start`'s recording (`None` when it cannot be
/// simulated).
pub(crate) fn simulate(start: &Start, m: &ModelSpec) -> Option<Vec<RowError>> {
    let pred = predict(m, start.rec, &start.all_runs).ok()?;
    Some(errors(start.rec, &pred))
}

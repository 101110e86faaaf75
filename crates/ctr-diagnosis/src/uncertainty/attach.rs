//! The findings given their intervals: the fit problem of a diagnosis's findings, and
//! each finding's `ci95` (with the combinations the data identify) at the fitted model.

use super::{Assessment, Combination};
use crate::candidates::EffectId;
use crate::fit::Problem;
use crate::report::prose::{explain, parameters};
use crate::report::{Correlated, Finding};
use ctr_analysis::model::ModelSpec;
use ctr_formats::{Correction, Recording};
use serde_json::Value;

/// What the report says about the uncertainty as a whole.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Overall {
    pub method: String,
    pub identifiability: Vec<String>,
    pub correlated: Vec<Correlated>,
}

/// The fit problem of the findings `effects` of `fitted` (torsion has no parameter; a
/// clearance fitted as a table stays one).
pub(crate) fn problem_of<'a>(
    rec: &'a Recording,
    fitted: &ModelSpec,
    effects: &[EffectId],
    rows: &[usize],
    huber_mm: f64,
    threads: usize,
) -> Problem<'a> {
    let blocks: Vec<EffectId> = effects
        .iter()
        .copied()
        .filter(|e| *e != EffectId::Torsion)
        .collect();
    let clearance_table = fitted
        .effects
        .clearance
        .as_ref()
        .filter(|c| !c.table_deg.is_empty() && blocks.contains(&EffectId::Clearance))
        .and_then(|c| c.table_deg.first().map(Vec::len));
    Problem {
        base: fitted.clone(),
        blocks,
        rec,
        rows: rows.to_vec(),
        huber_mm,
        threads,
        clearance_table,
    }
}

/// Gives every finding its `ci95` (and `identified` combinations), at `fitted` against
/// the user's model `user`; returns the model with what is not identified set to the
/// nominal (the findings' parameters rewritten from it) and the report's overall words.
/// `assessed`, when given, is `problem`'s assessment already computed.
pub(crate) fn attach(
    problem: &Problem,
    user: &ModelSpec,
    findings: &mut [Finding],
    assessed: Option<Assessment>,
    remainder: Option<&Correction>,
) -> (ModelSpec, Overall, Option<Assessment>) {
    let x = problem.read(&problem.base);
    let nominal = problem.read(user);
    let Some(a) = assessed.or_else(|| Assessment::new(problem, &x, &nominal)) else {
        for f in findings.iter_mut() {
            f.ci95 = Value::Null;
        }
        let overall = Overall {
            method: if x.is_empty() {
                "no fitted parameter".into()
            } else {
                "not computed: the fitted model cannot be simulated for the Jacobian".into()
            },
            identifiability: Vec::new(),
            correlated: Vec::new(),
        };
        return (problem.base.clone(), overall, None);
    };
    let model = problem.model(&a.x);
    let mut at = 0;
    let mut ranges = Vec::new();
    for &b in &problem.blocks {
        let len = problem.block_len(b);
        ranges.push((b, at, len));
        at += len;
    }
    let combos = a.combinations();
    let alt = remainder.and_then(|c| a.with_remainder(problem, c));
    for f in findings.iter_mut() {
        f.parameters = parameters(f.effect, &model);
        f.explanation = explain(f.effect, &model);
        let Some(&(b, at, len)) = ranges.iter().find(|r| r.0 == f.effect) else {
            f.ci95 = f.parameters.clone();
            continue;
        };
        let mut ci = a.ci95(problem, b, at, len, alt.as_ref());
        let mine: Vec<Value> = combos
            .iter()
            .filter(|c| c.effect == b)
            .map(Combination::to_json)
            .collect();
        if let (false, Value::Object(m)) = (mine.is_empty(), &mut ci) {
            m.insert("identified".into(), Value::Array(mine));
        }
        f.ci95 = ci;
        let own: Vec<&Combination> = combos.iter().filter(|c| c.effect == b).collect();
        if let Some(first) = own.first() {
            let words: Vec<String> = own.iter().map(|c| c.words()).collect();
            f.explanation += &format!(
                " The data identify only {}; the values alone are not identified ({}).",
                words.join(", "),
                a.tie_along(first.direction).words()
            );
        }
    }
    let mut method = a.method.clone();
    if let Some(alt) = &alt {
        method += &format!(
            "; the report does not explain the residual: each interval is joined with the \
             one of the parameters refitted together with the {} terms of the empirical \
             correction (Gauss-Newton with the Jacobian at the fit; sd from the joint \
             information and the residual both leave): what the remainder can move them by",
            alt.terms
        );
    }
    let overall = Overall {
        method,
        identifiability: a.statements(&combos),
        correlated: a.correlated(),
    };
    (model, overall, Some(a))
}

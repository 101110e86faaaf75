//! Check 2 of a finding: its parameters are constant, not proportional to a feature of
//! the rows (see the module docs of [`crate::verify`]).

use super::{Context, Failure, ModelFrame, MIN_GAIN_OVER_EMPIRICAL};
use crate::candidates::EffectId;
use crate::empirical::{self, Basis, Field};
use crate::fit::Problem;
use crate::report::Figures;
use crate::residual::{positions, with_angles, RowError};
use ctr_analysis::model::ModelSpec;

impl Context<'_> {
    /// Check 2: the failure of `c` (`e_without`: `m`'s errors with `c` taken out) when
    /// its parameters fit clearly better proportional to a feature than constant.
    pub(super) fn against_proportional(
        &self,
        m: &ModelSpec,
        frame: &ModelFrame,
        directions: &[Field],
        e: &[RowError],
        c: EffectId,
    ) -> Option<Failure> {
        let (feature, constant, proportional) = self.proportional(m, frame, directions, e, c)?;
        let clearly_better = proportional.heldout_score()
            < (1.0 - MIN_GAIN_OVER_EMPIRICAL) * constant.heldout_score();
        clearly_better.then_some(Failure::Varying {
            feature,
            constant,
            proportional,
        })
    }

    /// The tip directions of `c`'s parameters in `m` at every row: column `j` of the
    /// Jacobian of the tip positions with respect to its parameters, `J_c,j(q)`, in
    /// `m`'s W (`frame`).
    pub(super) fn directions(
        &self,
        m: &ModelSpec,
        frame: &ModelFrame,
        c: EffectId,
    ) -> Option<Vec<Field>> {
        let rows = self.rec.rows.len();
        let problem = Problem {
            base: m.clone(),
            blocks: vec![c],
            rec: self.rec,
            rows: (0..rows).collect(),
            huber_mm: self.huber_mm,
            threads: self.threads,
            clearance_table: None,
        };
        let x = c.read(m);
        let p0 = problem.predictions(&x)?;
        let jac = problem.jacobian(&x, &p0)?;
        Some(
            (0..jac.ncols())
                .map(|j| {
                    frame.field(
                        (0..rows)
                            .map(|r| [jac[(3 * r, j)], jac[(3 * r + 1, j)], jac[(3 * r + 2, j)]])
                            .collect(),
                    )
                })
                .collect(),
        )
    }

    /// With `c` taken out to first order about `m` (whose errors in W are `e_model`):
    /// the held-out RMS of the linear fit of the `k` constant parameter directions
    /// `J_c,j`, and of the best `k` proportional fields `J_c,j f`, with the feature
    /// chosen first. The error without `c` is `e - J_c x` (`x` its fitted parameters,
    /// those whose zero means it is absent): both fits then stand on the same
    /// linearisation, and the constant one gives `m`'s own error back whatever the
    /// effect's size (a frame turned by degrees is not judged on the curvature of its
    /// rotation).
    fn proportional(
        &self,
        m: &ModelSpec,
        frame: &ModelFrame,
        constant: &[Field],
        e_model: &[RowError],
        c: EffectId,
    ) -> Option<(String, Figures, Figures)> {
        let rows = self.rec.rows.len();
        let k = constant.len();
        let direction = |j: usize, r: usize| constant[j][r];
        let x = c.read(m);
        let e_row: Vec<RowError> = e_model
            .iter()
            .enumerate()
            .map(|(r, v)| {
                let mut w = *v;
                for (j, xj) in x.iter().enumerate().filter(|(j, _)| c.absence_of(*j)) {
                    for a in 0..3 {
                        w[a] -= direction(j, r)[a] * xj;
                    }
                }
                w
            })
            .collect();
        let e_row = &e_row[..];
        // fitted to the positions (the tip directions `J_c`); the angular errors stay
        let e = &positions(e_row);
        let basis = Basis::raw(self.rec, &frame.tips(self.rec, e_model));
        let mut fields: Vec<Field> = Vec::new();
        let mut names = Vec::new();
        for j in 0..k {
            for (feature, col) in basis.varying() {
                fields.push(
                    (0..rows)
                        .map(|r| direction(j, r).map(|d| d * col[r]))
                        .collect(),
                );
                names.push(feature.name());
            }
        }
        // the robust weights of the fitted model (where its fit converged): the constant
        // fit then takes the finding's own values
        let w = empirical::weights(&positions(e_model), &self.fit, self.huber_mm);
        let heldout = |fields: &[Field], terms: &[(usize, f64)]| {
            let left = empirical::subtract(fields, terms, e);
            self.figures(&with_angles(&left, e_row))
        };
        let all: Vec<usize> = (0..k).collect();
        let h_const = heldout(constant, &empirical::coefficients(constant, &all, e, &w));
        let terms = empirical::pursue(&fields, e, &w, k);
        let first = terms.first().map(|&(i, _)| names[i].clone())?;
        Some((first, h_const, heldout(&fields, &terms)))
    }
}

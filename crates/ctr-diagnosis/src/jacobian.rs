//! The fit's Jacobian: the predictions' derivatives in the parameters by central
//! differences at each parameter's natural scale (one-sided at a bound, or where one
//! side cannot be simulated), one column per job on the thread pool
//! ([`ctr_formats::parallel::map`]).
//!
//! The columns of the effects that leave the mechanics alone (on the joints: joint
//! offsets, latency, the play friction; on the measurement: sensor offset and
//! rotation, registration; [`crate::candidates::EffectId::leaves_mechanics`]) do not solve the rows again:
//! the rows are solved once at the parameters with the core's analytic joint Jacobian
//! ([`Linearised`], beside the solved columns; under a load, where the core has no
//! analytic one, by probes, and only where that costs fewer solves than the columns),
//! and each step's prediction is the chain rule through it, exact in the measurement
//! (checked against solving again in `ctr-analysis/tests/linearised.rs`). Measured on
//! the real three-tube recording: the search's solves went from 7.6 to 2.4 million.

use crate::fit::Problem;
use ctr_analysis::linearised::Linearised;
use nalgebra::{DMatrix, DVector};

impl Problem<'_> {
    /// Jacobian of the predictions by central differences (one-sided at a bound, or
    /// where one side cannot be simulated).
    pub fn jacobian(&self, x: &[f64], p0: &[f64]) -> Option<DMatrix<f64>> {
        Some(self.jacobian_and_blocked(x, p0).0)
    }

    /// [`jacobian`](Self::jacobian), and for each parameter whether the model cannot be
    /// simulated a step up / down from `x` (a feed offset pushing a joint past its
    /// tube's end): the fit's steps hold it there on that side.
    pub(crate) fn jacobian_and_blocked(
        &self,
        x: &[f64],
        p0: &[f64],
    ) -> (DMatrix<f64>, Vec<[bool; 2]>) {
        let np = x.len();
        let cheap = self.linearised_columns(x);
        // first the rows linearised (one job) beside the columns that need solves, then
        // the columns of the effects that leave the mechanics alone, without solving
        // where the rows could be linearised; `threads` is at least 1 (0: all cores)
        let mut jobs: Vec<Option<usize>> =
            (0..np).filter(|j| !cheap.contains(j)).map(Some).collect();
        if !cheap.is_empty() {
            jobs.insert(0, None);
        }
        let threads = self.threads.max(1);
        // the linearisation alone has the threads to itself (its runs side by side)
        let alone = if jobs.len() == 1 { threads } else { 1 };
        let done = ctr_formats::parallel::map(&jobs, threads, |job| match job {
            Some(j) => (Some(self.column(x, p0, *j, None)), None),
            None => (None, self.moves_without_solving(x, alone)),
        });
        let mut columns: Vec<Option<(Vec<f64>, [bool; 2])>> = vec![None; np];
        let mut moves = None;
        for (job, (column, linearised)) in jobs.iter().zip(done) {
            match job {
                Some(j) => columns[*j] = column,
                None => moves = linearised,
            }
        }
        let rest =
            ctr_formats::parallel::map(&cheap, threads, |&j| self.column(x, p0, j, moves.as_ref()));
        for (&j, c) in cheap.iter().zip(rest) {
            columns[j] = Some(c);
        }
        let mut jac = DMatrix::zeros(p0.len(), np);
        let mut blocked = Vec::with_capacity(np);
        for (j, c) in columns.into_iter().enumerate() {
            let (c, b) = c.expect("every column computed");
            jac.set_column(j, &DVector::from_vec(c));
            blocked.push(b);
        }
        (jac, blocked)
    }

    /// Column `j` of the Jacobian at `x` (predictions `p0`) by central differences at
    /// the parameter's natural scale, from the linearised rows `moves` where given (else
    /// solved), and whether a step up / down cannot be simulated.
    fn column(
        &self,
        x: &[f64],
        p0: &[f64],
        j: usize,
        moves: Option<&Moves>,
    ) -> (Vec<f64>, [bool; 2]) {
        let (h, (lo, hi)) = self.scale(j);
        let up = if x[j] + h > hi { 0.0 } else { h };
        let down = if x[j] - h < lo { 0.0 } else { h };
        // a side the model cannot be simulated on is left out: one-sided there, a zero
        // column (the parameter cannot move) where neither side can
        let side = |d: f64| -> Option<Vec<f64>> {
            let mut xs = x.to_vec();
            xs[j] += d;
            match moves {
                _ if d == 0.0 => None,
                Some(moves) => moves.predictions(self, &xs),
                None => self.predictions_on(&xs, 1),
            }
        };
        let (pp, pm) = (side(up), side(-down));
        let blocked = [up > 0.0 && pp.is_none(), down > 0.0 && pm.is_none()];
        let (up, down) = (
            if pp.is_some() { up } else { 0.0 },
            if pm.is_some() { down } else { 0.0 },
        );
        if up == 0.0 && down == 0.0 {
            return (vec![0.0; p0.len()], blocked);
        }
        // one-sided: from the prediction at `x` on the same basis
        let here = moves.and_then(|m| m.here.as_deref()).unwrap_or(p0);
        let (pp, pm) = (pp.as_deref().unwrap_or(here), pm.as_deref().unwrap_or(here));
        let col = pp
            .iter()
            .zip(pm)
            .map(|(a, b)| (a - b) / (up + down))
            .collect();
        (col, blocked)
    }

    /// Whether parameter `j` belongs to an effect that leaves the mechanics alone
    /// (a clearance table never does).
    fn leaves_mechanics(&self, j: usize) -> bool {
        let b = self.effect_of(j);
        self.table(b).is_none() && b.leaves_mechanics()
    }

    /// The columns at `x` taken from the linearised rows: those of the effects that
    /// leave the mechanics alone, where linearising costs fewer solves of each row
    /// ([`Linearised::solves_per_row`]: under a load its probes) than the two per
    /// column it saves; none else.
    fn linearised_columns(&self, x: &[f64]) -> Vec<usize> {
        let cheap: Vec<usize> = (0..x.len()).filter(|&j| self.leaves_mechanics(j)).collect();
        let cost = Linearised::solves_per_row(&self.model(x), self.rec, &self.rows);
        match cost {
            Some(c) if !cheap.is_empty() && c < (2 * cheap.len()) as f64 => cheap,
            _ => Vec::new(),
        }
    }

    /// The rows at `x` linearised (their runs on `threads`) for the columns of the
    /// effects that leave the mechanics alone, when there are such columns and the
    /// model has a joint Jacobian (else they are solved like the others).
    fn moves_without_solving(&self, x: &[f64], threads: usize) -> Option<Moves> {
        let linearised = Linearised::new(&self.model(x), self.rec, &self.rows, threads)
            .ok()
            .flatten()?;
        let mut moves = Moves {
            linearised,
            here: None,
        };
        moves.here = moves.predictions(self, x);
        Some(moves)
    }
}

/// A fit's rows linearised at its parameters ([`Linearised`]): the predictions of
/// nearby parameters of the effects that leave the mechanics alone, without solving.
struct Moves {
    linearised: Linearised,
    /// The predictions at the parameters linearised at, on the same basis.
    here: Option<Vec<f64>>,
}

impl Moves {
    /// `problem`'s predictions at `x` (differing from where the rows were linearised
    /// only in effects that leave the mechanics alone); `None` where its joints leave
    /// the robot's ranges.
    fn predictions(&self, problem: &Problem, x: &[f64]) -> Option<Vec<f64>> {
        let pred = self
            .linearised
            .predict(&problem.model(x), problem.rec)
            .ok()??;
        problem.assembled(&pred, x)
    }
}

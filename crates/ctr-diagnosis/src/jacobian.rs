//! The fit's Jacobian: the predictions' derivatives in the parameters by central
//! differences at each parameter's natural scale (one-sided at a bound, or where one
//! side cannot be simulated), one column per job on the thread pool
//! ([`ctr_formats::parallel::map`]).
//!
//! Most columns do not solve the rows again
//! ([`crate::candidates::EffectId::linearised_as`]): the rows are
//! solved once at the parameters ([`Linearised`], one job beside the solved columns)
//! with what the columns need, and each step's prediction is the chain rule through
//! it, exact in the measurement (checked against solving again in
//! `ctr-analysis/tests/linearised.rs`). The measurement's columns (sensor offset and
//! rotation, registration) need a plain solve; the joint effects' (joint offsets,
//! latency, the play friction) the core's analytic joint Jacobian (under a load, where
//! the core has none, probes); the stiffness and precurvature factors' its analytic
//! parameter Jacobian (unloaded rows only). Of these the cheapest in solves that covers
//! the most columns is taken, where it costs fewer solves than the two per column it
//! saves. Measured on the real three-tube recording: the search's solves went from
//! 7.6 to 2.4 million with the joints, and to 1.7 million with the scales.

use crate::fit::Problem;
use ctr_analysis::linearised::{Linearised, Moving};
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
        let (cheap, way) = self.linearised_columns(x);
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
            None => (
                None,
                way.and_then(|w| self.moves_without_solving(x, w, alone)),
            ),
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

    /// How parameter `j`'s predictions can move without solving
    /// ([`crate::candidates::EffectId::linearised_as`]; a clearance table never can).
    fn linearised_as(&self, j: usize) -> Option<Moving> {
        let b = self.effect_of(j);
        self.table(b).map_or_else(|| b.linearised_as(), |_| None)
    }

    /// The columns at `x` taken from the linearised rows, and what the linearisation
    /// carries: of the four ways to linearise ([`Moving`]), the one that saves the most
    /// solves of each row (two per column it covers, less its cost,
    /// [`Linearised::cost_per_row`]: under a load the joints' probes, and no scales),
    /// if any saves some; none else. The measurement's columns come with any.
    fn linearised_columns(&self, x: &[f64]) -> (Vec<usize>, Option<Moving>) {
        let model = self.model(x);
        let kinds: Vec<Option<Moving>> = (0..x.len()).map(|j| self.linearised_as(j)).collect();
        let covered = |way: Moving| -> Vec<usize> {
            (0..x.len())
                .filter(|&j| match kinds[j] {
                    Some(Moving::Measurement) => true,
                    Some(Moving::Joints) => way.joints(),
                    Some(Moving::Scales) => way.scales(),
                    _ => false,
                })
                .collect()
        };
        let mut best: (f64, Vec<usize>, Option<Moving>) = (0.0, Vec::new(), None);
        for way in [
            Moving::Measurement,
            Moving::Joints,
            Moving::Scales,
            Moving::Both,
        ] {
            let Some(cost) = Linearised::cost_per_row(&model, self.rec, &self.rows, way) else {
                continue;
            };
            let columns = covered(way);
            let saved = (2 * columns.len()) as f64 - cost;
            if saved > best.0 {
                best = (saved, columns, Some(way));
            }
        }
        (best.1, best.2)
    }

    /// The rows at `x` linearised as `way` (their runs on `threads`) for the columns
    /// it covers, when the model has the Jacobians it needs (else they are solved like
    /// the others).
    fn moves_without_solving(&self, x: &[f64], way: Moving, threads: usize) -> Option<Moves> {
        let linearised = Linearised::moving(&self.model(x), self.rec, &self.rows, threads, way)
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
    /// the robot's ranges. A model the linearisation does not carry is solved, as the
    /// columns that are not linearised: never taken for one that cannot be simulated
    /// (which would hold its parameter still).
    fn predictions(&self, problem: &Problem, x: &[f64]) -> Option<Vec<f64>> {
        if !problem.feeds_in_range(x) {
            return None;
        }
        match self.linearised.predict(&problem.model(x), problem.rec) {
            Ok(Some(pred)) => problem.assembled(&pred, x),
            Ok(None) => problem.predictions_on(x, 1),
            Err(_) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::candidates::EffectId;
    use crate::fit::Problem;
    use crate::synth::{generate, Ranges, SynthSpec};
    use ctr_analysis::model::ModelSpec;
    use ctr_formats::Friction;

    /// A fit of the stiffness factors alone (a candidate's screen) on a model whose
    /// friction grows with the contact moment: the factors move the plays too, and the
    /// columns taken without solving are the solved central differences (they were
    /// zero, the parameters held still, while the linearisation left that out).
    #[test]
    fn stiffness_columns_beside_the_contact_friction_are_the_solved_ones() {
        let text = include_str!("../../../data/robots/nitinol3.toml");
        let spec = ctr_formats::RobotSpec::from_toml_str(text, "nitinol3.toml").unwrap();
        let mut user = ModelSpec::from_spec(&spec);
        user.effects.friction = Some(Friction {
            rotation_play_deg: vec![1.0, 1.0],
            feed_play_mm: vec![],
            rotation_friction_coefficient: vec![0.02, 0.03],
        });
        // three factors: their columns are linearised (two saved solves each of a row
        // outweigh the parameter Jacobian's cost)
        let ranges = Ranges {
            increments_mm: vec![[10.0, 50.0]; 3],
            theta_deg: [-180.0, 180.0],
        };
        let mut world = user.clone();
        EffectId::Stiffness.write(&mut world, &[1.0, 0.8, 1.2]);
        let rec = generate(&world, &ranges, &SynthSpec::default())
            .unwrap()
            .recording;
        let problem = Problem::for_test(user, vec![EffectId::Stiffness], &rec, 4);
        let x = [1.0, 0.9, 1.1];
        let p0 = problem.predictions(&x).unwrap();
        let jac = problem.jacobian(&x, &p0).unwrap();
        for j in 0..x.len() {
            let h = problem.scale(j).0;
            let at = |d: f64| {
                let mut xs = x.to_vec();
                xs[j] += d;
                problem.predictions(&xs).unwrap()
            };
            let (up, down) = (at(h), at(-h));
            let solved: Vec<f64> = up
                .iter()
                .zip(&down)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect();
            let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
            let size = norm(&mut solved.iter().copied());
            let gap = norm(&mut jac.column(j).iter().zip(&solved).map(|(a, b)| a - b));
            assert!(size > 1e-3, "factor {j} moves the tips ({size})");
            assert!(gap <= 1e-2 * size, "factor {j}: {:.2e} apart", gap / size);
        }
    }
}

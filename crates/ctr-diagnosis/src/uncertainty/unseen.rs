//! The directions the data do not see, in a basis that says which parameters are
//! unseen together, and the fitted values set to the nominal along them.
//!
//! The eigenvectors of the scaled information below
//! [`UNIDENTIFIED_EIGEN`](super::UNIDENTIFIED_EIGEN) span the directions along which
//! the tips do not change. Any basis of that span describes it, and an eigen solver's is
//! arbitrary where the eigenvalues are (nearly) equal, as they are for every unseen
//! direction: it mixes a common factor of the stiffnesses with the feed plays of two
//! tubes that never move. Stated direction by direction, a mixed basis names parameters
//! together that are unseen each on its own (twice, once per direction), and a
//! combination orthogonal to one direction leans on another and is lost.
//!
//! So the basis is put in reduced echelon form: Gauss-Jordan elimination with complete
//! pivoting on the scaled directions (unit-free), then back to the parameters' units
//! (a diagonal scaling keeps every zero). Each direction then has a pivot parameter no
//! other direction holds; a parameter unseen on its own is a direction by itself;
//! directions of disjoint parameters come apart. Directions that share parameters form
//! one [`Group`], stated once.
//!
//! Along a group the fitted values are arbitrary, so they are moved to the point of
//! their span nearest the nominal (least squares in the parameters' units), as far as the
//! fit's bounds allow (the segment toward it is cut where it leaves them), and only
//! where the cost does not change (the tips really do not move): [`Tie`] says how far
//! that went, and the report says it in words. What is left of a direction below
//! [`PART_OF_DIRECTION`](super::PART_OF_DIRECTION) of its largest component is the eigen
//! solver's rounding and is dropped (the parameters taking part are those above it).

use super::parts;
use crate::fit::Problem;
use nalgebra::{DMatrix, DVector};

/// Relative change of the robust cost up to which moving along a direction not seen
/// counts as leaving the tips where they were: the simulation's rounding, no more (the
/// report's figures are those of the values before the move, so the move must not
/// change them; a direction that is unseen only to first order, as a rotation vector's
/// component, stays as fitted).
const SAME_COST_WITHIN: f64 = 1e-9;

/// How far a group's values went toward the nominal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Tie {
    /// Set to the nominal along the group's directions.
    Nominal,
    /// Moved toward the nominal until a parameter met the fit's bounds.
    TowardNominal,
    /// Left as fitted (the first step toward the nominal meets a bound, or moving
    /// there moves the tips).
    Fitted,
}

impl Tie {
    /// In words, after "the values are" / "they are".
    pub(crate) fn words(self) -> &'static str {
        match self {
            Tie::Nominal => "kept at the nominal along the direction the data cannot see",
            Tie::TowardNominal => {
                "moved toward the nominal along the direction the data cannot see, as far \
                 as the fit's bounds allow"
            }
            Tie::Fitted => {
                "left as fitted: the nominal along the direction the data cannot see is \
                 outside the fit's bounds, or the tips there differ by more than rounding"
            }
        }
    }
}

/// Directions not seen that share parameters, stated together.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Group {
    /// Indices of its directions.
    pub directions: Vec<usize>,
    /// The parameters taking part, ascending.
    pub parameters: Vec<usize>,
    /// How far its values went toward the nominal.
    pub tie: Tie,
}

/// The directions not seen, in reduced echelon form, and their groups.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Unseen {
    /// The directions, in the parameters' units.
    pub directions: Vec<DVector<f64>>,
    pub groups: Vec<Group>,
}

impl Unseen {
    /// The directions spanned by `scaled` (unit-free directions, parameter `j` scaled
    /// by `d[j]`), in reduced echelon form and the parameters' units, grouped; no value
    /// tied yet ([`Tie::Fitted`]).
    pub(crate) fn new(scaled: &[DVector<f64>], d: &[f64]) -> Self {
        let directions: Vec<DVector<f64>> = echelon(scaled)
            .into_iter()
            .map(|v| DVector::from_iterator(v.len(), v.iter().zip(d).map(|(a, s)| a * s)))
            .map(|u| {
                // what is not part of it is the eigen solver's rounding: without it a
                // parameter that sits on a bound would stop the values' move at once
                let part = parts(&u);
                DVector::from_fn(u.len(), |j, _| if part.contains(&j) { u[j] } else { 0.0 })
            })
            .collect();
        let groups = groups(&directions)
            .into_iter()
            .map(|members| {
                let mut parameters: Vec<usize> = members
                    .iter()
                    .flat_map(|&k| parts(&directions[k]))
                    .collect();
                parameters.sort_unstable();
                parameters.dedup();
                Group {
                    directions: members,
                    parameters,
                    tie: Tie::Fitted,
                }
            })
            .collect();
        Unseen { directions, groups }
    }

    /// The group direction `k` belongs to.
    pub(crate) fn group_of(&self, k: usize) -> Option<&Group> {
        self.groups.iter().find(|g| g.directions.contains(&k))
    }

    /// `x` with each group's values moved to the nominal along its directions (module
    /// doc) where that leaves the cost `cost` as it is (within rounding: a lower cost
    /// would be a better fit than the one whose figures the report gives); records how
    /// far each went.
    pub(crate) fn tie(
        &mut self,
        problem: &Problem,
        x: &[f64],
        nominal: &[f64],
        cost: f64,
    ) -> Vec<f64> {
        let bounds: Vec<(f64, f64)> = (0..x.len()).map(|j| problem.scale(j).1).collect();
        let mut at = x.to_vec();
        for g in &mut self.groups {
            let u: Vec<&DVector<f64>> = g.directions.iter().map(|&k| &self.directions[k]).collect();
            let (moved, tie) = toward_nominal(&u, &at, nominal, &bounds);
            let same = |c: f64| (c - cost).abs() <= SAME_COST_WITHIN * cost + f64::MIN_POSITIVE;
            if tie != Tie::Fitted && problem.cost_at(&moved).is_some_and(same) {
                at = moved;
                g.tie = tie;
            }
        }
        at
    }
}

/// The span of `vectors` (linearly independent, of one length) in reduced echelon
/// form: Gauss-Jordan with complete pivoting, each pivot scaled to 1.
///
/// ```text
/// (1, 1, 0), (1, -1, 0) -> (1, 0, 0), (0, 1, 0)
/// ```
pub(crate) fn echelon(vectors: &[DVector<f64>]) -> Vec<DVector<f64>> {
    let k = vectors.len();
    let Some(p) = vectors.first().map(DVector::len) else {
        return Vec::new();
    };
    let mut m = DMatrix::from_fn(k, p, |i, j| vectors[i][j]);
    let mut free = vec![true; p];
    let mut rank = 0;
    for i in 0..k {
        let mut pivot: Option<(usize, usize)> = None;
        let mut largest = 0.0;
        for r in i..k {
            for c in (0..p).filter(|&c| free[c]) {
                if m[(r, c)].abs() > largest {
                    largest = m[(r, c)].abs();
                    pivot = Some((r, c));
                }
            }
        }
        let Some((r, c)) = pivot else { break };
        m.swap_rows(i, r);
        free[c] = false;
        let scale = m[(i, c)];
        m.row_mut(i).scale_mut(1.0 / scale);
        let row = m.row(i).into_owned();
        for other in (0..k).filter(|&o| o != i) {
            let f = m[(other, c)];
            if f != 0.0 {
                for j in 0..p {
                    m[(other, j)] -= f * row[j];
                }
            }
        }
        rank += 1;
    }
    (0..rank).map(|i| m.row(i).transpose()).collect()
}

/// The directions' groups: indices of directions connected by shared parameters.
fn groups(directions: &[DVector<f64>]) -> Vec<Vec<usize>> {
    let part: Vec<Vec<usize>> = directions.iter().map(parts).collect();
    let mut group: Vec<usize> = (0..directions.len()).collect();
    // merge until no two groups share a parameter (few directions: quadratic is fine)
    let mut changed = true;
    while changed {
        changed = false;
        for a in 0..directions.len() {
            for b in a + 1..directions.len() {
                let shares = part[a].iter().any(|j| part[b].contains(j));
                if shares && group[a] != group[b] {
                    let (keep, drop) = (group[a].min(group[b]), group[a].max(group[b]));
                    group
                        .iter_mut()
                        .filter(|g| **g == drop)
                        .for_each(|g| *g = keep);
                    changed = true;
                }
            }
        }
    }
    let mut out: Vec<Vec<usize>> = Vec::new();
    for (k, &g) in group.iter().enumerate() {
        match out.iter_mut().find(|members| group[members[0]] == g) {
            Some(members) => members.push(k),
            None => out.push(vec![k]),
        }
    }
    out
}

/// `x` moved along the span of `u` to the point nearest `nominal` (least squares in
/// the parameters' units), cut where the segment toward it leaves `bounds`.
fn toward_nominal(
    u: &[&DVector<f64>],
    x: &[f64],
    nominal: &[f64],
    bounds: &[(f64, f64)],
) -> (Vec<f64>, Tie) {
    let np = x.len();
    let basis = DMatrix::from_fn(np, u.len(), |j, k| u[k][j]);
    let off = DVector::from_iterator(np, (0..np).map(|j| x[j] - nominal[j]));
    let gram = basis.transpose() * &basis;
    let Some(solved) = gram
        .cholesky()
        .map(|c| c.solve(&(basis.transpose() * &off)))
    else {
        return (x.to_vec(), Tie::Fitted);
    };
    // toward the nominal: -step, no further than all of it
    let step = basis * solved;
    let toward: Vec<f64> = step.iter().map(|d| -d).collect();
    let reach = reach(x, &toward, bounds).min(1.0);
    let tie = if reach >= 1.0 {
        Tie::Nominal
    } else if reach > 0.0 {
        Tie::TowardNominal
    } else {
        Tie::Fitted
    };
    let moved = (0..np).map(|j| x[j] - reach * step[j]).collect();
    (moved, tie)
}

/// How far `x` can go along `d` (as a multiple of it, `>= 0`; infinite where `d` is
/// zero) with every parameter within `bounds`.
pub(super) fn reach(x: &[f64], d: &[f64], bounds: &[(f64, f64)]) -> f64 {
    x.iter()
        .zip(d)
        .zip(bounds)
        .fold(f64::INFINITY, |reach, ((&x, &d), &(lo, hi))| {
            if d > 0.0 {
                reach.min((hi - x) / d)
            } else if d < 0.0 {
                reach.min((lo - x) / d)
            } else {
                reach
            }
        })
        .max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: &[f64]) -> DVector<f64> {
        DVector::from_column_slice(x)
    }

    /// Two parameters unseen each on its own, mixed by an eigen solver, come apart;
    /// a third direction of other parameters stays whole and forms its own group.
    #[test]
    fn a_mixed_basis_comes_apart_into_single_parameters() {
        let s = 0.5_f64.sqrt();
        let mixed = [
            v(&[s, s, 0.0, 0.0]),
            v(&[s, -s, 0.0, 0.0]),
            v(&[0.0, 0.0, 1.0, 1.0]),
        ];
        let e = echelon(&mixed);
        assert_eq!(e.len(), 3);
        let supports: Vec<Vec<usize>> = e.iter().map(parts).collect();
        assert!(
            supports.contains(&vec![0]) && supports.contains(&vec![1]),
            "{supports:?}"
        );
        assert!(supports.contains(&vec![2, 3]), "{supports:?}");
        let g = groups(&e);
        assert_eq!(g.len(), 3, "{g:?}");
    }

    /// Directions that share a parameter are one group; the echelon form spans the same
    /// space (each input is a combination of its directions).
    #[test]
    fn shared_parameters_make_one_group_and_the_span_is_kept() {
        let ab = v(&[1.0, 1.0, 0.0]);
        let bc = v(&[0.0, 1.0, 1.0]);
        let e = echelon(&[ab.clone(), bc.clone()]);
        assert_eq!(groups(&e), vec![vec![0, 1]]);
        let basis = DMatrix::from_fn(3, 2, |j, k| e[k][j]);
        for w in [ab, bc] {
            let fit = &basis * basis.clone().svd(true, true).solve(&w, 1e-12).unwrap();
            assert!((fit - w).norm() < 1e-12);
        }
    }

    /// The values go to the nominal along the span where the bounds allow, part way
    /// where a parameter meets its bound first, and nowhere where it sits on it.
    #[test]
    fn toward_the_nominal_stops_at_the_bounds() {
        let u = v(&[1.0, 1.0]);
        let bounds = [(-1.0, 1.0); 2];
        let (x, tie) = toward_nominal(&[&u], &[0.5, 0.3], &[0.0, 0.0], &bounds);
        assert_eq!(tie, Tie::Nominal);
        assert!(
            (x[0] - 0.1).abs() < 1e-12 && (x[1] + 0.1).abs() < 1e-12,
            "{x:?}"
        );
        let (x, tie) = toward_nominal(
            &[&u],
            &[0.5, -0.9],
            &[0.0, 0.0],
            &[(-1.0, 1.0), (-1.0, 1.0)],
        );
        // nearest point: shift by -0.2 -> (0.7, -0.7): inside
        assert_eq!(tie, Tie::Nominal, "{x:?}");
        let (x, tie) = toward_nominal(&[&u], &[0.9, 0.9], &[-0.5, -0.5], &[(0.0, 1.0), (0.0, 1.0)]);
        assert_eq!(tie, Tie::TowardNominal);
        assert!(x.iter().all(|&a| (a - 0.0).abs() < 1e-12), "{x:?}");
        let (x, tie) = toward_nominal(&[&u], &[0.0, 0.5], &[-0.5, 0.0], &[(0.0, 1.0), (0.0, 1.0)]);
        assert_eq!(tie, Tie::Fitted);
        assert_eq!(x, vec![0.0, 0.5]);
    }
}

//! The held-out rows a decision counts: a glitch set aside before it.
//!
//! The search, the frame's test, the checks and the predictive model decide on
//! held-out figures. One tracker glitch among few held-out rows (12 mm among 16 rows of
//! 0.7 mm) decides a held-out RMS alone, so no candidate could gain on it and the
//! choice would be the glitch's. So each decision counts the held-out rows where the
//! model it starts from (the one every candidate of the decision is compared with)
//! misses by at most [`GLITCH_MEDIANS`] times its median miss over the held-out rows;
//! the others are set aside for every candidate alike. The figures a report prints
//! count every row.

use crate::residual::{figures, size2, RowError};
use crate::robust::median;
use ctr_formats::Recording;

/// A held-out row whose error under the model a decision starts from exceeds this many
/// times that model's median held-out error is set aside for the decision (for
/// Gaussian noise the median of a 3-D error is 1.54 sigma: 8 medians is 12 sigma,
/// never reached by noise; a structured residual rarely has a row at 8 times its
/// median, a glitch of many mm on a model that misses by one always does).
pub(crate) const GLITCH_MEDIANS: f64 = 8.0;

/// The held-out rows a decision counts (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Scored {
    /// Whether each row is held out and counted.
    mask: Vec<bool>,
}

impl Scored {
    /// The held-out rows of `held` that decisions starting from the model whose error
    /// vectors are `e` count.
    pub(crate) fn from(e: &[RowError], held: &[bool]) -> Self {
        let mut sizes: Vec<f64> = e
            .iter()
            .zip(held)
            .filter(|(_, h)| **h)
            .map(|(v, _)| size2(v).sqrt())
            .filter(|s| s.is_finite())
            .collect();
        if sizes.is_empty() {
            return Scored {
                mask: held.to_vec(),
            };
        }
        let limit = GLITCH_MEDIANS * median(&mut sizes);
        let mask = e
            .iter()
            .zip(held)
            .map(|(v, &h)| {
                h && size2(v).sqrt().partial_cmp(&limit) != Some(std::cmp::Ordering::Greater)
            })
            .collect();
        Scored { mask }
    }

    /// What a decision compares of error vectors `e`: their held-out score over the
    /// rows counted ([`crate::report::Figures::heldout_score`]).
    pub(crate) fn score(&self, rec: &Recording, e: &[RowError]) -> f64 {
        // only the held-out figures count: rows set aside pass for fit rows here
        figures(rec, e, &self.mask).heldout_score()
    }

    /// Whether each row is held out and counted.
    pub(crate) fn mask(&self) -> &[bool] {
        &self.mask
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A glitch among the held-out rows is set aside; the rows of a model that misses
    /// by more everywhere are not.
    #[test]
    fn a_glitch_is_set_aside_and_a_large_error_everywhere_is_not() {
        let held: Vec<bool> = (0..40).map(|r| r % 4 == 0).collect();
        let mut e: Vec<RowError> = (0..40)
            .map(|r| [0.5 + 0.01 * r as f64, -0.3, 0.2, 0.0, 0.0, 0.0])
            .collect();
        e[8][0] = 12.0;
        let s = Scored::from(&e, &held);
        let counted: Vec<usize> = (0..40).filter(|&r| s.mask()[r]).collect();
        assert_eq!(counted.len(), 9);
        assert!(!counted.contains(&8) && counted.contains(&12));
        // ten times larger everywhere: nothing set aside
        let big: Vec<RowError> = e.iter().map(|v| v.map(|x| 10.0 * x)).collect();
        let mut big = big;
        big[8] = e[9].map(|x| 10.0 * x);
        let all = Scored::from(&big, &held);
        assert_eq!(all.mask(), &held[..]);
    }
}

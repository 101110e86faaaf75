//! The options of a diagnosis and a calibration.

use crate::candidates::EffectId;
use crate::split::Holdout;
use ctr_analysis::job::DEFAULT_WARN_MARGIN;

/// Options of a diagnosis.
#[derive(Clone, Debug, PartialEq)]
pub struct Options {
    /// The split.
    pub holdout: Holdout,
    /// The effects tried (default: all ten).
    pub candidates: Vec<EffectId>,
    /// Threads for the fits (0: all cores).
    pub threads: usize,
    /// `calibrate` only: fit the clearance as a smooth table of this many values per
    /// pair over one turn (the seed's measured "database") instead of a cosine profile.
    pub clearance_table: Option<usize>,
    /// Rows where the user's or the fitted model has a stability margin below this are
    /// marked near a snap in the report's `stability` (default
    /// [`DEFAULT_WARN_MARGIN`], `ctr-cli fk --warn-margin`'s); 0 marks only rows on an
    /// unstable branch. Finite and not negative.
    pub warn_margin: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            holdout: Holdout::default(),
            candidates: EffectId::ALL.to_vec(),
            threads: 0,
            clearance_table: None,
            warn_margin: DEFAULT_WARN_MARGIN,
        }
    }
}

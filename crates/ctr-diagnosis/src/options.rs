//! The options of a diagnosis and a calibration.

use crate::candidates::EffectId;
use crate::start::split::Holdout;
use ctr_analysis::margin::DEFAULT_WARN_MARGIN;

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
    /// The checks a finding must pass before the report calls it physics (all on; one
    /// is turned off only to show what it guards against).
    pub checks: Checks,
}

/// The acceptance checks of a finding (module `verify`): each `true` runs it.
///
/// ```
/// let all = ctr_diagnosis::Checks::default();
/// assert!(all.beats_generic && all.constant && all.identified && all.present);
/// assert!(all.within_tolerance);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Checks {
    /// It beats a generic empirical correction with as many parameters, held out.
    pub beats_generic: bool,
    /// Its parameters fit better constant than proportional to a feature of the rows.
    pub constant: bool,
    /// Its parameters' joint 95 % region excludes the nominal.
    pub identified: bool,
    /// At least one of its parameters' 95 % intervals excludes the value that means it
    /// is not there (where its parameters are identified alone), and none of its
    /// parameters sits on a bound of its fit (where the interval is cut by the bound).
    pub present: bool,
    /// None of its parameters lies more than [`TOLERANCE_SIGMAS`](crate::TOLERANCE_SIGMAS)
    /// of the lab's tolerance from its nominal (a tube five times softer than its
    /// datasheet stands in for something else).
    pub within_tolerance: bool,
}

impl Default for Checks {
    fn default() -> Self {
        Checks {
            beats_generic: true,
            constant: true,
            identified: true,
            present: true,
            within_tolerance: true,
        }
    }
}

impl Default for Options {
    fn default() -> Self {
        Options {
            holdout: Holdout::default(),
            candidates: EffectId::ALL.to_vec(),
            threads: 0,
            clearance_table: None,
            warn_margin: DEFAULT_WARN_MARGIN,
            checks: Checks::default(),
        }
    }
}

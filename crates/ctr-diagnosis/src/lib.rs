//! Diagnosis: where a model and a recording disagree, which left-out physics explains
//! it, fitted, and the gain shown on rows the fit did not see.
//!
//! This crate sits above the row model: it simulates a recording only through
//! `ctr_analysis::simulate::predict` (a [`ModelSpec`](ctr_analysis::model::ModelSpec):
//! robot, model kind and effects, run along the recorded commands) and reads and writes
//! the contract's files through `ctr_formats`. `ctr-cli diagnose` / `calibrate` /
//! `evaluate` and `ctr_py.diagnose` / `calibrate` / `evaluate` are thin calls of
//! [`diagnose()`], [`calibrate()`] and [`evaluate()`].
//!
//! 1. **Split** ([`Holdout`]): each run is cut into contiguous blocks and every
//!    `every`-th block (staggered between runs) is held out; or whole runs are held out
//!    by label. Never random rows: neighbouring samples share their errors. Time effects
//!    need whole runs, so every run is always simulated; only the residuals of the
//!    held-out rows are kept from the fit.
//! 2. **Noise**: estimated from the data, not from the model: the second differences
//!    of the user model's residual along each run remove any error that varies smoothly
//!    with the motion, leaving `6 sigma^2` of white tracker noise per axis (a robust
//!    median-absolute-deviation estimate, so jumps at reversals and outliers do not
//!    count). Rows repeated at rest give a second estimate where there are enough.
//!    With angular columns (`qw,qx,qy,qz` or `tx,ty,tz`, `angular`), their noise is
//!    estimated the same way on the angular error, and each row's residual gains the
//!    angular components weighted by the position noise over theirs (whitened alike).
//! 3. **Locate** ([`locate`]): regressions of the residual on runs, joints, exposed
//!    lengths, relative angles (periodic), direction of motion and workspace position.
//! 4. **Explain**: forward selection over the contract's effects the model leaves out
//!    ([`EffectId`]). The tracker's frame is no candidate: where the registration is
//!    one, it is in the model from the start and every fit solves it in closed form at
//!    every point it tries (`measurement`: variable projection; the sensor offset and
//!    rotation likewise wherever they are fitted), so no account depends on how the
//!    tracker was registered. Each round fits every remaining candidate's parameters
//!    (`fit`: robust Levenberg-Marquardt, bounded) with the effects found so far held,
//!    and the candidate with the lowest held-out error is added if it passes both
//!    tests: the Bayesian information criterion on the fit rows,
//!    `N ln(C_new / C_old) + k ln N < 0` (N residual components, k parameters, C the
//!    robust cost), and a held-out RMS at least [`MIN_HELDOUT_GAIN`] lower, on the
//!    held-out rows the model so far does not miss by many times its median (`scored`:
//!    one glitch among few held-out rows decides no choice). The effects found are then
//!    refitted together. Where no candidate passes both, the one the criterion likes
//!    best may enter for a look-ahead of two rounds, kept only if the model it leads
//!    to pays over where it began. When nothing enters, every effect found is tested
//!    again against the model without it, refitted (`search::backward`), and those
//!    that no longer pay leave: the search revisits what it took first.
//! 5. **Verify** (`verify`): a finding is physics only when the data say so. With the
//!    other findings in place, each must beat the generic empirical correction of as
//!    many parameters in its place on the held-out rows (where it leaves only noise,
//!    a correction also in the stretches and shears of the tip position, unless the
//!    effect is itself a map of the tip position: a sensor offset along the tip that
//!    mimics a tracker's scale fails), and its
//!    parameters must fit better constant than proportional to a feature of the rows
//!    (a feed offset where the feed gain is wrong fails). Findings that fail are taken
//!    out and the rest refitted, until all pass.
//! 6. **Verdict**: `explained` is true when the held-out residual (tracker outliers set
//!    aside) is at most [`NOISE_TOLERANCE`] times the noise estimate. When false, a
//!    learned discrepancy (`empirical::gp`: a Gaussian process over the joints and their
//!    history, fitted on the fit rows) is fitted on top of the physics and reported
//!    apart as `empirical`, with its held-out RMS and its band (the linear correction
//!    of `hybrid`, in the joints, time and tip position, where it cannot be fitted). Tracker outliers are judged on what is left after both: rows far from the
//!    residual's median and from their neighbours, by the residual's own robust spread.
//! 7. **Uncertainty** (`uncertainty`): every finding's parameters get 95 % intervals
//!    (`ci95`) from the fit's Jacobian, the larger of the classical and a
//!    cluster-robust covariance; directions the data cannot pin are tied to the nominal
//!    and the combinations they do pin reported instead.
//! 8. **Near a snap** (`stability`, [`Stability`]): the rows where the user's or the
//!    fitted model, solved along each run as the robot moved, has a stability margin
//!    below [`Options::warn_margin`] (or below 0: an unstable branch), from the margins
//!    of the simulations already made; a jump in the data there is physics, and
//!    tracker outliers among those rows are said to be so.
//!
//! One concept per module: `split` ([`Holdout`]), `noise` (the estimate and the
//! outliers), `residual` (error vectors and their figures), `angular` (the angular
//! columns' errors and noise), `weighting` (their weight against the positions),
//! `robust` (the median and its spread), `scored` (the held-out rows a decision
//! counts), [`locate`], `jacobian` (the fits' Jacobian), `measurement` (the
//! measurement solved inside every fit), `candidates`
//! ([`EffectId`]: each effect as a parameter block), `fit`, `levenberg` (its steps),
//! `search` (forward selection, the frame, the revisit; [`diagnose()`]),
//! `empirical` (the generic basis and matching pursuit), `verify` (the checks of a
//! finding), `hybrid` (the empirical term), `uncertainty` (intervals and
//! identifiability), `numbers` (a JSON value's numbers by key path),
//! `calibrate` and `evaluate` (no search), `start` (what both start from and how both
//! finish), `stability` (the rows near a snap), `report` ([`Report`] and its
//! [`summary`](Report::summary)), `prose` (the words), `plots` (the SVG plots drawn
//! from a report and its recording, [`Plot`]), `html` (the report as one
//! self-contained page, [`Page`]), `options`, `error`. The fits run on the one thread
//! pool, `ctr_formats::parallel`; results do not depend on the thread count.
//!
//! With the `synth` feature (off by default), `synth` generates recordings with
//! concealed effects: the proof bench of the diagnosis, used by this crate's tests and
//! by the example that writes the bundled `data/examples/liu2023-recording.csv`; and
//! re-frames recordings (`synth::Reframe`: a turned tracker, a moved encoder zero, a
//! time shift, glitches) so that the true change to the model is exact, which the
//! example `reframe` and `scripts/reframe.sh` run on a real recording.

mod calibrate;
mod candidates;
mod diagnose;
mod empirical;
mod error;
mod evaluate;
mod finish;
mod fit;
mod found;
mod grade;
mod jacobian;
mod levenberg;
pub mod locate;
mod measurement;
mod options;
mod paired;
mod predictive;
mod quantiles;
mod report;
mod residual;
mod robust;
mod scored;
mod search;
mod start;
#[cfg(feature = "synth")]
pub mod synth;
mod tolerance;
mod uncertainty;
mod verdict;
mod verify;

pub use calibrate::calibrate;
pub use candidates::EffectId;
pub use diagnose::diagnose;
pub use empirical::hybrid::{FOLDS, MAX_TERMS};
pub use error::DiagnoseError;
pub use evaluate::evaluate;
pub use grade::absent_value;
pub use locate::stability::{
    checked_warn_margin, near_snap_words, MarginRange, Marks, Stability, ROWS_AFTER_A_SNAP,
};
pub use locate::Statement;
pub use options::{Checks, Options};
pub use report::html::{escape_html, Page};
pub use report::plots::Plot;
pub use report::{
    fitted_file, Alternative, AngularFigures, AngularNoise, Band, Correlated, Diagnosis, Empirical,
    ExpectedInterval, Figures, Finding, GpInput, Grade, JointRun, Noise, Report, RunErrors, Split,
    SuggestedRun, Term, Trial,
};
pub use search::MIN_HELDOUT_GAIN;
pub use start::noise::{estimate_noise, NOISE_TOLERANCE, OUTLIER_SIGMAS};
pub use start::split::{split, Holdout};
pub use tolerance::{
    CURVATURE_RADIUS_TOLERANCE, DENSITY_TOLERANCE, STANDARD_GRAVITY_M_S2, TOLERANCE_SIGMAS,
    YOUNGS_MODULUS_TOLERANCE,
};
pub use uncertainty::suggest::{MIN_SHRINK, SUGGESTED_ROWS, WIDE};
pub use uncertainty::{CORRELATED_ABOVE, INDEPENDENT_BELOW, UNIDENTIFIED_EIGEN};
pub use verify::MIN_GAIN_OVER_EMPIRICAL;

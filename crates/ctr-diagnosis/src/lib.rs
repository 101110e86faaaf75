//! Diagnosis: where a model and a recording disagree, which left-out physics explains
//! it, fitted, graded by the evidence, and the gain shown on rows the fit did not see.
//!
//! This crate sits above the row model: it simulates a recording only through
//! `ctr_analysis::simulate` (a [`ModelSpec`](ctr_analysis::model::ModelSpec): robot,
//! model kind and effects, run along the recorded commands; `ctr_analysis::linearised`
//! for the fits' Jacobians) and reads and writes the contract's files through
//! `ctr_formats`. `ctr-cli diagnose` / `calibrate` / `evaluate` and `ctr_py.diagnose` /
//! `calibrate` / `evaluate` are thin calls of [`diagnose()`], [`calibrate()`] and
//! [`evaluate()`].
//!
//! [`diagnose()`] is one pipeline of named stages over one state, in this order
//! (`diagnose.rs`; a module or folder per stage):
//!
//! 1. **The tracker's frame** (`search::frame`, `measurement`). A registration says
//!    nothing of the robot, so it is no candidate: where the user's model has none and
//!    the candidates hold it, it is in the model from the start, and every fit solves it
//!    in closed form at every point it tries (variable projection: weighted
//!    Kabsch/Umeyama, then robust Gauss-Newton; the sensor offset and rotation likewise
//!    wherever they are fitted). No account depends on how the tracker was registered.
//! 2. **Start** (`start`): the angular columns (`qw,qx,qy,qz` or `tx,ty,tz`) weighted by
//!    their noise against the positions (`start::angular`, `start::weighting`); the
//!    **split** ([`Holdout`]: each run cut into contiguous blocks, every `every`-th held
//!    out and staggered between runs, or whole runs by label; never random rows, as
//!    neighbouring samples share their errors; time effects need whole runs, so every run
//!    is always simulated); the **noise** from the data, not the model (`start::noise`:
//!    the second differences of the user model's residual along each run remove any error
//!    that varies smoothly with the motion, leaving `6 sigma^2` of white tracker noise per
//!    axis, by a robust median-absolute-deviation estimate); and where the error sits
//!    ([`locate`]: regressions on runs, joints, exposed lengths, relative angles, direction
//!    of motion and workspace position).
//! 3. **Search** (`search`): forward selection over the effects the model leaves out
//!    ([`EffectId`]). Each round screens every candidate beside the effects found so far
//!    on a sample of the fit rows (`search::screen`), fits the most promising in full
//!    (`fit`, `levenberg`: robust Huber Levenberg-Marquardt, bounded, several starts where
//!    the problem is not convex) and adds the one with the lowest held-out error if it
//!    passes both tests: the Bayesian information criterion on the fit rows,
//!    `N ln(C_new / C_old) + k ln N < 0` (N residual components, k parameters, C the
//!    robust cost), and a held-out RMS at least [`MIN_HELDOUT_GAIN`] lower, on the
//!    held-out rows the model so far does not miss by many times its median (`scored`:
//!    one glitch among few held-out rows decides no choice). The effects found are then
//!    refitted together. Where only the criterion accepts a candidate, it may enter for a
//!    look-ahead of two rounds, kept only if the model it leads to pays over where it
//!    began; when nothing enters, every effect found is tested again against the model
//!    without it, refitted (`search::backward`), and those that no longer pay leave.
//! 4. **Verify** (`verify`): a finding is physics only when the data say so. With the
//!    other findings in place each must beat a generic empirical correction of as many
//!    parameters on the held-out rows (`empirical`, with the stretches and shears of
//!    the tip position among its terms, unless the effect is itself a map of the tip
//!    position), fit better constant than proportional to a
//!    feature of the rows (a feed offset where the feed gain is wrong fails), and be
//!    identified (its joint 95 % region excludes the nominal). Findings that fail are
//!    taken out and the rest refitted, then revisited as the search revisits, until all
//!    pass: the **established** findings.
//! 5. **Predictive** (`predictive`): the search's model is the best predictive model. A
//!    finding the checks took out stays in it, graded **predictive** ([`Grade`]), where
//!    the fitted model without it does worse on the held-out rows by at least
//!    [`MIN_HELDOUT_GAIN`], the gain the search asks of every effect to enter and to
//!    keep its place; the others are dropped. A
//!    predictive finding never makes an established one.
//! 6. **Finish** (`finish`):
//!    - the **verdict** (`verdict`): `explained` when the held-out residual (tracker
//!      outliers aside) is at most [`NOISE_TOLERANCE`] times the noise estimate and no
//!      predictive finding was needed to get there. When it is not, a learned discrepancy
//!      is fitted on top of the physics (`empirical::gp`: a Gaussian process over the
//!      commanded joints, their relative rotations and the play operators of those
//!      rotations along each run, i.e. the joints and their history; its length scales,
//!      signal, noise and play width by the marginal likelihood of the fit rows) and
//!      reported apart as `empirical`, with its held-out RMS and its band; where it cannot
//!      be fitted, the linear correction of `empirical::hybrid` stands in. Tracker
//!      outliers are judged on what is left after both: rows far from the residual's
//!      median and from their neighbours ([`OUTLIER_SIGMAS`] robust deviations);
//!    - the **intervals** (`uncertainty`): 95 % intervals (`ci95`) from the fit's
//!      Jacobian, the larger of the classical and a cluster-robust covariance, each end
//!      checked along its profile and, where the residual is not explained, joined with
//!      the remainder's; directions the data cannot pin tied to the nominal and the
//!      combinations they do pin reported instead; the run to record next
//!      (`uncertainty::suggest`);
//!    - the **grades** (`grade`, `tolerance`): established only where an interval
//!      excludes the value that means "not there", none sits on a bound, and every
//!      parameter is within [`TOLERANCE_SIGMAS`] of the lab's tolerances
//!      ([`CURVATURE_RADIUS_TOLERANCE`], [`YOUNGS_MODULUS_TOLERANCE`],
//!      [`DENSITY_TOLERANCE`]);
//!    - the rows **near a snap** (`locate::stability`, [`Stability`]): where the user's or
//!      the fitted model, solved along each run as the robot moved, has a stability
//!      margin below [`Options::warn_margin`] (or below 0); a jump in the data there is
//!      physics, and tracker outliers among those rows are said to be so;
//!    - the **report** ([`Report`], its [`summary`](Report::summary), the SVG plots
//!      [`Plot`] and the self-contained HTML page [`Page`]).
//!
//! [`calibrate()`] fits named effects together without the search (the same start and
//! finish, graded by the intervals alone); [`evaluate()`] gives several models' tip errors
//! run by run. [`Checks`] turns a check off, to show what it is for.
//!
//! Other modules: `candidates` (each effect as a parameter block), `found` (the model a
//! stage hands on), `jacobian` (the fits' Jacobian: linearised columns for the effects on
//! the joints or the measurement, solved ones for the mechanics), `residual`, `robust`,
//! `quantiles`, `options`, `error`. The fits run on the one thread pool,
//! `ctr_formats::parallel`; results do not depend on the thread count.
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
mod sessions;
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
    ExpectedInterval, Figures, Finding, GpInput, Grade, JointRun, Noise, Report, RunErrors,
    SessionChange, Split, SuggestedRun, Term, Trial,
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

//! The learned discrepancy along a run: the joints its inputs read (the commanded ones
//! delayed by the model's latency, as the latency effect delays them) and each row's
//! correction and band. The Gaussian process itself is `crate::discrepancy`.

use crate::model::ModelSpec;
use crate::timeline::{actual_joints, TimeEffects};
use ctr_formats::Recording;

/// The joints a discrepancy reads for the rows of run `run` of `rec`: the commanded ones
/// delayed by `model`'s latency along the run (as the latency effect delays them; the
/// commands themselves without one). Not the joint offsets' or the friction's: the play
/// inputs model the history themselves, and an offset only shifts what is standardised.
pub fn delayed_commands(model: &ModelSpec, rec: &Recording, run: usize) -> Vec<Vec<f64>> {
    delayed(model, Some(&rec.run_times(run)), rec.run_joints(run))
}

/// The commanded joint rows `joints` of one run delayed by `model`'s latency at their
/// times `t_s` (as they are without a latency or without times).
fn delayed(model: &ModelSpec, t_s: Option<&[f64]>, joints: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
    match (model.effects.latency, t_s) {
        (Some(l), Some(t)) if l.tau_s != 0.0 => {
            let mut delay = TimeEffects::none(model.robot.n_tubes());
            delay.latency_s = l.tau_s;
            actual_joints(t, &joints, &delay)
        }
        _ => joints,
    }
}

/// `model`'s discrepancy along one run of commanded joint rows `joints` (flat, file
/// order and units) at times `t_s` (needed where the model has a latency): each row's
/// correction (mm) and the standard deviation of a measurement about it (mm per axis);
/// `None` without a discrepancy.
///
/// ```
/// use ctr_analysis::{learned::along_commands, model::ModelSpec};
/// use ctr_formats::RobotSpec;
/// let spec = RobotSpec::from_toml_str("[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\n\
///     length_mm = 260.0\ncurved_length_mm = 0.0\nyoungs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n", "r.toml")?;
/// assert!(along_commands(&ModelSpec::from_spec(&spec), &[50.0, 0.0], None).is_none());
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub fn along_commands(
    model: &ModelSpec,
    joints: &[f64],
    t_s: Option<&[f64]>,
) -> Option<Vec<([f64; 3], f64)>> {
    let gp = model.discrepancy.as_ref()?;
    let width = 2 * model.robot.n_tubes();
    let rows: Vec<Vec<f64>> = joints.chunks(width).map(<[f64]>::to_vec).collect();
    let rows = delayed(model, t_s, rows);
    let refs: Vec<&[f64]> = rows.iter().map(|r| &r[..]).collect();
    Some(gp.along_run(&refs))
}

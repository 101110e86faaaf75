//! The words of a report: each finding explained with its fitted values, its parameters
//! as the robot file writes them, and what is left.

use crate::candidates::EffectId;
use crate::report::{Figures, Noise};
use ctr_analysis::model::ModelSpec;
use ctr_formats::{Clearance, Friction, Latency, Recording};
use std::collections::BTreeMap;

/// The effect's table of the robot file, as JSON.
pub(crate) fn parameters(c: EffectId, m: &ModelSpec) -> serde_json::Value {
    let e = &m.effects;
    let v = match c {
        EffectId::Torsion => serde_json::to_value(BTreeMap::from([("kind", "torsion")])),
        EffectId::Friction => serde_json::to_value(&e.friction),
        EffectId::Clearance => serde_json::to_value(&e.clearance),
        EffectId::Gravity => serde_json::to_value(&e.gravity),
        EffectId::Registration => serde_json::to_value(e.registration),
        EffectId::JointOffset => serde_json::to_value(&e.joint_offset),
        EffectId::Stiffness => serde_json::to_value(&e.stiffness),
        EffectId::Precurvature => serde_json::to_value(&e.precurvature),
        EffectId::Latency => serde_json::to_value(e.latency),
        EffectId::SensorOffset => serde_json::to_value(e.sensor_offset),
        EffectId::SensorRotation => serde_json::to_value(e.sensor_rotation),
    };
    v.unwrap_or(serde_json::Value::Null)
}

fn list(v: &[f64], unit: &str) -> String {
    v.iter()
        .map(|x| format!("{x:.3}{unit}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The finding in words.
pub(crate) fn explain(c: EffectId, m: &ModelSpec) -> String {
    let e = &m.effects;
    match c {
        EffectId::Torsion => "The model leaves out torsion: the tubes twist along their \
            length, so the relative angles at the tips differ from the commanded ones."
            .into(),
        EffectId::Friction => friction_words(e.friction.as_ref().expect("written by the fit")),
        EffectId::Clearance => clearance_words(e.clearance.as_ref().expect("written by the fit")),
        EffectId::Gravity => {
            let g = e.gravity.as_ref().expect("written by the fit");
            format!(
                "The model leaves out the tubes' weight: gravity of {:.2} m/s^2 along \
                 ({:.3}, {:.3}, {:.3}) in W bends the robot.",
                g.g_m_s2, g.direction_w[0], g.direction_w[1], g.direction_w[2]
            )
        }
        EffectId::Registration => {
            let r = e.registration.expect("written by the fit");
            format!(
                "The measuring frame is not W: it is shifted by ({}) mm and rotated by \
                 {:.3} deg about ({:.3}, {:.3}, {:.3}).",
                list(&r.translation_mm, ""),
                r.rotation_deg,
                r.rotation_axis[0],
                r.rotation_axis[1],
                r.rotation_axis[2]
            )
        }
        EffectId::JointOffset => {
            let o = e.joint_offset.as_ref().expect("written by the fit");
            format!(
                "The actuators' zeros differ from the nominal ones: feed offsets ({}) mm, \
                 rotation offsets ({}) deg, tube 1 first.",
                list(&o.feed_mm, ""),
                list(&o.rotation_deg, "")
            )
        }
        EffectId::Stiffness => {
            let s = e.stiffness.as_ref().expect("written by the fit");
            format!(
                "The tubes' stiffness differs from the description: E times ({}), tube 1 \
                 first.",
                list(&s.factor, "")
            )
        }
        EffectId::Precurvature => {
            let p = e.precurvature.as_ref().expect("written by the fit");
            format!(
                "The tubes' precurvature differs from the description: curvature radius \
                 times ({}), tube 1 first.",
                list(&p.radius_factor, "")
            )
        }
        EffectId::Latency => latency_words(e.latency.expect("written by the fit")),
        EffectId::SensorOffset => {
            let s = e.sensor_offset.expect("written by the fit");
            format!(
                "The tracked point is not the tube's tip: it sits at ({}) mm in the tip \
                 frame.",
                list(&s.offset_mm, "")
            )
        }
        EffectId::SensorRotation => {
            let s = e.sensor_rotation.expect("written by the fit");
            let v = nalgebra::Vector3::from(s.rotation_vector_deg);
            format!(
                "The tracked sensor sits turned in the tip frame: by {:.3} deg in all, \
                 rotation vector ({}) deg (tip frame).",
                v.norm(),
                list(&s.rotation_vector_deg, "")
            )
        }
    }
}

/// The friction finding in words: the play of each relative rotation, and of the
/// feeds where there is one.
fn friction_words(f: &Friction) -> String {
    let mut s = String::from(
        "The model leaves out friction between the tubes: the tip depends on the \
         direction of motion (hysteresis)",
    );
    for (i, w) in f.rotation_play_deg.iter().enumerate() {
        s += &format!(
            "; the rotation of tube {} relative to tube {} lags by a play of \
             +/-{w:.2} deg",
            i + 2,
            i + 1
        );
    }
    for (i, m) in f.rotation_friction_coefficient.iter().enumerate() {
        if *m > 0.0 {
            s += &format!(
                "; that play grows with the bending moment where tube {} ends \
                 (friction coefficient {m:.4})",
                i + 1
            );
        }
    }
    if f.feed_play_mm.iter().any(|w| *w > 0.0) {
        s += &format!("; feed play per tube {}", list(&f.feed_play_mm, " mm"));
    }
    s + "."
}

/// The clearance finding in words: for each pair of tubes, the largest deflection and
/// the relative angle where it peaks (from the table, or the cosine profile).
fn clearance_words(c: &Clearance) -> String {
    let mut parts = Vec::new();
    for (i, t) in c.table_deg.iter().enumerate() {
        let (k, max) =
            t.iter().enumerate().fold(
                (0, f64::NEG_INFINITY),
                |a, (k, v)| if *v > a.1 { (k, *v) } else { a },
            );
        parts.push(format!(
            "tube {} leaves tube {}'s tip deflected by up to {max:.2} deg, largest at a \
             relative angle of {:.0} deg (a table of {} values over one turn)",
            i + 2,
            i + 1,
            360.0 * k as f64 / t.len() as f64,
            t.len()
        ));
    }
    for i in 0..c.max_deflection_deg.len() {
        parts.push(format!(
            "tube {} leaves tube {}'s tip deflected by up to {:.2} deg, largest at a \
             relative angle of {:.0} deg",
            i + 2,
            i + 1,
            c.max_deflection_deg[i],
            c.peak_deg[i]
        ));
    }
    format!(
        "The model leaves out the clearance between the tubes: {}.",
        parts.join("; ")
    )
}

/// The latency finding in words: the measured tip lags the commands, or leads them
/// (time stamps shifted).
fn latency_words(l: Latency) -> String {
    if l.tau_s >= 0.0 {
        format!(
            "The measured tip lags the commanded joints by {:.3} s (actuator \
             tracking or tracker delay).",
            l.tau_s
        )
    } else {
        format!(
            "The measured tip leads the commanded joints by {:.3} s (the time \
             stamps are shifted).",
            -l.tau_s
        )
    }
}

/// Up to ten file lines, `, ...` after them when there are more.
fn lines_words(lines: &[usize]) -> String {
    lines
        .iter()
        .take(10)
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(", ")
        + if lines.len() > 10 { ", ..." } else { "" }
}

/// What is left, in words. `near_snap` are the file lines of the outliers that lie near
/// a snap of a model (said apart: physics, not the tracker).
pub(crate) fn leftover(
    rec: &Recording,
    fig: &Figures,
    inliers: &Figures,
    outliers: &[usize],
    near_snap: &[usize],
    outlier_threshold_mm: f64,
    noise: &Noise,
    explained: bool,
    where_: impl FnOnce() -> String,
) -> String {
    let outlier_note = if outliers.is_empty() {
        String::new()
    } else {
        let (snap, tracker): (Vec<usize>, Vec<usize>) = outliers
            .iter()
            .map(|&r| rec.rows[r].line)
            .partition(|line| near_snap.contains(line));
        let mut kinds = Vec::new();
        if !tracker.is_empty() {
            kinds.push(format!("tracker outliers: lines {}", lines_words(&tracker)));
        }
        if !snap.is_empty() {
            kinds.push(format!(
                "near a snap, physics rather than a tracker glitch: lines {}",
                lines_words(&snap)
            ));
        }
        format!(
            " once {} row{} farther than {outlier_threshold_mm:.3} mm from the residual's median \
             ({}) are set aside",
            outliers.len(),
            if outliers.len() == 1 { "" } else { "s" },
            kinds.join("; ")
        )
    };
    if explained {
        format!(
            "residual is consistent with measurement noise{outlier_note}: {:.3} mm RMS on the \
             fit rows, {:.3} mm held out, against {:.3} mm of noise estimated from the data",
            inliers.rms_mm, inliers.heldout_rms_mm, noise.rms_mm
        )
    } else {
        format!(
            "{:.3} mm RMS is left ({:.3} mm held out{}), above the {:.3} mm of noise \
             estimated from the data, and no effect of the vocabulary reduces it further; it \
             sits in {}",
            fig.rms_mm,
            fig.heldout_rms_mm,
            if outliers.is_empty() {
                String::new()
            } else {
                format!(
                    "; {:.3} mm without {} outlier rows{}",
                    inliers.rms_mm,
                    outliers.len(),
                    if near_snap.is_empty() {
                        String::new()
                    } else {
                        format!(
                            ", lines {} of them near a snap (physics rather than a tracker \
                             glitch)",
                            lines_words(near_snap)
                        )
                    }
                )
            },
            noise.rms_mm,
            where_()
        )
    }
}

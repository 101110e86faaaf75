//! The linearised prediction ([`Linearised`]) against solving again: at the point
//! linearised it is the solved prediction; for a step of any effect on the joints or the
//! measurement, its central difference is the solved central difference (the chain
//! rule through the core's analytic joint Jacobian), and so for a tube's stiffness or
//! precurvature factor where the scales move (its parameter Jacobian); a change it does
//! not carry, a load where it has no derivative, or a learned term is refused rather
//! than linearised wrongly.

use ctr_analysis::linearised::{Linearised, Moving};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::{predict_rows, Prediction};
use ctr_formats::{
    Clearance, Friction, Gravity, JointOffset, Latency, Precurvature, Recording, Registration,
    SensorOffset, SensorRotation, Stiffness,
};

mod common;

/// A model of the three-tube recording with every effect that moves without solving,
/// beside a clearance (its kinks are in the joint Jacobian), and its rows: every
/// third of the recording, as a fit counts a sample.
fn setting() -> (ModelSpec, Recording, Vec<usize>) {
    let (spec, rec, _) = common::recording("dev-unexplained-feed-gain");
    let n = spec.robot.n_tubes();
    assert_eq!(n, 3, "a three-tube recording");
    let mut m = ModelSpec::from_spec(&spec);
    let e = &mut m.effects;
    e.clearance = Some(Clearance {
        max_deflection_deg: vec![2.0; n - 1],
        peak_deg: vec![200.0; n - 1],
        table_deg: vec![],
    });
    e.joint_offset = Some(JointOffset {
        feed_mm: vec![-0.4, 0.2, 0.3],
        rotation_deg: vec![1.0, -2.0, 3.0],
    });
    e.latency = Some(Latency { tau_s: 0.05 });
    e.friction = Some(Friction {
        rotation_friction_coefficient: vec![],
        rotation_play_deg: vec![1.5, 2.5],
        feed_play_mm: vec![0.0, 0.0, 0.2],
    });
    e.registration = Some(Registration {
        translation_mm: [1.0, -2.0, 0.5],
        rotation_axis: [0.2, 0.3, 1.0],
        rotation_deg: 4.0,
    });
    e.sensor_offset = Some(SensorOffset {
        offset_mm: [0.3, -0.2, 1.5],
    });
    e.sensor_rotation = Some(SensorRotation {
        rotation_vector_deg: [3.0, -2.0, 5.0],
    });
    let rows = (0..rec.rows.len()).step_by(3).collect();
    (m, rec, rows)
}

/// `m` moved by `d` steps of one parameter.
type Step<'a> = Box<dyn Fn(f64) -> ModelSpec + 'a>;

/// The step of `m` that `f` takes (`f(model, d)` moves one parameter by `d` steps).
fn step_of(m: &ModelSpec, f: fn(&mut ModelSpec, f64)) -> Step<'_> {
    Box::new(move |d| {
        let mut moved = m.clone();
        f(&mut moved, d);
        moved
    })
}

/// Steps of one parameter of each effect on the joints or the measurement: the model
/// moved by `+d` and by `-d` of the step.
fn steps(m: &ModelSpec) -> Vec<(&'static str, Step<'_>)> {
    let at = |f| step_of(m, f);
    vec![
        (
            "feed offset of tube 2, mm",
            at(|m, d| m.effects.joint_offset.as_mut().unwrap().feed_mm[1] += 0.01 * d),
        ),
        (
            "rotation offset of tube 3, deg",
            at(|m, d| m.effects.joint_offset.as_mut().unwrap().rotation_deg[2] += 0.05 * d),
        ),
        (
            "latency, s",
            at(|m, d| m.effects.latency.as_mut().unwrap().tau_s += 1e-3 * d),
        ),
        (
            "rotation play of pair 2, deg",
            at(|m, d| m.effects.friction.as_mut().unwrap().rotation_play_deg[1] += 0.05 * d),
        ),
        (
            "feed play of tube 3, mm",
            at(|m, d| m.effects.friction.as_mut().unwrap().feed_play_mm[2] += 0.01 * d),
        ),
        (
            "registration angle, deg",
            at(|m, d| m.effects.registration.as_mut().unwrap().rotation_deg += 0.05 * d),
        ),
        (
            "registration x, mm",
            at(|m, d| m.effects.registration.as_mut().unwrap().translation_mm[0] += 0.01 * d),
        ),
        (
            "sensor offset z, mm",
            at(|m, d| m.effects.sensor_offset.as_mut().unwrap().offset_mm[2] += 0.01 * d),
        ),
        (
            "sensor rotation x, deg",
            at(|m, d| {
                m.effects
                    .sensor_rotation
                    .as_mut()
                    .unwrap()
                    .rotation_vector_deg[0] += 0.05 * d
            }),
        ),
    ]
}

/// Position (mm) and quaternion components of the rows, one vector.
fn flat(p: &Prediction, rows: &[usize]) -> Vec<f64> {
    rows.iter()
        .flat_map(|&r| p.p[r].iter().chain(&p.q[r]).copied().collect::<Vec<_>>())
        .collect()
}

/// The largest difference, mm or quaternion units, between `lin`'s prediction of the
/// model it linearised, `m`, and solving `m` again.
fn at_the_point(lin: &Linearised, m: &ModelSpec, rec: &Recording, rows: &[usize]) -> f64 {
    let near = flat(&lin.predict(m, rec).unwrap().unwrap(), rows);
    let solved = flat(&predict_rows(m, rec, rows).unwrap(), rows);
    near.iter()
        .zip(&solved)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

#[test]
fn at_the_point_linearised_it_is_the_solved_prediction() {
    let (m, rec, rows) = setting();
    let lin = Linearised::new(&m, &rec, &rows, 2)
        .unwrap()
        .expect("unloaded");
    let worst = at_the_point(&lin, &m, &rec, &rows);
    assert!(worst < 1e-9, "{worst} mm or quaternion units apart");
}

/// How far apart the central differences of `step` are, linearised and solved,
/// relative to the solved one's size (which must be more than rounding).
fn apart(
    lin: &Linearised,
    rec: &Recording,
    rows: &[usize],
    step: &dyn Fn(f64) -> ModelSpec,
) -> f64 {
    let (up, down) = (step(1.0), step(-1.0));
    let difference =
        |a: Vec<f64>, b: Vec<f64>| -> Vec<f64> { a.iter().zip(b).map(|(a, b)| a - b).collect() };
    let chain = difference(
        flat(&lin.predict(&up, rec).unwrap().unwrap(), rows),
        flat(&lin.predict(&down, rec).unwrap().unwrap(), rows),
    );
    let solved = difference(
        flat(&predict_rows(&up, rec, rows).unwrap(), rows),
        flat(&predict_rows(&down, rec, rows).unwrap(), rows),
    );
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let size = norm(&solved);
    assert!(size > 1e-9, "the step moves the tips ({size})");
    let gap: Vec<f64> = chain.iter().zip(&solved).map(|(a, b)| a - b).collect();
    norm(&gap) / size
}

/// The relative gap of an exact column: rounding.
const ROUNDING: f64 = 1e-9;
/// The relative gap of a first-order column at a fit's step.
const LINEARISATION: f64 = 1e-2;

/// Every effect's central difference by `lin` is the solved one: the same to first
/// order, at most a part in a hundred at the step a fit takes (the second-order term,
/// and rows that sit on a kink of the model: a feed exactly where a tube's precurved
/// part leaves the next, first-order apart either way); the measurement's exact to
/// rounding.
fn every_effect_as_solved(lin: &Linearised, m: &ModelSpec, rec: &Recording, rows: &[usize]) {
    for (name, step) in steps(m) {
        let gap = apart(lin, rec, rows, &step);
        let bound = if name.starts_with("registration") || name.starts_with("sensor") {
            ROUNDING
        } else {
            LINEARISATION
        };
        assert!(gap <= bound, "{name}: {gap:.2e} apart");
    }
}

#[test]
fn its_central_differences_are_the_solved_ones_for_every_kind_of_effect() {
    let (m, rec, rows) = setting();
    let lin = Linearised::new(&m, &rec, &rows, 2)
        .unwrap()
        .expect("unloaded");
    every_effect_as_solved(&lin, &m, &rec, &rows);
}

#[test]
fn a_change_of_the_mechanics_is_refused() {
    let (m, rec, rows) = setting();
    let lin = Linearised::new(&m, &rec, &rows, 2)
        .unwrap()
        .expect("unloaded");
    let mut stiffer = m.clone();
    stiffer.effects.precurvature = Some(Precurvature {
        radius_factor: vec![1.0, 1.01, 1.0],
    });
    assert!(lin.predict(&stiffer, &rec).unwrap().is_none());
}

#[test]
fn joints_out_of_range_are_an_error_as_a_solve_says() {
    let (m, rec, rows) = setting();
    let lin = Linearised::new(&m, &rec, &rows, 2)
        .unwrap()
        .expect("unloaded");
    let mut behind = m.clone();
    // tube 1 fed 1 m: past its own length on every row
    behind.effects.joint_offset.as_mut().unwrap().feed_mm[0] = 1000.0;
    assert!(lin.predict(&behind, &rec).is_err());
    assert!(predict_rows(&behind, &rec, &rows).is_err());
}

#[test]
fn under_gravity_its_probed_central_differences_are_the_solved_ones() {
    let (mut m, rec, mut rows) = setting();
    // the loaded solver has no clearance kinks
    m.effects.clearance = None;
    m.effects.gravity = Some(Gravity {
        direction_w: [0.0, 0.0, -1.0],
        g_m_s2: 9.81,
    });
    // loaded solves cost more: one row in nine
    rows.retain(|r| r % 9 == 0);
    let lin = Linearised::new(&m, &rec, &rows, 2)
        .unwrap()
        .expect("probed under a load");
    let worst = at_the_point(&lin, &m, &rec, &rows);
    assert!(worst < 1e-9, "at the point: {worst} apart");
    every_effect_as_solved(&lin, &m, &rec, &rows);
}

#[test]
fn a_learned_term_is_not_linearised() {
    let (mut m, rec, rows) = setting();
    m.empirical = Some(ctr_formats::Correction::default());
    assert!(Linearised::new(&m, &rec, &rows, 2).unwrap().is_none());
}

/// The setting with every tube's stiffness and precurvature off their nominal.
fn scaled_setting() -> (ModelSpec, Recording, Vec<usize>) {
    let (mut m, rec, rows) = setting();
    m.effects.stiffness = Some(Stiffness {
        factor: vec![1.0, 0.9, 1.1],
    });
    m.effects.precurvature = Some(Precurvature {
        radius_factor: vec![1.0, 1.05, 0.95],
    });
    (m, rec, rows)
}

/// Steps of a stiffness and a precurvature factor (the model moved by `+d` and `-d`
/// of the step): a fit's natural step.
fn scale_steps(m: &ModelSpec) -> Vec<(&'static str, Step<'_>)> {
    let at = |f| step_of(m, f);
    vec![
        (
            "stiffness factor of tube 2",
            at(|m, d| m.effects.stiffness.as_mut().unwrap().factor[1] += 0.01 * d),
        ),
        (
            "stiffness factor of tube 3",
            at(|m, d| m.effects.stiffness.as_mut().unwrap().factor[2] += 0.01 * d),
        ),
        (
            "radius factor of tube 1",
            at(|m, d| m.effects.precurvature.as_mut().unwrap().radius_factor[0] += 0.01 * d),
        ),
        (
            "radius factor of tube 3",
            at(|m, d| m.effects.precurvature.as_mut().unwrap().radius_factor[2] += 0.01 * d),
        ),
    ]
}

#[test]
fn with_the_scales_their_central_differences_are_the_solved_ones_too() {
    let (m, rec, rows) = scaled_setting();
    let lin = Linearised::moving(&m, &rec, &rows, 2, Moving::Both)
        .unwrap()
        .expect("unloaded");
    let worst = at_the_point(&lin, &m, &rec, &rows);
    assert!(worst < 1e-9, "at the point: {worst} apart");
    every_effect_as_solved(&lin, &m, &rec, &rows);
    for (name, step) in scale_steps(&m) {
        let gap = apart(&lin, &rec, &rows, &step);
        assert!(gap <= LINEARISATION, "{name}: {gap:.2e} apart");
    }
}

#[test]
fn each_way_refuses_what_it_does_not_carry() {
    let (m, rec, rows) = scaled_setting();
    let mut later = m.clone();
    later.effects.latency.as_mut().unwrap().tau_s += 1e-3;
    let mut softer = m.clone();
    softer.effects.stiffness.as_mut().unwrap().factor[1] *= 0.99;
    let mut turned = m.clone();
    turned.effects.registration.as_mut().unwrap().rotation_deg += 0.1;
    for (way, joints, scales) in [
        (Moving::Measurement, false, false),
        (Moving::Joints, true, false),
        (Moving::Scales, false, true),
    ] {
        let lin = Linearised::moving(&m, &rec, &rows, 2, way)
            .unwrap()
            .expect("unloaded");
        let predicts = |model: &ModelSpec| lin.predict(model, &rec).unwrap().is_some();
        assert_eq!(predicts(&later), joints, "{way:?} and a latency");
        assert_eq!(predicts(&softer), scales, "{way:?} and a stiffness");
        // the measurement moves with every way, exactly
        assert!(predicts(&turned), "{way:?} and a registration");
        let turn = step_of(&m, |m, d| {
            m.effects.registration.as_mut().unwrap().rotation_deg += 0.05 * d
        });
        let gap = apart(&lin, &rec, &rows, &turn);
        assert!(gap <= ROUNDING, "{way:?}: the registration {gap:.2e} apart");
    }
}

#[test]
fn where_friction_grows_with_the_contact_moment_the_scales_move_the_joints_too() {
    // the contact moment is the scaled tubes': a softer tube 2 changes the plays, so
    // each row's actual joints, besides its mechanics
    let (mut m, rec, rows) = scaled_setting();
    m.effects
        .friction
        .as_mut()
        .unwrap()
        .rotation_friction_coefficient = vec![0.02, 0.03];
    let lin = Linearised::moving(&m, &rec, &rows, 2, Moving::Scales)
        .unwrap()
        .expect("unloaded");
    let worst = at_the_point(&lin, &m, &rec, &rows);
    assert!(worst < 1e-9, "at the point: {worst} apart");
    for (name, step) in scale_steps(&m) {
        let gap = apart(&lin, &rec, &rows, &step);
        assert!(gap <= LINEARISATION, "{name}: {gap:.2e} apart");
    }
    let both = Linearised::cost_per_row(&m, &rec, &rows, Moving::Both);
    assert_eq!(
        Linearised::cost_per_row(&m, &rec, &rows, Moving::Scales),
        both
    );
}

#[test]
fn under_gravity_the_scales_are_not_linearised() {
    let (mut m, rec, rows) = scaled_setting();
    m.effects.clearance = None;
    m.effects.gravity = Some(Gravity {
        direction_w: [0.0, 0.0, -1.0],
        g_m_s2: 9.81,
    });
    let rows: Vec<usize> = rows.into_iter().filter(|r| r % 9 == 0).collect();
    for way in [Moving::Scales, Moving::Both] {
        assert!(Linearised::cost_per_row(&m, &rec, &rows, way).is_none());
        assert!(Linearised::moving(&m, &rec, &rows, 2, way)
            .unwrap()
            .is_none());
    }
}

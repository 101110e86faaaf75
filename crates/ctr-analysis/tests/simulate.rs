//! The simulator with effects from a robot file reproduces the shared recordings down
//! to their noise floor when given the concealed effect at its true value.

use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_formats::{
    Clearance, Effects, Friction, Gravity, Latency, Recording, Registration, RobotSpec,
};
use serde_json::Value;

mod common;

/// A shared recording, the model of the robot its truth file names, and the truth file.
fn load(id: &str) -> (ModelSpec, Recording, Value) {
    let (spec, rec, truth) = common::recording(id);
    (ModelSpec::from_spec(&spec), rec, truth)
}

fn rms(model: &ModelSpec, rec: &Recording) -> f64 {
    let runs: Vec<usize> = (0..rec.runs.len()).collect();
    let pred = predict(model, rec, &runs).unwrap();
    assert_eq!(pred.failed, 0);
    let sum: f64 = rec
        .rows
        .iter()
        .zip(&pred.p)
        .map(|(r, p)| (0..3).map(|k| (r.p[k] - p[k]).powi(2)).sum::<f64>())
        .sum();
    (sum / rec.rows.len() as f64).sqrt()
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

fn v3(v: &Value) -> [f64; 3] {
    std::array::from_fn(|i| f(&v[i]))
}

/// The truth file's effects in the robot file's terms.
fn truth_effects(truth: &Value, n: usize) -> Effects {
    let e = &truth["world"]["effects"];
    let mut out = Effects::default();
    if let Some(c) = e.get("clearance") {
        out.clearance = Some(Clearance {
            max_deflection_deg: vec![f(&c["delta_max_deg"]); n - 1],
            peak_deg: vec![f(&c["phi0_deg"]); n - 1],
            table_deg: vec![],
        });
    }
    if let Some(c) = e.get("friction") {
        out.friction = Some(Friction {
            rotation_friction_coefficient: vec![],
            rotation_play_deg: vec![f(&c["rotation_play_half_width_deg"]); n - 1],
            feed_play_mm: vec![],
        });
    }
    if let Some(c) = e.get("latency") {
        out.latency = Some(Latency {
            tau_s: f(&c["tau_s"]),
        });
    }
    if let Some(c) = e.get("gravity") {
        out.gravity = Some(Gravity {
            direction_w: v3(&c["direction_W"]),
            g_m_s2: f(&c["g_m_s2"]),
        });
    }
    if let Some(c) = e.get("registration") {
        out.registration = Some(Registration {
            translation_mm: v3(&c["translation_mm"]),
            rotation_axis: v3(&c["rotation_axis"]),
            rotation_deg: f(&c["rotation_deg"]),
        });
    }
    out
}

#[test]
fn true_effects_reach_the_noise_floor() {
    for id in [
        "dev-clean",
        "dev-clearance",
        "dev-friction",
        "dev-gravity",
        "dev-latency",
        "dev-registration",
    ] {
        let (mut model, rec, truth) = load(id);
        let floor = f(&truth["noise_floor_rms_mm"]);
        let without = rms(&model, &rec);
        model.effects = truth_effects(&truth, model.robot.n_tubes());
        let with = rms(&model, &rec);
        eprintln!("{id}: {without:.4} mm without, {with:.4} with, floor {floor:.4}");
        assert!(with <= 1.02 * floor, "{id}");
        if id != "dev-clean" {
            assert!(without > 1.5 * floor, "{id}");
        }
    }
}

/// A recorded tip force is a load, and the loaded mechanics model torsion: on the rigid
/// model the row model refuses it (once it was solved silently with torsion instead),
/// while the torsion model bends the tip by it, against the force.
#[test]
fn a_recorded_force_on_the_rigid_model_is_refused_not_solved_with_torsion() {
    use ctr_analysis::simulate::SimError;
    use ctr_core::{SolveError, Unsupported};
    let spec = RobotSpec::from_toml_str(
        "[[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\nlength_mm = 260.0\n\
         curved_length_mm = 0.0\nyoungs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n",
        "r.toml",
    )
    .unwrap();
    let rec = Recording::read(
        "s1_mm,theta1_deg,x_mm,y_mm,z_mm,fx_n,fy_n,fz_n\n80,0,0,0,80,0.02,0,0\n".as_bytes(),
        "rec.csv",
        1,
    )
    .unwrap();
    let mut model = ModelSpec::from_spec(&spec);
    let pred = predict(&model, &rec, &[0]).unwrap();
    // a straight tube pushed along +x bends toward +x
    assert!(pred.p[0][0] > 0.1, "{:?}", pred.p[0]);
    model.model = ctr_core::Model::Rigid;
    assert_eq!(
        predict(&model, &rec, &[0]),
        Err(SimError::Load {
            row: 0,
            error: SolveError::Unsupported(Unsupported::LoadsOnRigid)
        })
    );
}

/// The runs of a prediction side by side give the same numbers, bit for bit, as one
/// after the other (each run is a time series of its own).
#[test]
fn runs_predicted_side_by_side_are_the_same_as_in_turn() {
    let (model, rec, _) = load("dev-friction");
    assert!(rec.runs.len() > 2, "several runs");
    let rows: Vec<usize> = (0..rec.rows.len()).step_by(2).collect();
    let one = ctr_analysis::simulate::predict_rows_on(&model, &rec, &rows, 1).unwrap();
    let three = ctr_analysis::simulate::predict_rows_on(&model, &rec, &rows, 3).unwrap();
    for &r in &rows {
        assert_eq!(one.p[r], three.p[r], "row {r}");
        assert_eq!(one.q[r], three.q[r], "row {r}");
    }
    assert_eq!(one.failed, three.failed);
}

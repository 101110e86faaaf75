//! The effects follow the conventions of `shared/data/recordings/*.truth.json`: with
//! the concealed effect switched on at its true value the model explains each
//! recording down to its noise floor, and without it the error is far larger.
use ctr_core::effects::{ClearanceProfile, Effects, Registration};
use ctr_core::friction::PlayFriction;
use ctr_core::{Gravity, Joints, Loads, Model, Request, Robot, Solver};
use ctr_suite::serde_json::Value;
use ctr_suite::*;

fn rms(errors: &[f64]) -> f64 {
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt()
}

/// RMS tip error of a model over a recording: `model` maps (row index, commanded joints)
/// to the predicted tip.
fn rms_of<const N: usize>(
    rows: &[RecRow<N>],
    mut model: impl FnMut(usize, &Joints<f64, N>) -> nalgebra::Vector3<f64>,
) -> f64 {
    let e: Vec<f64> = rows
        .iter()
        .enumerate()
        .map(|(i, r)| (model(i, &r.q) - nalgebra::Vector3::from(r.p)).norm())
        .collect();
    rms(&e)
}

fn floor(truth: &Value) -> f64 {
    truth["noise_floor_rms_mm"].as_f64().unwrap()
}

fn plain<const N: usize>(robot: &Robot<f64, N>, rows: &[RecRow<N>]) -> f64 {
    let mut solver = Solver::default();
    rms_of(rows, |_, q| {
        solver
            .solve(robot, Request::new(*q, Model::Torsion))
            .unwrap()
            .tip
            .position
    })
}

fn deg(v: &Value) -> f64 {
    v.as_f64().unwrap().to_radians()
}

#[test]
fn clean_recording_is_at_its_noise_floor() {
    let (rows, truth) = recording::<2>("dev-clean");
    let e = plain(&robot::<2>("nitinol2"), &rows);
    eprintln!("clean: {e:.4} mm vs floor {:.4}", floor(&truth));
    assert!(e <= 1.02 * floor(&truth));
}

#[test]
fn clearance_convention() {
    let (rows, truth) = recording::<2>("dev-clearance");
    let robot = robot::<2>("liu2023");
    let c = &truth["world"]["effects"]["clearance"];
    let mut effects = Effects::default();
    effects.clearance[0] = Some(ClearanceProfile::Cosine {
        max_deflection_rad: deg(&c["delta_max_deg"]),
        peak_rad: deg(&c["phi0_deg"]),
    });
    let mut solver = Solver::default();
    let with = rms_of(&rows, |_, q| {
        solver
            .solve(&robot, Request::new(*q, Model::Torsion).effects(&effects))
            .unwrap()
            .tip
            .position
    });
    let without = plain(&robot, &rows);
    eprintln!(
        "clearance: {with:.4} mm with, {without:.4} without, floor {:.4}",
        floor(&truth)
    );
    assert!(with <= 1.02 * floor(&truth));
    assert!(without > 3.0 * floor(&truth));
}

#[test]
fn registration_convention() {
    let (rows, truth) = recording::<3>("dev-registration");
    let robot = robot::<3>("nitinol3");
    let r = &truth["world"]["effects"]["registration"];
    let v = |x: &Value| -> [f64; 3] { core::array::from_fn(|i| x[i].as_f64().unwrap()) };
    let reg = Registration::from_axis_angle(
        v(&r["rotation_axis"]),
        deg(&r["rotation_deg"]),
        v(&r["translation_mm"]),
    );
    let effects = Effects {
        registration: Some(reg),
        ..Default::default()
    };
    let mut solver = Solver::default();
    let with = rms_of(&rows, |_, q| {
        solver
            .solve(&robot, Request::new(*q, Model::Torsion).effects(&effects))
            .unwrap()
            .tip
            .position
    });
    eprintln!("registration: {with:.4} mm, floor {:.4}", floor(&truth));
    assert!(with <= 1.02 * floor(&truth));
}

#[test]
fn gravity_convention() {
    let (rows, truth) = recording::<2>("dev-gravity");
    let robot = robot::<2>("liu2023");
    let loads = Loads {
        gravity: Some(Gravity::new([-1.0, 0.0, 0.0], 9.81)),
        ..Default::default()
    };
    let mut solver = Solver::default();
    let with = rms_of(&rows, |_, q| {
        solver
            .solve(&robot, Request::new(*q, Model::Torsion).loads(loads))
            .unwrap()
            .tip
            .position
    });
    let without = plain(&robot, &rows);
    eprintln!(
        "gravity: {with:.4} mm with, {without:.4} without, floor {:.4}",
        floor(&truth)
    );
    assert!(with <= 1.02 * floor(&truth));
    assert!(without > 1.5 * floor(&truth));
}

#[test]
fn friction_convention() {
    let (rows, truth) = recording::<2>("dev-friction");
    let robot = robot::<2>("liu2023");
    let w = deg(&truth["world"]["effects"]["friction"]["rotation_play_half_width_deg"]);
    let mut friction = PlayFriction::new([w, 0.0], [0.0; 2]);
    let mut solver = Solver::default();
    let mut run = String::new();
    let with = rms_of(&rows, |i, q| {
        if rows[i].run != run {
            run = rows[i].run.clone();
            friction.reset(q);
        }
        let actual = friction.apply(q);
        solver
            .solve(&robot, Request::new(actual, Model::Torsion))
            .unwrap()
            .tip
            .position
    });
    let without = plain(&robot, &rows);
    eprintln!(
        "friction: {with:.4} mm with, {without:.4} without, floor {:.4}",
        floor(&truth)
    );
    assert!(with <= 1.02 * floor(&truth));
    assert!(without > 3.0 * floor(&truth));
}

//! The effects follow the conventions of `tests/data/shared/recordings/*.truth.json`: with
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

/// RMS tip error over a recording of the solves `request` asks for: it maps (row index,
/// commanded joints) to the request of that row (one warm solver along the rows).
fn rms_of<'a, const N: usize>(
    robot: &Robot<f64, N>,
    rows: &[RecRow<N>],
    mut request: impl FnMut(usize, &Joints<f64, N>) -> Request<'a, f64, N>,
) -> f64 {
    let mut solver = Solver::default();
    let e: Vec<f64> = rows
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let tip = solver.solve(robot, request(i, &r.q)).unwrap().tip.position;
            (tip - nalgebra::Vector3::from(r.p)).norm()
        })
        .collect();
    rms(&e)
}

fn floor(truth: &Value) -> f64 {
    truth["noise_floor_rms_mm"].as_f64().unwrap()
}

fn plain<const N: usize>(robot: &Robot<f64, N>, rows: &[RecRow<N>]) -> f64 {
    rms_of(robot, rows, |_, q| Request::new(*q, Model::Torsion))
}

/// A recording's RMS tip errors and its noise floor, mm.
struct Errors {
    /// With the concealed effect modelled.
    with: f64,
    /// With the plain torsion model.
    without: f64,
    /// The truth file's noise floor.
    floor: f64,
}

/// The errors over a recording with the effect (the requests of `request`, as for
/// [`rms_of`]) and without it, printed under `label`.
fn errors<'a, const N: usize>(
    label: &str,
    robot: &Robot<f64, N>,
    (rows, truth): (&[RecRow<N>], &Value),
    request: impl FnMut(usize, &Joints<f64, N>) -> Request<'a, f64, N>,
) -> Errors {
    let with = rms_of(robot, rows, request);
    let without = plain(robot, rows);
    let floor = floor(truth);
    eprintln!("{label}: {with:.4} mm with, {without:.4} without, floor {floor:.4}");
    Errors {
        with,
        without,
        floor,
    }
}

/// A recording of `tests/data/shared/recordings`, its truth file, and the shared robot `robot`
/// it was made on.
fn load<const N: usize>(id: &str, robot_name: &str) -> (Robot<f64, N>, Vec<RecRow<N>>, Value) {
    let (rows, truth) = recording::<N>(id);
    (robot::<N>(robot_name), rows, truth)
}

fn deg(v: &Value) -> f64 {
    v.as_f64().unwrap().to_radians()
}

#[test]
fn clean_recording_is_at_its_noise_floor() {
    let (robot, rows, truth) = load::<2>("dev-clean", "nitinol2");
    let e = plain(&robot, &rows);
    eprintln!("clean: {e:.4} mm vs floor {:.4}", floor(&truth));
    assert!(e <= 1.02 * floor(&truth));
}

#[test]
fn clearance_convention() {
    let (robot, rows, truth) = load::<2>("dev-clearance", "liu2023");
    let c = &truth["world"]["effects"]["clearance"];
    let mut effects = Effects::default();
    effects.clearance[0] = Some(ClearanceProfile::Cosine {
        max_deflection_rad: deg(&c["delta_max_deg"]),
        peak_rad: deg(&c["phi0_deg"]),
    });
    let e = errors("clearance", &robot, (&rows, &truth), |_, q| {
        Request::new(*q, Model::Torsion).effects(&effects)
    });
    assert!(e.with <= 1.02 * e.floor);
    assert!(e.without > 3.0 * e.floor);
}

#[test]
fn registration_convention() {
    let (robot, rows, truth) = load::<3>("dev-registration", "nitinol3");
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
    let with = rms_of(&robot, &rows, |_, q| {
        Request::new(*q, Model::Torsion).effects(&effects)
    });
    eprintln!("registration: {with:.4} mm, floor {:.4}", floor(&truth));
    assert!(with <= 1.02 * floor(&truth));
}

#[test]
fn gravity_convention() {
    let (robot, rows, truth) = load::<2>("dev-gravity", "liu2023");
    let loads = Loads {
        gravity: Some(Gravity::new([-1.0, 0.0, 0.0], 9.81)),
        ..Default::default()
    };
    let e = errors("gravity", &robot, (&rows, &truth), |_, q| {
        Request::new(*q, Model::Torsion).loads(loads)
    });
    assert!(e.with <= 1.02 * e.floor);
    assert!(e.without > 1.5 * e.floor);
}

#[test]
fn friction_convention() {
    let (robot, rows, truth) = load::<2>("dev-friction", "liu2023");
    let w = deg(&truth["world"]["effects"]["friction"]["rotation_play_half_width_deg"]);
    let mut friction = PlayFriction::new([w, 0.0], [0.0; 2]);
    let mut run = String::new();
    let e = errors("friction", &robot, (&rows, &truth), |i, q| {
        if rows[i].run != run {
            run = rows[i].run.clone();
            friction.reset(q);
        }
        Request::new(friction.apply(q), Model::Torsion)
    });
    assert!(e.with <= 1.02 * e.floor);
    assert!(e.without > 3.0 * e.floor);
}

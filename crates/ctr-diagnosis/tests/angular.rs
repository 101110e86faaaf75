//! The angular columns of a recording in the diagnosis: an orientation shows what the
//! positions cannot, a tangent's noise is estimated from the data, very noisy angles
//! weigh (almost) nothing, and a bad tangent row is refused with its place.

mod common;

use common::angular::{angular_recording, angular_spec, positions_only, SIGMA_MM};
use ctr_analysis::model::ModelSpec;
use ctr_diagnosis::{diagnose, Diagnosis, EffectId, Options};
use ctr_formats::{AngularColumns, JointOffset, Recording, RobotSpec};

/// Noise of the angular columns, degrees per component.
const SIGMA_DEG: f64 = 0.3;
/// A noise estimate must be within this fraction of the noise planted.
const NOISE_WITHIN: f64 = 0.2;
/// The roll offset of the inner (straight) tube: invisible in the positions, deg.
const INNER_ROLL_DEG: f64 = 8.0;
/// A fitted rotation offset must be within this of the planted one, deg.
const OFFSET_WITHIN_DEG: f64 = 1.0;

/// A curved outer tube and a straight inner one: turning the inner tube turns the tip
/// frame about its tangent and moves the tip not at all.
fn user() -> ModelSpec {
    let spec = RobotSpec::from_toml_str(
        "[[tube]]\nouter_diameter_mm = 1.8\ninner_diameter_mm = 1.5\nlength_mm = 180.0\n\
         curved_length_mm = 60.0\ncurvature_radius_mm = 150.0\nyoungs_modulus_mpa = 58000.0\n\
         poisson_ratio = 0.33\n\
         [[tube]]\nouter_diameter_mm = 1.2\ninner_diameter_mm = 0.9\nlength_mm = 260.0\n\
         curved_length_mm = 0.0\nyoungs_modulus_mpa = 58000.0\npoisson_ratio = 0.33\n",
        "straight-inner.toml",
    )
    .unwrap();
    ModelSpec::from_spec(&spec)
}

/// `user` with rotation offsets `rotation_deg` (tube 1 first).
fn with_rotation_offsets(rotation_deg: [f64; 2]) -> ModelSpec {
    let mut m = user();
    m.effects.joint_offset = Some(JointOffset {
        feed_mm: vec![0.0, 0.0],
        rotation_deg: rotation_deg.to_vec(),
    });
    m
}

/// A short seeded recording of `world` measuring `angular` with `sigma_deg`.
fn record(world: &ModelSpec, angular: AngularColumns, sigma_deg: f64, seed: u64) -> Recording {
    angular_recording(world, &angular_spec(seed, angular, sigma_deg))
}

fn found(d: &Diagnosis) -> Vec<EffectId> {
    d.report.findings.iter().map(|f| f.effect).collect()
}

/// The turn of each tube the data see: its rotation offset plus the tracker frame's
/// turn about W's z axis (turning every tube about the insertion axis moves the tip as
/// turning the frame about it does: the data see their sum, and the fit puts their
/// common part in the frame).
fn turns_seen(d: &Diagnosis) -> Vec<f64> {
    let twist = d.fitted.effects.registration.map_or(0.0, |r| {
        let v = nalgebra::Vector3::from(r.rotation_vector_deg()).map(f64::to_radians);
        let q = nalgebra::UnitQuaternion::from_scaled_axis(v);
        (2.0 * q.k.atan2(q.w)).to_degrees()
    });
    rotation_offsets(d).into_iter().map(|o| o + twist).collect()
}

fn rotation_offsets(d: &Diagnosis) -> Vec<f64> {
    d.fitted
        .effects
        .joint_offset
        .as_ref()
        .map_or(vec![0.0, 0.0], |o| o.rotation_deg.clone())
}

/// The noise estimate of the angular columns, degrees (from a diagnosis without
/// candidates: the estimate alone).
fn angular_sigma_deg(rec: &Recording, model: &ModelSpec) -> (String, usize, f64) {
    let opt = Options {
        candidates: vec![],
        ..Options::default()
    };
    let d = diagnose(model, rec, &opt).unwrap();
    let a = d
        .report
        .noise
        .angular
        .expect("the angular columns reported");
    (a.columns, a.components, a.sigma_deg)
}

#[test]
fn an_orientation_shows_a_roll_the_positions_cannot() {
    let world = with_rotation_offsets([0.0, INNER_ROLL_DEG]);
    let rec = record(&world, AngularColumns::Orientation, SIGMA_DEG, 11);
    let opt = Options::default();
    let with = diagnose(&user(), &rec, &opt).unwrap();
    // the inner straight tube's roll is a constant turn of the tip frame about its
    // tangent: a rotation offset of that tube or a sensor turned about the tip's z, which
    // the data cannot tell apart; either is found, the other listed as equal
    let f = &with.report.findings;
    assert_eq!(f.len(), 1, "{}", with.report.summary("rec.csv"));
    let other = match f[0].effect {
        EffectId::JointOffset => EffectId::SensorRotation,
        EffectId::SensorRotation => EffectId::JointOffset,
        e => panic!("{} found: {}", e.as_str(), with.report.summary("rec.csv")),
    };
    assert!(
        f[0].equally_explained_by.iter().any(|a| a.effect == other),
        "{}",
        with.report.summary("rec.csv")
    );
    let roll = match f[0].effect {
        EffectId::JointOffset => turns_seen(&with)[1] - turns_seen(&with)[0],
        _ => {
            with.fitted
                .effects
                .sensor_rotation
                .unwrap()
                .rotation_vector_deg[2]
        }
    };
    eprintln!("with orientations: {:?}, roll {roll}", found(&with));
    assert!(
        (roll - INNER_ROLL_DEG).abs() < OFFSET_WITHIN_DEG,
        "inner roll {roll} deg"
    );
    assert!(with.report.explained);
    let a = with.report.noise.angular.as_ref().unwrap();
    assert_eq!((a.columns.as_str(), a.components), ("qw,qx,qy,qz", 3));
    // the same rows without their orientations: the roll leaves no trace
    let without = diagnose(&user(), &positions_only(&rec), &opt).unwrap();
    assert!(
        !found(&without).contains(&EffectId::JointOffset),
        "{}",
        without.report.summary("rec.csv")
    );
    assert!(without.report.noise.angular.is_none());
    eprintln!("without: {:?}", found(&without));
}

#[test]
fn the_noise_of_a_tangent_and_of_an_orientation_is_estimated_from_the_data() {
    let world = user();
    for (columns, names, components, seed) in [
        (AngularColumns::Tangent, "tx,ty,tz", 2, 5),
        (AngularColumns::Orientation, "qw,qx,qy,qz", 3, 6),
    ] {
        let rec = record(&world, columns, SIGMA_DEG, seed);
        let (cols, k, sigma) = angular_sigma_deg(&rec, &world);
        eprintln!("{names}: estimated {sigma} deg, planted {SIGMA_DEG}");
        assert_eq!((cols.as_str(), k), (names, components));
        assert!(
            (sigma / SIGMA_DEG - 1.0).abs() < NOISE_WITHIN,
            "{names}: estimated {sigma} deg, planted {SIGMA_DEG}"
        );
    }
}

#[test]
fn very_noisy_angles_weigh_almost_nothing() {
    /// Angular noise far above what the positions tell, deg per component.
    const NOISY_DEG: f64 = 15.0;
    /// A rotation offset of the curved outer tube: plain in the positions, deg.
    const OUTER_DEG: f64 = 5.0;
    let world = with_rotation_offsets([OUTER_DEG, 0.0]);
    let rec = record(&world, AngularColumns::Tangent, NOISY_DEG, 21);
    let opt = Options::default();
    let with = diagnose(&user(), &rec, &opt).unwrap();
    let without = diagnose(&user(), &positions_only(&rec), &opt).unwrap();
    // with a straight inner tube, turning the outer one turns the whole robot about
    // its axis: a rotation offset, or the tracker's frame turned about that axis with
    // the offset named as equal
    for d in [&with, &without] {
        let f = &d.report.findings;
        let one_of = match f.as_slice() {
            [f] if f.effect == EffectId::JointOffset => true,
            [f] if f.effect == EffectId::Registration => f
                .equally_explained_by
                .iter()
                .any(|a| a.effect == EffectId::JointOffset),
            _ => false,
        };
        assert!(one_of, "{}", d.report.summary("rec.csv"));
    }
    assert_eq!(found(&with), found(&without));
    let (a, b) = (turns_seen(&with)[0], turns_seen(&without)[0]);
    eprintln!(
        "noisy tangents: {a} deg with, {b} without; {:?}",
        with.report.noise.angular
    );
    assert!(
        (a - OUTER_DEG).abs() < OFFSET_WITHIN_DEG,
        "with tangents {a} deg"
    );
    assert!((b - OUTER_DEG).abs() < OFFSET_WITHIN_DEG, "without {b} deg");
    assert_eq!(with.report.explained, without.report.explained);
    // the weight follows the noise: a degree counts as little
    let ang = with.report.noise.angular.as_ref().unwrap();
    assert!(
        (ang.sigma_deg / NOISY_DEG - 1.0).abs() < NOISE_WITHIN,
        "estimated {} deg, planted {NOISY_DEG}",
        ang.sigma_deg
    );
    assert!(
        ang.mm_per_deg < 2.0 * SIGMA_MM / NOISY_DEG,
        "{}",
        ang.mm_per_deg
    );
}

#[test]
fn a_tangent_that_is_not_unit_is_refused_with_its_place() {
    let head = "run,s1_mm,theta1_deg,x_mm,y_mm,z_mm,tx,ty,tz\n";
    let ok = Recording::read(
        format!("{head}a,10,0,0,0,10,0,0,1\na,11,0,0,0,11,0.6,0,0.8\n").as_bytes(),
        "rec.csv",
        1,
    )
    .unwrap();
    assert_eq!(ok.rows[1].tangent, Some([0.6, 0.0, 0.8]));
    assert_eq!(ok.angular_columns(), Some(AngularColumns::Tangent));
    let bad = format!("{head}a,10,0,0,0,10,0,0,1\na,11,0,0,0,11,0,0.5,1\n");
    let e = Recording::read(bad.as_bytes(), "rec.csv", 1).unwrap_err();
    assert_eq!(
        e.to_string(),
        "rec.csv:3: tx,ty,tz = 0, 0.5, 1 has norm 1.118033988749895: expected a unit tangent \
         (norm 1 within 1e-3)"
    );
    let nan = format!("{head}a,10,0,0,0,10,0,nan,1\n");
    let e = Recording::read(nan.as_bytes(), "rec.csv", 1).unwrap_err();
    assert_eq!(
        e.to_string(),
        "rec.csv:2: column ty: \"nan\" is not a finite number"
    );
    let partial = "s1_mm,theta1_deg,x_mm,y_mm,z_mm,tx,tz\n10,0,0,0,10,0,1\n";
    let e = Recording::read(partial.as_bytes(), "rec.csv", 1).unwrap_err();
    assert_eq!(
        e.to_string(),
        "rec.csv:1: missing column ty (the header needs tx,ty,tz)"
    );
}

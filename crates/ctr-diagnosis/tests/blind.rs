//! The diagnosis run blind on generated recordings ([`ctr_diagnosis::synth`]): the world
//! is the project's own model of a shared robot with effects switched on, the user's
//! model is the robot file's plain torsion model (the rigid model where torsion is
//! concealed). Each case asserts that the findings are exactly the concealed effects
//! (as a set: the order is the diagnosis's) and that the held-out RMS after fitting is
//! at most 1.25 x the noise floor, the RMS of the noise actually added to the inlier
//! rows. With outliers, the held-out RMS is taken over the held-out inlier rows (the
//! outliers' jumps are not a model's to explain).
//!
//! Magnitudes are the realistic ones of the issue: clearance 2-3 deg, friction play
//! 3-8 deg, registration a few mm and 1-3 deg, joint offsets 1 mm and 5 deg, stiffness
//! factors 0.7-1.4, radius factors 0.85-1.15, latency 0.2-0.8 s, sensor offsets 2-5 mm,
//! gravity on liu2023 (the one robot that sags measurably; tracker noise 0.05 mm there,
//! as in the shared gravity recording). Run in release:
//! `cargo test -p ctr-diagnosis --release --test blind -- --nocapture`.
//!
//! `CTR_SYNTH_OUT=DIR` also writes every generated recording to `DIR/<case>.csv` (for
//! `ctr-cli diagnose` and `scripts/bench_diagnose.sh`).

mod common;

use common::coverage::{Tally, HALF_WIDTH_FLOOR};
use common::{print_trials, public_ids, public_truth, robot, shared};
use ctr_analysis::model::ModelSpec;
use ctr_analysis::simulate::predict;
use ctr_core::Model;
use ctr_diagnosis::synth::{generate, write_csv, Ranges, SynthSpec, Unmodelled};
use ctr_diagnosis::{diagnose, split, Options};
use ctr_formats::{
    Clearance, Effects, Friction, Gravity, JointOffset, Latency, Precurvature, Registration,
    RobotSpec, SensorOffset, Stiffness,
};
use std::path::PathBuf;

/// Tolerance on the held-out RMS after fitting, as a multiple of the noise floor.
const FLOOR_TOLERANCE: f64 = 1.25;
/// Largest share of rows without a planted outlier that may be flagged as outliers.
const MAX_FALSE_OUTLIER_SHARE: f64 = 0.02;
/// Tracker noise for the gravity cases, mm per axis (the sag is a fraction of a mm).
const GRAVITY_NOISE_SIGMA_MM: f64 = 0.05;
/// Rotation step of the rotation runs for three tubes, degrees (three rotation runs:
/// about 1,000 rows in all, as for two tubes at the default 3 degrees).
const THREE_TUBE_ROTATION_STEP_DEG: f64 = 4.0;
/// Random-walk rows for three tubes.
const THREE_TUBE_WALK_ROWS: usize = 250;

/// One blind case: the world and the measurement.
struct Case {
    name: &'static str,
    robot: &'static str,
    /// Torsion concealed: the world is the torsion model, the user's the rigid one.
    torsion: bool,
    effects: Effects,
    seed: u64,
    noise_sigma_mm: f64,
    outlier_fraction: f64,
    /// Effects outside the vocabulary: the report must not name them as any effect of
    /// the vocabulary, and must say `explained: false`.
    unmodelled: Vec<Unmodelled>,
    /// A concealed effect of the vocabulary may go unnamed (the report incomplete, not
    /// false): the findings must be among the truth's, not all of them.
    may_miss: bool,
}

impl Case {
    fn new(name: &'static str, robot: &'static str, seed: u64) -> Self {
        Case {
            name,
            robot,
            torsion: false,
            effects: Effects::default(),
            seed,
            noise_sigma_mm: SynthSpec::default().noise_sigma_mm,
            outlier_fraction: 0.0,
            unmodelled: Vec::new(),
            may_miss: false,
        }
    }

    fn may_miss(mut self) -> Self {
        self.may_miss = true;
        self
    }

    fn unmodelled(mut self, u: Unmodelled) -> Self {
        self.unmodelled.push(u);
        self
    }

    fn effects(mut self, effects: Effects) -> Self {
        self.effects = effects;
        self
    }

    fn torsion(mut self) -> Self {
        self.torsion = true;
        self
    }

    fn sigma(mut self, sigma_mm: f64) -> Self {
        self.noise_sigma_mm = sigma_mm;
        self
    }

    fn outliers(mut self, fraction: f64) -> Self {
        self.outlier_fraction = fraction;
        self
    }

    fn expected(&self) -> Vec<&'static str> {
        let mut e = self.effects.present();
        if self.torsion {
            e.push("torsion");
        }
        e.sort_unstable();
        e
    }
}

/// A shared robot and its stable ranges (`tests/data/shared/manifest.json`).
fn robot_and_ranges(name: &str) -> (RobotSpec, Ranges) {
    let manifest = std::fs::read_to_string(shared().join("manifest.json")).unwrap();
    (robot(name), Ranges::from_manifest(&manifest, name).unwrap())
}

/// The measurement of a case: the shared recordings' sampling, about 1,000 rows.
fn synth_spec(case: &Case, n_tubes: usize) -> SynthSpec {
    let default = SynthSpec::default();
    let three = n_tubes >= 3;
    SynthSpec {
        seed: case.seed,
        noise_sigma_mm: case.noise_sigma_mm,
        outlier_fraction: case.outlier_fraction,
        rotation_step_deg: if three {
            THREE_TUBE_ROTATION_STEP_DEG
        } else {
            default.rotation_step_deg
        },
        walk_rows: if three {
            THREE_TUBE_WALK_ROWS
        } else {
            default.walk_rows
        },
        file: format!("{}.csv", case.name),
        unmodelled: case.unmodelled.clone(),
        ..default
    }
}

/// The user's model of a case and the recording its world generates.
fn generated(case: &Case) -> (ModelSpec, ctr_diagnosis::synth::Synthetic) {
    let (spec, ranges) = robot_and_ranges(case.robot);
    let user = ModelSpec {
        robot: spec.robot,
        model: if case.torsion {
            Model::Rigid
        } else {
            Model::Torsion
        },
        effects: Effects::default(),
        empirical: None,
        discrepancy: None,
    };
    let world = ModelSpec {
        robot: spec.robot,
        model: Model::Torsion,
        effects: case.effects.clone(),
        empirical: None,
        discrepancy: None,
    };
    let gen = generate(&world, &ranges, &synth_spec(case, spec.robot.n_tubes())).unwrap();
    assert_eq!(gen.failed, 0, "{}: the world's solves converge", case.name);
    (user, gen)
}

/// Diagnoses `case` blind and checks the report (module doc); returns whether it named
/// every concealed effect of the vocabulary (always, unless [`Case::may_miss`]).
fn run(case: Case) -> bool {
    let started = std::time::Instant::now();
    let (user, gen) = generated(&case);
    let rec = &gen.recording;
    if let Some(dir) = std::env::var_os("CTR_SYNTH_OUT") {
        let path = PathBuf::from(dir).join(format!("{}.csv", case.name));
        write_csv(rec, std::fs::File::create(&path).unwrap()).unwrap();
    }
    let floor = gen.noise_floor_rms_mm();
    // what the concealed physics moves the tip by (user model vs the noiseless world)
    let all: Vec<usize> = (0..rec.runs.len()).collect();
    let user_p = predict(&user, rec, &all).unwrap().p;
    let magnitude = (user_p
        .iter()
        .zip(&gen.clean)
        .map(|(a, b)| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / rec.rows.len() as f64)
        .sqrt();

    let gen_time = started.elapsed();
    let d = diagnose(&user, rec, &Options::default()).unwrap();
    let r = &d.report;
    // the established findings are the answer; predictive ones may stand in for what
    // lies outside the vocabulary, but never for what is not there in a recording the
    // vocabulary explains
    let mut found: Vec<&str> = r.established().map(|f| f.effect.as_str()).collect();
    let order = found.join(", ");
    found.sort_unstable();
    let expected = case.expected();
    let predictive: Vec<&str> = r
        .findings
        .iter()
        .filter(|f| f.grade == ctr_diagnosis::Grade::Predictive)
        .map(|f| f.effect.as_str())
        .collect();

    // held-out RMS of the fitted model over the held-out inlier rows
    let (held, _) = split(rec, &Options::default().holdout).unwrap();
    let fitted_p = predict(&d.fitted, rec, &all).unwrap().p;
    let (mut sum, mut count) = (0.0, 0usize);
    for (i, row) in rec.rows.iter().enumerate() {
        if held[i] && gen.outlier_rows.binary_search(&i).is_err() {
            sum += (0..3)
                .map(|k| (fitted_p[i][k] - row.p[k]).powi(2))
                .sum::<f64>();
            count += 1;
        }
    }
    let final_heldout = if gen.outlier_rows.is_empty() {
        r.final_.heldout_rms_mm
    } else {
        (sum / count as f64).sqrt()
    };
    let outside = !case.unmodelled.is_empty();
    let predictive_in_truth = outside || predictive.iter().all(|f| expected.contains(f));
    let false_outliers = r
        .outlier_lines
        .iter()
        .filter(|line| {
            !gen.outlier_rows
                .iter()
                .any(|&row| rec.rows[row].line == **line)
        })
        .count();
    let complete = found == expected;
    let among_truth = found.iter().all(|f| expected.contains(f));
    let ok = (complete || (case.may_miss && among_truth))
        && predictive_in_truth
        && r.explained != outside
        && (outside || final_heldout <= FLOOR_TOLERANCE * floor)
        && false_outliers as f64 <= MAX_FALSE_OUTLIER_SHARE * rec.rows.len() as f64;
    eprintln!(
        "{} [{}] {}: truth {} {} {:?} -> found [{order}], explained {}; {} rows, {} outliers ({false_outliers} flagged not planted); effect {magnitude:.3} mm; \
         baseline held-out {:.3} -> final held-out {final_heldout:.3} (report {:.3}), floor {floor:.3} \
         (ratio {:.2}), noise est {:.3}; {:.1} s (generation {:.1} s)",
        if ok { "PASS" } else { "FAIL" },
        case.name,
        case.robot,
        if case.torsion { "torsion +" } else { "" },
        serde_json::to_string(&case.effects).unwrap(),
        case.unmodelled,
        r.explained,
        rec.rows.len(),
        gen.outlier_rows.len(),
        r.baseline.heldout_rms_mm,
        r.final_.heldout_rms_mm,
        final_heldout / floor,
        r.noise.rms_mm,
        started.elapsed().as_secs_f64(),
        gen_time.as_secs_f64(),
    );
    for f in &r.findings {
        eprintln!(
            "   found {} ({}): {}",
            f.effect.as_str(),
            f.grade.as_str(),
            f.parameters
        );
    }
    if !ok || std::env::var_os("CTR_BLIND_VERBOSE").is_some() {
        print_trials(r);
        eprintln!("   {}", r.unexplained);
    }
    if case.may_miss {
        assert!(
            among_truth,
            "{}: {found:?} not among {expected:?}",
            case.name
        );
    } else {
        assert_eq!(found, expected, "{}: findings", case.name);
    }
    assert!(
        predictive_in_truth,
        "{}: predictive {predictive:?} where the vocabulary explains the recording ({expected:?})",
        case.name
    );
    assert_eq!(r.explained, !outside, "{}: explained", case.name);
    let astray = common::coverage::intervals_not_holding_their_values(r);
    assert!(astray.is_empty(), "{}: {astray:?}", case.name);
    assert!(
        false_outliers as f64 <= MAX_FALSE_OUTLIER_SHARE * rec.rows.len() as f64,
        "{}: {false_outliers} rows flagged as outliers that were not planted",
        case.name
    );
    if outside {
        return complete;
    }
    assert!(
        final_heldout <= FLOOR_TOLERANCE * floor,
        "{}: held-out RMS {final_heldout:.4} above {FLOOR_TOLERANCE} x floor {floor:.4}",
        case.name
    );
    complete
}

fn joint_offset(n: usize, tube: usize, feed_mm: f64, rotation_deg: f64) -> JointOffset {
    let mut o = JointOffset {
        feed_mm: vec![0.0; n],
        rotation_deg: vec![0.0; n],
    };
    o.feed_mm[tube] = feed_mm;
    o.rotation_deg[tube] = rotation_deg;
    o
}

fn factors(n: usize, tube: usize, factor: f64) -> Vec<f64> {
    let mut f = vec![1.0; n];
    f[tube] = factor;
    f
}

fn clearance(max_deg: &[f64], peak_deg: &[f64]) -> Clearance {
    Clearance {
        max_deflection_deg: max_deg.to_vec(),
        peak_deg: peak_deg.to_vec(),
        table_deg: Vec::new(),
    }
}

fn friction(play_deg: &[f64]) -> Friction {
    Friction {
        rotation_friction_coefficient: vec![],
        rotation_play_deg: play_deg.to_vec(),
        feed_play_mm: Vec::new(),
    }
}

fn registration(rotation_vector_deg: [f64; 3], translation_mm: [f64; 3]) -> Registration {
    Registration::from_rotation_vector(rotation_vector_deg, translation_mm)
}

/// One `#[test]` a blind case, named as the test: `name: "robot", seed N` (and the
/// [`Case`] builders `torsion()`, `sigma(mm)`, `outliers(fraction)`), then the concealed
/// effects in braces as `effect: value` (each a field of [`Effects`]).
macro_rules! blind_tests {
    ($(
        $(#[$attr:meta])*
        $name:ident: $robot:literal, seed $seed:literal $(, $builder:ident($($arg:expr)?))*
            $({ $($effect:ident: $value:expr),* $(,)? })?;
    )*) => {
        $(
            $(#[$attr])*
            #[test]
            fn $name() {
                run(Case::new(stringify!($name), $robot, $seed)
                    $(.$builder($($arg)?))*
                    .effects(Effects {
                        $($($effect: Some($value),)*)?
                        ..Default::default()
                    }));
            }
        )*
    };
}

blind_tests! {
    // ---- clean recordings: no findings allowed ----
    clean_liu2023: "liu2023", seed 11;
    clean_nitinol2: "nitinol2", seed 12;
    clean_nitinol3: "nitinol3", seed 13;

    // ---- each effect alone ----
    torsion_nitinol2: "nitinol2", seed 21, torsion();
    torsion_nitinol3: "nitinol3", seed 22, torsion();
    friction_liu2023: "liu2023", seed 23 { friction: friction(&[5.0]) };
    friction_nitinol3: "nitinol3", seed 24 { friction: friction(&[3.0, 6.0]) };
    // the seed's friction: the plays grow with the contact moment (no constant part)
    contact_friction_nitinol3: "nitinol3", seed 60 {
        friction: Friction {
            rotation_friction_coefficient: vec![0.02, 0.03],
            ..Friction::default()
        },
    };
    contact_friction_liu2023: "liu2023", seed 61 {
        friction: Friction {
            rotation_friction_coefficient: vec![0.03],
            rotation_play_deg: vec![1.0],
            ..Friction::default()
        },
    };
    clearance_nitinol2: "nitinol2", seed 25 { clearance: clearance(&[2.5], &[60.0]) };
    clearance_liu2023: "liu2023", seed 26 { clearance: clearance(&[2.0], &[300.0]) };
    gravity_liu2023: "liu2023", seed 27, sigma(GRAVITY_NOISE_SIGMA_MM) {
        gravity: Gravity { direction_w: [0.0, -1.0, 0.0], g_m_s2: 9.81 },
    };
    registration_nitinol2: "nitinol2", seed 28 {
        registration: registration([0.4, 1.8, 0.3], [2.0, -3.0, 1.5]),
    };
    registration_nitinol3: "nitinol3", seed 29 {
        registration: registration([-1.0, 0.5, 2.5], [-1.0, 4.0, -2.0]),
    };
    joint_offset_liu2023: "liu2023", seed 30 { joint_offset: joint_offset(2, 1, 1.0, 5.0) };
    joint_offset_nitinol3: "nitinol3", seed 31 { joint_offset: joint_offset(3, 1, -1.0, 5.0) };
    stiffness_nitinol2: "nitinol2", seed 32 {
        stiffness: Stiffness { factor: factors(2, 1, 0.75) },
    };
    stiffness_nitinol3: "nitinol3", seed 33 {
        stiffness: Stiffness { factor: factors(3, 0, 1.35) },
    };
    precurvature_liu2023: "liu2023", seed 34 {
        precurvature: Precurvature { radius_factor: factors(2, 1, 1.12) },
    };
    precurvature_nitinol3: "nitinol3", seed 35 {
        precurvature: Precurvature { radius_factor: factors(3, 1, 0.88) },
    };
    latency_nitinol2: "nitinol2", seed 36 { latency: Latency { tau_s: 0.4 } };
    latency_nitinol3: "nitinol3", seed 37 { latency: Latency { tau_s: 0.7 } };
    sensor_offset_nitinol2: "nitinol2", seed 38 {
        sensor_offset: SensorOffset { offset_mm: [0.0, 1.5, -3.0] },
    };
    sensor_offset_liu2023: "liu2023", seed 39 {
        sensor_offset: SensorOffset { offset_mm: [2.0, 0.0, -4.0] },
    };

    // ---- pairs, the confusable ones above all ----
    latency_friction_liu2023: "liu2023", seed 41 {
        latency: Latency { tau_s: 0.3 },
        friction: friction(&[5.0]),
    };
    latency_friction_nitinol2: "nitinol2", seed 42 {
        latency: Latency { tau_s: 0.6 },
        friction: friction(&[3.0]),
    };
    registration_joint_offset_nitinol2: "nitinol2", seed 43 {
        registration: registration([0.0, 1.0, 2.0], [3.0, 1.0, -2.0]),
        joint_offset: joint_offset(2, 1, 1.0, 5.0),
    };
    registration_joint_offset_nitinol3: "nitinol3", seed 44 {
        registration: registration([1.5, 0.0, -1.5], [-2.0, 2.0, 3.0]),
        joint_offset: joint_offset(3, 2, 1.0, -5.0),
    };
    // the outer tube's rotation offset turns the whole robot except the inner tube's
    // relative angle: closest to the registration's rotation about z
    registration_joint_offset_outer_liu2023: "liu2023", seed 50 {
        registration: registration([0.5, 0.0, 2.0], [-2.0, 1.0, 2.0]),
        joint_offset: joint_offset(2, 0, 1.0, 5.0),
    };
    stiffness_precurvature_nitinol2: "nitinol2", seed 45 {
        stiffness: Stiffness { factor: factors(2, 1, 1.3) },
        precurvature: Precurvature { radius_factor: factors(2, 0, 0.9) },
    };
    stiffness_precurvature_liu2023: "liu2023", seed 46 {
        stiffness: Stiffness { factor: factors(2, 0, 0.75) },
        precurvature: Precurvature { radius_factor: factors(2, 1, 1.1) },
    };
    clearance_latency_nitinol2: "nitinol2", seed 47 {
        clearance: clearance(&[3.0], &[150.0]),
        latency: Latency { tau_s: 0.5 },
    };
    gravity_registration_liu2023: "liu2023", seed 48, sigma(GRAVITY_NOISE_SIGMA_MM) {
        gravity: Gravity { direction_w: [-1.0, 0.0, 0.0], g_m_s2: 9.81 },
        registration: registration([0.0, 0.0, 1.5], [1.0, 2.0, 0.0]),
    };
    torsion_sensor_offset_nitinol3: "nitinol3", seed 49, torsion() {
        sensor_offset: SensorOffset { offset_mm: [1.0, -1.0, -3.0] },
    };

    // ---- outliers: 1 % of the rows jump by 5 mm; the findings must not change ----
    outliers_clean_nitinol2: "nitinol2", seed 51, outliers(0.01);
    outliers_clearance_liu2023: "liu2023", seed 52, outliers(0.01) {
        clearance: clearance(&[2.5], &[205.0]),
    };
    outliers_latency_friction_nitinol3: "nitinol3", seed 53, outliers(0.01) {
        latency: Latency { tau_s: 0.25 },
        friction: friction(&[4.0, 4.0]),
    };

    // ---- effects outside the vocabulary, alone and with effects of it: the findings
    // are only the in-vocabulary ones and `explained` is false ----
    feed_gain_nitinol3: "nitinol3", seed 61,
        unmodelled(Unmodelled::FeedGain { tube: 2, gain: 0.94 });
    feed_gain_liu2023: "liu2023", seed 62,
        unmodelled(Unmodelled::FeedGain { tube: 1, gain: 1.05 });
    rotation_gain_nitinol2: "nitinol2", seed 63,
        unmodelled(Unmodelled::RotationGain { tube: 1, gain: 1.06 });
    gear_runout_nitinol3: "nitinol3", seed 64,
        unmodelled(Unmodelled::GearRunout { tube: 2, amplitude_deg: 8.0, phase_deg: 30.0 });
    tracker_drift_nitinol2: "nitinol2", seed 65,
        unmodelled(Unmodelled::TrackerDrift { velocity_mm_s: [0.004, -0.003, 0.002] });
    tracker_scale_liu2023: "liu2023", seed 66,
        unmodelled(Unmodelled::TrackerScale { scale_error: [0.01, -0.008, 0.006] });
    friction_drift_liu2023: "liu2023", seed 67,
        unmodelled(Unmodelled::TrackerDrift { velocity_mm_s: [-0.003, 0.004, 0.0] }) {
        friction: friction(&[6.0]),
    };
    latency_feed_gain_nitinol2: "nitinol2", seed 68,
        unmodelled(Unmodelled::FeedGain { tube: 1, gain: 1.06 }) {
        latency: Latency { tau_s: 0.5 },
    };
    tracker_wander_nitinol2: "nitinol2", seed 70,
        unmodelled(Unmodelled::TrackerWander { rms_mm: 0.6, period_s: 40.0, seed: 7 });
    tracker_wander_latency_nitinol3: "nitinol3", seed 71,
        unmodelled(Unmodelled::TrackerWander { rms_mm: 0.6, period_s: 40.0, seed: 8 }) {
        latency: Latency { tau_s: 0.4 },
    };
    // With a registration, a once-per-turn gear error (periodic in a joint's own angle
    // along that joint's direction) is shared by joint_offset, gravity and stiffness,
    // and each passes every check of `verify`; they stay predictive: the rotation
    // offsets are identified only with the registration's rotation (their own intervals
    // a whole turn, the sums holding 0), and a stiffness factor and gravity sit on the
    // bounds of their fit (a factor e^-2 beside gravity at 30 m/s^2 per axis).
    // The registration, the tracker's frame, stays in the model (solved in every fit)
    // but may go unnamed as established: with the runout left, its parameters fit the
    // data better proportional to the tip's z than constant.
    registration_runout_nitinol2: "nitinol2", seed 69, may_miss(),
        unmodelled(Unmodelled::GearRunout { tube: 1, amplitude_deg: 5.0, phase_deg: -60.0 }) {
        registration: registration([0.5, -1.2, 0.4], [1.5, 2.0, -1.0]),
    };
}

// ---- the generator itself ----

#[test]
fn generated_recording_round_trips_through_csv() {
    let (spec, ranges) = robot_and_ranges("nitinol3");
    let case = Case::new("round_trip", "nitinol3", 5).outliers(0.01);
    let world = ModelSpec {
        robot: spec.robot,
        model: Model::Torsion,
        effects: Effects {
            latency: Some(Latency { tau_s: 0.3 }),
            ..Default::default()
        },
        empirical: None,
        discrepancy: None,
    };
    let synth = synth_spec(&case, 3);
    let a = generate(&world, &ranges, &synth).unwrap();
    let b = generate(&world, &ranges, &synth).unwrap();
    assert_eq!(a, b, "a seed fixes the recording");
    let rows = a.recording.rows.len();
    assert!((600..=1100).contains(&rows), "{rows} rows");
    assert_eq!(a.outlier_rows.len(), (0.01 * rows as f64).round() as usize);
    let labels: Vec<&str> = a.recording.runs.iter().map(|r| r.label.as_str()).collect();
    assert_eq!(
        labels,
        [
            "feed",
            "feed-b",
            "rot-outer",
            "rot-middle",
            "rot-inner",
            "scatter"
        ]
    );
    let mut csv = Vec::new();
    write_csv(&a.recording, &mut csv).unwrap();
    let back = ctr_formats::Recording::read(csv.as_slice(), &synth.file, 3).unwrap();
    assert_eq!(back, a.recording);
}

/// Number of seeded recordings of [`effects_outside_the_vocabulary_over_seeds`].
const OUTSIDE_SEEDS: u64 = 12;

/// Seeds of [`effects_outside_the_vocabulary_over_seeds`] whose concealed effect of the
/// vocabulary must be named: what the method reaches today (9 of 12), held as a floor.
const OUTSIDE_COMPLETE_AT_LEAST: usize = 9;

/// Effects outside the vocabulary over many seeds: the kind (feed gain, rotation gain,
/// gear runout, tracker drift, tracker scale), its size, the robot and whether an effect
/// of the vocabulary (friction, latency or clearance) acts beside it are all drawn from
/// the seed. Every case must name no effect the truth lacks (no false finding), say
/// `explained: false` and flag at most 2 % of the rows as outliers (issue 14's done-when);
/// and at least [`OUTSIDE_COMPLETE_AT_LEAST`] must name the concealed effect of the
/// vocabulary as well (complete).
///
/// Measured: 12 of 12 without a false finding and with `explained: false`; 9 of 12
/// complete. The two tracker-scale cases that a sensor offset along the tip took (and
/// called explained) now fail that offset in `verify` (at the noise it must beat a
/// generic correction with the tip position's stretches and shears). Three clearances
/// of 2.5 deg beside a larger error outside the vocabulary (a drift, seed 0; a gear
/// runout, seed 10; a feed gain, seed 11) go unnamed: the search finds each, but once
/// the proxies of the other error are removed the clearance is refitted alone, soaks up
/// part of that error, and fails a check (proportional to a feed rather than constant;
/// no better than a generic correction). The report then names nothing, which is not
/// false, only incomplete. About 3 minutes in release; `CTR_SEEDS=0,10` runs only
/// those seeds (and skips the completeness count).
#[test]
fn effects_outside_the_vocabulary_over_seeds() {
    use ctr_analysis::rng::Rng;
    let (mut failed, mut incomplete, mut complete) = (Vec::new(), Vec::new(), 0);
    let only: Option<Vec<u64>> = std::env::var("CTR_SEEDS")
        .ok()
        .map(|v| v.split(',').map(|s| s.parse().unwrap()).collect());
    for seed in 0..OUTSIDE_SEEDS {
        let mut rng = Rng::new(1000 + seed);
        let robot = ["liu2023", "nitinol2", "nitinol3"][rng.below(3)];
        let n = robot_and_ranges(robot).0.robot.n_tubes();
        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
        let _unused_draw = rng.below(n); // kept: the seeds' cases stay the same
        let u = rng.uniform();
        let unmodelled = match rng.below(5) {
            0 => Unmodelled::FeedGain {
                tube: n - 1,
                gain: 1.0 + sign * (0.04 + 0.04 * u),
            },
            1 => Unmodelled::RotationGain {
                tube: n - 1,
                gain: 1.0 + sign * (0.05 + 0.05 * u),
            },
            2 => Unmodelled::GearRunout {
                tube: n - 1,
                amplitude_deg: 8.0 + 4.0 * u,
                phase_deg: 360.0 * rng.uniform(),
            },
            3 => {
                let d = rng.unit_vector();
                Unmodelled::TrackerDrift {
                    velocity_mm_s: d.map(|v| v * (0.004 + 0.004 * u)),
                }
            }
            _ => Unmodelled::TrackerScale {
                scale_error: [0.0; 3].map(|_: f64| sign * (0.006 + 0.006 * rng.uniform())),
            },
        };
        let mut effects = Effects::default();
        if rng.uniform() < 0.5 {
            match rng.below(3) {
                0 => effects.friction = Some(friction(&vec![5.0; n - 1])),
                1 => {
                    effects.latency = Some(Latency {
                        tau_s: 0.3 + 0.4 * rng.uniform(),
                    })
                }
                _ => {
                    effects.clearance = Some(clearance(
                        &vec![2.5; n - 1],
                        &vec![360.0 * rng.uniform(); n - 1],
                    ))
                }
            }
        }
        if only.as_ref().is_some_and(|o| !o.contains(&seed)) {
            continue;
        }
        let name: &'static str = Box::leak(format!("outside_seed_{seed}").into_boxed_str());
        let case = Case::new(name, robot, 2000 + seed)
            .effects(effects)
            .unmodelled(unmodelled)
            .may_miss();
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(case))) {
            Ok(true) => complete += 1,
            Ok(false) => incomplete.push(name),
            Err(_) => failed.push(name),
        }
    }
    eprintln!(
        "outside the vocabulary: {complete} complete, incomplete {incomplete:?}, failed {failed:?}"
    );
    assert!(
        failed.is_empty(),
        "{} of {OUTSIDE_SEEDS} failed: {failed:?}",
        failed.len()
    );
    assert!(
        only.is_some() || complete >= OUTSIDE_COMPLETE_AT_LEAST,
        "{complete} of {OUTSIDE_SEEDS} complete (at least {OUTSIDE_COMPLETE_AT_LEAST}): \
         {incomplete:?} miss an effect of the vocabulary"
    );
}

// ---- the intervals (`ci95`) against the truth over seeds ----

/// Seeded recordings of the interval test.
const INTERVAL_SEEDS: u64 = 24;
/// Share of the truth's scalar parameters the intervals must hold (the 85 %).
const MIN_COVERAGE: f64 = 0.85;
/// The truth of `effect` in the report's form (`parameters`), with the zeros the
/// world leaves implicit written out.
fn truth_parameters(effects: &Effects, effect: &str, n: usize) -> serde_json::Value {
    let mut e = effects.clone();
    if let Some(f) = &mut e.friction {
        f.feed_play_mm.resize(n, 0.0);
    }
    serde_json::to_value(&e).unwrap()[effect].clone()
}

/// Over seeded recordings with realistic effects of the vocabulary (alone), and over
/// them and the public recordings together, the truth lies in the reported `ci95` for
/// at least 85 % of the scalar parameters, and the median half-width is at most a quarter of the
/// parameter's size plus a small floor. Where only a combination is identified
/// (stiffness factors: their ratio), the combination counts instead of the factors.
#[test]
fn intervals_hold_the_truth_over_seeds() {
    use ctr_analysis::rng::Rng;
    let mut seeded = Tally::default();
    for seed in 0..INTERVAL_SEEDS {
        let mut rng = Rng::new(3000 + seed);
        let kind = seed as usize % 8;
        let robot = if kind == 7 {
            "liu2023"
        } else {
            ["liu2023", "nitinol2", "nitinol3"][rng.below(3)]
        };
        let n = robot_and_ranges(robot).0.robot.n_tubes();
        let sign = if rng.uniform() < 0.5 { -1.0 } else { 1.0 };
        let u = rng.uniform();
        let tube = rng.below(n);
        let mut effects = Effects::default();
        let mut sigma = SynthSpec::default().noise_sigma_mm;
        match kind {
            0 => {
                effects.latency = Some(Latency {
                    tau_s: 0.2 + 0.6 * u,
                })
            }
            1 => {
                let d = rng.unit_vector();
                let t = rng.unit_vector();
                effects.registration = Some(registration(
                    d.map(|v| v * (1.0 + 2.0 * u)),
                    t.map(|v| v * (2.0 + 3.0 * u)),
                ))
            }
            2 => effects.joint_offset = Some(joint_offset(n, tube, sign * 1.0, 5.0 * sign)),
            3 => {
                effects.clearance = Some(clearance(
                    &vec![2.0 + u; n - 1],
                    &vec![360.0 * rng.uniform(); n - 1],
                ))
            }
            4 => effects.friction = Some(friction(&vec![3.0 + 5.0 * u; n - 1])),
            5 => {
                let d = rng.unit_vector();
                effects.sensor_offset = Some(SensorOffset {
                    offset_mm: d.map(|v| v * (2.0 + 3.0 * u)),
                })
            }
            6 => {
                effects.stiffness = Some(Stiffness {
                    factor: factors(n, tube, 1.0 + sign * (0.25 + 0.1 * u)),
                })
            }
            _ => {
                sigma = GRAVITY_NOISE_SIGMA_MM;
                effects.gravity = Some(Gravity {
                    direction_w: [-1.0, 0.0, 0.0],
                    g_m_s2: 9.81,
                })
            }
        }
        let name: &'static str = Box::leak(format!("interval_seed_{seed}").into_boxed_str());
        let case = Case::new(name, robot, 4000 + seed)
            .effects(effects.clone())
            .sigma(sigma);
        let (user, gen) = generated(&case);
        let d = diagnose(&user, &gen.recording, &Options::default()).unwrap();
        let ratio = |t: &[usize]| {
            let f = &effects.stiffness.as_ref()?.factor;
            Some(f[t[0] - 1] / f[t[1] - 1])
        };
        for f in &d.report.findings {
            let truth = truth_parameters(&effects, f.effect.as_str(), n);
            if !truth.is_null() {
                seeded.finding(name, f, &truth, ratio);
            }
        }
        eprintln!(
            "{name} [{robot}] {} -> {:?}",
            serde_json::to_string(&effects).unwrap(),
            d.report
                .findings
                .iter()
                .map(|f| format!("{} {} ci {}", f.effect.as_str(), f.parameters, f.ci95))
                .collect::<Vec<_>>()
        );
    }
    // the public recordings (an independent simulator's)
    let mut public = Tally::default();
    for id in &public_ids() {
        let (spec, rec, truth) = common::recording(id);
        let d = diagnose(&ModelSpec::from_spec(&spec), &rec, &Options::default()).unwrap();
        let n = spec.robot.n_tubes();
        for f in &d.report.findings {
            if let Some(t) = public_truth(&truth["world"]["effects"], f.effect.as_str(), n) {
                public.finding(id, f, &t, |_| None);
            }
        }
    }
    let mut all = Tally::default();
    for t in [&seeded, &public] {
        all.inside += t.inside;
        all.total += t.total;
        all.widths.extend(&t.widths);
        all.misses.extend(t.misses.iter().cloned());
    }
    all.widths.sort_by(f64::total_cmp);
    let median = all
        .widths
        .get(all.widths.len() / 2)
        .copied()
        .unwrap_or(f64::NAN);
    let coverage = all.inside as f64 / all.total.max(1) as f64;
    eprintln!(
        "intervals: seeded {} of {}, public {} of {}, together {} of {} scalar parameters \
         hold the truth ({:.1} %); median half-width {median:.3} x (a quarter of the size + \
         {HALF_WIDTH_FLOOR}); misses: {:#?}",
        seeded.inside,
        seeded.total,
        public.inside,
        public.total,
        all.inside,
        all.total,
        100.0 * coverage,
        all.misses
    );
    assert!(
        seeded.total >= 2 * INTERVAL_SEEDS as usize,
        "{} compared",
        seeded.total
    );
    assert!(
        public.total >= 10,
        "{} public parameters compared",
        public.total
    );
    // the seeded recordings alone and both together; the public recordings alone are
    // not yet held to it (16 of 20: see `docs/diagnosis.md`, "Measured", for the misses)
    let seeded_coverage = seeded.inside as f64 / seeded.total.max(1) as f64;
    assert!(
        seeded_coverage >= MIN_COVERAGE,
        "seeded coverage {seeded_coverage:.3}: {:#?}",
        seeded.misses
    );
    assert!(
        coverage >= MIN_COVERAGE,
        "coverage {coverage:.3}: {:#?}",
        all.misses
    );
    assert!(median <= 1.0, "median half-width ratio {median:.3}");
}

/// The case: tube 2 of a two-tube robot 30 % softer than its description.
/// Kinematics see only the ratio of the stiffnesses: the report says so, gives the
/// ratio with its interval, keeps the factors at their nominal product and gives them
/// no interval of their own.
#[test]
fn stiffness_ratio_is_identified_not_the_factors() {
    let case = Case::new("stiffness_ratio", "nitinol2", 71).effects(Effects {
        stiffness: Some(Stiffness {
            factor: vec![1.0, 0.7],
        }),
        ..Default::default()
    });
    let (user, gen) = generated(&case);
    let d = diagnose(&user, &gen.recording, &Options::default()).unwrap();
    let r = &d.report;
    let f = r
        .findings
        .iter()
        .find(|f| f.effect.as_str() == "stiffness")
        .expect("stiffness found");
    let factor: Vec<f64> = serde_json::from_value(f.parameters["factor"].clone()).unwrap();
    // tied to the nominal along the direction the data cannot see: product 1
    assert!((factor[0] * factor[1] - 1.0).abs() < 1e-6, "{factor:?}");
    for k in 0..2 {
        let ci: [f64; 2] = serde_json::from_value(f.ci95["factor"][k].clone()).unwrap();
        assert!(
            ci[0] < 0.2 && ci[1] > 5.0,
            "factor {k} not identified: {ci:?}"
        );
    }
    let ids = f.ci95["identified"].as_array().expect("identified");
    assert_eq!(ids.len(), 1, "{ids:?}");
    assert_eq!(
        ids[0]["combination"],
        "stiffness factor of tube 2 / stiffness factor of tube 1"
    );
    let value = ids[0]["value"].as_f64().unwrap();
    let ci: [f64; 2] = serde_json::from_value(ids[0]["ci95"].clone()).unwrap();
    assert!((value - 0.7).abs() < 0.01, "ratio {value}");
    assert!(
        ci[0] <= 0.7 && 0.7 <= ci[1] && ci[1] - ci[0] < 0.05,
        "{ci:?}"
    );
    assert_eq!(r.identifiability.len(), 1, "{:?}", r.identifiability);
    assert!(r.identifiability[0].contains("stiffness factor of tube 1"));
    let summary = r.summary("stiffness_ratio.csv");
    assert!(summary.contains("only this is identified"), "{summary}");
    eprintln!("{summary}");
}

/// The 95 % half-width of `parameter` (as `suggested_run.expected` names it) in a
/// report, where the file writes that parameter as it is fitted.
fn half_width(r: &ctr_diagnosis::Report, parameter: &str) -> Option<f64> {
    let index = |rest: &str| -> Option<usize> {
        let k: usize = rest
            .split(|c: char| !c.is_ascii_digit())
            .next()?
            .parse()
            .ok()?;
        Some(k - 1)
    };
    let axis = |rest: &str| ["x", "y", "z"].iter().position(|a| *a == rest);
    let (effect, key, i) = if parameter == "latency" {
        ("latency", "tau_s", None)
    } else if let Some(rest) = parameter.strip_prefix("rotation play of tubes ") {
        ("friction", "rotation_play_deg", index(rest))
    } else if let Some(rest) = parameter.strip_prefix("feed play of tube ") {
        ("friction", "feed_play_mm", index(rest))
    } else if let Some(rest) = parameter.strip_prefix("feed offset of tube ") {
        ("joint_offset", "feed_mm", index(rest))
    } else if let Some(rest) = parameter.strip_prefix("rotation offset of tube ") {
        ("joint_offset", "rotation_deg", index(rest))
    } else if let Some(rest) = parameter.strip_prefix("registration translation ") {
        ("registration", "translation_mm", axis(rest))
    } else {
        return None;
    };
    let f = r.findings.iter().find(|f| f.effect.as_str() == effect)?;
    let mut node = f.ci95.get(key)?;
    if let Some(i) = i {
        node = node.get(i)?;
    }
    Some((node[1].as_f64()? - node[0].as_f64()?) / 2.0)
}

/// A parameter's interval is held to shrink as predicted where the suggested run is
/// predicted to shrink its half-width below this share of today's.
const PREDICTED_SHRINK: f64 = 0.9;

/// A confusable pair on a short recording (about 160 rows): latency and friction both
/// delay the tip at a reversal, and with few reversals the friction's feed plays are
/// poorly pinned. The report suggests a run; recorded (simulated with the world, its own
/// noise) and diagnosed with the rest, it shrinks the uncertain intervals as predicted,
/// within a factor of 2.
#[test]
fn a_suggested_run_shrinks_the_intervals_as_predicted() {
    use ctr_diagnosis::synth::{record, CommandedRun};
    let case = Case::new("short_latency_friction", "nitinol2", 81).effects(Effects {
        latency: Some(Latency { tau_s: 0.4 }),
        friction: Some(friction(&[3.0])),
        ..Default::default()
    });
    let (spec, ranges) = robot_and_ranges(case.robot);
    let short = SynthSpec {
        feed_steps: 8,
        rotation_step_deg: 15.0,
        walk_rows: 30,
        ..synth_spec(&case, spec.robot.n_tubes())
    };
    let world = ModelSpec {
        robot: spec.robot,
        model: Model::Torsion,
        effects: case.effects.clone(),
        empirical: None,
        discrepancy: None,
    };
    let user = ModelSpec {
        effects: Effects::default(),
        ..world.clone()
    };
    let gen = generate(&world, &ranges, &short).unwrap();
    let rec = &gen.recording;
    let d = diagnose(&user, rec, &Options::default()).unwrap();
    let r = &d.report;
    eprintln!("{} rows\n{}", rec.rows.len(), r.summary("short.csv"));
    let run = r.suggested_run.as_ref().expect("a suggested run");
    let joints = d.suggested_joints.as_ref().expect("its joints");
    assert_eq!(joints.q.len(), run.rows);
    // the run, recorded by the world with fresh noise, appended to the recording
    let new = record(
        &world,
        &[CommandedRun {
            label: "suggested".into(),
            joints: joints.q.clone(),
        }],
        &SynthSpec {
            seed: 999,
            sample_period_s: run.sample_period_s,
            ..short.clone()
        },
    )
    .unwrap();
    let mut both = rec.clone();
    let t0 = rec.rows.last().unwrap().t_s + short.run_gap_s;
    let start = both.rows.len();
    for row in &new.recording.rows {
        let mut row = row.clone();
        row.t_s += t0;
        row.run = both.runs.len();
        row.line = both.rows.len() + 2;
        both.rows.push(row);
    }
    both.runs.push(ctr_formats::Run {
        label: "suggested".into(),
        rows: start..both.rows.len(),
    });
    let again = diagnose(&user, &both, &Options::default()).unwrap();
    eprintln!("{}", again.report.summary("short+suggested.csv"));
    let mut compared = 0;
    for e in &run.expected {
        let (Some(now), Some(after)) = (
            half_width(r, &e.parameter),
            half_width(&again.report, &e.parameter),
        ) else {
            continue;
        };
        let [Some(lo), Some(hi)] = e.ci95_expected else {
            continue;
        };
        let predicted = (hi - lo) / 2.0;
        eprintln!(
            "{}: half-width now {now:.4}, predicted {predicted:.4}, after {after:.4}",
            e.parameter
        );
        // a run cannot be held to shrink what it is not predicted to shrink
        if predicted > PREDICTED_SHRINK * now {
            continue;
        }
        assert!(after < now, "{}: the interval shrinks", e.parameter);
        let ratio = after / predicted;
        assert!(
            (0.5..=2.0).contains(&ratio),
            "{}: after / predicted = {ratio:.2}",
            e.parameter
        );
        compared += 1;
    }
    assert!(
        compared >= 1,
        "an uncertain parameter compared: {:?}",
        run.expected
    );
}

/// A registration beside rotation offsets: turning every tube and the tracker frame
/// the other way about the robot's axis moves no tip. The report says so and gives
/// the sums it does identify, which hold the truth (offset + the registration's
/// rotation about z).
#[test]
fn registration_and_rotation_offsets_share_one_rotation() {
    let case = Case::new("registration_rotation", "nitinol2", 82).effects(Effects {
        registration: Some(registration([0.0, 1.0, 2.0], [3.0, 1.0, -2.0])),
        joint_offset: Some(joint_offset(2, 1, 1.0, 5.0)),
        ..Default::default()
    });
    let (user, gen) = generated(&case);
    let d = diagnose(&user, &gen.recording, &Options::default()).unwrap();
    let r = &d.report;
    assert!(
        r.identifiability
            .iter()
            .any(|s| s.contains("registration rotation z")
                && s.contains("rotation offset of tube 2")),
        "{:?}",
        r.identifiability
    );
    let f = r
        .findings
        .iter()
        .find(|f| f.effect.as_str() == "joint_offset")
        .expect("joint offsets found");
    let ids = f.ci95["identified"].as_array().expect("identified sums");
    // truth: rotation offsets (0, 5) deg, the registration's rotation about z 2 deg
    for (tube, truth) in [(1, 2.0), (2, 7.0)] {
        let c = ids
            .iter()
            .find(|c| {
                c["combination"]
                    == format!("rotation offset of tube {tube} + registration rotation z (deg)")
            })
            .unwrap_or_else(|| panic!("tube {tube}: {ids:?}"));
        let ci: [f64; 2] = serde_json::from_value(c["ci95"].clone()).unwrap();
        assert!(
            ci[0] <= truth && truth <= ci[1],
            "tube {tube}: {truth} not in {ci:?}"
        );
    }
}

// ---- each acceptance check of a finding keeps a false finding out ----

/// The established findings of `case` diagnosed with `checks`, its walk `walk_rows` long.
fn found_with(case: &Case, walk_rows: usize, checks: ctr_diagnosis::Checks) -> Vec<&'static str> {
    let (spec, ranges) = robot_and_ranges(case.robot);
    let (user, _) = generated(case);
    let world = ModelSpec {
        effects: case.effects.clone(),
        ..user.clone()
    };
    let synth = SynthSpec {
        walk_rows,
        ..synth_spec(case, spec.robot.n_tubes())
    };
    let gen = generate(&world, &ranges, &synth).unwrap();
    let opt = Options {
        checks,
        ..Default::default()
    };
    let d = diagnose(&user, &gen.recording, &opt).unwrap();
    if std::env::var_os("CTR_BLIND_VERBOSE").is_some() {
        eprintln!("{}", d.report.summary(case.name));
        print_trials(&d.report);
    }
    d.report.established().map(|f| f.effect.as_str()).collect()
}

/// The checks of the verification (`verify`), each turned off alone on a recording
/// whose cause lies outside the vocabulary (beside one of it, at most): with every check
/// on the report names what the vocabulary holds and nothing else; without the check, a
/// false finding.
#[test]
fn each_acceptance_check_keeps_a_false_finding_out() {
    let all = ctr_diagnosis::Checks::default();
    let default_walk = SynthSpec::default().walk_rows;
    let cases = [
        // a wrong lead-screw pitch: a joint offset of the feed stands in for it,
        // constant where the error grows with the feed (check 2)
        (
            "check 2, constant",
            Case::new("ablate_feed_gain", "liu2023", 62).unmodelled(Unmodelled::FeedGain {
                tube: 1,
                gain: 1.05,
            }),
            default_walk,
            ctr_diagnosis::Checks {
                constant: false,
                ..all
            },
        ),
        // a miscalibrated tracker: a precurvature takes part of the scale error, no
        // better than a generic term of its size (check 1); its intervals then hold the
        // factor 1 too, which the interval rule of check 3 also catches: both off (a
        // scale of 1-2 % per axis: with the tracker's frame solved in every fit, the
        // smaller scale of seed 66 leaves a precurvature nothing to take)
        (
            "check 1, beats a generic term (and the interval rule)",
            Case::new("ablate_tracker_scale", "liu2023", 67).unmodelled(Unmodelled::TrackerScale {
                scale_error: [0.02, -0.015, 0.01],
            }),
            default_walk,
            ctr_diagnosis::Checks {
                beats_generic: false,
                present: false,
                ..all
            },
        ),
        // a gear's once-per-turn error beside a latency: the stiffness of a tube five
        // times softer than its datasheet, beside gravity at four times the earth's,
        // takes part of it and passes the other checks; outside the lab's tolerance, it
        // is not established
        (
            "the lab's tolerance",
            Case::new("ablate_runout", "liu2023", 2001)
                .effects(Effects {
                    latency: Some(Latency {
                        tau_s: 0.53708853543493,
                    }),
                    ..Default::default()
                })
                .unmodelled(Unmodelled::GearRunout {
                    tube: 1,
                    amplitude_deg: 9.935945236204633,
                    phase_deg: 248.01509390014525,
                }),
            default_walk,
            ctr_diagnosis::Checks {
                within_tolerance: false,
                ..all
            },
        ),
    ];
    // the example, a 3 % tracker scale error: no clearance or precurvature (nor
    // anything else) established with every check on
    let large =
        Case::new("large_tracker_scale", "liu2023", 67).unmodelled(Unmodelled::TrackerScale {
            scale_error: [0.03, 0.03, 0.03],
        });
    assert_eq!(found_with(&large, default_walk, all), Vec::<&str>::new());
    for (check, case, walk, without) in cases {
        let truth = case.expected();
        let sorted = |mut v: Vec<&'static str>| {
            v.sort_unstable();
            v
        };
        assert_eq!(sorted(found_with(&case, walk, all)), truth, "{check}");
        let false_finding = found_with(&case, walk, without);
        eprintln!("{}, {check} off: {false_finding:?}", case.name);
        assert!(false_finding.iter().any(|f| !truth.contains(f)), "{check}");
    }
}

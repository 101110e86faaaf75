//! Helpers shared by the cross-crate tests and the benches: the robots and reference
//! tables of `tests/data/shared`, read without the std crate so that ctr-core's own tests
//! need nothing but the core.
#![allow(missing_docs)]

pub use serde_json;

use ctr_core::nalgebra::{Matrix3, Vector3, Vector6};
use ctr_core::{Joints, Robot, TubeParams};
use serde::Deserialize;
use std::path::PathBuf;

/// The project's copy of the shared reference data (`tests/data/shared`; override with
/// `CTR_SHARED_DATA`).
pub fn shared_data() -> PathBuf {
    if let Ok(p) = std::env::var("CTR_SHARED_DATA") {
        return PathBuf::from(p);
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/shared")
}

#[derive(Deserialize)]
struct RobotFile {
    tube: Vec<TubeFile>,
}

#[derive(Deserialize)]
struct TubeFile {
    outer_diameter_mm: f64,
    inner_diameter_mm: f64,
    length_mm: f64,
    curved_length_mm: f64,
    curvature_radius_mm: Option<f64>,
    youngs_modulus_mpa: f64,
    poisson_ratio: f64,
    density_kg_m3: Option<f64>,
}

pub fn tube_params(name: &str) -> Vec<TubeParams<f64>> {
    let path = shared_data().join("robots").join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let file: RobotFile = toml::from_str(&text).unwrap();
    file.tube
        .iter()
        .map(|t| TubeParams {
            curvature_radius_mm: t.curvature_radius_mm,
            density_kg_m3: t.density_kg_m3,
            ..TubeParams::new(
                t.outer_diameter_mm,
                t.inner_diameter_mm,
                t.length_mm,
                t.curved_length_mm,
                t.youngs_modulus_mpa,
                t.poisson_ratio,
            )
        })
        .collect()
}

pub fn robot<const N: usize>(name: &str) -> Robot<f64, N> {
    let p: [TubeParams<f64>; N] = tube_params(name).try_into().unwrap();
    Robot::new(p).unwrap()
}

pub fn robot_f32<const N: usize>(name: &str) -> Robot<f32, N> {
    let p: Vec<TubeParams<f32>> = tube_params(name)
        .iter()
        .map(|t| TubeParams {
            outer_diameter_mm: t.outer_diameter_mm as f32,
            inner_diameter_mm: t.inner_diameter_mm as f32,
            length_mm: t.length_mm as f32,
            curved_length_mm: t.curved_length_mm as f32,
            curvature_radius_mm: t.curvature_radius_mm.map(|v| v as f32),
            youngs_modulus_mpa: t.youngs_modulus_mpa as f32,
            poisson_ratio: t.poisson_ratio as f32,
            bending_stiffness_nmm2: None,
            torsional_stiffness_nmm2: None,
            density_kg_m3: t.density_kg_m3.map(|v| v as f32),
        })
        .collect();
    Robot::new(p.try_into().unwrap()).unwrap()
}

/// One row of a reference table: joints, tip position (mm), quaternion (w, x, y, z).
pub struct RefRow<const N: usize> {
    pub q: Joints<f64, N>,
    pub p: [f64; 3],
    pub quat: [f64; 4],
}

pub fn reference<const N: usize>(name: &str, model: &str) -> Vec<RefRow<N>> {
    let path = shared_data()
        .join("reference")
        .join(format!("{name}-{model}.csv"));
    let mut rdr =
        csv::Reader::from_path(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    rdr.records()
        .map(|r| {
            let v: Vec<f64> = r.unwrap().iter().map(|x| x.parse().unwrap()).collect();
            let s: [f64; N] = core::array::from_fn(|i| v[2 * i]);
            let t: [f64; N] = core::array::from_fn(|i| v[2 * i + 1]);
            RefRow {
                q: Joints::from_mm_deg(s, t),
                p: [v[2 * N], v[2 * N + 1], v[2 * N + 2]],
                quat: [v[2 * N + 3], v[2 * N + 4], v[2 * N + 5], v[2 * N + 6]],
            }
        })
        .collect()
}

/// Angle between two orientations, rad.
pub fn angle_between(a: &nalgebra::UnitQuaternion<f64>, quat: [f64; 4]) -> f64 {
    let b = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        quat[0], quat[1], quat[2], quat[3],
    ));
    a.angle_to(&b)
}

/// One row of a recording: time, run label, commanded joints, measured tip (mm).
pub struct RecRow<const N: usize> {
    pub t_s: f64,
    pub run: String,
    pub q: Joints<f64, N>,
    pub p: [f64; 3],
}

/// A recording of `tests/data/shared/recordings` and its truth file.
pub fn recording<const N: usize>(id: &str) -> (Vec<RecRow<N>>, serde_json::Value) {
    let dir = shared_data().join("recordings");
    let mut rdr = csv::Reader::from_path(dir.join(format!("{id}.csv"))).unwrap();
    let header: Vec<String> = rdr.headers().unwrap().iter().map(String::from).collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name}"))
    };
    let rows = rdr
        .records()
        .map(|r| {
            let r = r.unwrap();
            let f = |name: &str| r[col(name)].parse::<f64>().unwrap();
            RecRow {
                t_s: f("t_s"),
                run: r[col("run")].to_string(),
                q: Joints::from_mm_deg(
                    core::array::from_fn(|i| f(&format!("s{}_mm", i + 1))),
                    core::array::from_fn(|i| f(&format!("theta{}_deg", i + 1))),
                ),
                p: [f("x_mm"), f("y_mm"), f("z_mm")],
            }
        })
        .collect();
    let truth = std::fs::read_to_string(dir.join(format!("{id}.truth.json"))).unwrap();
    (rows, serde_json::from_str(&truth).unwrap())
}

/// Property tests: how they run (a fixed seed, the regression files, the failure
/// message) and the random robots and joints they draw.
pub mod props;

/// `(dp, omega)` of a central difference between two tip frames over `2h`, omega the
/// spatial angular velocity `vee(dR R^T)` at the midpoint frame `r`.
pub fn difference(
    plus: &ctr_core::Frame<f64>,
    minus: &ctr_core::Frame<f64>,
    r: &Matrix3<f64>,
    h: f64,
) -> Vector6<f64> {
    let dp = (plus.position - minus.position) / (2.0 * h);
    let w = (plus.rotation - minus.rotation) / (2.0 * h) * r.transpose();
    let omega = Vector3::new(
        w[(2, 1)] - w[(1, 2)],
        w[(0, 2)] - w[(2, 0)],
        w[(1, 0)] - w[(0, 1)],
    ) * 0.5;
    Vector6::new(dp.x, dp.y, dp.z, omega.x, omega.y, omega.z)
}

/// A valid two-tube robot of round numbers (precurved tubes of 200 and 100 mm radius),
/// for tests that need one robot and no data file.
pub fn two_tubes() -> [TubeParams<f64>; 2] {
    [
        TubeParams {
            curvature_radius_mm: Some(200.0),
            ..TubeParams::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33)
        },
        TubeParams {
            curvature_radius_mm: Some(100.0),
            ..TubeParams::new(1.2, 0.9, 260.0, 90.0, 58000.0, 0.33)
        },
    ]
}

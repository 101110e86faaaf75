//! The shared reference configurations of a 3-tube robot (`robots/nitinol3.toml`, the
//! joints of `reference/nitinol3-{rigid,torsion,gravity}.csv`), solved as the host's
//! `ctr-cli fk` solves them, so the two can be compared number for number:
//!
//! - the same robot and joints, bit for bit (the build script writes them in shortest
//!   round-trip form);
//! - the same request: the file's model (`rigid` or `torsion`), and for `gravity` the
//!   torsion model under the tubes' weight along the manifest's direction;
//! - the same warm starts: `ctr-cli fk` solves the rows in chunks of
//!   [`HOST_CHUNK_ROWS`], each chunk from a fresh solver and each row warm-started from
//!   the row before (`ctr_analysis::batch`). A warm start changes the tip only below the
//!   Newton tolerance, but mirroring it leaves only the arithmetic to differ.

use ctr_core::{
    Gravity, Joints, Loads, Model, Real, Request, Robot, RobotError, SolveError, Solver, Status,
    TubeParams,
};

/// A tube as the robot file gives it (the fields of `ctr_core::TubeParams`, in `f64`).
pub struct TubeRow {
    /// Outer diameter, mm.
    pub outer_diameter_mm: f64,
    /// Inner diameter, mm.
    pub inner_diameter_mm: f64,
    /// Whole length, mm.
    pub length_mm: f64,
    /// Length of the precurved part, mm.
    pub curved_length_mm: f64,
    /// Young's modulus, MPa.
    pub youngs_modulus_mpa: f64,
    /// Poisson ratio.
    pub poisson_ratio: f64,
    /// Signed radius of the precurved part, mm.
    pub curvature_radius_mm: Option<f64>,
    /// Measured E I, N mm^2.
    pub bending_stiffness_nmm2: Option<f64>,
    /// Measured G J, N mm^2.
    pub torsional_stiffness_nmm2: Option<f64>,
    /// Density, kg/m^3.
    pub density_kg_m3: Option<f64>,
}

/// One reference table: its model and its rows' joints `s1_mm, theta1_deg, ...`.
pub struct Table {
    /// `rigid`, `torsion` or `gravity` (the file name's model).
    pub model: &'static str,
    /// The joints of each row, file units.
    pub joints: &'static [[f64; 2 * N_TUBES]],
}

/// Tubes of the reference robot.
pub const N_TUBES: usize = 3;

// TUBES and TABLES, written by build.rs
include!(concat!(env!("OUT_DIR"), "/reference_data.rs"));

/// Rows of a warm-started chunk in `ctr-cli fk` (`ctr_analysis::batch::WARM_CHUNK_ROWS`).
pub const HOST_CHUNK_ROWS: usize = 32;

/// Direction of gravity in W for the `gravity` tables (`manifest.json`,
/// `reference.gravity_model.direction_W`).
pub const GRAVITY_DIRECTION_W: [f64; 3] = [-1.0, 0.0, 0.0];
/// Magnitude of gravity for the `gravity` tables, m/s^2 (`reference.gravity_model.g_m_s2`).
pub const GRAVITY_M_S2: f64 = 9.81;

/// A solved tip, widened to `f64` for printing.
pub struct Tip {
    /// Position in W, mm.
    pub position_mm: [f64; 3],
    /// Orientation of tube n's material frame, unit quaternion `w, x, y, z`.
    pub orientation: [f64; 4],
    /// How the solve ended.
    pub status: Status,
}

fn convert<T: Real>(v: f64) -> T {
    ctr_core::nalgebra::convert(v)
}

fn widen<T: Real>(v: T) -> f64 {
    ctr_core::nalgebra::try_convert(v).unwrap_or(f64::NAN)
}

/// The reference robot in `T`.
pub fn robot<T: Real>() -> Result<Robot<T, N_TUBES>, RobotError> {
    let opt = |v: Option<f64>| v.map(convert::<T>);
    Robot::new(TUBES.each_ref().map(|t| TubeParams {
        curvature_radius_mm: opt(t.curvature_radius_mm),
        bending_stiffness_nmm2: opt(t.bending_stiffness_nmm2),
        torsional_stiffness_nmm2: opt(t.torsional_stiffness_nmm2),
        density_kg_m3: opt(t.density_kg_m3),
        ..TubeParams::new(
            convert(t.outer_diameter_mm),
            convert(t.inner_diameter_mm),
            convert(t.length_mm),
            convert(t.curved_length_mm),
            convert(t.youngs_modulus_mpa),
            convert(t.poisson_ratio),
        )
    }))
}

/// Solves every row of `table` in `T` (rows in order, warm starts as the host's), and
/// hands each row's index and tip to `each`.
pub fn solve_table<T: Real>(
    robot: &Robot<T, N_TUBES>,
    table: &Table,
    mut each: impl FnMut(usize, Result<Tip, SolveError>),
) {
    let loads = Loads {
        gravity: Some(Gravity::new(
            GRAVITY_DIRECTION_W.map(convert::<T>),
            convert(GRAVITY_M_S2),
        )),
        ..Default::default()
    };
    let model = if table.model == "rigid" {
        Model::Rigid
    } else {
        Model::Torsion
    };
    let mut solver = Solver::<T, N_TUBES>::default();
    for (row, joints) in table.joints.iter().enumerate() {
        if row % HOST_CHUNK_ROWS == 0 {
            solver = Solver::default();
        }
        let q = Joints::from_mm_deg(
            core::array::from_fn(|i| convert(joints[2 * i])),
            core::array::from_fn(|i| convert(joints[2 * i + 1])),
        );
        let mut request = Request::new(q, model);
        if table.model == "gravity" {
            request = request.loads(loads);
        }
        let tip = solver.solve(robot, request).map(|sol| {
            let p = sol.tip.position;
            let r = sol.tip.orientation();
            Tip {
                position_mm: [widen(p.x), widen(p.y), widen(p.z)],
                orientation: [widen(r.w), widen(r.i), widen(r.j), widen(r.k)],
                status: sol.status,
            }
        });
        each(row, tip);
    }
}

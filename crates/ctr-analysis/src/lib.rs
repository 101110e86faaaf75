//! The std layer shared by the CLI, the Python wheel and the diagnosis (`ctr-diagnosis`):
//! the row model, batches, the timeline of time effects, simulation of recordings,
//! inverse kinematics, the stability margin and the learned discrepancy's evaluation.
//!
//! Data flows one way: files ([`ctr_formats`]) -> a validated robot ([`AnyRobot`](ctr_formats::AnyRobot), the
//! core's `Robot<f64, N>` for a tube count known at run time) and checked joints or
//! targets -> core solves of the file's whole model ([`model`]: ONE row model, the
//! robot, its `[model] kind` and `[model.effects]`; [`batch`] on the one thread pool,
//! thread-count independent; [`simulate`] along recordings, and [`linearised`] the
//! same rows moved without solving again, for a fit's Jacobian; [`ik`] for targets) ->
//! tip or joint files. [`job`] strings these together for `ctr-cli fk` and `ctr-cli ik`.
//! The forward numerics are the core's; this crate prepares rows for it, dispatches,
//! and solves the inverse problem on top of the core's forward kinematics.
//!
//! Beside them: [`timeline`] (latency and the play-operator friction along a run, with
//! [`contact`]'s friction that grows with the contact moment), [`limits`] (the joint
//! ranges the IK keeps), [`margin`] (the stability margin: the joint distance to the
//! nearest snap), [`discrepancy`] and [`learned`] (the `[model.discrepancy]` Gaussian
//! process over the joints and their history, evaluated along each run) and [`rng`] (the
//! one seeded random generator).
//!
//! ```
//! use ctr_analysis::model::ModelSpec;
//! use ctr_formats::RobotSpec;
//! let spec = RobotSpec::from_toml_str(r#"
//! [[tube]]
//! outer_diameter_mm = 1.2
//! inner_diameter_mm = 0.9
//! length_mm = 260.0
//! curved_length_mm = 90.0
//! curvature_radius_mm = 100.0
//! youngs_modulus_mpa = 58000.0
//! poisson_ratio = 0.33
//! "#, "robot.toml")?;
//! let fk = ModelSpec::from_spec(&spec).fk(&[50.0, 0.0])?;
//! // an arc of radius 100 mm over 50 mm bends toward +x
//! assert!((fk.position[0] - 100.0 * (1.0 - 0.5_f64.cos())).abs() < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod batch;
pub mod contact;
pub mod discrepancy;
pub mod ik;
pub mod job;
pub mod learned;
pub mod limits;
pub mod linearised;
pub mod margin;
pub mod model;
pub mod rng;
pub mod simulate;
pub mod timeline;

//! What a solve is about, as validated data: the robot ([`robot`]), its joints
//! ([`joints`]), the backbone's sections ([`sections`]), the effects beyond the base
//! mechanics ([`effects`], [`friction`]) and the loads ([`loads`]).

pub mod effects;
pub mod friction;
pub mod joints;
pub mod loads;
pub mod robot;
pub mod sections;

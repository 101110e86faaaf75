//! The numerics the solver is built from, each written once: dual numbers ([`dual`]),
//! the SE(3) exponential and frames ([`se3`]), the exponential's series ([`series`]),
//! and small fixed-size linear algebra.

pub mod dual;
pub(crate) mod linalg;
pub mod se3;
pub mod series;

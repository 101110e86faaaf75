//! The scalar type the core is generic over.

use nalgebra::RealField;

/// A real scalar the solver can run on: `f64` (the default everywhere) or `f32`.
///
/// Blanket-implemented for every `Copy` [`RealField`].
///
/// ```
/// fn twice<T: ctr_core::Real>(x: T) -> T { x + x }
/// assert_eq!(twice(1.5_f32), 3.0);
/// assert_eq!(twice(1.5_f64), 3.0);
/// ```
pub trait Real: RealField + Copy {}

impl<T: RealField + Copy> Real for T {}

/// Converts an `f64` constant to `T` (exact for `f64`, rounded for `f32`); never panics.
#[inline(always)]
pub(crate) fn c<T: Real>(x: f64) -> T {
    nalgebra::convert(x)
}

//! Linear algebra types used everywhere (column-major `glam` types in the precision of
//! [`crate::real`]: f32 here, f64 in `rtmpm-physics-f64`).

pub use crate::real::{Mat3, Real, ToReal, Vec3};
pub use glam::IVec3;

/// Outer product `a b^T`.
#[inline]
pub fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Trace of a 3x3 matrix.
#[inline]
pub fn trace(m: Mat3) -> Real {
    m.x_axis.x + m.y_axis.y + m.z_axis.z
}

/// Frobenius norm squared.
#[inline]
pub fn norm2(m: Mat3) -> Real {
    m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()
}

/// Diagonal matrix from a vector.
#[inline]
pub fn diag(d: Vec3) -> Mat3 {
    Mat3::from_diagonal(d)
}

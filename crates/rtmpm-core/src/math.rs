//! Linear algebra types used everywhere (single precision, column-major `glam` types).

pub use glam::{IVec3, Mat3, Vec3};

/// Outer product `a b^T`.
#[inline]
pub fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Trace of a 3x3 matrix.
#[inline]
pub fn trace(m: Mat3) -> f32 {
    m.x_axis.x + m.y_axis.y + m.z_axis.z
}

/// Frobenius norm squared.
#[inline]
pub fn norm2(m: Mat3) -> f32 {
    m.x_axis.length_squared() + m.y_axis.length_squared() + m.z_axis.length_squared()
}

/// Diagonal matrix from a vector.
#[inline]
pub fn diag(d: Vec3) -> Mat3 {
    Mat3::from_diagonal(d)
}

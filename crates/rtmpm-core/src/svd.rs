//! 3x3 singular value and polar decompositions (stub: to be implemented).

use crate::math::{Mat3, Vec3};

/// `a = u diag(sigma) v^T` with `u`, `v` rotations (det = +1). Singular values are sorted by
/// decreasing magnitude; the last one is negative when `det(a) < 0` (inverted elements).
pub fn svd3(_a: Mat3) -> (Mat3, Vec3, Mat3) {
    todo!()
}

/// Polar decomposition `a = r s` with `r` a rotation and `s` symmetric.
pub fn polar(_a: Mat3) -> (Mat3, Mat3) {
    todo!()
}

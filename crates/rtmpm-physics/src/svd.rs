//! 3x3 singular value and polar decompositions, in the precision of [`crate::real`].
//!
//! Algorithm (ported line for line to `crates/rtmpm-cuda/kernels/svd.cuh`):
//! 1. one-sided (Hestenes) Jacobi: the columns of `B = A V` are orthogonalised by plane rotations
//!    applied from the right and accumulated into `V` (a proper rotation by construction). The
//!    rotation angles are computed from the columns themselves, never from `A^T A`, so small
//!    singular values keep their accuracy in f32 (and f64). At most [`MAX_SWEEPS`] cyclic sweeps, stopping
//!    early after a sweep without rotation;
//! 2. the columns of `B` (and `V`) are sorted by decreasing norm, swapping two columns and
//!    negating one of them so that `det V` stays +1;
//! 3. QR of `B` by Givens rotations (McAdams et al. 2011, "Computing the SVD of 3x3 matrices with
//!    minimal branching", section 4): `U = Q` is a proper rotation, `sigma = diag(R)` with
//!    `sigma_1, sigma_2 >= 0` and the sign of `det A` carried by `sigma_3`.

use crate::math::{Mat3, Real, Vec3};

/// Maximum number of cyclic Jacobi sweeps (3 rotations each); 3x3 converges in 3-5.
pub const MAX_SWEEPS: usize = 8;

/// Relative tolerance below which two columns count as orthogonal.
const ORTHO_TOL: Real = Real::EPSILON;

/// One Hestenes rotation of columns `p`, `q` of `b`, accumulated into `v`. Returns whether a
/// rotation was applied.
#[inline]
fn jacobi_pair(b: &mut [Vec3; 3], v: &mut [Vec3; 3], p: usize, q: usize) -> bool {
    let alpha = b[p].dot(b[p]);
    let beta = b[q].dot(b[q]);
    let gamma = b[p].dot(b[q]);
    if gamma.abs() <= ORTHO_TOL * alpha.sqrt() * beta.sqrt() {
        return false;
    }
    // Classical Jacobi angle for the 2x2 Gram matrix [alpha gamma; gamma beta] (Golub & Van Loan,
    // Alg. 8.4.2), with sqrt(1 + zeta^2) evaluated without overflow.
    let zeta = (beta - alpha) / (2.0 * gamma);
    let az = zeta.abs();
    let root = if az > 1.0 {
        az * (1.0 + (1.0 / az) * (1.0 / az)).sqrt()
    } else {
        (1.0 + az * az).sqrt()
    };
    let t = if zeta >= 0.0 { 1.0 } else { -1.0 } / (az + root);
    let c = 1.0 / (1.0 + t * t).sqrt();
    let s = c * t;
    let (bp, bq) = (b[p], b[q]);
    b[p] = c * bp - s * bq;
    b[q] = s * bp + c * bq;
    let (vp, vq) = (v[p], v[q]);
    v[p] = c * vp - s * vq;
    v[q] = s * vp + c * vq;
    true
}

/// Swaps columns `p`, `q` of `b` and `v` and negates the new column `q`, keeping `b = a v` and
/// `det v = +1`.
#[inline]
fn swap_neg(b: &mut [Vec3; 3], v: &mut [Vec3; 3], p: usize, q: usize) {
    let (bp, vp) = (b[p], v[p]);
    b[p] = b[q];
    v[p] = v[q];
    b[q] = -bp;
    v[q] = -vp;
}

/// Givens rotation acting on rows `p`, `q` of `r` (given as columns) that zeroes `r[k][q]` against
/// `r[k][p]`; the transpose is accumulated into the columns of `u`.
#[inline]
fn givens_qr(r: &mut [Vec3; 3], u: &mut [Vec3; 3], p: usize, q: usize, k: usize) {
    let a = r[k][p];
    let b = r[k][q];
    let h = (a * a + b * b).sqrt();
    if h <= 0.0 {
        return;
    }
    let c = a / h;
    let s = b / h;
    for col in r.iter_mut() {
        let (rp, rq) = (col[p], col[q]);
        col[p] = c * rp + s * rq;
        col[q] = -s * rp + c * rq;
    }
    // Exact zero below the pivot.
    r[k][q] = 0.0;
    let (up, uq) = (u[p], u[q]);
    u[p] = c * up + s * uq;
    u[q] = -s * up + c * uq;
}

/// `a = u diag(sigma) v^T` with `u`, `v` rotations (det = +1). Singular values are sorted by
/// decreasing magnitude; the last one is negative when `det(a) < 0` (inverted elements).
pub fn svd3(a: Mat3) -> (Mat3, Vec3, Mat3) {
    let mut b = [a.x_axis, a.y_axis, a.z_axis];
    let mut v = [Vec3::X, Vec3::Y, Vec3::Z];
    for _ in 0..MAX_SWEEPS {
        let mut rotated = jacobi_pair(&mut b, &mut v, 0, 1);
        rotated |= jacobi_pair(&mut b, &mut v, 0, 2);
        rotated |= jacobi_pair(&mut b, &mut v, 1, 2);
        if !rotated {
            break;
        }
    }
    // Sort by decreasing column norm (3-element sorting network).
    if b[0].length_squared() < b[1].length_squared() {
        swap_neg(&mut b, &mut v, 0, 1);
    }
    if b[0].length_squared() < b[2].length_squared() {
        swap_neg(&mut b, &mut v, 0, 2);
    }
    if b[1].length_squared() < b[2].length_squared() {
        swap_neg(&mut b, &mut v, 1, 2);
    }
    // QR of B: zero (1,0), (2,0), then (2,1).
    let mut u = [Vec3::X, Vec3::Y, Vec3::Z];
    givens_qr(&mut b, &mut u, 0, 1, 0);
    givens_qr(&mut b, &mut u, 0, 2, 0);
    givens_qr(&mut b, &mut u, 1, 2, 1);
    let sigma = Vec3::new(b[0][0], b[1][1], b[2][2]);
    (
        Mat3::from_cols(u[0], u[1], u[2]),
        sigma,
        Mat3::from_cols(v[0], v[1], v[2]),
    )
}

/// Polar decomposition `a = r s` with `r` a rotation and `s` symmetric (`r = u v^T`,
/// `s = v diag(sigma) v^T`; `s` is indefinite when `det(a) < 0`).
pub fn polar(a: Mat3) -> (Mat3, Mat3) {
    let (u, sigma, v) = svd3(a);
    let r = u * v.transpose();
    let s = v * Mat3::from_diagonal(sigma) * v.transpose();
    (r, s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::norm2;
    use rand::{Rng, SeedableRng};

    fn rot(axis: Vec3, angle: Real) -> Mat3 {
        Mat3::from_axis_angle(axis.normalize(), angle)
    }

    fn max_abs(m: Mat3) -> Real {
        m.to_cols_array()
            .iter()
            .fold(0.0 as Real, |acc, x| acc.max(x.abs()))
    }

    /// Checks every property of the SVD; tolerances relative to the largest entry of `a`.
    fn check_svd(a: Mat3) {
        let (u, s, v) = svd3(a);
        let scale = max_abs(a).max(1e-30);
        let rec = u * Mat3::from_diagonal(s) * v.transpose();
        let err = max_abs(rec - a) / scale;
        assert!(
            err < 2e-6,
            "reconstruction error {err} for {a:?}: u={u:?} s={s:?} v={v:?}"
        );
        for m in [u, v] {
            let e = max_abs(m.transpose() * m - Mat3::IDENTITY);
            assert!(e < 2e-6, "not orthogonal ({e}): {m:?}");
            assert!(
                (m.determinant() - 1.0).abs() < 2e-6,
                "det {} != 1",
                m.determinant()
            );
        }
        let tol = 2e-6 * scale;
        assert!(
            s.x >= 0.0 && s.y >= 0.0,
            "first two singular values must be >= 0: {s:?}"
        );
        assert!(
            s.x + tol >= s.y && s.y + tol >= s.z.abs(),
            "not sorted: {s:?}"
        );
        let det = a.determinant();
        if det.abs() > 1e-4 * scale * scale * scale {
            assert_eq!(
                s.z < 0.0,
                det < 0.0,
                "sign of last singular value vs det {det}: {s:?}"
            );
        }
    }

    fn hard_matrices() -> Vec<Mat3> {
        let r1 = rot(Vec3::new(1.0, 2.0, 3.0), 0.7);
        let r2 = rot(Vec3::new(-0.3, 1.0, 0.2), 2.1);
        let d = Mat3::from_diagonal;
        vec![
            Mat3::IDENTITY,
            Mat3::ZERO,
            -Mat3::IDENTITY,
            d(Vec3::new(3.0, 2.0, 1.0)),
            d(Vec3::new(1.0, 2.0, 3.0)),
            d(Vec3::new(2.0, 2.0, 2.0)),
            d(Vec3::new(1.0, 5.0, 5.0)),
            d(Vec3::new(-1.0, 2.0, 0.5)),
            d(Vec3::new(0.0, 0.0, 1.0)),
            d(Vec3::new(1e3, 1.0, 1e-3)),
            r1,
            r2,
            rot(Vec3::Z, std::f64::consts::PI as Real),
            rot(Vec3::X, 1e-4),
            // near-singular
            r1 * d(Vec3::new(1.0, 0.5, 1e-6)) * r2,
            r1 * d(Vec3::new(1.0, 1e-6, 1e-6)) * r2,
            // rank 2 and rank 1 exactly
            Mat3::from_cols(
                Vec3::new(1.0, 2.0, 3.0),
                Vec3::new(4.0, 5.0, 6.0),
                Vec3::new(7.0, 8.0, 9.0),
            ),
            Mat3::from_cols(
                Vec3::new(1.0, 2.0, 3.0),
                Vec3::new(2.0, 4.0, 6.0),
                Vec3::new(-1.0, -2.0, -3.0),
            ),
            crate::math::outer(Vec3::new(0.3, -0.4, 1.2), Vec3::new(-2.0, 0.1, 0.7)),
            // inverted
            r1 * d(Vec3::new(1.2, 0.9, -0.3)) * r2,
            r1 * d(Vec3::new(1.0, 1.0, -1.0)),
            // large anisotropy
            r1 * d(Vec3::new(1e3, 1.0, 1e-3)) * r2,
            r2 * d(Vec3::new(1e-3, 1e3, 1.0)) * r1,
            // repeated singular values in a rotated frame
            r1 * d(Vec3::new(2.0, 2.0, 0.5)) * r2,
            // nearly equal columns
            Mat3::from_cols(
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(1.0, 1.0, 1.0 + 1e-6),
                Vec3::new(1.0, 1.0 + 1e-6, 1.0),
            ),
        ]
    }

    #[test]
    fn svd_hard_matrices() {
        for a in hard_matrices() {
            check_svd(a);
        }
    }

    #[test]
    fn svd_random_matrices() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(42);
        for i in 0..2000 {
            let mut a =
                Mat3::from_cols_array(&std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            if i % 4 == 1 {
                // near the identity, like a deformation gradient
                a = Mat3::IDENTITY + 0.1 * a;
            }
            check_svd(a);
        }
    }

    #[test]
    fn svd_known_singular_values() {
        // Singular values of a rotated diagonal are recovered, also the tiny ones, relative to
        // the largest (sorted, sign on the last for det < 0).
        let r1 = rot(Vec3::new(1.0, 2.0, 3.0), 0.7);
        let r2 = rot(Vec3::new(-0.3, 1.0, 0.2), 2.1);
        let cases = [
            (Vec3::new(3.0, 2.0, 1.0), Vec3::new(3.0, 2.0, 1.0)),
            (Vec3::new(0.5, -2.0, 1.0), Vec3::new(2.0, 1.0, -0.5)),
            (Vec3::new(1.0, 0.5, 1e-6), Vec3::new(1.0, 0.5, 1e-6)),
            (Vec3::new(1e3, 1.0, 1e-3), Vec3::new(1e3, 1.0, 1e-3)),
        ];
        for (d, expected) in cases {
            let (_, s, _) = svd3(r1 * Mat3::from_diagonal(d) * r2);
            let e = (s - expected).abs().max_element() / expected.x;
            assert!(e < 1e-5, "{s:?} vs {expected:?}");
        }
        // Diagonal input: exact.
        let (_, s, _) = svd3(Mat3::from_diagonal(Vec3::new(1.0, 3.0, 2.0)));
        assert_eq!(s, Vec3::new(3.0, 2.0, 1.0));
    }

    #[test]
    fn polar_decomposition() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
        let mut mats = hard_matrices();
        for _ in 0..200 {
            mats.push(Mat3::from_cols_array(&std::array::from_fn(|_| {
                rng.random_range(-1.0..1.0)
            })));
        }
        for a in mats {
            let (r, s) = polar(a);
            let scale = max_abs(a).max(1e-30);
            assert!(max_abs(r * s - a) / scale < 2e-6, "r s != a for {a:?}");
            assert!(max_abs(r.transpose() * r - Mat3::IDENTITY) < 2e-6);
            assert!((r.determinant() - 1.0).abs() < 2e-6);
            assert!(max_abs(s - s.transpose()) / scale < 2e-6, "s not symmetric");
        }
        // Rotation times SPD: recovers both factors.
        let r0 = rot(Vec3::new(0.2, 1.0, -0.5), 0.9);
        let s0 = Mat3::from_cols(
            Vec3::new(2.0, 0.3, 0.1),
            Vec3::new(0.3, 1.5, -0.2),
            Vec3::new(0.1, -0.2, 1.0),
        );
        let (r, s) = polar(r0 * s0);
        assert!(norm2(r - r0) < 1e-10);
        assert!(norm2(s - s0) < 1e-10);
    }
}

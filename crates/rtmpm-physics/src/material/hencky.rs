//! Hencky (logarithmic) strain: the St.Venant-Kirchhoff stress of the log-strain models and the
//! one return mapping they share (Drucker-Prager, von Mises, ...): decompose the trial `F`,
//! project its principal log strain with the model's rule, recompose. Klar et al. 2016,
//! "Drucker-Prager elastoplasticity for sand animation", section 7.3.

use crate::math::{Mat3, Real, Vec3};
use crate::svd::svd3;

/// Singular values are clamped to at least this value before `ln` (degenerate or inverted `F`):
/// the Hencky strain stays finite (`ln(1e-4) ~ -9.2`), i.e. a very compressed, uninverted state.
pub const HENCKY_SIGMA_MIN: Real = 1e-4;

/// Hencky (logarithmic) principal strain `ln(max(sigma, HENCKY_SIGMA_MIN))`.
pub fn strain(sigma: Vec3) -> Vec3 {
    sigma.max(Vec3::splat(HENCKY_SIGMA_MIN)).ln()
}

/// Principal Kirchhoff stress of St.Venant-Kirchhoff with Hencky strain:
/// `2 mu eps + lambda tr(eps)` (Klar 2016, eq. 26 times `F^T`).
pub fn principal_stress(eps: Vec3, mu: Real, lambda: Real) -> Vec3 {
    2.0 * mu * eps + Vec3::splat(lambda * (eps.x + eps.y + eps.z))
}

/// Kirchhoff stress `tau = U (2 mu eps + lambda tr(eps) I) U^T`, `eps = ln(sigma)`, `F = U sigma V^T`.
pub fn kirchhoff(f: Mat3, mu: Real, lambda: Real) -> Mat3 {
    let (u, sigma, _) = svd3(f);
    let t = principal_stress(strain(sigma), mu, lambda);
    u * Mat3::from_diagonal(t) * u.transpose()
}

/// The return mapping of a log-strain model: `F = U sigma V^T`, `eps = ln(sigma)`; the model's
/// rule maps `(eps, plastic)` to the admissible strain and the new plastic state, or `None` when
/// the step is elastic (then `f_trial` is returned unchanged); else `U exp(eps') V^T`.
pub fn return_map(
    f_trial: Mat3,
    plastic: &mut Real,
    rule: impl FnOnce(Vec3, Real) -> Option<(Vec3, Real)>,
) -> Mat3 {
    let (u, sigma, v) = svd3(f_trial);
    let Some((eps, p)) = rule(strain(sigma), *plastic) else {
        return f_trial;
    };
    *plastic = p;
    u * Mat3::from_diagonal(eps.exp()) * v.transpose()
}

//! Compressible NeoHookean hyperelasticity (Bonet & Wood, "Nonlinear continuum mechanics", eq. 6.28).

use super::constitutive::Constitutive;
use super::params::{Elasticity, ParamError};
use crate::math::{Mat3, Real, Vec3};

/// Smallest `J` used in `ln(J)`: `J <= 0` (inverted element) is clamped to this value so the
/// stress stays finite and strongly repulsive (`lambda ln(1e-4) ~ -9.2 lambda`).
pub const NEO_HOOKEAN_J_MIN: Real = 1e-4;

/// Compressible NeoHookean solid.
#[derive(Clone, Debug, PartialEq)]
pub struct NeoHookean {
    /// Shear modulus mu (Pa).
    pub mu: Real,
    /// First Lamé parameter lambda (Pa).
    pub lambda: Real,
}

impl NeoHookean {
    /// From Young's modulus (Pa) and Poisson's ratio.
    pub fn from_young_poisson(youngs_modulus: Real, poisson_ratio: Real) -> Self {
        let (mu, lambda) = super::constitutive::lame(youngs_modulus, poisson_ratio);
        Self { mu, lambda }
    }
}

impl Constitutive for NeoHookean {
    const NAME: &'static str = "neo_hookean";
    const SUMMARY: &'static str = "compressible NeoHookean hyperelastic solid";
    const GPU_PARAMS: &'static [&'static str] = &["mu", "lambda"];
    const COLOUR: [f32; 3] = [0.88, 0.22, 0.25];
    type Params = Elasticity;

    fn new(p: Elasticity) -> Result<Self, ParamError> {
        let (mu, lambda) = p.lame()?;
        Ok(Self { mu, lambda })
    }

    /// Kirchhoff stress `tau = mu (F F^T - I) + lambda ln(J) I`, `J` clamped to
    /// [`NEO_HOOKEAN_J_MIN`].
    fn kirchhoff(&self, f: Mat3, _plastic: Real, _c: Mat3) -> Mat3 {
        let j = f.determinant().max(NEO_HOOKEAN_J_MIN);
        // Bonet & Wood eq. 6.28 times J: tau = mu (b - I) + lambda ln(J) I, b = F F^T.
        (f * f.transpose() - Mat3::IDENTITY) * self.mu
            + Mat3::from_diagonal(Vec3::splat(self.lambda * j.ln()))
    }

    fn wave_modulus(&self) -> Real {
        self.lambda + 2.0 * self.mu
    }

    fn gpu_params(&self) -> Vec<Real> {
        vec![self.mu, self.lambda]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Mat3, b: Mat3, tol: Real) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() <= tol)
    }

    const M: NeoHookean = NeoHookean {
        mu: 1.0,
        lambda: 2.0,
    };

    #[test]
    fn zero_stress_at_rest_and_under_rotation() {
        assert_eq!(M.kirchhoff(Mat3::IDENTITY, 0.0, Mat3::ZERO), Mat3::ZERO);
        let r = Mat3::from_axis_angle(Vec3::new(1.0, 0.0, 2.0).normalize(), 0.4);
        assert!(close(M.kirchhoff(r, 0.0, Mat3::ZERO), Mat3::ZERO, 1e-6));
    }

    #[test]
    fn uniaxial_stretch_hand_computed() {
        // F = diag(1.1, 1, 1): F F^T - I = diag(0.21, 0, 0), ln J = ln 1.1 = 0.0953102,
        // lambda ln J = 0.1906204; tau = diag(0.21 + 0.1906204, 0.1906204, 0.1906204).
        let tau = M.kirchhoff(
            Mat3::from_diagonal(Vec3::new(1.1, 1.0, 1.0)),
            0.0,
            Mat3::ZERO,
        );
        let expected = Mat3::from_diagonal(Vec3::new(0.4006204, 0.1906204, 0.1906204));
        assert!(close(tau, expected, 1e-6), "{tau:?}");
    }

    #[test]
    fn inverted_is_finite_and_repulsive() {
        let tau = M.kirchhoff(
            Mat3::from_diagonal(Vec3::new(1.0, 1.0, -0.5)),
            0.0,
            Mat3::ZERO,
        );
        assert!(tau.is_finite());
        // pressure term lambda ln(J_MIN) < 0 dominates: compressive (pushes back out)
        assert!(tau.z_axis.z < 0.0);
        assert!((tau.x_axis.x - 2.0 * NEO_HOOKEAN_J_MIN.ln()).abs() < 1e-5);
    }

    #[test]
    fn frame_indifference() {
        let r = Mat3::from_axis_angle(Vec3::new(0.3, -1.0, 0.5).normalize(), 2.2);
        let f = Mat3::from_cols(
            Vec3::new(1.1, 0.2, -0.1),
            Vec3::new(0.05, 0.9, 0.1),
            Vec3::new(0.0, 0.3, 1.2),
        );
        let lhs = M.kirchhoff(r * f, 0.0, Mat3::ZERO);
        let rhs = r * M.kirchhoff(f, 0.0, Mat3::ZERO) * r.transpose();
        assert!(close(lhs, rhs, 1e-5), "{lhs:?} vs {rhs:?}");
    }
}

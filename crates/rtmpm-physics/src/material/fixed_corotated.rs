//! FixedCorotated hyperelasticity (Stomakhin et al. 2012, "Energetically consistent invertible
//! elasticity").

use super::constitutive::Constitutive;
use super::params::{Elasticity, ParamError};
use crate::math::{Mat3, Real, Vec3};
use crate::svd::polar;

/// FixedCorotated hyperelastic solid.
#[derive(Clone, Debug, PartialEq)]
pub struct FixedCorotated {
    /// Shear modulus mu (Pa).
    pub mu: Real,
    /// First Lamé parameter lambda (Pa).
    pub lambda: Real,
}

/// Kirchhoff stress of the FixedCorotated model with Lamé parameters `mu`, `lambda`:
/// `tau = P F^T = 2 mu (F - R) F^T + lambda (J - 1) J I` (Stomakhin 2012, eq. 2, with `R` the
/// rotation of the polar decomposition of `F`; well defined for inverted `F`).
pub fn fixed_corotated_kirchhoff(f: Mat3, mu: Real, lambda: Real) -> Mat3 {
    let (r, _) = polar(f);
    let j = f.determinant();
    (f - r) * f.transpose() * (2.0 * mu) + Mat3::from_diagonal(Vec3::splat(lambda * (j - 1.0) * j))
}

impl FixedCorotated {
    /// From Young's modulus (Pa) and Poisson's ratio.
    pub fn from_young_poisson(youngs_modulus: Real, poisson_ratio: Real) -> Self {
        let (mu, lambda) = super::constitutive::lame(youngs_modulus, poisson_ratio);
        Self { mu, lambda }
    }
}

impl Constitutive for FixedCorotated {
    const NAME: &'static str = "fixed_corotated";
    const SUMMARY: &'static str = "FixedCorotated hyperelastic solid (jelly, rubber)";
    const GPU_PARAMS: &'static [&'static str] = &["mu", "lambda"];
    const COLOUR: [f32; 3] = [0.88, 0.22, 0.25];
    type Params = Elasticity;

    fn new(p: Elasticity) -> Result<Self, ParamError> {
        let (mu, lambda) = p.lame()?;
        Ok(Self { mu, lambda })
    }

    /// Kirchhoff stress `tau = 2 mu (F - R) F^T + lambda (J - 1) J I`.
    fn kirchhoff(&self, f: Mat3, _plastic: Real, _c: Mat3) -> Mat3 {
        fixed_corotated_kirchhoff(f, self.mu, self.lambda)
    }

    fn wave_modulus(&self) -> Real {
        self.lambda + 2.0 * self.mu
    }

    /// Strain energy density per reference volume (Stomakhin et al. 2012):
    /// psi = mu |F - R|^2 + lambda / 2 (J - 1)^2.
    fn energy_density(&self, f: Mat3) -> Option<Real> {
        let (r, _) = crate::svd::polar(f);
        let j = f.determinant();
        Some(self.mu * crate::math::norm2(f - r) + 0.5 * self.lambda * (j - 1.0) * (j - 1.0))
    }

    fn gpu_params(&self) -> Vec<Real> {
        vec![self.mu, self.lambda]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn energy_is_zero_at_rest_and_its_derivative_is_the_stress() {
        let m = FixedCorotated {
            mu: 3.0,
            lambda: 5.0,
        };
        assert!(m.energy_density(Mat3::IDENTITY).unwrap_or(Real::NAN).abs() < 1e-6);
        // P = d psi / d F by central differences must match tau F^-T (tau = P F^T).
        let f = Mat3::from_cols_array(&[1.1, 0.05, -0.02, 0.03, 0.95, 0.04, -0.01, 0.02, 1.05]);
        let p = m.kirchhoff(f, 0.0, Mat3::ZERO) * f.transpose().inverse();
        let h = 1e-3;
        for k in 0..9 {
            let mut a = f.to_cols_array();
            let mut b = a;
            a[k] += h;
            b[k] -= h;
            let d = (m
                .energy_density(Mat3::from_cols_array(&a))
                .unwrap_or(Real::NAN)
                - m.energy_density(Mat3::from_cols_array(&b))
                    .unwrap_or(Real::NAN))
                / (2.0 * h);
            let pk = p.to_cols_array()[k];
            assert!(
                (d - pk).abs() < 2e-2 * (1.0 + pk.abs()),
                "component {k}: d psi/dF = {d}, P = {pk}"
            );
        }
    }

    fn close(a: Mat3, b: Mat3, tol: Real) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() <= tol)
    }

    const M: FixedCorotated = FixedCorotated {
        mu: 1.0,
        lambda: 2.0,
    };

    #[test]
    fn zero_stress_at_rest_and_under_rotation() {
        assert!(close(
            M.kirchhoff(Mat3::IDENTITY, 0.0, Mat3::ZERO),
            Mat3::ZERO,
            1e-7
        ));
        let r = Mat3::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize(), 1.3);
        assert!(close(M.kirchhoff(r, 0.0, Mat3::ZERO), Mat3::ZERO, 1e-6));
    }

    #[test]
    fn uniaxial_stretch_hand_computed() {
        // F = diag(1.1, 1, 1): R = I, F - R = diag(0.1, 0, 0), (F - R) F^T = diag(0.11, 0, 0),
        // J = 1.1, lambda (J - 1) J = 2 * 0.1 * 1.1 = 0.22.
        // tau = 2 * 1 * diag(0.11, 0, 0) + 0.22 I = diag(0.44, 0.22, 0.22).
        let tau = M.kirchhoff(
            Mat3::from_diagonal(Vec3::new(1.1, 1.0, 1.0)),
            0.0,
            Mat3::ZERO,
        );
        assert!(
            close(tau, Mat3::from_diagonal(Vec3::new(0.44, 0.22, 0.22)), 1e-6),
            "{tau:?}"
        );
    }

    #[test]
    fn inverted_hand_computed() {
        // F = diag(1, 1, -1): the SVD is already diagonal, u = v = I, sigma = (1, 1, -1), so
        // R = I (a rotation, not the reflection F itself) and F - R = diag(0, 0, -2),
        // (F - R) F^T = diag(0, 0, 2), J = -1, lambda (J - 1) J = 2 * (-2) * (-1) = 4.
        // tau = 2 * diag(0, 0, 2) + 4 I = diag(4, 4, 8): pushes the inverted axis back out.
        let tau = M.kirchhoff(
            Mat3::from_diagonal(Vec3::new(1.0, 1.0, -1.0)),
            0.0,
            Mat3::ZERO,
        );
        assert!(
            close(tau, Mat3::from_diagonal(Vec3::new(4.0, 4.0, 8.0)), 1e-5),
            "{tau:?}"
        );
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
        // tau is symmetric.
        let t = M.kirchhoff(f, 0.0, Mat3::ZERO);
        assert!(close(t, t.transpose(), 1e-6));
    }

    #[test]
    fn constructor_from_young_poisson() {
        let m = FixedCorotated::from_young_poisson(1e4, 0.25);
        assert!((m.mu - 4000.0).abs() < 1e-2 && (m.lambda - 4000.0).abs() < 1e-2);
    }
}

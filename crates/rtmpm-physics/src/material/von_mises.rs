//! von Mises (J2) elastoplasticity with Hencky strain and linear isotropic hardening: radial
//! return in principal log-strain space (Simo & Hughes 1998, "Computational inelasticity",
//! box 3.1; with Hencky strain as in Simo 1992).

use super::constitutive::Constitutive;
use super::hencky;
use super::params::{self, Elasticity, ParamError};
use crate::math::{Mat3, Real, Vec3};
use serde::Deserialize;

/// von Mises metal/plasticine. The plastic scalar is the equivalent plastic strain
/// `eps_p = sum sqrt(2/3) delta gamma` (uniaxial plastic strain), which drives the hardening.
#[derive(Clone, Debug, PartialEq)]
pub struct VonMises {
    /// Shear modulus mu (Pa).
    pub mu: Real,
    /// First Lamé parameter lambda (Pa).
    pub lambda: Real,
    /// Initial yield stress (Pa).
    pub yield_stress: Real,
    /// Linear isotropic hardening modulus (Pa); 0 = perfectly plastic.
    pub hardening: Real,
}

/// The scene parameters of a von Mises solid.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VonMisesParams {
    pub youngs_modulus: Option<f32>,
    pub poisson_ratio: Option<f32>,
    pub mu: Option<f32>,
    pub lambda: Option<f32>,
    /// Initial yield stress (Pa), required.
    pub yield_stress: Option<f32>,
    /// Linear isotropic hardening modulus (Pa, default 0).
    pub hardening_modulus: Option<f32>,
}

impl VonMises {
    /// From Young's modulus (Pa), Poisson's ratio, yield stress (Pa) and hardening modulus (Pa).
    pub fn from_young_poisson(
        youngs_modulus: Real,
        poisson_ratio: Real,
        yield_stress: Real,
        hardening: Real,
    ) -> Self {
        let (mu, lambda) = super::constitutive::lame(youngs_modulus, poisson_ratio);
        Self {
            mu,
            lambda,
            yield_stress,
            hardening,
        }
    }

    /// Radius of the yield surface `||dev tau|| <= sqrt(2/3) (sigma_y + H eps_p)`.
    pub fn yield_radius(&self, eps_p: Real) -> Real {
        Real::sqrt(2.0 / 3.0) * (self.yield_stress + self.hardening * eps_p)
    }

    /// Radial return of the principal log strain: `f = 2 mu ||dev eps|| - sqrt(2/3)(sigma_y +
    /// H eps_p)`; if `f > 0`, `delta gamma = f / (2 mu + 2 H / 3)` (Simo & Hughes box 3.1),
    /// `dev eps -= delta gamma n`, `eps_p += sqrt(2/3) delta gamma`. Returns the new strain and the
    /// increment of `eps_p` (0 = elastic).
    pub fn project_strain(&self, eps: Vec3, eps_p: Real) -> (Vec3, Real) {
        let tr = eps.x + eps.y + eps.z;
        let e_hat = eps - Vec3::splat(tr / 3.0);
        let norm = e_hat.length();
        let f = 2.0 * self.mu * norm - self.yield_radius(eps_p);
        if f <= 0.0 || norm <= 0.0 {
            return (eps, 0.0);
        }
        let dg = f / (2.0 * self.mu + 2.0 * self.hardening / 3.0);
        (eps - e_hat * (dg / norm), Real::sqrt(2.0 / 3.0) * dg)
    }
}

impl Constitutive for VonMises {
    const NAME: &'static str = "von_mises";
    const SUMMARY: &'static str =
        "von Mises (J2) metal/plasticine: Hencky elasticity, radial return, linear hardening";
    const GPU_PARAMS: &'static [&'static str] = &["mu", "lambda", "yield_stress", "hardening"];
    const COLOUR: [f32; 3] = [0.60, 0.38, 0.82];
    type Params = VonMisesParams;

    fn new(p: VonMisesParams) -> Result<Self, ParamError> {
        let (mu, lambda) = Elasticity {
            youngs_modulus: p.youngs_modulus,
            poisson_ratio: p.poisson_ratio,
            mu: p.mu,
            lambda: p.lambda,
        }
        .lame()?;
        let ys = params::required("yield_stress", p.yield_stress, "von_mises", "1e4")?;
        Ok(VonMises {
            mu,
            lambda,
            yield_stress: params::positive("yield_stress", ys, "yield stress")?,
            hardening: params::non_negative(
                "hardening_modulus",
                p.hardening_modulus,
                0.0,
                "hardening modulus",
            )?,
        })
    }

    /// Kirchhoff stress (St.Venant-Kirchhoff with Hencky strain), see [`hencky::kirchhoff`].
    fn kirchhoff(&self, f: Mat3, _eps_p: Real, _c: Mat3) -> Mat3 {
        hencky::kirchhoff(f, self.mu, self.lambda)
    }

    /// Plastic projection of the trial elastic `F` ([`VonMises::project_strain`] through
    /// [`hencky::return_map`]); elastic states return `f_trial` unchanged.
    fn project(&self, f_trial: Mat3, eps_p: &mut Real, _dt: Real) -> Mat3 {
        hencky::return_map(f_trial, eps_p, |eps, eps_p| {
            let (eps, dp) = self.project_strain(eps, eps_p);
            (dp > 0.0).then_some((eps, eps_p + dp))
        })
    }

    fn wave_modulus(&self) -> Real {
        self.lambda + 2.0 * self.mu
    }

    fn gpu_params(&self) -> Vec<Real> {
        vec![self.mu, self.lambda, self.yield_stress, self.hardening]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn close(a: Mat3, b: Mat3, tol: Real) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() <= tol)
    }

    fn dev_norm(tau: Mat3) -> Real {
        let p = (tau.x_axis.x + tau.y_axis.y + tau.z_axis.z) / 3.0;
        crate::math::norm2(tau - Mat3::IDENTITY * p).sqrt()
    }

    fn metal(h: Real) -> VonMises {
        VonMises {
            mu: 100.0,
            lambda: 200.0,
            yield_stress: 1.0,
            hardening: h,
        }
    }

    #[test]
    fn zero_stress_at_rest() {
        assert_eq!(
            metal(0.0).kirchhoff(Mat3::IDENTITY, 0.0, Mat3::ZERO),
            Mat3::ZERO
        );
    }

    #[test]
    fn uniaxial_stretch_hand_computed() {
        // mu = 100, lambda = 200, F = diag(1.01, 1, 1): eps = (ln 1.01, 0, 0) = (0.00995033, 0, 0);
        // tau = (2*100*0.00995033 + 200*0.00995033, 200*0.00995033, same) = (3.980132, 1.990066, ..).
        let tau = metal(0.0).kirchhoff(
            Mat3::from_diagonal(Vec3::new(1.01, 1.0, 1.0)),
            0.0,
            Mat3::ZERO,
        );
        let expected = Mat3::from_diagonal(Vec3::new(3.980132, 1.990066, 1.990066));
        assert!(close(tau, expected, 1e-4), "{tau:?}");
    }

    #[test]
    fn frame_indifference() {
        let m = metal(0.0);
        let r = Mat3::from_axis_angle(Vec3::new(0.3, -1.0, 0.5).normalize(), 2.2);
        let f = Mat3::from_cols(
            Vec3::new(1.1, 0.2, -0.1),
            Vec3::new(0.05, 0.9, 0.1),
            Vec3::new(0.0, 0.3, 1.2),
        );
        let lhs = m.kirchhoff(r * f, 0.0, Mat3::ZERO);
        let rhs = r * m.kirchhoff(f, 0.0, Mat3::ZERO) * r.transpose();
        assert!(close(lhs, rhs, 1e-3), "{lhs:?} vs {rhs:?}");
    }

    #[test]
    fn below_yield_unchanged() {
        // eps_hat norm of diag(1.001, 0.999, 1): ~sqrt(2) 1e-3, 2 mu * that = 0.283 < sqrt(2/3) = 0.816.
        let m = metal(0.0);
        let f = Mat3::from_diagonal(Vec3::new(1.001, 0.999, 1.0));
        let mut ep = 0.0;
        assert_eq!(m.project(f, &mut ep, 1e-3), f);
        assert_eq!(ep, 0.0);
        // Pure volumetric strain never yields.
        let f = Mat3::from_diagonal(Vec3::splat(0.7));
        assert_eq!(m.project(f, &mut ep, 1e-3), f);
        assert_eq!(ep, 0.0);
    }

    #[test]
    fn shear_hand_computed_perfect_plasticity() {
        // eps = (0.01, -0.01, 0): ||eps_hat|| = 0.01414214, 2 mu ||eps_hat|| = 2.828427,
        // f = 2.828427 - 0.8164966 = 2.011930, dg = f / 200 = 0.01005965,
        // eps_p += sqrt(2/3) dg = 0.00821365; new ||dev tau|| = sqrt(2/3) sigma_y exactly.
        let m = metal(0.0);
        let (h, dp) = m.project_strain(Vec3::new(0.01, -0.01, 0.0), 0.0);
        assert!((dp - 0.00821365).abs() < 1e-6, "{dp}");
        let tau = hencky_principal_stress_dev_norm(&m, h);
        assert!((tau - m.yield_radius(0.0)).abs() < 1e-4, "{tau}");
    }

    fn hencky_principal_stress_dev_norm(m: &VonMises, eps: Vec3) -> Real {
        let tr = eps.x + eps.y + eps.z;
        (2.0 * m.mu * (eps - Vec3::splat(tr / 3.0))).length()
    }

    #[test]
    fn never_exceeds_yield_surface() {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(3);
        for h in [0.0, 50.0] {
            let m = metal(h);
            for _ in 0..500 {
                let f = Mat3::IDENTITY
                    + 0.2
                        * Mat3::from_cols_array(&std::array::from_fn(|_| {
                            rng.random_range(-1.0..1.0)
                        }));
                let mut ep = rng.random_range(0.0..0.1);
                let ep0 = ep;
                let fe = m.project(f, &mut ep, 1e-3);
                assert!(ep >= ep0);
                let radius = m.yield_radius(ep);
                let d = dev_norm(m.kirchhoff(fe, 0.0, Mat3::ZERO));
                assert!(d <= radius * (1.0 + 1e-3) + 1e-4, "{d} > {radius}");
                if ep > ep0 {
                    // consistent return: exactly on the (hardened) surface
                    assert!(
                        (d - radius).abs() <= radius * 1e-3 + 1e-4,
                        "{d} vs {radius}"
                    );
                    // volume (trace of log strain) is preserved
                    assert!((fe.determinant() - f.determinant()).abs() < 1e-4);
                }
            }
        }
    }
}

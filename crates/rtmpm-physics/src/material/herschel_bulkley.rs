//! Herschel-Bulkley viscoplastic fluid (mud, lava, toothpaste, fresh concrete; Bingham when the
//! flow index is 1): the weakly compressible pressure of [`Fluid`] for the volume, and an
//! elastic-viscoplastic shear stress. Below the yield stress the shear response is elastic
//! (Hencky strain, shear modulus `mu`); above it the excess relaxes at the Herschel-Bulkley rate
//! `gamma_dot = ((tau - tau_y) / K)^(1/n)`, so that steady shear flow carries
//! `tau = tau_y + K gamma_dot^n`. The elastic-viscoplastic scheme is that of Yue et al. 2015
//! ("Continuum foam: a material point method for shear-dependent flows", ACM TOG 34(5)), written
//! on the principal Hencky strain like the other log-strain models ([`super::hencky`]).

use super::constitutive::Constitutive;
use super::fluid::{EosName, Fluid};
use super::hencky;
use super::params::{self, ParamError};
use crate::math::{Mat3, Real, Vec3};
use crate::svd::svd3;
use serde::Deserialize;

/// Bisection steps of the Herschel-Bulkley relaxation (2^-40 of the overstress: exact in f32
/// and to 1e-12 in f64).
pub const HB_BISECTION_STEPS: u32 = 40;

/// Herschel-Bulkley fluid. The plastic scalar is the accumulated plastic shear strain.
#[derive(Clone, Debug, PartialEq)]
pub struct HerschelBulkley {
    /// The volume: bulk modulus and equation of state (no Newtonian viscosity).
    pub volume: Fluid,
    /// Elastic shear modulus below the yield stress (Pa).
    pub mu: Real,
    /// Yield stress tau_y (Pa), in shear.
    pub yield_stress: Real,
    /// Consistency K (Pa s^n).
    pub consistency: Real,
    /// Flow index n (1: Bingham; < 1 shear-thinning; > 1 shear-thickening).
    pub flow_index: Real,
}

/// The scene parameters of a Herschel-Bulkley fluid.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HerschelBulkleyParams {
    /// Bulk modulus (Pa), required.
    pub bulk_modulus: Option<f32>,
    /// `"linear"` or `"tait"` (as a fluid).
    pub eos: Option<EosName>,
    /// Tait exponent.
    pub gamma: Option<f32>,
    /// Elastic shear modulus (Pa), required.
    pub shear_modulus: Option<f32>,
    /// Yield stress (Pa), required, >= 0.
    pub yield_stress: Option<f32>,
    /// Consistency K (Pa s^n), required, >= 0.
    pub consistency: Option<f32>,
    /// Flow index n (default 1: Bingham), > 0.
    pub flow_index: Option<f32>,
}

impl HerschelBulkley {
    /// The shear stress after the relaxation of a step of length `dt` from the elastic trial
    /// `tau_trial > tau_y`: the root in `(tau_y, tau_trial]` of
    /// `tau_trial - tau = mu dt ((tau - tau_y) / K)^(1/n)` (the elastic relaxation of the
    /// overstress equals the Herschel-Bulkley flow of the step). Closed form for Bingham
    /// (`n = 1`), the yield stress itself when `K = 0` (rigid-perfectly plastic), else bisection.
    pub fn relax(&self, tau_trial: Real, dt: Real) -> Real {
        let (ty, k, n) = (self.yield_stress, self.consistency, self.flow_index);
        if k <= 0.0 {
            return ty;
        }
        let a = self.mu * dt / k;
        if n == 1.0 {
            return (tau_trial + a * ty) / (1.0 + a);
        }
        let (mut lo, mut hi) = (ty, tau_trial);
        for _ in 0..HB_BISECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            let g = tau_trial - mid - self.mu * dt * ((mid - ty) / k).powf(1.0 / n);
            if g > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// Return mapping of the principal log strain over a step `dt`: the equivalent shear stress
    /// `tau = sqrt(2) mu ||dev eps||` (the shear stress in simple shear); above the yield stress
    /// the deviatoric strain is scaled to [`HerschelBulkley::relax`]'s stress, the volume kept.
    /// Returns the new strain and plastic shear strain, `None` when elastic.
    pub fn project_strain(&self, eps: Vec3, gamma_p: Real, dt: Real) -> Option<(Vec3, Real)> {
        let tr = eps.x + eps.y + eps.z;
        let e_hat = eps - Vec3::splat(tr / 3.0);
        let tau = Real::sqrt(2.0) * self.mu * e_hat.length();
        if tau <= self.yield_stress || tau <= 0.0 {
            return None;
        }
        let t = self.relax(tau, dt);
        Some((
            e_hat * (t / tau) + Vec3::splat(tr / 3.0),
            gamma_p + (tau - t) / self.mu,
        ))
    }
}

impl Constitutive for HerschelBulkley {
    const NAME: &'static str = "herschel_bulkley";
    const SUMMARY: &'static str = "Herschel-Bulkley viscoplastic fluid (Bingham when n = 1): yield stress, consistency, flow index";
    const GPU_PARAMS: &'static [&'static str] = &[
        "bulk_modulus",
        "tait",
        "gamma",
        "shear_modulus",
        "yield_stress",
        "consistency",
        "flow_index",
    ];
    const COLOUR: [f32; 3] = [0.45, 0.30, 0.17];
    type Params = HerschelBulkleyParams;

    fn new(p: HerschelBulkleyParams) -> Result<Self, ParamError> {
        let volume = Fluid::new(super::fluid::FluidParams {
            bulk_modulus: p.bulk_modulus,
            eos: p.eos,
            gamma: p.gamma,
            viscosity: None,
        })?;
        let mu = params::required("shear_modulus", p.shear_modulus, Self::NAME, "1e4")?;
        let ty = params::required("yield_stress", p.yield_stress, Self::NAME, "100")?;
        let k = params::required("consistency", p.consistency, Self::NAME, "10")?;
        let n = params::positive("flow_index", p.flow_index.unwrap_or(1.0), "flow index n")?;
        Ok(HerschelBulkley {
            volume,
            mu: params::positive("shear_modulus", mu, "shear modulus (Pa)")?,
            yield_stress: params::non_negative("yield_stress", Some(ty), 0.0, "yield stress (Pa)")?,
            consistency: params::non_negative(
                "consistency",
                Some(k),
                0.0,
                "consistency K (Pa s^n)",
            )?,
            flow_index: n,
        })
    }

    /// `tau = U diag(2 mu dev eps) U^T - J p(J) I`, `eps` the principal Hencky strain of `F`.
    fn kirchhoff(&self, f: Mat3, _gamma_p: Real, _c: Mat3) -> Mat3 {
        let (u, sigma, _) = svd3(f);
        let eps = hencky::strain(sigma);
        let e_hat = eps - Vec3::splat((eps.x + eps.y + eps.z) / 3.0);
        let j = f.determinant().max(super::fluid::FLUID_J_MIN);
        u * Mat3::from_diagonal(2.0 * self.mu * e_hat) * u.transpose()
            - Mat3::from_diagonal(Vec3::splat(j * self.volume.pressure(j)))
    }

    /// The Herschel-Bulkley relaxation of the shear strain over the step (through
    /// [`hencky::return_map`]); the plastic scalar accumulates the plastic shear strain.
    fn project(&self, f_trial: Mat3, gamma_p: &mut Real, dt: Real) -> Mat3 {
        hencky::return_map(f_trial, gamma_p, |eps, g| self.project_strain(eps, g, dt))
    }

    fn wave_modulus(&self) -> Real {
        self.volume.wave_modulus() + 4.0 / 3.0 * self.mu
    }

    fn gpu_params(&self) -> Vec<Real> {
        let v = self.volume.gpu_params();
        vec![
            v[0],
            v[1],
            v[2],
            self.mu,
            self.yield_stress,
            self.consistency,
            self.flow_index,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mud(ty: Real, k: Real, n: Real) -> HerschelBulkley {
        HerschelBulkley {
            volume: Fluid {
                bulk_modulus: 1e5,
                eos: super::super::Eos::Linear,
                viscosity: 0.0,
            },
            mu: 1e4,
            yield_stress: ty,
            consistency: k,
            flow_index: n,
        }
    }

    /// Shear stress tau_xy of a state.
    fn shear(m: &HerschelBulkley, f: Mat3) -> Real {
        m.kirchhoff(f, 0.0, Mat3::ZERO).y_axis.x
    }

    #[test]
    fn zero_stress_at_rest() {
        assert_eq!(
            mud(100.0, 10.0, 1.0).kirchhoff(Mat3::IDENTITY, 0.0, Mat3::ZERO),
            Mat3::ZERO
        );
    }

    #[test]
    fn isochoric_stretch_hand_computed() {
        // F = diag(1.01, 1/1.01, 1): eps = (ln 1.01, -ln 1.01, 0) = (0.00995033, -0.00995033, 0),
        // traceless, J = 1: tau = 2 mu eps = (199.0066, -199.0066, 0) with mu = 1e4.
        let f = Mat3::from_diagonal(Vec3::new(1.01, 1.0 / 1.01, 1.0));
        let tau = mud(100.0, 10.0, 1.0).kirchhoff(f, 0.0, Mat3::ZERO);
        assert!((tau.x_axis.x - 199.0066).abs() < 1e-2, "{tau:?}");
        assert!((tau.y_axis.y + 199.0066).abs() < 1e-2, "{tau:?}");
        assert!(tau.z_axis.z.abs() < 1e-3, "{tau:?}");
    }

    #[test]
    fn bingham_relaxation_hand_computed_and_the_root_of_its_equation() {
        // tau_y = 100, K = 10, mu = 1e4, dt = 1e-3: a = mu dt / K = 1; from tau_trial = 300,
        // tau = (300 + 100) / 2 = 200, and 300 - 200 = 1e4 * 1e-3 * (200 - 100) / 10 = 100.
        let m = mud(100.0, 10.0, 1.0);
        assert!((m.relax(300.0, 1e-3) - 200.0).abs() < 1e-3);
        // Shear-thinning (n = 0.5): the bisection's root satisfies the equation.
        let m = mud(100.0, 10.0, 0.5);
        let t = m.relax(300.0, 1e-3);
        let residual = 300.0 - t - 1e4 * 1e-3 * ((t - 100.0) / 10.0).powf(2.0);
        assert!(
            t > 100.0 && t < 300.0 && residual.abs() < 1e-2,
            "{t} {residual}"
        );
        // K = 0: rigid-perfectly plastic, back to the yield stress.
        assert_eq!(mud(100.0, 0.0, 1.0).relax(300.0, 1e-3), 100.0);
    }

    #[test]
    fn below_the_yield_stress_the_shear_is_elastic() {
        let m = mud(100.0, 10.0, 1.0);
        let f = Mat3::from_cols(Vec3::X, Vec3::new(0.005, 1.0, 0.0), Vec3::Z);
        let mut g = 0.0;
        assert_eq!(m.project(f, &mut g, 1e-3), f);
        assert_eq!(g, 0.0);
        assert!((shear(&m, f) - 50.0).abs() < 0.5, "{}", shear(&m, f));
    }

    #[test]
    fn return_map_keeps_the_volume_and_is_frame_indifferent() {
        let m = mud(100.0, 10.0, 0.7);
        let f = Mat3::from_cols(
            Vec3::new(1.1, 0.2, -0.05),
            Vec3::new(0.1, 0.9, 0.05),
            Vec3::new(0.0, 0.1, 1.02),
        );
        let mut g = 0.0;
        let fe = m.project(f, &mut g, 1e-3);
        assert!(g > 0.0);
        assert!((fe.determinant() - f.determinant()).abs() < 1e-5);
        let r = Mat3::from_axis_angle(Vec3::new(0.2, 1.0, -0.4).normalize(), 1.3);
        let mut g2 = 0.0;
        let fr = m.project(r * f, &mut g2, 1e-3);
        assert!((fr - r * fe).to_cols_array().iter().all(|x| x.abs() < 1e-4));
        assert!((g - g2).abs() < 1e-6);
    }

    #[test]
    fn steady_simple_shear_carries_the_herschel_bulkley_stress() {
        // Simple shear at rate gamma_dot, many small steps: tau_xy -> tau_y + K gamma_dot^n.
        for (n, rate) in [(1.0, 2.0), (0.5, 4.0), (1.5, 1.0)] {
            let m = mud(100.0, 20.0, n);
            let dt = 1e-4;
            let step = Mat3::from_cols(Vec3::X, Vec3::new(rate * dt, 1.0, 0.0), Vec3::Z);
            let mut f = Mat3::IDENTITY;
            let mut g = 0.0;
            for _ in 0..20000 {
                f = m.project(step * f, &mut g, dt);
            }
            let expected = 100.0 + 20.0 * rate.powf(n);
            let got = shear(&m, f);
            assert!(
                (got - expected).abs() < 0.01 * expected,
                "n = {n}: {got} vs {expected}"
            );
        }
    }

    #[test]
    fn bad_parameters_are_clear_errors() {
        use crate::material::Material;
        let build = |s: &str| {
            Material::parse("mud", 1500.0, "herschel_bulkley", s)
                .err()
                .map(|e| e.field)
        };
        let ok = "bulk_modulus = 1e5\nshear_modulus = 1e4\nyield_stress = 50\nconsistency = 5";
        assert_eq!(build(ok), None);
        assert_eq!(
            build(&format!("{ok}\nflow_index = 0")).as_deref(),
            Some("flow_index")
        );
        assert_eq!(
            build("bulk_modulus = 1e5\nshear_modulus = 1e4\nyield_stress = -1\nconsistency = 5")
                .as_deref(),
            Some("yield_stress")
        );
        assert_eq!(
            build("bulk_modulus = 1e5\nshear_modulus = 1e4\nconsistency = 5").as_deref(),
            Some("yield_stress")
        );
        assert_eq!(
            build(&format!("{ok}\nviscosity = 1")).as_deref(),
            Some("viscosity")
        );
    }
}

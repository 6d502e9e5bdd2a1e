//! Drucker-Prager sand, Klar et al. 2016 ("Drucker-Prager elastoplasticity for sand animation"):
//! St.Venant-Kirchhoff elasticity with Hencky strain and a return mapping in log-strain space.

use super::constitutive::Constitutive;
use super::hencky;
use super::params::{self, Elasticity, ParamError};
use crate::math::{Mat3, Real, Vec3};
use serde::Deserialize;

/// Which Mohr-Coulomb states the Drucker-Prager cone is fitted to, for a given friction angle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Cone {
    /// Through Mohr-Coulomb's triaxial-compression corners (Klar 2016, eq. 27): the usual 3D
    /// fit. In plane-strain flow it is stronger than Mohr-Coulomb: 30 degrees acts like 43.9.
    #[default]
    Compression,
    /// Equal to Mohr-Coulomb in plane-strain plastic flow. The return mapping keeps the volume
    /// (no dilatancy), so the out-of-plane deviatoric stress vanishes in plane-strain flow
    /// (tau_z = mean stress) and `||dev tau|| = -alpha tr(tau)` is Mohr-Coulomb's
    /// `(tau_1 - tau_3) = -(tau_1 + tau_3) sin(phi)` when `alpha = sqrt(2) sin(phi) / 3`.
    PlaneStrain,
}

/// Drucker-Prager sand. The plastic scalar accumulates the plastic multipliers `|delta gamma|`
/// of the return mapping (Klar's `q` without hardening: it is only recorded, for output).
#[derive(Clone, Debug, PartialEq)]
pub struct DruckerPrager {
    /// Shear modulus mu (Pa).
    pub mu: Real,
    /// First Lamé parameter lambda (Pa).
    pub lambda: Real,
    /// Friction angle (degrees).
    pub friction_angle: Real,
    /// How the cone is fitted to Mohr-Coulomb at that friction angle.
    pub cone: Cone,
    /// Cohesion, as a log-strain shift of the cone tip (0 = dry sand).
    pub cohesion: Real,
}

/// The scene parameters of Drucker-Prager sand.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DruckerPragerParams {
    pub youngs_modulus: Option<f32>,
    pub poisson_ratio: Option<f32>,
    pub mu: Option<f32>,
    pub lambda: Option<f32>,
    /// Degrees, in [0, 90) (default 30).
    pub friction_angle: Option<f32>,
    /// `"compression"` (default) or `"plane_strain"`.
    pub cone: Option<ConeName>,
    /// Log-strain shift of the cone tip (default 0).
    pub cohesion: Option<f32>,
}

/// The cone fits by name.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ConeName {
    Compression,
    PlaneStrain,
}

impl DruckerPrager {
    /// From Young's modulus (Pa), Poisson's ratio, friction angle (degrees), the cone's fit and
    /// cohesion.
    pub fn from_young_poisson(
        youngs_modulus: Real,
        poisson_ratio: Real,
        friction_angle: Real,
        cone: Cone,
        cohesion: Real,
    ) -> Self {
        let (mu, lambda) = super::constitutive::lame(youngs_modulus, poisson_ratio);
        Self {
            mu,
            lambda,
            friction_angle,
            cone,
            cohesion,
        }
    }

    /// Cone slope alpha of the yield surface `||dev tau|| + alpha tr(tau) <= 0`:
    /// compression cone `sqrt(2/3) 2 sin(phi) / (3 - sin(phi))` (Klar 2016, eq. 27), or
    /// plane-strain cone `sqrt(2) sin(phi) / 3` (see [`Cone::PlaneStrain`]).
    pub fn alpha(&self) -> Real {
        let s = self.friction_angle.to_radians().sin();
        match self.cone {
            Cone::Compression => Real::sqrt(2.0 / 3.0) * 2.0 * s / (3.0 - s),
            Cone::PlaneStrain => Real::sqrt(2.0) * s / 3.0,
        }
    }

    /// Return mapping on the principal log strain (Klar 2016, algorithm 2 / section 7.3, d = 3),
    /// with the cone tip shifted by the cohesion `c`: `eps' = eps - c`, project `eps'`, add `c`
    /// back. Returns the projected principal log strain and the plastic multiplier (0 = elastic).
    pub fn project_strain(&self, eps: Vec3) -> (Vec3, Real) {
        let c = Vec3::splat(self.cohesion);
        let e = eps - c;
        let tr = e.x + e.y + e.z;
        let e_hat = e - Vec3::splat(tr / 3.0);
        let e_hat_norm = e_hat.length();
        // Klar eq. 28: delta gamma = ||eps_hat|| + (d lambda + 2 mu) / (2 mu) tr(eps) alpha
        let dg =
            e_hat_norm + (3.0 * self.lambda + 2.0 * self.mu) / (2.0 * self.mu) * tr * self.alpha();
        if dg <= 0.0 {
            // Case I: inside the cone (includes pure hydrostatic compression).
            (eps, 0.0)
        } else if e_hat_norm <= 0.0 || tr > 0.0 {
            // Case II: tension beyond the (shifted) tip: project to the tip.
            (c, e.length())
        } else {
            // Case III: project along the deviatoric direction onto the cone.
            (e - e_hat * (dg / e_hat_norm) + c, dg)
        }
    }
}

impl Constitutive for DruckerPrager {
    const NAME: &'static str = "drucker_prager";
    const SUMMARY: &'static str =
        "Drucker-Prager sand: Hencky elasticity, log-strain return mapping (Klar 2016)";
    const GPU_PARAMS: &'static [&'static str] = &["mu", "lambda", "alpha", "cohesion"];
    const COLOUR: [f32; 3] = [0.86, 0.70, 0.42];
    type Params = DruckerPragerParams;

    fn new(p: DruckerPragerParams) -> Result<Self, ParamError> {
        let (mu, lambda) = Elasticity {
            youngs_modulus: p.youngs_modulus,
            poisson_ratio: p.poisson_ratio,
            mu: p.mu,
            lambda: p.lambda,
        }
        .lame()?;
        let phi = params::finite("friction_angle", p.friction_angle.unwrap_or(30.0))?;
        if !(0.0..90.0).contains(&phi) {
            return Err(ParamError::new(
                "friction_angle",
                format!("friction angle must be in [0, 90) degrees, got {phi}"),
                "use degrees, typically 25-45 for sand",
            ));
        }
        Ok(DruckerPrager {
            mu,
            lambda,
            friction_angle: phi,
            cone: match p.cone.unwrap_or(ConeName::Compression) {
                ConeName::Compression => Cone::Compression,
                ConeName::PlaneStrain => Cone::PlaneStrain,
            },
            cohesion: params::non_negative("cohesion", p.cohesion, 0.0, "cohesion")?,
        })
    }

    /// Kirchhoff stress (St.Venant-Kirchhoff with Hencky strain), see [`hencky::kirchhoff`].
    fn kirchhoff(&self, f: Mat3, _q: Real, _c: Mat3) -> Mat3 {
        hencky::kirchhoff(f, self.mu, self.lambda)
    }

    /// Plastic projection of the trial elastic `F` ([`DruckerPrager::project_strain`] through
    /// [`hencky::return_map`]); `q` accumulates the plastic multipliers.
    fn project(&self, f_trial: Mat3, q: &mut Real, _dt: Real) -> Mat3 {
        hencky::return_map(f_trial, q, |eps, q| {
            let (eps, dq) = self.project_strain(eps);
            (dq > 0.0).then_some((eps, q + dq))
        })
    }

    fn wave_modulus(&self) -> Real {
        self.lambda + 2.0 * self.mu
    }

    /// The cone slope from its one formula, [`DruckerPrager::alpha`].
    fn gpu_params(&self) -> Vec<Real> {
        vec![self.mu, self.lambda, self.alpha(), self.cohesion]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Mat3, b: Mat3, tol: Real) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() <= tol)
    }

    fn sand() -> DruckerPrager {
        DruckerPrager {
            mu: 1.0,
            lambda: 2.0,
            friction_angle: 30.0,
            cone: Cone::Compression,
            cohesion: 0.0,
        }
    }

    /// Yield function value of a principal log strain (<= 0 inside the cone).
    fn yield_value(m: &DruckerPrager, eps: Vec3) -> Real {
        let e = eps - Vec3::splat(m.cohesion);
        let tr = e.x + e.y + e.z;
        let e_hat = e - Vec3::splat(tr / 3.0);
        e_hat.length() + (3.0 * m.lambda + 2.0 * m.mu) / (2.0 * m.mu) * tr * m.alpha()
    }

    #[test]
    fn alpha_hand_computed() {
        // phi = 30 deg: sin = 0.5, alpha = sqrt(2/3) * 1 / 2.5 = 0.8164966 * 0.4 = 0.3265986.
        assert!((sand().alpha() - 0.3265986).abs() < 1e-6);
    }

    #[test]
    fn plane_strain_alpha_hand_computed() {
        // sqrt(2) * 0.5 / 3 = 0.2357023.
        let m = DruckerPrager {
            cone: Cone::PlaneStrain,
            ..sand()
        };
        assert!((m.alpha() - 0.2357023).abs() < 1e-6);
    }

    /// Mobilised friction `sin(phi) = (tau_1 - tau_3) / -(tau_1 + tau_3)` of the in-plane
    /// principal Kirchhoff stresses after plane-strain simple shear (x moves with y, z fixed)
    /// under isotropic compression, driven through the return mapping to steady plastic flow;
    /// also the out-of-plane stress relative to the in-plane mean (0 in steady flow).
    fn plane_strain_shear(m: &DruckerPrager) -> (Real, Real) {
        let mut fe = Mat3::from_diagonal(Vec3::splat(0.99));
        let mut q = 0.0;
        let shear = Mat3::from_cols(Vec3::X, Vec3::new(1e-4, 1.0, 0.0), Vec3::Z);
        for _ in 0..5000 {
            fe = m.project(shear * fe, &mut q, 1e-3);
        }
        let tau = m.kirchhoff(fe, 0.0, Mat3::ZERO);
        let (txx, tyy, txy) = (tau.x_axis.x, tau.y_axis.y, tau.y_axis.x);
        let centre = 0.5 * (txx + tyy);
        let radius = (0.25 * (txx - tyy) * (txx - tyy) + txy * txy).sqrt();
        (radius / -centre, tau.z_axis.z / centre - 1.0)
    }

    #[test]
    fn plane_strain_flow_mobilises_the_friction_angle_of_the_cone() {
        // Plane-strain cone: Mohr-Coulomb's 30 degrees, sin = 0.5.
        let ps = DruckerPrager {
            cone: Cone::PlaneStrain,
            ..sand()
        };
        let (s, z) = plane_strain_shear(&ps);
        assert!((s - 0.5).abs() < 1e-3, "sin(phi) {s}");
        assert!(z.abs() < 1e-3, "out-of-plane {z}");
        // Compression cone at 30 degrees: sin(phi) = 3 alpha / sqrt(2) = 0.6928 (43.9 degrees).
        let (s, z) = plane_strain_shear(&sand());
        assert!(
            (s - 3.0 * sand().alpha() / (2.0 as Real).sqrt()).abs() < 1e-3,
            "sin(phi) {s}"
        );
        assert!((s - 0.6928203).abs() < 1e-3 && z.abs() < 1e-3, "{s} {z}");
    }

    #[test]
    fn zero_stress_at_rest() {
        assert_eq!(
            sand().kirchhoff(Mat3::IDENTITY, 0.0, Mat3::ZERO),
            Mat3::ZERO
        );
    }

    #[test]
    fn uniaxial_stretch_hand_computed() {
        // F = diag(1.1, 1, 1): eps = (ln 1.1, 0, 0) = (0.0953102, 0, 0), tr = 0.0953102;
        // tau = 2 mu eps + lambda tr = (0.1906204 + 0.1906204, 0.1906204, 0.1906204).
        let tau = sand().kirchhoff(
            Mat3::from_diagonal(Vec3::new(1.1, 1.0, 1.0)),
            0.0,
            Mat3::ZERO,
        );
        let expected = Mat3::from_diagonal(Vec3::new(0.3812408, 0.1906204, 0.1906204));
        assert!(close(tau, expected, 1e-6), "{tau:?}");
    }

    #[test]
    fn frame_indifference() {
        let m = sand();
        let r = Mat3::from_axis_angle(Vec3::new(0.3, -1.0, 0.5).normalize(), 2.2);
        let f = Mat3::from_cols(
            Vec3::new(1.1, 0.2, -0.1),
            Vec3::new(0.05, 0.9, 0.1),
            Vec3::new(0.0, 0.3, 1.2),
        );
        let lhs = m.kirchhoff(r * f, 0.0, Mat3::ZERO);
        let rhs = r * m.kirchhoff(f, 0.0, Mat3::ZERO) * r.transpose();
        assert!(close(lhs, rhs, 1e-5), "{lhs:?} vs {rhs:?}");
    }

    #[test]
    fn tension_projects_to_tip() {
        // F = 1.1 I: eps = ln(1.1) (1, 1, 1), tr > 0 -> sigma = I, q += ||eps|| = sqrt(3) ln 1.1.
        let m = sand();
        let mut q = 0.0;
        let r = Mat3::from_axis_angle(Vec3::new(1.0, 1.0, 1.0).normalize(), 0.5);
        let fe = m.project(
            r * Mat3::from_diagonal(Vec3::new(1.1, 1.1, 1.1)),
            &mut q,
            1e-3,
        );
        assert!(close(fe, r, 1e-6), "{fe:?}");
        assert!(
            (q - (3.0 as Real).sqrt() * (1.1 as Real).ln()).abs() < 1e-6,
            "{q}"
        );
        assert!(close(m.kirchhoff(fe, 0.0, Mat3::ZERO), Mat3::ZERO, 1e-6));
        // Tension with shear too.
        let mut q = 0.0;
        let fe = m.project(Mat3::from_diagonal(Vec3::new(1.2, 1.0, 1.05)), &mut q, 1e-3);
        assert!(close(fe, Mat3::IDENTITY, 1e-6), "{fe:?}");
    }

    #[test]
    fn cohesion_shifts_tip() {
        // c = 0.01: tension goes to sigma = exp(0.01) I, with tensile stress
        // (2 mu + 3 lambda) c = 8 * 0.01 = 0.08 on the diagonal.
        let m = DruckerPrager {
            cohesion: 0.01,
            ..sand()
        };
        let mut q = 0.0;
        let fe = m.project(Mat3::from_diagonal(Vec3::splat(1.1)), &mut q, 1e-3);
        assert!(
            close(fe, Mat3::IDENTITY * (0.01 as Real).exp(), 1e-6),
            "{fe:?}"
        );
        assert!(close(
            m.kirchhoff(fe, 0.0, Mat3::ZERO),
            Mat3::IDENTITY * 0.08,
            1e-5
        ));
        // Small tension below the cohesion is elastic.
        let f = Mat3::from_diagonal(Vec3::splat(1.005));
        let mut q = 0.0;
        assert_eq!(m.project(f, &mut q, 1e-3), f);
        assert_eq!(q, 0.0);
    }

    #[test]
    fn hydrostatic_compression_stays_elastic() {
        let m = sand();
        for s in [0.99, 0.9, 0.5] {
            let f = Mat3::from_diagonal(Vec3::splat(s));
            let mut q = 0.0;
            assert_eq!(m.project(f, &mut q, 1e-3), f);
            assert_eq!(q, 0.0);
        }
    }

    #[test]
    fn pure_shear_yields_to_cone() {
        // Isochoric shear eps = (l, -l, 0): tr = 0 so the cone has zero radius there; case III
        // removes the whole deviatoric part: sigma = I, q += ||eps_hat|| = sqrt(2) l.
        let m = sand();
        let l = (1.1 as Real).ln();
        let mut q = 0.0;
        let fe = m.project(
            Mat3::from_diagonal(Vec3::new(1.1, 1.0 / 1.1, 1.0)),
            &mut q,
            1e-3,
        );
        assert!(close(fe, Mat3::IDENTITY, 1e-6), "{fe:?}");
        assert!((q - (2.0 as Real).sqrt() * l).abs() < 1e-6);
    }

    #[test]
    fn shear_under_pressure_lands_on_cone() {
        // eps = (l - p, -l - p, -p) with l = 0.1, p = 0.01: yield = sqrt(2) 0.1 - 4 * 0.03 * alpha
        // = 0.1414214 - 0.0391918 > 0 -> case III; afterwards on the cone (yield = 0), trace kept.
        let m = sand();
        let eps = Vec3::new(0.09, -0.11, -0.01);
        assert!((yield_value(&m, eps) - 0.1022296).abs() < 1e-6);
        let (h, dg) = m.project_strain(eps);
        assert!((dg - 0.1022296).abs() < 1e-6);
        assert!(yield_value(&m, h).abs() < 1e-6, "{h:?}");
        assert!(((h.x + h.y + h.z) - (eps.x + eps.y + eps.z)).abs() < 1e-6);
        // The deviatoric direction is kept.
        let d = h - Vec3::splat((h.x + h.y + h.z) / 3.0);
        let d0 = eps - Vec3::splat((eps.x + eps.y + eps.z) / 3.0);
        assert!(d.normalize().dot(d0.normalize()) > 1.0 - 1e-6);
        // Through the full F path in a rotated frame.
        let r1 = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.6);
        let r2 = Mat3::from_axis_angle(Vec3::new(-1.0, 0.2, 0.5).normalize(), 1.9);
        let mut q = 0.5;
        let fe = m.project(r1 * Mat3::from_diagonal(eps.exp()) * r2, &mut q, 1e-3);
        assert!(close(fe, r1 * Mat3::from_diagonal(h.exp()) * r2, 1e-5));
        assert!((q - 0.5 - 0.1022296).abs() < 1e-6);
    }

    #[test]
    fn degenerate_sigma_is_finite() {
        let m = sand();
        let mut q = 0.0;
        for f in [Mat3::ZERO, Mat3::from_diagonal(Vec3::new(1.0, 1.0, -0.5))] {
            assert!(m.kirchhoff(f, 0.0, Mat3::ZERO).is_finite());
            let fe = m.project(f, &mut q, 1e-3);
            assert!(fe.is_finite() && q.is_finite());
        }
    }
}

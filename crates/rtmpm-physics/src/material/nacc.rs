//! Non-associated Cam-clay (NACC) of Wolper et al. 2019 ("CD-MPM: continuum damage material point
//! methods for dynamic fracture animation", ACM TOG 38(4)): a cohesive, hardening soil (damp sand,
//! clay, snow, brittle crumbly solids). Hencky elasticity; the yield surface in the plane of the
//! pressure `p = -tr(tau)/3` and the shear stress `q = sqrt(3/2) ||dev tau||` is the ellipse
//! `y(p, q) = (1 + 2 beta) q^2 + M^2 (p + beta p0)(p - p0) <= 0`, from `-beta p0` (tension) to
//! `p0` (compression). The plastic state is `alpha`, the log of the plastic volume change:
//! `p0 = kappa sinh(xi max(-alpha, 0))` hardens when the material is compacted (alpha < 0) and
//! softens to nothing when it is torn apart. The return mapping is CD-MPM's non-associated one,
//! in principal Hencky strain (through [`super::hencky::return_map`]): beyond either tip to the
//! tip (changing alpha by the plastic volume change), else `q` down to the ellipse at the same `p`.

use super::constitutive::Constitutive;
use super::hencky;
use super::params::{self, Elasticity, ParamError};
use crate::math::{Mat3, Real, Vec3};
use serde::Deserialize;

/// Non-associated Cam-clay. The plastic scalar is `alpha` (starts at `alpha0`).
#[derive(Clone, Debug, PartialEq)]
pub struct Nacc {
    /// Shear modulus mu (Pa).
    pub mu: Real,
    /// First Lamé parameter lambda (Pa).
    pub lambda: Real,
    /// Slope M of the critical state line (from the friction angle).
    pub m: Real,
    /// Tensile strength over compressive strength (cohesion), `beta >= 0`.
    pub beta: Real,
    /// Hardening `xi >= 0`.
    pub xi: Real,
    /// Initial `alpha` (<= 0: the initial compressive strength `p0 = kappa sinh(-xi alpha0)`).
    pub alpha0: Real,
}

/// The scene parameters of NACC.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NaccParams {
    pub youngs_modulus: Option<f32>,
    pub poisson_ratio: Option<f32>,
    pub mu: Option<f32>,
    pub lambda: Option<f32>,
    /// Degrees, in (0, 90) (default 30): `M = 6 sin(phi) / (3 - sin(phi))`.
    pub friction_angle: Option<f32>,
    /// Cohesion ratio beta (default 0.5), >= 0.
    pub beta: Option<f32>,
    /// Hardening xi (default 1), >= 0.
    pub xi: Option<f32>,
    /// Initial alpha (default -0.01), <= 0.
    pub alpha0: Option<f32>,
}

impl Nacc {
    /// Bulk modulus `kappa = lambda + 2 mu / 3`.
    pub fn kappa(&self) -> Real {
        self.lambda + 2.0 / 3.0 * self.mu
    }

    /// Compressive strength `p0 = kappa sinh(xi max(-alpha, 0))`.
    pub fn p0(&self, alpha: Real) -> Real {
        self.kappa() * (self.xi * (-alpha).max(0.0)).sinh()
    }

    /// Yield function `(1 + 2 beta) q^2 + M^2 (p + beta p0)(p - p0)` (<= 0 admissible).
    pub fn yield_function(&self, p: Real, q: Real, alpha: Real) -> Real {
        let p0 = self.p0(alpha);
        (1.0 + 2.0 * self.beta) * q * q + self.m * self.m * (p + self.beta * p0) * (p - p0)
    }

    /// Pressure and shear stress `(p, q)` of a principal Hencky strain.
    pub fn p_q(&self, eps: Vec3) -> (Real, Real) {
        let tr = eps.x + eps.y + eps.z;
        let e_hat = eps - Vec3::splat(tr / 3.0);
        (
            -self.kappa() * tr,
            Real::sqrt(1.5) * 2.0 * self.mu * e_hat.length(),
        )
    }

    /// Uniaxial compressive strength: the stress `s` of `p = s / 3, q = s` on the ellipse.
    pub fn uniaxial_strength(&self, alpha: Real) -> Real {
        let p0 = self.p0(alpha);
        let m2 = self.m * self.m;
        // (1 + 2 beta + M^2 / 9) s^2 + M^2 p0 (beta - 1) / 3 s - M^2 beta p0^2 = 0
        let a = 1.0 + 2.0 * self.beta + m2 / 9.0;
        let b = m2 * p0 * (self.beta - 1.0) / 3.0;
        let c = -m2 * self.beta * p0 * p0;
        (-b + (b * b - 4.0 * a * c).sqrt()) / (2.0 * a)
    }

    /// CD-MPM's return mapping of a principal Hencky strain: `(eps', alpha')`, `None` inside.
    pub fn project_strain(&self, eps: Vec3, alpha: Real) -> Option<(Vec3, Real)> {
        let kappa = self.kappa();
        let tr = eps.x + eps.y + eps.z;
        let (p, q) = self.p_q(eps);
        let p0 = self.p0(alpha);
        let tip = |p_tip: Real| {
            // To a tip (q = 0, p = p_tip); alpha takes the plastic volume change
            // log(J_trial / J_new) = tr - tr_new.
            let tr_new = -p_tip / kappa;
            Some((Vec3::splat(tr_new / 3.0), alpha + tr - tr_new))
        };
        if p > p0 {
            return tip(p0);
        }
        if p < -self.beta * p0 {
            return tip(-self.beta * p0);
        }
        if self.yield_function(p, q, alpha) <= 0.0 {
            return None;
        }
        let m2 = self.m * self.m;
        let q_new = (-m2 * (p + self.beta * p0) * (p - p0) / (1.0 + 2.0 * self.beta))
            .max(0.0)
            .sqrt();
        let e_hat = eps - Vec3::splat(tr / 3.0);
        let scale = if q > 0.0 { q_new / q } else { 0.0 };
        Some((e_hat * scale + Vec3::splat(tr / 3.0), alpha))
    }
}

impl Constitutive for Nacc {
    const NAME: &'static str = "nacc";
    const SUMMARY: &'static str =
        "non-associated Cam-clay: cohesive, hardening soil (Wolper et al. 2019, CD-MPM)";
    const GPU_PARAMS: &'static [&'static str] = &["mu", "lambda", "m", "beta", "xi"];
    const COLOUR: [f32; 3] = [0.62, 0.52, 0.40];
    type Params = NaccParams;

    fn new(p: NaccParams) -> Result<Self, ParamError> {
        let (mu, lambda) = Elasticity {
            youngs_modulus: p.youngs_modulus,
            poisson_ratio: p.poisson_ratio,
            mu: p.mu,
            lambda: p.lambda,
        }
        .lame()?;
        let phi = params::finite("friction_angle", p.friction_angle.unwrap_or(30.0))?;
        if !(phi > 0.0 && phi < 90.0) {
            return Err(ParamError::new(
                "friction_angle",
                format!("friction angle must be in (0, 90) degrees, got {phi}"),
                "use degrees, typically 25-45 for soils",
            ));
        }
        let alpha0 = params::finite("alpha0", p.alpha0.unwrap_or(-0.01))?;
        if alpha0 > 0.0 {
            return Err(ParamError::new(
                "alpha0",
                format!(
                    "alpha0 must be <= 0, got {alpha0} (a positive alpha0 starts without strength)"
                ),
                "use a small negative value, e.g. -0.01 (more negative: stronger)",
            ));
        }
        let s = phi.to_radians().sin();
        Ok(Nacc {
            mu,
            lambda,
            m: 6.0 * s / (3.0 - s),
            beta: params::non_negative("beta", p.beta, 0.5, "cohesion ratio beta")?,
            xi: params::non_negative("xi", p.xi, 1.0, "hardening xi")?,
            alpha0,
        })
    }

    /// Kirchhoff stress (St.Venant-Kirchhoff with Hencky strain), see [`hencky::kirchhoff`].
    fn kirchhoff(&self, f: Mat3, _alpha: Real, _c: Mat3) -> Mat3 {
        hencky::kirchhoff(f, self.mu, self.lambda)
    }

    /// [`Nacc::project_strain`] through [`hencky::return_map`]; the plastic scalar is alpha.
    fn project(&self, f_trial: Mat3, alpha: &mut Real, _dt: Real) -> Mat3 {
        hencky::return_map(f_trial, alpha, |eps, a| self.project_strain(eps, a))
    }

    fn initial_plastic(&self) -> Real {
        self.alpha0
    }

    fn wave_modulus(&self) -> Real {
        self.lambda + 2.0 * self.mu
    }

    fn gpu_params(&self) -> Vec<Real> {
        vec![self.mu, self.lambda, self.m, self.beta, self.xi]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::svd::svd3;

    fn soil() -> Nacc {
        Nacc {
            mu: 1e5,
            lambda: 1.5e5,
            m: 1.2,
            beta: 0.5,
            xi: 1.0,
            alpha0: -0.01,
        }
    }

    fn eps_of(f: Mat3) -> Vec3 {
        hencky::strain(svd3(f).1)
    }

    #[test]
    fn strength_hand_computed() {
        // kappa = 1.5e5 + 2e5 / 3 = 216666.67; p0 = kappa sinh(0.01) = 2166.7028.
        let m = soil();
        assert!((m.kappa() - 216_666.67).abs() < 0.1);
        assert!((m.p0(-0.01) - 2_166.703).abs() < 0.05, "{}", m.p0(-0.01));
        assert_eq!(m.p0(0.3), 0.0);
        // phi = 30 degrees: M = 6 * 0.5 / 2.5 = 1.2.
        let m2 = Nacc::new(
            crate::material::MaterialParams::parse("nacc", "mu = 1e5\nlambda = 1.5e5")
                .unwrap()
                .deserialize()
                .unwrap(),
        )
        .unwrap();
        assert!((m2.m - 1.2).abs() < 1e-6);
    }

    #[test]
    fn zero_stress_at_rest_and_elastic_inside() {
        let m = soil();
        assert_eq!(m.kirchhoff(Mat3::IDENTITY, -0.01, Mat3::ZERO), Mat3::ZERO);
        let f = Mat3::from_diagonal(Vec3::new(0.9995, 1.0, 1.0));
        let mut a = -0.01;
        assert_eq!(m.project(f, &mut a, 1e-3), f);
        assert_eq!(a, -0.01);
    }

    #[test]
    fn shear_beyond_the_ellipse_lands_on_it_at_the_same_pressure() {
        let m = soil();
        let r = Mat3::from_axis_angle(Vec3::new(1.0, 0.3, -0.2).normalize(), 0.7);
        // Compression and shear: p inside (-beta p0, p0), q well beyond the ellipse.
        let f = r * Mat3::from_diagonal(Vec3::new(0.99, 1.005, 1.0)) * r.transpose();
        let (p, q) = m.p_q(eps_of(f));
        assert!(p > 0.0 && p < m.p0(-0.01) && m.yield_function(p, q, -0.01) > 0.0);
        let mut a = -0.01;
        let fe = m.project(f, &mut a, 1e-3);
        let (p2, q2) = m.p_q(eps_of(fe));
        assert_eq!(a, -0.01);
        assert!((p2 - p).abs() < 1e-3 * p, "{p} -> {p2}");
        assert!(q2 < q);
        let y = m.yield_function(p2, q2, a);
        assert!(y.abs() < 1e-4 * m.p0(a) * m.p0(a), "y = {y}");
    }

    #[test]
    fn beyond_the_tips_to_the_tips_with_hardening_and_softening() {
        let m = soil();
        // Strong compression: to the tip (p0, 0) of the step's ellipse; alpha takes the plastic
        // volume change, log(0.97^3) + p0 / kappa, and decreases (compaction hardens).
        let p0 = m.p0(-0.01);
        let mut a = -0.01;
        let fe = m.project(Mat3::from_diagonal(Vec3::splat(0.97)), &mut a, 1e-3);
        let (p, q) = m.p_q(eps_of(fe));
        assert!((p - p0).abs() < 1e-2 * p0 && q.abs() < 1e-2, "{p} {q} {p0}");
        let expected = -0.01 + 3.0 * (0.97 as Real).ln() + p0 / m.kappa();
        assert!((a - expected).abs() < 1e-5, "{a} vs {expected}");
        assert!(m.p0(a) > p0);
        // Strong tension: to the tip (-beta p0, 0); alpha increases (softening).
        let mut a = -0.01;
        let fe = m.project(Mat3::from_diagonal(Vec3::splat(1.03)), &mut a, 1e-3);
        let (p, _) = m.p_q(eps_of(fe));
        assert!((p + m.beta * p0).abs() < 1e-2 * p0, "{p}");
        assert!(a > -0.01 && m.p0(a) < p0);
    }

    #[test]
    fn uniaxial_strength_is_on_the_ellipse() {
        let m = soil();
        let s = m.uniaxial_strength(-0.01);
        assert!(s > 0.0);
        assert!(m.yield_function(s / 3.0, s, -0.01).abs() < 1e-6 * s * s);
        assert!(m.yield_function(0.99 * s / 3.0, 0.99 * s, -0.01) < 0.0);
        assert!(m.yield_function(1.01 * s / 3.0, 1.01 * s, -0.01) > 0.0);
    }

    #[test]
    fn frame_indifference() {
        let m = soil();
        let f = Mat3::from_cols(
            Vec3::new(0.97, 0.02, 0.0),
            Vec3::new(0.03, 1.02, -0.01),
            Vec3::new(0.0, 0.01, 0.99),
        );
        let r = Mat3::from_axis_angle(Vec3::new(-0.3, 1.0, 0.5).normalize(), 2.0);
        let (mut a1, mut a2) = (-0.01, -0.01);
        let g1 = m.project(f, &mut a1, 1e-3);
        let g2 = m.project(r * f, &mut a2, 1e-3);
        assert!((g2 - r * g1).to_cols_array().iter().all(|x| x.abs() < 1e-5));
        assert!((a1 - a2).abs() < 1e-6);
        let t1 = m.kirchhoff(g1, a1, Mat3::ZERO);
        let t2 = m.kirchhoff(g2, a2, Mat3::ZERO);
        assert!(
            (t2 - r * t1 * r.transpose())
                .to_cols_array()
                .iter()
                .all(|x| x.abs() < 1.0)
        );
    }

    #[test]
    fn bad_parameters_are_clear_errors() {
        use crate::material::Material;
        let field = |s: &str| {
            Material::parse("soil", 1500.0, "nacc", s)
                .err()
                .map(|e| e.field)
        };
        let base = "youngs_modulus = 5e5\npoisson_ratio = 0.3";
        assert_eq!(field(base), None);
        assert_eq!(
            field(&format!("{base}\nalpha0 = 0.1")).as_deref(),
            Some("alpha0")
        );
        assert_eq!(
            field(&format!("{base}\nbeta = -1")).as_deref(),
            Some("beta")
        );
        assert_eq!(
            field(&format!("{base}\nfriction_angle = 95")).as_deref(),
            Some("friction_angle")
        );
        assert_eq!(
            field(&format!("{base}\ncohesion = 1")).as_deref(),
            Some("cohesion")
        );
    }
}

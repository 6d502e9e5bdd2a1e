//! Snow plasticity, Stomakhin et al. 2013 ("A material point method for snow simulation"):
//! FixedCorotated elasticity hardened by `exp(xi (1 - Jp))` and singular-value clamping.

use super::constitutive::Constitutive;
use super::fixed_corotated::fixed_corotated_kirchhoff;
use super::params::{self, Elasticity, ParamError};
use crate::math::{Mat3, Real, Vec3};
use crate::svd::svd3;
use serde::Deserialize;

/// Bound on the hardening exponent: `xi (1 - Jp)` is clamped to `[-S, M]` with `M = 3`, so
/// compacted snow is at most `e^3 ~ 20` times stiffer than fresh snow (an unbounded factor
/// would drive the CFL step to zero).
pub const SNOW_MAX_HARDENING_EXPONENT: Real = 3.0;

/// Bound on the softening side: `xi (1 - Jp) >= -S`, `S = 10`: stretched snow keeps at least
/// `e^-10 ~ 5e-5` of its stiffness, practically the paper's unbounded softening (an earlier
/// bound of 3 kept 5 % of the stiffness in torn snow).
pub const SNOW_MAX_SOFTENING_EXPONENT: Real = 10.0;

/// `Jp` is kept in `[SNOW_JP_MIN, SNOW_JP_MAX]` so it stays positive (an inverted trial `F` has a
/// negative determinant ratio) and finite; inside the range used by the clamped exponent this is
/// irrelevant for any `xi >= 0.003`.
pub const SNOW_JP_MIN: Real = 1e-3;
/// Upper bound of `Jp`, see [`SNOW_JP_MIN`].
pub const SNOW_JP_MAX: Real = 1e3;

/// Snow (Stomakhin et al. 2013). The plastic scalar is `Jp`, the plastic volume ratio (starts at 1).
#[derive(Clone, Debug, PartialEq)]
pub struct Snow {
    /// Initial Lamé parameters (hardened by `exp(xi (1 - Jp))`).
    pub mu: Real,
    /// Initial first Lamé parameter lambda (Pa).
    pub lambda: Real,
    /// Critical compression theta_c (e.g. 2.5e-2).
    pub critical_compression: Real,
    /// Critical stretch theta_s (e.g. 7.5e-3).
    pub critical_stretch: Real,
    /// Hardening coefficient xi (e.g. 10).
    pub hardening: Real,
}

/// The scene parameters of snow.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SnowParams {
    pub youngs_modulus: Option<f32>,
    pub poisson_ratio: Option<f32>,
    pub mu: Option<f32>,
    pub lambda: Option<f32>,
    /// theta_c (default 2.5e-2).
    pub critical_compression: Option<f32>,
    /// theta_s (default 7.5e-3).
    pub critical_stretch: Option<f32>,
    /// xi (default 10).
    pub hardening: Option<f32>,
}

impl Snow {
    /// The paper's parameters (Stomakhin 2013, table 2, "reference"): E = 1.4e5 Pa, nu = 0.2,
    /// theta_c = 2.5e-2, theta_s = 7.5e-3, xi = 10.
    pub fn reference() -> Self {
        let (mu, lambda) = super::constitutive::lame(1.4e5, 0.2);
        Self {
            mu,
            lambda,
            critical_compression: 2.5e-2,
            critical_stretch: 7.5e-3,
            hardening: 10.0,
        }
    }

    /// Hardening factor `exp(clamp(xi (1 - Jp), -S, M))` (Stomakhin 2013, eq. 8), see
    /// [`SNOW_MAX_HARDENING_EXPONENT`] and [`SNOW_MAX_SOFTENING_EXPONENT`].
    pub fn hardening_factor(&self, jp: Real) -> Real {
        let e = (self.hardening * (1.0 - jp))
            .clamp(-SNOW_MAX_SOFTENING_EXPONENT, SNOW_MAX_HARDENING_EXPONENT);
        e.exp()
    }
}

impl Constitutive for Snow {
    const NAME: &'static str = "snow";
    const SUMMARY: &'static str =
        "snow: FixedCorotated hardened by compaction, singular-value clamping (Stomakhin 2013)";
    const GPU_PARAMS: &'static [&'static str] = &[
        "mu",
        "lambda",
        "critical_compression",
        "critical_stretch",
        "hardening",
    ];
    const COLOUR: [f32; 3] = [0.92, 0.93, 0.96];
    type Params = SnowParams;

    fn new(p: SnowParams) -> Result<Self, ParamError> {
        let (mu, lambda) = Elasticity {
            youngs_modulus: p.youngs_modulus,
            poisson_ratio: p.poisson_ratio,
            mu: p.mu,
            lambda: p.lambda,
        }
        .lame()?;
        Ok(Snow {
            mu,
            lambda,
            critical_compression: params::positive(
                "critical_compression",
                p.critical_compression.unwrap_or(2.5e-2),
                "critical compression",
            )?,
            critical_stretch: params::positive(
                "critical_stretch",
                p.critical_stretch.unwrap_or(7.5e-3),
                "critical stretch",
            )?,
            hardening: params::non_negative("hardening", p.hardening, 10.0, "hardening")?,
        })
    }

    /// Kirchhoff stress: FixedCorotated with `mu`, `lambda` times [`Snow::hardening_factor`].
    fn kirchhoff(&self, f: Mat3, jp: Real, _c: Mat3) -> Mat3 {
        let h = self.hardening_factor(jp);
        fixed_corotated_kirchhoff(f, self.mu * h, self.lambda * h)
    }

    /// Clamps the singular values of the trial elastic `F` into `[1 - theta_c, 1 + theta_s]`
    /// and moves the removed volume into `Jp`: `Jp_new = Jp J_e_trial / J_e_new`
    /// (Stomakhin 2013, section 7), clamped to `[SNOW_JP_MIN, SNOW_JP_MAX]`.
    fn project(&self, f_trial: Mat3, jp: &mut Real, _dt: Real) -> Mat3 {
        let (u, s, v) = svd3(f_trial);
        let lo = 1.0 - self.critical_compression;
        let hi = 1.0 + self.critical_stretch;
        let sc = Vec3::new(s.x.clamp(lo, hi), s.y.clamp(lo, hi), s.z.clamp(lo, hi));
        let ratio = (s.x * s.y * s.z) / (sc.x * sc.y * sc.z);
        *jp = (*jp * ratio).clamp(SNOW_JP_MIN, SNOW_JP_MAX);
        u * Mat3::from_diagonal(sc) * v.transpose()
    }

    /// The plastic volume ratio starts at 1.
    fn initial_plastic(&self) -> Real {
        1.0
    }

    /// Upper bound of `lambda + 2 mu` over the admissible hardening range, for the CFL condition:
    /// `Jp` can approach its lower bound (0, compaction), where the exponent is
    /// `min(xi, M)` for `xi >= 0`; for `xi < 0`, stretching (`Jp` large) reaches `M`.
    fn wave_modulus(&self) -> Real {
        let e_max = if self.hardening >= 0.0 {
            self.hardening.min(SNOW_MAX_HARDENING_EXPONENT)
        } else {
            SNOW_MAX_HARDENING_EXPONENT
        };
        (self.lambda + 2.0 * self.mu) * e_max.exp()
    }

    fn gpu_params(&self) -> Vec<Real> {
        vec![
            self.mu,
            self.lambda,
            self.critical_compression,
            self.critical_stretch,
            self.hardening,
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Mat3, b: Mat3, tol: Real) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() <= tol)
    }

    fn snow() -> Snow {
        Snow {
            mu: 1.0,
            lambda: 2.0,
            critical_compression: 0.025,
            critical_stretch: 0.0075,
            hardening: 10.0,
        }
    }

    #[test]
    fn zero_stress_at_rest() {
        assert!(close(
            snow().kirchhoff(Mat3::IDENTITY, 1.0, Mat3::ZERO),
            Mat3::ZERO,
            1e-7
        ));
        assert!(close(
            snow().kirchhoff(Mat3::IDENTITY, 0.8, Mat3::ZERO),
            Mat3::ZERO,
            1e-7
        ));
    }

    #[test]
    fn hardened_stress_hand_computed() {
        // Jp = 0.95: h = exp(10 * 0.05) = exp(0.5) = 1.6487213. FixedCorotated with mu = 1,
        // lambda = 2 at F = diag(1.1, 1, 1) is diag(0.44, 0.22, 0.22) (see fixed_corotated.rs),
        // linear in (mu, lambda): tau = 1.6487213 * diag(0.44, 0.22, 0.22).
        let tau = snow().kirchhoff(
            Mat3::from_diagonal(Vec3::new(1.1, 1.0, 1.0)),
            0.95,
            Mat3::ZERO,
        );
        let expected = Mat3::from_diagonal(Vec3::new(0.7254374, 0.3627187, 0.3627187));
        assert!(close(tau, expected, 1e-5), "{tau:?}");
    }

    #[test]
    fn hardening_exponent_is_clamped() {
        let m = snow();
        assert!((m.hardening_factor(-100.0) - (3.0 as Real).exp()).abs() < 1e-4);
        assert!((m.hardening_factor(1e6) - (-10.0 as Real).exp()).abs() < 1e-9);
        // Softening goes on past the compaction bound: Jp = 1.5 gives e^-5 (the paper's value).
        assert!((m.hardening_factor(1.5) - (-5.0 as Real).exp()).abs() < 1e-7);
        assert!(
            m.kirchhoff(Mat3::from_diagonal(Vec3::splat(0.9)), 1e-3, Mat3::ZERO)
                .is_finite()
        );
        // CFL bound covers every admissible Jp.
        for jp in [SNOW_JP_MIN, 0.1, 0.5, 0.9, 1.0, 2.0, SNOW_JP_MAX] {
            let h = m.hardening_factor(jp);
            assert!(h * (m.lambda + 2.0 * m.mu) <= m.wave_modulus() * (1.0 + 1e-6));
        }
        assert!((m.wave_modulus() - 4.0 * (3.0 as Real).exp()).abs() < 1e-4);
        let soft = Snow {
            hardening: 1.0,
            ..snow()
        };
        assert!((soft.wave_modulus() - 4.0 * (1.0 as Real).exp()).abs() < 1e-5);
    }

    #[test]
    fn project_clamps_and_updates_jp() {
        // F = diag(1.1, 0.9, 1.0): clamped to diag(1.0075, 0.975, 1.0);
        // Jp = 1 * (1.1 * 0.9 * 1) / (1.0075 * 0.975 * 1) = 0.99 / 0.98231250 = 1.0078259.
        let m = snow();
        let mut jp = 1.0;
        let fe = m.project(Mat3::from_diagonal(Vec3::new(1.1, 0.9, 1.0)), &mut jp, 1e-3);
        assert!(
            close(fe, Mat3::from_diagonal(Vec3::new(1.0075, 0.975, 1.0)), 1e-6),
            "{fe:?}"
        );
        assert!((jp - 1.0078259).abs() < 1e-6, "{jp}");
        // Rotated frame: singular values clamped, rotations kept, total volume preserved.
        let r1 = Mat3::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.6);
        let r2 = Mat3::from_axis_angle(Vec3::new(-1.0, 0.2, 0.5).normalize(), 1.9);
        let f = r1 * Mat3::from_diagonal(Vec3::new(1.2, 0.99, 0.8)) * r2;
        let mut jp = 0.9;
        let fe = m.project(f, &mut jp, 1e-3);
        let expected = r1 * Mat3::from_diagonal(Vec3::new(1.0075, 0.99, 0.975)) * r2;
        assert!(close(fe, expected, 1e-5), "{fe:?}");
        assert!((jp * fe.determinant() - 0.9 * f.determinant()).abs() < 1e-5);
    }

    #[test]
    fn project_inside_is_identity() {
        let m = snow();
        let f = Mat3::from_diagonal(Vec3::new(1.005, 0.98, 1.0));
        let mut jp = 0.97;
        let fe = m.project(f, &mut jp, 1e-3);
        assert!(close(fe, f, 1e-6));
        assert!((jp - 0.97).abs() < 1e-6);
    }

    #[test]
    fn frame_indifference() {
        let m = snow();
        let r = Mat3::from_axis_angle(Vec3::new(0.3, -1.0, 0.5).normalize(), 2.2);
        let f = Mat3::from_cols(
            Vec3::new(1.01, 0.02, 0.0),
            Vec3::new(0.0, 0.98, 0.01),
            Vec3::new(0.0, 0.0, 1.0),
        );
        let lhs = m.kirchhoff(r * f, 0.9, Mat3::ZERO);
        let rhs = r * m.kirchhoff(f, 0.9, Mat3::ZERO) * r.transpose();
        assert!(close(lhs, rhs, 1e-5), "{lhs:?} vs {rhs:?}");
    }
}

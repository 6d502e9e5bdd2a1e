//! Weakly compressible fluid tracking only the volume ratio `J = det F`.

use super::constitutive::Constitutive;
use super::params::{self, ParamError};
use crate::math::{Mat3, Real, Vec3};
use serde::Deserialize;

/// Smallest volume ratio used by the fluid: `project` and the equation of state clamp `J` to at
/// least this value, so an inverted or collapsed particle gets a large but finite restoring
/// pressure instead of NaN (`J^-gamma` of a non-positive `J`).
pub const FLUID_J_MIN: Real = 1e-3;

/// Equation of state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Eos {
    /// `p = K (1 - J)` (mpm88's linear model).
    Linear,
    /// `p = K (J^-gamma - 1)` (Tait / Cole).
    Tait {
        /// Exponent gamma (7 for water).
        gamma: Real,
    },
}

/// Weakly compressible fluid.
#[derive(Clone, Debug, PartialEq)]
pub struct Fluid {
    /// Bulk modulus K (Pa).
    pub bulk_modulus: Real,
    /// Equation of state.
    pub eos: Eos,
    /// Dynamic viscosity (Pa s).
    pub viscosity: Real,
}

/// The scene parameters of a fluid.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluidParams {
    /// Bulk modulus K (Pa).
    pub bulk_modulus: Option<f32>,
    /// `"linear"` (default, unless `gamma` is given) or `"tait"`.
    pub eos: Option<EosName>,
    /// Tait exponent (default 7).
    pub gamma: Option<f32>,
    /// Dynamic viscosity (Pa s, default 0).
    pub viscosity: Option<f32>,
}

/// The equations of state by name.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum EosName {
    Linear,
    Tait,
}

impl Fluid {
    /// Pressure `p(J)` of the equation of state (`J` clamped to [`FLUID_J_MIN`]).
    pub fn pressure(&self, j: Real) -> Real {
        let j = j.max(FLUID_J_MIN);
        match self.eos {
            // mpm88: p = K (1 - J)
            Eos::Linear => self.bulk_modulus * (1.0 - j),
            // Tait (Cole 1948; Becker & Teschner 2007): p = K (J^-gamma - 1)
            Eos::Tait { gamma } => self.bulk_modulus * (j.powf(-gamma) - 1.0),
        }
    }

    /// Factor on K giving the small-strain stiffness dp/d(-J) at J = 1 (1 for linear, gamma for Tait).
    pub fn eos_stiffness_factor(&self) -> Real {
        match self.eos {
            Eos::Linear => 1.0,
            Eos::Tait { gamma } => gamma,
        }
    }
}

impl Constitutive for Fluid {
    const NAME: &'static str = "fluid";
    const SUMMARY: &'static str =
        "weakly compressible fluid (linear or Tait pressure, Newtonian viscosity)";
    const GPU_PARAMS: &'static [&'static str] = &["bulk_modulus", "tait", "gamma", "viscosity"];
    const COLOUR: [f32; 3] = [0.20, 0.48, 0.92];
    type Params = FluidParams;

    fn new(p: FluidParams) -> Result<Fluid, ParamError> {
        let k = params::required("bulk_modulus", p.bulk_modulus, "fluid", "1e5")?;
        let bulk_modulus = params::positive("bulk_modulus", k, "bulk modulus")?;
        let eos = match (p.eos, p.gamma) {
            (Some(EosName::Linear), Some(_)) => {
                return Err(ParamError::new(
                    "gamma",
                    "gamma is given but eos = \"linear\"",
                    "remove gamma, or use eos = \"tait\"",
                ));
            }
            (Some(EosName::Linear), None) | (None, None) => Eos::Linear,
            (_, g) => Eos::Tait {
                gamma: params::positive("gamma", g.unwrap_or(7.0), "gamma")?,
            },
        };
        let viscosity = params::non_negative("viscosity", p.viscosity, 0.0, "viscosity (Pa s)")?;
        Ok(Fluid {
            bulk_modulus,
            eos,
            viscosity,
        })
    }

    /// Kirchhoff stress `tau = -J p I + J mu (C + C^T)`, with `C` the APIC affine matrix (an
    /// approximation of `grad v`) and `J = det F` (clamped to [`FLUID_J_MIN`]).
    fn kirchhoff(&self, f: Mat3, _plastic: Real, c: Mat3) -> Mat3 {
        let j = f.determinant().max(FLUID_J_MIN);
        let p = self.pressure(j);
        // Newtonian fluid: sigma = -p I + mu (grad v + grad v^T); tau = J sigma.
        Mat3::from_diagonal(Vec3::splat(-j * p)) + (c + c.transpose()) * (j * self.viscosity)
    }

    /// Resets `F` to the isotropic `J^(1/3) I` keeping only the volume ratio (Taichi's mpm99),
    /// `J` clamped to [`FLUID_J_MIN`].
    fn project(&self, f_trial: Mat3, _plastic: &mut Real, _dt: Real) -> Mat3 {
        let j = f_trial.determinant().max(FLUID_J_MIN);
        Mat3::from_diagonal(Vec3::splat(j.cbrt()))
    }

    fn wave_modulus(&self) -> Real {
        self.bulk_modulus * self.eos_stiffness_factor()
    }

    fn gpu_params(&self) -> Vec<Real> {
        let (tait, gamma) = match self.eos {
            Eos::Linear => (0.0, 1.0),
            Eos::Tait { gamma } => (1.0, gamma),
        };
        vec![self.bulk_modulus, tait, gamma, self.viscosity]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Mat3, b: Mat3, tol: Real) -> bool {
        (a - b).to_cols_array().iter().all(|x| x.abs() <= tol)
    }

    const WATER_LINEAR: Fluid = Fluid {
        bulk_modulus: 10.0,
        eos: Eos::Linear,
        viscosity: 0.0,
    };

    #[test]
    fn zero_stress_at_rest() {
        for eos in [Eos::Linear, Eos::Tait { gamma: 7.0 }] {
            let m = Fluid {
                bulk_modulus: 1e5,
                eos,
                viscosity: 1e-3,
            };
            assert_eq!(m.kirchhoff(Mat3::IDENTITY, 0.0, Mat3::ZERO), Mat3::ZERO);
        }
    }

    #[test]
    fn linear_eos_hand_computed() {
        // F = diag(1.1, 1, 1): J = 1.1, p = K (1 - J) = 10 * (-0.1) = -1,
        // tau = -J p I = 1.1 I (tension pulls back).
        let f = Mat3::from_diagonal(Vec3::new(1.1, 1.0, 1.0));
        let tau = WATER_LINEAR.kirchhoff(f, 0.0, Mat3::ZERO);
        assert!(close(tau, Mat3::IDENTITY * 1.1, 1e-5), "{tau:?}");
        // Compression J = 0.9: p = 1, tau = -0.9 I.
        let tau = WATER_LINEAR.kirchhoff(
            Mat3::from_diagonal(Vec3::new(0.9, 1.0, 1.0)),
            0.0,
            Mat3::ZERO,
        );
        assert!(close(tau, Mat3::IDENTITY * -0.9, 1e-5), "{tau:?}");
    }

    #[test]
    fn tait_eos_hand_computed() {
        // J = 0.9, gamma = 7, K = 2: p = 2 (0.9^-7 - 1) = 2 * (2.0907515 - 1) = 2.181503,
        // tau = -J p I = -1.9633527 I.
        let m = Fluid {
            bulk_modulus: 2.0,
            eos: Eos::Tait { gamma: 7.0 },
            viscosity: 0.0,
        };
        let tau = m.kirchhoff(
            Mat3::from_diagonal(Vec3::new(1.0, 0.9, 1.0)),
            0.0,
            Mat3::ZERO,
        );
        assert!(close(tau, Mat3::IDENTITY * -1.9633527, 1e-5), "{tau:?}");
    }

    #[test]
    fn viscous_stress_hand_computed() {
        // Simple shear v_x = y: grad v = C has C[row x][col y] = 1, i.e. column y = (1, 0, 0).
        // J = 1 so no pressure; tau = mu (C + C^T) has xy = yx = mu = 0.5.
        let m = Fluid {
            bulk_modulus: 10.0,
            eos: Eos::Linear,
            viscosity: 0.5,
        };
        let c = Mat3::from_cols(Vec3::ZERO, Vec3::X, Vec3::ZERO);
        let tau = m.kirchhoff(Mat3::IDENTITY, 0.0, c);
        let expected = Mat3::from_cols(
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(0.5, 0.0, 0.0),
            Vec3::ZERO,
        );
        assert!(close(tau, expected, 1e-7), "{tau:?}");
    }

    #[test]
    fn frame_indifference() {
        let m = Fluid {
            bulk_modulus: 3.0,
            eos: Eos::Tait { gamma: 7.0 },
            viscosity: 0.2,
        };
        let r = Mat3::from_axis_angle(Vec3::new(1.0, -2.0, 0.5).normalize(), 0.8);
        let f = Mat3::from_cols(
            Vec3::new(1.1, 0.1, 0.0),
            Vec3::new(0.05, 0.95, 0.1),
            Vec3::new(0.0, -0.1, 1.02),
        );
        let c = Mat3::from_cols(
            Vec3::new(0.1, 0.3, 0.0),
            Vec3::new(-0.2, 0.0, 0.4),
            Vec3::new(0.0, 0.1, -0.1),
        );
        // Under a rotation of the frame, F -> R F and grad v -> R grad v R^T.
        let lhs = m.kirchhoff(r * f, 0.0, r * c * r.transpose());
        let rhs = r * m.kirchhoff(f, 0.0, c) * r.transpose();
        assert!(close(lhs, rhs, 1e-5), "{lhs:?} vs {rhs:?}");
    }

    #[test]
    fn project_keeps_volume_only() {
        let f = Mat3::from_cols(
            Vec3::new(1.2, 0.1, 0.0),
            Vec3::new(0.3, 0.9, 0.0),
            Vec3::new(0.0, 0.0, 0.8),
        );
        let j = f.determinant();
        let g = WATER_LINEAR.project(f, &mut 0.0, 1e-3);
        assert!((g.determinant() - j).abs() < 1e-5);
        assert!(close(g, Mat3::IDENTITY * j.cbrt(), 1e-6));
        // Inverted: clamped to the minimum volume ratio, stays finite and positive.
        let g = WATER_LINEAR.project(-Mat3::IDENTITY, &mut 0.0, 1e-3);
        assert!((g.determinant() - FLUID_J_MIN).abs() < 1e-6);
        let tau = Fluid {
            bulk_modulus: 1e6,
            eos: Eos::Tait { gamma: 7.0 },
            viscosity: 0.0,
        }
        .kirchhoff(-Mat3::IDENTITY, 0.0, Mat3::ZERO);
        assert!(tau.is_finite());
    }
}

//! Constitutive models, one file per material.
//!
//! Every model answers three questions used by the transfer scheme (MLS-MPM, Hu et al. 2018):
//! * [`Model::kirchhoff`]: the Kirchhoff stress `tau = P F^T` of the elastic deformation gradient,
//! * [`Model::project`]: the plastic return mapping applied to the trial `F` after each step,
//! * [`Model::sound_speed`]: the elastic wave speed, for the CFL time step.

pub mod drucker_prager;
pub mod fixed_corotated;
pub mod fluid;
pub mod neo_hookean;
pub mod snow;
pub mod von_mises;

pub use drucker_prager::{Cone, DruckerPrager};
pub use fixed_corotated::FixedCorotated;
pub use fluid::{Eos, Fluid};
pub use neo_hookean::NeoHookean;
pub use snow::Snow;
pub use von_mises::VonMises;

use crate::math::{Mat3, Real};

/// Lamé parameters `(mu, lambda)` from Young's modulus and Poisson's ratio.
pub fn lame(youngs_modulus: Real, poisson_ratio: Real) -> (Real, Real) {
    let (e, nu) = (youngs_modulus, poisson_ratio);
    let mu = e / (2.0 * (1.0 + nu));
    let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    (mu, lambda)
}

/// A constitutive model with its parameters (SI units).
#[derive(Clone, Debug, PartialEq)]
pub enum Model {
    Fluid(Fluid),
    FixedCorotated(FixedCorotated),
    NeoHookean(NeoHookean),
    Snow(Snow),
    DruckerPrager(DruckerPrager),
    VonMises(VonMises),
}

/// A named material of a scene: density and constitutive model.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// Density (kg/m^3).
    pub density: Real,
    pub model: Model,
}

impl Model {
    /// Kirchhoff stress `tau = P(F) F^T` (= J sigma). `c` is the APIC velocity gradient, used by
    /// viscous models.
    pub fn kirchhoff(&self, f: Mat3, plastic: Real, c: Mat3) -> Mat3 {
        match self {
            Model::Fluid(m) => m.kirchhoff(f, c),
            Model::FixedCorotated(m) => m.kirchhoff(f),
            Model::NeoHookean(m) => m.kirchhoff(f),
            Model::Snow(m) => m.kirchhoff(f, plastic),
            Model::DruckerPrager(m) => m.kirchhoff(f),
            Model::VonMises(m) => m.kirchhoff(f),
        }
    }

    /// Plastic return mapping: maps the trial elastic `F` to the admissible one and updates the
    /// plastic state scalar. Purely elastic models return `f_trial` unchanged.
    pub fn project(&self, f_trial: Mat3, plastic: &mut Real) -> Mat3 {
        match self {
            Model::Fluid(m) => m.project(f_trial),
            Model::FixedCorotated(_) | Model::NeoHookean(_) => f_trial,
            Model::Snow(m) => m.project(f_trial, plastic),
            Model::DruckerPrager(m) => m.project(f_trial, plastic),
            Model::VonMises(m) => m.project(f_trial, plastic),
        }
    }

    /// Elastic strain energy density per reference volume, for the models that define one
    /// (fixed corotated); None for the others.
    pub fn energy_density(&self, f: Mat3) -> Option<Real> {
        match self {
            Model::FixedCorotated(m) => Some(m.energy_density(f)),
            _ => None,
        }
    }

    /// Initial value of the plastic state scalar (snow: `Jp = 1`).
    pub fn initial_plastic(&self) -> Real {
        match self {
            Model::Snow(_) => 1.0,
            _ => 0.0,
        }
    }

    /// P-wave speed `sqrt((lambda + 2 mu) / rho)` (fluid: `sqrt(K / rho)`), for the CFL condition.
    pub fn sound_speed(&self, density: Real) -> Real {
        let modulus = match self {
            Model::Fluid(m) => m.bulk_modulus * m.eos_stiffness_factor(),
            Model::FixedCorotated(m) => m.lambda + 2.0 * m.mu,
            Model::NeoHookean(m) => m.lambda + 2.0 * m.mu,
            Model::Snow(m) => m.max_stiffness(),
            Model::DruckerPrager(m) => m.lambda + 2.0 * m.mu,
            Model::VonMises(m) => m.lambda + 2.0 * m.mu,
        };
        (modulus / density).sqrt()
    }

    /// Short name of the model kind, as written in scene files.
    pub fn kind(&self) -> &'static str {
        match self {
            Model::Fluid(_) => "fluid",
            Model::FixedCorotated(_) => "fixed_corotated",
            Model::NeoHookean(_) => "neo_hookean",
            Model::Snow(_) => "snow",
            Model::DruckerPrager(_) => "drucker_prager",
            Model::VonMises(_) => "von_mises",
        }
    }
}

//! What every constitutive model provides ([`Constitutive`]), and the Lamé parameters of the
//! elastic solids.

use super::table::ParamError;
use crate::math::{Mat3, Real};

/// Lamé parameters `(mu, lambda)` from Young's modulus and Poisson's ratio.
pub fn lame(youngs_modulus: Real, poisson_ratio: Real) -> (Real, Real) {
    let (e, nu) = (youngs_modulus, poisson_ratio);
    let mu = e / (2.0 * (1.0 + nu));
    let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    (mu, lambda)
}

/// A constitutive model: what a model file provides.
pub trait Constitutive: Sized {
    /// The name in scene files (`type = "..."`); also the name of its kernel file
    /// (`kernels/material/<NAME>.cuh`) and of its device functions (`<NAME>_kirchhoff`, ...).
    const NAME: &'static str;
    /// One line for `rtmpm check` and the docs.
    const SUMMARY: &'static str;
    /// Its parameters on the device, in order: the CUDA crate emits them as the fields of a
    /// `real` struct (`FluidParams` for `fluid`) that the `.cuh` reads; [`Self::gpu_params`]
    /// gives their values.
    const GPU_PARAMS: &'static [&'static str];
    /// Default colour in pictures (linear RGB, 0..1).
    const COLOUR: [f32; 3];
    /// Its parameters as written in a `[[material]]` table (every field but `name`, `type` and
    /// `density`); serde rejects unknown fields.
    type Params: serde::de::DeserializeOwned;

    /// Check the parameters and build the model; the error names the field and a fix.
    fn new(p: Self::Params) -> Result<Self, ParamError>;
    /// Kirchhoff stress `tau = P(F) F^T` (`= J sigma`) of the elastic `F`, with the plastic state
    /// scalar and the APIC velocity gradient `c` (viscous models).
    fn kirchhoff(&self, f: Mat3, plastic: Real, c: Mat3) -> Mat3;
    /// Plastic return mapping of the trial elastic `F` at the end of a step of length `dt`
    /// (rate-dependent models), updating the plastic state scalar. Elastic models return
    /// `f_trial`.
    fn project(&self, f_trial: Mat3, _plastic: &mut Real, _dt: Real) -> Mat3 {
        f_trial
    }
    /// Initial value of the plastic state scalar.
    fn initial_plastic(&self) -> Real {
        0.0
    }
    /// The largest P-wave modulus (`lambda + 2 mu`; a fluid's `K dp/dJ`) the model can reach:
    /// the sound speed of the CFL condition is `sqrt(modulus / density)`.
    fn wave_modulus(&self) -> Real;
    /// Elastic strain energy density per reference volume, where the model defines one.
    fn energy_density(&self, _f: Mat3) -> Option<Real> {
        None
    }
    /// The values of [`Self::GPU_PARAMS`], in that order.
    fn gpu_params(&self) -> Vec<Real>;
}

/// What the registry knows of a model without an instance (for the CUDA contract and docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelInfo {
    /// [`Constitutive::NAME`].
    pub name: &'static str,
    /// [`Constitutive::SUMMARY`].
    pub summary: &'static str,
    /// [`Constitutive::GPU_PARAMS`].
    pub gpu_params: &'static [&'static str],
}

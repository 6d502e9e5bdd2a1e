//! Constitutive models, one file per material.
//!
//! A model file holds everything about its material on the Rust side: its scene parameters
//! (a serde struct, with validation and the error hints), its stress and return mapping, and
//! the encoding of its parameters for the GPU. Its twin on the device is
//! `crates/rtmpm-cuda/kernels/material/<name>.cuh`. Every model implements [`Constitutive`]; the
//! registry below (`models!`) lists them once, and everything that dispatches on the model (the
//! [`Model`] enum, the scene's `type = "..."`, the GPU kind codes, the kernels' material switch,
//! which the CUDA crate generates from [`Model::ALL`]) follows from that list.
//!
//! Adding a material: a model file here, its `.cuh`, one line in `models!`, an example scene,
//! and its section in `docs/scene-format.md`.
//!
//! Every model answers the questions of the transfer scheme (MLS-MPM, Hu et al. 2018):
//! [`Constitutive::kirchhoff`] (the Kirchhoff stress `tau = P F^T`), [`Constitutive::project`]
//! (the plastic return mapping of the trial `F`) and [`Constitutive::wave_modulus`] (for the
//! CFL time step).

pub mod drucker_prager;
pub mod fixed_corotated;
pub mod fluid;
pub mod hencky;
pub mod herschel_bulkley;
pub mod nacc;
pub mod neo_hookean;
pub mod params;
pub mod snow;
#[cfg(not(feature = "f64"))]
pub mod table;
pub mod von_mises;
#[cfg(feature = "f64")]
pub use rtmpm_physics::material::table;

pub use drucker_prager::{Cone, DruckerPrager};
pub use fixed_corotated::FixedCorotated;
pub use fluid::{Eos, Fluid};
pub use herschel_bulkley::HerschelBulkley;
pub use nacc::Nacc;
pub use neo_hookean::NeoHookean;
pub use params::{MaterialParams, ParamError};
pub use snow::Snow;
pub use von_mises::VonMises;

use crate::Particles;
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

/// The registry: the enum of models and its dispatch, from one list of `Variant(Type)`; the
/// position in the list is the model's kind code on the GPU.
macro_rules! models {
    ($($variant:ident($ty:ty)),* $(,)?) => {
        /// A constitutive model with its parameters (SI units).
        #[derive(Clone, Debug, PartialEq)]
        pub enum Model {
            $(#[doc = concat!("[`", stringify!($ty), "`]")] $variant($ty)),*
        }

        impl Model {
            /// Every model, in kind-code order.
            pub const ALL: &'static [ModelInfo] = &[$(ModelInfo {
                name: <$ty>::NAME,
                summary: <$ty>::SUMMARY,
                gpu_params: <$ty>::GPU_PARAMS,
            }),*];

            /// Build the model `kind` (a scene's `type`) from its parameters.
            pub fn from_params(p: &MaterialParams) -> Result<Model, ParamError> {
                $(if p.kind == <$ty>::NAME {
                    return Ok(Model::$variant(<$ty>::new(p.deserialize()?)?));
                })*
                Err(params::unknown_kind(&p.kind, Self::ALL))
            }

            /// Kirchhoff stress, see [`Constitutive::kirchhoff`].
            pub fn kirchhoff(&self, f: Mat3, plastic: Real, c: Mat3) -> Mat3 {
                match self { $(Model::$variant(m) => m.kirchhoff(f, plastic, c)),* }
            }

            /// Plastic return mapping, see [`Constitutive::project`].
            pub fn project(&self, f_trial: Mat3, plastic: &mut Real, dt: Real) -> Mat3 {
                match self { $(Model::$variant(m) => m.project(f_trial, plastic, dt)),* }
            }

            /// See [`Constitutive::initial_plastic`].
            pub fn initial_plastic(&self) -> Real {
                match self { $(Model::$variant(m) => m.initial_plastic()),* }
            }

            /// See [`Constitutive::energy_density`].
            pub fn energy_density(&self, f: Mat3) -> Option<Real> {
                match self { $(Model::$variant(m) => m.energy_density(f)),* }
            }

            /// See [`Constitutive::wave_modulus`].
            pub fn wave_modulus(&self) -> Real {
                match self { $(Model::$variant(m) => m.wave_modulus()),* }
            }

            /// Name of the model, as written in scene files.
            pub fn kind(&self) -> &'static str {
                match self { $(Model::$variant(_) => <$ty>::NAME),* }
            }

            /// Default colour in pictures.
            pub fn colour(&self) -> [f32; 3] {
                match self { $(Model::$variant(_) => <$ty>::COLOUR),* }
            }

            /// The parameters on the device, see [`Constitutive::gpu_params`].
            pub fn gpu_params(&self) -> Vec<Real> {
                match self { $(Model::$variant(m) => m.gpu_params()),* }
            }
        }
    };
}

models! {
    Fluid(Fluid),
    FixedCorotated(FixedCorotated),
    NeoHookean(NeoHookean),
    Snow(Snow),
    DruckerPrager(DruckerPrager),
    VonMises(VonMises),
    HerschelBulkley(HerschelBulkley),
    Nacc(Nacc),
}

impl Model {
    /// Kind code on the GPU: the position in [`Model::ALL`].
    pub fn code(&self) -> u32 {
        let kind = self.kind();
        Self::ALL.iter().position(|m| m.name == kind).unwrap_or(0) as u32
    }

    /// P-wave speed `sqrt(modulus / density)` for the CFL condition.
    pub fn sound_speed(&self, density: Real) -> Real {
        (self.wave_modulus() / density).sqrt()
    }
}

/// A named material of a scene: density, constitutive model, and the parameters it was built
/// from (each precision builds its own model from them, [`Material::new`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// Density (kg/m^3).
    pub density: Real,
    pub model: Model,
    /// `type` and the model's fields as written in the scene.
    pub params: MaterialParams,
}

impl Material {
    /// Build the material: the model from `params`.
    pub fn new(name: &str, density: Real, params: MaterialParams) -> Result<Material, ParamError> {
        Ok(Material {
            name: name.to_string(),
            density,
            model: Model::from_params(&params)?,
            params,
        })
    }

    /// A material from TOML text of its model's fields, e.g.
    /// `Material::parse("water", 1000.0, "fluid", "bulk_modulus = 1e5")` (tests, examples).
    pub fn parse(
        name: &str,
        density: Real,
        kind: &str,
        fields: &str,
    ) -> Result<Material, ParamError> {
        Material::new(name, density, MaterialParams::parse(kind, fields)?)
    }
}

/// Cauchy stress `sigma = tau / J` per particle, `[xx, yy, zz, xy, yz, xz]` (Pa), from each
/// particle's material model in `materials` (the `stress` field of output frames; the
/// renderer's von Mises colouring).
pub fn cauchy_stress(p: &Particles, materials: &[Material]) -> Vec<[Real; 6]> {
    (0..p.len())
        .map(|i| {
            let model = &materials[p.material[i] as usize].model;
            cauchy_stress_of(model, p.f[i], p.plastic[i], p.c[i])
        })
        .collect()
}

/// The Cauchy stress of one particle of material model `model`, `[xx, yy, zz, xy, yz, xz]`
/// (Pa), see [`cauchy_stress`].
pub fn cauchy_stress_of(model: &Model, f: Mat3, plastic: Real, c: Mat3) -> [Real; 6] {
    let j = f.determinant();
    let s = model.kirchhoff(f, plastic, c) * (1.0 / j);
    [
        s.x_axis.x, s.y_axis.y, s.z_axis.z, s.y_axis.x, s.z_axis.y, s.z_axis.x,
    ]
}

//! The registry of the constitutive models: one list, `models!`, gives the [`Model`] enum and
//! its dispatch, the scene's `type = "..."` names and the GPU kind codes; and the named
//! [`Material`] of a scene.

use super::constitutive::{Constitutive, ModelInfo};
use super::drucker_prager::DruckerPrager;
use super::fixed_corotated::FixedCorotated;
use super::fluid::Fluid;
use super::herschel_bulkley::HerschelBulkley;
use super::nacc::Nacc;
use super::neo_hookean::NeoHookean;
use super::params;
use super::snow::Snow;
use super::table::{MaterialParams, ParamError};
use super::von_mises::VonMises;
use crate::math::{Mat3, Real};
use crate::particles::Particles;

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

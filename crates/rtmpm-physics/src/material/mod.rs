//! Constitutive models, one file per material.
//!
//! A model file holds everything about its material on the Rust side: its scene parameters
//! (a serde struct, with validation and the error hints), its stress and return mapping, and
//! the encoding of its parameters for the GPU. Its twin on the device is
//! `crates/rtmpm-cuda/kernels/material/<name>.cuh`. Every model implements [`Constitutive`]; the
//! registry (`registry.rs`, `models!`) lists them once, and everything that dispatches on the model (the
//! [`Model`] enum, the scene's `type = "..."`, the GPU kind codes, the kernels' material switch,
//! which the CUDA crate generates from [`Model::ALL`]) follows from that list.
//!
//! Adding a material: a model file here, its `.cuh`, one line in `models!` (`registry.rs`), an example scene,
//! and its section in `docs/scene-format.md`.
//!
//! Every model answers the questions of the transfer scheme (MLS-MPM, Hu et al. 2018):
//! [`Constitutive::kirchhoff`] (the Kirchhoff stress `tau = P F^T`), [`Constitutive::project`]
//! (the plastic return mapping of the trial `F`) and [`Constitutive::wave_modulus`] (for the
//! CFL time step).

pub mod constitutive;
pub mod drucker_prager;
pub mod fixed_corotated;
pub mod fluid;
pub mod hencky;
pub mod herschel_bulkley;
pub mod nacc;
pub mod neo_hookean;
pub mod params;
pub mod registry;
pub mod snow;
#[cfg(not(feature = "f64"))]
pub mod table;
pub mod von_mises;
#[cfg(feature = "f64")]
pub use rtmpm_physics::material::table;

pub use constitutive::{Constitutive, ModelInfo, lame};
pub use drucker_prager::{Cone, DruckerPrager};
pub use fixed_corotated::FixedCorotated;
pub use fluid::{Eos, Fluid};
pub use herschel_bulkley::HerschelBulkley;
pub use nacc::Nacc;
pub use neo_hookean::NeoHookean;
pub use registry::{Material, Model, cauchy_stress, cauchy_stress_of};
pub use snow::Snow;
pub use table::{MaterialParams, ParamError};
pub use von_mises::VonMises;

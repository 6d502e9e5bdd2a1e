//! The host/device contract, defined once, here: the constants the kernels and the host share
//! (particle fields, control words, error bits, limits, material, collider, boundary and
//! transfer codes) and the layouts of every struct copied to the GPU. The kernels get the
//! constants from a generated header (`contract.cuh`, [`prelude`]), the material registry from
//! another (`material/registry.cuh`, [`material_registry`]), and the program ends with a
//! `static_assert` per field of every struct ([`layout_asserts`]): a C struct that drifts from
//! its Rust twin fails to compile, naming the field.
//!
//! Precision: one mechanism. Every struct that holds `real` values is generic over the host
//! type (`f32` or `f64`) and declared with `real` on the device ([`Scalars`], [`StepParams`],
//! [`MaterialGpu`]); every other struct ([`Ctx`], [`GpuCollider`], [`ColliderPoses`], ...) has
//! no precision. Every struct derives (or, for the generic ones, implements with a compile-time
//! proof of no padding) `bytemuck::Pod`, so no padding byte is ever read.

mod constants;
mod headers;
mod layout;
pub mod render;
mod state_layout;

pub use constants::*;
pub use headers::{layout_asserts, material_registry, materials, prelude, shape_registry};
pub use layout::*;
pub use state_layout::{MAX_FIELDS, StateLayout};

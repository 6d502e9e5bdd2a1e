//! rtmpm's CPU physics in double precision.
//!
//! This crate has no physics of its own: it compiles rtmpm-core's physics source files
//! (`math`, `shape`, `svd`, `material/`, `particles`, `boundary/rules`, `cpu/`) a second time,
//! with its own [`real`] module where `Real = f64`, `Vec3 = glam::DVec3` and `Mat3 = glam::DMat3`.
//! Every formula therefore has one source, in rtmpm-core, and runs in both precisions.
//!
//! The scene, the grid layout and the [`sim::Backend`] interface are rtmpm-core's (f32 at the
//! interface): [`cpu::CpuBackend`] converts the particles to f64 when it is created and back to
//! f32 in `read_particles`. Collider geometry (analytic shapes and mesh SDFs) is evaluated by
//! rtmpm-core in f32, see [`boundary::Collider`].

// The unit tests inside the shared files are written for f32 and run in rtmpm-core: in test mode
// (only `cargo clippy --all-targets` builds it) this library is empty.
#![cfg(not(test))]
// The shared files widen their f32 statistics with `as f64`, a no-op here.
#![allow(clippy::unnecessary_cast)]

pub mod boundary;
#[path = "../../rtmpm-core/src/cpu/mod.rs"]
pub mod cpu;
#[path = "../../rtmpm-core/src/material/mod.rs"]
pub mod material;
#[path = "../../rtmpm-core/src/math.rs"]
pub mod math;
#[path = "../../rtmpm-core/src/particles.rs"]
pub mod particles;
pub mod real;
#[path = "../../rtmpm-core/src/shape.rs"]
pub mod shape;
#[path = "../../rtmpm-core/src/svd.rs"]
pub mod svd;

/// rtmpm-core's simulation interface, with the particle health check of this precision.
pub mod sim {
    pub use crate::particles::{MAX_CELLS_PER_STEP, check_particle};
    pub use rtmpm_core::sim::*;
}

pub use particles::Particles;
pub use rtmpm_core::{grid, rigid, scene, transfer};

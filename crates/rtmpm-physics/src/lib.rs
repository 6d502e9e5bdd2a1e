//! rtmpm's physics in one precision: what the Material Point Method computes, independent of the
//! scene format and of the compute backend.
//!
//! * [`real`]: the precision, [`real::Real`] (f32 here; the package `rtmpm-physics-f64` compiles
//!   these same files with `Real = f64`); [`convert`]: the f32 scene's and interface's values in
//!   it.
//! * [`math`], [`svd`]: small linear algebra and the 3x3 SVD / polar decomposition.
//! * [`shape_function`]: the shape functions of the transfers (quadratic B-splines of MLS-MPM,
//!   uGIMP, linear hats) on the 3x3x3 node stencil; [`compact_kernel`]: the compact kernel of
//!   CK-MPM on two staggered grids (2x2x2 nodes each).
//! * [`transfer`]: the particle-grid transfer schemes (MLS/APIC, GIMP, linear MPM; USL/MUSL;
//!   PIC/FLIP) selected by a scene's `[solver]` table.
//! * [`material`]: one file per constitutive model (stress and return mapping) and the registry.
//! * [`particles`]: particle state, struct-of-arrays.
//! * [`boundary`]: the boundary rule of walls and colliders, and the domain walls.
//! * [`grid`]: the sparse grid layout of Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern
//!   GPUs" (GTC 2022): 4x4x4 blocks, 64-bit interleaved codes, block hash to dense ids,
//!   gblocks/pblocks with 3x3x3 neighbour lists.
//!
//! What does not depend on the precision ([`grid`], [`transfer`], [`material::table`],
//! [`boundary::Condition`]) is compiled in the f32 package only; the f64 package uses those
//! types, so that one scene serves both precisions.

// Statistics are widened to f64 with `as f64`, a no-op in the f64 package.
#![cfg_attr(feature = "f64", allow(clippy::unnecessary_cast))]

pub mod boundary;
pub mod compact_kernel;
pub mod convert;
#[cfg(not(feature = "f64"))]
pub mod grid;
pub mod material;
pub mod math;
pub mod particles;
pub mod real;
pub mod shape_function;
pub mod svd;
#[cfg(not(feature = "f64"))]
pub mod transfer;

#[cfg(feature = "f64")]
pub use rtmpm_physics::{grid, transfer};

pub use particles::Particles;

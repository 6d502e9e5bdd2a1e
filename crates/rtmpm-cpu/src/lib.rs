//! The CPU reference backend: explicit MLS-MPM (APIC, quadratic B-splines) or, per scene, the
//! classic MPM transfers (uGIMP or linear hats, USL or MUSL, PIC/FLIP; see [`physics::transfer`]),
//! parallel with rayon and deterministic: the same scene gives the same result bit for bit
//! whatever the number of threads. Every quantity of the step is a [`Real`]: f32 in the package
//! `rtmpm-cpu`, f64 in the package `rtmpm-cpu-f64`, which compiles these same files with its
//! feature `f64` against `rtmpm-physics-f64` (both name their physics dependency `physics`; see
//! [`physics::real`]).
//!
//! One step is four stages, each in its own file (MUSL adds a re-map: `g2p_mpm_velocity`,
//! `p2g_musl`, `grid_update_musl` before the final G2P):
//! 1. [`rebuild`]: stencil base of every particle, block layout (sorted block codes, gblocks,
//!    pblocks, 3x3x3 neighbour lists) and the particle order (sorted by block, then cell), all in
//!    parallel. The CPU rebuilds every step (the free zone that avoids it is a GPU optimisation)
//!    and re-sorts the particle storage every [`rebuild::RESORT_EVERY`] steps.
//! 2. [`p2g`]: particle to grid, scattered block by block in 8 colour passes (no atomics).
//! 3. [`grid_update`]: momentum to velocity, gravity, walls and colliders.
//! 4. [`g2p`]: grid to particle, deformation update, plasticity, advection, health check.

// Statistics are widened to f64 with `as f64`, a no-op in the f64 package.
#![cfg_attr(feature = "f64", allow(clippy::unnecessary_cast))]

mod backend;
mod collider;
pub mod g2p;
pub mod grid_update;
pub mod p2g;
pub mod rebuild;
mod state;
mod step;
// Run in both precisions (`cargo test -p rtmpm-cpu -p rtmpm-cpu-f64`; CI checks it test by test,
// scripts/check_f64_tests.py).
#[cfg(test)]
mod tests;

pub use collider::Collider;
pub use state::{CpuBackend, GRID_PAD, MAX_THREADS, Node, StepConstants};

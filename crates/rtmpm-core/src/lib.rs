//! rtmpm core: everything that is not tied to one compute backend.
//!
//! * [`real`]: the precision of the physics (f32 here; `rtmpm-f64` compiles the same physics
//!   files in f64).
//! * [`math`], [`svd`], [`shape`]: small linear algebra, the 3x3 SVD/polar decomposition and the
//!   shape functions (quadratic B-splines of MLS-MPM, uGIMP, linear hats).
//! * [`transfer`]: the particle-grid transfer schemes (MLS/APIC, GIMP, linear MPM; USL/MUSL;
//!   PIC/FLIP) selected by a scene's `[solver]` table.
//! * [`material`]: one file per constitutive model (stress and return mapping).
//! * [`grid`]: the sparse grid layout of Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022) (4x4x4 blocks, 64-bit interleaved codes,
//!   block hash to dense ids, gblocks/pblocks with 3x3x3 neighbour lists).
//! * [`particles`]: particle state, struct-of-arrays.
//! * [`boundary`]: domain walls and colliders (signed distance fields, OBJ meshes).
//! * [`scene`]: the TOML scene schema, its validation and particle sampling.
//! * [`sim`]: the backend trait and the frame/step driver shared by every backend.
//! * [`cpu`]: the CPU reference backend (deterministic, rayon).
//! * [`io`]: PLY, VTK XML (.vtu/.pvd) and checkpoints, all written atomically.
//! * [`surface`]: fluid surfaces as triangle meshes (reconstruction: cargo feature `surface`).
//! * [`render`]: CPU particle renderer (shaded spheres, ground, shadows, colour bar), PNG/GIF.
//! * [`rigid`], [`emitter`]: dynamic rigid bodies coupled to the grid, particle emitters;
//!   [`checks`]: the measurements of their validation cases.

pub mod boundary;
pub mod checks;
pub mod cpu;
pub mod emitter;
pub mod grid;
pub mod io;
pub mod material;
pub mod math;
pub mod particles;
pub mod real;
pub mod render;
pub mod rigid;
pub mod scene;
pub mod shape;
pub mod sim;
pub mod surface;
pub mod svd;
pub mod transfer;

pub use particles::Particles;
pub use scene::Scene;

//! rtmpm core: the scene, its I/O and rendering, and the simulation interface, on top of the
//! physics of `rtmpm-physics`.
//!
//! * [`boundary`]: colliders (signed distance fields, OBJ meshes, keyframed motion).
//! * [`scene`]: the TOML scene schema, its validation and particle sampling.
//! * [`sim`]: the backend trait and the frame/step driver shared by every backend.
//! * [`io`]: PLY, VTK XML (.vtu/.pvd) and checkpoints, all written atomically.
//! * [`surface`]: fluid surfaces as triangle meshes (reconstruction: cargo feature `surface`).
//! * [`render`]: CPU particle renderer (shaded spheres, ground, shadows, colour bar), PNG/GIF.
//! * [`rigid`], [`emitter`]: dynamic rigid bodies coupled to the grid, particle emitters;
//!   [`checks`]: the measurements of their validation cases.

pub mod boundary;
pub mod checks;
pub mod emitter;
pub mod io;
pub mod render;
pub mod rigid;
pub mod scene;
pub mod sim;
pub mod surface;

pub use scene::Scene;

// The physics lives in rtmpm-physics; until the other crates name it, its modules are reachable
// here as before.
pub use rtmpm_physics::{Particles, grid, material, math, particles, real, svd, transfer};

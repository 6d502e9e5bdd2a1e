//! Fluid surfaces: a triangle mesh per frame around the particles of chosen materials (fluids
//! by default), for rendering here and for Houdini, Blender and ParaView.
//!
//! [`reconstruct`] (cargo feature `surface`, on in the `rtmpm` command) runs `splashsurf_lib`
//! (Löschner, Longva, Jeske, Kugelstadt and Bender, "Weighted Laplacian smoothing for surface
//! reconstruction of particle-based fluids", VMV 2023): an SPH density field of the particles
//! (cubic spline kernel) on a sparse marching-cubes grid, split into subdomains processed in
//! parallel, then Laplacian smoothing of the vertices and area-weighted vertex normals,
//! themselves smoothed. Without the feature, [`TriMesh`] and the writers still exist (the
//! renderer draws meshes either way) and [`AVAILABLE`] is false.

pub mod memory;
mod mesh;
mod params;
#[cfg(feature = "surface")]
mod reconstruct;

pub use mesh::TriMesh;
pub use params::{SurfaceParams, radius_of_volume};
#[cfg(feature = "surface")]
pub use reconstruct::reconstruct;

/// True when this build can reconstruct surfaces (cargo feature `surface`).
pub const AVAILABLE: bool = cfg!(feature = "surface");

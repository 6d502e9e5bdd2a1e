//! Triangle meshes from OBJ files and their signed distance grids (stub).

use crate::math::Vec3;

/// A signed distance field sampled on a regular grid around a closed triangle mesh.
#[derive(Clone, Debug)]
pub struct MeshSdf {
    pub origin: Vec3,
    pub spacing: f32,
    pub dims: [u32; 3],
    /// Distances, x fastest.
    pub values: Vec<f32>,
}

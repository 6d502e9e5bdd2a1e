//! Filling bodies with particles (stub).

use super::{Scene, SceneError};
use crate::Particles;
use crate::boundary::mesh::MeshSdf;
use crate::math::Vec3;
use std::sync::Arc;

/// Geometry of a body.
#[derive(Clone, Debug)]
pub enum BodyShape {
    Box {
        min: Vec3,
        max: Vec3,
    },
    Sphere {
        center: Vec3,
        radius: f32,
    },
    Cylinder {
        center: Vec3,
        axis: Vec3,
        radius: f32,
        half_height: f32,
    },
    Mesh(Arc<MeshSdf>),
}

/// Sample every body of the scene.
pub fn sample_scene(_scene: &Scene) -> Result<Particles, SceneError> {
    todo!()
}

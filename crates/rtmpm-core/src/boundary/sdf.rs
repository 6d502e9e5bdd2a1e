//! Signed distance functions of collider shapes (stub).

use super::mesh::MeshSdf;
use crate::math::Vec3;
use std::sync::Arc;

/// Collider shape in its rest pose; negative distance inside.
#[derive(Clone, Debug)]
pub enum Shape {
    /// Points `x` with `(x - point) . normal < 0` are inside.
    HalfSpace {
        point: Vec3,
        normal: Vec3,
    },
    Box {
        center: Vec3,
        half_extents: Vec3,
    },
    Sphere {
        center: Vec3,
        radius: f32,
    },
    /// Capped cylinder along unit `axis`.
    Cylinder {
        center: Vec3,
        axis: Vec3,
        radius: f32,
        half_height: f32,
    },
    /// Triangle mesh sampled into a signed distance grid.
    Mesh(Arc<MeshSdf>),
}

impl Shape {
    /// Signed distance (negative inside).
    pub fn distance(&self, _x: Vec3) -> f32 {
        todo!()
    }
    /// Outward unit normal (gradient of the distance).
    pub fn normal(&self, _x: Vec3) -> Vec3 {
        todo!()
    }
}

//! The shape of a body of material (`[[body]]`, `[[emitter]]`): what the sampler fills with
//! particles.

use crate::mesh::MeshSdf;
use crate::points::PointSet;
use crate::sdf::{box_distance, cylinder_distance};
use glam::Vec3;
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
    /// Capped cylinder along unit `axis`.
    Cylinder {
        center: Vec3,
        axis: Vec3,
        radius: f32,
        half_height: f32,
    },
    Mesh(Arc<MeshSdf>),
    /// The points of a particle file, and whether the body uses the file's velocities.
    Particles {
        points: Arc<PointSet>,
        file_velocity: bool,
    },
}

impl BodyShape {
    /// True when `x` is inside (mesh: signed distance < 0; analytic shapes include the surface).
    pub fn contains(&self, x: Vec3) -> bool {
        match self {
            BodyShape::Box { min, max } => x.cmpge(*min).all() && x.cmple(*max).all(),
            BodyShape::Sphere { center, radius } => {
                (x - *center).length_squared() <= radius * radius
            }
            BodyShape::Cylinder {
                center,
                axis,
                radius,
                half_height,
            } => cylinder_distance(x, *center, *axis, *radius, *half_height) <= 0.0,
            BodyShape::Mesh(m) => m.distance(x) < 0.0,
            BodyShape::Particles { .. } => false,
        }
    }

    /// Signed distance (negative inside).
    pub fn distance(&self, x: Vec3) -> f32 {
        match self {
            BodyShape::Box { min, max } => {
                box_distance(x, 0.5 * (*min + *max), 0.5 * (*max - *min))
            }
            BodyShape::Sphere { center, radius } => (x - *center).length() - radius,
            BodyShape::Cylinder {
                center,
                axis,
                radius,
                half_height,
            } => cylinder_distance(x, *center, *axis, *radius, *half_height),
            BodyShape::Mesh(m) => m.distance(x),
            // A cloud of points has no inside.
            BodyShape::Particles { .. } => f32::INFINITY,
        }
    }

    /// Axis-aligned bounding box `(min, max)`.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        match self {
            BodyShape::Box { min, max } => (*min, *max),
            BodyShape::Sphere { center, radius } => (*center - *radius, *center + *radius),
            BodyShape::Cylinder {
                center,
                axis,
                radius,
                half_height,
            } => {
                let a = *axis;
                let e = Vec3::new(
                    half_height * a.x.abs() + radius * (1.0 - a.x * a.x).max(0.0).sqrt(),
                    half_height * a.y.abs() + radius * (1.0 - a.y * a.y).max(0.0).sqrt(),
                    half_height * a.z.abs() + radius * (1.0 - a.z * a.z).max(0.0).sqrt(),
                );
                (*center - e, *center + e)
            }
            BodyShape::Mesh(m) => (m.mesh_min, m.mesh_max),
            BodyShape::Particles { points, .. } => {
                let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
                for p in &points.positions {
                    lo = lo.min(*p);
                    hi = hi.max(*p);
                }
                (lo, hi)
            }
        }
    }

    /// Volume (m^3): analytic, or estimated from the signed distance grid for meshes.
    pub fn volume(&self) -> f32 {
        match self {
            BodyShape::Box { min, max } => (*max - *min).max(Vec3::ZERO).element_product(),
            BodyShape::Sphere { radius, .. } => 4.0 / 3.0 * std::f32::consts::PI * radius.powi(3),
            BodyShape::Cylinder {
                radius,
                half_height,
                ..
            } => std::f32::consts::PI * radius * radius * 2.0 * half_height,
            BodyShape::Mesh(m) => m.volume(),
            BodyShape::Particles { points, .. } => points
                .volumes
                .as_ref()
                .map_or(0.0, |v| v.iter().map(|&x| x as f64).sum::<f64>() as f32),
        }
    }
}

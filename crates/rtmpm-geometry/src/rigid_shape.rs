//! A rigid body's shape about its centre of mass, in the body frame: box, sphere, cylinder or
//! closed triangle mesh ([`RigidMesh`]).

use crate::rigid_mesh::RigidMesh;
use crate::sdf::{Shape, box_distance, cylinder_distance, sphere_distance};
use glam::{Mat3, Vec3};
use std::sync::Arc;

/// A body's shape about its centre, in its rest orientation.
#[derive(Clone, Debug, PartialEq)]
pub enum RigidShape {
    Box {
        half_extents: Vec3,
    },
    Sphere {
        radius: f32,
    },
    /// A capped cylinder whose axis is the body's local y axis.
    Cylinder {
        radius: f32,
        half_height: f32,
    },
    /// A closed triangle mesh about its centre of mass.
    Mesh(Arc<RigidMesh>),
}

impl RigidShape {
    /// Volume (m^3).
    pub fn volume(&self) -> f32 {
        match *self {
            RigidShape::Box { half_extents } => {
                8.0 * half_extents.x * half_extents.y * half_extents.z
            }
            RigidShape::Sphere { radius } => 4.0 / 3.0 * std::f32::consts::PI * radius.powi(3),
            RigidShape::Cylinder {
                radius,
                half_height,
            } => std::f32::consts::PI * radius * radius * 2.0 * half_height,
            RigidShape::Mesh(ref m) => m.volume,
        }
    }

    /// Surface area (m^2).
    pub fn area(&self) -> f32 {
        use std::f32::consts::PI;
        match *self {
            RigidShape::Box { half_extents: h } => 8.0 * (h.x * h.y + h.y * h.z + h.z * h.x),
            RigidShape::Sphere { radius } => 4.0 * PI * radius * radius,
            RigidShape::Cylinder {
                radius,
                half_height,
            } => 2.0 * PI * radius * (radius + 2.0 * half_height),
            RigidShape::Mesh(ref m) => m.mesh.area(),
        }
    }

    /// Signed distance (negative inside) of the point `p` given in the body frame.
    pub fn distance(&self, p: Vec3) -> f32 {
        match *self {
            RigidShape::Box { half_extents } => box_distance(p, Vec3::ZERO, half_extents),
            RigidShape::Sphere { radius } => sphere_distance(p, Vec3::ZERO, radius),
            RigidShape::Cylinder {
                radius,
                half_height,
            } => cylinder_distance(p, Vec3::ZERO, Vec3::Y, radius, half_height),
            RigidShape::Mesh(ref m) => m.sdf.distance(p),
        }
    }

    /// Outward unit normal at `p` (body frame), as the colliders' shapes compute it.
    pub fn normal(&self, p: Vec3) -> Vec3 {
        match *self {
            RigidShape::Box { half_extents } => Shape::Box {
                center: Vec3::ZERO,
                half_extents,
            }
            .normal(p),
            RigidShape::Sphere { .. } => p.try_normalize().unwrap_or(Vec3::Y),
            RigidShape::Cylinder {
                radius,
                half_height,
            } => Shape::Cylinder {
                center: Vec3::ZERO,
                axis: Vec3::Y,
                radius,
                half_height,
            }
            .normal(p),
            RigidShape::Mesh(ref m) => m.sdf.normal(p),
        }
    }

    /// The shape as a collider shape about the origin of the body frame (the colliders' signed
    /// distances evaluate it: the renderer, the GPU's coupling).
    pub fn sdf_shape(&self) -> Shape {
        match *self {
            RigidShape::Box { half_extents } => Shape::Box {
                center: Vec3::ZERO,
                half_extents,
            },
            RigidShape::Sphere { radius } => Shape::Sphere {
                center: Vec3::ZERO,
                radius,
            },
            RigidShape::Cylinder {
                radius,
                half_height,
            } => Shape::Cylinder {
                center: Vec3::ZERO,
                axis: Vec3::Y,
                radius,
                half_height,
            },
            RigidShape::Mesh(ref m) => Shape::Mesh(m.sdf.clone()),
        }
    }

    /// Radius of a sphere about the centre that holds the shape (for a mesh, precomputed: its
    /// farthest vertex).
    pub fn bounding_radius(&self) -> f32 {
        match self {
            RigidShape::Mesh(m) => m.radius,
            _ => self.world_half_extents(Mat3::IDENTITY).length(),
        }
    }

    /// Half-extents of the axis-aligned box around the shape turned by `r`.
    pub fn world_half_extents(&self, r: Mat3) -> Vec3 {
        match *self {
            RigidShape::Box { half_extents } => {
                let a = Mat3::from_cols(r.x_axis.abs(), r.y_axis.abs(), r.z_axis.abs());
                a * half_extents
            }
            RigidShape::Sphere { radius } => Vec3::splat(radius),
            RigidShape::Cylinder {
                radius,
                half_height,
            } => {
                // The half-height along the turned axis plus the radius of the caps' discs
                // (their extent along world x is radius sqrt(a_y^2 + a_z^2), a the unit axis;
                // summed this way, not as 1 - a_x^2, a lying cylinder's bound is exact).
                let a = r.y_axis;
                let a2 = a * a;
                let disc = Vec3::new(a2.y + a2.z, a2.x + a2.z, a2.x + a2.y);
                a.abs() * half_height
                    + Vec3::new(disc.x.sqrt(), disc.y.sqrt(), disc.z.sqrt()) * radius
            }
            RigidShape::Mesh(ref m) => m.world_half_extents(r),
        }
    }
}

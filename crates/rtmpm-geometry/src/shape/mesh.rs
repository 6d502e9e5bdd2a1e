//! A triangle mesh from an OBJ file (`shape = "mesh"`): its signed distance grid, and for a
//! rigid body the closed solid with its mass properties.

use super::kind::{GpuParams, ShapeFields, ShapeKind, UsdPrim, Use};
use crate::mesh::MeshSdf;
use crate::rigid_mesh::RigidMesh;
use glam::{Mat3, Quat, Vec3};
use std::sync::Arc;

/// Grid cells of margin around a mesh's signed distance grid.
pub const MARGIN: u32 = 3;

/// A mesh: the signed distance grid the simulation evaluates (spacing half a cell), and, for a
/// rigid body, the closed mesh in the body frame with its exact volume and inertia (whose
/// `sdf` is this one).
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    pub sdf: Arc<MeshSdf>,
    pub solid: Option<Arc<RigidMesh>>,
}

impl Mesh {
    /// The mesh of a rigid body.
    pub fn solid(m: RigidMesh) -> Mesh {
        Mesh {
            sdf: m.sdf.clone(),
            solid: Some(Arc::new(m)),
        }
    }
}

impl ShapeKind for Mesh {
    const NAME: &'static str = "mesh";
    const NOUN: &'static str = "a mesh";
    const FIELDS: &'static [&'static str] = &["file", "scale", "translate"];
    const USES: &'static [Use] = &[Use::Collider, Use::Body, Use::RigidBody];

    fn read<F: ShapeFields>(f: &F, _: Use) -> Result<Self, F::Error> {
        let (mesh, _) = f.mesh_file()?;
        Ok(Mesh {
            sdf: Arc::new(MeshSdf::build(&mesh, 0.5 * f.dx(), MARGIN)),
            solid: None,
        })
    }

    /// A closed mesh about its centre of mass, which is the body's position; `convex`: the
    /// engine collides it as its convex hull.
    fn read_body<F: ShapeFields>(f: &F) -> Result<(Self, Vec3, Quat), F::Error> {
        let (mesh, path) = f.mesh_file()?;
        let (m, com) = RigidMesh::new(&mesh, f.convex(), 0.5 * f.dx(), MARGIN).map_err(|e| {
            f.error(
                "file",
                format!("{} cannot be a rigid body: {e}", path.display()),
                e.fix(),
            )
        })?;
        Ok((Mesh::solid(m), com, Quat::IDENTITY))
    }

    /// A mesh is read in its frame ([`ShapeKind::read_body`]).
    fn body_frame(self) -> (Self, Vec3, Quat) {
        (self, Vec3::ZERO, Quat::IDENTITY)
    }

    fn distance(&self, x: Vec3) -> f32 {
        self.sdf.distance(x)
    }

    fn normal(&self, x: Vec3) -> Vec3 {
        self.sdf.normal(x)
    }

    /// Signed distance < 0.
    fn contains(&self, x: Vec3) -> bool {
        self.sdf.distance(x) < 0.0
    }

    /// The mesh's own bounds.
    fn bounds(&self) -> (Vec3, Vec3) {
        (self.sdf.mesh_min, self.sdf.mesh_max)
    }

    /// The distance grid.
    fn distance_bounds(&self) -> (Vec3, Vec3) {
        (self.sdf.origin, self.sdf.grid_max())
    }

    /// The centre of the mesh's bounding box.
    fn center(&self) -> Vec3 {
        0.5 * (self.sdf.mesh_min + self.sdf.mesh_max)
    }

    /// Exact for a rigid body's closed mesh, else estimated from the grid.
    fn volume(&self) -> f32 {
        match &self.solid {
            Some(m) => m.volume,
            None => self.sdf.volume(),
        }
    }

    /// A rigid body's mesh; NaN for a mesh whose triangles are not kept.
    fn area(&self) -> f32 {
        self.solid.as_ref().map_or(f32::NAN, |m| m.mesh.area())
    }

    /// A rigid body's: exact (the extreme vertices); else the turned bounding box.
    fn half_extents(&self, r: Mat3) -> Vec3 {
        match &self.solid {
            Some(m) => m.world_half_extents(r),
            None => {
                let a = Mat3::from_cols(r.x_axis.abs(), r.y_axis.abs(), r.z_axis.abs());
                a * (0.5 * (self.sdf.mesh_max - self.sdf.mesh_min))
            }
        }
    }

    /// A rigid body's: its farthest vertex.
    fn bounding_radius(&self) -> f32 {
        match &self.solid {
            Some(m) => m.radius,
            None => self.half_extents(Mat3::IDENTITY).length(),
        }
    }

    /// The grid's origin and spacing, its dimensions and values.
    fn gpu(&self) -> GpuParams<'_> {
        let o = self.sdf.origin;
        GpuParams {
            dims: self.sdf.dims,
            values: &self.sdf.values,
            ..GpuParams::of(&[o.x, o.y, o.z, self.sdf.spacing])
        }
    }

    /// A rigid body's triangles.
    fn usd(&self) -> Option<UsdPrim<'_>> {
        self.solid.as_ref().map(|m| UsdPrim::Mesh(&m.mesh))
    }
}

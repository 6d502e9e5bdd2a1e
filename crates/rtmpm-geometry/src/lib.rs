//! rtmpm's geometry: every shape a scene describes and the signed distances the simulation
//! evaluates, in f32 like the scene.
//!
//! * [`sdf`]: analytic signed distance functions and the collider [`sdf::Shape`].
//! * [`mesh`]: triangle meshes ([`mesh::TriMesh`], parsed from OBJ text) and their signed
//!   distance grids ([`mesh::MeshSdf`]).
//! * [`body_shape`]: the shape of a body of material ([`BodyShape`], what the sampler fills).
//! * [`rigid_shape`], [`rigid_mesh`]: the shape of a rigid body about its centre of mass
//!   ([`RigidShape`]; closed meshes with their mass properties, [`RigidMesh`]).
//! * [`points`]: the points of a particle file ([`PointSet`]).
//! * [`collider`], [`keyframes`]: colliders (a shape, its boundary rule and its motion: constant
//!   velocities or keyframes).
//! * [`tool`]: the user's tool of a live view, a kinematic collider.
//! * [`surface`]: fluid surfaces as triangle meshes with normals (reconstruction: cargo
//!   feature `surface`).

pub mod body_shape;
pub mod collider;
pub mod keyframes;
pub mod mesh;
pub mod points;
pub mod rigid_mesh;
pub mod rigid_shape;
pub mod sdf;
pub mod surface;
pub mod tool;

pub use body_shape::BodyShape;
pub use collider::Collider;
pub use keyframes::{Keyframe, Keyframes};
pub use points::PointSet;
pub use rigid_mesh::{
    MAX_BODY_TRIANGLES, MeshBodyError, RigidMesh, mass_properties as mesh_mass_properties,
};
pub use rigid_shape::RigidShape;
pub use tool::{Tool, ToolShape};

//! rtmpm's geometry: every shape a scene describes and the signed distances the simulation
//! evaluates, in f32 like the scene.
//!
//! * [`shape`]: the one shape vocabulary ([`Shape`]: half-space, box, sphere, cylinder, mesh,
//!   particles), what a collider, a body, an emitter and a rigid body is: signed distances,
//!   inside tests, bounds, the scene fields of each shape and where it may be used.
//! * [`mesh`]: triangle meshes ([`mesh::TriMesh`], parsed from OBJ text) and their signed
//!   distance grids ([`mesh::MeshSdf`]).
//! * [`rigid_mesh`]: closed meshes with their mass properties ([`RigidMesh`]), a mesh rigid
//!   body's solid.
//! * [`points`]: the points of a particle file ([`PointSet`]).
//! * [`collider`], [`keyframes`]: colliders (a shape, its boundary rule and its motion: constant
//!   velocities or keyframes).
//! * [`tool`]: the user's tool of a live view, a kinematic collider.
//! * [`surface`]: fluid surfaces as triangle meshes with normals (reconstruction: cargo
//!   feature `surface`).

pub mod collider;
pub mod keyframes;
pub mod mesh;
pub mod points;
pub mod rigid_mesh;
pub mod shape;
pub mod surface;
pub mod tool;

pub use collider::Collider;
pub use keyframes::{Keyframe, Keyframes};
pub use points::PointSet;
pub use rigid_mesh::{
    MAX_BODY_TRIANGLES, MeshBodyError, RigidMesh, mass_properties as mesh_mass_properties,
};
pub use shape::{Shape, ShapeInfo, Use};
pub use tool::{Tool, ToolShape};

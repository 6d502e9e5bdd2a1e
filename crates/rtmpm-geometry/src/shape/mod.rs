//! The one shape vocabulary of rtmpm: every collider, body, emitter, rigid body and the user's
//! tool is a [`Shape`].
//!
//! A shape file holds everything about its shape on the Rust side: its scene fields and their
//! checks ([`ShapeKind::read`], through the scene's validator, [`ShapeFields`]), where a scene
//! may use it ([`ShapeKind::USES`]), its signed distance, normal and inside test, its bounds,
//! volume and area, its frame as a rigid body, its parameters on the GPU and its USD primitive.
//! Its twin on the device is `crates/rtmpm-cuda/kernels/geometry/<name>.cuh` (distance, normal,
//! inside test, shared by the grid update, the device sampler and the render stage). The
//! registry (`registry.rs`, `shapes!`) lists them once; everything that dispatches on the shape
//! (the [`Shape`] enum, the scene's `shape = "..."`, the check of a shape's use, the GPU kind
//! codes and the kernels' shape switch, which the CUDA crate generates from [`Shape::ALL`])
//! follows from that list.
//!
//! Adding a shape: its file here and two lines in this one (its `mod`, its line in the
//! `shapes!` list below), its `kernels/geometry/<name>.cuh`, its rigid-body collider in
//! `rtmpm-rigid/src/world.rs` (where rigid bodies may be of it), and its section in
//! `docs/scene-format.md`.

#[macro_use]
mod registry;

mod cuboid;
mod cylinder;
mod half_space;
mod kind;
mod mesh;
mod points;
mod sphere;

pub use cuboid::Cuboid;
pub use cylinder::Cylinder;
pub use half_space::HalfSpace;
pub use mesh::{MARGIN as MESH_MARGIN, Mesh};
pub use points::Points;
pub use sphere::Sphere;

pub use kind::{
    GpuParams, ShapeFields, ShapeInfo, ShapeKind, UsdPrim, Use, box_distance, cylinder_distance,
    fmt3, usd_number,
};

use glam::{Mat3, Quat, Vec3};

// The shapes, `Variant(Type)`: the position in this list is the shape's kind code on the GPU.
shapes! {
    HalfSpace(HalfSpace),
    Box(Cuboid),
    Sphere(Sphere),
    Cylinder(Cylinder),
    Mesh(Mesh),
    Particles(Points),
}

/// The shapes `u` may be, as a message's fix lists them: `"box" (min, max), "sphere" (center,
/// radius) or "cylinder" (center, axis, radius, height)`.
pub fn allowed_for(u: Use) -> String {
    let names: Vec<String> = Shape::ALL
        .iter()
        .filter(|s| s.allows(u))
        .map(ShapeInfo::with_fields)
        .collect();
    match names.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => String::new(),
    }
}

#[cfg(test)]
mod tests;

//! The floating-point precision of the physics: single precision (f32) in this crate.
//!
//! The physics modules (`math`, `shape`, `svd`, `material`, `particles`, `boundary/rules`, `cpu`)
//! are written against [`Real`], [`Vec3`] and [`Mat3`] from this module. The crate `rtmpm-f64`
//! compiles the very same source files a second time with its own `real` module, where `Real` is
//! f64 (`glam::DVec3`, `glam::DMat3`): one source of truth per formula, two precisions.
//!
//! The scene and the [`crate::sim::Backend`] interface stay f32; the functions below convert
//! from them into this precision and back (here: identities, no rounding).

use crate::boundary::{Collider, Walls};
use crate::material::Material;
use crate::sim;
pub use glam::{Mat3, Vec3};

/// The floating-point type of every quantity the step computes.
pub type Real = f32;

/// Name of the precision, as written in scene files (`[solver] precision`).
pub const PRECISION: &str = "f32";

/// Integer grid index to a vector of [`Real`].
pub trait ToReal {
    /// The same vector in [`Real`].
    fn to_real(self) -> Vec3;
}

impl ToReal for glam::IVec3 {
    #[inline]
    fn to_real(self) -> Vec3 {
        self.as_vec3()
    }
}

/// A scalar of the scene or interface (f32) in [`Real`].
#[inline]
pub fn real(x: f32) -> Real {
    x
}

/// A vector of the scene or interface (f32) in [`Real`].
#[inline]
pub fn vec3(v: glam::Vec3) -> Vec3 {
    v
}

/// A [`Real`] back to the interface's f32.
#[inline]
pub fn to_f32(x: Real) -> f32 {
    x
}

/// A vector back to the interface's f32.
#[inline]
pub fn vec3_to_f32(v: Vec3) -> glam::Vec3 {
    v
}

/// A matrix back to the interface's f32.
#[inline]
pub fn mat3_to_f32(m: Mat3) -> glam::Mat3 {
    m
}

/// The interface's particles in this precision.
pub fn particles(p: sim::Particles) -> crate::Particles {
    p
}

/// The scene's materials in this precision.
pub fn materials(m: &[Material]) -> Result<Vec<Material>, sim::SimError> {
    Ok(m.to_vec())
}

/// The scene's walls in this precision.
pub fn walls(w: &Walls) -> Walls {
    w.clone()
}

/// The scene's colliders in this precision.
pub fn colliders(c: &[Collider]) -> Vec<Collider> {
    c.to_vec()
}

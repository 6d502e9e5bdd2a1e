//! The floating-point precision of this crate's physics: double precision (f64).
//!
//! rtmpm-core's `real.rs` is the f32 twin of this file; the physics files compiled here import
//! [`Real`], [`Vec3`] and [`Mat3`] from it. The conversions below take the scene's and the
//! interface's f32 values into f64 (exactly) and back (rounded to nearest).

use crate::boundary::{BoundaryRule, Collider, Walls};
use crate::material::Material;
use crate::sim;
pub use glam::{DMat3 as Mat3, DVec3 as Vec3};
use rtmpm_core::material as core;

/// The floating-point type of every quantity the step computes.
pub type Real = f64;

/// Name of the precision, as written in scene files (`[solver] precision`).
pub const PRECISION: &str = "f64";

/// Integer grid index to a vector of [`Real`].
pub trait ToReal {
    /// The same vector in [`Real`].
    fn to_real(self) -> Vec3;
}

impl ToReal for glam::IVec3 {
    #[inline]
    fn to_real(self) -> Vec3 {
        self.as_dvec3()
    }
}

/// A scalar of the scene or interface (f32) in [`Real`].
#[inline]
pub fn real(x: f32) -> Real {
    x as f64
}

/// A vector of the scene or interface (f32) in [`Real`].
#[inline]
pub fn vec3(v: glam::Vec3) -> Vec3 {
    v.as_dvec3()
}

/// A matrix of the interface (f32) in [`Real`].
#[inline]
pub fn mat3(m: glam::Mat3) -> Mat3 {
    m.as_dmat3()
}

/// A [`Real`] back to the interface's f32.
#[inline]
pub fn to_f32(x: Real) -> f32 {
    x as f32
}

/// A vector back to the interface's f32.
#[inline]
pub fn vec3_to_f32(v: Vec3) -> glam::Vec3 {
    v.as_vec3()
}

/// A matrix back to the interface's f32.
#[inline]
pub fn mat3_to_f32(m: Mat3) -> glam::Mat3 {
    m.as_mat3()
}

/// The interface's particles in this precision.
pub fn particles(p: sim::Particles) -> crate::Particles {
    crate::Particles {
        x: p.x.iter().map(|&v| vec3(v)).collect(),
        v: p.v.iter().map(|&v| vec3(v)).collect(),
        c: p.c.iter().map(|&m| mat3(m)).collect(),
        f: p.f.iter().map(|&m| mat3(m)).collect(),
        plastic: p.plastic.iter().map(|&x| real(x)).collect(),
        mass: p.mass.iter().map(|&x| real(x)).collect(),
        vol0: p.vol0.iter().map(|&x| real(x)).collect(),
        material: p.material,
    }
}

/// The scene's materials in this precision: each model built from the scene's parameters by the
/// shared model files (`material/<model>.rs`), so the f64 models are those of the scene text,
/// not widened f32 models.
pub fn materials(m: &[core::Material]) -> Result<Vec<Material>, sim::SimError> {
    m.iter()
        .map(|m| {
            Material::new(&m.name, real(m.density), m.params.clone())
                .map_err(|e| sim::SimError::Backend(format!("material `{}` in f64: {e}", m.name)))
        })
        .collect()
}

/// A boundary rule in this precision.
pub fn rule(r: &rtmpm_core::boundary::BoundaryRule) -> BoundaryRule {
    BoundaryRule {
        condition: r.condition,
        friction: real(r.friction),
    }
}

/// The scene's walls in this precision.
pub fn walls(w: &rtmpm_core::boundary::Walls) -> Walls {
    Walls {
        thickness: w.thickness,
        faces: w.faces.each_ref().map(rule),
    }
}

/// The scene's colliders, their rules in this precision (geometry stays f32, see
/// [`Collider`]).
pub fn colliders(c: &[rtmpm_core::boundary::Collider]) -> Vec<Collider> {
    c.iter()
        .map(|c| Collider {
            rule: rule(&c.rule),
            geometry: c.clone(),
        })
        .collect()
}

//! The floating-point precision of the physics: f32 in the package `rtmpm-physics`, f64 in the
//! package `rtmpm-physics-f64`, which compiles these same source files with its feature `f64`.
//!
//! Every formula is written against [`Real`], [`Vec3`] and [`Mat3`] of this module: one source
//! per formula, two precisions. The scene and the backend interface stay f32 (they use the
//! f32 package's types); the functions below take their values into this precision (exactly) and
//! back (rounded to nearest; in f32 all of them are identities).

#[cfg(feature = "f64")]
pub use glam::{DMat3 as Mat3, DVec3 as Vec3};
#[cfg(not(feature = "f64"))]
pub use glam::{Mat3, Vec3};

#[cfg(not(feature = "f64"))]
use crate as single;
use crate::boundary::{BoundaryRule, Walls};
use crate::material::Material;
#[cfg(feature = "f64")]
use rtmpm_physics as single;

/// The floating-point type of every quantity the step computes.
#[cfg(not(feature = "f64"))]
pub type Real = f32;
/// The floating-point type of every quantity the step computes.
#[cfg(feature = "f64")]
pub type Real = f64;

/// Name of the precision, as written in scene files (`[solver] precision`).
pub const PRECISION: &str = if cfg!(feature = "f64") { "f64" } else { "f32" };

/// Integer grid index to a vector of [`Real`].
pub trait ToReal {
    /// The same vector in [`Real`].
    fn to_real(self) -> Vec3;
}

impl ToReal for glam::IVec3 {
    #[inline]
    fn to_real(self) -> Vec3 {
        #[cfg(not(feature = "f64"))]
        return self.as_vec3();
        #[cfg(feature = "f64")]
        return self.as_dvec3();
    }
}

/// A scalar of the scene or interface (f32) in [`Real`].
#[inline]
pub fn real(x: f32) -> Real {
    Real::from(x)
}

/// A vector of the scene or interface (f32) in [`Real`].
#[inline]
pub fn vec3(v: glam::Vec3) -> Vec3 {
    #[cfg(not(feature = "f64"))]
    return v;
    #[cfg(feature = "f64")]
    return v.as_dvec3();
}

/// A matrix of the interface (f32) in [`Real`].
#[inline]
pub fn mat3(m: glam::Mat3) -> Mat3 {
    #[cfg(not(feature = "f64"))]
    return m;
    #[cfg(feature = "f64")]
    return m.as_dmat3();
}

/// A [`Real`] back to the interface's f32.
#[inline]
pub fn to_f32(x: Real) -> f32 {
    #[cfg(not(feature = "f64"))]
    return x;
    #[cfg(feature = "f64")]
    return x as f32;
}

/// A vector back to the interface's f32.
#[inline]
pub fn vec3_to_f32(v: Vec3) -> glam::Vec3 {
    #[cfg(not(feature = "f64"))]
    return v;
    #[cfg(feature = "f64")]
    return v.as_vec3();
}

/// A matrix back to the interface's f32.
#[inline]
pub fn mat3_to_f32(m: Mat3) -> glam::Mat3 {
    #[cfg(not(feature = "f64"))]
    return m;
    #[cfg(feature = "f64")]
    return m.as_mat3();
}

/// The interface's particles (f32) in this precision.
pub fn particles(p: single::Particles) -> crate::Particles {
    #[cfg(not(feature = "f64"))]
    return p;
    #[cfg(feature = "f64")]
    return crate::Particles {
        x: p.x.iter().map(|&v| vec3(v)).collect(),
        v: p.v.iter().map(|&v| vec3(v)).collect(),
        c: p.c.iter().map(|&m| mat3(m)).collect(),
        f: p.f.iter().map(|&m| mat3(m)).collect(),
        plastic: p.plastic.iter().map(|&x| real(x)).collect(),
        mass: p.mass.iter().map(|&x| real(x)).collect(),
        vol0: p.vol0.iter().map(|&x| real(x)).collect(),
        material: p.material,
    };
}

/// The scene's materials in this precision: in f64 each model is built again from the
/// parameters as written (`Material::params`) by the model files, so the f64 models are those
/// of the scene text, not widened f32 models. The error names the material.
pub fn materials(m: &[single::material::Material]) -> Result<Vec<Material>, String> {
    #[cfg(not(feature = "f64"))]
    return Ok(m.to_vec());
    #[cfg(feature = "f64")]
    return m
        .iter()
        .map(|m| {
            Material::new(&m.name, real(m.density), m.params.clone())
                .map_err(|e| format!("material `{}` in f64: {e}", m.name))
        })
        .collect();
}

/// A boundary rule of the scene in this precision.
pub fn rule(r: &single::boundary::BoundaryRule) -> BoundaryRule {
    BoundaryRule {
        condition: r.condition,
        friction: real(r.friction),
    }
}

/// The scene's walls in this precision.
pub fn walls(w: &single::boundary::Walls) -> Walls {
    Walls {
        thickness: w.thickness,
        faces: w.faces.each_ref().map(rule),
    }
}

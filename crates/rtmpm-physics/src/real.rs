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

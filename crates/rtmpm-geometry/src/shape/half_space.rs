//! A half-space: the points behind a plane (`shape = "half_space"`, colliders only).

use super::kind::{GpuParams, ShapeFields, ShapeKind, UsdPrim, Use};
use glam::{Mat3, Quat, Vec3};

/// Points `x` with `(x - point) . normal < 0` are inside; `normal` is a unit vector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfSpace {
    pub point: Vec3,
    pub normal: Vec3,
}

impl ShapeKind for HalfSpace {
    const NAME: &'static str = "half_space";
    const NOUN: &'static str = "a half-space";
    const FIELDS: &'static [&'static str] = &["point", "normal"];
    const USES: &'static [Use] = &[Use::Collider];
    const REFUSAL: &'static str = "it is infinite";

    fn read<F: ShapeFields>(f: &F, _: Use) -> Result<Self, F::Error> {
        let point = f.point("point")?;
        let normal = f.vector("normal").ok_or_else(|| f.missing("normal"))?;
        let normal = f.unit("normal", normal, "normal")?;
        Ok(HalfSpace { point, normal })
    }

    fn body_frame(self) -> (Self, Vec3, Quat) {
        (self, Vec3::ZERO, Quat::IDENTITY)
    }

    fn distance(&self, x: Vec3) -> f32 {
        (x - self.point).dot(self.normal)
    }

    fn normal(&self, _: Vec3) -> Vec3 {
        self.normal
    }

    fn contains(&self, x: Vec3) -> bool {
        self.distance(x) <= 0.0
    }

    /// The whole space.
    fn bounds(&self) -> (Vec3, Vec3) {
        (Vec3::NEG_INFINITY, Vec3::INFINITY)
    }

    /// The point of the plane.
    fn center(&self) -> Vec3 {
        self.point
    }

    fn volume(&self) -> f32 {
        f32::INFINITY
    }

    fn area(&self) -> f32 {
        f32::INFINITY
    }

    fn half_extents(&self, _: Mat3) -> Vec3 {
        Vec3::INFINITY
    }

    /// Point, unit normal.
    fn gpu(&self) -> GpuParams<'_> {
        let (p, n) = (self.point, self.normal);
        GpuParams::of(&[p.x, p.y, p.z, n.x, n.y, n.z])
    }

    fn usd(&self) -> Option<UsdPrim<'_>> {
        None
    }
}

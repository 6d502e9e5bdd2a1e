//! A ball (`shape = "sphere"`).

use super::kind::{GpuParams, ShapeFields, ShapeKind, UsdPrim, Use, usd_number};
use glam::{Mat3, Quat, Vec3};

/// The ball of this centre and radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

impl ShapeKind for Sphere {
    const NAME: &'static str = "sphere";
    const NOUN: &'static str = "a sphere";
    const FIELDS: &'static [&'static str] = &["center", "radius"];
    const USES: &'static [Use] = &[Use::Collider, Use::Body, Use::Emitter, Use::RigidBody];

    fn read<F: ShapeFields>(f: &F, _: Use) -> Result<Self, F::Error> {
        let center = f.point("center")?;
        let radius = f.length("radius")?;
        Ok(Sphere { center, radius })
    }

    fn body_frame(self) -> (Self, Vec3, Quat) {
        let body = Sphere {
            center: Vec3::ZERO,
            radius: self.radius,
        };
        (body, self.center, Quat::IDENTITY)
    }

    fn distance(&self, x: Vec3) -> f32 {
        (x - self.center).length() - self.radius
    }

    /// At the centre, where it is undefined: +y.
    fn normal(&self, x: Vec3) -> Vec3 {
        (x - self.center).try_normalize().unwrap_or(Vec3::Y)
    }

    /// The surface included.
    fn contains(&self, x: Vec3) -> bool {
        (x - self.center).length_squared() <= self.radius * self.radius
    }

    fn bounds(&self) -> (Vec3, Vec3) {
        (self.center - self.radius, self.center + self.radius)
    }

    fn center(&self) -> Vec3 {
        self.center
    }

    fn volume(&self) -> f32 {
        4.0 / 3.0 * std::f32::consts::PI * self.radius.powi(3)
    }

    fn area(&self) -> f32 {
        4.0 * std::f32::consts::PI * self.radius * self.radius
    }

    fn half_extents(&self, _: Mat3) -> Vec3 {
        Vec3::splat(self.radius)
    }

    /// Centre, radius.
    fn gpu(&self) -> GpuParams<'_> {
        let c = self.center;
        GpuParams::of(&[c.x, c.y, c.z, self.radius])
    }

    fn usd(&self) -> Option<UsdPrim<'_>> {
        Some(UsdPrim::Schema {
            schema: "Sphere",
            attributes: vec![format!("double radius = {}", usd_number(self.radius))],
        })
    }
}

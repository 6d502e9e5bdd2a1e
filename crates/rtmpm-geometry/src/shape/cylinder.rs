//! A capped cylinder (`shape = "cylinder"`).

use super::kind::{
    GpuParams, ShapeFields, ShapeKind, UsdPrim, Use, any_perpendicular, cylinder_distance,
    usd_number,
};
use glam::{Mat3, Quat, Vec3};

/// The capped cylinder of this centre, unit axis, radius and half-height (in a rigid body's
/// frame: about the origin, along y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    pub center: Vec3,
    pub axis: Vec3,
    pub radius: f32,
    pub half_height: f32,
}

impl ShapeKind for Cylinder {
    const NAME: &'static str = "cylinder";
    const NOUN: &'static str = "a cylinder";
    const FIELDS: &'static [&'static str] = &["center", "axis", "radius", "height"];
    const USES: &'static [Use] = &[Use::Collider, Use::Body, Use::Emitter, Use::RigidBody];

    /// `axis` defaults to y; `height` is the full height.
    fn read<F: ShapeFields>(f: &F, _: Use) -> Result<Self, F::Error> {
        let center = f.point("center")?;
        let axis = f.unit("axis", f.vector("axis").unwrap_or([0.0, 1.0, 0.0]), "axis")?;
        let radius = f.length("radius")?;
        let height = f.length("height")?;
        Ok(Cylinder {
            center,
            axis,
            radius,
            half_height: 0.5 * height,
        })
    }

    /// About the centre along y (rapier's cylinders and ours), turned to `axis`.
    fn body_frame(self) -> (Self, Vec3, Quat) {
        let body = Cylinder {
            center: Vec3::ZERO,
            axis: Vec3::Y,
            ..self
        };
        (
            body,
            self.center,
            Quat::from_rotation_arc(Vec3::Y, self.axis),
        )
    }

    fn distance(&self, x: Vec3) -> f32 {
        cylinder_distance(x, self.center, self.axis, self.radius, self.half_height)
    }

    fn normal(&self, x: Vec3) -> Vec3 {
        let p = x - self.center;
        let h = p.dot(self.axis);
        let radial = p - h * self.axis;
        let r = radial.length();
        let er = if r > 0.0 {
            radial / r
        } else {
            any_perpendicular(self.axis)
        };
        let ea = if h >= 0.0 { self.axis } else { -self.axis };
        let dr = r - self.radius;
        let dh = h.abs() - self.half_height;
        if dr > 0.0 && dh > 0.0 {
            (er * dr + ea * dh).normalize()
        } else if dr > 0.0 || (dr <= 0.0 && dh <= 0.0 && dr >= dh) {
            er
        } else {
            ea
        }
    }

    /// The surface included.
    fn contains(&self, x: Vec3) -> bool {
        self.distance(x) <= 0.0
    }

    /// Per axis: the half-height along the axis plus the radius of the caps' discs.
    fn bounds(&self) -> (Vec3, Vec3) {
        let a = self.axis;
        let disc = (Vec3::ONE - a * a).max(Vec3::ZERO);
        let e = a.abs() * self.half_height
            + Vec3::new(disc.x.sqrt(), disc.y.sqrt(), disc.z.sqrt()) * self.radius;
        (self.center - e, self.center + e)
    }

    fn center(&self) -> Vec3 {
        self.center
    }

    fn volume(&self) -> f32 {
        std::f32::consts::PI * self.radius * self.radius * 2.0 * self.half_height
    }

    fn area(&self) -> f32 {
        2.0 * std::f32::consts::PI * self.radius * (self.radius + 2.0 * self.half_height)
    }

    /// The half-height along the turned axis plus the radius of the caps' discs (their extent
    /// along world x is radius sqrt(a_y^2 + a_z^2), a the unit axis; summed this way, not as
    /// 1 - a_x^2, a lying cylinder's bound is exact).
    fn half_extents(&self, r: Mat3) -> Vec3 {
        let a = r * self.axis;
        let a2 = a * a;
        let disc = Vec3::new(a2.y + a2.z, a2.x + a2.z, a2.x + a2.y);
        a.abs() * self.half_height
            + Vec3::new(disc.x.sqrt(), disc.y.sqrt(), disc.z.sqrt()) * self.radius
    }

    /// Centre, unit axis, radius, half-height.
    fn gpu(&self) -> GpuParams<'_> {
        let (c, a) = (self.center, self.axis);
        GpuParams::of(&[c.x, c.y, c.z, a.x, a.y, a.z, self.radius, self.half_height])
    }

    /// A `Cylinder` along y (a cylinder in its body frame).
    fn usd(&self) -> Option<UsdPrim<'_>> {
        Some(UsdPrim::Schema {
            schema: "Cylinder",
            attributes: vec![
                "uniform token axis = \"Y\"".into(),
                format!("double height = {}", usd_number(2.0 * self.half_height)),
                format!("double radius = {}", usd_number(self.radius)),
            ],
        })
    }
}

//! An axis-aligned box (`shape = "box"`).

use super::kind::{
    GpuParams, ShapeFields, ShapeKind, UsdPrim, Use, box_distance, fmt3, usd_number,
};
use glam::{Mat3, Quat, Vec3};

/// The box `min .. max` (in a rigid body's frame: `-h .. h`). Its signed distance is taken
/// about its centre `(min + max) / 2` with half-extents `(max - min) / 2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cuboid {
    pub min: Vec3,
    pub max: Vec3,
}

impl Cuboid {
    /// The box of this centre and these half-extents.
    pub fn centred(center: Vec3, half_extents: Vec3) -> Cuboid {
        Cuboid {
            min: center - half_extents,
            max: center + half_extents,
        }
    }

    /// Its centre.
    pub fn middle(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Its half-extents.
    pub fn half_size(&self) -> Vec3 {
        0.5 * (self.max - self.min)
    }
}

impl ShapeKind for Cuboid {
    const NAME: &'static str = "box";
    const NOUN: &'static str = "a box";
    const FIELDS: &'static [&'static str] = &["min", "max"];
    const USES: &'static [Use] = &[Use::Collider, Use::Body, Use::Emitter, Use::RigidBody];

    fn read<F: ShapeFields>(f: &F, _: Use) -> Result<Self, F::Error> {
        let min = f.point("min")?;
        let max = f.point("max")?;
        if !max.cmpgt(min).all() {
            return Err(f.error(
                "max",
                format!(
                    "box max {} is not above min {} on every axis",
                    fmt3(max),
                    fmt3(min)
                ),
                "make every component of max larger than min".into(),
            ));
        }
        Ok(Cuboid { min, max })
    }

    fn body_frame(self) -> (Self, Vec3, Quat) {
        let h = self.half_size();
        let body = Cuboid { min: -h, max: h };
        (body, self.middle(), Quat::IDENTITY)
    }

    fn distance(&self, x: Vec3) -> f32 {
        box_distance(x, self.middle(), self.half_size())
    }

    /// Outside: the gradient of the distance to the nearest point; inside: the face of least
    /// penetration.
    fn normal(&self, x: Vec3) -> Vec3 {
        let p = x - self.middle();
        let q = p.abs() - self.half_size();
        let sign = Vec3::select(p.cmplt(Vec3::ZERO), Vec3::NEG_ONE, Vec3::ONE);
        if q.max_element() > 0.0 {
            return (q.max(Vec3::ZERO) * sign)
                .try_normalize()
                .unwrap_or(Vec3::Y);
        }
        let mut n = Vec3::ZERO;
        let axis = if q.x >= q.y && q.x >= q.z {
            0
        } else if q.y >= q.z {
            1
        } else {
            2
        };
        n[axis] = sign[axis];
        n
    }

    /// The surface included.
    fn contains(&self, x: Vec3) -> bool {
        x.cmpge(self.min).all() && x.cmple(self.max).all()
    }

    fn bounds(&self) -> (Vec3, Vec3) {
        (self.min, self.max)
    }

    /// The centre minus and plus the half-extents.
    fn distance_bounds(&self) -> (Vec3, Vec3) {
        let (c, h) = (self.middle(), self.half_size());
        (c - h, c + h)
    }

    fn center(&self) -> Vec3 {
        self.middle()
    }

    fn volume(&self) -> f32 {
        (self.max - self.min).max(Vec3::ZERO).element_product()
    }

    fn area(&self) -> f32 {
        let h = self.half_size();
        8.0 * (h.x * h.y + h.y * h.z + h.z * h.x)
    }

    fn half_extents(&self, r: Mat3) -> Vec3 {
        let a = Mat3::from_cols(r.x_axis.abs(), r.y_axis.abs(), r.z_axis.abs());
        a * self.half_size()
    }

    /// Min, max.
    fn gpu(&self) -> GpuParams<'_> {
        let (a, b) = (self.min, self.max);
        GpuParams::of(&[a.x, a.y, a.z, b.x, b.y, b.z])
    }

    /// A `Cube` of size 2 scaled to the half-extents (a box about the origin).
    fn usd(&self) -> Option<UsdPrim<'_>> {
        let h = self.half_size();
        Some(UsdPrim::Schema {
            schema: "Cube",
            attributes: vec![
                "double size = 2".into(),
                format!(
                    "float3 xformOp:scale = ({}, {}, {})",
                    usd_number(h.x),
                    usd_number(h.y),
                    usd_number(h.z)
                ),
                "uniform token[] xformOpOrder = [\"xformOp:scale\"]".into(),
            ],
        })
    }
}

//! The points of a particle file (`shape = "particles"`, bodies only): a body that starts as
//! a file's particles.

use super::kind::{GpuParams, ShapeFields, ShapeKind, UsdPrim, Use};
use crate::points::PointSet;
use glam::{Mat3, Quat, Vec3};
use std::sync::Arc;

/// The points of a particle file, placed by `scale` and `translate`.
#[derive(Clone, Debug, PartialEq)]
pub struct Points {
    pub points: Arc<PointSet>,
}

impl ShapeKind for Points {
    const NAME: &'static str = "particles";
    const NOUN: &'static str = "a particle file";
    const FIELDS: &'static [&'static str] = &["file", "scale", "translate"];
    const USES: &'static [Use] = &[Use::Body];
    const REFUSAL: &'static str = "only a body can be made of a file's particles";
    /// The points are the particles: nothing is sampled on the device.
    const DEVICE: bool = false;

    fn read<F: ShapeFields>(f: &F, _: Use) -> Result<Self, F::Error> {
        Ok(Points {
            points: Arc::new(f.points_file()?),
        })
    }

    fn body_frame(self) -> (Self, Vec3, Quat) {
        (self, Vec3::ZERO, Quat::IDENTITY)
    }

    /// A cloud of points has no inside.
    fn distance(&self, _: Vec3) -> f32 {
        f32::INFINITY
    }

    fn normal(&self, _: Vec3) -> Vec3 {
        Vec3::Y
    }

    fn contains(&self, _: Vec3) -> bool {
        false
    }

    /// The bounds of the points.
    fn bounds(&self) -> (Vec3, Vec3) {
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for p in &self.points.positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        (lo, hi)
    }

    /// The centre of their bounds.
    fn center(&self) -> Vec3 {
        let (lo, hi) = self.bounds();
        0.5 * (lo + hi)
    }

    /// The sum of the file's volumes (0 without them).
    fn volume(&self) -> f32 {
        self.points
            .volumes
            .as_ref()
            .map_or(0.0, |v| v.iter().map(|&x| x as f64).sum::<f64>() as f32)
    }

    fn area(&self) -> f32 {
        0.0
    }

    fn half_extents(&self, r: Mat3) -> Vec3 {
        let (lo, hi) = self.bounds();
        let a = Mat3::from_cols(r.x_axis.abs(), r.y_axis.abs(), r.z_axis.abs());
        a * (0.5 * (hi - lo))
    }

    fn gpu(&self) -> GpuParams<'_> {
        GpuParams::default()
    }

    fn usd(&self) -> Option<UsdPrim<'_>> {
        None
    }
}

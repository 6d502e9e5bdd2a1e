//! The scene's colliders as the grid update queries them: the boundary rule in the precision of
//! the step, the shape (analytic or mesh SDF) and motion evaluated in f32 like the scene that
//! describes them.

use physics::boundary::BoundaryRule;
use physics::math::Vec3;
use physics::real;

/// A collider of the scene with its boundary rule in this precision.
#[derive(Clone, Debug)]
pub struct Collider {
    /// The rule, in this precision.
    pub rule: BoundaryRule,
    /// The scene's collider.
    pub geometry: rtmpm_geometry::Collider,
}

impl Collider {
    /// The scene's collider `c`.
    pub fn new(c: &rtmpm_geometry::Collider) -> Collider {
        Collider {
            rule: physics::convert::rule(&c.rule),
            geometry: c.clone(),
        }
    }

    /// At time `t`, if `x` is inside the collider, the outward unit normal and the collider's
    /// velocity at `x` (see `rtmpm_geometry::Collider::query`). The node position goes in
    /// rounded to f32; in f64 the normal comes back renormalised.
    #[inline]
    pub fn query(&self, x: Vec3, t: f32) -> Option<(Vec3, Vec3)> {
        let (n, v) = self.geometry.query(real::vec3_to_f32(x), t)?;
        let n = real::vec3(n);
        #[cfg(feature = "f64")]
        let n = n.normalize();
        Some((n, real::vec3(v)))
    }
}

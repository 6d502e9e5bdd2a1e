//! Boundary conditions in double precision: rtmpm-core's rules and walls compiled in f64, and
//! colliders whose geometry is rtmpm-core's (f32).

#[path = "../../rtmpm-core/src/boundary/rules.rs"]
pub mod rules;

pub use rtmpm_core::boundary::Condition;
pub use rules::{BoundaryRule, Walls};

use crate::real::Vec3;

/// A collider of the scene. Its shape (analytic or mesh SDF) and rigid motion are evaluated by
/// rtmpm-core in f32, like the scene that describes them; the node position goes in rounded to
/// f32, and the normal comes back renormalised in f64. The boundary rule applied with the
/// answer is the f64 one.
#[derive(Clone, Debug)]
pub struct Collider {
    /// The rule, in f64.
    pub rule: BoundaryRule,
    /// The scene's collider.
    pub geometry: rtmpm_core::boundary::Collider,
}

impl Collider {
    /// At time `t`, if `x` is inside the collider, the outward unit normal and the collider's
    /// velocity at `x` (see `rtmpm_core::boundary::Collider::query`).
    pub fn query(&self, x: Vec3, t: f32) -> Option<(Vec3, Vec3)> {
        let (n, v) = self.geometry.query(x.as_vec3(), t)?;
        Some((n.as_dvec3().normalize(), v.as_dvec3()))
    }
}

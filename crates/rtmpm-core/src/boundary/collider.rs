//! Colliders: analytic or mesh shapes moving with a linear and angular velocity (stub).

use super::BoundaryRule;
use super::sdf::Shape;
use crate::math::Vec3;

/// A rigid obstacle.
#[derive(Clone, Debug)]
pub struct Collider {
    pub shape: Shape,
    pub rule: BoundaryRule,
    /// Linear velocity (m/s).
    pub velocity: Vec3,
    /// Angular velocity (rad/s) about `pivot`.
    pub angular_velocity: Vec3,
    /// Centre of rotation at t = 0 (moves with `velocity`).
    pub pivot: Vec3,
}

impl Collider {
    /// At time `t`, if `x` is inside the collider (signed distance <= 0), return the outward
    /// unit normal and the collider's velocity at `x`.
    pub fn query(&self, _x: Vec3, _t: f32) -> Option<(Vec3, Vec3)> {
        todo!()
    }
}

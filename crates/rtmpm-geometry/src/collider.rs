//! Colliders: analytic or mesh shapes moving with a constant linear and angular velocity, or
//! along keyframes ([`Keyframes`]).

use super::keyframes::Keyframes;
use super::shape::Shape;
use glam::{Mat3, Vec3};
use rtmpm_physics::boundary::BoundaryRule;

/// A rigid obstacle.
///
/// Without keyframes, at time `t` the collider has translated by `velocity * t` and rotated by
/// the angle `|angular_velocity| t` about the axis `angular_velocity` around its moving pivot
/// `pivot + velocity * t`. With keyframes, the rest shape is turned about `pivot` by the
/// keyframed rotation and `pivot` is carried to the keyframed position (`velocity` and
/// `angular_velocity` are then zero and unused).
#[derive(Clone, Debug)]
pub struct Collider {
    pub shape: Shape,
    pub rule: BoundaryRule,
    /// Linear velocity (m/s).
    pub velocity: Vec3,
    /// Angular velocity (rad/s) about `pivot`.
    pub angular_velocity: Vec3,
    /// Centre of rotation in the rest pose (at t = 0 without keyframes; moves with `velocity`).
    pub pivot: Vec3,
    /// Keyframed motion, replacing `velocity` and `angular_velocity` when given.
    pub keyframes: Option<Keyframes>,
}

impl Collider {
    /// Linear velocity of the pivot and angular velocity (rad/s) at time `t`: the surface
    /// velocity at world point `x` is `v + w x (x - pivot_at(t))`.
    pub fn motion_at(&self, t: f32) -> (Vec3, Vec3) {
        match &self.keyframes {
            Some(k) => k.velocity(t),
            None => (self.velocity, self.angular_velocity),
        }
    }

    /// Rotation of the collider at time `t` (rest frame to world).
    pub fn rotation(&self, t: f32) -> Mat3 {
        if let Some(k) = &self.keyframes {
            return k.rotation(t);
        }
        let w = self.angular_velocity;
        let speed = w.length();
        if speed > 0.0 {
            Mat3::from_axis_angle(w / speed, speed * t)
        } else {
            Mat3::IDENTITY
        }
    }

    /// Position of the pivot at time `t`.
    pub fn pivot_at(&self, t: f32) -> Vec3 {
        if let Some(k) = &self.keyframes {
            return k.pose(t).0;
        }
        self.pivot + self.velocity * t
    }

    /// Signed distance of the world point `x` to the collider at time `t`.
    pub fn distance(&self, x: Vec3, t: f32) -> f32 {
        let r = self.rotation(t);
        self.shape
            .distance(r.transpose() * (x - self.pivot_at(t)) + self.pivot)
    }

    /// The world position at time `t` of the rest-pose point `x_rest`.
    pub fn to_world(&self, x_rest: Vec3, t: f32) -> Vec3 {
        self.rotation(t) * (x_rest - self.pivot) + self.pivot_at(t)
    }

    /// Axis-aligned world bounds at time `t` (the posed corners of
    /// [`Shape::distance_bounds`]); `None` for a half-space.
    pub fn bounds(&self, t: f32) -> Option<(Vec3, Vec3)> {
        let (lo, hi) = self.shape.finite_bounds()?;
        let (mut wlo, mut whi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let w = self.to_world(c, t);
            wlo = wlo.min(w);
            whi = whi.max(w);
        }
        Some((wlo, whi))
    }

    /// At time `t`, if `x` is inside the collider (signed distance <= 0), return the outward
    /// unit normal and the collider's velocity at `x`.
    pub fn query(&self, x: Vec3, t: f32) -> Option<(Vec3, Vec3)> {
        let r = self.rotation(t);
        let pivot_t = self.pivot_at(t);
        let x_rest = r.transpose() * (x - pivot_t) + self.pivot;
        if self.shape.distance(x_rest) > 0.0 {
            return None;
        }
        let n = (r * self.shape.normal(x_rest))
            .try_normalize()
            .unwrap_or(Vec3::Y);
        let (v, w) = self.motion_at(t);
        Some((n, v + w.cross(x - pivot_t)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shape::{Cuboid, Sphere};
    use rtmpm_physics::boundary::Condition;

    fn rule() -> BoundaryRule {
        BoundaryRule {
            condition: Condition::Slip,
            friction: 0.0,
        }
    }

    #[test]
    fn static_sphere() {
        let c = Collider {
            shape: Shape::Sphere(Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            }),
            rule: rule(),
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            pivot: Vec3::ZERO,
            keyframes: None,
        };
        assert!(c.query(Vec3::new(1.5, 0.0, 0.0), 0.0).is_none());
        let (n, v) = c.query(Vec3::new(0.5, 0.0, 0.0), 3.0).unwrap();
        assert!((n - Vec3::X).length() < 1e-6);
        assert_eq!(v, Vec3::ZERO);
    }

    #[test]
    fn moving_sphere() {
        let c = Collider {
            shape: Shape::Sphere(Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            }),
            rule: rule(),
            velocity: Vec3::new(2.0, 0.0, 0.0),
            angular_velocity: Vec3::ZERO,
            pivot: Vec3::ZERO,
            keyframes: None,
        };
        // At t = 1 the sphere is centred at (2, 0, 0).
        assert!(c.query(Vec3::ZERO, 1.0).is_none());
        let (n, v) = c.query(Vec3::new(2.0, 0.5, 0.0), 1.0).unwrap();
        assert!((n - Vec3::Y).length() < 1e-6);
        assert!((v - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6);
        assert!((c.distance(Vec3::new(4.0, 0.0, 0.0), 1.0) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn rotating_box() {
        // A thin paddle along x, spinning about z at pi/2 rad/s around the origin.
        let w = std::f32::consts::FRAC_PI_2;
        let c = Collider {
            shape: Shape::Box(Cuboid::centred(Vec3::ZERO, Vec3::new(1.0, 0.1, 0.1))),
            rule: rule(),
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::new(0.0, 0.0, w),
            pivot: Vec3::ZERO,
            keyframes: None,
        };
        let tip = Vec3::new(0.0, 0.95, 0.0);
        assert!(c.query(tip, 0.0).is_none());
        // After 1 s the paddle has turned by 90 degrees and lies along y.
        let (n, v) = c.query(tip, 1.0).unwrap();
        assert!((v - Vec3::new(-w * 0.95, 0.0, 0.0)).length() < 1e-5, "{v}");
        // Nearest face of the rotated paddle at the tip is its end, now pointing along +y.
        assert!((n - Vec3::Y).length() < 1e-4, "{n}");
        // A point beside the paddle: normal is the rotated +y face, i.e. -x.
        let (n, _) = c.query(Vec3::new(-0.05, 0.5, 0.0), 1.0).unwrap();
        assert!((n + Vec3::X).length() < 1e-4, "{n}");
    }

    #[test]
    fn rotating_and_translating_pivot() {
        let c = Collider {
            shape: Shape::Sphere(Sphere {
                center: Vec3::new(1.0, 0.0, 0.0),
                radius: 0.25,
            }),
            rule: rule(),
            velocity: Vec3::new(0.0, 0.0, 1.0),
            angular_velocity: Vec3::new(0.0, std::f32::consts::PI, 0.0),
            pivot: Vec3::ZERO,
            keyframes: None,
        };
        // At t = 1: pivot at (0,0,1), the sphere centre rotated by pi about y: (-1, 0, 1).
        let p = Vec3::new(-1.0, 0.0, 1.0);
        let (_, v) = c.query(p, 1.0).unwrap();
        let expect =
            Vec3::new(0.0, 0.0, 1.0) + Vec3::new(0.0, std::f32::consts::PI, 0.0).cross(p - Vec3::Z);
        assert!((v - expect).length() < 1e-5);
        assert!(c.query(Vec3::new(1.0, 0.0, 1.0), 1.0).is_none());
    }
}

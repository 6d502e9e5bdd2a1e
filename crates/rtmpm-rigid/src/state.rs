//! A body's state as the grid update sees it, its pose as the rigid-body engine holds it, and
//! the impulses the grid gives it in a step.

use glam::{Mat3, Quat, Vec3};
use rtmpm_geometry::Shape;
use rtmpm_physics::boundary::Condition;

/// A body's state at the current time, as the grid update sees it.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyState {
    /// The shape in the body frame.
    pub shape: Shape,
    /// Rest-to-world rotation.
    pub rotation: Mat3,
    /// Centre of mass (m).
    pub center: Vec3,
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
    /// True when the material's impulses move it.
    pub dynamic: bool,
    pub condition: Condition,
    pub friction: f32,
}

impl BodyState {
    /// The body at this instant as a motionless collider (one keyframe at its pose), for
    /// pictures: the renderer draws colliders.
    pub fn collider(&self) -> rtmpm_geometry::Collider {
        let key = rtmpm_geometry::Keyframe {
            t: 0.0,
            position: self.center,
            rotation: Quat::from_mat3(&self.rotation).normalize(),
        };
        rtmpm_geometry::Collider {
            shape: self.shape.clone(),
            rule: rtmpm_physics::boundary::BoundaryRule::default(),
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            pivot: Vec3::ZERO,
            keyframes: rtmpm_geometry::Keyframes::new(vec![key]).ok(),
        }
    }

    /// If `x` is inside the body, the outward unit normal and the body's velocity at `x`.
    pub fn query(&self, x: Vec3) -> Option<(Vec3, Vec3)> {
        let p = self.rotation.transpose() * (x - self.center);
        if self.shape.distance(p) > 0.0 {
            return None;
        }
        let n = (self.rotation * self.shape.normal(p))
            .try_normalize()
            .unwrap_or(Vec3::Y);
        Some((
            n,
            self.velocity + self.angular_velocity.cross(x - self.center),
        ))
    }
}

/// A body's pose and velocities as the rigid-body engine holds them, bit for bit: what a
/// checkpoint stores to resume the bodies ([`crate::RigidWorld::poses`], [`crate::RigidWorld::set_poses`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyPose {
    /// The body's origin (its centre) in the world (m).
    pub position: Vec3,
    /// Rest-to-world rotation (unit quaternion).
    pub rotation: Quat,
    pub velocity: Vec3,
    pub angular_velocity: Vec3,
}

impl BodyPose {
    /// True when every component is finite and the rotation is a unit quaternion (within
    /// 1e-3).
    pub fn is_valid(&self) -> bool {
        self.position.is_finite()
            && self.rotation.is_finite()
            && (self.rotation.length() - 1.0).abs() < 1e-3
            && self.velocity.is_finite()
            && self.angular_velocity.is_finite()
    }

    /// What makes the pose invalid, in words (`None` when [`BodyPose::is_valid`]).
    pub fn problem(&self) -> Option<String> {
        let v3 = |v: Vec3| format!("({}, {}, {})", v.x, v.y, v.z);
        if !self.position.is_finite() {
            return Some(format!("its position {} is not finite", v3(self.position)));
        }
        if !self.rotation.is_finite() || (self.rotation.length() - 1.0).abs() >= 1e-3 {
            let q = self.rotation;
            return Some(format!(
                "its rotation quaternion ({}, {}, {}, {}) is not a finite unit quaternion",
                q.x, q.y, q.z, q.w
            ));
        }
        if !self.velocity.is_finite() {
            return Some(format!("its velocity {} is not finite", v3(self.velocity)));
        }
        if !self.angular_velocity.is_finite() {
            return Some(format!(
                "its angular velocity {} is not finite",
                v3(self.angular_velocity)
            ));
        }
        None
    }
}

/// The impulse and angular impulse (about the centre of mass) the grid gives one body in one
/// step, summed in f64.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Exchange {
    pub impulse: [f64; 3],
    pub torque: [f64; 3],
}

impl Exchange {
    /// Add the reaction of a node at offset `r` from the centre whose momentum changed by `dp`.
    pub fn add_reaction(&mut self, r: [f64; 3], dp: [f64; 3]) {
        for (j, d) in self.impulse.iter_mut().zip(dp) {
            *j -= d;
        }
        let t = [
            r[1] * dp[2] - r[2] * dp[1],
            r[2] * dp[0] - r[0] * dp[2],
            r[0] * dp[1] - r[1] * dp[0],
        ];
        for (l, t) in self.torque.iter_mut().zip(t) {
            *l -= t;
        }
    }

    /// Sum of two exchanges.
    pub fn plus(mut self, o: &Exchange) -> Exchange {
        for a in 0..3 {
            self.impulse[a] += o.impulse[a];
            self.torque[a] += o.torque[a];
        }
        self
    }

    /// The mean force and torque of this exchange over a step of `dt` seconds.
    pub fn load(&self, dt: f64) -> BodyLoad {
        let per = |a: [f64; 3]| a.map(|c| if dt > 0.0 { c / dt } else { 0.0 });
        BodyLoad {
            force: per(self.impulse),
            torque: per(self.torque),
        }
    }
}

/// The load the material puts on a body over one step: the impulse and angular impulse of its
/// [`Exchange`] divided by the step's dt. For every kind of body (a kinematic or fixed body is
/// not moved by it, but the material pushes on it all the same: the force on a robot's tool).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BodyLoad {
    /// Force on the body (N).
    pub force: [f64; 3],
    /// Torque about its centre of mass (N m).
    pub torque: [f64; 3],
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_geometry::shape::{Cuboid, Cylinder};

    #[test]
    fn a_turned_box_answers_inside_points_with_its_face_normal_and_velocity() {
        let b = BodyState {
            shape: Shape::Box(Cuboid::centred(Vec3::ZERO, Vec3::new(1.0, 0.5, 0.5))),
            rotation: Mat3::from_rotation_z(std::f32::consts::FRAC_PI_2),
            center: Vec3::new(1.0, 0.0, 0.0),
            velocity: Vec3::X,
            angular_velocity: Vec3::new(0.0, 0.0, 2.0),
            dynamic: true,
            condition: Condition::Slip,
            friction: 0.0,
        };
        // Turned by 90 degrees about z: 1 m long along y now.
        assert!(b.query(Vec3::new(1.0, 0.9, 0.0)).is_some());
        assert!(b.query(Vec3::new(1.9, 0.0, 0.0)).is_none());
        let (n, v) = b.query(Vec3::new(1.45, 0.0, 0.0)).unwrap();
        assert!((n - Vec3::X).length() < 1e-5, "{n}");
        assert!(
            (v - (Vec3::X + Vec3::new(0.0, 0.9, 0.0))).length() < 1e-5,
            "{v}"
        );
    }

    #[test]
    fn a_cylinder_lying_along_x_answers_like_the_colliders_cylinder() {
        let shape = Shape::Cylinder(Cylinder {
            center: Vec3::ZERO,
            axis: Vec3::Y,
            radius: 0.5,
            half_height: 1.0,
        });
        assert!((shape.volume() - std::f32::consts::PI * 0.25 * 2.0).abs() < 1e-6);
        // Local y turned onto world x.
        let rotation = Mat3::from_quat(Quat::from_rotation_arc(Vec3::Y, Vec3::X));
        let h = shape.half_extents(rotation);
        assert!((h - Vec3::new(1.0, 0.5, 0.5)).length() < 1e-5, "{h}");
        let b = BodyState {
            shape,
            rotation,
            center: Vec3::ZERO,
            velocity: Vec3::ZERO,
            angular_velocity: Vec3::ZERO,
            dynamic: true,
            condition: Condition::Slip,
            friction: 0.0,
        };
        let collider = Shape::Cylinder(Cylinder {
            center: Vec3::ZERO,
            axis: Vec3::X,
            radius: 0.5,
            half_height: 1.0,
        });
        for x in [
            Vec3::new(0.9, 0.45, 0.0),
            Vec3::new(0.2, -0.1, 0.3),
            Vec3::new(-0.95, 0.0, 0.1),
            Vec3::new(0.0, 0.0, -0.49),
        ] {
            let (n, _) = b.query(x).expect("inside");
            assert!((n - collider.normal(x)).length() < 1e-5, "{x}: {n}");
        }
        assert!(b.query(Vec3::new(1.05, 0.0, 0.0)).is_none());
        assert!(b.query(Vec3::new(0.0, 0.55, 0.0)).is_none());
        // The round side is along y now, the caps along x.
        let (n, _) = b.query(Vec3::new(0.0, 0.45, 0.0)).unwrap();
        assert!((n - Vec3::Y).length() < 1e-5, "{n}");
        let (n, _) = b.query(Vec3::new(-0.98, 0.0, 0.0)).unwrap();
        assert!((n + Vec3::X).length() < 1e-5, "{n}");
    }

    #[test]
    fn a_body_as_a_collider_has_the_body_s_pose() {
        let b = BodyState {
            shape: Shape::Box(Cuboid::centred(Vec3::ZERO, Vec3::new(1.0, 0.25, 0.25))),
            rotation: Mat3::from_rotation_z(std::f32::consts::FRAC_PI_2),
            center: Vec3::new(3.0, 2.0, 0.0),
            velocity: Vec3::X,
            angular_velocity: Vec3::ZERO,
            dynamic: true,
            condition: Condition::Slip,
            friction: 0.0,
        };
        let c = b.collider();
        // Turned to lie along y about (3, 2, 0): inside 0.9 m above the centre, outside 0.9 m
        // to its side, and the same answers as the body's own query.
        for (x, inside) in [
            (Vec3::new(3.0, 2.9, 0.0), true),
            (Vec3::new(3.9, 2.0, 0.0), false),
            (Vec3::new(3.0, 1.2, 0.1), true),
        ] {
            assert_eq!(c.distance(x, 0.0) < 0.0, inside, "{x}");
            assert_eq!(b.query(x).is_some(), inside, "{x}");
        }
        assert!((c.distance(Vec3::new(3.0, 2.0, 0.0), 1.0) + 0.25).abs() < 1e-5);
    }

    #[test]
    fn reactions_sum_to_the_opposite_momentum_and_its_moment() {
        let mut e = Exchange::default();
        e.add_reaction([1.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
        assert_eq!(e.impulse, [0.0, -2.0, 0.0]);
        assert_eq!(e.torque, [0.0, 0.0, -2.0]);
    }
}

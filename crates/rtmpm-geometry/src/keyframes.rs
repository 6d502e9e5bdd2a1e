//! Keyframed collider motion: poses at given times, linear interpolation of the position,
//! spherical linear interpolation (slerp) of the rotation, and the velocity that follows from
//! them, held still before the first key and after the last.
//!
//! Between keys `k` and `k + 1` the pivot moves at the constant velocity
//! `v_k = (p_{k+1} - p_k) / (t_{k+1} - t_k)` and the body turns at the constant angular velocity
//! `w_k = axis * angle / (t_{k+1} - t_k)`, where `axis * angle` is the rotation vector of the
//! shorter arc from `q_k` to `q_{k+1}` (`q_{k+1} q_k^-1`). The pose is the integral of that
//! velocity: `p(t) = p_k + v_k (t - t_k)`, `q(t) = exp((t - t_k) w_k) q_k`, which is the slerp
//! of `q_k` and `q_{k+1}`; so the velocity the boundary rule sees is exactly the derivative of
//! the pose the collider has.

use glam::{Mat3, Quat, Vec3};

/// One key: at time `t` the collider's pivot is at `position` and its rest shape is turned by
/// `rotation` about the pivot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe {
    /// Time (s).
    pub t: f32,
    /// World position of the pivot (m).
    pub position: Vec3,
    /// Rest-to-world rotation (unit quaternion).
    pub rotation: Quat,
}

/// Validated keys (at least one, times strictly increasing) and the constant linear and
/// angular velocities of the segments between them.
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframes {
    keys: Vec<Keyframe>,
    /// Per segment `k` (between keys `k` and `k + 1`): linear velocity of the pivot.
    linear: Vec<Vec3>,
    /// Per segment: angular velocity (rad/s, world frame).
    angular: Vec<Vec3>,
}

/// Why keys were refused: the index of the offending key and the problem.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyError {
    /// Index of the key at fault.
    pub key: usize,
    /// Which field of the key (`t`, `position`, `rotation`); empty for the list itself.
    pub field: &'static str,
    pub message: String,
    pub hint: String,
}

/// The rotation vector (axis times angle, radians) of the shorter arc of the unit quaternion
/// `q`.
pub fn rotation_vector(q: Quat) -> Vec3 {
    // q and -q are the same rotation; w >= 0 picks the arc of at most pi.
    let q = if q.w < 0.0 { -q } else { q };
    let s = q.xyz().length();
    if s < 1e-12 {
        return Vec3::ZERO;
    }
    let angle = 2.0 * s.atan2(q.w);
    q.xyz() * (angle / s)
}

impl Keyframes {
    /// Check the keys (at least one; finite values; times strictly increasing; unit
    /// rotations) and derive the velocity of each segment.
    pub fn new(keys: Vec<Keyframe>) -> Result<Keyframes, KeyError> {
        if keys.is_empty() {
            return Err(KeyError {
                key: 0,
                field: "",
                message: "keyframes is empty".into(),
                hint: "give at least one key, e.g. keyframes = [{ t = 0.0, position = [0.5, 0.5, 0.5] }]"
                    .into(),
            });
        }
        for (k, key) in keys.iter().enumerate() {
            if !key.t.is_finite() || key.t < 0.0 {
                return Err(KeyError {
                    key: k,
                    field: "t",
                    message: format!("key time {} is not a finite time >= 0", key.t),
                    hint: "give times in seconds from the start of the run".into(),
                });
            }
            if !key.position.is_finite() {
                return Err(KeyError {
                    key: k,
                    field: "position",
                    message: "the position has a non-finite component".into(),
                    hint: "write finite numbers".into(),
                });
            }
            if !key.rotation.is_finite() || (key.rotation.length() - 1.0).abs() > 1e-3 {
                return Err(KeyError {
                    key: k,
                    field: "rotation",
                    message: "the rotation is not a finite rotation".into(),
                    hint: "write the rotation as a rotation vector [rx, ry, rz] (axis times angle in radians) of finite numbers".into(),
                });
            }
            if k > 0 && key.t <= keys[k - 1].t {
                return Err(KeyError {
                    key: k,
                    field: "t",
                    message: format!(
                        "key times must increase strictly: key {k} is at t = {} s, key {} at t = {} s",
                        key.t,
                        k - 1,
                        keys[k - 1].t
                    ),
                    hint: "sort the keys by time and give each a distinct time".into(),
                });
            }
        }
        let (mut linear, mut angular) = (Vec::new(), Vec::new());
        for w in keys.windows(2) {
            let h = w[1].t - w[0].t;
            linear.push((w[1].position - w[0].position) / h);
            angular.push(rotation_vector(w[1].rotation * w[0].rotation.conjugate()) / h);
        }
        Ok(Keyframes {
            keys,
            linear,
            angular,
        })
    }

    /// The keys.
    pub fn keys(&self) -> &[Keyframe] {
        &self.keys
    }

    /// The segment holding time `t` and the time since its first key; `None` before the
    /// first key and from the last key on (the collider holds still there).
    fn segment(&self, t: f32) -> Option<(usize, f32)> {
        let n = self.keys.len();
        if n < 2 || t.is_nan() || t < self.keys[0].t || t >= self.keys[n - 1].t {
            return None;
        }
        // The last key with t_k <= t (k <= n - 2 since t < t_{n-1}).
        let k = self.keys.partition_point(|key| key.t <= t) - 1;
        Some((k, t - self.keys[k].t))
    }

    /// Pivot position and rotation (rest to world) at time `t`.
    pub fn pose(&self, t: f32) -> (Vec3, Quat) {
        match self.segment(t) {
            Some((k, dt)) => {
                let key = &self.keys[k];
                let q = Quat::from_scaled_axis(self.angular[k] * dt) * key.rotation;
                (key.position + self.linear[k] * dt, q.normalize())
            }
            None => {
                let key = if t >= self.keys[self.keys.len() - 1].t {
                    &self.keys[self.keys.len() - 1]
                } else {
                    &self.keys[0]
                };
                (key.position, key.rotation)
            }
        }
    }

    /// Rotation matrix (rest to world) at time `t`.
    pub fn rotation(&self, t: f32) -> Mat3 {
        Mat3::from_quat(self.pose(t).1)
    }

    /// Linear velocity of the pivot and angular velocity (rad/s) at time `t`; zero before the
    /// first key and from the last key on. At a key the segment that starts there counts.
    pub fn velocity(&self, t: f32) -> (Vec3, Vec3) {
        match self.segment(t) {
            Some((k, _)) => (self.linear[k], self.angular[k]),
            None => (Vec3::ZERO, Vec3::ZERO),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::{FRAC_PI_2, PI};

    fn key(t: f32, p: [f32; 3], r: [f32; 3]) -> Keyframe {
        Keyframe {
            t,
            position: Vec3::from_array(p),
            rotation: Quat::from_scaled_axis(Vec3::from_array(r)),
        }
    }

    fn paddle() -> Keyframes {
        Keyframes::new(vec![
            key(0.5, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
            key(1.5, [1.0, 2.0, 0.0], [0.0, FRAC_PI_2, 0.0]),
            key(2.0, [1.0, 2.0, -1.0], [0.0, PI * 0.9, 0.0]),
        ])
        .unwrap()
    }

    #[test]
    fn interpolates_linearly_and_spherically() {
        let k = paddle();
        let (p, q) = k.pose(1.0);
        assert!((p - Vec3::new(0.5, 1.0, 0.0)).length() < 1e-6, "{p}");
        // Half way between 0 and pi/2 about y.
        let expect = Quat::from_rotation_y(FRAC_PI_2 * 0.5);
        assert!(q.angle_between(expect) < 1e-5, "{q}");
        // A quarter into the second segment: pi/2 + 0.25 * 0.4 pi about y.
        let (p, q) = k.pose(1.625);
        assert!((p - Vec3::new(1.0, 2.0, -0.25)).length() < 1e-6, "{p}");
        let expect = Quat::from_rotation_y(FRAC_PI_2 + 0.25 * 0.4 * PI);
        assert!(q.angle_between(expect) < 1e-5, "{q}");
        // glam's own slerp gives the same rotation.
        let s = k.keys[1].rotation.slerp(k.keys[2].rotation, 0.25);
        assert!(q.angle_between(s) < 1e-5);
    }

    #[test]
    fn holds_before_the_first_and_after_the_last_key() {
        let k = paddle();
        assert_eq!(k.pose(0.0), (k.keys[0].position, k.keys[0].rotation));
        assert_eq!(k.velocity(0.2), (Vec3::ZERO, Vec3::ZERO));
        assert_eq!(k.pose(9.0), (k.keys[2].position, k.keys[2].rotation));
        assert_eq!(k.velocity(2.0), (Vec3::ZERO, Vec3::ZERO));
        // A single key: always there, never moving.
        let one = Keyframes::new(vec![key(1.0, [1.0, 2.0, 3.0], [0.1, 0.0, 0.0])]).unwrap();
        for t in [0.0, 1.0, 5.0] {
            assert_eq!(one.pose(t).0, Vec3::new(1.0, 2.0, 3.0));
            assert_eq!(one.velocity(t), (Vec3::ZERO, Vec3::ZERO));
        }
    }

    #[test]
    fn velocity_is_the_finite_difference_of_the_pose() {
        let k = paddle();
        let h = 1e-3;
        for t in [0.6, 1.0, 1.4, 1.6, 1.9] {
            let (v, w) = k.velocity(t);
            let (p0, q0) = k.pose(t - h);
            let (p1, q1) = k.pose(t + h);
            let v_fd = (p1 - p0) / (2.0 * h);
            let w_fd = rotation_vector(q1 * q0.conjugate()) / (2.0 * h);
            assert!(
                (v - v_fd).length() < 1e-3 * v.length().max(1.0),
                "t {t}: {v} vs {v_fd}"
            );
            assert!(
                (w - w_fd).length() < 2e-3 * w.length().max(1.0),
                "t {t}: {w} vs {w_fd}"
            );
        }
        // And the values themselves: a quarter turn about y in the first second, the pivot
        // from the origin to [1, 2, 0].
        assert!((k.velocity(1.0).1 - Vec3::new(0.0, FRAC_PI_2, 0.0)).length() < 1e-5);
        assert!((k.velocity(1.0).0 - Vec3::new(1.0, 2.0, 0.0)).length() < 1e-6);
        // At a key the segment starting there counts.
        assert!((k.velocity(1.5).0 - Vec3::new(0.0, 0.0, -2.0)).length() < 1e-5);
    }

    #[test]
    fn bad_keys_are_refused_naming_the_key() {
        assert_eq!(Keyframes::new(vec![]).unwrap_err().field, "");
        let e = Keyframes::new(vec![
            key(1.0, [0.0; 3], [0.0; 3]),
            key(0.5, [0.0; 3], [0.0; 3]),
        ])
        .unwrap_err();
        assert_eq!((e.key, e.field), (1, "t"));
        let e = Keyframes::new(vec![
            key(1.0, [0.0; 3], [0.0; 3]),
            key(1.0, [0.0; 3], [0.0; 3]),
        ])
        .unwrap_err();
        assert_eq!((e.key, e.field), (1, "t"));
        let e = Keyframes::new(vec![key(f32::NAN, [0.0; 3], [0.0; 3])]).unwrap_err();
        assert_eq!((e.key, e.field), (0, "t"));
        let e = Keyframes::new(vec![
            key(0.0, [0.0; 3], [0.0; 3]),
            key(1.0, [0.0, f32::NAN, 0.0], [0.0; 3]),
        ])
        .unwrap_err();
        assert_eq!((e.key, e.field), (1, "position"));
    }
}

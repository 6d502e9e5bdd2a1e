//! An orbit camera: a point looked at, the angles it is seen from and the distance; orbit,
//! pan and zoom move it, reset brings back the first one.

use glam::Vec3;
use rtmpm_render::Camera;

/// Radians of orbit per pixel of mouse motion.
const ORBIT_PER_PIXEL: f32 = 0.008;
/// The elevation stays within this of straight up or down (radians), where yaw is undefined.
const PITCH_LIMIT: f32 = 1.55;

/// A camera that orbits a target point (world `+y` up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitCamera {
    /// The point looked at (m).
    pub target: Vec3,
    /// Angle about `+y` of the eye around the target (radians; 0: the eye on `+z`).
    pub yaw: f32,
    /// Elevation of the eye above the target's horizontal plane (radians).
    pub pitch: f32,
    /// Distance from the eye to the target (m).
    pub distance: f32,
    /// Vertical field of view (degrees).
    pub fov_deg: f32,
    home: (Vec3, f32, f32, f32),
}

impl OrbitCamera {
    /// The orbit camera at `c` (its home for [`OrbitCamera::reset`]).
    pub fn from_camera(c: Camera) -> OrbitCamera {
        let d = c.position - c.target;
        let distance = d.length().max(1e-6);
        let pitch = (d.y / distance)
            .clamp(-1.0, 1.0)
            .asin()
            .clamp(-PITCH_LIMIT, PITCH_LIMIT);
        let yaw = d.x.atan2(d.z);
        OrbitCamera {
            target: c.target,
            yaw,
            pitch,
            distance,
            fov_deg: c.fov_deg,
            home: (c.target, yaw, pitch, distance),
        }
    }

    /// Unit vector from the target to the eye.
    fn direction(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(cp * sy, sp, cp * cy)
    }

    /// The renderer's camera.
    pub fn camera(&self) -> Camera {
        Camera {
            position: self.target + self.direction() * self.distance,
            target: self.target,
            fov_deg: self.fov_deg,
        }
    }

    /// Turn around the target by a mouse motion of `(dx, dy)` pixels (right, down): the scene
    /// follows the mouse.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * ORBIT_PER_PIXEL;
        self.yaw = self.yaw.rem_euclid(std::f32::consts::TAU);
        self.pitch = (self.pitch + dy * ORBIT_PER_PIXEL).clamp(-PITCH_LIMIT, PITCH_LIMIT);
    }

    /// Move eye and target sideways by a mouse motion of `(dx, dy)` pixels in an image
    /// `height` pixels high: the point under the cursor at the target's depth follows it.
    pub fn pan(&mut self, dx: f32, dy: f32, height: u32) {
        let c = self.camera();
        let fwd = (c.target - c.position).normalize_or(Vec3::NEG_Z);
        let right = fwd.cross(Vec3::Y).normalize_or(Vec3::X);
        let up = right.cross(fwd);
        let per_pixel =
            2.0 * self.distance * (0.5 * self.fov_deg.to_radians()).tan() / height.max(1) as f32;
        self.target += (-dx * right + dy * up) * per_pixel;
    }

    /// Multiply the distance to the target by `factor` (< 1: closer), within a thousandth and
    /// a thousand times the home distance.
    pub fn zoom(&mut self, factor: f32) {
        if !(factor.is_finite() && factor > 0.0) {
            return;
        }
        let home = self.home.3;
        self.distance = (self.distance * factor).clamp(1e-3 * home, 1e3 * home);
    }

    /// Back to the first camera.
    pub fn reset(&mut self) {
        (self.target, self.yaw, self.pitch, self.distance) = self.home;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start() -> Camera {
        Camera::framing(Vec3::ZERO, Vec3::ONE, 16.0 / 9.0, 40.0)
    }

    #[test]
    fn the_orbit_camera_starts_where_it_was_given() {
        let c = start();
        let o = OrbitCamera::from_camera(c);
        let back = o.camera();
        assert!((back.position - c.position).length() < 1e-4, "{back:?}");
        assert_eq!(back.target, c.target);
    }

    #[test]
    fn orbit_keeps_the_distance_pan_moves_both_zoom_scales_and_reset_returns() {
        let mut o = OrbitCamera::from_camera(start());
        let d0 = o.distance;
        o.orbit(100.0, -40.0);
        let c = o.camera();
        assert!(((c.position - c.target).length() - d0).abs() < 1e-4);
        assert_ne!(c.position, start().position);
        // Dragging right turns the eye to the left around the target (the scene follows).
        let before = OrbitCamera::from_camera(start()).camera();
        let (x_before, _, _) = before.project(1280, 720, Vec3::new(1.0, 0.5, 0.5));
        let mut o2 = OrbitCamera::from_camera(start());
        o2.orbit(30.0, 0.0);
        let (x_after, _, _) = o2.camera().project(1280, 720, Vec3::new(1.0, 0.5, 0.5));
        assert!(x_after > x_before, "{x_before} -> {x_after}");
        let t0 = o.target;
        o.pan(50.0, 0.0, 720);
        assert!((o.target - t0).length() > 0.0);
        o.zoom(0.5);
        assert!((o.distance - 0.5 * d0).abs() < 1e-5);
        o.zoom(f32::NAN);
        o.zoom(1e-9);
        assert!(o.distance >= 1e-3 * d0);
        o.orbit(0.0, 1e6);
        assert!(o.pitch <= PITCH_LIMIT && o.camera().check().is_ok());
        o.reset();
        assert!((o.camera().position - start().position).length() < 1e-4);
    }

    #[test]
    fn panning_follows_the_cursor_at_the_targets_depth() {
        let mut o = OrbitCamera::from_camera(start());
        let before = o.camera();
        let p = before.target;
        o.pan(64.0, -20.0, 720);
        let (x, y, _) = o.camera().project(1280, 720, p);
        // The old target moved with the cursor by (64, -20) pixels.
        assert!(
            (x - (640.0 + 64.0)).abs() < 0.5 && (y - (360.0 - 20.0)).abs() < 0.5,
            "{x} {y}"
        );
    }
}

//! Pinhole camera: position, target, vertical field of view; automatic framing of a box.

use rtmpm_physics::math::Vec3;

/// A perspective camera looking from `position` at `target`, world `+y` up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (m).
    pub position: Vec3,
    /// Point looked at (m); must differ from `position`.
    pub target: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_deg: f32,
}

impl Camera {
    /// Default field of view (degrees).
    pub const DEFAULT_FOV: f32 = 40.0;

    /// A camera that frames the box `[min, max]` from the front-right-above (looking towards
    /// `-z` and slightly down and left) at its centre, for an image of the given aspect ratio
    /// (width / height).
    pub fn framing(min: Vec3, max: Vec3, aspect: f32, fov_deg: f32) -> Camera {
        let center = 0.5 * (min + max);
        let dir = Vec3::new(0.55, 0.5, 1.0).normalize();
        let half_v = 0.5 * fov_deg.to_radians();
        let (tan_v, tan_h) = (half_v.tan(), half_v.tan() * aspect.max(1e-3));
        // Basis of the view (forward = -dir), as in `view`.
        let fwd = -dir;
        let right = fwd.cross(Vec3::Y).normalize();
        let up = right.cross(fwd);
        // The nearest distance at which every corner of the box is inside the view, plus 5%.
        let mut dist: f32 = 1e-6;
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { min.x } else { max.x },
                if i & 2 == 0 { min.y } else { max.y },
                if i & 4 == 0 { min.z } else { max.z },
            );
            let o = c - center;
            let need = o.dot(dir) + (o.dot(right).abs() / tan_h).max(o.dot(up).abs() / tan_v);
            dist = dist.max(need);
        }
        let dist = 1.05 * dist;
        Camera {
            position: center + dir * dist,
            target: center,
            fov_deg,
        }
    }

    /// Check the camera: fov in (0, 180), finite, position != target. Returns a message.
    pub fn check(&self) -> Result<(), String> {
        // First: a camera framed with a fov of 0 has an infinite position.
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            return Err(format!(
                "field of view must be in (0, 180) degrees, got {}",
                self.fov_deg
            ));
        }
        if !self.position.is_finite() || !self.target.is_finite() {
            return Err("camera position and target must be finite".into());
        }
        let d = (self.target - self.position).length();
        if !d.is_finite() {
            return Err(format!(
                "the camera position {} and target {} are too far apart: their distance \
                 overflows a 32-bit float",
                self.position, self.target
            ));
        }
        if d <= 1e-9 {
            return Err("the camera position and target coincide".into());
        }
        Ok(())
    }

    /// About how many pixels of a picture `height` pixels high the box `[min, max]` spans: its
    /// diagonal over its nearest distance from the eye, times the focal length (infinite with
    /// the eye inside it; 0 when too far for f32).
    pub fn pixels_across(&self, min: Vec3, max: Vec3, height: u32) -> f32 {
        let nearest = self.position.clamp(min, max);
        let d = (self.position.as_dvec3() - nearest.as_dvec3()).length();
        if d == 0.0 {
            return f32::INFINITY;
        }
        let diag = (max - min).as_dvec3().length();
        let focal = self.view(height, height).focal as f64;
        (diag / d * focal) as f32
    }

    /// The direction from the eye through pixel coordinates `(x, y)` (x right, y down, pixel
    /// centres at +0.5) of a `width` x `height` image, scaled so that its component along the
    /// viewing direction is 1: the point at view depth `z` on it is `position + ray * z`.
    pub fn pixel_ray(&self, width: u32, height: u32, x: f32, y: f32) -> Vec3 {
        self.view(width, height).ray(x, y)
    }

    /// Pixel coordinates (x right, y down) and view depth of the point `p` in a `width` x
    /// `height` image (depth <= 0: behind the eye).
    pub fn project(&self, width: u32, height: u32, p: Vec3) -> (f32, f32, f32) {
        self.view(width, height).project(p)
    }

    /// The view for an image of `width` x `height` pixels (the GPU renderers take their camera
    /// from it too).
    pub fn view(&self, width: u32, height: u32) -> View {
        let fwd = (self.target - self.position).normalize_or(Vec3::NEG_Z);
        let mut right = fwd.cross(Vec3::Y);
        if right.length_squared() < 1e-8 {
            // Looking straight up or down: any horizontal right vector will do.
            right = fwd.cross(Vec3::Z);
        }
        let right = right.normalize();
        let up = right.cross(fwd);
        let focal = 0.5 * height as f32 / (0.5 * self.fov_deg.to_radians()).tan();
        View {
            pos: self.position,
            fwd,
            right,
            up,
            focal,
            cx: 0.5 * width as f32,
            cy: 0.5 * height as f32,
        }
    }
}

/// A camera resolved for one image size: orthonormal basis and focal length in pixels.
#[derive(Clone, Copy, Debug)]
pub struct View {
    /// Eye position (m).
    pub pos: Vec3,
    /// Viewing direction (unit).
    pub fwd: Vec3,
    /// Right of the image (unit).
    pub right: Vec3,
    /// Up of the image (unit).
    pub up: Vec3,
    /// Focal length (pixels).
    pub focal: f32,
    /// Image centre (pixels).
    pub cx: f32,
    /// See `cx`.
    pub cy: f32,
}

impl View {
    /// Pixel coordinates (x right, y down; pixel centres at +0.5) and view depth of `p`.
    #[inline]
    pub fn project(&self, p: Vec3) -> (f32, f32, f32) {
        let d = p - self.pos;
        let z = d.dot(self.fwd);
        let s = self.focal / z;
        (
            self.cx + d.dot(self.right) * s,
            self.cy - d.dot(self.up) * s,
            z,
        )
    }

    /// World direction (not normalised; its component along `fwd` is 1) through pixel
    /// coordinates `(x, y)`.
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Vec3 {
        self.fwd + self.right * ((x - self.cx) / self.focal)
            - self.up * ((y - self.cy) / self.focal)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_projects_to_centre_and_framing_sees_corners() {
        let (lo, hi) = (Vec3::ZERO, Vec3::new(1.0, 0.75, 0.5));
        let cam = Camera::framing(lo, hi, 16.0 / 9.0, 40.0);
        cam.check().unwrap();
        let v = cam.view(1280, 720);
        let (x, y, z) = v.project(cam.target);
        assert!((x - 640.0).abs() < 1e-3 && (y - 360.0).abs() < 1e-3 && z > 0.0);
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let (x, y, z) = v.project(c);
            assert!(z > 0.0 && (0.0..1280.0).contains(&x) && (0.0..720.0).contains(&y));
        }
        // A point above the target is drawn above the centre.
        let (_, y_up, _) = v.project(cam.target + Vec3::Y * 0.1);
        assert!(y_up < 360.0);
        // The ray through a projected point points at it.
        let p = Vec3::new(0.3, 0.2, 0.1);
        let (x, y, z) = v.project(p);
        let r = v.ray(x, y);
        assert!((v.pos + r * z - p).length() < 1e-4);
    }

    #[test]
    fn bad_cameras_are_rejected() {
        let mut c = Camera {
            position: Vec3::ONE,
            target: Vec3::ONE,
            fov_deg: 40.0,
        };
        assert!(c.check().is_err());
        c.target = Vec3::ZERO;
        c.fov_deg = 180.0;
        assert!(c.check().is_err());
        c.fov_deg = 60.0;
        assert!(c.check().is_ok());
        // Looking straight down works.
        c.position = Vec3::new(0.0, 5.0, 0.0);
        let v = c.view(100, 100);
        assert!(v.right.is_finite() && v.up.is_finite());
    }
}

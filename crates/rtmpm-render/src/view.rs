//! What a live view asks a backend to draw (`rtmpm_sim::Backend::render_view`), and the same
//! request as options of this CPU renderer: one definition of the picture for every backend.

use crate::camera::Camera;
use crate::colormap;
use crate::input::{RenderOptions, von_mises};
use rtmpm_physics::Particles;
use rtmpm_scene::ColorBy;
use rtmpm_scene::Scene;

/// What a live view asks a backend to draw (all in scene units). The picture is the one
/// [`super::render`] draws with [`ViewRequest::options`]: same camera model, palette, colour
/// modes and ranges, colliders and floor.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewRequest {
    /// The camera (eye, target, vertical field of view; world `+y` up).
    pub camera: Camera,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Material, speed, J, stress or plastic.
    pub color_by: ColorBy,
    /// Colour-bar range of the field; `None`: the 1st to 99th percentile of this frame.
    pub range: Option<(f32, f32)>,
    /// Particle radius on screen (m).
    pub radius: f32,
    /// Draw the scene's colliders, its rigid bodies and the user's tool
    /// (`rtmpm_sim::Backend::set_tool`).
    pub colliders: bool,
    /// Draw the checkered floor at the bottom of the domain's interior.
    pub floor: bool,
    /// Shadows on the floor and on the material.
    pub shadows: bool,
    /// Simulated time of the picture (s): the pose of moving colliders.
    pub time: f32,
}

/// Largest side of a live view's image (pixels).
pub const MAX_VIEW_SIDE: u32 = 4096;

impl ViewRequest {
    /// A request for `scene` at `width` x `height`: the camera of [`Camera::framing`] on the
    /// domain's interior, colour by material, floor, colliders and shadows on.
    pub fn framing(scene: &Scene, width: u32, height: u32, radius: f32) -> ViewRequest {
        let (lo, hi) = scene.interior();
        ViewRequest {
            camera: Camera::framing(
                lo,
                hi,
                width as f32 / height.max(1) as f32,
                Camera::DEFAULT_FOV,
            ),
            width,
            height,
            color_by: ColorBy::Material,
            range: None,
            radius,
            colliders: true,
            floor: true,
            shadows: true,
            time: 0.0,
        }
    }

    /// A clear message when the request cannot be drawn: image size, camera, radius, range.
    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_VIEW_SIDE).contains(&self.width) || !(1..=MAX_VIEW_SIDE).contains(&self.height)
        {
            return Err(format!(
                "view size {}x{} is out of range (1 to {MAX_VIEW_SIDE} per side)",
                self.width, self.height
            ));
        }
        self.camera.check()?;
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(format!(
                "the particle radius must be positive, got {}",
                self.radius
            ));
        }
        if let Some((lo, hi)) = self.range
            && !(lo.is_finite() && hi.is_finite() && hi > lo)
        {
            return Err(format!(
                "the colour range must be finite with hi above lo, got {lo}, {hi}"
            ));
        }
        Ok(())
    }

    /// The CPU renderer's options for this request on `scene` (bounds: the domain's interior;
    /// palette: [`colormap::scene_palette`]). Rigid bodies are the caller's to add to
    /// `colliders` (they move).
    pub fn options(&self, scene: &Scene) -> RenderOptions {
        let (lo, hi) = scene.interior();
        let mut o = RenderOptions::new(lo, hi, self.radius);
        o.width = self.width;
        o.height = self.height;
        o.camera = self.camera;
        o.color_by = self.color_by;
        o.range = self.range;
        o.floor = self.floor.then_some(lo.y);
        o.palette = colormap::scene_palette(scene);
        o.shadows = self.shadows;
        if self.colliders {
            o.colliders = scene.colliders.clone();
        }
        o.time = self.time;
        o
    }
}

/// The scalar field that `color_by` colours by, one value per particle (`None` for
/// [`ColorBy::Material`]); stress needs the scene's materials.
pub fn particle_field(p: &Particles, scene: &Scene, color_by: ColorBy) -> Option<Vec<f32>> {
    match color_by {
        ColorBy::Material => None,
        ColorBy::Speed => Some(p.v.iter().map(|v| v.length()).collect()),
        ColorBy::J => Some(p.f.iter().map(|f| f.determinant()).collect()),
        ColorBy::Plastic => Some(p.plastic.clone()),
        ColorBy::Stress => Some(
            rtmpm_physics::material::cauchy_stress(p, &scene.materials)
                .into_iter()
                .map(von_mises)
                .collect(),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_physics::math::Vec3;

    fn scene() -> Scene {
        Scene::from_toml(
            "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.1\n[time]\nduration = 0.1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e4\n\
             [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.3,0.3,0.3]\nmax = [0.5,0.5,0.5]\n\
             [[collider]]\nshape = \"sphere\"\ncenter = [0.7,0.5,0.5]\nradius = 0.1\n",
            "<test>",
        )
        .expect("scene")
    }

    #[test]
    fn a_request_becomes_the_cpu_renderers_options_on_the_interior() {
        let s = scene();
        let mut r = ViewRequest::framing(&s, 320, 180, 0.01);
        r.check().expect("a framing request is drawable");
        r.color_by = ColorBy::Speed;
        r.range = Some((0.0, 2.0));
        r.time = 0.25;
        let o = r.options(&s);
        let (lo, hi) = s.interior();
        assert_eq!((o.width, o.height, o.radius), (320, 180, 0.01));
        assert_eq!(o.bounds, (lo, hi));
        assert_eq!(o.floor, Some(lo.y));
        assert_eq!(
            (o.color_by, o.range, o.time),
            (ColorBy::Speed, Some((0.0, 2.0)), 0.25)
        );
        assert_eq!(o.colliders.len(), 1);
        assert_eq!(o.palette, colormap::scene_palette(&s));
        r.colliders = false;
        r.floor = false;
        let o = r.options(&s);
        assert!(o.colliders.is_empty() && o.floor.is_none());
    }

    #[test]
    fn undrawable_requests_are_refused_with_the_reason() {
        let s = scene();
        let good = ViewRequest::framing(&s, 64, 64, 0.01);
        let mut r = good.clone();
        r.width = 0;
        assert!(r.check().unwrap_err().contains("size"));
        r = good.clone();
        r.height = MAX_VIEW_SIDE + 1;
        assert!(r.check().is_err());
        r = good.clone();
        r.radius = f32::NAN;
        assert!(r.check().unwrap_err().contains("radius"));
        r = good.clone();
        r.range = Some((1.0, 1.0));
        assert!(r.check().unwrap_err().contains("range"));
        r = good;
        r.camera.target = r.camera.position;
        assert!(r.check().is_err());
    }

    #[test]
    fn fields_follow_the_colour_mode() {
        let s = scene();
        let mut p = Particles::default();
        p.push(Vec3::ZERO, Vec3::new(3.0, 4.0, 0.0), 1.0, 1.0, 0, 0.5);
        assert!(particle_field(&p, &s, ColorBy::Material).is_none());
        assert_eq!(particle_field(&p, &s, ColorBy::Speed), Some(vec![5.0]));
        assert_eq!(particle_field(&p, &s, ColorBy::J), Some(vec![1.0]));
        assert_eq!(particle_field(&p, &s, ColorBy::Plastic), Some(vec![0.5]));
        assert_eq!(
            particle_field(&p, &s, ColorBy::Stress).map(|v| v.len()),
            Some(1)
        );
    }
}

//! Steering a running simulation: the tool dragged along the cursor's ray ([`ToolDrag`]) and
//! balls of material thrown into the scene ([`ball`]).

use glam::Vec3;
use rtmpm_geometry::Shape;
use rtmpm_geometry::shape::Sphere;
use rtmpm_geometry::{Tool, ToolShape};
use rtmpm_physics::Particles;
use rtmpm_render::Camera;
use rtmpm_scene::Scene;
use rtmpm_scene::emitter::Emitter;
use rtmpm_scene::sampling::per_axis;

/// Most particles one thrown ball may have.
pub const MAX_BALL_PARTICLES: usize = 1_000_000;

/// The tool while the user holds it: where it is, where the cursor wants it, how fast it goes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Held {
    /// View depth it was grabbed at (m along the viewing direction).
    depth: f32,
    eye: Vec3,
    ray: Vec3,
    goal: Vec3,
    center: Vec3,
    velocity: Vec3,
}

/// The user's tool: its shape, and its motion while held. It moves towards the point of the
/// cursor's ray at the depth where it was grabbed, no faster than the session allows (the
/// backend holds it where it is put; [`ToolDrag::advance`] moves it with the simulated time).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolDrag {
    pub shape: ToolShape,
    held: Option<Held>,
    /// The box the tool's centre stays in (the domain, grown by the tool's size).
    bounds: (Vec3, Vec3),
}

impl ToolDrag {
    /// A tool of `shape`, not held, kept within `domain` (its centre may go a tool's size out).
    pub fn new(shape: ToolShape, domain: (Vec3, Vec3)) -> ToolDrag {
        ToolDrag {
            shape,
            held: None,
            bounds: domain,
        }
    }

    fn clamp(&self, p: Vec3) -> Vec3 {
        let pad = match self.shape {
            ToolShape::Sphere { radius } => Vec3::splat(radius),
            ToolShape::Box { half } => half,
        };
        p.clamp(self.bounds.0 - pad, self.bounds.1 + pad)
    }

    /// Grab the tool on the ray `eye + ray * z` at view depth `depth`: it appears there.
    pub fn grab(&mut self, eye: Vec3, ray: Vec3, depth: f32) {
        let p = self.clamp(eye + ray * depth);
        self.held = Some(Held {
            depth,
            eye,
            ray,
            goal: p,
            center: p,
            velocity: Vec3::ZERO,
        });
    }

    /// Aim at the ray `eye + ray * z`, at the depth of the grab.
    pub fn aim(&mut self, eye: Vec3, ray: Vec3) {
        if let Some(h) = self.held.as_mut() {
            (h.eye, h.ray) = (eye, ray);
        }
        self.retarget();
    }

    /// Multiply the depth of the grab by `factor` (> 1: deeper into the scene).
    pub fn push(&mut self, factor: f32) {
        if let Some(h) = self.held.as_mut()
            && factor.is_finite()
            && factor > 0.0
        {
            h.depth = (h.depth * factor).max(1e-4);
        }
        self.retarget();
    }

    fn retarget(&mut self) {
        if let Some(h) = self.held {
            let goal = self.clamp(h.eye + h.ray * h.depth);
            if let Some(h) = self.held.as_mut() {
                h.goal = goal;
            }
        }
    }

    /// Let go: the tool leaves the simulation.
    pub fn release(&mut self) {
        self.held = None;
    }

    /// True while held.
    pub fn held(&self) -> bool {
        self.held.is_some()
    }

    /// True while held and moving.
    pub fn moving(&self) -> bool {
        self.held.is_some_and(|h| h.velocity != Vec3::ZERO)
    }

    /// Choose the velocity that reaches the goal in `duration` seconds of simulated time, at
    /// most `max_speed` (m/s).
    pub fn plan(&mut self, duration: f64, max_speed: f32) {
        if let Some(h) = self.held.as_mut() {
            let d = h.goal - h.center;
            let v = if duration > 0.0 {
                d / duration as f32
            } else {
                Vec3::ZERO
            };
            h.velocity = v.clamp_length_max(max_speed.max(0.0));
            if !h.velocity.is_finite() {
                h.velocity = Vec3::ZERO;
            }
        }
    }

    /// Move the held tool by its velocity over `dt` seconds; it stops at the goal.
    pub fn advance(&mut self, dt: f64) {
        if let Some(h) = self.held.as_mut() {
            let step = h.velocity * dt as f32;
            let left = h.goal - h.center;
            if step.length_squared() >= left.length_squared() || step.dot(left) <= 0.0 {
                h.center = h.goal;
                h.velocity = Vec3::ZERO;
            } else {
                h.center += step;
            }
        }
    }

    /// The tool as the backend takes it, while held.
    pub fn tool(&self) -> Option<Tool> {
        self.held.map(|h| Tool {
            shape: self.shape,
            center: h.center,
            velocity: h.velocity,
        })
    }

    /// The tool's size (m): the sphere's radius or the box's largest half extent.
    pub fn size(&self) -> f32 {
        match self.shape {
            ToolShape::Sphere { radius } => radius,
            ToolShape::Box { half } => half.max_element(),
        }
    }
}

/// View depth of the nearest particle within `reach` of the pixel ray `ray` of camera `cam`
/// (a ray from [`Camera::pixel_ray`], whose component along the viewing direction is 1).
pub fn pick_depth(positions: &[Vec3], cam: &Camera, ray: Vec3, reach: f32) -> Option<f32> {
    let fwd = (cam.target - cam.position).normalize_or(Vec3::NEG_Z);
    let reach2 = reach * reach;
    positions
        .iter()
        .filter_map(|p| {
            let d = *p - cam.position;
            let z = d.dot(fwd);
            (z > 0.0 && (d - ray * z).length_squared() <= reach2).then_some(z)
        })
        .min_by(f32::total_cmp)
}

/// Where the ray `eye + dir * s` (s > 0) enters the box `[lo, hi]`, as `s`; the eye itself
/// (s = 0) when it is inside; `None` when the ray misses.
pub fn ray_enters_box(eye: Vec3, dir: Vec3, lo: Vec3, hi: Vec3) -> Option<f32> {
    let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
    for a in 0..3 {
        if dir[a].abs() < 1e-12 {
            if eye[a] < lo[a] || eye[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (mut ta, mut tb) = ((lo[a] - eye[a]) / dir[a], (hi[a] - eye[a]) / dir[a]);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    (t0 <= t1).then_some(t0)
}

/// The particles of a ball of the scene's material `material` (its bodies' particles per
/// cell, else 8, on the jittered lattice of the emitters) at `center` with `radius`, moving at
/// `velocity`. Refused with the reason when the material does not exist, the ball does not
/// fit inside the domain's interior or has more than [`MAX_BALL_PARTICLES`] particles.
pub fn ball(
    scene: &Scene,
    material: usize,
    center: Vec3,
    radius: f32,
    velocity: Vec3,
    seed: u64,
) -> Result<Particles, String> {
    let m = scene.materials.get(material).ok_or_else(|| {
        format!(
            "no material {material}: the scene has {} (0 to {})",
            scene.materials.len(),
            scene.materials.len().saturating_sub(1)
        )
    })?;
    if !(radius.is_finite() && radius > 0.0 && center.is_finite() && velocity.is_finite()) {
        return Err(format!(
            "a ball needs a positive radius and a finite centre and velocity, got radius \
             {radius}, centre {center}, velocity {velocity}"
        ));
    }
    let (lo, hi) = scene.interior();
    if (center - radius).cmplt(lo).any() || (center + radius).cmpgt(hi).any() {
        return Err(format!(
            "a ball of radius {radius} m at {center} does not fit inside the domain's interior \
             {lo} to {hi}"
        ));
    }
    let ppc = scene
        .bodies
        .iter()
        .find(|b| b.material as usize == material)
        .map_or(8, |b| b.particles_per_cell);
    let spacing = scene.dx / per_axis(ppc) as f32;
    let estimate = (4.0 / 3.0 * std::f64::consts::PI * (radius as f64 / spacing as f64).powi(3))
        .ceil() as usize;
    if estimate > MAX_BALL_PARTICLES {
        return Err(format!(
            "a ball of radius {radius} m would have about {estimate} particles, more than \
             {MAX_BALL_PARTICLES}: throw a smaller one"
        ));
    }
    let shape = Shape::Sphere(Sphere { center, radius });
    let cells = Emitter::lattice(&shape, spacing, seed);
    let n = cells.len() as u64;
    let e = Emitter {
        name: "thrown ball".into(),
        material: material as u32,
        shape,
        velocity,
        rate: 1.0,
        start: 0.0,
        stop: n as f64,
        spacing,
        particle_mass: m.density * spacing.powi(3),
        cells,
        seed,
    };
    let mut p = Particles::default();
    e.emit(0, n, m, &mut p);
    Ok(p)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> Scene {
        Scene::from_toml(
            "[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = 0.05\n[time]\nduration = 0.1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e4\n\
             [[body]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.3,0.3,0.3]\nmax = [0.5,0.5,0.5]\n",
            "<test>",
        )
        .expect("scene")
    }

    #[test]
    fn the_held_tool_chases_the_cursor_no_faster_than_allowed_and_stops_there() {
        let mut t = ToolDrag::new(ToolShape::Sphere { radius: 0.1 }, (Vec3::ZERO, Vec3::ONE));
        assert!(t.tool().is_none());
        t.grab(Vec3::new(0.5, 0.5, 2.0), Vec3::NEG_Z, 1.5);
        let tool = t.tool().expect("held");
        assert_eq!(tool.center, Vec3::new(0.5, 0.5, 0.5));
        // The cursor moves 0.3 m to the right; the tool may go 1 m/s: 0.3 s to get there.
        t.aim(Vec3::new(0.8, 0.5, 2.0), Vec3::NEG_Z);
        t.plan(0.1, 1.0);
        assert!((t.tool().unwrap().velocity - Vec3::X).length() < 1e-6);
        for _ in 0..10 {
            t.advance(0.01);
        }
        assert!((t.tool().unwrap().center.x - 0.6).abs() < 1e-5);
        assert!(t.moving());
        for _ in 0..30 {
            t.advance(0.01);
        }
        let tool = t.tool().unwrap();
        assert!((tool.center - Vec3::new(0.8, 0.5, 0.5)).length() < 1e-6);
        assert_eq!(tool.velocity, Vec3::ZERO, "it stops at the goal");
        // Pushed deeper along the view, and kept near the domain.
        t.push(100.0);
        t.plan(1.0, 1e9);
        t.advance(1.0);
        assert!(t.tool().unwrap().center.z >= -0.1 - 1e-6);
        t.release();
        assert!(t.tool().is_none() && !t.held());
    }

    #[test]
    fn picking_finds_the_nearest_particle_on_the_ray() {
        let cam = Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            target: Vec3::ZERO,
            fov_deg: 40.0,
        };
        let ray = cam.pixel_ray(100, 100, 50.0, 50.0);
        let pts = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(0.5, 0.0, 3.0),
            Vec3::new(0.0, 0.0, 9.0),
        ];
        assert_eq!(pick_depth(&pts, &cam, ray, 0.1), Some(3.0));
        assert_eq!(pick_depth(&pts[..1], &cam, ray, 0.1), Some(4.0));
        assert_eq!(
            pick_depth(&pts[3..], &cam, ray, 0.1),
            None,
            "behind the eye"
        );
    }

    #[test]
    fn rays_enter_boxes_where_expected() {
        let (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        let s = ray_enters_box(Vec3::new(0.5, 0.5, 3.0), Vec3::NEG_Z, lo, hi).unwrap();
        assert!((s - 2.0).abs() < 1e-6);
        assert_eq!(ray_enters_box(Vec3::splat(0.5), Vec3::X, lo, hi), Some(0.0));
        assert_eq!(
            ray_enters_box(Vec3::new(2.0, 0.5, 3.0), Vec3::NEG_Z, lo, hi),
            None
        );
    }

    #[test]
    fn a_thrown_ball_has_the_materials_mass_and_velocity_inside_the_domain_only() {
        let s = scene();
        let v = Vec3::new(0.0, 0.0, -2.0);
        let p = ball(&s, 0, Vec3::splat(0.5), 0.1, v, 7).expect("ball");
        // 2 particles per cell per axis at dx 0.05: spacing 0.025, (4/3 pi 0.1^3) / 0.025^3.
        let expect = 4.0 / 3.0 * std::f32::consts::PI * 0.1f32.powi(3) / 0.025f32.powi(3);
        assert!(
            (p.len() as f32 - expect).abs() < 0.05 * expect,
            "{}",
            p.len()
        );
        assert!(p.v.iter().all(|x| *x == v));
        assert!(
            p.x.iter()
                .all(|x| (*x - Vec3::splat(0.5)).length() < 0.1 + 0.025)
        );
        let mass: f64 = p.total_mass();
        assert!((mass - 1000.0 * p.len() as f64 * 0.025f64.powi(3)).abs() < 1e-6 * mass);
        assert!(
            ball(&s, 3, Vec3::splat(0.5), 0.1, v, 7)
                .unwrap_err()
                .contains("no material")
        );
        assert!(
            ball(&s, 0, Vec3::splat(0.05), 0.1, v, 7)
                .unwrap_err()
                .contains("fit")
        );
        assert!(ball(&s, 0, Vec3::splat(0.5), f32::NAN, v, 7).is_err());
    }
}

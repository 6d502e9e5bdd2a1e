//! What a scene allows but probably gets wrong: legal values that do nothing, or that the run
//! cannot follow. `rtmpm check`, `rtmpm run` and Python print them ([`Scene::warnings`]).

use crate::scene::Scene;
use crate::settings::StepMode;
use glam::Mat3;
use rtmpm_rigid::{JointKind, RigidKind};
use std::f32::consts::PI;

impl Scene {
    /// What this scene allows but probably gets wrong, one line each, for `rtmpm check` and
    /// `rtmpm run` to print: dynamic rigid bodies that can hang in a fluid they are denser than
    /// ([`rtmpm_rigid::resolution_warnings`]), emitters that emit nothing or pile up, rigid
    /// bodies thinner than a cell or leaving the domain, boundaries faster than a fixed step,
    /// material that starts in contact with a slip or sticky wall, collider or rigid body above
    /// it ([`crate::contact::hanging_warnings`]).
    // `Real` is f64 in the f64 build of this crate.
    #[allow(clippy::unnecessary_cast)]
    pub fn warnings(&self) -> Vec<String> {
        let fluids: Vec<(&str, f32)> = self
            .materials
            .iter()
            .filter(|m| matches!(m.model, rtmpm_physics::material::Model::Fluid(_)))
            .map(|m| (m.name.as_str(), m.density as f32))
            .collect();
        let mut out = rtmpm_rigid::resolution_warnings(&self.rigid_bodies, &fluids, self.dx);
        out.extend(scene_warnings(self));
        out.extend(crate::contact::hanging_warnings(self));
        out
    }
}

/// Every warning of `scene` besides the rigid bodies' resolution
/// ([`rtmpm_rigid::resolution_warnings`]), one line each, naming the field and the fix.
fn scene_warnings(scene: &Scene) -> Vec<String> {
    let mut out = Vec::new();
    emitters(scene, &mut out);
    rigid_bodies(scene, &mut out);
    joints(scene, &mut out);
    fixed_step(scene, &mut out);
    let g = crate::speeds::norm(scene.gravity);
    if g > 100.0 * EARTH_GRAVITY as f64 {
        out.push(format!(
            "gravity is {g:.4e} m/s^2, {:.0} times Earth's ({EARTH_GRAVITY}): check its units \
             (m/s^2)",
            g / EARTH_GRAVITY as f64
        ));
    }
    out
}

/// Earth's gravity (m/s^2).
const EARTH_GRAVITY: f32 = 9.81;

/// Revolute joints whose limits lie beyond the angle's range, +-pi (they limit nothing).
fn joints(scene: &Scene, out: &mut Vec<String>) {
    for (i, j) in scene.joints.iter().enumerate() {
        if let JointKind::Revolute {
            limits: Some([lo, hi]),
            ..
        } = j.kind
            && (lo < -PI || hi > PI)
        {
            out.push(format!(
                "joint[{i}]: limits = [{lo}, {hi}] reach beyond +-pi, the range of a revolute \
                 joint's angle, and do not limit it there; give the limits in radians within \
                 [-3.1416, 3.1416] (or remove them)"
            ));
        }
    }
}

/// Emitters that start after the run ends, or emit faster than their particles leave them.
fn emitters(scene: &Scene, out: &mut Vec<String>) {
    let end = scene.time.duration as f64;
    for (i, e) in scene.emitters.iter().enumerate() {
        if e.start >= end {
            out.push(format!(
                "emitter[{i}] `{}` starts at {} s, when the run has ended (time.duration = {} \
                 s): it emits nothing; start it earlier (`emitter[{i}].start`) or run longer",
                e.name, e.start as f32, scene.time.duration
            ));
        } else if e.piles_up() {
            out.push(format!(
                "emitter[{i}] `{}` emits {:.4e} particles per second, but at its velocity only \
                 about {:.4e} per second leave it (cross-section x speed / particle volume): the \
                 rest pile up inside it, are compressed and burst out (a dense cluster that can \
                 blow up the run); lower `emitter[{i}].rate` (volume_rate = cross-section x \
                 speed = {:.4e} m^3/s) or raise its velocity",
                e.name,
                e.rate,
                e.outflow(),
                e.cross_section() * e.velocity.length() as f64
            ));
        }
    }
}

/// Rigid bodies thinner than a cell (the material meets a body at the grid nodes inside it),
/// and kinematic bodies that leave the domain before the end.
fn rigid_bodies(scene: &Scene, out: &mut Vec<String>) {
    let (lo, hi) = scene.interior();
    for (i, b) in scene.rigid_bodies.iter().enumerate() {
        let extent = 2.0 * b.shape.half_extents(Mat3::from_quat(b.rotation));
        let thinnest = extent.min_element();
        if thinnest < scene.dx {
            out.push(format!(
                "rigid_body[{i}] `{}` is only {thinnest:.3e} m thick, less than a grid cell (dx \
                 = {} m): the material meets a body at the grid nodes inside it, so it passes \
                 through this one; make the body at least a cell thick (better 2-5 cells) or use \
                 a smaller dx",
                b.name, scene.dx
            ));
        }
        if b.kind == RigidKind::Kinematic && b.velocity.length() > 0.0 {
            // When its centre leaves the interior, moving at its constant velocity.
            let v = b.velocity;
            let leave = (0..3)
                .filter(|&a| v[a] != 0.0)
                .map(|a| {
                    let wall = if v[a] > 0.0 { hi[a] } else { lo[a] };
                    (wall - b.position[a]) / v[a]
                })
                .fold(f32::INFINITY, f32::min);
            if leave < scene.time.duration {
                out.push(format!(
                    "kinematic rigid_body[{i}] `{}` moves at a constant {} m/s and leaves the \
                     domain at about t = {leave:.4} s, before the run ends (time.duration = {} \
                     s); lower `rigid_body[{i}].velocity` or make the body dynamic",
                    b.name,
                    b.velocity.length(),
                    scene.time.duration
                ));
            }
        }
    }
}

/// With a fixed `time.dt`, the speed sources that move more than a cell per step: the step
/// does not follow them, so the material they meet blows up.
fn fixed_step(scene: &Scene, out: &mut Vec<String>) {
    let StepMode::Fixed { dt } = scene.time.step else {
        return;
    };
    let dx = scene.dx as f64;
    for s in scene.speed_sources() {
        let cells = s.speed * dt as f64 / dx;
        if cells > 1.0 {
            out.push(format!(
                "{} moves at {:.4e} m/s, {cells:.1} cells per step of time.dt = {dt:e} s: the \
                 material it meets is flung faster than the step follows and the run will blow \
                 up; lower `{}`, or time.dt to at most {:.3e} s (or use time.cfl, whose step \
                 follows it)",
                s.what,
                s.speed,
                s.field,
                dx / s.speed
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::scene::Scene;

    fn scene(time: &str, extra: &str) -> Scene {
        let text = format!(
            "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.05\n[time]\nduration = 1\n{time}\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n\
             {extra}"
        );
        Scene::from_toml(&text, "warnings").unwrap()
    }

    fn emitter(extra: &str) -> String {
        format!(
            "[[emitter]]\nname = \"jet\"\nmaterial = \"w\"\nshape = \"box\"\n\
             min = [0.4, 0.4, 0.4]\nmax = [0.5, 0.5, 0.5]\n{extra}\n"
        )
    }

    #[test]
    fn emitters_that_do_nothing_or_pile_up() {
        // The jet's flux: 0.1 x 0.1 m at 1 m/s is 0.01 m^3/s.
        let ok = scene("", &emitter("velocity = [0, 1, 0]\nvolume_rate = 0.01"));
        assert!(ok.warnings().is_empty(), "{:?}", ok.warnings());
        let w = scene("", &emitter("velocity = [0, 1, 0]\nvolume_rate = 0.05")).warnings();
        assert!(w.len() == 1 && w[0].contains("pile up"), "{w:?}");
        let w = scene("", &emitter("rate = 100\nstart = 2\nstop = 3")).warnings();
        assert!(w.len() == 1 && w[0].contains("emitter[0].start"), "{w:?}");
    }

    #[test]
    fn thin_and_leaving_rigid_bodies() {
        let body = |extra: &str| {
            format!(
                "[[rigid_body]]\nshape = \"box\"\nmin = [0.3, 0.3, 0.3]\nmax = [0.5, 0.5, 0.32]\n\
                 density = 500\n{extra}\n"
            )
        };
        let w = scene("", &body("")).warnings();
        assert!(w.len() == 1 && w[0].contains("thick"), "{w:?}");
        let w = scene("", &body("type = \"kinematic\"\nvelocity = [2, 0, 0]")).warnings();
        assert!(w.iter().any(|w| w.contains("leaves the domain")), "{w:?}");
    }

    #[test]
    fn a_fixed_step_that_a_collider_outruns() {
        let c = "[[collider]]\nshape = \"sphere\"\ncenter = [0.5, 0.5, 0.5]\nradius = 0.1\n\
                 velocity = [100, 0, 0]\n";
        let w = scene("dt = 1e-3", c).warnings();
        assert!(
            w.len() == 1 && w[0].contains("collider[0].velocity") && w[0].contains("2.0 cells"),
            "{w:?}"
        );
        assert!(scene("dt = 1e-4", c).warnings().is_empty());
    }
}

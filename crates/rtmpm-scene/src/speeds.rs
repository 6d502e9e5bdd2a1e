//! The speeds a scene drives its material at, besides the particles' own: colliders (their
//! constant motion or keyframes), rigid bodies, emitters and gravity. The time step has to
//! follow them (a boundary moving several cells in one step tunnels through the material or
//! flings it), so the CFL step of a run ([`crate::sim::Simulation::next_dt`]) and the budget's
//! estimate of the steps ([`super::Budget`]) count them, and a blow-up or a collapsed step
//! names the one to blame.
//!
//! A boundary's speed is that of its fastest point where the material can be: the pivot's
//! speed plus the spin times the largest distance from the pivot to the body within the
//! domain. Gravity is counted twice: as the speed of a fall across the domain (what material
//! falling that far reaches), and as its own bound on the step, `|g| dt^2 <= cfl dx` (the
//! displacement it adds in one step within a fraction of a cell).

use crate::scene::{Body, Scene};
use glam::Mat3;
use rtmpm_geometry::{Collider, Shape};
use rtmpm_physics::math::Vec3;
use rtmpm_rigid::BodyState;

/// Something that moves the material at a speed of its own.
#[derive(Clone, Debug, PartialEq)]
pub struct SpeedSource {
    /// What moves, e.g. "collider[0]" or "emitter[1] `jet`".
    pub what: String,
    /// The field that sets the speed, e.g. "collider[0].keyframes".
    pub field: String,
    /// Largest speed (m/s) of a point of it where the material can be.
    pub speed: f64,
}

/// The length of `v` computed in f64: the length of a vector of f32 components up to about
/// 3.4e38 (whose square overflows f32 from about 1.8e19 on) is finite.
pub fn norm(v: Vec3) -> f64 {
    v.as_dvec3().length()
}

/// Largest distance from `pivot` to a point of `bounds` (`None`: unbounded, a half-space) that
/// lies in the domain `(lo, hi)`, bounded by the farthest corner of the domain.
fn reach(pivot: Vec3, bounds: Option<(Vec3, Vec3)>, domain: (Vec3, Vec3)) -> f32 {
    let farthest = |(lo, hi): (Vec3, Vec3)| {
        let d = (pivot - lo).abs().max((hi - pivot).abs());
        d.length()
    };
    let to_domain = farthest(domain);
    match bounds {
        Some(b) => farthest(b).min(to_domain),
        None => to_domain,
    }
}

/// Speed (m/s) of the fastest point of collider `c` at time `t` within `domain`.
pub fn collider_speed(c: &Collider, t: f32, domain: (Vec3, Vec3)) -> f32 {
    let (v, w) = c.motion_at(t);
    let spin = norm(w);
    if spin == 0.0 {
        return norm(v) as f32;
    }
    (norm(v) + spin * reach(c.pivot_at(t), c.bounds(t), domain) as f64) as f32
}

/// Speed (m/s) of the fastest point of collider `c` at any time of `[t0, t1]`: its motion at
/// `t0` and that of each keyframed segment that starts within the interval (a segment's
/// velocity is constant).
pub fn collider_speed_within(c: &Collider, t0: f32, t1: f32, domain: (Vec3, Vec3)) -> f32 {
    let mut s = collider_speed(c, t0, domain);
    if let Some(k) = &c.keyframes {
        let keys = k.keys();
        let first = keys.partition_point(|key| key.t <= t0);
        for key in keys[first..].iter().take_while(|key| key.t < t1) {
            s = s.max(collider_speed(c, key.t, domain));
        }
    }
    s
}

/// The step from time `t`, at most `dt`, that no keyframed collider outruns: a collider whose
/// next segment (from a key at `t_k` within the step) is faster than the step follows would
/// move unseen through the material for the rest of the step (the boundary is applied with
/// the motion at the step's start). For each such key the step ends at `t_k`, or is
/// `step_for(the segment's speed)` when that is longer (a key closer than that step).
pub fn keyframe_step(scene: &Scene, t: f64, dt: f32, step_for: impl Fn(f32) -> f32) -> f32 {
    let domain = (scene.domain_min, scene.domain_max);
    let mut out = dt;
    for c in &scene.colliders {
        let Some(k) = &c.keyframes else {
            continue;
        };
        let keys = k.keys();
        let first = keys.partition_point(|key| key.t as f64 <= t);
        for key in &keys[first..] {
            let to_key = (key.t as f64 - t) as f32;
            if to_key >= out {
                break;
            }
            let fast = step_for(collider_speed(c, key.t, domain));
            if fast < out {
                out = to_key.max(fast);
            }
        }
    }
    out
}

/// The largest [`collider_speed`] over the run: the constant motion's, or that of the fastest
/// keyframed segment.
pub fn collider_peak_speed(c: &Collider, domain: (Vec3, Vec3)) -> f32 {
    match &c.keyframes {
        // A segment's velocity is constant; its reach is taken at the segment's first key.
        Some(k) => k
            .keys()
            .iter()
            .map(|key| collider_speed(c, key.t, domain))
            .fold(0.0, f32::max),
        None => collider_speed(c, 0.0, domain),
    }
}

/// Speed (m/s) of the fastest point of a rigid body of `shape` turned by `rotation`, moving at
/// `v` and spinning at `w`; the spin counts at least a cell `dx` from the centre (the nodes
/// that take the body's velocity).
pub fn rigid_speed(shape: &Shape, rotation: Mat3, v: Vec3, w: Vec3, dx: f32) -> f32 {
    let spin = norm(w);
    if spin == 0.0 {
        return norm(v) as f32;
    }
    (norm(v) + spin * shape.half_extents(rotation).length().max(dx) as f64) as f32
}

/// The largest step (s) gravity `g` allows: `|g| dt^2 <= cfl dx` (infinite without gravity).
pub fn gravity_dt(g: Vec3, dx: f32, cfl: f32) -> f32 {
    let a = norm(g);
    if a > 0.0 {
        (cfl as f64 * dx as f64 / a).sqrt() as f32
    } else {
        f32::INFINITY
    }
}

/// Speed (m/s) of a fall across the domain minus the walls under `scene.gravity`:
/// `sqrt(2 |g| h)`, `h` the interior's extent along gravity.
pub fn fall_speed(scene: &Scene) -> f64 {
    let g = scene.gravity.as_dvec3();
    let a = g.length();
    if a == 0.0 {
        return 0.0;
    }
    let (lo, hi) = scene.interior();
    let h = ((hi - lo).as_dvec3() * g.abs() / a).element_sum();
    (2.0 * a * h).sqrt()
}

/// Largest initial speed (m/s) of a body's particles: its velocity, its spin times the extent
/// of its bounding box, or its file's velocities.
fn body_speed(b: &Body) -> f64 {
    let (lo, hi) = b.shape.bounds();
    let mut s = norm(b.velocity) + norm(b.angular_velocity) * norm(hi - lo);
    if let (Shape::Particles(p), true) = (&b.shape, b.file_velocity) {
        let fastest = p.points.velocities.iter().flatten().map(|&v| norm(v));
        s = s.max(fastest.fold(0.0, f64::max));
    }
    s
}

/// The field of a constant motion that dominates: `velocity` when it is the larger part.
fn motion_field(prefix: &str, v: f32, rest: f32) -> String {
    if v >= rest {
        format!("{prefix}.velocity")
    } else {
        format!("{prefix}.angular_velocity")
    }
}

impl Scene {
    /// Every source of speed of the scene besides the materials' sound speeds: the bodies'
    /// initial velocities, the emitters', the colliders' and the rigid bodies' motion, and a fall
    /// across the domain under gravity (zero speeds left out).
    pub fn speed_sources(&self) -> Vec<SpeedSource> {
        let domain = (self.domain_min, self.domain_max);
        let mut out = Vec::new();
        let mut push = |what: String, field: String, speed: f64| {
            if speed > 0.0 {
                out.push(SpeedSource { what, field, speed });
            }
        };
        for (i, b) in self.bodies.iter().enumerate() {
            let field = match &b.shape {
                Shape::Particles(_)
                    if b.file_velocity
                        && b.velocity == Vec3::ZERO
                        && b.angular_velocity == Vec3::ZERO =>
                {
                    format!("body[{i}].file")
                }
                _ => motion_field(
                    &format!("body[{i}]"),
                    b.velocity.length(),
                    b.angular_velocity.length(),
                ),
            };
            push(format!("body[{i}] `{}`", b.name), field, body_speed(b));
        }
        for (i, e) in self.emitters.iter().enumerate() {
            push(
                format!("emitter[{i}] `{}`", e.name),
                format!("emitter[{i}].velocity"),
                norm(e.velocity),
            );
        }
        for (i, c) in self.colliders.iter().enumerate() {
            let field = if c.keyframes.is_some() {
                format!("collider[{i}].keyframes")
            } else {
                motion_field(
                    &format!("collider[{i}]"),
                    c.velocity.length(),
                    collider_speed(c, 0.0, domain) - c.velocity.length(),
                )
            };
            push(
                format!("collider[{i}]"),
                field,
                collider_peak_speed(c, domain) as f64,
            );
        }
        for (i, b) in self.rigid_bodies.iter().enumerate() {
            let rotation = Mat3::from_quat(b.rotation);
            let speed = rigid_speed(&b.shape, rotation, b.velocity, b.angular_velocity, self.dx);
            push(
                format!("rigid_body[{i}] `{}`", b.name),
                motion_field(
                    &format!("rigid_body[{i}]"),
                    b.velocity.length(),
                    speed - b.velocity.length(),
                ),
                speed as f64,
            );
        }
        push(
            "gravity (a fall across the domain)".into(),
            "gravity".into(),
            fall_speed(self),
        );
        out
    }

    /// The fastest of [`Scene::speed_sources`], if any.
    pub fn fastest_source(&self) -> Option<SpeedSource> {
        self.speed_sources()
            .into_iter()
            .max_by(|a, b| a.speed.total_cmp(&b.speed))
    }
}

/// The fastest boundary or emitter over the times `[t0, t1]` of a run (`t0 = t1`: at that
/// time): the colliders' motion ([`collider_speed_within`]), the rigid bodies' `states`, and
/// the emitters still emitting at `t0`. `None` when nothing moves.
pub fn fastest_boundary(
    scene: &Scene,
    (t0, t1): (f64, f64),
    states: &[BodyState],
) -> Option<SpeedSource> {
    let domain = (scene.domain_min, scene.domain_max);
    let mut best: Option<SpeedSource> = None;
    let mut consider = |what: &dyn Fn() -> (String, String), speed: f32| {
        if speed > 0.0 && best.as_ref().is_none_or(|b| (speed as f64) > b.speed) {
            let (what, field) = what();
            best = Some(SpeedSource {
                what,
                field,
                speed: speed as f64,
            });
        }
    };
    for (i, c) in scene.colliders.iter().enumerate() {
        let field = if c.keyframes.is_some() {
            "keyframes"
        } else {
            "velocity"
        };
        consider(
            &|| (format!("collider[{i}]"), format!("collider[{i}].{field}")),
            collider_speed_within(c, t0 as f32, t1 as f32, domain),
        );
    }
    for (i, b) in states.iter().enumerate() {
        let name = scene.rigid_bodies.get(i).map_or("", |s| s.name.as_str());
        consider(
            &|| {
                (
                    format!("rigid_body[{i}] `{name}`"),
                    format!("rigid_body[{i}].velocity"),
                )
            },
            rigid_speed(
                &b.shape,
                b.rotation,
                b.velocity,
                b.angular_velocity,
                scene.dx,
            ),
        );
    }
    for (i, e) in scene.emitters.iter().enumerate() {
        if t0 < e.stop {
            consider(
                &|| {
                    (
                        format!("emitter[{i}] `{}`", e.name),
                        format!("emitter[{i}].velocity"),
                    )
                },
                e.velocity.length(),
            );
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(extra: &str) -> Scene {
        let text = format!(
            "[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.05\n[time]\nduration = 1\n\
             [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000\nbulk_modulus = 1e5\n\
             {extra}"
        );
        Scene::from_toml(&text, "speeds").unwrap()
    }

    #[test]
    fn every_source_is_counted() {
        let s = scene(
            "[[collider]]\nshape = \"sphere\"\ncenter = [0.5, 0.5, 0.5]\nradius = 0.1\n\
             velocity = [3, 0, 0]\n\
             [[collider]]\nshape = \"box\"\nmin = [0.2, 0.2, 0.2]\nmax = [0.4, 0.3, 0.3]\n\
             keyframes = [{ t = 0, position = [0.3, 0.25, 0.25] }, \
             { t = 0.1, position = [0.3, 0.75, 0.25] }]\n\
             [[emitter]]\nmaterial = \"w\"\nshape = \"box\"\nmin = [0.5, 0.5, 0.5]\n\
             max = [0.6, 0.6, 0.6]\nvelocity = [0, 7, 0]\nrate = 100\n",
        );
        let src = s.speed_sources();
        let speed = |field: &str| src.iter().find(|s| s.field == field).map(|s| s.speed);
        assert_eq!(speed("collider[0].velocity"), Some(3.0));
        // 0.5 m in 0.1 s.
        assert!((speed("collider[1].keyframes").unwrap() - 5.0).abs() < 1e-4);
        assert_eq!(speed("emitter[0].velocity"), Some(7.0));
        // A fall across the interior (1 m less 3 cells of wall at each end) under 9.81.
        let g = speed("gravity").unwrap();
        assert!((g - (2.0 * 9.81f64 * 0.7).sqrt()).abs() < 1e-3, "{g}");
        assert_eq!(s.fastest_source().unwrap().field, "emitter[0].velocity");
    }

    #[test]
    fn a_spinning_collider_counts_its_reach_in_the_domain() {
        // A half-space spinning at 2 rad/s about the domain's centre: its farthest point in the
        // domain is a corner, sqrt(3) / 2 m away.
        let s = scene(
            "[[collider]]\nshape = \"half_space\"\npoint = [0.5, 0.5, 0.5]\n\
             normal = [0, 1, 0]\nangular_velocity = [0, 0, 2]\npivot = [0.5, 0.5, 0.5]\n",
        );
        let c = &s.colliders[0];
        let v = collider_speed(c, 0.0, (s.domain_min, s.domain_max));
        assert!((v - 3f32.sqrt()).abs() < 1e-5, "{v}");
        assert_eq!(s.speed_sources()[0].field, "collider[0].angular_velocity");
    }

    #[test]
    fn gravity_bounds_the_step() {
        let dt = gravity_dt(Vec3::new(0.0, -1e6, 0.0), 0.01, 0.4);
        assert!((1e6 * dt * dt - 0.004).abs() < 1e-6);
        assert_eq!(gravity_dt(Vec3::ZERO, 0.01, 0.4), f32::INFINITY);
    }

    #[test]
    fn a_faster_keyframed_segment_within_a_step_ends_the_step_at_its_key() {
        // Still until t = 0.031, then 0.05 m in 1 ms (50 m/s), then still.
        let s = scene(
            "[[collider]]\nshape = \"box\"\nmin = [0.4, 0.2, 0.3]\nmax = [0.6, 0.8, 0.7]\n\
             keyframes = [{ t = 0.0, position = [0.5, 0.5, 0.5] }, \
             { t = 0.031, position = [0.5, 0.5, 0.5] }, \
             { t = 0.032, position = [0.5, 0.5, 0.55] }]\n",
        );
        let c = &s.colliders[0];
        let domain = (s.domain_min, s.domain_max);
        // The step of a speed: 0.4 dx / v, at most 2.4 ms.
        let step_for = |v: f32| {
            if v > 0.0 {
                (0.02 / v).min(2.4e-3)
            } else {
                2.4e-3
            }
        };
        // A step from 0.029 would pass over the whole segment: it ends at the key.
        let dt = keyframe_step(&s, 0.029, 2.4e-3, step_for);
        assert!((dt - 2e-3).abs() < 1e-7, "{dt}");
        // A key closer than the fast segment's step: that step (4e-4 s) from now.
        let dt = keyframe_step(&s, 0.03099, 2.4e-3, step_for);
        assert!((dt - 4e-4).abs() < 1e-9, "{dt}");
        // Within the segment, and after it (a slower segment ahead): unchanged.
        assert_eq!(keyframe_step(&s, 0.0312, 4e-4, step_for), 4e-4);
        assert_eq!(keyframe_step(&s, 0.0325, 2.4e-3, step_for), 2.4e-3);
        // The speed over an interval holds the segments that start in it.
        assert_eq!(collider_speed_within(c, 0.0307, 0.0309, domain), 0.0);
        assert!((collider_speed_within(c, 0.0307, 0.0331, domain) - 50.0).abs() < 0.01);
        let over = |t0, t1| fastest_boundary(&s, (t0, t1), &[]).map(|b| b.field);
        assert_eq!(over(0.0325, 0.0325), None);
        assert_eq!(
            over(0.0305, 0.0325).as_deref(),
            Some("collider[0].keyframes")
        );
    }
}

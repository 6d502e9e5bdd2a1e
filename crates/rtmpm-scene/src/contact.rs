//! Material that starts hanging from an obstacle: a body of material in contact with a slip or
//! sticky wall, collider or rigid body above it. Those rules remove the normal velocity both
//! ways, so the nodes they act on hold the material that touches the obstacle from below (it
//! hangs from a ceiling or from the underside of a body instead of falling); the separating rule,
//! the default, lets it go. Checked before anything is sampled, from the shapes: the walls
//! against each body's bounding box, colliders and rigid bodies against points of the body on a
//! lattice of half a cell.

use crate::scene::{Body, Scene};
use rtmpm_geometry::{Collider, Shape};
use rtmpm_physics::boundary::Condition;
use rtmpm_physics::math::Vec3;

/// Material within this many cells of an obstacle's surface touches its nodes: the reach of
/// the quadratic B-splines.
pub const CONTACT_CELLS: f32 = 1.5;

/// An obstacle is above the material when the normal it pushes the material along (out of the
/// obstacle) is within 60 degrees of gravity's direction: `n . g / |g| >= 0.5`.
pub const ABOVE_COS: f32 = 0.5;

/// Lattice points per axis at most, for one body against one obstacle.
const MAX_POINTS_PER_AXIS: f32 = 48.0;

const FACES: [&str; 6] = ["x_min", "x_max", "y_min", "y_max", "z_min", "z_max"];

/// One warning per body of material and slip or sticky obstacle above it that the body starts
/// in contact with; empty without gravity.
pub fn hanging_warnings(scene: &Scene) -> Vec<String> {
    let Some(down) = scene.gravity.try_normalize() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (i, body) in scene.bodies.iter().enumerate() {
        let what = format!("body[{i}] `{}`", body.name);
        out.extend(walls_above(scene, body, down, &what));
        for (k, c) in scene.colliders.iter().enumerate() {
            if let Some(x) = touches_from_below(scene, body, c, c.rule.condition, down) {
                out.push(message(
                    &what,
                    &format!("collider[{k}]"),
                    c.rule.condition,
                    x,
                    &format!("give collider[{k}] condition = \"separate\""),
                    scene.dx,
                ));
            }
        }
        for (k, b) in scene.rigid_bodies.iter().enumerate() {
            let c = rigid_collider(b);
            if let Some(x) = touches_from_below(scene, body, &c, b.condition, down) {
                out.push(message(
                    &what,
                    &format!("rigid_body[{k}] `{}`", b.name),
                    b.condition,
                    x,
                    &format!("give rigid_body[{k}] condition = \"separate\""),
                    scene.dx,
                ));
            }
        }
    }
    out
}

fn name(c: Condition) -> &'static str {
    match c {
        Condition::Sticky => "sticky",
        Condition::Slip => "slip",
        Condition::Separate => "separate",
    }
}

fn message(what: &str, obstacle: &str, c: Condition, x: Vec3, fix: &str, dx: f32) -> String {
    format!(
        "{what} starts in contact with {obstacle} (condition \"{}\") above it, near ({:.4}, \
         {:.4}, {:.4}): a {} obstacle keeps the material that touches it from moving away, so \
         this material hangs from it instead of falling; {fix} (it then only stops material \
         moving into it), or start the body at least {CONTACT_CELLS} cells ({:.4} m) away from \
         it (docs/scene-format.md, \"Which rule\")",
        name(c),
        x.x,
        x.y,
        x.z,
        name(c),
        CONTACT_CELLS * dx
    )
}

/// The walls of non-separating faces above the body that its bounding box comes within
/// [`CONTACT_CELLS`] of (the wall's inner node plane is where bodies may start).
fn walls_above(scene: &Scene, body: &Body, down: Vec3, what: &str) -> Vec<String> {
    let (lo, hi) = body.shape.bounds();
    let (imin, imax) = scene.interior();
    let reach = CONTACT_CELLS * scene.dx;
    let mut out = Vec::new();
    for (k, face) in FACES.iter().enumerate() {
        let rule = scene.walls.faces[k];
        if rule.condition == Condition::Separate {
            continue;
        }
        let axis = k / 2;
        // The normal the wall pushes material along, into the domain.
        let mut n = Vec3::ZERO;
        n[axis] = if k % 2 == 0 { 1.0 } else { -1.0 };
        if n.dot(down) < ABOVE_COS {
            continue;
        }
        let (gap, at) = if k % 2 == 0 {
            (lo[axis] - imin[axis], imin[axis])
        } else {
            (imax[axis] - hi[axis], imax[axis])
        };
        if gap >= reach {
            continue;
        }
        let mut x = 0.5 * (lo + hi);
        x[axis] = at;
        out.push(message(
            what,
            &format!("the {face} wall"),
            rule.condition,
            x,
            &format!("give that face condition = \"separate\" ([walls.faces.{face}])"),
            scene.dx,
        ));
    }
    out
}

/// A rigid body at its initial pose as a motionless collider (its shape in the body frame,
/// placed by one keyframe).
fn rigid_collider(b: &rtmpm_rigid::RigidBodySpec) -> Collider {
    let key = rtmpm_geometry::Keyframe {
        t: 0.0,
        position: b.position,
        rotation: b.rotation,
    };
    Collider {
        shape: b.shape.clone(),
        rule: Default::default(),
        velocity: Vec3::ZERO,
        angular_velocity: Vec3::ZERO,
        pivot: Vec3::ZERO,
        keyframes: rtmpm_geometry::Keyframes::new(vec![key]).ok(),
    }
}

/// The unit normal of `c` at the world point `x` at t = 0, pointing out of the obstacle.
fn normal_at(c: &Collider, x: Vec3) -> Vec3 {
    let r = c.rotation(0.0);
    let x_rest = r.transpose() * (x - c.pivot_at(0.0)) + c.pivot;
    (r * c.shape.normal(x_rest)).normalize_or_zero()
}

/// A point of `body` within [`CONTACT_CELLS`] of the obstacle `c` (at t = 0) where the
/// obstacle is above it, when its rule `condition` is slip or sticky.
fn touches_from_below(
    scene: &Scene,
    body: &Body,
    c: &Collider,
    condition: Condition,
    down: Vec3,
) -> Option<Vec3> {
    if condition == Condition::Separate {
        return None;
    }
    let reach = CONTACT_CELLS * scene.dx;
    let (mut lo, mut hi) = body.shape.bounds();
    if let Some((clo, chi)) = c.bounds(0.0) {
        lo = lo.max(clo - reach);
        hi = hi.min(chi + reach);
    }
    if !(lo.cmple(hi).all()) {
        return None;
    }
    let hangs = |x: Vec3| c.distance(x, 0.0) < reach && normal_at(c, x).dot(down) >= ABOVE_COS;
    if let Shape::Particles(p) = &body.shape {
        return p
            .points
            .positions
            .iter()
            .copied()
            .filter(|x| x.cmpge(lo).all() && x.cmple(hi).all())
            .find(|&x| hangs(x));
    }
    let h = (0.5 * scene.dx).max((hi - lo).max_element() / MAX_POINTS_PER_AXIS);
    let n = ((hi - lo) / h).ceil().max(Vec3::ONE);
    let (nx, ny, nz) = (n.x as u32, n.y as u32, n.z as u32);
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                let x = lo + (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * h;
                let x = x.min(hi);
                if body.shape.contains(x) && hangs(x) {
                    return Some(x);
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use crate::Scene;

    const HEAD: &str = r#"
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.05
[time]
duration = 0.1
[[material]]
name = "mud"
type = "fluid"
density = 1000.0
bulk_modulus = 1e4
"#;

    fn warnings(rest: &str) -> Vec<String> {
        warnings_with("", rest)
    }

    /// The warnings of the scene `top` (top-level fields) + the common head + `rest`.
    fn warnings_with(top: &str, rest: &str) -> Vec<String> {
        let s = Scene::from_toml(&format!("{top}{HEAD}{rest}"), "test.toml").expect("scene");
        super::hanging_warnings(&s)
    }

    /// A body up to the ceiling's plane (0.85 = 1 - 3 cells) under a slip ceiling hangs; under
    /// the default (separating) walls, or 2 cells below, or with the ceiling a side wall (no
    /// gravity along it), it does not.
    #[test]
    fn a_body_under_a_slip_ceiling_is_warned_about() {
        let body = "[[body]]\nmaterial = \"mud\"\nshape = \"box\"\nmin = [0.3, 0.15, 0.3]\n";
        let w = warnings(&format!(
            "[walls]\ncondition = \"slip\"\n{body}max = [0.6, 0.85, 0.6]\n"
        ));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("the y_max wall (condition \"slip\")"),
            "{}",
            w[0]
        );
        assert!(w[0].contains("[walls.faces.y_max]"), "{}", w[0]);
        assert!(warnings(&format!("{body}max = [0.6, 0.85, 0.6]\n")).is_empty());
        assert!(
            warnings(&format!(
                "[walls]\ncondition = \"slip\"\n{body}max = [0.6, 0.75, 0.6]\n"
            ))
            .is_empty()
        );
        // Gravity along -z: the ceiling is a side wall, the z_min face (separate here) the floor.
        assert!(
            warnings_with(
                "gravity = [0.0, 0.0, -9.81]\n",
                &format!(
                    "[walls]\ncondition = \"sticky\"\nfaces.z_min = {{ condition = \"separate\" \
                     }}\n{body}max = [0.6, 0.85, 0.6]\n"
                )
            )
            .is_empty()
        );
    }

    /// The underside of a sticky box collider touching the top of the material is warned
    /// about; the same collider beside the material, or separating, is not.
    #[test]
    fn a_body_under_a_sticky_collider_is_warned_about() {
        let body = "[[body]]\nmaterial = \"mud\"\nshape = \"sphere\"\ncenter = [0.5, 0.4, \
                    0.5]\nradius = 0.2\n";
        let above = "[[collider]]\nshape = \"box\"\nmin = [0.3, 0.62, 0.3]\n\
                     max = [0.7, 0.8, 0.7]\ncondition = \"sticky\"\n";
        let w = warnings(&format!("{body}{above}"));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("collider[0] (condition \"sticky\")"),
            "{}",
            w[0]
        );
        let beside = "[[collider]]\nshape = \"box\"\nmin = [0.72, 0.2, 0.3]\n\
                      max = [0.8, 0.6, 0.7]\ncondition = \"sticky\"\n";
        assert!(warnings(&format!("{body}{beside}")).is_empty());
        let separate = above.replace("sticky", "separate");
        assert!(warnings(&format!("{body}{separate}")).is_empty());
        // The default rule is the separating one.
        let default = above.replace("condition = \"sticky\"\n", "");
        assert!(warnings(&format!("{body}{default}")).is_empty());
    }

    /// Material touching the underside of a slip rigid body (a box resting on it) is warned
    /// about; under the default rule it is not.
    #[test]
    fn material_under_a_slip_rigid_body_is_warned_about() {
        let body = "[[body]]\nmaterial = \"mud\"\nshape = \"box\"\nmin = [0.15, 0.15, 0.15]\n\
                    max = [0.85, 0.5, 0.85]\n";
        let rigid = "[[rigid_body]]\nname = \"crate\"\nshape = \"box\"\nmin = [0.4, 0.45, 0.4]\n\
                     max = [0.6, 0.6, 0.6]\ndensity = 500.0\ncondition = \"slip\"\n";
        let w = warnings(&format!("{body}{rigid}"));
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("rigid_body[0] `crate` (condition \"slip\")"),
            "{}",
            w[0]
        );
        let default = rigid.replace("condition = \"slip\"\n", "");
        assert!(warnings(&format!("{body}{default}")).is_empty());
    }
}

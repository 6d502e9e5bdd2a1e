//! Joints between rigid bodies (`[[joint]]`, cargo feature `rigid`): the scene tables, the
//! errors, and rapier's joints as the rigid-body world builds them (stepped without material,
//! so that what is measured is the joint's kinematics).
#![cfg(feature = "rigid")]

use glam::Vec3;
use rtmpm_rigid::{Exchange, RigidWorld};
use rtmpm_scene::Scene;

/// A scene around `tables`: a unit box domain with slip walls and a little water in a corner
/// (a scene needs material; the tests below step only the bodies).
fn scene(tables: &str) -> Result<Scene, String> {
    let text = format!(
        r#"
name = "joints"
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.05
[time]
duration = 1.0
fps = 10
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 1e4
[[body]]
material = "water"
shape = "box"
min = [0.8, 0.2, 0.8]
max = [0.85, 0.25, 0.85]
{tables}
"#
    );
    Scene::from_toml(&text, "joints.toml").map_err(|e| e.to_string())
}

fn world(scene: &Scene) -> RigidWorld {
    RigidWorld::new(
        &scene.rigid_bodies,
        &scene.joints,
        scene.gravity,
        scene.interior(),
    )
    .expect("world")
    .expect("bodies")
}

/// Step the bodies alone for `t` seconds at `dt`, calling `each` with the time after each step.
fn run(w: &mut RigidWorld, t: f32, dt: f32, mut each: impl FnMut(f32, &RigidWorld)) {
    let none = vec![Exchange::default(); w.states().len()];
    let steps = (t / dt).round() as usize;
    for s in 0..steps {
        w.advance(&none, dt);
        each((s + 1) as f32 * dt, w);
    }
}

/// A ball on a spherical joint 0.2 m below a fixed point swings as a pendulum: its distance to
/// the anchor stays 0.2 m (within 1 mm) and its small swings have the period 2 pi sqrt(L / g)
/// within 2 % (the ball's own inertia makes the true period longer by
/// sqrt(1 + 2 r^2 / (5 L^2)) = 1.002 for r = 0.02).
#[test]
fn a_ball_on_a_spherical_joint_swings_as_a_pendulum() {
    let s = scene(
        r#"
[[rigid_body]]
name = "bob"
shape = "sphere"
center = [0.5, 0.5, 0.5]
radius = 0.02
mass = 1.0
velocity = [0.1, 0.0, 0.0]
[[joint]]
type = "spherical"
body = "bob"
anchor = [0.5, 0.7, 0.5]
"#,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.joints.len(), 1);
    let anchor = Vec3::new(0.5, 0.7, 0.5);
    let mut w = world(&s);
    let (mut worst, mut crossings) = (0.0f32, Vec::new());
    let mut prev = 0.0f32;
    run(&mut w, 2.0, 1e-3, |t, w| {
        let c = w.states()[0].center;
        worst = worst.max(((c - anchor).length() - 0.2).abs());
        let x = c.x - 0.5;
        if prev < 0.0 && x >= 0.0 {
            crossings.push(t);
        }
        prev = x;
    });
    let expected = 2.0 * std::f32::consts::PI * (0.2f32 / 9.81).sqrt();
    let period = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f32;
    println!("length error {worst:.2e} m, period {period:.4} s (2 pi sqrt(L/g) = {expected:.4} s)");
    assert!(worst < 1e-3, "the joint stretched by {worst} m");
    assert!(crossings.len() >= 2, "{crossings:?}");
    assert!(
        (period / expected - 1.0).abs() < 0.02,
        "period {period}, expected {expected}"
    );
}

/// A plate hinged to the world about z at its top edge falls about the hinge only: it never
/// turns about x or y, and the hinge point of the plate stays at the anchor (within 1 mm).
#[test]
fn a_revolute_joint_turns_only_about_its_axis() {
    let s = scene(
        r#"
[[rigid_body]]
name = "flap"
shape = "box"
min = [0.5, 0.4, 0.45]
max = [0.7, 0.42, 0.55]
density = 500.0
[[joint]]
type = "revolute"
body = 0
anchor = [0.5, 0.41, 0.5]
axis = [0.0, 0.0, 1.0]
"#,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut w = world(&s);
    let anchor = Vec3::new(0.5, 0.41, 0.5);
    let local = Vec3::new(-0.1, 0.0, 0.0); // the hinge point in the plate's frame
    let (mut off_axis, mut drift, mut turned) = (0.0f32, 0.0f32, 0.0f32);
    run(&mut w, 0.5, 1e-3, |_, w| {
        let b = w.states()[0].clone();
        off_axis = off_axis.max(b.angular_velocity.x.abs().max(b.angular_velocity.y.abs()));
        drift = drift.max((b.center + b.rotation * local - anchor).length());
        turned = turned.max(b.angular_velocity.z.abs());
    });
    println!(
        "spin about z up to {turned:.3} rad/s, about x/y {off_axis:.2e}, hinge drift {drift:.2e} m"
    );
    assert!(turned > 1.0, "the flap did not swing: {turned}");
    assert!(off_axis < 1e-3 * turned, "turned about x or y: {off_axis}");
    assert!(drift < 1e-3, "the hinge moved by {drift} m");
}

/// A box on a vertical prismatic joint with limits [-0.1, 0] falls 0.1 m and stops there, never
/// moving sideways or turning.
#[test]
fn a_prismatic_joint_slides_along_its_axis_within_its_limits() {
    let s = scene(
        r#"
[[rigid_body]]
shape = "box"
min = [0.45, 0.45, 0.45]
max = [0.55, 0.55, 0.55]
density = 500.0
[[joint]]
type = "prismatic"
body = 0
anchor = [0.5, 0.5, 0.5]
axis = [0.0, 1.0, 0.0]
limits = [-0.1, 0.0]
"#,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut w = world(&s);
    let (mut side, mut spin) = (0.0f32, 0.0f32);
    run(&mut w, 1.0, 1e-3, |_, w| {
        let b = w.states()[0].clone();
        side = side.max((b.center.x - 0.5).abs().max((b.center.z - 0.5).abs()));
        spin = spin.max(b.angular_velocity.length());
    });
    let y = w.states()[0].center.y;
    println!("rest height {y:.4} m, sideways {side:.2e} m, spin {spin:.2e} rad/s");
    assert!((y - 0.4).abs() < 2e-3, "stopped at {y}, the limit is 0.4");
    assert!(side < 1e-4 && spin < 1e-3, "sideways {side}, spin {spin}");
}

/// Two boxes welded by a fixed joint (touching at the start, which jointed bodies may) fall as
/// one: their offset stays the initial 0.1 m along x.
#[test]
fn a_fixed_joint_keeps_two_bodies_together() {
    let s = scene(
        r#"
[[rigid_body]]
name = "a"
shape = "box"
min = [0.4, 0.5, 0.45]
max = [0.5, 0.6, 0.55]
density = 500.0
angular_velocity = [0.0, 0.0, 2.0]
[[rigid_body]]
name = "b"
shape = "box"
min = [0.5, 0.5, 0.45]
max = [0.6, 0.6, 0.55]
density = 800.0
[[joint]]
type = "fixed"
body = "a"
to = "b"
anchor = [0.5, 0.55, 0.5]
"#,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut w = world(&s);
    let mut worst = 0.0f32;
    run(&mut w, 0.3, 1e-3, |_, w| {
        let (a, b) = (w.states()[0].clone(), w.states()[1].clone());
        worst = worst.max(((b.center - a.center).length() - 0.1).abs());
    });
    println!("offset error {worst:.2e} m");
    assert!(worst < 1e-3, "the welded boxes separated by {worst} m");
}

/// Bad joints are refused with the field and a fix.
#[test]
fn bad_joints_are_refused_with_the_field() {
    let body = r#"
[[rigid_body]]
name = "a"
shape = "sphere"
center = [0.5, 0.5, 0.5]
radius = 0.05
density = 500.0
"#;
    let cases = [
        (
            "type = \"spherical\"\nbody = \"nope\"\nanchor = [0.5, 0.6, 0.5]",
            "joint[0].body",
            "no rigid body is named",
        ),
        (
            "type = \"spherical\"\nbody = 3\nanchor = [0.5, 0.6, 0.5]",
            "joint[0].body",
            "there is no rigid_body[3]",
        ),
        (
            "type = \"spherical\"\nbody = 0\nto = \"a\"\nanchor = [0.5, 0.6, 0.5]",
            "joint[0].to",
            "to itself",
        ),
        (
            "type = \"revolute\"\nbody = 0\nanchor = [0.5, 0.6, 0.5]",
            "joint[0].axis",
            "needs an axis",
        ),
        (
            "type = \"revolute\"\nbody = 0\nanchor = [0.5, 0.6, 0.5]\naxis = [0, 0, 0]",
            "joint[0].axis",
            "zero",
        ),
        (
            "type = \"spherical\"\nbody = 0\nanchor = [0.5, 0.6, 0.5]\naxis = [0, 0, 1]",
            "joint[0].axis",
            "has no axis",
        ),
        (
            "type = \"revolute\"\nbody = 0\nanchor = [0.5, 0.6, 0.5]\naxis = [0, 0, 1]\nlimits = [1, -1]",
            "joint[0].limits",
            "lower limit",
        ),
        (
            "type = \"fixed\"\nbody = 0\nanchor = [0.5, 0.6, 0.5]\nlimits = [0, 1]",
            "joint[0].limits",
            "only revolute",
        ),
        (
            "type = \"spherical\"\nbody = 0\nanchor = [0.5, 2.0, 0.5]",
            "joint[0].anchor",
            "outside the domain",
        ),
    ];
    for (joint, field, words) in cases {
        let e = scene(&format!("{body}\n[[joint]]\n{joint}\n")).expect_err(joint);
        assert!(e.contains(field) && e.contains(words), "{joint}:\n{e}");
    }
    // A fixed body jointed to the world holds nothing.
    let e = scene(
        "[[rigid_body]]\nshape = \"sphere\"\ncenter = [0.5, 0.5, 0.5]\nradius = 0.05\ntype = \"fixed\"\n\
         [[joint]]\ntype = \"spherical\"\nbody = 0\nanchor = [0.5, 0.6, 0.5]\n",
    )
    .expect_err("fixed");
    assert!(e.contains("no body of this joint is dynamic"), "{e}");
}

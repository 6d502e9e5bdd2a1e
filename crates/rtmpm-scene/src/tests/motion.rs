//! Scene tests of prescribed motion: keyframed colliders.

use super::*;

const BASE: &str = r#"name = "t"
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.0625
[time]
duration = 1.0
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 1e5
[[body]]
material = "water"
shape = "box"
min = [0.25, 0.25, 0.25]
max = [0.5, 0.5, 0.5]
[[collider]]
shape = "box"
min = [0.4, 0.3, 0.45]
max = [0.6, 0.7, 0.55]
keyframes = [
  { t = 0.0, position = [0.5, 0.5, 0.5] },
  { t = 1.0, position = [0.5, 0.5, 0.6], rotation = [0.0, 1.0, 0.0] },
  { t = 2.0, rotation = [0.0, 2.0, 0.0] },
]
"#;

fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::from_toml(text, "test.toml")
}

/// `BASE` with `from` replaced by `to` must fail on `field`, with a line and a fix.
fn expect_err(from: &str, to: &str, field: &str) -> SceneError {
    assert!(BASE.contains(from), "{from}");
    let e = parse(&BASE.replacen(from, to, 1)).expect_err(&format!("{to} should fail"));
    assert_eq!(e.field.as_deref(), Some(field), "{e}");
    assert!(e.hint.is_some() && e.line.is_some(), "{e}");
    e
}

#[test]
fn keyframes_are_read_with_defaults() {
    let s = parse(BASE).unwrap();
    let c = &s.colliders[0];
    let k = c.keyframes.as_ref().expect("keyframes");
    assert_eq!(k.keys().len(), 3);
    // A key without position keeps the rest pivot (the box centre).
    assert_eq!(k.keys()[2].position, Vec3::new(0.5, 0.5, 0.5));
    assert_eq!(c.pivot, Vec3::new(0.5, 0.5, 0.5));
    // Half way through the first segment: 0.05 m along z, 0.5 rad about y.
    assert!((c.pivot_at(0.5) - Vec3::new(0.5, 0.5, 0.55)).length() < 1e-6);
    let (v, w) = c.motion_at(0.5);
    assert!((v - Vec3::new(0.0, 0.0, 0.1)).length() < 1e-6, "{v}");
    assert!((w - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-5, "{w}");
    // The collider's surface velocity at a point is v + w x (x - pivot(t)).
    let x = c.pivot_at(0.5) + Vec3::new(0.05, 0.0, 0.0);
    let (_, vc) = c.query(x, 0.5).expect("inside");
    assert!((vc - (v + w.cross(Vec3::new(0.05, 0.0, 0.0)))).length() < 1e-6);
    // After the last key it holds still.
    assert_eq!(c.motion_at(3.0), (Vec3::ZERO, Vec3::ZERO));
}

#[test]
fn bad_keyframes_name_the_field_and_the_fix() {
    expect_err(
        "{ t = 1.0, position",
        "{ t = 0.0, position",
        "collider[0].keyframes[1].t",
    );
    expect_err("{ t = 2.0,", "{ t = nan,", "collider[0].keyframes[2].t");
    expect_err("{ t = 2.0,", "{ t = -2.0,", "collider[0].keyframes[2].t");
    expect_err(
        "position = [0.5, 0.5, 0.6]",
        "position = [0.5, inf, 0.6]",
        "collider[0].keyframes[1].position",
    );
    let e = expect_err(
        "rotation = [0.0, 2.0, 0.0]",
        "rotation = [0.0, 4.5, 0.0]",
        "collider[0].keyframes[2].rotation",
    );
    assert!(e.message.contains("shorter arc"), "{e}");
    let e = expect_err(
        "keyframes = [",
        "velocity = [1.0, 0.0, 0.0]\nkeyframes = [",
        "collider[0].velocity",
    );
    assert!(e.to_string().contains("remove `velocity`"), "{e}");
    expect_err(
        "keyframes = [",
        "angular_velocity = [1.0, 0.0, 0.0]\nkeyframes = [",
        "collider[0].angular_velocity",
    );
    let empty = BASE.replacen(
        "keyframes = [\n  { t = 0.0, position = [0.5, 0.5, 0.5] },\n  { t = 1.0, position = [0.5, 0.5, 0.6], rotation = [0.0, 1.0, 0.0] },\n  { t = 2.0, rotation = [0.0, 2.0, 0.0] },\n]",
        "keyframes = []",
        1,
    );
    assert_ne!(empty, BASE);
    let e = parse(&empty).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("collider[0].keyframes"), "{e}");
    // Unknown fields of a key are reported (typo of `position`).
    let e = parse(&BASE.replacen("{ t = 0.0, position", "{ t = 0.0, positon", 1)).unwrap_err();
    assert!(e.message.contains("positon"), "{e}");
}

const RIGID: &str = r#"[[rigid_body]]
shape = "box"
min = [0.6, 0.6, 0.6]
max = [0.7, 0.7, 0.7]
density = 500.0
[[rigid_body]]
shape = "sphere"
center = [0.3, 0.75, 0.3]
radius = 0.05
mass = 2.0
"#;

#[test]
fn rigid_bodies_are_read_and_bad_ones_refused() {
    let text = format!("{BASE}{RIGID}");
    let s = parse(&text).unwrap();
    assert_eq!(s.rigid_bodies.len(), 2);
    let b = &s.rigid_bodies[0];
    assert!((b.mass - 500.0 * 0.001).abs() < 1e-6);
    assert_eq!(b.position, Vec3::new(0.65, 0.65, 0.65));
    assert_eq!(s.rigid_bodies[1].mass, 2.0);
    let bad = |from: &str, to: &str, field: &str| {
        assert!(text.contains(from), "{from}");
        let e = parse(&text.replacen(from, to, 1)).expect_err(to);
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
        assert!(e.hint.is_some() && e.line.is_some(), "{e}");
    };
    bad("density = 500.0\n", "", "rigid_body[0].density");
    bad("density = 500.0", "density = -5.0", "rigid_body[0].density");
    bad("mass = 2.0", "mass = 0.0", "rigid_body[1].mass");
    bad(
        "mass = 2.0",
        "mass = 2.0\ndensity = 3.0",
        "rigid_body[1].mass",
    );
    bad(
        "max = [0.7, 0.7, 0.7]",
        "max = [0.7, 0.99, 0.7]",
        "rigid_body[0].shape",
    );
    bad(
        "center = [0.3, 0.75, 0.3]",
        "center = [0.65, 0.72, 0.65]",
        "rigid_body[1]",
    );
    // A mesh body takes file, scale and translate (tests_rigid_mesh.rs), not a centre.
    bad(
        "shape = \"sphere\"\ncenter",
        "shape = \"mesh\"\ncenter",
        "rigid_body[1].center",
    );
    // A missing mesh file is reported on `file`.
    bad(
        "shape = \"sphere\"\ncenter = [0.3, 0.75, 0.3]\nradius = 0.05",
        "shape = \"mesh\"\nfile = \"no-such-boat.obj\"",
        "rigid_body[1].file",
    );
    // A cylinder needs its height.
    bad(
        "shape = \"sphere\"\ncenter",
        "shape = \"cylinder\"\ncenter",
        "rigid_body[1].height",
    );
    bad(
        "density = 500.0",
        "density = 500.0\ntype = \"fixed\"\nvelocity = [1.0, 0.0, 0.0]",
        "rigid_body[0].velocity",
    );
    bad("mass = 2.0", "mass = -1.0", "rigid_body[1].mass");
    bad("mass = 2.0", "mass = nan", "rigid_body[1].mass");
}

#[test]
fn rigid_cylinders_take_the_colliders_fields() {
    use rtmpm_geometry::Shape;
    use rtmpm_geometry::shape::Cylinder;
    let cyl = "[[rigid_body]]\nshape = \"cylinder\"\ncenter = [0.5, 0.5, 0.5]\nradius = 0.1\n\
               height = 0.4\naxis = [1.0, 0.0, 0.0]\ndensity = 100.0\n";
    let s = parse(&format!("{BASE}{cyl}")).unwrap();
    let b = &s.rigid_bodies[0];
    assert_eq!(
        b.shape,
        Shape::Cylinder(Cylinder {
            center: Vec3::ZERO,
            axis: Vec3::Y,
            radius: 0.1,
            half_height: 0.2
        })
    );
    assert!((b.mass - 100.0 * std::f32::consts::PI * 0.01 * 0.4).abs() < 1e-5);
    // The axis turns the body's local y (the cylinder's axis) onto x.
    assert!((b.rotation * Vec3::Y - Vec3::X).length() < 1e-6);
    // Without an axis it stands along y; a rotation turns it after the axis.
    let s = parse(&format!(
        "{BASE}{}",
        cyl.replace("axis = [1.0, 0.0, 0.0]\n", "")
    ))
    .unwrap();
    assert_eq!(s.rigid_bodies[0].rotation, glam::Quat::IDENTITY);
    let turned = cyl.replace(
        "axis = [1.0, 0.0, 0.0]",
        "axis = [1.0, 0.0, 0.0]\nrotation = [0.0, 1.5707964, 0.0]",
    );
    let s = parse(&format!("{BASE}{turned}")).unwrap();
    assert!((s.rigid_bodies[0].rotation * Vec3::Y - Vec3::NEG_Z).length() < 1e-6);
    let bad = |from: &str, to: &str, field: &str| {
        assert!(cyl.contains(from), "{from}");
        let e = parse(&format!("{BASE}{}", cyl.replacen(from, to, 1))).expect_err(to);
        assert_eq!(e.field.as_deref(), Some(field), "{e}");
        assert!(e.hint.is_some(), "{e}");
    };
    bad("height = 0.4", "height = 0.0", "rigid_body[0].height");
    bad("radius = 0.1", "radius = -0.1", "rigid_body[0].radius");
    bad(
        "axis = [1.0, 0.0, 0.0]",
        "axis = [0.0, 0.0, 0.0]",
        "rigid_body[0].axis",
    );
    // Lying along x, 0.4 long: centred at x = 0.9 it reaches x = 1.1, beyond the interior
    // (0.1875 .. 0.8125: three wall cells of 0.0625).
    bad(
        "center = [0.5, 0.5, 0.5]",
        "center = [0.9, 0.5, 0.5]",
        "rigid_body[0].shape",
    );
}

#[test]
fn bodies_that_can_hang_in_a_fluid_are_warned_about() {
    // In water at dx = 0.0625: the box (0.1 m, V / A = 1/60 m) of density 500 floats, the
    // sphere (radius 0.05 m, V / A = 1/60 m) of mass 2 kg (density 3820) sinks with an excess
    // weight of a water layer 2.82 / 60 m = 0.75 cells thick over its surface.
    let text = format!("{BASE}{RIGID}");
    assert!(parse(&text).unwrap().warnings().is_empty());
    // Density 1500: a layer of 0.5 / 60 m = 0.133 cells; 0.4 cells needs dx <= 0.0208 m.
    let heavy_box = text.replacen("density = 500.0", "density = 1500.0", 1);
    let w = parse(&heavy_box).unwrap().warnings();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("rigid_body[0] `rigid_body0` (density 1500) can hang in `water`")
            && w[0].contains("0.13 cells")
            && w[0].contains("dx <= 0.0208"),
        "{w:?}"
    );
    // Not a kinematic body (the material does not load it), nor at 3000 (0.53 cells).
    let kinematic = heavy_box.replacen(
        "density = 1500.0",
        "density = 1500.0\ntype = \"kinematic\"",
        1,
    );
    assert!(parse(&kinematic).unwrap().warnings().is_empty());
    let heavier = text.replacen("density = 500.0", "density = 3000.0", 1);
    assert!(parse(&heavier).unwrap().warnings().is_empty());
    // A sphere given by its mass: density 1200 is 0.2 / 60 m = 0.053 cells.
    let mass = 1200.0 * 4.0 / 3.0 * std::f32::consts::PI * 0.05f32.powi(3);
    let w = parse(&text.replacen("mass = 2.0", &format!("mass = {mass}"), 1))
        .unwrap()
        .warnings();
    assert!(w.len() == 1 && w[0].starts_with("rigid_body[1]"), "{w:?}");
    // Only fluids count: the same body in a Drucker-Prager sand of density 1000 may rest in it.
    let sand = heavy_box.replacen(
        "type = \"fluid\"\ndensity = 1000.0\nbulk_modulus = 1e5",
        "type = \"drucker_prager\"\ndensity = 1000.0\nyoungs_modulus = 1e5\npoisson_ratio = 0.3\nfriction_angle = 30.0",
        1,
    );
    assert_ne!(sand, heavy_box);
    assert!(parse(&sand).unwrap().warnings().is_empty());
}

#[test]
fn rigid_example_scenes_validate() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/rigid");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) == Some("toml") {
            let s = Scene::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
            assert!(!s.rigid_bodies.is_empty());
            assert!(s.sample_particles().unwrap().len() > 5_000);
            n += 1;
        }
    }
    assert!(n >= 2, "{n} scenes");
}

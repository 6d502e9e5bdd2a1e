//! Scene tests of `[output]`, `[surface]` and particle-file bodies.

use super::*;
use rtmpm_io::FrameFields;
use rtmpm_io::bgeo::write_bgeo;
use rtmpm_io::ply::write_ply;
use rtmpm_io::testing::TestDir;

const SCENE: &str = r#"name = "t"
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
[[material]]
name = "jelly"
type = "fixed_corotated"
density = 500.0
youngs_modulus = 1e5
poisson_ratio = 0.3
"#;

fn box_body(material: &str) -> String {
    format!(
        "[[body]]\nmaterial = \"{material}\"\nshape = \"box\"\nmin = [0.25, 0.25, 0.25]\nmax = [0.5, 0.5, 0.5]\n"
    )
}

fn parse_in(dir: &Path, text: &str) -> Result<Scene, SceneError> {
    Scene::from_toml_in(text, "test.toml", dir)
}

#[test]
fn output_formats_and_surface_defaults() {
    let d = TestDir::new("scene-out");
    let text = format!(
        "{SCENE}{}[output]\nformats = [\"bgeo\", \"bgeo.gz\", \"vtu\"]\nsurface = [\"obj\", \"vtu\"]\ncompress = false\n",
        box_body("water")
    );
    let s = parse_in(&d.0, &text).unwrap();
    let o = &s.output;
    assert!(o.writes("bgeo") && o.writes("bgeo.gz") && o.writes("vtu"));
    assert!(!o.writes("ply") && !o.compress);
    // In the registry's order, whatever the order given.
    let names: Vec<&str> = o.formats.iter().map(|f| f.name).collect();
    assert_eq!(names, ["bgeo", "bgeo.gz", "vtu"]);
    assert_eq!(
        o.surface_formats,
        MeshFormats {
            obj: true,
            ply: false,
            vtu: true,
            usda: false
        }
    );
    // Fluids form the surface by default.
    assert_eq!(o.surface.materials, [0]);
    assert_eq!(o.surface.smoothing_length, 2.0);
    // Defaults: PLY only, compressed VTU, no surfaces.
    let s = parse_in(&d.0, &format!("{SCENE}{}", box_body("jelly"))).unwrap();
    assert!(s.output.writes("ply") && !s.output.writes("bgeo") && s.output.compress);
    assert_eq!(s.output.formats.len(), 1);
    // An unknown format: the field, the name and the formats there are.
    let e = parse_in(
        &d.0,
        &format!(
            "{SCENE}{}[output]\nformats = [\"ply\", \"xyz\"]\n",
            box_body("jelly")
        ),
    )
    .unwrap_err();
    assert_eq!(e.field.as_deref(), Some("output.formats"), "{e}");
    assert!(e.message.contains("\"xyz\""), "{e}");
    let hint = e.hint.clone().unwrap_or_default();
    assert!(
        hint.contains("\"usda\"") && hint.contains("\"bgeo.gz\""),
        "{e}"
    );
    assert!(!s.output.surface_formats.any());
}

#[test]
fn surface_table_and_its_errors() {
    let d = TestDir::new("scene-surf");
    let text = format!(
        "{SCENE}{}[surface]\nmaterials = [\"jelly\", \"water\"]\ncube_size = 0.75\nthreshold = 0.5\nsmoothing_iters = 3\n",
        box_body("jelly")
    );
    let s = parse_in(&d.0, &text).unwrap().output.surface;
    assert_eq!(s.materials, [1, 0]);
    assert_eq!(
        (s.cube_size, s.threshold, s.smoothing_iters),
        (0.75, 0.5, 3)
    );
    let err =
        |extra: &str| parse_in(&d.0, &format!("{SCENE}{}{extra}", box_body("jelly"))).unwrap_err();
    let e = err("[surface]\nmaterials = [\"lava\"]\n");
    assert_eq!(e.field.as_deref(), Some("surface.materials[0]"));
    assert!(e.to_string().contains("\"jelly\""), "{e}");
    assert_eq!(
        err("[surface]\nthreshold = 1.2\n").field.as_deref(),
        Some("surface.threshold")
    );
    assert_eq!(
        err("[surface]\ncube_size = -1\n").field.as_deref(),
        Some("surface.cube_size")
    );
    assert!(
        err("[surface]\nsmoothing = 1\n")
            .to_string()
            .contains("unknown field")
    );
    // Surfaces asked for in a scene with no fluid and no materials named.
    let jelly_only = SCENE
        .replace(
            "type = \"fluid\"",
            "type = \"neo_hookean\"\nyoungs_modulus = 1e5\npoisson_ratio = 0.3",
        )
        .replace("bulk_modulus = 1e5\n", "");
    let e = parse_in(
        &d.0,
        &format!(
            "{jelly_only}{}[output]\nsurface = [\"ply\"]\n",
            box_body("jelly")
        ),
    )
    .unwrap_err();
    assert_eq!(e.field.as_deref(), Some("output.surface"));
    let e = parse_in(
        &d.0,
        &format!(
            "{SCENE}{}[output]\nformats = [\"bgeo.zip\"]\n",
            box_body("jelly")
        ),
    )
    .unwrap_err();
    assert!(e.to_string().contains("bgeo.gz"), "{e}");
}

/// A run's frame seeds a new run: particles from a PLY (volume from particles_per_cell) and a
/// BGEO (volume = mass / density), velocities from the file unless the body gives one.
#[test]
fn particles_body_from_frames() {
    let d = TestDir::new("scene-particles");
    // A first run's particles: sample a scene, give them velocities, write a frame.
    let first = parse_in(&d.0, &format!("{SCENE}{}", box_body("jelly"))).unwrap();
    let mut p = first.sample_particles().unwrap();
    for (i, v) in p.v.iter_mut().enumerate() {
        *v = Vec3::new(i as f32 * 1e-3, -1.0, 0.5);
    }
    write_ply(&d.path("seed.ply"), &p, &FrameFields::default()).unwrap();
    write_bgeo(&d.path("seed.bgeo.gz"), &p, &FrameFields::default(), true).unwrap();

    let body = |file: &str, extra: &str| {
        format!(
            "{SCENE}[[body]]\nmaterial = \"jelly\"\nshape = \"particles\"\nfile = \"{file}\"\n{extra}"
        )
    };
    let s = parse_in(&d.0, &body("seed.ply", "particles_per_cell = 27\n")).unwrap();
    let q = s.sample_particles().unwrap();
    assert_eq!(q.x, p.x);
    assert_eq!(q.v, p.v);
    let vol = 0.0625f32.powi(3) / 27.0;
    assert!(q.vol0.iter().all(|&v| v == vol));
    assert!(q.mass.iter().all(|&m| m == 500.0 * vol));
    assert!(q.material.iter().all(|&m| m == 1));

    let s = parse_in(&d.0, &body("seed.bgeo.gz", "")).unwrap();
    let q = s.sample_particles().unwrap();
    assert_eq!(q.x, p.x);
    assert_eq!(q.v, p.v);
    for (a, b) in q.vol0.iter().zip(&p.vol0) {
        assert!((a - b).abs() <= 1e-6 * b, "{a} vs {b}");
    }
    // A body velocity replaces the file's; translate moves the points.
    let s = parse_in(
        &d.0,
        &body(
            "seed.ply",
            "velocity = [1.0, 0.0, 0.0]\ntranslate = [0.1, 0.0, 0.0]\n",
        ),
    )
    .unwrap();
    let q = s.sample_particles().unwrap();
    assert!(q.v.iter().all(|v| *v == Vec3::X));
    assert!((q.x[0].x - p.x[0].x - 0.1).abs() < 1e-6);
}

#[test]
fn particles_body_errors() {
    let d = TestDir::new("scene-particles-bad");
    let mut p = rtmpm_physics::Particles::default();
    p.push(Vec3::splat(0.5), Vec3::ZERO, 1.0, 1e-4, 0, 0.0);
    p.push(Vec3::splat(0.99), Vec3::ZERO, 1.0, 1e-4, 0, 0.0);
    write_ply(&d.path("out.ply"), &p, &FrameFields::default()).unwrap();
    std::fs::write(d.path("trunc.bgeo"), b"BgeoV\0\0\0\x05\0\0").unwrap();
    let err = |extra: &str| {
        parse_in(
            &d.0,
            &format!("{SCENE}[[body]]\nmaterial = \"water\"\nshape = \"particles\"\n{extra}"),
        )
        .unwrap_err()
    };
    let e = err("");
    assert_eq!(e.field.as_deref(), Some("body[0].file"));
    let e = err("file = \"nope.vtu\"\n");
    assert!(e.to_string().contains("nope.vtu"), "{e}");
    let e = err("file = \"trunc.bgeo\"\n");
    assert!(
        e.to_string().contains("trunc.bgeo") && e.to_string().contains("truncated"),
        "{e}"
    );
    // A point inside the walls.
    let e = err("file = \"out.ply\"\n");
    assert!(e.to_string().contains("outside the domain"), "{e}");
    let e = err("file = \"out.ply\"\nsampling = \"random\"\n");
    assert_eq!(e.field.as_deref(), Some("body[0].sampling"));
    let e = err("file = \"out.ply\"\nradius = 1.0\n");
    assert_eq!(e.field.as_deref(), Some("body[0].radius"));
    let e = parse_in(
        &d.0,
        &format!(
            "{SCENE}{}[[collider]]\nshape = \"particles\"\nfile = \"out.ply\"\n",
            box_body("water")
        ),
    )
    .unwrap_err();
    assert!(e.to_string().contains("only a body"), "{e}");
}

/// A particles body in the sampling walk and the budget: its estimate is exact (the file's
/// point count), counting and sampling agree, and the file's velocities set the CFL step.
#[test]
fn particles_body_estimate_count_and_budget() {
    use crate::budget::Budget;
    use crate::sampling::{body_is_empty, count_body, estimate_body};
    let d = TestDir::new("scene-particles-budget");
    let first = parse_in(&d.0, &format!("{SCENE}{}", box_body("jelly"))).unwrap();
    let mut p = first.sample_particles().unwrap();
    let n = p.len();
    assert!(n > 100);
    write_ply(&d.path("still.ply"), &p, &FrameFields::default()).unwrap();
    p.v[7] = Vec3::new(0.0, -1000.0, 0.0);
    write_ply(&d.path("fast.ply"), &p, &FrameFields::default()).unwrap();
    let body = |file: &str| {
        format!("{SCENE}[[body]]\nmaterial = \"jelly\"\nshape = \"particles\"\nfile = \"{file}\"\n")
    };
    let still = parse_in(&d.0, &body("still.ply")).unwrap();
    assert_eq!(estimate_body(&still, 0), n as u64);
    assert_eq!(count_body(&still, 0).unwrap(), n as u64);
    assert!(!body_is_empty(&still, 0).unwrap());
    assert_eq!(still.sample_particles().unwrap().len(), n);
    let b = Budget::estimate(&still, Some(1));
    assert_eq!(
        (b.body_particles.as_slice(), b.particles),
        (&[n as u64][..], n as u64)
    );
    assert!(!b.dt_reason.contains("body[0]"), "{}", b.dt_reason);
    // 1000 m/s in the file, far above the jelly's sound speed: it sets the step.
    let fast = parse_in(&d.0, &body("fast.ply")).unwrap();
    let b = Budget::estimate(&fast, Some(1));
    assert!(b.dt_reason.contains("`body[0].file`"), "{}", b.dt_reason);
    assert!(b.dt < 0.4 * 0.0625 / 1000.0, "{}", b.dt);
    // The body's own velocity replaces the file's: the budget no longer sees 1000 m/s.
    let mut text = body("fast.ply");
    text.push_str("velocity = [0.0, 0.0, 0.0]\n");
    let b = Budget::estimate(&parse_in(&d.0, &text).unwrap(), Some(1));
    assert!(!b.dt_reason.contains("body[0]"), "{}", b.dt_reason);
}

/// The particles made from a file go through the value checks of `io::contents`: a volume
/// that is finite in the file but gives an infinite mass is an error naming the file.
#[test]
fn particles_body_values_are_checked() {
    let d = TestDir::new("scene-particles-values");
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float volume\nend_header\n".to_vec();
    for (x, vol) in [(0.5f32, 1e-4f32), (0.6, 1e37)] {
        for v in [x, 0.5, 0.5, vol] {
            ply.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(d.path("heavy.ply"), &ply).unwrap();
    let text = format!(
        "{SCENE}[[body]]\nmaterial = \"jelly\"\nshape = \"particles\"\nfile = \"heavy.ply\"\n"
    );
    let s = parse_in(&d.0, &text).unwrap();
    let e = s.sample_particles().unwrap_err();
    assert_eq!(e.field.as_deref(), Some("body[0]"));
    assert!(
        e.message.contains("heavy.ply")
            && e.message.contains("point 1")
            && e.message.contains("mass"),
        "{e}"
    );
}

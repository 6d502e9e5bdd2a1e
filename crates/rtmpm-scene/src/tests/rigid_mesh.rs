//! Scene tests of mesh rigid bodies (`[[rigid_body]] shape = "mesh"`): read, placed about their
//! centre of mass, and bad meshes refused on `file` with the reason and a fix.

use super::*;
use rtmpm_geometry::Shape;
use std::path::{Path, PathBuf};

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
"#;

/// The unit cube's corners and six outward quads (OBJ, 1-based).
const CUBE_V: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n";
const CUBE_F: [&str; 6] = [
    "f 1 4 3 2\n",
    "f 5 6 7 8\n",
    "f 1 2 6 5\n",
    "f 2 3 7 6\n",
    "f 3 4 8 7\n",
    "f 4 1 5 8\n",
];

/// A fresh folder for this test's files.
fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rtmpm-scene-mesh-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn write(d: &Path, name: &str, text: &str) -> PathBuf {
    let p = d.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

/// A scene with one mesh body of `file` (0.2 m cube at 0.6 .. 0.8) and `extra` lines.
fn scene(file: &Path, extra: &str) -> String {
    format!(
        "{BASE}[[rigid_body]]\nshape = \"mesh\"\nfile = \"{}\"\nscale = 0.2\n\
         translate = [0.6, 0.6, 0.6]\ndensity = 500.0\n{extra}",
        file.display()
    )
}

fn refused(text: &str, field: &str, says: &str) -> SceneError {
    let e = Scene::from_toml(text, "test.toml").expect_err(says);
    assert_eq!(e.field.as_deref(), Some(field), "{e}");
    assert!(e.message.contains(says), "`{says}` not in: {e}");
    assert!(e.hint.is_some() && e.line.is_some(), "{e}");
    e
}

#[test]
fn a_cube_mesh_body_is_placed_at_its_centre_of_mass_with_the_box_s_mass() {
    let d = dir("ok");
    let cube = write(&d, "cube.obj", &format!("{CUBE_V}{}", CUBE_F.concat()));
    let s = Scene::from_toml(&scene(&cube, "convex = true\n"), "test.toml")
        .unwrap_or_else(|e| panic!("{e}"));
    let b = &s.rigid_bodies[0];
    assert!(
        (b.position - Vec3::splat(0.7)).length() < 1e-6,
        "{}",
        b.position
    );
    assert!((b.mass - 500.0 * 0.008).abs() < 1e-5 * b.mass, "{}", b.mass);
    let Shape::Mesh(m) = &b.shape else {
        panic!("a mesh")
    };
    assert!(m.solid.as_ref().is_some_and(|s| s.convex));
    // Centred: the body's shape answers like the box about the origin (near the faces, where
    // the interpolated grid is exact; deep inside it rounds the box's medial kinks by O(h)).
    assert!(b.shape.distance(Vec3::ZERO) < -0.05);
    let top = b.shape.distance(Vec3::new(0.02, 0.09, 0.01));
    assert!((top + 0.01).abs() < 1e-3, "{top}");
    assert!(b.shape.distance(Vec3::new(0.0, 0.12, 0.0)) > 0.0);
    assert!((b.shape.half_extents(glam::Mat3::IDENTITY) - Vec3::splat(0.1)).length() < 1e-6);
    // A rotation turns it about its centre: by 0.7 rad about y its corners reach 0.7 + 0.141
    // on x, inside the walls' 0.8125 no more (3 cells of 0.0625 m).
    let turned = format!("{}rotation = [0.0, 0.7, 0.0]\n", scene(&cube, ""));
    refused(&turned, "rigid_body[0].shape", "outside the domain");
    let turned = format!("{}rotation = [0.0, 0.05, 0.0]\n", scene(&cube, ""));
    assert!(Scene::from_toml(&turned, "test.toml").is_ok());
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn bad_mesh_bodies_are_refused_on_their_file_with_a_fix() {
    let d = dir("bad");
    let cube = write(&d, "cube.obj", &format!("{CUBE_V}{}", CUBE_F.concat()));
    // Missing file.
    refused(
        &scene(&d.join("missing.obj"), ""),
        "rigid_body[0].file",
        "cannot read mesh file",
    );
    // Open: the top face missing.
    let open = write(&d, "open.obj", &format!("{CUBE_V}{}", CUBE_F[..5].concat()));
    let e = refused(&scene(&open, ""), "rigid_body[0].file", "not closed");
    assert!(e.message.contains("open.obj"), "{e}");
    // Inverted normals: every face wound the other way.
    let flipped: String = CUBE_F
        .iter()
        .map(|f| {
            let mut v: Vec<&str> = f.split_whitespace().skip(1).collect();
            v.reverse();
            format!("f {}\n", v.join(" "))
        })
        .collect();
    let inv = write(&d, "inverted.obj", &format!("{CUBE_V}{flipped}"));
    refused(&scene(&inv, ""), "rigid_body[0].file", "inverted normals");
    // Zero volume: a triangle and its back side.
    let flat = write(
        &d,
        "flat.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n",
    );
    refused(&scene(&flat, ""), "rigid_body[0].file", "no volume");
    // Non-manifold: a second cube sharing an edge with the first... simplest, a face twice.
    let twice = write(
        &d,
        "twice.obj",
        &format!("{CUBE_V}{}{}", CUBE_F.concat(), CUBE_F[0]),
    );
    refused(&scene(&twice, ""), "rigid_body[0].file", "not a manifold");
    // convex = true on a mesh that is not convex: the cube with its top dented in.
    let dent = format!(
        "{CUBE_V}v 0.5 0.6 0.5\n{}f 4 9 3\nf 3 9 7\nf 7 9 8\nf 8 9 4\n",
        [0, 1, 2, 3, 5].map(|k| CUBE_F[k]).concat()
    );
    let dent = write(&d, "dent.obj", &dent);
    assert!(Scene::from_toml(&scene(&dent, ""), "test.toml").is_ok());
    refused(
        &scene(&dent, "convex = true\n"),
        "rigid_body[0].file",
        "not convex",
    );
    // Too many triangles for a body.
    let mut big = String::from(CUBE_V);
    for _ in 0..=rtmpm_geometry::MAX_BODY_TRIANGLES {
        big.push_str("f 1 2 3\n");
    }
    let big = write(&d, "big.obj", &big);
    refused(&scene(&big, ""), "rigid_body[0].file", "more than the");
    // `convex` belongs to mesh bodies only.
    let text = format!(
        "{BASE}[[rigid_body]]\nshape = \"sphere\"\ncenter = [0.7, 0.7, 0.7]\nradius = 0.1\n\
         density = 500.0\nconvex = true\n"
    );
    refused(&text, "rigid_body[0].convex", "not a parameter");
    // Fields of other shapes are refused on a mesh body.
    refused(
        &scene(&cube, "radius = 0.1\n"),
        "rigid_body[0].radius",
        "not a parameter",
    );
    std::fs::remove_dir_all(&d).ok();
}

/// A turned cube mesh body answers the coupling's queries as the box body of the same size,
/// place and rotation: the mesh is turned about its centre of mass as the box about its centre.
/// At points more than a grid spacing (dx / 2) from the surface: the same inside or outside,
/// and inside, the same velocity and, away from the box's medial kinks, the same face normal
/// within 0.05.
#[test]
fn a_turned_cube_mesh_body_answers_as_the_turned_box_body() {
    use rtmpm_rigid::BodyState;
    let d = dir("turned");
    let cube = write(&d, "cube.obj", &format!("{CUBE_V}{}", CUBE_F.concat()));
    let turn = "rotation = [0.3, -0.5, 0.2]\n";
    // Both about (0.5, 0.5, 0.5): turned, their corners need more room than at 0.7.
    let text =
        scene(&cube, turn).replace("translate = [0.6, 0.6, 0.6]", "translate = [0.4, 0.4, 0.4]");
    // At dx = 0.02 m the grid (spacing 0.01 m) resolves the 0.2 m cube by 20 spacings.
    let fine = |t: &str| t.replace("dx = 0.0625", "dx = 0.02");
    let mesh = Scene::from_toml(&fine(&text), "test.toml").unwrap_or_else(|e| panic!("{e}"));
    let boxed = Scene::from_toml(
        &fine(&format!(
            "{BASE}[[rigid_body]]\nshape = \"box\"\nmin = [0.4, 0.4, 0.4]\nmax = [0.6, 0.6, 0.6]\n\
             density = 500.0\n{turn}"
        )),
        "test.toml",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let state = |s: &Scene| {
        let b = &s.rigid_bodies[0];
        BodyState {
            shape: b.shape.clone(),
            rotation: glam::Mat3::from_quat(b.rotation),
            center: b.position,
            velocity: Vec3::new(0.1, 0.0, 0.0),
            angular_velocity: Vec3::new(0.0, 2.0, 0.0),
            dynamic: true,
            condition: b.condition,
            friction: b.friction,
        }
    };
    let (m, b) = (state(&mesh), state(&boxed));
    assert!((m.center - b.center).length() < 1e-6);
    assert!((m.rotation.x_axis - b.rotation.x_axis).length() < 1e-6);
    let h = 0.5 * mesh.dx;
    let mut seed = 7u32;
    let mut rnd = || {
        seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
        (seed >> 8) as f32 / (1u32 << 24) as f32
    };
    let (mut inside, mut compared) = (0, 0);
    for _ in 0..4000 {
        let x = b.center + (Vec3::new(rnd(), rnd(), rnd()) - 0.5) * 0.3;
        let p = b.rotation.transpose() * (x - b.center);
        let exact = b.shape.distance(p);
        if exact.abs() < h {
            continue;
        }
        let (qm, qb) = (m.query(x), b.query(x));
        assert_eq!(qm.is_some(), qb.is_some(), "at {x}: box distance {exact}");
        if let (Some((nm, vm)), Some((nb, vb))) = (qm, qb) {
            inside += 1;
            assert!((vm - vb).length() < 1e-5, "velocity at {x}");
            // Away from the box's medial kinks: the nearest face nearer than the next by more than
            // the reach of the grid's normal (the trilinear cell, one spacing h, and the central
            // difference, h / 2).
            let q = (p.abs() - Vec3::splat(0.1)).to_array();
            let mut s = q;
            s.sort_by(|a, b| b.total_cmp(a));
            if s[0] - s[1] > 1.5 * h {
                compared += 1;
                assert!((nm - nb).length() < 0.05, "normal at {x}: {nm} vs {nb}");
            }
        }
    }
    println!("{inside} inside, {compared} normals compared");
    assert!(
        inside > 300 && compared > 100,
        "{inside} inside, {compared} compared"
    );
    std::fs::remove_dir_all(&d).ok();
}

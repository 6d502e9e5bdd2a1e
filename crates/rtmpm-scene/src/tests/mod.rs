//! Scene parsing, validation and sampling tests.

use crate::*;
use rtmpm_physics::boundary::Condition;
use rtmpm_physics::material::{Cone, Eos, Model};
use rtmpm_physics::math::Vec3;
use std::path::{Path, PathBuf};

mod io;
mod motion;
mod rigid_mesh;
mod sampling;
mod settings;

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

const BASE: &str = r#"name = "t"
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.0625
[time]
duration = 1.0
fps = 24
[[material]]
name = "jelly"
type = "fixed_corotated"
density = 1000.0
youngs_modulus = 1e5
poisson_ratio = 0.3
[[body]]
material = "jelly"
shape = "box"
min = [0.25, 0.25, 0.25]
max = [0.5, 0.5, 0.5]
"#;

fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::from_toml(text, "test.toml")
}

/// Parse `BASE` with `from` replaced by `to`, expecting an error on `field`.
fn expect_err(from: &str, to: &str, field: &str) -> SceneError {
    assert!(BASE.contains(from), "{from}");
    let text = BASE.replacen(from, to, 1);
    let e = parse(&text).expect_err(&format!("{to} should fail"));
    assert_eq!(e.field.as_deref(), Some(field), "{e}");
    assert!(e.hint.is_some(), "{e}");
    assert!(e.line.is_some(), "no line: {e}");
    e
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn example_scenes_validate() {
    let mut n = 0;
    for entry in std::fs::read_dir(scenes_dir()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        // Every world of a batch (`[batch]`), the scene alone otherwise.
        let batch = crate::BatchScene::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
        let particles: usize = batch
            .worlds
            .iter()
            .map(|s| s.sample_particles().unwrap().len())
            .sum();
        assert!(
            (5_000..=150_000).contains(&particles),
            "{}: {particles} particles",
            path.display()
        );
        n += 1;
    }
    assert!(n >= 6, "found {n} scenes");
}

#[test]
fn bench_scene_matches_spec() {
    let s = Scene::from_file(&scenes_dir().join("bench_fluid_n64.toml")).unwrap();
    let p = s.sample_particles().unwrap();
    assert_eq!(p.len(), 65536);
    assert_eq!(s.n_cells(), [64, 64, 64]);
    assert_eq!(s.time.step, StepMode::Fixed { dt: 2e-4 });
    assert!(
        matches!(&s.materials[0].model, Model::Fluid(f) if f.eos == Eos::Linear && f.bulk_modulus == 400.0)
    );
    let (lo, hi) = p.bounding_box();
    assert!(lo.min_element() >= 0.15 && hi.max_element() <= 0.55);
    let vol = 0.4f32.powi(3) / 65536.0;
    assert!((p.vol0[0] - vol).abs() < 1e-3 * vol);
}

#[test]
fn defaults() {
    let s = parse(BASE).unwrap();
    assert_eq!(s.gravity, Vec3::new(0.0, -9.81, 0.0));
    let StepMode::Cfl {
        cfl,
        max_dt,
        min_dt,
    } = s.time.step
    else {
        panic!("{:?}", s.time.step)
    };
    assert_eq!((cfl, max_dt), (0.4, 1e-3));
    assert!(min_dt > 0.0 && min_dt <= 1.001e-6, "{min_dt}");
    assert_eq!(s.walls.thickness, 3);
    assert_eq!(s.walls.faces[0].condition, Condition::Separate);
    assert_eq!(s.output.dir, PathBuf::from("out/t"));
    assert!(s.output.writes("ply") && !s.output.writes("vtu"));
    assert_eq!(s.bodies[0].particles_per_cell, 8);
    assert_eq!(s.bodies[0].sampling, Sampling::Jittered);
    assert_eq!(s.n_cells(), [16, 16, 16]);
}

#[test]
fn wall_face_overrides() {
    let text = format!(
        "{BASE}[walls]\ncondition = \"slip\"\nfriction = 0.5\n[walls.faces.y_min]\ncondition = \"sticky\"\n"
    );
    let s = parse(&text).unwrap();
    assert_eq!(s.walls.faces[2].condition, Condition::Sticky);
    assert_eq!(s.walls.faces[2].friction, 0.5);
    assert_eq!(s.walls.faces[3].condition, Condition::Slip);
}

#[test]
fn syntax_error_position() {
    let text = BASE.replacen("fps = 24", "fps = = 24", 1);
    let e = parse(&text).unwrap_err();
    assert_eq!(e.line, Some(line_of(&text, "fps = = 24")), "{e}");
    assert_eq!(e.column, Some(7), "{e}");
}

#[test]
fn unknown_field_named() {
    let text = BASE.replacen(
        "poisson_ratio = 0.3",
        "poisson_ratio = 0.3\npoisson_ration = 0.3",
        1,
    );
    let e = parse(&text).unwrap_err();
    assert_eq!(
        e.field.as_deref(),
        Some("material[0].poisson_ration"),
        "{e}"
    );
    assert_eq!(e.line, Some(line_of(&text, "poisson_ration")), "{e}");
    assert_eq!(e.column, Some(1));
    let text = format!("{BASE}[walls]\nthicknes = 3\n");
    let e = parse(&text).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("walls.thicknes"), "{e}");
}

#[test]
fn type_error_named() {
    let text = BASE.replacen("density = 1000.0", "density = \"heavy\"", 1);
    let e = parse(&text).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("material[0].density"), "{e}");
    assert_eq!(e.line, Some(line_of(&text, "heavy")));
    let text = BASE.replacen("shape = \"box\"", "shape = \"cube\"", 1);
    let e = parse(&text).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("body[0].shape"), "{e}");
}

#[test]
fn missing_field_named() {
    let text = BASE.replacen("duration = 1.0\n", "", 1);
    let e = parse(&text).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("time.duration"), "{e}");
}

#[test]
fn impossible_values() {
    let e = expect_err("dx = 0.0625", "dx = 0.0", "domain.dx");
    assert_eq!(e.line, Some(5));
    expect_err("dx = 0.0625", "dx = -1.0", "domain.dx");
    expect_err(
        "max = [1.0, 1.0, 1.0]",
        "max = [1.0, 0.0, 1.0]",
        "domain.max[1]",
    );
    let e = expect_err(
        "max = [1.0, 1.0, 1.0]",
        "max = [1.0, 1.0, 1.03]",
        "domain.max[2]",
    );
    assert!(e.hint.unwrap().contains("domain.max[2] = 1 "));
    let e = expect_err("density = 1000.0", "density = 0.0", "material[0].density");
    assert_eq!(e.line, Some(line_of(BASE, "density")));
    expect_err(
        "youngs_modulus = 1e5",
        "youngs_modulus = -1e5",
        "material[0].youngs_modulus",
    );
    let e = expect_err(
        "poisson_ratio = 0.3",
        "poisson_ratio = 0.5",
        "material[0].poisson_ratio",
    );
    assert_eq!(e.line, Some(line_of(BASE, "poisson_ratio")));
    assert!(e.hint.unwrap().contains("fluid"));
    expect_err(
        "poisson_ratio = 0.3",
        "poisson_ratio = -1.0",
        "material[0].poisson_ratio",
    );
    expect_err("youngs_modulus = 1e5\n", "", "material[0].youngs_modulus");
    let e = expect_err(
        "material = \"jelly\"",
        "material = \"jely\"",
        "body[0].material",
    );
    assert!(e.hint.unwrap().contains("\"jelly\""));
    expect_err("duration = 1.0", "duration = 0.0", "time.duration");
    expect_err("fps = 24", "fps = -24", "time.fps");
    expect_err("fps = 24", "fps = 24\ndt = 0.0", "time.dt");
    expect_err("fps = 24", "fps = 24\ncfl = 1.5", "time.cfl");
    expect_err("fps = 24", "fps = 24\ncfl = 0.0", "time.cfl");
    expect_err(
        "shape = \"box\"",
        "shape = \"box\"\nparticles_per_cell = 0",
        "body[0].particles_per_cell",
    );
    // Outside the domain / inside the walls (walls: 3 cells = 0.1875).
    let e = expect_err(
        "min = [0.25, 0.25, 0.25]",
        "min = [0.1, 0.25, 0.25]",
        "body[0].shape",
    );
    assert!(e.hint.unwrap().contains("0.1875"));
    expect_err(
        "max = [0.5, 0.5, 0.5]",
        "max = [0.5, 1.5, 0.5]",
        "body[0].shape",
    );
    // A body smaller than the particle spacing produces no particles.
    expect_err(
        "max = [0.5, 0.5, 0.5]",
        "max = [0.251, 0.251, 0.251]",
        "body[0]",
    );
}

fn fluid(extra: &str) -> String {
    BASE.replacen(
        "type = \"fixed_corotated\"\ndensity = 1000.0\nyoungs_modulus = 1e5\npoisson_ratio = 0.3",
        &format!("type = \"fluid\"\ndensity = 1000.0\n{extra}"),
        1,
    )
}

fn parse_err(text: &str, field: &str) -> SceneError {
    let e = parse(text).expect_err("should fail");
    assert_eq!(e.field.as_deref(), Some(field), "{e}");
    assert!(e.line.is_some(), "{e}");
    e
}

#[test]
fn material_values() {
    let s = parse(&fluid("bulk_modulus = 1e5\ngamma = 7.0\nviscosity = 0.1")).unwrap();
    assert!(matches!(&s.materials[0].model, Model::Fluid(f) if f.eos == Eos::Tait { gamma: 7.0 }));
    let s = parse(&fluid("bulk_modulus = 1e5")).unwrap();
    assert!(matches!(&s.materials[0].model, Model::Fluid(f) if f.eos == Eos::Linear));
    parse_err(&fluid("bulk_modulus = 0.0"), "material[0].bulk_modulus");
    parse_err(
        &fluid("bulk_modulus = 1e5\nviscosity = -1.0"),
        "material[0].viscosity",
    );
    parse_err(
        &fluid("bulk_modulus = 1e5\nfriction_angle = 30.0"),
        "material[0].friction_angle",
    );
    parse_err(
        &fluid("bulk_modulus = 1e5\neos = \"linear\"\ngamma = 7.0"),
        "material[0].gamma",
    );
    let sand = |extra: &str| {
        BASE.replacen(
            "type = \"fixed_corotated\"",
            &format!("type = \"drucker_prager\"\n{extra}"),
            1,
        )
    };
    let s = parse(&sand("")).unwrap();
    assert!(
        matches!(&s.materials[0].model, Model::DruckerPrager(d) if d.friction_angle == 30.0 && d.cohesion == 0.0 && d.cone == Cone::Compression)
    );
    let s = parse(&sand("cone = \"plane_strain\"")).unwrap();
    assert!(
        matches!(&s.materials[0].model, Model::DruckerPrager(d) if d.cone == Cone::PlaneStrain)
    );
    parse_err(&sand("cone = \"triaxial\""), "material[0].cone");
    parse_err(
        &fluid("bulk_modulus = 1e5\ncone = \"plane_strain\""),
        "material[0].cone",
    );
    parse_err(&sand("friction_angle = 90.0"), "material[0].friction_angle");
    parse_err(&sand("friction_angle = -1.0"), "material[0].friction_angle");
    parse_err(&sand("cohesion = -0.1"), "material[0].cohesion");
    let snow = BASE.replacen("type = \"fixed_corotated\"", "type = \"snow\"", 1);
    let s = parse(&snow).unwrap();
    assert!(
        matches!(&s.materials[0].model, Model::Snow(m) if m.hardening == 10.0 && m.critical_compression == 2.5e-2)
    );
    assert_eq!(s.materials[0].model.initial_plastic(), 1.0);
    let vm = BASE.replacen(
        "type = \"fixed_corotated\"",
        "type = \"von_mises\"\nyield_stress = 1e4",
        1,
    );
    assert!(
        matches!(&parse(&vm).unwrap().materials[0].model, Model::VonMises(m) if m.yield_stress == 1e4)
    );
    let lame = BASE.replacen(
        "youngs_modulus = 1e5\npoisson_ratio = 0.3",
        "mu = 1e5\nlambda = 2e5",
        1,
    );
    assert!(
        matches!(&parse(&lame).unwrap().materials[0].model, Model::FixedCorotated(m) if m.mu == 1e5 && m.lambda == 2e5)
    );
    parse_err(
        &format!("{BASE}[walls]\nfriction = -0.5\n"),
        "walls.friction",
    );
}

#[test]
fn colliders() {
    let text = format!(
        "{BASE}[[collider]]\nshape = \"half_space\"\npoint = [0.0, 0.2, 0.0]\nnormal = [0.0, 2.0, 0.0]\n\
         [[collider]]\nshape = \"box\"\nmin = [0.6, 0.2, 0.2]\nmax = [0.8, 0.4, 0.4]\nvelocity = [1.0, 0.0, 0.0]\nfriction = 0.3\n"
    );
    let s = parse(&text).unwrap();
    assert_eq!(s.colliders.len(), 2);
    assert!(
        matches!(s.colliders[0].shape, rtmpm_geometry::Shape::HalfSpace(h) if h.normal == Vec3::Y)
    );
    assert!((s.colliders[1].pivot - Vec3::new(0.7, 0.3, 0.3)).length() < 1e-6);
    let bad = text.replacen("normal = [0.0, 2.0, 0.0]", "normal = [0.0, 0.0, 0.0]", 1);
    let e = parse_err(&bad, "collider[0].normal");
    assert_eq!(e.line, Some(line_of(&bad, "normal = [0.0, 0.0, 0.0]")));
    parse_err(
        &text.replacen("friction = 0.3", "friction = -0.3", 1),
        "collider[1].friction",
    );
    parse_err(
        &text.replacen("min = [0.6, 0.2, 0.2]", "radius = 0.1", 1),
        "collider[1].radius",
    );
}

#[test]
fn mesh_errors() {
    let text = format!("{BASE}[[collider]]\nshape = \"mesh\"\nfile = \"does/not/exist.obj\"\n");
    let e = parse_err(&text, "collider[0].file");
    assert!(e.message.contains("does/not/exist.obj"), "{e}");
    let dir = std::env::temp_dir().join(format!("rtmpm-scene-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("empty.obj"), "# empty\n").unwrap();
    let text = format!("{BASE}[[collider]]\nshape = \"mesh\"\nfile = \"empty.obj\"\n");
    let e = Scene::from_toml_in(&text, "t", &dir).unwrap_err();
    assert_eq!(e.field.as_deref(), Some("collider[0].file"));
    assert!(e.message.contains("no triangles"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mesh_body() {
    let text = BASE.replacen(
        "shape = \"box\"\nmin = [0.25, 0.25, 0.25]\nmax = [0.5, 0.5, 0.5]",
        "shape = \"mesh\"\nfile = \"meshes/blob.obj\"\nscale = 0.2\ntranslate = [0.5, 0.5, 0.5]",
        1,
    );
    let s = Scene::from_toml_in(&text, "t", &scenes_dir()).unwrap();
    let p = s.sample_particles().unwrap();
    let vol = s.bodies[0].shape.volume();
    // Roughly the blob's volume (~4/3 pi 0.2^3 ~ 0.0335) filled at 8 per cell of 0.0625^3.
    assert!(vol > 0.02 && vol < 0.05, "{vol}");
    let expect = vol / (0.0625f32.powi(3) / 8.0);
    assert!(
        (p.len() as f32 - expect).abs() < 0.15 * expect,
        "{} vs {expect}",
        p.len()
    );
}

#[test]
fn regular_box_counts() {
    let text = BASE.replacen(
        "shape = \"box\"",
        "shape = \"box\"\nsampling = \"regular\"",
        1,
    );
    let s = parse(&text).unwrap();
    let p = s.sample_particles().unwrap();
    // 0.25^3 box = 4^3 cells, 8 per cell.
    assert_eq!(p.len(), 8 * 64);
    let vol = 0.0625f32.powi(3) / 8.0;
    assert!((p.vol0[0] - vol).abs() < 1e-9);
    assert!((p.mass[0] - 1000.0 * vol).abs() < 1e-6);
    assert!(p.plastic.iter().all(|&q| q == 0.0));
    // Sub-cell centres of the global grid.
    let h = 0.0625 / 2.0;
    for x in &p.x {
        let g = *x / h - 0.5;
        assert!((g - g.round()).abs().max_element() < 1e-3, "{x}");
    }
    let ppc27 = text.replacen(
        "sampling = \"regular\"",
        "sampling = \"regular\"\nparticles_per_cell = 27",
        1,
    );
    assert_eq!(
        parse(&ppc27).unwrap().sample_particles().unwrap().len(),
        27 * 64
    );
}

#[test]
fn adjacent_bodies_tile() {
    let text = format!(
        "{}[[body]]\nmaterial = \"jelly\"\nshape = \"box\"\nsampling = \"regular\"\nmin = [0.5, 0.25, 0.25]\nmax = [0.75, 0.5, 0.5]\n",
        BASE.replacen(
            "shape = \"box\"",
            "shape = \"box\"\nsampling = \"regular\"",
            1
        )
    );
    let p = parse(&text).unwrap().sample_particles().unwrap();
    assert_eq!(p.len(), 2 * 8 * 64);
    let mut xs: Vec<[i64; 3]> =
        p.x.iter()
            .map(|x| (*x * 1e5).round().as_i64vec3().to_array())
            .collect();
    xs.sort();
    xs.dedup();
    assert_eq!(xs.len(), p.len(), "duplicate particles on the shared face");
}

#[test]
fn sampling_determinism() {
    let a = parse(BASE).unwrap().sample_particles().unwrap();
    let b = parse(BASE).unwrap().sample_particles().unwrap();
    assert_eq!(a, b);
    let c = parse(&format!("seed = 7\n{BASE}"))
        .unwrap()
        .sample_particles()
        .unwrap();
    assert_ne!(a.x, c.x);
    let random = BASE.replacen(
        "shape = \"box\"",
        "shape = \"box\"\nsampling = \"random\"",
        1,
    );
    let r1 = parse(&random).unwrap().sample_particles().unwrap();
    let r2 = parse(&random).unwrap().sample_particles().unwrap();
    assert_eq!(r1, r2);
    assert_eq!(r1.len(), 8 * 64);
}

#[test]
fn sphere_and_cylinder_sampling() {
    let sphere = BASE.replacen(
        "min = [0.25, 0.25, 0.25]\nmax = [0.5, 0.5, 0.5]",
        "center = [0.5, 0.5, 0.5]\nradius = 0.25\nangular_velocity = [0.0, 0.0, 2.0]\nvelocity = [1.0, 0.0, 0.0]",
        1,
    )
    .replacen("shape = \"box\"", "shape = \"sphere\"", 1);
    let s = parse(&sphere).unwrap();
    let p = s.sample_particles().unwrap();
    let expect = 4.0 / 3.0 * std::f32::consts::PI * 0.25f32.powi(3) / (0.0625f32.powi(3) / 8.0);
    assert!(
        (p.len() as f32 - expect).abs() < 0.05 * expect,
        "{}",
        p.len()
    );
    for (x, v) in p.x.iter().zip(&p.v) {
        assert!((*x - Vec3::splat(0.5)).length() <= 0.25 + 1e-5);
        let want = Vec3::X + Vec3::new(0.0, 0.0, 2.0).cross(*x - Vec3::splat(0.5));
        assert!((*v - want).length() < 0.01, "{v} vs {want}");
    }
    let cyl = BASE
        .replacen(
            "min = [0.25, 0.25, 0.25]\nmax = [0.5, 0.5, 0.5]",
            "center = [0.5, 0.5, 0.5]\naxis = [1.0, 1.0, 0.0]\nradius = 0.1\nheight = 0.4",
            1,
        )
        .replacen("shape = \"box\"", "shape = \"cylinder\"", 1);
    let p = parse(&cyl).unwrap().sample_particles().unwrap();
    let expect = std::f32::consts::PI * 0.01 * 0.4 / (0.0625f32.powi(3) / 8.0);
    assert!(
        (p.len() as f32 - expect).abs() < 0.1 * expect,
        "{} vs {expect}",
        p.len()
    );
    let e = parse_err(
        &cyl.replacen("axis = [1.0, 1.0, 0.0]", "axis = [0.0, 0.0, 0.0]", 1),
        "body[0].axis",
    );
    assert_eq!(e.line, Some(line_of(&cyl, "axis")));
}

#[test]
fn error_display() {
    let e = expect_err("density = 1000.0", "density = -5.0", "material[0].density");
    let s = e.to_string();
    assert!(
        s.starts_with(&format!(
            "test.toml:{}:1: field `material[0].density`",
            line_of(BASE, "density")
        )),
        "{s}"
    );
    assert!(s.contains("fix:"));
}

#[test]
fn never_panics_on_garbage() {
    for text in [
        "",
        "[[[",
        "domain = 3",
        "[domain]\nmin = [1]\n",
        "name = \"\u{1F600}\"\n[time]\nduration = nan\n",
        "\u{0}",
    ] {
        assert!(parse(text).is_err());
    }
    let nan = BASE.replacen("duration = 1.0", "duration = nan", 1);
    parse_err(&nan, "time.duration");
}

#[test]
fn doc_example_validates() {
    let doc = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/scene-format.md"),
    )
    .unwrap();
    let start = doc.find("## Example").unwrap();
    let block = &doc[start..];
    let a = block.find("```toml\n").unwrap() + 8;
    let b = a + block[a..].find("```").unwrap();
    let s = parse(&block[a..b]).unwrap();
    assert_eq!(s.colliders.len(), 1);
}

//! Rigid bodies coupled two ways to the material on the CPU backend (cargo feature `rigid`):
//! the rigid-body and emitter validation checks at the quick resolution of `rtmpm validate`, on the same scenes
//! (`validation/*.toml`) and measurements (`rtmpm_driver::checks`).
#![cfg(feature = "rigid")]

mod common;

use common::cpu::CpuBackend;
use rtmpm_driver::{Simulation, checks};
use rtmpm_scene::Scene;

const ARCHIMEDES: &str = include_str!("../../../validation/archimedes.toml");
const SINKING: &str = include_str!("../../../validation/sinking.toml");
const MOMENTUM: &str = include_str!("../../../validation/rigid_momentum.toml");

fn simulation(text: &str) -> Simulation<CpuBackend> {
    let scene = Scene::from_toml(text, "test").unwrap_or_else(|e| panic!("{e}"));
    let p = scene.sample_particles().expect("particles");
    let backend = CpuBackend::new(&scene, p, None).expect("backend");
    Simulation::<CpuBackend>::with_backend(scene, Box::new(backend))
}

/// Archimedes: boxes of density 500 and 750 on water float with the submerged fraction of their
/// height, and of their volume in the pose of each of the last frames, equal to the density
/// ratio within 5 % (the tolerance of the validation case; the box rocks by about 12 degrees at this resolution, so the two
/// differ: volume 0.491 and 0.761). Measured at dx = 0.02 m (the box is 5 cells high), its
/// draft below the open water's surface in each frame from 1.0 to 1.5 s, averaged (the box and
/// the water still bob by a few mm): 0.491 and 0.756 of its height (-1.8 %, +0.8 %; with the
/// surface of the last frame alone, 0.494 and 0.753, and over four alignments of the water
/// surface with the grid at most 2.5 % and 2.9 % off). The CPU backend is deterministic (any
/// thread count), so the margin to the bound is not noise. The density-250 box is not checked
/// here: its draft of 2.5 cm is 1.25 cells at this resolution, and a node-based boundary places
/// the box to about 0.1 to 0.2 dx, so it floats 0.9 to 17.6 % off over those alignments (-6.9 % in
/// this scene); `rtmpm validate` checks it, with the others, at dx / 4 (validation/RESULTS.md,
/// "Rigid bodies and emitters"). Until 2026-11-26 this test also passed the 250 box, with a
/// surface measure (the 98th percentile of all heights) that the walls' rim of water raised.
#[test]
fn boxes_float_with_the_submerged_fraction_of_archimedes() {
    for density in [500.0, 750.0] {
        let text =
            checks::edit_toml(ARCHIMEDES, &[("rigid_body.0.density", density.into())]).unwrap();
        let f = checks::float(&mut simulation(&text), |_, _| {}).expect("stable");
        let expect = density / 1000.0;
        let volume = f.volume_fraction.expect("a box");
        println!(
            "density {density}: submerged fraction {:.3} of its height, {volume:.3} of its \
             volume (Archimedes {expect}; mean tilt {:.1} deg), centre {:.4} m, surface {:.4} m",
            f.fraction, f.mean_tilt_degrees, f.centre, f.surface
        );
        assert!(
            (f.fraction / expect - 1.0).abs() < 0.05,
            "density {density}: submerged fraction {}, expected {expect}",
            f.fraction
        );
        assert!(
            (volume / expect - 1.0).abs() < 0.05,
            "density {density}: submerged volume fraction {volume}, expected {expect}"
        );
    }
}

/// Zero gravity, no walls reached: a jelly ball thrown at a free box. The grid gives the box
/// exactly the momentum its rule takes from the nodes, so the material's momentum plus the
/// box's is conserved, and the box is pushed along the throw.
#[test]
fn momentum_of_material_plus_body_is_conserved() {
    let c = checks::collide(&mut simulation(MOMENTUM)).expect("stable");
    println!(
        "momentum: start {}, material {} + box {}; box speed {:.4} m/s, elastic estimate {:.4} \
         m/s ({:.3})",
        c.start,
        c.material,
        c.body,
        c.body_speed,
        c.elastic,
        c.body_speed / c.elastic
    );
    // The elastic-collision estimate 2 m1 v / (m1 + m2) is an upper bound (the ball keeps some
    // energy as vibration): measured 0.91 of it; the validation case asks within 10 %.
    let ratio = c.body_speed / c.elastic;
    assert!(
        (ratio - 1.0).abs() < 0.1,
        "box speed {ratio} of the elastic estimate"
    );
    assert!(c.momentum_error() < 0.01, "momentum error {c:?}");
}

/// Sinking and floating: in one tank of water, a sphere of density 2,500 reaches the floor and
/// one of 500 floats (its centre stays above the water's surface minus a radius).
#[test]
fn a_heavy_sphere_sinks_to_the_floor_and_a_light_one_floats() {
    let s = checks::settle(&mut simulation(SINKING)).expect("stable");
    let (heavy, light) = (s[0].center.y, s[1].center.y);
    println!("heavy sphere centre {heavy:.4} m, light {light:.4} m (floor 0.06, surface ~0.26)");
    // On the floor (the domain minus the walls starts at 0.06): within a cell.
    assert!(heavy - 0.045 < 0.06 + 0.02, "heavy sphere at {heavy}");
    // Floating: half submerged puts the centre at the surface (~0.26); sinking would not.
    assert!(light > 0.26 - 0.045, "light sphere at {light}");
}

/// `checks::refine` halves dx and doubles the walls' cells: the interior stays where it was.
#[test]
fn refined_validation_scenes_keep_their_walls_in_metres() {
    for text in [ARCHIMEDES, SINKING, MOMENTUM] {
        let a = Scene::from_toml(text, "a").unwrap();
        let b = Scene::from_toml(&checks::refine(text, 2).unwrap(), "b").unwrap();
        assert_eq!(b.dx, a.dx / 2.0);
        let (ia, ib) = (a.interior(), b.interior());
        assert!((ia.0 - ib.0).length() < 1e-6 && (ia.1 - ib.1).length() < 1e-6);
        assert_eq!(a.rigid_bodies, b.rigid_bodies);
    }
}

/// A cylinder of density 500 (radius 0.05 m, 0.16 m long) lying along x on the water of the
/// Archimedes scene floats half submerged: by the symmetry of its circular section about the
/// axis, a lying cylinder of half the water's density floats with the axis at the surface, so
/// the submerged fraction of its height (its diameter) is 0.5 as for a box, within 5 %. Lying
/// rather than standing: the water then pushes on the curved side (the cylinder's own distance
/// and normals, not a box-like cap), the `axis` field turns the body (local y onto x), and a
/// lying cylinder is stable however long it is, where a standing one tips over unless its
/// radius exceeds sqrt(s (1 - s) / 2) of its height (s the density ratio).
#[test]
fn a_lying_cylinder_of_half_the_waters_density_floats_half_submerged() {
    let block = "shape = \"box\"\nmin = [0.24, 0.27, 0.24]\nmax = [0.36, 0.37, 0.36]";
    assert!(ARCHIMEDES.contains(block));
    let text = ARCHIMEDES.replacen(
        block,
        "shape = \"cylinder\"\ncenter = [0.3, 0.32, 0.3]\nradius = 0.05\nheight = 0.16\n\
         axis = [1.0, 0.0, 0.0]",
        1,
    );
    let mut sim = simulation(&text);
    let spec = &sim.scene.rigid_bodies[0];
    let volume = std::f32::consts::PI * 0.05f32.powi(2) * 0.16;
    assert!((spec.mass - 500.0 * volume).abs() < 1e-6 * spec.mass);
    let f = checks::float(&mut sim, |_, _| {}).expect("stable");
    let b = sim.backend.rigid.as_ref().expect("rigid world").states()[0].clone();
    println!(
        "cylinder: submerged fraction {:.3} (Archimedes 0.5), centre {:.4} m, surface {:.4} m, \
         axis {}",
        f.fraction, f.centre, f.surface, b.rotation.y_axis
    );
    // Still lying along x.
    assert!(b.rotation.y_axis.x.abs() > 0.99, "{}", b.rotation.y_axis);
    assert!(
        (f.fraction / 0.5 - 1.0).abs() < 0.05,
        "submerged fraction {}",
        f.fraction
    );
}

/// Run `first` frames, write a checkpoint and read it back, resume from it on a new backend for
/// `then` frames; returns (the resumed run's bodies, the uninterrupted run's bodies, both runs'
/// particles equal bit for bit).
fn resume_against_straight(
    text: &str,
    first: u64,
    then: u64,
) -> (Vec<rtmpm_rigid::BodyPose>, Vec<rtmpm_rigid::BodyPose>, bool) {
    use rtmpm_io::checkpoint::Checkpoint;
    use rtmpm_sim::Backend;
    let mut straight = simulation(text);
    for _ in 0..first {
        straight.advance_frame().expect("stable");
    }
    let mut p = rtmpm_sim::Particles::default();
    straight.backend.read_particles(&mut p).expect("read");
    let ck = Checkpoint {
        scene_toml: text.into(),
        scene_origin: "test".into(),
        time: straight.time,
        step: straight.step,
        frame: straight.frame,
        bodies: straight.backend.rigid_poses(),
        files: Vec::new(),
        particles: p,
    };
    let dir = std::env::temp_dir().join(format!("rtmpm-rigid-ckpt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join(format!("{first}.ckpt"));
    ck.save(&path).expect("save");
    let back = Checkpoint::load(&path).expect("load");
    std::fs::remove_file(&path).ok();
    assert_eq!(back, ck);
    let scene = Scene::from_toml(&back.scene_toml, "test").expect("scene");
    scene
        .check_checkpoint(&back)
        .expect("checkpoint fits its scene");
    let backend = CpuBackend::new(&scene, back.particles, None).expect("backend");
    let mut resumed = Simulation::<CpuBackend>::with_backend(scene, Box::new(backend));
    resumed.time = back.time;
    resumed.step = back.step;
    resumed.frame = back.frame;
    resumed
        .backend
        .set_rigid_poses(&back.bodies)
        .expect("restore bodies");
    assert_eq!(resumed.backend.rigid_poses(), ck.bodies);
    for _ in 0..then {
        straight.advance_frame().expect("stable");
        resumed.advance_frame().expect("stable");
    }
    let (mut a, mut b) = (
        rtmpm_sim::Particles::default(),
        rtmpm_sim::Particles::default(),
    );
    straight.backend.read_particles(&mut a).expect("read");
    resumed.backend.read_particles(&mut b).expect("read");
    let same = a.x == b.x && a.v == b.v && a.f == b.f;
    (
        resumed.backend.rigid_poses(),
        straight.backend.rigid_poses(),
        same,
    )
}

/// A checkpoint holds the bodies: a box floating on water (touching no other body nor a wall)
/// resumed after 6 frames continues for 4 more frames exactly as the uninterrupted run, bit
/// for bit, bodies and particles (the CPU backend and rapier are deterministic, and a body
/// without contacts has no solver state besides its pose and velocities).
#[test]
#[cfg_attr(
    feature = "f64",
    ignore = "a checkpoint holds the particles' f32 interface state: an f64 run resumes from it \
              rounded, not bit for bit"
)]
fn a_resumed_floating_box_continues_bit_for_bit() {
    let (resumed, straight, same) = resume_against_straight(ARCHIMEDES, 6, 4);
    println!("resumed {resumed:?}\nstraight {straight:?}");
    assert_eq!(resumed, straight);
    assert!(same, "particles differ after the resume");
}

/// A body resting on the floor at the checkpoint: rapier's cached contact impulses (the warm
/// start of its solver) are not in the checkpoint, so the resumed run's first contact solve
/// starts from zero. The heavy sphere of the sinking scene, on the floor from about 0.5 s,
/// resumed at 0.8 s: after 0.2 s more its centre is where the uninterrupted run puts it within
/// 1e-4 m (measured 2.9e-6 m; a contact's position correction is a fraction of a millimetre
/// per step, and the first solve without a warm start corrects a little less).
#[test]
fn a_resumed_body_resting_on_the_floor_continues_within_a_tenth_of_a_millimetre() {
    let (resumed, straight, _) = resume_against_straight(SINKING, 8, 2);
    let d = (resumed[0].position - straight[0].position).length();
    println!(
        "heavy sphere: resumed {:?}, straight {:?}: {d:.3e} m apart",
        resumed[0].position, straight[0].position
    );
    assert!(resumed[0].position.y < 0.06 + 0.045 + 0.02, "on the floor");
    assert!(d < 1e-4, "{d} m");
}

/// An OBJ of the unit cube `[0, 1]^3` (six outward quads), written to a fresh temporary folder;
/// returns its path.
fn cube_obj(tag: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("rtmpm-mesh-body-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("cube.obj");
    std::fs::write(
        &path,
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .expect("write the cube");
    path
}

/// The Archimedes scene with its box body (0.24 .. 0.36 x 0.27 .. 0.37 x 0.24 .. 0.36) given
/// as the cube mesh scaled and translated onto the same box; `extra` lines added to the table.
fn archimedes_with_mesh(obj: &std::path::Path, extra: &str) -> String {
    let block = "shape = \"box\"\nmin = [0.24, 0.27, 0.24]\nmax = [0.36, 0.37, 0.36]";
    assert!(ARCHIMEDES.contains(block));
    ARCHIMEDES.replacen(
        block,
        &format!(
            "shape = \"mesh\"\nfile = \"{}\"\nscale = [0.12, 0.1, 0.12]\n\
             translate = [0.24, 0.27, 0.24]\n{extra}",
            obj.display()
        ),
        1,
    )
}

/// A convex mesh body of the box's shape has the box's mass, centre and inertia: the closed
/// mesh's solid integrated exactly (rigid/mesh.rs), in the scene's spec and in rapier, against
/// the analytic box (m = rho a b c, I = m (b^2 + c^2) / 12 ...), within f32 rounding (1e-5
/// relative; rapier's principal moments 1e-4, see below). The triangle-mesh collider
/// (convex = false) gets the same.
#[test]
fn a_convex_mesh_body_has_the_analytic_mass_and_inertia_of_its_box() {
    let obj = cube_obj("mass");
    let (a, b, c) = (0.12f32, 0.1f32, 0.12f32);
    let mass = 500.0 * a * b * c;
    let expect = [b * b + c * c, a * a + c * c, a * a + b * b].map(|s| mass * s / 12.0);
    let mut sorted = expect;
    sorted.sort_by(f32::total_cmp);
    for convex in ["convex = true", "convex = false"] {
        let sim = simulation(&archimedes_with_mesh(&obj, convex));
        let spec = &sim.scene.rigid_bodies[0];
        assert!(
            (spec.mass - mass).abs() < 1e-5 * mass,
            "{} vs {mass}",
            spec.mass
        );
        assert!(
            (spec.position - glam::Vec3::new(0.3, 0.32, 0.3)).length() < 1e-6,
            "{}",
            spec.position
        );
        let rigid_mesh = match &spec.shape {
            rtmpm_geometry::Shape::Mesh(m) => m.solid.clone().expect("a solid"),
            s => panic!("not a mesh: {s:?}"),
        };
        let i = rigid_mesh.unit_inertia * (spec.mass / rigid_mesh.volume);
        for (k, e) in expect.iter().enumerate() {
            assert!(
                (i.col(k)[k] - e).abs() < 1e-5 * e,
                "I[{k}] {} vs {e}",
                i.col(k)[k]
            );
        }
        let (m, p) = sim
            .backend
            .rigid
            .as_ref()
            .expect("rigid world")
            .mass_properties(0)
            .expect("body 0");
        println!("{convex}: rapier mass {m} (box {mass}), inertia {p} (box {sorted:?})");
        assert!((m - mass).abs() < 1e-5 * mass, "rapier mass {m}");
        // rapier diagonalises the tensor in f32 (`MassProperties::with_inertia_matrix`, a
        // symmetric eigen-decomposition; two equal moments here): measured 2.1e-5 relative,
        // hence 1e-4 for rapier's principal moments (1e-5 for the tensor handed to it, above).
        for k in 0..3 {
            assert!((p[k] - sorted[k]).abs() < 1e-4 * sorted[k], "rapier I {p}");
        }
    }
}

/// The cube mesh body floats like the box body it replaces: the Archimedes scene at density
/// 500 (quick resolution, dx = 0.02 m), the mesh body's floating height (averaged over the last
/// frames, `checks::float`) within 2 mm (a tenth of a cell) of the box body's, and its
/// submerged fraction within 5 % of 0.5. The coupling evaluates the mesh's distance grid
/// (spacing dx / 2, trilinear) where the box body evaluates the exact box distance: the same
/// faces, so the same floating up to the grid's rounding of the edges.
#[test]
fn a_cube_mesh_body_floats_like_the_box_body() {
    let obj = cube_obj("float");
    let boxed = checks::float(&mut simulation(ARCHIMEDES), |_, _| {}).expect("stable");
    let meshed = checks::float(
        &mut simulation(&archimedes_with_mesh(&obj, "convex = true")),
        |_, _| {},
    )
    .expect("stable");
    println!(
        "box: centre {:.4} m, fraction {:.3}; mesh: centre {:.4} m, fraction {:.3}; {:.2} mm \
         apart",
        boxed.centre,
        boxed.fraction,
        meshed.centre,
        meshed.fraction,
        (meshed.centre - boxed.centre).abs() * 1e3
    );
    assert!(
        (meshed.centre - boxed.centre).abs() < 0.002,
        "mesh {meshed:?} vs box {boxed:?}"
    );
    assert!((meshed.fraction / 0.5 - 1.0).abs() < 0.05, "{meshed:?}");
}

/// A closed non-convex mesh body (the cube with its top dented in: a triangle-mesh collider in
/// rapier, `convex` off) of density 2,500 replaces the heavy sphere of the sinking scene: it
/// sinks through the water and rests on the floor (rapier's triangle-mesh contacts with the
/// floor's slab): its lowest vertex within one cell above the floor (y = 0.06 m, the top of the
/// wall band) and not more than half a cell into it.
#[test]
fn a_heavy_non_convex_mesh_body_sinks_to_the_floor() {
    let dir = std::env::temp_dir().join(format!("rtmpm-mesh-body-dent-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let obj = dir.join("dent.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\nv 0.5 0.6 0.5\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 4 1 5 8\n\
         f 4 9 3\nf 3 9 7\nf 7 9 8\nf 8 9 4\n",
    )
    .expect("write the mesh");
    let block = "shape = \"sphere\"\ncenter = [0.18, 0.31, 0.2]\nradius = 0.045";
    assert!(SINKING.contains(block));
    let text = SINKING.replacen(
        block,
        &format!(
            "shape = \"mesh\"\nfile = \"{}\"\nscale = 0.09\ntranslate = [0.135, 0.265, 0.155]",
            obj.display()
        ),
        1,
    );
    let mut sim = simulation(&text);
    let rtmpm_geometry::Shape::Mesh(rtmpm_geometry::shape::Mesh { solid: Some(m), .. }) =
        sim.scene.rigid_bodies[0].shape.clone()
    else {
        panic!("a mesh body")
    };
    assert!(!m.convex);
    let s = checks::settle(&mut sim).expect("stable");
    let lowest = m
        .mesh
        .vertices
        .iter()
        .map(|v| (s[0].rotation * *v + s[0].center).y)
        .fold(f32::INFINITY, f32::min);
    println!(
        "dented cube: centre {}, lowest vertex {lowest:.4} m (floor 0.06)",
        s[0].center
    );
    std::fs::remove_dir_all(&dir).ok();
    assert!(lowest < 0.06 + 0.02, "not on the floor: {lowest}");
    assert!(lowest > 0.06 - 0.01, "into the floor: {lowest}");
}

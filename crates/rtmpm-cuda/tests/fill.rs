//! The device fill of the particle state (`rtmpm_cuda::setup::fill`, `fill=device`, the default of
//! `CudaBackend::from_bodies`) against the host packing (`fill=host`): the same state word for
//! word, over the whole capacity (needs a GPU; skips with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --test fill -- --include-ignored --nocapture`.

use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_driver::Simulation;
use rtmpm_scene::Scene;
use rtmpm_scene::deferred::sample_bodies_deferred;
use rtmpm_scene::sampling::{SampledBody, sample_bodies};
use std::path::Path;

fn gpu() -> bool {
    match probe() {
        Ok(_) => true,
        Err(e) => {
            println!("skipped: no usable CUDA GPU ({e})");
            false
        }
    }
}

fn options(device_fill: bool) -> CudaOptions {
    CudaOptions {
        device_fill,
        ..CudaOptions::default()
    }
}

/// The scene `text` with `precision` ("f32"/"f64", or "compact": f32 with the compact particle
/// state) in its `[solver]` table, read in `dir`.
fn scene_in(text: &str, precision: &str, dir: &Path) -> Scene {
    let solver = match precision {
        "compact" => "particle_state = \"compact\"".to_string(),
        p => format!("precision = \"{p}\""),
    };
    let text = format!("{text}\n[solver]\n{solver}\n");
    Scene::from_toml_in(&text, "fill test", dir).unwrap_or_else(|e| panic!("{e}"))
}

/// Build the backend of `bodies` with the device fill and with the host packing: the states are
/// equal byte for byte (slots past the particles included: zero in both), and equal to the
/// host's image `pack_bodies` at the particles. Returns the device-filled backend.
fn same_state(label: &str, scene: &Scene, bodies: &[SampledBody]) -> CudaBackend {
    let n: usize = bodies.iter().map(|b| b.len()).sum();
    let mut dev = CudaBackend::from_bodies(scene, bodies, options(true)).expect("device fill");
    let mut host = CudaBackend::from_bodies(scene, bodies, options(false)).expect("host pack");
    let (a, b) = (
        dev.state_bytes().expect("read"),
        host.state_bytes().expect("read"),
    );
    assert_eq!(a.len(), b.len(), "{label}: state sizes");
    assert_eq!(dev.capacity(), host.capacity(), "{label}: capacities");
    let cap = dev.capacity();
    let layout = dev.state_layout();
    assert_eq!(layout, host.state_layout(), "{label}: layouts");
    let wb = a.len() / (layout.words() * cap);
    if let Some(i) = (0..a.len()).find(|&i| a[i] != b[i]) {
        let (f, slot) = ((i / wb) / cap, (i / wb) % cap);
        panic!(
            "{label}: first difference in field {f}, slot {slot} of {n} (capacity {cap}): \
             device {:?}, host {:?}",
            &a[i / wb * wb..i / wb * wb + wb],
            &b[i / wb * wb..i / wb * wb + wb]
        );
    }
    // And the host image itself at the particles (stride n there).
    let fluid: Vec<bool> = scene
        .materials
        .iter()
        .map(|m| matches!(m.model, rtmpm_physics::material::Model::Fluid(_)))
        .collect();
    let image = rtmpm_cuda::state::pack_bodies(bodies, &fluid, layout, wb == 8).expect("pack");
    for f in 0..layout.words() {
        assert!(
            a[f * cap * wb..(f * cap + n) * wb] == image[f * n * wb..(f + 1) * n * wb],
            "{label}: field {f} differs from pack_bodies"
        );
    }
    // The same scene with the bodies the GPU can draw left to it (sample=device, the default):
    // the same state again, byte for byte.
    let deferred = sample_bodies_deferred(scene, &|_| {}).expect("sample");
    let drawn = deferred
        .iter()
        .filter(|b| matches!(b, SampledBody::Deferred(_)))
        .count();
    if drawn > 0 {
        let mut d = CudaBackend::from_bodies(scene, &deferred, options(true)).expect("drawn");
        let c = d.state_bytes().expect("read");
        assert_eq!(c.len(), b.len(), "{label}: state sizes (drawn)");
        if let Some(i) = (0..c.len()).find(|&i| c[i] != b[i]) {
            let (f, slot) = ((i / wb) / cap, (i / wb) % cap);
            panic!(
                "{label}: drawn on the device: first difference in field {f}, slot {slot} of \
                 {n}: drawn {:?}, host {:?}",
                &c[i / wb * wb..i / wb * wb + wb],
                &b[i / wb * wb..i / wb * wb + wb]
            );
        }
        println!(
            "{label}: {drawn} of {} bodies drawn on the device: identical; set-up {}",
            deferred.len(),
            d.setup_phases()
        );
    }
    assert!(n > 0, "{label}: no particles");
    assert!(
        dev.setup_phases().fill > 0.0,
        "{label}: the device filled the state"
    );
    println!(
        "{label}: {n} particles, {layout:?} layout, capacity {cap}, {wb}-byte words: identical \
         (device fill: {}); set-up {}",
        dev.setup_phases().fill > 0.0,
        dev.setup_phases()
    );
    dev
}

fn check(label: &str, text: &str) {
    let dir = std::env::temp_dir();
    for precision in ["f32", "f64", "compact"] {
        let scene = scene_in(text, precision, &dir);
        let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
        same_state(&format!("{label} ({precision})"), &scene, &bodies);
    }
}

const HEAD: &str = r#"
name = "fill"
seed = 7
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.03125
[time]
duration = 0.1
fps = 30
cfl = 0.4
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 4.0e4
gamma = 7.15
[[material]]
name = "jelly"
type = "neo_hookean"
density = 1100.0
youngs_modulus = 2.0e4
poisson_ratio = 0.3
[[material]]
name = "sand"
type = "drucker_prager"
density = 1600.0
youngs_modulus = 3.5e5
poisson_ratio = 0.3
friction_angle = 35.0
"#;

/// A water box on the regular lattice.
const REGULAR_BOX: &str = r#"
[[body]]
material = "water"
shape = "box"
min = [0.1, 0.1, 0.1]
max = [0.6, 0.5, 0.7]
particles_per_cell = 8
sampling = "regular"
"#;

/// A jelly sphere, jittered, moving.
const SPHERE: &str = r#"
[[body]]
material = "jelly"
shape = "sphere"
center = [0.5, 0.5, 0.5]
radius = 0.3
particles_per_cell = 8
sampling = "jittered"
velocity = [0.3, -1.0, 0.0]
"#;

/// A sand cylinder on a slant, random, spinning.
const CYLINDER: &str = r#"
[[body]]
material = "sand"
shape = "cylinder"
center = [0.5, 0.5, 0.5]
radius = 0.2
height = 0.5
axis = [1.0, 1.0, 0.0]
particles_per_cell = 4
sampling = "random"
angular_velocity = [0.0, 3.0, -1.0]
"#;

/// Bodies drawn on the device by default: a sand cylinder on a slant, jittered, moving; a jelly
/// sphere whose surface passes through lattice points (regular); a water mesh body, random and
/// spinning.
fn drawn() -> String {
    let mesh = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/meshes/blob.obj");
    format!(
        r#"
[[body]]
material = "sand"
shape = "cylinder"
center = [0.4, 0.45, 0.5]
radius = 0.15
height = 0.4
axis = [0.48, 0.6, 0.64]
particles_per_cell = 27
sampling = "jittered"
velocity = [0.0, -2.0, 0.5]
[[body]]
material = "jelly"
shape = "sphere"
center = [0.7109375, 0.7109375, 0.7109375]
radius = 0.15625
particles_per_cell = 8
sampling = "regular"
[[body]]
material = "water"
shape = "mesh"
file = "{}"
scale = 0.12
translate = [0.75, 0.3, 0.3]
particles_per_cell = 8
sampling = "random"
angular_velocity = [0.0, 4.0, 0.0]
"#,
        mesh.display()
    )
}

/// Two bodies of two materials, each with its velocity and spin.
const TWO_BODIES: &str = r#"
[[body]]
material = "water"
shape = "box"
min = [0.1, 0.1, 0.1]
max = [0.45, 0.4, 0.9]
particles_per_cell = 8
sampling = "jittered"
velocity = [1.0, -0.0, 0.25]
angular_velocity = [2.0, 0.0, -5.0]
[[body]]
material = "jelly"
shape = "sphere"
center = [0.7, 0.6, 0.5]
radius = 0.2
particles_per_cell = 27
sampling = "regular"
velocity = [-2.0, 1.5, 0.0]
angular_velocity = [0.5, 7.0, 1.0e-3]
"#;

/// A jelly box, a water body of 500 points (a binary PLY written into `dir`) and a sand
/// sphere.
fn points_scene(dir: &Path) -> String {
    // A binary PLY of 500 points between two bodies of shapes.
    std::fs::create_dir_all(dir).expect("temp dir");
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 500\nproperty float x\n\
property float y\nproperty float z\nend_header\n"
        .to_vec();
    for i in 0..500 {
        let t = i as f32 * 0.01;
        for v in [
            0.3 + 0.2 * t.sin(),
            0.5 + 0.1 * t.cos(),
            0.2 + 0.0009 * i as f32,
        ] {
            ply.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(dir.join("pts.ply"), ply).expect("write ply");
    format!(
        "{HEAD}{}",
        r#"
[[body]]
material = "jelly"
shape = "box"
min = [0.1, 0.1, 0.1]
max = [0.3, 0.3, 0.3]
particles_per_cell = 8
velocity = [0.0, 0.0, 1.0]
[[body]]
material = "water"
shape = "particles"
file = "pts.ply"
angular_velocity = [0.0, 1.0, 0.0]
[[body]]
material = "sand"
shape = "sphere"
center = [0.7, 0.7, 0.7]
radius = 0.1
particles_per_cell = 8
angular_velocity = [1.0, 0.0, 0.0]
"#
    )
}

/// Over 8.4M particles at dx = 1/128: a water box and a spinning jelly sphere.
fn pieces_scene() -> String {
    format!(
        "{}{}",
        HEAD.replace("dx = 0.03125", "dx = 0.0078125"),
        r#"
[[body]]
material = "water"
shape = "box"
min = [0.05, 0.05, 0.05]
max = [0.95, 0.7, 0.95]
particles_per_cell = 8
sampling = "regular"
[[body]]
material = "jelly"
shape = "sphere"
center = [0.5, 0.82, 0.5]
radius = 0.1
particles_per_cell = 8
angular_velocity = [0.0, 0.0, 2.0]
"#
    )
}

/// Every scene of these tests parses and samples (on the CPU: a GPU run should not be the
/// first to find a body inside the walls).
#[test]
fn the_test_scenes_are_valid() {
    let dir = std::env::temp_dir().join(format!("rtmpm_fill_cpu_{}", std::process::id()));
    let scenes = [
        REGULAR_BOX.to_string(),
        SPHERE.to_string(),
        CYLINDER.to_string(),
        TWO_BODIES.to_string(),
        drawn(),
    ]
    .map(|b| format!("{HEAD}{b}"));
    let points = points_scene(&dir);
    for (k, text) in scenes.iter().chain([&points]).enumerate() {
        for precision in ["f32", "f64", "compact"] {
            let scene = scene_in(text, precision, &dir);
            let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
            assert!(
                bodies.iter().all(|b| !b.is_empty()),
                "scene {k}: an empty body"
            );
        }
    }
    let scene = scene_in(&points, "f32", &dir);
    let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
    assert!(matches!(bodies[1], SampledBody::Points(_)), "a points body");
    let _ = std::fs::remove_dir_all(&dir);
    let scene = scene_in(&pieces_scene(), "f32", &dir);
    let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
    let n: usize = bodies.iter().map(|b| b.len()).sum();
    assert!(n > 2 * rtmpm_cuda::setup::fill::PIECE, "{n} particles");
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/fountain.toml");
    let scene = Scene::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(!scene.emitters.is_empty(), "the fountain emits");
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn device_fill_equals_host_pack_regular_water_box() {
    if !gpu() {
        return;
    }

    check("regular water box", &format!("{HEAD}{REGULAR_BOX}"));
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn device_fill_equals_host_pack_jittered_sphere_and_random_cylinder() {
    if !gpu() {
        return;
    }

    check("jittered sphere", &format!("{HEAD}{SPHERE}"));

    check("random cylinder", &format!("{HEAD}{CYLINDER}"));
}

/// Bodies drawn on the device (a slanted jittered cylinder, a sphere through lattice points, a
/// random spinning mesh body).
#[test]
#[ignore = "needs a CUDA GPU"]
fn bodies_drawn_on_the_device_equal_the_host_s() {
    if !gpu() {
        return;
    }
    let scene = scene_in(&format!("{HEAD}{}", drawn()), "f32", &std::env::temp_dir());
    let deferred = sample_bodies_deferred(&scene, &|_| {}).expect("sample");
    assert!(
        deferred
            .iter()
            .all(|b| matches!(b, SampledBody::Deferred(_))),
        "both drawn"
    );
    check("drawn bodies", &format!("{HEAD}{}", drawn()));
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn device_fill_equals_host_pack_two_bodies_with_velocity_and_spin() {
    if !gpu() {
        return;
    }

    check("two bodies, spin", &format!("{HEAD}{TWO_BODIES}"));
}

/// The compact layout (C encoded: a constant of each body) with bodies of two materials.
#[test]
#[ignore = "needs a CUDA GPU"]
fn device_fill_equals_host_pack_in_the_compact_layout() {
    if !gpu() {
        return;
    }
    let scene = scene_in(
        &format!("{HEAD}{TWO_BODIES}"),
        "compact",
        &std::env::temp_dir(),
    );
    let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
    let dev = same_state("two bodies (compact)", &scene, &bodies);
    assert!(dev.state_layout().compact());
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn device_fill_equals_host_pack_with_a_points_body() {
    if !gpu() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("rtmpm_fill_{}", std::process::id()));
    let text = points_scene(&dir);
    for precision in ["f32", "f64"] {
        let scene = scene_in(&text, precision, &dir);
        let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
        same_state(&format!("points body ({precision})"), &scene, &bodies);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Past two pieces of the upload (4M particles each): the two page-locked buffers used again,
/// a short last piece, then a second body.
#[test]
#[ignore = "needs a CUDA GPU"]
fn device_fill_equals_host_pack_over_several_pieces() {
    if !gpu() {
        return;
    }
    let text = pieces_scene();
    let scene = scene_in(&text, "f32", &std::env::temp_dir());
    let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
    let n: usize = bodies.iter().map(|b| b.len()).sum();
    assert!(n > 2 * rtmpm_cuda::setup::fill::PIECE, "{n} particles");
    same_state("several pieces", &scene, &bodies);
}

/// Emitters' slots past the initial particles stay zero until they emit, and emitting works on a
/// device-filled state: the fountain emits as many particles as with the host packing.
#[test]
#[ignore = "needs a CUDA GPU"]
fn device_fill_keeps_emitter_slots_and_emits() {
    if !gpu() {
        return;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/fountain.toml");
    let scene = Scene::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
    let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
    let n0: usize = bodies.iter().map(|b| b.len()).sum();
    let dev = same_state("fountain (emitter)", &scene, &bodies);
    assert!(dev.capacity() > n0, "no emitter slots");
    let host = CudaBackend::from_bodies(&scene, &bodies, options(false)).expect("host");
    let mut a = Simulation::new(scene.clone(), Box::new(dev));
    let mut b = Simulation::new(scene.clone(), Box::new(host));
    for _ in 0..3 {
        a.advance_frame().expect("device-filled frame");
        b.advance_frame().expect("host-packed frame");
    }
    let (na, nb) = (a.backend.num_particles(), b.backend.num_particles());
    assert!(na > n0, "nothing emitted ({na} of {n0})");
    assert_eq!(na, nb, "emitted particles");
}

/// A scene with rigid bodies builds from a device-filled state and steps.
#[cfg(feature = "rigid")]
#[test]
#[ignore = "needs a CUDA GPU"]
fn device_fill_with_rigid_bodies() {
    if !gpu() {
        return;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/rigid/floating_box.toml");
    let scene = match Scene::from_file(&path) {
        Ok(s) => s,
        // Without the `rigid` feature the scene may be refused: nothing to test then.
        Err(e) => {
            println!("skipped: {e}");
            return;
        }
    };
    let bodies = sample_bodies(&scene, &|_| {}).expect("sample");
    let dev = same_state("floating box (rigid)", &scene, &bodies);
    let mut a = Simulation::new(scene.clone(), Box::new(dev));
    a.advance_frame().expect("frame");
    assert!(!a.backend.rigid_bodies().is_empty(), "no rigid body");
}

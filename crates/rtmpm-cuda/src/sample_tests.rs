//! Tests of the device's walk of deferred bodies without a GPU: the kernels' walk
//! (`kernels/sample.cuh`) compiled for the CPU finds the host's positions bit for bit, the
//! rows of a piece, and every host path through a deferred body (block counts, speeds, the
//! walked copy) gives what the eagerly sampled body gives.

use super::*;
use rtmpm_core::Scene;
use rtmpm_core::scene::deferred::{can_defer, sample_bodies_deferred};
use rtmpm_core::scene::sampling::{BodyPositions, sample_bodies};

/// Bodies of every deferrable kind: regular and jittered; box, sphere and a tilted cylinder; off
/// the lattice's alignment; one with a velocity (uniform: deferrable) and one with a spin (not).
const SCENE: &str = r#"
name = "sample"
seed = 11
[domain]
min = [-0.25, 0.0, 0.1]
max = [1.0114, 1.0017, 1.0275]
dx = 0.0371
[time]
duration = 0.1
fps = 30
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 4.0e4
gamma = 7.15
[[body]]
material = "water"
shape = "box"
min = [0.1013, 0.15, 0.2377]
max = [0.6, 0.5, 0.7]
particles_per_cell = 8
sampling = "regular"
velocity = [1.0, -2.0, 0.5]
[[body]]
material = "water"
shape = "sphere"
center = [0.6, 0.6, 0.6]
radius = 0.2003
particles_per_cell = 8
sampling = "jittered"
[[body]]
material = "water"
shape = "cylinder"
center = [0.4, 0.3, 0.5]
axis = [0.48, 0.6, 0.64]
radius = 0.1
height = 0.3
particles_per_cell = 27
sampling = "jittered"
[[body]]
material = "water"
shape = "box"
min = [0.1, 0.6, 0.25]
max = [0.3, 0.85, 0.4]
sampling = "jittered"
[[body]]
material = "water"
shape = "sphere"
center = [0.2, 0.75, 0.8]
radius = 0.1
angular_velocity = [0.0, 1.0, 0.0]
"#;

fn scene() -> Scene {
    Scene::from_toml(SCENE, "sample test").expect("scene")
}

fn positions(b: &BodyPositions) -> Vec<[u32; 3]> {
    b.chunks
        .iter()
        .flatten()
        .map(|x| x.to_array().map(f32::to_bits))
        .collect()
}

#[test]
fn deferred_bodies_are_the_eager_bodies() {
    let scene = scene();
    let eager = sample_bodies(&scene, &|_| {}).expect("sample");
    let deferred = sample_bodies_deferred(&scene, &|_| {}).expect("sample");
    let kinds: Vec<bool> = (0..5).map(|i| can_defer(&scene, i)).collect();
    assert_eq!(
        kinds,
        [true, true, true, true, false],
        "the spinning sphere stays"
    );
    for (i, (e, d)) in eager.iter().zip(&deferred).enumerate() {
        assert_eq!(e.len(), d.len(), "body {i}: the count");
        let (SampledBody::Shape(e), d) = (e, d) else {
            panic!("body {i}: eager is a shape")
        };
        match d {
            SampledBody::Deferred(d) => {
                assert!(d.shared.chunks.is_empty(), "the host keeps no position");
                assert_eq!(positions(e), positions(&d.positions()), "body {i}");
                assert_eq!(e.centre, d.shared.centre);
                assert_eq!(e.mass, d.shared.mass);
            }
            SampledBody::Shape(s) => assert_eq!(positions(e), positions(s)),
            SampledBody::Points(_) => panic!("no points body"),
        }
    }
    // The host paths through a deferred body.
    assert_eq!(
        crate::capacity::block_counts(&scene, &eager),
        crate::capacity::block_counts(&scene, &deferred)
    );
    assert_eq!(
        crate::state::max_speed(&eager),
        crate::state::max_speed(&deferred)
    );
    let base = crate::capacity::base_of(&scene);
    assert_eq!(
        crate::state::map_positions(&eager, &base),
        crate::state::map_positions(&deferred, &base)
    );
    let walked = walked(&deferred);
    for (e, w) in eager.iter().zip(&walked) {
        let (SampledBody::Shape(e), SampledBody::Shape(w)) = (e, w) else {
            panic!("walked bodies are shapes")
        };
        assert_eq!(positions(e), positions(w));
    }
    let fluid = crate::state::fluid_materials(&scene);
    let layout = crate::contract::StateLayout::Fluid;
    assert!(crate::state::pack_bodies(&deferred, &fluid, layout, false).is_err());
    assert_eq!(
        crate::state::pack_bodies(&eager, &fluid, layout, false),
        crate::state::pack_bodies(&walked, &fluid, layout, false)
    );
    // The device fill's table and pieces treat a deferred body as its eager twin.
    assert_eq!(
        crate::fill::table(&eager, &fluid, layout, false),
        crate::fill::table(&deferred, &fluid, layout, false)
    );
    assert_eq!(
        crate::fill::pieces(&eager, 1000),
        crate::fill::pieces(&deferred, 1000)
    );
}

#[test]
fn the_rows_of_a_piece_are_those_it_overlaps() {
    // Rows of 3, 0, 2, 0, 4 particles: first particles 0, 3, 3, 5, 5, total 9.
    let offsets = [0u64, 3, 3, 5, 5, 9];
    assert_eq!(rows_of(&offsets, 0, 9), 0..5);
    assert_eq!(rows_of(&offsets, 0, 3), 0..1);
    assert_eq!(rows_of(&offsets, 2, 4), 0..3);
    assert_eq!(rows_of(&offsets, 3, 4), 2..3);
    assert_eq!(rows_of(&offsets, 5, 6), 4..5);
    assert_eq!(rows_of(&offsets, 8, 9), 4..5);
    assert_eq!(rows_of(&offsets, 9, 9), 5..5);
    assert_eq!(rows_of(&[0], 0, 0), 0..0);
}

/// Bodies whose surfaces pass exactly through lattice points (dx a power of two, shapes centred
/// on lattice points): the walk's inside tests decide on the boundary.
const EXACT: &str = r#"
name = "sample exact"
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = 0.0625
[time]
duration = 0.1
fps = 30
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 4.0e4
gamma = 7.15
[[body]]
material = "water"
shape = "sphere"
center = [0.515625, 0.515625, 0.515625]
radius = 0.15625
sampling = "regular"
[[body]]
material = "water"
shape = "box"
min = [0.234375, 0.234375, 0.234375]
max = [0.421875, 0.421875, 0.421875]
sampling = "regular"
[[body]]
material = "water"
shape = "cylinder"
center = [0.515625, 0.515625, 0.515625]
axis = [0.0, 1.0, 0.0]
radius = 0.15625
height = 0.25
sampling = "regular"
"#;

/// Compile `harness` (with the kernels' folder and the contract header on its include path)
/// with g++ for the CPU, without contraction; `None` where g++ is missing.
fn compile_twin(name: &str, harness: &str) -> Option<std::path::PathBuf> {
    if std::process::Command::new("g++")
        .arg("--version")
        .output()
        .is_err()
    {
        eprintln!("skipped: no g++ here");
        return None;
    }
    let dir = std::env::temp_dir().join(format!("rtmpm-sample-twin-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    std::fs::write(dir.join("contract.cuh"), crate::contract::prelude()).expect("header");
    let src = dir.join(format!("{name}.cpp"));
    std::fs::write(&src, harness).expect("harness");
    let exe = dir.join(name);
    let kernels = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("kernels");
    let built = std::process::Command::new("g++")
        .args(["-O2", "-std=c++17", "-ffp-contract=off", "-I"])
        .arg(&kernels)
        .arg("-I")
        .arg(&dir)
        .arg(&src)
        .arg("-o")
        .arg(&exe)
        .output()
        .expect("g++ runs");
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    Some(exe)
}

/// Run `exe` with `input` on stdin; its stdout's lines as numbers.
fn run_twin(exe: &std::path::Path, input: &str) -> Vec<Vec<u64>> {
    use std::io::Write;
    let mut child = std::process::Command::new(exe)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("twin runs");
    let mut stdin = child.stdin.take().expect("stdin");
    let input = input.to_string();
    let writer = std::thread::spawn(move || stdin.write_all(input.as_bytes()));
    let run = child.wait_with_output().expect("twin output");
    writer.join().expect("writer").expect("input written");
    assert!(run.status.success());
    String::from_utf8_lossy(&run.stdout)
        .lines()
        .map(|l| l.split(' ').map(|t| t.parse().expect("a number")).collect())
        .collect()
}

/// The kernels' walk compiled for the CPU from each deferred body's recipe: the host's
/// positions, bit for bit, in order (jittered and regular, off the lattice and on it).
#[test]
fn the_device_walk_compiled_for_the_cpu_is_the_host_walk() {
    let harness = r#"
#include <cstdio>
#include "contract.cuh"
#include "sample.cuh"
int main() {
    unsigned w[SAMPLE_WORDS];
    unsigned long long rows;
    if (scanf("%llu", &rows) != 1) return 2;
    for (int i = 0; i < SAMPLE_WORDS; ++i) if (scanf("%u", &w[i]) != 1) return 2;
    SpRecipe R = sp_load(w);
    for (sp_u64 r = 0; r < rows; ++r)
        sp_row(R, r, [&](const float* x) {
            unsigned b[3];
            memcpy(b, x, 12);
            printf("%u %u %u\n", b[0], b[1], b[2]);
        });
    return 0;
}
"#;
    let Some(exe) = compile_twin("walk", harness) else {
        return;
    };
    let mut checked = 0;
    for text in [SCENE, EXACT] {
        let scene = Scene::from_toml(text, "sample test").expect("scene");
        let deferred = sample_bodies_deferred(&scene, &|_| {}).expect("sample");
        for (i, body) in deferred.iter().enumerate() {
            let SampledBody::Deferred(d) = body else {
                continue;
            };
            let words = recipe(d).expect("a drawable shape");
            let mut input = format!("{} ", d.lattice.rows_count());
            input.extend(words.iter().map(|w| format!("{w} ")));
            let device: Vec<[u32; 3]> = run_twin(&exe, &input)
                .into_iter()
                .map(|v| [v[0] as u32, v[1] as u32, v[2] as u32])
                .collect();
            let host = positions(&d.positions());
            assert_eq!(
                device.len(),
                host.len(),
                "{}: body {i}: the count",
                scene.name
            );
            let first_diff = device.iter().zip(&host).position(|(a, b)| a != b);
            assert_eq!(first_diff, None, "{}: body {i}", scene.name);
            assert!(!host.is_empty());
            checked += 1;
        }
    }
    assert_eq!(checked, 7);
}

/// The kernels' sphere and cylinder tests compiled for the CPU give the host's values bit for
/// bit (`(x - c).length_squared()`, `cylinder_distance`) at random points about random
/// cylinders: an operation in another order or contracted would differ in the last bits.
#[test]
fn the_device_shape_tests_compiled_for_the_cpu_are_the_host_s() {
    use rand::{Rng, SeedableRng};
    use rtmpm_core::boundary::sdf::cylinder_distance;
    use rtmpm_core::math::Vec3;
    let harness = r#"
#include <cstdio>
#include "contract.cuh"
#include "sample.cuh"
int main() {
    unsigned w[11];
    while (true) {
        for (int i = 0; i < 11; ++i) if (scanf("%u", &w[i]) != 1) return 0;
        float c[8], x[3];
        memcpy(c, w, 32);
        memcpy(x, w + 8, 12);
        float d2 = sp_sphere_d2(c, x), cd = sp_cylinder_distance(c, x);
        unsigned b[2];
        memcpy(b, &d2, 4);
        memcpy(b + 1, &cd, 4);
        printf("%u %u\n", b[0], b[1]);
    }
}
"#;
    let Some(exe) = compile_twin("shapes", harness) else {
        return;
    };
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let mut v = |s: f32| Vec3::new(rng.random(), rng.random(), rng.random()) * s;
    let mut cases = Vec::new();
    for _ in 0..20_000 {
        let c = v(1.0);
        let axis = (v(2.0) - Vec3::ONE).normalize_or(Vec3::Y);
        let (r, hh) = (0.05 + v(0.3).x, 0.05 + v(0.3).y);
        let x = c + (v(2.0) - Vec3::ONE) * 0.5;
        cases.push((c, axis, r, hh, x));
    }
    let input: String = cases
        .iter()
        .map(|(c, a, r, hh, x)| {
            let f = c
                .to_array()
                .into_iter()
                .chain(a.to_array())
                .chain([*r, *hh])
                .chain(x.to_array());
            f.map(|v| format!("{} ", v.to_bits())).collect::<String>()
        })
        .collect();
    let device = run_twin(&exe, &input);
    assert_eq!(device.len(), cases.len());
    for ((c, a, r, hh, x), d) in cases.iter().zip(&device) {
        assert_eq!(
            d[0] as u32,
            (*x - *c).length_squared().to_bits(),
            "sphere at {x}"
        );
        assert_eq!(
            d[1] as u32,
            cylinder_distance(*x, *c, *a, *r, *hh).to_bits(),
            "cylinder at {x}"
        );
    }
}

//! Tests of the device's walk of deferred bodies without a GPU: the kernels' walk
//! (`kernels/sample.cuh`) compiled for the CPU finds the host's positions bit for bit, the
//! rows of a piece, and every host path through a deferred body (block counts, speeds, the
//! walked copy) gives what the eagerly sampled body gives.

use super::*;
use rtmpm_scene::Scene;
use rtmpm_scene::deferred::{can_defer, sample_bodies_deferred};
use rtmpm_scene::sampling::{BodyPositions, sample_bodies};

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
[[body]]
material = "water"
shape = "cylinder"
center = [0.75, 0.25, 0.4]
radius = 0.08
height = 0.2
axis = [1.0, 0.0, 0.0]
sampling = "random"
velocity = [0.0, 1.0, 0.0]
angular_velocity = [3.0, 0.0, 1.0]
[[body]]
material = "water"
shape = "mesh"
file = "meshes/blob.obj"
scale = 0.15
translate = [0.02, 0.45, 0.5]
sampling = "jittered"
[[body]]
material = "water"
shape = "mesh"
file = "meshes/blob.obj"
scale = 0.08
translate = [0.75, 0.75, 0.35]
sampling = "random"
"#;

/// The folder of the example scenes (their meshes).
fn scenes_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

fn scene_of(text: &str) -> Scene {
    Scene::from_toml_in(text, "sample test", &scenes_dir()).unwrap_or_else(|e| panic!("{e}"))
}

fn scene() -> Scene {
    scene_of(SCENE)
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
    assert!((0..8).all(|i| can_defer(&scene, i)), "every shape is drawn");
    for (i, (e, d)) in eager.iter().zip(&deferred).enumerate() {
        assert_eq!(e.len(), d.len(), "body {i}: the count");
        let (SampledBody::Shape(e), d) = (e, d) else {
            panic!("body {i}: eager is a shape")
        };
        match d {
            SampledBody::Deferred(d) => {
                assert!(d.shared.chunks.is_empty(), "the host keeps no position");
                assert_eq!(positions(e), positions(&d.positions()), "body {i}");
                // The spinning bodies' centroid, summed in walk order as the eager one.
                assert_eq!(e.centre.to_array(), d.shared.centre.to_array(), "body {i}");
                assert_eq!(e.mass, d.shared.mass);
                assert_eq!(e.vol0, d.shared.vol0);
            }
            SampledBody::Shape(s) => assert_eq!(positions(e), positions(s)),
            SampledBody::Points(_) => panic!("no points body"),
        }
    }
    // The host paths through a deferred body.
    assert_eq!(
        crate::setup::capacity::block_counts(&scene, &eager),
        crate::setup::capacity::block_counts(&scene, &deferred)
    );
    assert_eq!(
        crate::state::max_speed(&eager),
        crate::state::max_speed(&deferred)
    );
    let base = crate::setup::capacity::base_of(&scene);
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
        crate::setup::fill::table(&eager, &fluid, layout, false),
        crate::setup::fill::table(&deferred, &fluid, layout, false)
    );
    assert_eq!(
        crate::setup::fill::pieces(&eager, 1000),
        crate::setup::fill::pieces(&deferred, 1000)
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
    std::fs::create_dir_all(dir.join("geometry")).expect("temp dir");
    std::fs::write(
        dir.join("geometry/registry.cuh"),
        crate::contract::shape_registry(),
    )
    .expect("header");
    let src = dir.join(format!("{name}.cpp"));
    std::fs::write(&src, harness).expect("harness");
    let exe = dir.join(name);
    let kernels = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("kernels");
    let built = std::process::Command::new("g++")
        .args(["-O2", "-std=c++17", "-ffp-contract=off", "-I"])
        .arg(&kernels)
        .arg("-I")
        .arg(&dir)
        .arg("-I")
        .arg(kernels.join("geometry"))
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
#include <vector>
#include "contract.cuh"
#include "sample.cuh"
int main() {
    unsigned w[SAMPLE_WORDS];
    unsigned long long rows, nsdf;
    if (scanf("%llu", &rows) != 1) return 2;
    for (int i = 0; i < SAMPLE_WORDS; ++i) if (scanf("%u", &w[i]) != 1) return 2;
    if (scanf("%llu", &nsdf) != 1) return 2;
    std::vector<float> sdf(nsdf + 1);
    for (unsigned long long i = 0; i < nsdf; ++i) {
        unsigned b;
        if (scanf("%u", &b) != 1) return 2;
        sdf[i] = sp_bits(b);
    }
    SpRecipe R = sp_load(w, sdf.data());
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
        let scene = scene_of(text);
        let deferred = sample_bodies_deferred(&scene, &|_| {}).expect("sample");
        for (i, body) in deferred.iter().enumerate() {
            let SampledBody::Deferred(d) = body else {
                continue;
            };
            let (words, sdf) = recipe(d).expect("a drawable shape");
            let mut input = format!("{} ", rows(d));
            input.extend(words.iter().map(|w| format!("{w} ")));
            input.push_str(&format!("{} ", sdf.len()));
            input.extend(sdf.iter().map(|v| format!("{} ", v.to_bits())));
            let device: Vec<[u32; 3]> = run_twin(&exe, &input)
                .into_iter()
                .map(|v| [v[0] as u32, v[1] as u32, v[2] as u32])
                .collect();
            let host = positions(&d.positions());
            // A random walk's device rows go on to the end of the host's tries: the first
            // `count` points are the body's, and all of them the host's accepted ones.
            assert_eq!(device.len() as u64, d.accepted, "{}: body {i}", scene.name);
            let device = device[..host.len().min(device.len())].to_vec();
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
    assert_eq!(checked, 11);
}

/// Every shape with a device twin (`kernels/geometry/<name>.cuh`, dispatched by the generated
/// `geometry/registry.cuh`), compiled for the CPU in the sampler's arithmetic, gives the host's
/// signed distance, inside test and normal (`rtmpm_geometry::Shape`) bit for bit at random
/// points about random shapes (and mesh grids with random values, inside and outside the
/// grid): an operation in another order, contracted, or a parameter read from another word
/// would differ in the last bits.
#[test]
fn every_device_shape_compiled_for_the_cpu_is_the_host_s() {
    use rand::{Rng, SeedableRng};
    use rtmpm_geometry::Shape;
    use rtmpm_geometry::mesh::MeshSdf;
    use rtmpm_geometry::shape::{Cuboid, Cylinder, HalfSpace, Mesh, Sphere};
    use rtmpm_physics::math::Vec3;
    let harness = r#"
#include <cstdio>
#include <vector>
#include "contract.cuh"
#include "sample.cuh"
int main() {
    unsigned kind, pw[8], dims[3];
    unsigned long long nv, np;
    while (scanf("%u", &kind) == 1) {
        for (int i = 0; i < 8; ++i) if (scanf("%u", &pw[i]) != 1) return 2;
        for (int i = 0; i < 3; ++i) if (scanf("%u", &dims[i]) != 1) return 2;
        if (scanf("%llu", &nv) != 1) return 2;
        std::vector<float> v(nv + 1);
        for (unsigned long long i = 0; i < nv; ++i) {
            unsigned b;
            if (scanf("%u", &b) != 1) return 2;
            v[i] = sp_bits(b);
        }
        float p[8];
        for (int i = 0; i < 8; ++i) p[i] = sp_bits(pw[i]);
        GeoShape g;
        g.p = p;
        g.dims = dims;
        g.values = v.data();
        if (scanf("%llu", &np) != 1) return 2;
        for (unsigned long long i = 0; i < np; ++i) {
            unsigned b[3];
            if (scanf("%u %u %u", &b[0], &b[1], &b[2]) != 3) return 2;
            float x[3] = {sp_bits(b[0]), sp_bits(b[1]), sp_bits(b[2])}, n[3];
            float d = shape_distance_of<SpArith>(kind, g, x);
            bool in = shape_contains_of<SpArith>(kind, g, x);
            shape_normal_of<SpArith>(kind, g, x, n);
            printf("%u %u %u %u %u\n", sp_u32_of(d), in ? 1u : 0u, sp_u32_of(n[0]), sp_u32_of(n[1]),
                   sp_u32_of(n[2]));
        }
    }
    return 0;
}
"#;
    let Some(exe) = compile_twin("shapes", harness) else {
        return;
    };
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let mut v = |s: f32| Vec3::new(rng.random(), rng.random(), rng.random()) * s;
    let mut shapes = Vec::new();
    for _ in 0..40 {
        let c = v(1.0);
        let dir = (v(2.0) - Vec3::ONE).normalize_or(Vec3::Y);
        let (r, hh) = (0.05 + v(0.3).x, 0.05 + v(0.3).y);
        shapes.push(Shape::HalfSpace(HalfSpace {
            point: c,
            normal: dir,
        }));
        shapes.push(Shape::Box(Cuboid {
            min: c - v(0.3) - 0.01,
            max: c + v(0.3) + 0.01,
        }));
        shapes.push(Shape::Sphere(Sphere {
            center: c,
            radius: r,
        }));
        shapes.push(Shape::Cylinder(Cylinder {
            center: c,
            axis: dir,
            radius: r,
            half_height: hh,
        }));
    }
    for dims in [[7u32, 5, 6], [1, 4, 3], [2, 2, 9]] {
        let n = (dims[0] * dims[1] * dims[2]) as usize;
        let values = (0..n).map(|_| v(1.0).x - 0.4).collect();
        let sdf = MeshSdf {
            origin: Vec3::new(0.13, -0.2, 0.41),
            spacing: 0.037,
            dims,
            values,
            mesh_min: Vec3::ZERO,
            mesh_max: Vec3::ONE,
        };
        shapes.push(Shape::Mesh(Mesh {
            sdf: std::sync::Arc::new(sdf),
            solid: None,
        }));
    }
    let mut input = String::new();
    let mut points = Vec::new();
    for s in &shapes {
        let g = s.gpu();
        input.push_str(&format!("{} ", s.code()));
        input.extend(g.p.iter().map(|x| format!("{} ", x.to_bits())));
        input.extend(g.dims.iter().map(|d| format!("{d} ")));
        input.push_str(&format!("{} ", g.values.len()));
        input.extend(g.values.iter().map(|x| format!("{} ", x.to_bits())));
        let (lo, hi) = match s.finite_bounds() {
            Some((lo, hi)) => (lo - 0.05, hi + 0.05),
            None => (s.center() - 0.5, s.center() + 0.5),
        };
        let at: Vec<Vec3> = (0..2000).map(|_| lo + v(1.0) * (hi - lo)).collect();
        input.push_str(&format!("{}\n", at.len()));
        for p in &at {
            input.push_str(&format!(
                "{} {} {}\n",
                p.x.to_bits(),
                p.y.to_bits(),
                p.z.to_bits()
            ));
            points.push((s, *p));
        }
    }
    let device = run_twin(&exe, &input);
    assert_eq!(device.len(), points.len());
    let mut inside = vec![0usize; Shape::ALL.len()];
    for ((s, x), d) in points.iter().zip(&device) {
        let what = format!("{} at {x}", s.name());
        assert_eq!(d[0] as u32, s.distance(*x).to_bits(), "distance of {what}");
        assert_eq!(d[1] == 1, s.contains(*x), "inside test of {what}");
        let n = s.normal(*x);
        assert_eq!(
            [d[2] as u32, d[3] as u32, d[4] as u32],
            n.to_array().map(f32::to_bits),
            "normal of {what}"
        );
        inside[s.code() as usize] += s.contains(*x) as usize;
    }
    // Every shape with a device twin was met, with points inside and outside.
    for (k, info) in Shape::ALL.iter().enumerate() {
        if info.device {
            assert!(inside[k] > 0, "no point inside a {}", info.name);
        }
    }
}

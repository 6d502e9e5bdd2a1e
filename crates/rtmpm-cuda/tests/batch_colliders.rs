//! Worlds with static colliders of their own in a batch on the GPU (`rtmpm_cuda::batch::CudaBatch`:
//! per-world collider tables; needs a GPU, skips with a message otherwise), against the same
//! worlds run one by one on the CUDA backend:
//! `cargo test --release -p rtmpm-cuda --test batch_colliders -- --include-ignored --nocapture`.

use rtmpm_cuda::batch::CudaBatch;
use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;

fn gpu() -> bool {
    match probe() {
        Ok(_) => true,
        Err(e) => {
            println!("skipped: no usable CUDA GPU ({e})");
            false
        }
    }
}

fn read(b: &mut dyn Backend) -> Particles {
    let mut p = Particles::default();
    b.read_particles(&mut p).expect("read particles");
    p
}

/// A water column (0.1 x 0.2 x 0.28 m at 2 cm cells) collapsing against an obstacle of world
/// `w`'s own: a box 2 cm further along x in each world, a ball in world 2, sticky in world 3
/// (slip elsewhere).
fn world(w: usize) -> Scene {
    let x = 0.18 + 0.02 * w as f32;
    let obstacle = if w == 2 {
        "shape = \"sphere\"\ncenter = [0.24, 0.06, 0.2]\nradius = 0.06\n".to_string()
    } else {
        format!(
            "shape = \"box\"\nmin = [{x}, 0.0, 0.12]\nmax = [{}, 0.12, 0.28]\n",
            x + 0.04
        )
    };
    let rule = if w == 3 { "sticky" } else { "slip" };
    let text = format!(
        r#"name = "obstacle"
[domain]
min = [0.0, 0.0, 0.0]
max = [0.4, 0.4, 0.4]
dx = 0.02
[time]
duration = 0.1
fps = 50
dt = 2e-4
[walls]
thickness = 3
[[material]]
name = "water"
type = "fluid"
density = 1000.0
bulk_modulus = 1e4
[[body]]
material = "water"
shape = "box"
min = [0.06, 0.06, 0.06]
max = [0.16, 0.26, 0.34]
particles_per_cell = 8
[[collider]]
{obstacle}condition = "{rule}"
"#
    );
    Scene::from_toml(&text, "obstacle.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// Four worlds whose obstacles differ (place, shape, boundary rule) in one batch give, world by
/// world, the particles of their separate CUDA runs after 500 steps (0.1 s: the water front
/// reaches every obstacle): the agreement test's aggregate tolerances (centre of mass within
/// 0.1 cell, kinetic energy within 2 %, bounding box within a cell), while the worlds differ
/// from each other by more than that (the check could see a world reading another's
/// obstacle). About 5 s on an H200.
#[test]
#[ignore = "needs a CUDA GPU"]
fn worlds_with_their_own_obstacles_agree_with_their_separate_runs() {
    let worlds: Vec<Scene> = (0..4).map(world).collect();
    if !gpu() {
        return;
    }
    let options = CudaOptions {
        fast_math: false,
        ..CudaOptions::default()
    };
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut batch = CudaBatch::new(&worlds, &p0, options.clone()).expect("batch");
    assert!(
        batch.collider_bytes() > 0,
        "the worlds read tables of their own"
    );
    let mut single: Vec<CudaBackend> = worlds
        .iter()
        .zip(&p0)
        .map(|(s, p)| CudaBackend::new(s, p, options.clone()).expect("world"))
        .collect();
    let dt = 2e-4f32;
    for s in 0..500 {
        let t = s as f32 * dt;
        batch.step(dt, t).expect("batch step");
        for b in &mut single {
            b.step(dt, t).expect("step");
        }
    }
    assert!(
        batch.bad_world().expect("check").is_none(),
        "a world blew up"
    );
    let got = batch.read_worlds().expect("read");
    let dx = worlds[0].dx as f64;
    let mut failures = Vec::new();
    for w in 0..worlds.len() {
        let want = read(&mut single[w]);
        let d = got[w].aggregate_difference(&want);
        println!(
            "world {w}: |d com| {:.4} dx, KE {:.4e} vs {:.4e} ({:.3} %), |d bbox| {:.3} dx",
            d.com / dx,
            got[w].kinetic_energy(),
            want.kinetic_energy(),
            100.0 * d.kinetic,
            d.bbox / dx
        );
        if d.com > 0.1 * dx || d.kinetic > 0.02 || d.bbox > dx {
            failures.push(format!("world {w}: aggregates differ"));
        }
    }
    for (a, b) in [(0, 1), (0, 2), (1, 3)] {
        let d = got[a].aggregate_difference(&got[b]);
        println!(
            "world {a} vs world {b}: |d com| {:.3} dx, KE {:.2} %, |d bbox| {:.2} dx",
            d.com / dx,
            100.0 * d.kinetic,
            d.bbox / dx
        );
        assert!(
            d.com > 0.1 * dx || d.kinetic > 0.02 || d.bbox > dx,
            "worlds {a} and {b} end alike: the check could not see a mix-up"
        );
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

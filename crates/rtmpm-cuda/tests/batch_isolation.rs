//! Worlds in one batch of the same CUDA kernels (`rtmpm_cuda::batch::CudaBatch`) are isolated:
//! each gives the particles of its separate CUDA run; and a batch whose worlds cannot share the
//! arrays, or that the GPU cannot hold, is refused before anything is allocated (needs a GPU;
//! skips with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --test batch_isolation -- --include-ignored --nocapture`.

mod common;

use common::batch::{DT, agrees, precise, wedge_worlds};
use common::{gpu, read};
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_cuda::{CudaBackend, CudaOptions};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::time::Instant;

/// Isolation: 16 worlds with different yield stress and gravity in one batch give, world by
/// world, the particles of 16 separate CUDA runs (the agreement test's tolerances), while the
/// worlds differ from each other by far more than that.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_batch_gives_each_world_its_separate_run() {
    if !gpu() {
        return;
    }
    let steps: usize = std::env::var("BATCH_TEST_STEPS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(200);
    let worlds = wedge_worlds(16);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    let mut batch = CudaBatch::new(&worlds, &p0, precise()).expect("batch");
    let mut single: Vec<CudaBackend> = worlds
        .iter()
        .zip(&p0)
        .map(|(s, p)| CudaBackend::new(s, p, precise()).expect("world"))
        .collect();
    batch.step(DT, 0.0).expect("batch step");
    for b in &mut single {
        b.step(DT, 0.0).expect("step");
    }
    let first_batch = batch.read_worlds().expect("read");
    let first_single: Vec<Particles> = single.iter_mut().map(|b| read(b)).collect();
    for s in 1..steps {
        let t = s as f32 * DT;
        batch.step(DT, t).expect("batch step");
        for b in &mut single {
            b.step(DT, t).expect("step");
        }
    }
    assert!(
        batch.bad_world().expect("check").is_none(),
        "a world blew up"
    );
    let got = batch.read_worlds().expect("read");
    let mut failures = Vec::new();
    for w in 0..worlds.len() {
        let want = read(&mut single[w]);
        failures.extend(agrees(
            &format!("world {w:2} after {steps} steps"),
            Some((&first_batch[w], &first_single[w])),
            &got[w],
            &want,
            worlds[w].dx,
        ));
    }
    // The test can tell worlds apart: the first and last world end far apart.
    let d = got[0].aggregate_difference(&got[15]);
    println!(
        "world 0 vs world 15: |d com| {:.3e} m ({:.2} dx)",
        d.com,
        d.com / worlds[0].dx as f64
    );
    assert!(
        d.com > worlds[0].dx as f64,
        "the worlds do not differ: the check could not see a mix-up"
    );
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Worlds that cannot share the arrays, and a batch larger than the GPU, are refused before
/// anything is allocated, with the numbers.
#[test]
#[ignore = "needs a CUDA GPU"]
fn a_batch_the_gpu_cannot_hold_is_refused_with_the_numbers() {
    if !gpu() {
        return;
    }
    let mut worlds = wedge_worlds(2);
    let p0: Vec<Particles> = worlds
        .iter()
        .map(|s| s.sample_particles().expect("particles"))
        .collect();
    worlds[1].dx *= 0.5;
    let e = CudaBatch::new(&worlds, &p0, precise())
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("world 1 differs"), "{e}");
    // 8,000 worlds of a 4 m x 4 m floor (160 x 160 cells of grid each): far past the GPU's memory.
    let text = r#"
name = "wide"
[time]
duration = 0.1
fps = 10
dt = 1e-3
[domain]
min = [0.0, 0.0, 0.0]
max = [4.0, 0.3, 4.0]
dx = 0.025
[[material]]
name = "sand"
type = "drucker_prager"
density = 1600.0
youngs_modulus = 3.5e5
poisson_ratio = 0.3
friction_angle = 35.0
[[body]]
material = "sand"
shape = "box"
min = [1.9, 0.1, 1.9]
max = [2.0, 0.15, 2.0]
particles_per_cell = 1
"#;
    let one = Scene::from_toml(text, "wide").expect("scene");
    let p = one.sample_particles().expect("particles");
    let n = 8000;
    let t = Instant::now();
    let e = CudaBatch::new(&vec![one; n], &vec![p; n], CudaOptions::default())
        .err()
        .expect("refused")
        .to_string();
    println!("refused in {:.1} s: {e}", t.elapsed().as_secs_f64());
    assert!(
        e.contains("CUDA batch of 8000 worlds") && e.contains("GiB") && e.contains("free"),
        "{e}"
    );
}

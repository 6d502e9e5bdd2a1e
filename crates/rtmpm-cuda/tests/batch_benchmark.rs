//! The GPU batch's benchmark (`rtmpm_cuda::batch::CudaBatch`; ignored, needs a GPU): prints
//! particle-steps/s of a batch of sand beds, of one scene with as many particles and of the
//! worlds one after another (their steps only, and with each world's set-up: its backend built
//! in the same process), and a final table of the ratios:
//! `cargo test --release -p rtmpm-cuda --test batch_benchmark -- --include-ignored --nocapture`.

mod common;

use common::batch::sand_bed;
use common::gpu;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_cuda::{CudaBackend, CudaOptions};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::time::Instant;

/// Seconds of `steps` steps of `b` after 20 steps of warm-up, the GPU's work included (the
/// control words read back at the end wait for it).
fn time_steps(b: &mut dyn Backend, steps: usize) -> f64 {
    let dt = 2.5e-4;
    for s in 0..20 {
        b.step(dt, s as f32 * dt).expect("step");
    }
    b.max_speed().expect("sync");
    let t = Instant::now();
    for s in 20..20 + steps {
        b.step(dt, s as f32 * dt).expect("step");
    }
    b.max_speed().expect("sync");
    t.elapsed().as_secs_f64()
}

/// One world run as a user running the worlds one by one in one process pays it: its backend
/// built (checks, plan, the program from the kernel cache, the particles packed and uploaded)
/// and `steps` steps from its start (no warm-up: the first steps' graph capture is part of the
/// run), the GPU's work included. Returns (set-up seconds, whole-run seconds).
fn time_world_run(world: &Scene, p: &Particles, steps: usize) -> (f64, f64) {
    let dt = 2.5e-4;
    let t = Instant::now();
    let mut b = CudaBackend::new(world, p, CudaOptions::default()).expect("world");
    let setup = t.elapsed().as_secs_f64();
    for s in 0..steps {
        b.step(dt, s as f32 * dt).expect("step");
    }
    b.max_speed().expect("sync");
    let whole = t.elapsed().as_secs_f64();
    drop(b);
    (setup, whole)
}

/// `BATCH_WORLDS` (1024) sand beds of 9,408 particles: particle-steps/s batched, as one scene
/// of as many particles, and one after another (`BATCH_ALONE` worlds, 16, extrapolated).
#[test]
#[ignore = "needs a CUDA GPU; a benchmark"]
fn batch_benchmark() {
    if !gpu() {
        return;
    }
    let env = |k: &str, d: usize| {
        std::env::var(k)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let (n_worlds, steps, alone) = (
        env("BATCH_WORLDS", 1024),
        env("BATCH_STEPS", 200),
        env("BATCH_ALONE", 16),
    );
    let world = Scene::from_toml(&sand_bed(0.109375), "sand_bed").expect("sand bed");
    let p = world.sample_particles().expect("particles");
    let per = p.len();
    let t = Instant::now();
    let mut batch = CudaBatch::new(
        &vec![world.clone(); n_worlds],
        &vec![p.clone(); n_worlds],
        CudaOptions::default(),
    )
    .expect("batch");
    let setup = t.elapsed().as_secs_f64();
    let secs = time_steps(batch.backend(), steps);
    let total = (n_worlds * per) as f64;
    let batched = total * steps as f64 / secs;
    assert!(batch.bad_world().expect("check").is_none());
    drop(batch);

    // One scene of as many particles: a bed sqrt(n_worlds) times as wide each way.
    let half = 0.109375 * (n_worlds as f32).sqrt();
    let big = Scene::from_toml(&sand_bed(half), "sand_bed_big").expect("big bed");
    let bp = big.sample_particles().expect("particles");
    let mut one = CudaBackend::new(&big, &bp, CudaOptions::default()).expect("big scene");
    let big_secs = time_steps(&mut one, steps);
    let big_rate = bp.len() as f64 * steps as f64 / big_secs;
    drop(one);

    // One after another: `alone` worlds, each its own backend (its set-up not counted).
    let mut alone_secs = 0.0;
    for _ in 0..alone {
        let mut b = CudaBackend::new(&world, &p, CudaOptions::default()).expect("world");
        alone_secs += time_steps(&mut b, steps);
    }
    let alone_rate = (alone * per) as f64 * steps as f64 / alone_secs;

    // One after another with each world's set-up counted: built and run in turn (one world
    // built first, untimed, so that its program is in the kernel cache, as after a process's
    // first world).
    let _ = time_world_run(&world, &p, 1);
    let (mut alone_setup, mut alone_whole) = (0.0, 0.0);
    for _ in 0..alone {
        let (s, w) = time_world_run(&world, &p, steps);
        alone_setup += s;
        alone_whole += w;
    }
    let alone_setup_rate = (alone * per) as f64 * steps as f64 / alone_whole;
    println!("BENCH worlds {n_worlds} x {per} particles, {steps} steps, batch set-up {setup:.1} s");
    println!(
        "BENCH batched        {:>8.1} M particle-steps/s ({:.3} ms/step)",
        batched / 1e6,
        1e3 * secs / steps as f64
    );
    println!(
        "BENCH one big scene  {:>8.1} M particle-steps/s ({} particles, {:.3} ms/step)",
        big_rate / 1e6,
        bp.len(),
        1e3 * big_secs / steps as f64
    );
    println!(
        "BENCH one by one     {:>8.1} M particle-steps/s ({alone} worlds timed, extrapolated to {n_worlds}: {:.1} s a world-run of {steps} steps x {n_worlds})",
        alone_rate / 1e6,
        alone_secs / alone as f64 * n_worlds as f64
    );
    println!(
        "BENCH one by one with set-up {:>8.1} M particle-steps/s ({alone} worlds timed: {:.2} ms set-up + {:.2} ms for {steps} steps a world, extrapolated to {n_worlds}: {:.1} s)",
        alone_setup_rate / 1e6,
        1e3 * alone_setup / alone as f64,
        1e3 * (alone_whole - alone_setup) / alone as f64,
        alone_whole / alone as f64 * n_worlds as f64
    );
    println!(
        "BENCH batched / big scene {:.1} % (target >= 60 %), batched / one by one {:.1}x (target >= 20x)",
        100.0 * batched / big_rate,
        batched / alone_rate
    );
    // The ratios: the batch's steps against the worlds' steps, then against the worlds' set-up
    // and steps (what the target's rationale counts: N runs pay N set-ups), then whole runs of
    // `steps` steps with the batch's own set-up counted too.
    let batch_whole_rate = total * steps as f64 / (setup + secs);
    println!("BENCH table (target: batched at least 20x the worlds one after another)");
    println!(
        "BENCH | counted | batched M particle-steps/s | one after another | batched / one after another |"
    );
    for (what, a, b) in [
        ("steps only (both)", batched, alone_rate),
        (
            "one after another: each world's set-up and steps; batched: steps",
            batched,
            alone_setup_rate,
        ),
        (
            "set-up and steps (both: whole runs)",
            batch_whole_rate,
            alone_setup_rate,
        ),
    ] {
        println!(
            "BENCH | {what} | {:.1} | {:.1} | {:.1}x |",
            a / 1e6,
            b / 1e6,
            a / b
        );
    }
}

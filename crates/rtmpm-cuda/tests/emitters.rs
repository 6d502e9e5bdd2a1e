//! Emitters and keyframed colliders on the GPU against the CPU reference (needs a GPU; skips
//! with a message otherwise):
//! `cargo test --release -p rtmpm-cuda --test emitters -- --include-ignored --nocapture`.

use rtmpm_cpu::CpuBackend;
use rtmpm_cuda::{CudaBackend, CudaOptions, probe};
use rtmpm_driver::Simulation;
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use std::path::Path;

fn scene(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    Scene::from_file(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Run `frames` frames of `scene` on the CPU and on the GPU through `Simulation` (which emits);
/// after each frame the GPU's emitted water mass equals rate x t within one particle and the
/// particle counts agree; at the end the aggregates agree as in the agreement test.
fn compare(scene: &Scene, frames: u64, options: CudaOptions) {
    let p0 = scene.sample_particles().expect("particles");
    let cpu = CpuBackend::new(scene, p0.clone(), None).expect("cpu");
    let gpu = CudaBackend::new(scene, &p0, options).expect("cuda");
    let mut a = Simulation::new(scene.clone(), Box::new(cpu));
    let mut b = Simulation::new(scene.clone(), Box::new(gpu));
    let (mut pa, mut pb) = (Particles::default(), Particles::default());
    for _ in 0..frames {
        a.advance_frame().expect("cpu frame");
        b.advance_frame().expect("gpu frame");
        a.backend.read_particles(&mut pa).expect("read");
        b.backend.read_particles(&mut pb).expect("read");
        assert_eq!(pa.len(), pb.len(), "particle counts at t = {}", b.time);
        for (k, e) in scene.emitters.iter().enumerate() {
            let m = e.particle_mass as f64;
            let emitted: f64 = (p0.len()..pb.len())
                .filter(|&i| pb.material[i] == e.material)
                .map(|i| pb.mass[i] as f64)
                .sum();
            let expect = e.rate * (b.time.min(e.stop) - e.start).max(0.0) * m;
            assert!(
                (emitted - expect).abs() <= m * (1.0 + 1e-5) * (k + 1) as f64,
                "t = {}: GPU emitted {emitted} kg, rate x t = {expect} kg",
                b.time
            );
        }
    }
    let d = pa.aggregate_difference(&pb);
    let dx = scene.dx as f64;
    println!(
        "{}: {frames} frames, {} particles: |d com| {:.3} dx, KE {:.2} %, |d bbox| {:.2} dx",
        scene.name,
        pb.len(),
        d.com / dx,
        100.0 * d.kinetic,
        d.bbox / dx
    );
    assert!(d.com < 0.1 * dx && d.kinetic < 0.02, "{d:?}");
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn cuda_emits_as_the_cpu_does() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    let s = scene("fountain.toml");
    // Precise math for the comparison; the default (G2P2G, graphs) and the unfused pipeline.
    let precise = CudaOptions {
        fast_math: false,
        ..CudaOptions::default()
    };
    compare(&s, 6, precise.clone());
    compare(
        &s,
        6,
        CudaOptions {
            g2p2g: false,
            graph: false,
            ..precise
        },
    );
}

#[test]
#[ignore = "needs a CUDA GPU"]
fn cuda_keyframed_paddle_agrees_with_the_cpu() {
    if let Err(e) = probe() {
        println!("skipped: no usable CUDA GPU ({e})");
        return;
    }
    // 0.5 s: lowered into the honey and a fifth of a turn.
    let s = scene("paddle.toml");
    compare(
        &s,
        15,
        CudaOptions {
            fast_math: false,
            ..CudaOptions::default()
        },
    );
}

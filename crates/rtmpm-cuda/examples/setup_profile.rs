//! Where the set-up of a scene goes on the host, phase by phase (no GPU needed): sampling the
//! bodies, the CUDA backend's host work before its upload (stencil bases, block layout,
//! capacity plan, state packing) and the CPU backend's construction, each with its wall time
//! and the process's resident memory after it.
//!
//! `lean`: the CUDA image packed straight from the sampled positions (`state::pack_bodies`, no
//! `Particles` on the host), with the stencil bases from the positions.
//!
//! `device`: the host's share of `CudaBackend::from_bodies` with the device fill (the default):
//! the block counts from the positions, the initial speed, the fill table, and the gathering of
//! every piece of positions into one reused buffer (the page-locked buffers' role).
//!
//! `cargo run --release -p rtmpm-cuda --example setup_profile -- SCENE.toml [cpu|cuda|lean|device]`
//! (cpu and cuda by default; `RAYON_NUM_THREADS` sets the threads).

use rtmpm_physics::grid::BlockLayout;
use rtmpm_scene::Scene;
use std::time::Instant;

/// Resident memory now and at its peak (MB), from `/proc/self/status`.
fn rss() -> (f64, f64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|kb| kb.parse::<f64>().ok())
            .map_or(f64::NAN, |kb| kb / 1e3)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

fn phase(name: &str, start: Instant) {
    let (now, peak) = rss();
    println!(
        "  {name:<22} {:>8.3} s   resident {now:>9.1} MB (peak {peak:.1} MB)",
        start.elapsed().as_secs_f64()
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or("usage: setup_profile SCENE.toml [cpu] [cuda]")?;
    let want =
        |w: &str| (args.len() < 2 && w != "lean" && w != "device") || args.iter().any(|a| a == w);
    let total = Instant::now();
    let t = Instant::now();
    let scene = Scene::from_file(std::path::Path::new(path))?;
    phase("parse", t);
    let fluid = rtmpm_cuda::state::fluid_materials(&scene);
    let state_layout = rtmpm_cuda::state::layout_for(&scene, &rtmpm_cuda::CudaOptions::default())?;
    if want("device") {
        let t = Instant::now();
        let bodies = rtmpm_scene::sampling::sample_bodies(&scene, &|_| {})?;
        phase("device: sample bodies", t);
        let n: usize = bodies.iter().map(|b| b.len()).sum();
        let t = Instant::now();
        let blocks = rtmpm_cuda::setup::capacity::block_counts(&scene, &bodies);
        phase("device: block counts", t);
        let needed = rtmpm_cuda::setup::capacity::Capacity::needs_block_counts(
            &scene,
            &rtmpm_cuda::CudaOptions::default(),
        );
        println!(
            "  (the backend counts blocks only when the domain's grid does not fit: {needed})"
        );
        let t = Instant::now();
        let speed = rtmpm_cuda::state::max_speed(&bodies);
        phase("device: initial speed", t);
        let t = Instant::now();
        let rows = rtmpm_cuda::setup::fill::table(&bodies, &fluid, state_layout, false)?;
        phase("device: fill table", t);
        let t = Instant::now();
        let pieces = rtmpm_cuda::setup::fill::pieces(&bodies, rtmpm_cuda::setup::fill::PIECE);
        let most = pieces.iter().map(|p| p.len).max().unwrap_or(0);
        let mut buf = vec![0f32; 3 * most];
        for p in &pieces {
            if let rtmpm_scene::sampling::SampledBody::Shape(b) = &bodies[p.body] {
                rtmpm_cuda::setup::fill::gather(b, p.offset, p.len, &mut buf);
            }
        }
        phase("device: gather pieces", t);
        println!(
            "  {n} particles, {} pieces, blocks {blocks:?}, speed {speed}, table {} words",
            pieces.len(),
            rows.len()
        );
        let (_, peak) = rss();
        println!(
            "  total {:.3} s, peak resident {peak:.1} MB = {:.1} bytes/particle",
            total.elapsed().as_secs_f64(),
            peak * 1e6 / n.max(1) as f64
        );
        return Ok(());
    }
    if want("lean") {
        let t = Instant::now();
        let bodies = rtmpm_scene::sampling::sample_bodies(&scene, &|_| {})?;
        phase("lean: sample bodies", t);
        let n: usize = bodies.iter().map(|b| b.len()).sum();
        let t = Instant::now();
        let state = rtmpm_cuda::state::pack_bodies(&bodies, &fluid, state_layout, false)?;
        phase("lean: pack bodies", t);
        println!("  {n} particles, packed {:.1} MB", state.len() as f64 / 1e6);
        let (_, peak) = rss();
        println!(
            "  total {:.3} s, peak resident {peak:.1} MB = {:.1} bytes/particle",
            total.elapsed().as_secs_f64(),
            peak * 1e6 / n.max(1) as f64
        );
        return Ok(());
    }
    let t = Instant::now();
    let particles = scene.sample_particles()?;
    phase("sample", t);
    let n = particles.len();
    println!("  {n} particles, {} threads", rayon::current_num_threads());
    if want("cuda") {
        let t = Instant::now();
        let bases = rtmpm_cuda::setup::capacity::bases(&scene, &particles);
        phase("cuda: bases", t);
        let t = Instant::now();
        let mut layout = BlockLayout::default();
        layout.rebuild(&bases);
        phase("cuda: layout", t);
        let t = Instant::now();
        let state = rtmpm_cuda::state::pack(&particles, &fluid, state_layout, false, n, None)?;
        phase("cuda: pack", t);
        println!("  packed {:.1} MB", state.len() as f64 / 1e6);
        drop((state, layout, bases));
    }
    if want("cpu") {
        let t = Instant::now();
        let b = rtmpm_cpu::CpuBackend::new(&scene, particles, None)?;
        phase("cpu: backend", t);
        drop(b);
    }
    let (_, peak) = rss();
    println!(
        "  total {:.3} s, peak resident {peak:.1} MB = {:.1} bytes/particle",
        total.elapsed().as_secs_f64(),
        peak * 1e6 / n.max(1) as f64
    );
    Ok(())
}

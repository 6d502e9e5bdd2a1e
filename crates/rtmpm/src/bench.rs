//! `rtmpm bench`: the classic MLS-MPM fluid block (mpm88/mpm3d): n^3/4 particles at uniformly
//! random positions in [0.15, 0.55]^3 of the unit cube, dx = 1/n, walls 3 cells thick that remove
//! inward normal velocity, linear weakly compressible fluid (K = 400, density 1), gravity 9.8
//! down, fixed dt.

use crate::backend::{BackendKind, make_backend};
use crate::run::human_rate;
use anyhow::{Result, bail};
use clap::Args;
use rtmpm_core::Scene;
use rtmpm_core::sim::Simulation;
use std::time::Instant;

#[derive(Args)]
pub struct BenchArgs {
    /// Grid resolution n (dx = 1/n, n^3/4 particles).
    #[arg(long, default_value_t = 64)]
    pub n: u32,
    /// Timed steps (after warm-up).
    #[arg(long, default_value_t = 500)]
    pub steps: u64,
    /// Untimed warm-up steps.
    #[arg(long, default_value_t = 20)]
    pub warmup: u64,
    /// Backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// CPU worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// The fixed time step of the classic scene at resolution n.
fn fluid_block_dt(n: u32) -> f32 {
    match n {
        0..=64 => 2e-4,
        65..=128 => 8e-5,
        _ => 4e-5,
    }
}

/// Scene text of the fluid block at resolution `n`.
pub fn fluid_block_scene(n: u32) -> String {
    format!(
        r#"name = "bench_fluid_n{n}"
seed = 0
gravity = [0.0, -9.8, 0.0]
[domain]
min = [0.0, 0.0, 0.0]
max = [1.0, 1.0, 1.0]
dx = {dx:e}
[time]
duration = 10.0
fps = 50
dt = {dt:e}
[walls]
thickness = 3
condition = "separate"
[[material]]
name = "fluid"
type = "fluid"
density = 1.0
bulk_modulus = 400.0
eos = "linear"
[[body]]
material = "fluid"
shape = "box"
min = [0.15, 0.15, 0.15]
max = [0.55, 0.55, 0.55]
sampling = "random"
count = {count}
"#,
        dx = 1.0 / n as f64,
        dt = fluid_block_dt(n),
        count = (n as u64).pow(3) / 4,
    )
}

pub fn bench(args: BenchArgs) -> Result<()> {
    if !(8..=1024).contains(&args.n) {
        bail!("--n {} is out of range: use 8..=1024", args.n);
    }
    let scene = Scene::from_toml(&fluid_block_scene(args.n), "<bench fluid block>")?;
    let particles = scene.sample_particles()?;
    let n = particles.len();
    let dt = fluid_block_dt(args.n);
    let backend = make_backend(args.backend, &scene, particles, args.threads)?;
    let mut sim = Simulation::new(scene, backend);
    for _ in 0..args.warmup {
        sim.step_once(dt)?;
    }
    sim.check()?;
    let before: Vec<f64> = sim.backend.stage_times().iter().map(|s| s.1).collect();
    let start = Instant::now();
    for _ in 0..args.steps {
        sim.step_once(dt)?;
    }
    sim.check()?;
    let wall = start.elapsed().as_secs_f64();
    let rate = n as f64 * args.steps as f64 / wall;
    println!(
        "benchmark: MLS-MPM fluid block, n = {} (dx = 1/{}), dt = {dt:e}",
        args.n, args.n
    );
    println!("  backend      {}", sim.backend.name());
    println!("  particles    {n}");
    println!(
        "  steps        {} timed after {} warm-up",
        args.steps, args.warmup
    );
    println!(
        "  wall time    {wall:.3} s ({:.3} ms/step)",
        1e3 * wall / args.steps as f64
    );
    println!(
        "  throughput   {} ({rate:.4e} particle-steps/s)",
        human_rate(rate)
    );
    for ((name, total), b) in sim.backend.stage_times().into_iter().zip(before) {
        println!(
            "  stage        {name:<12} {:.3} ms/step",
            1e3 * (total - b) / args.steps as f64
        );
    }
    Ok(())
}

//! `rtmpm bench`: the classic MLS-MPM fluid block (mpm88/mpm3d): n^3/4 particles at uniformly
//! random positions in [0.15, 0.55]^3 of the unit cube, dx = 1/n, walls 3 cells thick that remove
//! inward normal velocity, linear weakly compressible fluid (K = 400, density 1), gravity 9.8
//! down, fixed dt.

use crate::backend::{BackendKind, make_backend};
use anyhow::{Result, bail};
use clap::Args;
use rtmpm_driver::Simulation;
use rtmpm_driver::progress::human_rate;
use rtmpm_physics::Particles;
use rtmpm_scene::sampling::SampledBody;
use rtmpm_scene::{Scene, StepMode};
use std::time::Instant;

#[derive(Args)]
pub struct BenchArgs {
    /// Grid resolution n (dx = 1/n, n^3/4 particles), 20 to 1600: below 20 the 3-cell walls
    /// reach into the block at 0.15; the memory budget refuses what does not fit.
    #[arg(long, default_value_t = 64)]
    pub n: u32,
    /// Timed steps (after warm-up).
    #[arg(long, default_value_t = 500)]
    pub steps: u64,
    /// Benchmark this scene file instead of the fluid block (needs a fixed `time.dt`).
    #[arg(long)]
    pub scene: Option<std::path::PathBuf>,
    /// Timed frames of the scene (overrides --steps).
    #[arg(long)]
    pub frames: Option<u64>,
    /// Untimed warm-up steps.
    #[arg(long, default_value_t = 20)]
    pub warmup: u64,
    /// Backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// CUDA backend switches, e.g. `free_zone=off,warp_reduce=off,graph=off`; P2G strategy
    /// `p2g=warp|shared|reverse_map|sort`.
    #[arg(long, value_name = "LIST", default_value = "")]
    pub cuda_options: rtmpm_cuda::CudaOptions,
    /// Floating-point precision of the whole step: f32 or f64 (default: the scene's
    /// `[solver] precision`, else f32).
    #[arg(long, value_name = "f32|f64")]
    pub precision: Option<rtmpm_scene::Precision>,
    /// CPU worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Several GPUs of this machine (CUDA; peer-to-peer or NCCL): also times the shared-block reduction.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub gpus: usize,
    /// After the timing, measure frame writing into this folder: the copy of a frame's columns
    /// out of the backend (GB/s), encoding and writing the files (MB/s), and the step time with
    /// a frame written in the background (one GPU or the CPU).
    #[arg(long, value_name = "DIR")]
    pub frame_write: Option<std::path::PathBuf>,
    /// Formats of --frame-write: `ply`, `bgeo`, `bgeo.gz`, comma separated.
    #[arg(long, value_name = "LIST", default_value = "ply")]
    pub frame_formats: String,
    /// Particles per chunk of --frame-write.
    #[arg(long, value_name = "N", default_value_t = rtmpm_driver::stream::DEFAULT_CHUNK)]
    pub frame_chunk: usize,
    /// With --frame-write, also time the whole-frame path (every field of every particle read
    /// to the host, then the files written in this thread): host memory for two copies of the
    /// state.
    #[arg(long)]
    pub frame_whole: bool,
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
    let (scene, label) = bench_scene(&args)?;
    let mut scene = scene;
    if let Some(p) = args.precision {
        scene.precision = p;
    }
    let StepMode::Fixed { dt } = scene.time.step else {
        bail!("benchmarks need a fixed time step: set `time.dt` in the scene");
    };
    let per_frame = (1.0 / (scene.time.fps as f64 * dt as f64)).round() as u64;
    let steps = args.frames.map_or(args.steps, |f| f * per_frame);
    let use_cuda = match args.backend {
        BackendKind::Cpu => false,
        BackendKind::Cuda => true,
        BackendKind::Auto => rtmpm_cuda::probe().is_ok(),
    };
    // One GPU: the bodies are packed straight from their sampled positions (no particles on
    // the host), so the host needs the CUDA estimate only.
    let lean = use_cuda && args.gpus <= 1;
    // Memory first: a scene that cannot fit is refused before it is sampled.
    crate::budget::enforce_for(
        &scene,
        Some(1),
        None,
        lean.then_some(&args.cuda_options),
        None,
        None,
    )?;
    if lean {
        let o = &args.cuda_options;
        let defer = o.device_fill && o.device_sample;
        let (bodies, sample_s) = rtmpm_driver::setup::sample_bodies(&scene, defer)?;
        let setup = rtmpm_driver::setup::SetupTimes {
            sample: sample_s,
            backend: 0.0,
        };
        print_header(&label, dt, steps, per_frame);
        return bench_cuda(&args, &scene, bodies, dt, steps, setup);
    }
    let (particles, sample_s) = rtmpm_driver::setup::sample(&scene)?;
    let mut setup = rtmpm_driver::setup::SetupTimes {
        sample: sample_s,
        backend: 0.0,
    };
    let n = particles.len();
    print_header(&label, dt, steps, per_frame);
    if use_cuda {
        return bench_multi_gpu(&args, &scene, &particles, dt, steps, setup);
    }
    if args.gpus > 1 {
        bail!("--gpus {} needs the CUDA backend", args.gpus);
    }
    if args.cuda_options != rtmpm_cuda::CudaOptions::default() {
        eprintln!(
            "warning: --cuda-options are switches of the CUDA backend; this benchmark runs on \
             the CPU backend, which ignores them"
        );
    }
    let t = Instant::now();
    let backend = make_backend(
        BackendKind::Cpu,
        &scene,
        particles,
        args.threads,
        &args.cuda_options,
    )?;
    setup.backend = t.elapsed().as_secs_f64();
    let mut sim = Simulation::new(scene, backend);
    for _ in 0..args.warmup {
        sim.step_once(dt)?;
    }
    sim.check()?;
    let before: Vec<f64> = sim.backend.stage_times().iter().map(|s| s.1).collect();
    let start = Instant::now();
    for _ in 0..steps {
        sim.step_once(dt)?;
    }
    sim.check()?;
    let wall = start.elapsed().as_secs_f64();
    let rate = n as f64 * steps as f64 / wall;
    println!("  backend      {}", sim.backend.name());
    println!("  particles    {n}");
    println!("  set-up       {} before the first step", setup.describe());
    println!("  steps        {steps} timed after {} warm-up", args.warmup);
    println!(
        "  wall time    {wall:.3} s ({:.3} ms/step)",
        1e3 * wall / steps as f64
    );
    println!(
        "  throughput   {} ({rate:.4e} particle-steps/s)",
        human_rate(rate)
    );
    for ((name, total), b) in sim.backend.stage_times().into_iter().zip(before) {
        println!(
            "  stage        {name:<12} {:.3} ms/step",
            1e3 * (total - b) / steps as f64
        );
    }
    let arrays = sim.backend.memory_bytes().map(|m| m.0);
    print_memory(n, arrays, None);
    if let Some(dir) = &args.frame_write {
        crate::bench_frames::frame_write_bench(
            sim.backend.as_mut(),
            dt,
            steps,
            dir,
            &args.frame_formats,
            args.frame_chunk,
            args.frame_whole,
        )?;
    }
    Ok(())
}

/// The benchmark's scene and its name in the report: the scene file given, else the fluid
/// block of side `--n` cells.
fn bench_scene(args: &BenchArgs) -> Result<(Scene, String)> {
    Ok(match &args.scene {
        Some(path) => (Scene::from_file(path)?, format!("scene {}", path.display())),
        None => {
            if !(20..=1600).contains(&args.n) {
                bail!(
                    "--n {} is out of range: use 20..=1600 (below 20 the walls, 3 cells thick, \
                     reach into the fluid block at 0.15; 1600 is already 1.0e9 particles)",
                    args.n
                );
            }
            let text = fluid_block_scene(args.n);
            let label = format!("MLS-MPM fluid block, n = {} (dx = 1/{})", args.n, args.n);
            (Scene::from_toml(&text, "<bench fluid block>")?, label)
        }
    })
}

/// The first line of a benchmark's report.
fn print_header(label: &str, dt: f32, steps: u64, per_frame: u64) {
    println!(
        "benchmark: {label}, dt = {dt:e}, {steps} steps ({} frames of {per_frame})",
        steps / per_frame.max(1)
    );
}

/// Peak resident memory of this process (bytes): `VmHWM` of `/proc/self/status` (Linux).
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The memory lines of a benchmark: bytes per particle on the host (peak resident memory of
/// the process, and the backend's own arrays where it counts them) and on the device.
fn print_memory(n: usize, host_arrays: Option<u64>, device: Option<u64>) {
    let per = |bytes: u64| bytes as f64 / n.max(1) as f64;
    if let Some(d) = device {
        println!(
            "  memory       device {:.1} bytes/particle ({:.1} MB: every allocation of the backend)",
            per(d),
            d as f64 / 1e6
        );
    }
    match peak_rss_bytes() {
        Some(h) => print!(
            "  memory       host {:.1} bytes/particle (peak resident {:.1} MB, whole process)",
            per(h),
            h as f64 / 1e6
        ),
        None => print!("  memory       host: peak resident memory unknown (no /proc/self/status)"),
    }
    match host_arrays {
        Some(a) => println!(
            "; backend arrays {:.1} bytes/particle ({:.1} MB)",
            per(a),
            a as f64 / 1e6
        ),
        None => println!(),
    }
}

/// CUDA: whole-run throughput (graph replay when enabled), then per-kernel event timing and the
/// fraction of the memory-bandwidth floor.
fn bench_cuda(
    args: &BenchArgs,
    scene: &Scene,
    bodies: Vec<SampledBody>,
    dt: f32,
    steps: u64,
    mut setup: rtmpm_driver::setup::SetupTimes,
) -> Result<()> {
    use rtmpm_sim::Backend;
    rtmpm_cuda::probe().map_err(|e| anyhow::anyhow!("the CUDA backend is not usable here: {e}"))?;
    let n: usize = bodies.iter().map(|b| b.len()).sum();
    let t = Instant::now();
    let mut b = rtmpm_cuda::CudaBackend::from_bodies(scene, &bodies, args.cuda_options.clone())?;
    // The positions are on the device now: the host frees them (12 bytes a particle).
    drop(bodies);
    setup.backend = t.elapsed().as_secs_f64();
    // The first step (waited for): it builds the first mapping and sort on the device.
    let mut first_step = None;
    for i in 0..args.warmup {
        let t = Instant::now();
        b.step(dt, i as f32 * dt)?;
        if i == 0 {
            b.check()?;
            first_step = Some(t.elapsed().as_secs_f64());
        }
    }
    b.check()?;
    let start = Instant::now();
    for i in 0..steps {
        b.step(dt, (args.warmup + i) as f32 * dt)?;
    }
    if let Some(bad) = b.check()? {
        bail!("the benchmark blew up (particle {})", bad.index);
    }
    let wall = start.elapsed().as_secs_f64();
    let rate = n as f64 * steps as f64 / wall;
    println!("  backend      {} [{:?}]", b.name(), args.cuda_options);
    println!("  particles    {n}");
    println!(
        "  set-up       {} before the first step (backend: {})",
        setup.describe(),
        b.setup_phases()
    );
    if let Some(s) = first_step {
        println!("  first step   {s:.2} s (the first mapping and sort, on the device)");
    }
    println!("  steps        {steps} timed after {} warm-up", args.warmup);
    println!(
        "  wall time    {wall:.3} s ({:.4} ms/step)",
        1e3 * wall / steps as f64
    );
    println!(
        "  throughput   {} ({rate:.4e} particle-steps/s)",
        human_rate(rate)
    );
    let k = rtmpm_cuda::bench_kernels(&mut b, dt, 0, steps.min(400) as u32)?;
    let bw = rtmpm_cuda::measure_copy_bandwidth()?;
    let floor_ms = k.bytes_per_step as f64 / (bw * 1e9) * 1e3;
    print_kernel_stages(&k);
    print_device_memory(args, &b, &k, n);
    println!(
        "  bandwidth    {:.1} MB/step must move; copy bandwidth {bw:.0} GB/s -> floor {floor_ms:.4} ms/step = {:.0} % of the evented step",
        k.bytes_per_step as f64 / 1e6,
        100.0 * floor_ms / k.ms_per_step.max(1e-12)
    );
    if let Some(dir) = &args.frame_write {
        crate::bench_frames::frame_write_bench(
            &mut b,
            dt,
            steps,
            dir,
            &args.frame_formats,
            args.frame_chunk,
            args.frame_whole,
        )?;
    }
    Ok(())
}

/// The evented time of each stage of the step, in the order the step ran them (the MUSL
/// re-map only on MUSL scenes), and of P2G's phases where it has several.
fn print_kernel_stages(k: &rtmpm_cuda::KernelTimings) {
    println!(
        "  kernels      (CUDA events, {} steps, {} rebuilds)",
        k.steps, k.rebuilds
    );
    // With G2P2G the P2G kernel runs only after a rebuild; the fused kernel does the rest.
    let g2p_name = if k.g2p2g { "g2p2g" } else { "g2p" };
    // The stages in the order the step ran them (the MUSL re-map only on MUSL scenes).
    for stage in &k.stages {
        let (name, ms) = match *stage {
            "rebuild" => ("rebuild", k.rebuild_ms),
            "p2g" => ("p2g", k.p2g_ms),
            "grid_update" => ("grid_update", k.grid_update_ms),
            "musl_remap" => ("musl_remap", k.musl_ms),
            _ => (g2p_name, k.g2p_ms),
        };
        println!(
            "    {name:<12} {ms:.4} ms/step ({:.0} %)",
            100.0 * ms / k.ms_per_step.max(1e-12)
        );
        if name == "p2g" && k.p2g_phases.len() > 1 {
            for (phase, ms) in &k.p2g_phases {
                println!("      p2g.{phase:<10} {ms:.4} ms/step");
            }
        }
    }
    println!("    step         {:.4} ms/step", k.ms_per_step);
}

/// The CUDA backend's memory: P2G's extra arrays and the grid, the device's bytes per particle
/// by array, the reverse map's size.
fn print_device_memory(
    args: &BenchArgs,
    b: &rtmpm_cuda::CudaBackend,
    k: &rtmpm_cuda::KernelTimings,
    n: usize,
) {
    let extra: usize = k.p2g_memory.iter().map(|m| m.1).sum();
    let parts: Vec<String> = k
        .p2g_memory
        .iter()
        .map(|(what, bytes)| format!("{what} {:.1}", *bytes as f64 / 1e6))
        .collect();
    println!(
        "  p2g memory   {:?}: {:.1} MB extra ({}); grid {:.1} MB",
        args.cuda_options.p2g,
        extra as f64 / 1e6,
        if parts.is_empty() {
            "none".to_string()
        } else {
            parts.join(", ") + " MB"
        },
        b.grid_bytes() as f64 / 1e6
    );
    print_memory(n, None, Some(b.device_bytes() as u64));
    let parts: Vec<String> = b
        .memory_breakdown()
        .iter()
        .map(|(what, bytes)| format!("{what} {:.1}", *bytes as f64 / n.max(1) as f64))
        .collect();
    println!("  device       bytes/particle: {}", parts.join(", "));
    if let Some(r) = b.reverse_map_size() {
        println!(
            "  reverse map  {} maps x {} entries per node, {} pblocks",
            r.replicas, r.slots, r.pblocks
        );
    }
}

/// Several GPUs: whole-run throughput (graph replay), then up to 200 steps with events around the
/// shared-block reduction (no graph, one synchronisation per step).
fn bench_multi_gpu(
    args: &BenchArgs,
    scene: &Scene,
    particles: &Particles,
    dt: f32,
    steps: u64,
    mut setup: rtmpm_driver::setup::SetupTimes,
) -> Result<()> {
    use rtmpm_sim::Backend;
    let n = particles.len();
    let t = Instant::now();
    let mut b =
        rtmpm_cuda::MultiGpuBackend::new(scene, particles, args.gpus, args.cuda_options.clone())?;
    setup.backend = t.elapsed().as_secs_f64();
    for i in 0..args.warmup {
        b.step(dt, i as f32 * dt)?;
    }
    b.check()?;
    let start = Instant::now();
    for i in 0..steps {
        b.step(dt, (args.warmup + i) as f32 * dt)?;
    }
    if let Some(bad) = b.check()? {
        bail!("the benchmark blew up (particle {})", bad.index);
    }
    let wall = start.elapsed().as_secs_f64();
    let rate = n as f64 * steps as f64 / wall;
    let shared = b.shared_blocks()?;
    let counts = b.counts()?;
    println!("  backend      {} [{:?}]", b.name(), args.cuda_options);
    println!("  particles    {n} ({counts:?} per GPU)");
    println!("  set-up       {} before the first step", setup.describe());
    println!("  steps        {steps} timed after {} warm-up", args.warmup);
    println!(
        "  wall time    {wall:.3} s ({:.4} ms/step)",
        1e3 * wall / steps as f64
    );
    println!(
        "  throughput   {} ({rate:.4e} particle-steps/s)",
        human_rate(rate)
    );
    let t0 = (args.warmup + steps) as f32 * dt;
    let k = steps.min(200) as u32;
    let (step_ms, reduce_ms) = b.time_reduction(dt, t0, k)?;
    println!(
        "  reduction    {reduce_ms:.4} ms/step ({}, {shared} shared blocks = {:.1} MB; evented step {step_ms:.4} ms, {k} steps)",
        b.reduction_steps(),
        shared as f64 * 1024.0 / 1e6
    );
    Ok(())
}

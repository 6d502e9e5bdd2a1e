//! `rtmpm run SCENE`: simulate frames with a progress bar, write output, checkpoints.

use crate::backend::{BackendKind, make_backend, make_backend_from_bodies};
use crate::render::RunRenderer;
use anyhow::{Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rtmpm_driver::Simulation;
use rtmpm_driver::outdir::{OutDir, scene_identity};
use rtmpm_driver::output::FrameOutput;
use rtmpm_driver::progress::{RANK_CHUNK, human_rate};
use rtmpm_driver::run::{Run, RunHooks, RunOptions, RunStart, RunStats};
use rtmpm_driver::setup::SetupTimes;
use rtmpm_geometry::surface::TriMesh;
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct RunArgs {
    /// Scene file (TOML). Optional with --resume (the checkpoint holds its scene; a file given with it must be that scene)
    pub scene: Option<PathBuf>,
    /// Backend.
    #[arg(long, value_enum, default_value_t = BackendKind::Auto)]
    pub backend: BackendKind,
    /// Output folder (default: the scene's `output.dir`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Number of frames to simulate (default: the scene's duration x fps).
    #[arg(long)]
    pub frames: Option<u64>,
    /// Stop after this many steps (a partial last frame is not written).
    #[arg(long)]
    pub steps: Option<u64>,
    /// CPU worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write a checkpoint every N frames: OUT/checkpoint_NNNNN.ckpt (of a batch scene: the
    /// folder OUT/checkpoint_NNNNN/, every world).
    #[arg(long, value_name = "N")]
    pub checkpoint_every: Option<u64>,
    /// Continue from a checkpoint written by --checkpoint-every (of a batch: its
    /// checkpoint_NNNNN folder, with the batch's scene file: `rtmpm run SCENE --resume DIR`).
    #[arg(long, value_name = "CKPT")]
    pub resume: Option<PathBuf>,
    /// CUDA backend switches, e.g. `free_zone=off,warp_reduce=off,graph=off`; P2G strategy
    /// `p2g=warp|shared|reverse_map|sort`.
    #[arg(long, value_name = "LIST", default_value = "")]
    pub cuda_options: rtmpm_cuda::CudaOptions,
    /// Floating-point precision of the whole step: f32 or f64 (default: the scene's
    /// `[solver] precision`, else f32).
    #[arg(long, value_name = "f32|f64")]
    pub precision: Option<rtmpm_scene::Precision>,
    /// Write no frame files (for timing).
    #[arg(long)]
    pub no_output: bool,
    /// Frames written in the background while the simulation steps on, when the frames are
    /// PLY and BGEO only (0: the next step waits for each frame's files). Host memory: the
    /// columns of about this many frames (32 bytes a particle for PLY, 40 for BGEO).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub frames_in_flight: usize,
    /// Particles per chunk when frames are streamed from the backend.
    #[arg(long, value_name = "N", default_value_t = rtmpm_driver::stream::DEFAULT_CHUNK)]
    pub frame_chunk: usize,
    /// Write each frame from a whole copy of the particles, in this thread (as before frames
    /// were streamed; the same files).
    #[arg(long)]
    pub whole_frames: bool,
    /// Remove the files of a previous run in the output folder first (frames, frames.pvd,
    /// checkpoints, movies; nothing else). Without it a folder holding another run is refused.
    #[arg(long)]
    pub overwrite: bool,
    /// Render every frame to OUT/frame_NNNNN.png while simulating, then movie.gif (and
    /// movie.mp4 when ffmpeg is on the PATH).
    #[arg(long)]
    pub render: bool,
    /// Rewrite this PNG after every frame (atomically): a live preview for an image viewer.
    #[arg(long, value_name = "PNG")]
    pub preview: Option<PathBuf>,
    #[command(flatten)]
    pub view: crate::render::ViewArgs,
    #[command(flatten)]
    pub multi: crate::multi::MultiGpuArgs,
}

pub fn run(args: RunArgs) -> Result<()> {
    if args.checkpoint_every == Some(0) {
        bail!(
            "--checkpoint-every 0 would write no checkpoint\n  fix: give --checkpoint-every N \
             (a checkpoint every N frames, N from 1), or leave it out"
        );
    }
    let mut start = RunStart::load(args.scene.as_deref(), args.resume.as_deref())?;
    if let Some(p) = args.precision {
        start.scene.precision = p;
    }
    let out_dir = args
        .out
        .clone()
        .unwrap_or_else(|| start.scene.output.dir.clone());
    // Multi-process runs: rank 0 writes the files; every rank gathers the particles at the same
    // points (a collective), so every rank must be given the same options.
    let writer = args.multi.writes_output();
    let writes_frames = writer && !args.no_output;
    let mode = args.multi.mode()?;
    // A fresh run on one GPU (or `auto`) packs the bodies straight from their sampled positions.
    let from_bodies = start.resume.is_none()
        && mode == crate::multi::Mode::Single
        && args.backend != BackendKind::Cpu;
    // PLY and BGEO frames stream from the backend in chunks, written in the background;
    // not across processes: there every rank reads the particles (a collective).
    let stream = !matches!(mode, crate::multi::Mode::Rank { .. })
        && !args.whole_frames
        && !args.render
        && args.preview.is_none();
    enforce_budget(&args, &start, &out_dir, writes_frames, stream, from_bodies)?;
    // A resumed run's rows of bodies.csv, checked before anything in the folder changes.
    if writes_frames {
        start.check_bodies_csv(&out_dir)?;
    }
    let RunStart {
        scene,
        scene_text,
        particles,
        resume,
    } = start;
    // The output folder: locked for this run, and holding no other run's files.
    let identity = scene_identity(&scene.name, &scene_text);
    // Held (the lock) until the run ends.
    let _folder = if writer && (writes_frames || args.render || args.checkpoint_every.is_some()) {
        let folder = OutDir::lock(&out_dir, &format!("rtmpm run of `{}`", scene.name))?;
        match &resume {
            None => folder.start_fresh(&identity, args.overwrite)?,
            Some(r) => folder.start_resume(&identity, r.frame, args.overwrite)?,
        }
        Some(folder)
    } else {
        None
    };
    let mut setup = SetupTimes::default();
    let (backend, n) = if from_bodies {
        run_backend_from_bodies(&args, &scene, &mut setup)?
    } else {
        let particles = match resume {
            Some(_) => particles,
            None => {
                let (p, seconds) = rtmpm_driver::setup::sample(&scene)?;
                setup.sample = seconds;
                p
            }
        };
        let start = Instant::now();
        let b = particle_backend(&args, mode, &scene, particles)?;
        setup.backend = start.elapsed().as_secs_f64();
        b
    };
    if backend.name().starts_with("cpu") && args.cuda_options != rtmpm_cuda::CudaOptions::default()
    {
        eprintln!(
            "warning: --cuda-options are switches of the CUDA backend; the run is on `{}`, which \
             ignores them",
            backend.name()
        );
    }
    let options = RunOptions {
        frames: args.frames,
        steps: args.steps,
        checkpoint_every: args.checkpoint_every,
        out_dir: out_dir.clone(),
        writer,
        write_frames: writes_frames,
        read_frames: !args.no_output,
        stream,
        frame_chunk: args.frame_chunk,
        frames_in_flight: args.frames_in_flight,
        collect: args.render || args.preview.is_some(),
        // Across processes every rank must take its steps in the same chunks: the health check
        // at the end of a chunk is a collective, so a chunk sized by each rank's own clock would
        // pair one rank's check with another's step and hang them (rank 0 alone writes the
        // frames, so its clock differs).
        fixed_chunk: matches!(mode, crate::multi::Mode::Rank { .. }).then_some(RANK_CHUNK),
    };
    let sim = Simulation::new(scene, backend);
    let mut run = Run::new(sim, n, scene_text, &identity, resume.as_ref(), options)?;
    announce(&run, n, &setup);
    let mut hooks = CliHooks {
        renderer: RunRenderer::new(
            args.render && writer,
            args.preview.clone().filter(|_| writer),
            &args.view,
            &out_dir,
            &run.sim.scene,
        ),
        bar: progress_bar(writer, run.total_frames(), run.sim.frame),
    };
    let stats = run.execute(&mut hooks)?;
    let rendered = hooks
        .renderer
        .map(RunRenderer::finish)
        .transpose()?
        .flatten();
    summary(&run, n, &stats, rendered);
    Ok(())
}

/// The budget before anything is sampled or allocated: refused with numbers and a fix (the
/// host's bytes of a CUDA run built from the positions when the CUDA backend is asked for: the
/// positions alone when the device fills the state, `fill=device`, the default), with the
/// background frame writer's buffers when frames are streamed, and a resumed run's particles.
fn enforce_budget(
    args: &RunArgs,
    start: &RunStart,
    out_dir: &std::path::Path,
    writes_frames: bool,
    stream: bool,
    from_bodies: bool,
) -> Result<()> {
    if args.frame_chunk == 0 {
        bail!(
            "--frame-chunk 0: a chunk holds at least one particle (the default is {})",
            rtmpm_driver::stream::DEFAULT_CHUNK
        );
    }
    let scene = &start.scene;
    // The background frame writer's buffers (PLY and BGEO frames, streamed from the backend).
    let buffers = (writes_frames && stream && FrameOutput::streamable(scene)).then(|| {
        crate::budget::FrameBuffers {
            frames_in_flight: args.frames_in_flight,
            chunk: args.frame_chunk,
            bytes_per_particle: 4 * FrameOutput::stream_columns(scene).words() as u64,
        }
    });
    crate::budget::enforce_for(
        scene,
        args.frames,
        writes_frames.then_some(out_dir),
        (from_bodies && args.backend == BackendKind::Cuda).then_some(&args.cuda_options),
        buffers,
        start.resume.as_ref().map(|_| start.particles.len() as u64),
    )?;
    Ok(())
}

/// The backend of a fresh run on one GPU (or `auto`), packed from the bodies' sampled
/// positions, and the number of particles.
fn run_backend_from_bodies(
    args: &RunArgs,
    scene: &Scene,
    setup: &mut SetupTimes,
) -> Result<(Box<dyn rtmpm_sim::Backend>, usize)> {
    // Bodies the GPU can draw are only counted (a CPU fallback walks them again).
    let o = &args.cuda_options;
    let defer = o.device_fill && o.device_sample;
    let (bodies, seconds) = rtmpm_driver::setup::sample_bodies(scene, defer)?;
    setup.sample = seconds;
    let n = bodies.iter().map(|b| b.len()).sum();
    let start = Instant::now();
    let backend = make_backend_from_bodies(
        args.backend,
        scene,
        bodies,
        args.threads,
        &args.cuda_options,
    )?;
    setup.backend = start.elapsed().as_secs_f64();
    Ok((backend, n))
}

/// The set-up and run lines on stderr.
fn announce(run: &Run, n: usize, setup: &SetupTimes) {
    let sim = &run.sim;
    match sim.backend.setup_details() {
        Some(d) => eprintln!(
            "set-up: {n} particles ready in {} (backend: {d})",
            setup.describe()
        ),
        None => eprintln!("set-up: {n} particles ready in {}", setup.describe()),
    }
    eprintln!(
        "running `{}`: {n} particles, {} frames on {}{}",
        sim.scene.name,
        run.total_frames().saturating_sub(sim.frame),
        sim.backend.name(),
        run.output
            .as_ref()
            .map(|o| format!(", output in {}", o.dir.display()))
            .unwrap_or_default()
    );
}

/// The progress bar of `total_frames` frames at `frame` (hidden on ranks that write nothing).
fn progress_bar(writer: bool, total_frames: u64, frame: u64) -> ProgressBar {
    let bar = if writer {
        ProgressBar::new(total_frames)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} frame {pos}/{len} [{bar:30}] t = {msg} | elapsed {elapsed_precise} | ETA {eta_precise}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.set_position(frame);
    bar
}

/// What `rtmpm run` shows while it runs: the progress bar, and the pictures of `--render` and
/// `--preview`.
struct CliHooks {
    renderer: Option<RunRenderer>,
    bar: ProgressBar,
}

impl RunHooks for CliHooks {
    fn frame_done(&mut self, sim: &Simulation, rate: f64) {
        self.bar.set_message(format!(
            "{:.4} s | dt {:.2e} | {}",
            sim.time,
            sim.last_dt,
            human_rate(rate)
        ));
        self.bar.set_position(sim.frame);
    }

    fn run_done(&mut self) {
        self.bar.finish_and_clear();
    }

    fn frame_written(
        &mut self,
        sim: &Simulation,
        host: &Particles,
        surface: Option<TriMesh>,
    ) -> Result<()> {
        match self.renderer.as_mut() {
            Some(r) => r.submit(
                sim.frame,
                sim.time,
                host,
                &sim.scene,
                surface,
                &sim.backend.rigid_bodies(),
            ),
            None => Ok(()),
        }
    }
}

/// The summary on stdout.
fn summary(run: &Run, n: usize, stats: &RunStats, rendered: Option<String>) {
    let sim = &run.sim;
    let wall = stats.started.elapsed().as_secs_f64();
    let steps = stats.steps;
    println!("summary");
    println!("  scene        {}", sim.scene.name);
    println!("  backend      {}", sim.backend.name());
    let n_end = sim.backend.num_particles();
    if n_end != n {
        println!("  particles    {n} at the start, {n_end} at the end (emitters)");
    } else {
        println!("  particles    {n}");
    }
    println!(
        "  frames       {}{}",
        sim.frame,
        if stats.stopped_by_steps {
            " (stopped by --steps)"
        } else {
            ""
        }
    );
    println!("  steps        {steps} (simulated time {:.4} s)", sim.time);
    println!("  wall time    {wall:.2} s");
    println!(
        "  throughput   {} ({:.2} ms/step)",
        human_rate(steps as f64 * n as f64 / wall.max(1e-9)),
        1e3 * wall / steps.max(1) as f64
    );
    if let Some(out) = &run.output {
        println!("  output       {}", out.dir.display());
    }
    if let Some(s) = &stats.stream {
        println!("  frame files  {}", rtmpm_driver::stream::describe(s));
    }
    if let Some(r) = rendered {
        println!("  render       {r}");
    }
}

/// The backend of a run that starts from particles (a checkpoint, the CPU, several GPUs) and
/// their number.
fn particle_backend(
    args: &RunArgs,
    mode: crate::multi::Mode,
    scene: &Scene,
    particles: Particles,
) -> Result<(Box<dyn rtmpm_sim::Backend>, usize)> {
    let n = particles.len();
    let backend = if mode == crate::multi::Mode::Single {
        make_backend(
            args.backend,
            scene,
            particles,
            args.threads,
            &args.cuda_options,
        )?
    } else {
        if args.backend == BackendKind::Cpu {
            bail!("--gpus and --rendezvous need the CUDA backend (not --backend cpu)");
        }
        args.multi
            .backend(mode, scene, &particles, &args.cuda_options)?
    };
    Ok((backend, n))
}

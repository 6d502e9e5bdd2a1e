//! `rtmpm run SCENE`: simulate frames with a progress bar, write output, checkpoints.

use crate::backend::{BackendKind, make_backend, make_backend_from_bodies};
use crate::outdir::{OutDir, scene_identity};
use crate::output::{FrameOutput, derived_fields};
use crate::progress::{Progress, RANK_CHUNK, human_rate};
use crate::render::RunRenderer;
use crate::stream::{FrameStreamer, StreamSettings};
use anyhow::{Context, Result, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rtmpm_driver::Simulation;
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_io::limits::{SCENE_MAX_BYTES, read_text_bounded};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args)]
pub struct RunArgs {
    /// Scene file (TOML). Optional with --resume (the checkpoint holds its scene).
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
    /// Write a checkpoint every N frames.
    #[arg(long, value_name = "N")]
    pub checkpoint_every: Option<u64>,
    /// Continue from a checkpoint written by --checkpoint-every.
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
    #[arg(long, value_name = "N", default_value_t = crate::stream::DEFAULT_CHUNK)]
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
    // Scene and initial state: from the scene file, or from a checkpoint.
    let (scene, particles, resume_state) = match &args.resume {
        Some(ckpt_path) => {
            let ckpt = Checkpoint::load(ckpt_path)
                .with_context(|| format!("cannot resume from {}", ckpt_path.display()))?;
            let base = Path::new(&ckpt.scene_origin)
                .parent()
                .unwrap_or(Path::new(""));
            let scene = Scene::from_toml_in(&ckpt.scene_toml, &ckpt.scene_origin, base)?;
            scene
                .check_checkpoint(&ckpt)
                .with_context(|| format!("cannot resume from {}", ckpt_path.display()))?;
            (
                scene,
                ckpt.particles,
                Some((
                    ckpt.time,
                    ckpt.step,
                    ckpt.frame,
                    ckpt.scene_toml,
                    ckpt.bodies,
                )),
            )
        }
        None => {
            let Some(path) = &args.scene else {
                bail!("no scene given: rtmpm run SCENE (or --resume CKPT)")
            };
            (Scene::from_file(path)?, Particles::default(), None)
        }
    };
    let scene_text = match (&resume_state, &args.scene) {
        (Some((_, _, _, text, _)), _) => text.clone(),
        (None, Some(path)) => read_text_bounded(path, SCENE_MAX_BYTES, "scene file")
            .with_context(|| format!("reading {}", path.display()))?,
        (None, None) => String::new(),
    };
    let mut scene = scene;
    if let Some(p) = args.precision {
        scene.precision = p;
    }
    let out_dir = args.out.clone().unwrap_or_else(|| scene.output.dir.clone());
    // Multi-process runs: rank 0 writes the files; every rank gathers the particles at the same
    // points (a collective), so every rank must be given the same options.
    let writer = args.multi.writes_output();
    let writes_frames = writer && !args.no_output;
    let mode = args.multi.mode()?;
    // A fresh run on one GPU (or `auto`) packs the bodies straight from their sampled positions.
    let from_bodies = resume_state.is_none()
        && mode == crate::multi::Mode::Single
        && args.backend != BackendKind::Cpu;
    // The budget before anything is sampled or allocated: refused with numbers and a fix (the
    // host's bytes of a CUDA run built from the positions when the CUDA backend is asked for:
    // the positions alone when the device fills the state, `fill=device`, the default).
    crate::budget::enforce_for(
        &scene,
        args.frames,
        writes_frames.then_some(out_dir.as_path()),
        (from_bodies && args.backend == BackendKind::Cuda).then_some(&args.cuda_options),
    )?;
    // The output folder: locked for this run, and holding no other run's files.
    let identity = scene_identity(&scene.name, &scene_text);
    // Held (the lock) until the run ends.
    let _folder = if writer && (writes_frames || args.render || args.checkpoint_every.is_some()) {
        let folder = OutDir::lock(&out_dir, &format!("rtmpm run of `{}`", scene.name))?;
        match &resume_state {
            None => folder.start_fresh(&identity, args.overwrite)?,
            Some((_, _, frame, _, _)) => folder.start_resume(&identity, *frame, args.overwrite)?,
        }
        Some(folder)
    } else {
        None
    };
    let mut setup = crate::setup::SetupTimes::default();
    let (backend, n) = if from_bodies {
        // Bodies the GPU can draw are only counted (a CPU fallback walks them again).
        let o = &args.cuda_options;
        let defer = o.device_fill && o.device_sample;
        let (bodies, seconds) = crate::setup::sample_bodies(&scene, defer)?;
        setup.sample = seconds;
        let n = bodies.iter().map(|b| b.len()).sum();
        let start = Instant::now();
        let backend = make_backend_from_bodies(
            args.backend,
            &scene,
            bodies,
            args.threads,
            &args.cuda_options,
        )?;
        setup.backend = start.elapsed().as_secs_f64();
        (backend, n)
    } else {
        let particles = match resume_state {
            Some(_) => particles,
            None => {
                let (p, seconds) = crate::setup::sample(&scene)?;
                setup.sample = seconds;
                p
            }
        };
        let start = Instant::now();
        let b = particle_backend(&args, mode, &scene, particles)?;
        setup.backend = start.elapsed().as_secs_f64();
        b
    };
    let mut sim = Simulation::new(scene, backend);

    // Entries of frames.pvd up to the checkpoint's own frame are kept: half a frame later.
    let resume_time = resume_state
        .as_ref()
        .map(|(time, ..)| *time + 0.5 / sim.scene.time.fps as f64);
    let mut output = if writes_frames {
        Some(FrameOutput::new(
            &out_dir,
            &sim.scene,
            &identity,
            resume_time,
        )?)
    } else {
        None
    };
    if let Some((time, step, frame, _, bodies)) = &resume_state {
        sim.time = *time;
        sim.step = *step;
        sim.frame = *frame;
        // The rigid bodies' poses and velocities (the checkpoint holds one per body of its
        // scene, checked above).
        sim.backend
            .set_rigid_poses(bodies)
            .context("cannot restore the checkpoint's rigid bodies")?;
    }
    let total_frames = args.frames.unwrap_or_else(|| sim.scene.time.frames());
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
        total_frames.saturating_sub(sim.frame),
        sim.backend.name(),
        output
            .as_ref()
            .map(|o| format!(", output in {}", o.dir.display()))
            .unwrap_or_default()
    );
    let mut renderer = RunRenderer::new(
        args.render && writer,
        args.preview.clone().filter(|_| writer),
        &args.view,
        &out_dir,
        &sim.scene,
    );
    let resumed_at = resume_state.as_ref().map(|r| r.2);
    let mut bodies = BodiesCsv::new(writes_frames, &out_dir, &sim, resumed_at)?;
    // PLY and BGEO frames stream from the backend in chunks, written in the background.
    let mut streamer = match output.as_ref() {
        Some(out)
            // Not across processes: there every rank reads the particles (a collective).
            if !matches!(mode, crate::multi::Mode::Rank { .. })
                && !args.whole_frames
                && !args.render
                && args.preview.is_none()
                && FrameOutput::streamable(&sim.scene) =>
        {
            let settings = StreamSettings {
                chunk: args.frame_chunk,
                frames_in_flight: args.frames_in_flight,
                derived: derived_fields(&sim.scene),
                models: sim
                    .scene
                    .materials
                    .iter()
                    .map(|m| m.model.clone())
                    .collect(),
            };
            Some(FrameStreamer::new(
                settings,
                &out.stream_formats(&sim.scene),
            )?)
        }
        _ => None,
    };
    let collect = (!args.no_output && streamer.is_none()) || args.render || args.preview.is_some();
    let mut host = Particles::default();
    if sim.frame == 0 && (collect || streamer.is_some()) {
        if collect {
            sim.backend.read_particles(&mut host)?;
        }
        let mut mesh = None;
        if let Some(out) = output.as_mut() {
            match streamer.as_mut() {
                Some(s) => {
                    s.write_frame(sim.backend.as_mut(), out.stream_files(0, &sim.scene), 0)?
                }
                None => {
                    let bodies = sim.backend.rigid_poses();
                    mesh = out.write_frame(0, 0.0, &host, &bodies, &sim.scene)?
                }
            }
            bodies.write(0, 0.0, &sim)?;
        }
        if let Some(r) = renderer.as_mut() {
            r.submit(0, 0.0, &host, &sim.scene, mesh, &sim.backend.rigid_bodies())?;
        }
    }

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
    bar.set_position(sim.frame);
    let start = Instant::now();
    let start_step = sim.step;
    let mut stopped_by_steps = false;
    // Across processes every rank must take its steps in the same chunks: the health check at
    // the end of a chunk is a collective, so a chunk sized by each rank's own clock would pair
    // one rank's check with another's step and hang them (rank 0 alone writes the frames, so
    // its clock differs).
    let fixed_chunk = matches!(mode, crate::multi::Mode::Rank { .. }).then_some(RANK_CHUNK);
    let mut progress = Progress::new(n, total_frames, fixed_chunk);
    while sim.frame < total_frames {
        let left = args
            .steps
            .map_or(u64::MAX, |max| max.saturating_sub(sim.step - start_step));
        // Steps in chunks of about a second, so that progress shows inside long frames.
        let chunk = progress.chunk();
        let t0 = Instant::now();
        let done = sim.advance(left.min(chunk))?;
        progress.chunk_took(t0.elapsed().as_secs_f64());
        progress.tick(&sim, start_step);
        if !done {
            if sim.step - start_step >= args.steps.unwrap_or(u64::MAX) {
                stopped_by_steps = true;
                break;
            }
            continue;
        }
        let elapsed = start.elapsed().as_secs_f64();
        let rate = (sim.step - start_step) as f64 * n as f64 / elapsed.max(1e-9);
        bar.set_message(format!(
            "{:.4} s | dt {:.2e} | {}",
            sim.time,
            sim.last_dt,
            human_rate(rate)
        ));
        bar.set_position(sim.frame);
        if collect {
            sim.backend.read_particles(&mut host)?;
        }
        let mut mesh = None;
        if let Some(out) = output.as_mut() {
            match streamer.as_mut() {
                Some(s) => {
                    let files = out.stream_files(sim.frame, &sim.scene);
                    s.write_frame(sim.backend.as_mut(), files, sim.frame)?
                }
                None => {
                    let bodies = sim.backend.rigid_poses();
                    mesh = out.write_frame(sim.frame, sim.time, &host, &bodies, &sim.scene)?
                }
            }
            bodies.write(sim.frame, sim.time, &sim)?;
        }
        if let Some(r) = renderer.as_mut() {
            r.submit(
                sim.frame,
                sim.time,
                &host,
                &sim.scene,
                mesh,
                &sim.backend.rigid_bodies(),
            )?;
        }
        if args
            .checkpoint_every
            .is_some_and(|every| every > 0 && sim.frame.is_multiple_of(every))
        {
            sim.backend.read_particles(&mut host)?;
            if !writer {
                continue;
            }
            let poses = sim.backend.rigid_poses();
            if poses.len() != sim.scene.rigid_bodies.len() {
                bail!(
                    "the backend `{}` does not give the poses of the scene's {} rigid bodies, \
                     which a checkpoint needs: run without --checkpoint-every, or on the CPU \
                     backend",
                    sim.backend.name(),
                    sim.scene.rigid_bodies.len()
                );
            }
            let ckpt = Checkpoint {
                scene_toml: scene_text.clone(),
                scene_origin: sim
                    .scene
                    .source
                    .as_ref()
                    .map_or("<checkpoint>".into(), |p| p.display().to_string()),
                time: sim.time,
                step: sim.step,
                frame: sim.frame,
                bodies: poses,
                particles: host.clone(),
            };
            std::fs::create_dir_all(&out_dir)
                .with_context(|| format!("cannot create output folder {}", out_dir.display()))?;
            let path = out_dir.join(format!("checkpoint_{:05}.ckpt", sim.frame));
            ckpt.save(&path)
                .with_context(|| format!("writing checkpoint {}", path.display()))?;
        }
    }
    bar.finish_and_clear();
    // Every frame in flight written (or its error, naming the file).
    let stream_stats = streamer.map(FrameStreamer::finish).transpose()?;
    let rendered = renderer.map(RunRenderer::finish).transpose()?.flatten();
    let wall = start.elapsed().as_secs_f64();
    let steps = sim.step - start_step;
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
        if stopped_by_steps {
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
    if let Some(out) = &output {
        println!("  output       {}", out.dir.display());
    }
    if let Some(s) = stream_stats {
        println!("  frame files  {}", crate::stream::describe(&s));
    }
    if let Some(r) = rendered {
        println!("  render       {r}");
    }
    Ok(())
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

/// `bodies.csv` in the output folder: the pose and velocities of every rigid body at every
/// frame (`[[rigid_body]]`; nothing when the scene has none).
struct BodiesCsv {
    file: Option<std::io::BufWriter<std::fs::File>>,
    names: Vec<String>,
}

impl BodiesCsv {
    /// The file, new; or, resuming at frame `resumed_at`, the rows of a previous run's file up
    /// to that frame kept (the rows of later frames are written again).
    fn new(
        writes: bool,
        dir: &std::path::Path,
        sim: &Simulation,
        resumed_at: Option<u64>,
    ) -> Result<BodiesCsv> {
        let names: Vec<String> = sim
            .scene
            .rigid_bodies
            .iter()
            .map(|b| b.name.clone())
            .collect();
        if !writes || names.is_empty() {
            return Ok(BodiesCsv { file: None, names });
        }
        use std::io::Write;
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let path = dir.join("bodies.csv");
        let kept: Vec<String> = match resumed_at {
            Some(at) => std::fs::read_to_string(&path)
                .unwrap_or_default()
                .lines()
                .skip(1)
                .filter(|l| {
                    l.split(',')
                        .next()
                        .and_then(|f| f.parse::<u64>().ok())
                        .is_some_and(|f| f <= at)
                })
                .map(str::to_string)
                .collect(),
            None => Vec::new(),
        };
        let mut f = std::io::BufWriter::new(
            std::fs::File::create(&path)
                .with_context(|| format!("cannot write {}", path.display()))?,
        );
        writeln!(f, "frame,time,body,x,y,z,qx,qy,qz,qw,vx,vy,vz,wx,wy,wz")?;
        for l in kept {
            writeln!(f, "{l}")?;
        }
        Ok(BodiesCsv {
            file: Some(f),
            names,
        })
    }

    fn write(&mut self, frame: u64, time: f64, sim: &Simulation) -> Result<()> {
        let Some(f) = self.file.as_mut() else {
            return Ok(());
        };
        use std::io::Write;
        for (b, name) in sim.backend.rigid_bodies().iter().zip(&self.names) {
            let q = glam::Quat::from_mat3(&b.rotation);
            let (c, v, w) = (b.center, b.velocity, b.angular_velocity);
            writeln!(
                f,
                "{frame},{time},{name:?},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                c.x, c.y, c.z, q.x, q.y, q.z, q.w, v.x, v.y, v.z, w.x, w.y, w.z
            )?;
        }
        f.flush()?;
        Ok(())
    }
}

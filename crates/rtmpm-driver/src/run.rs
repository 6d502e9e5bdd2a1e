//! A run of a scene to its last frame: where it starts ([`RunStart`]: a scene file, or a
//! checkpoint to resume), then [`Run::execute`]: the steps in chunks of about a second, every
//! frame written (streamed from the backend in chunks, or from a whole copy of the particles),
//! `bodies.csv`, checkpoints every few frames. What the caller shows while it runs (a progress
//! bar, pictures) it does in [`RunHooks`].

use crate::bodies_csv::{BodiesCsv, KeptRows};
use crate::output::{FrameOutput, derived_fields};
use crate::progress::Progress;
pub use crate::resume::ResumeState;
use crate::simulation::Simulation;
use crate::stream::{FrameStreamer, StreamSettings, StreamStats};
use anyhow::{Context, Result, bail};
use rtmpm_geometry::surface::TriMesh;
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_io::limits::{SCENE_MAX_BYTES, read_text_bounded};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The scene of a run and its initial state.
pub struct RunStart {
    /// The scene.
    pub scene: Scene,
    /// The scene's text (stored in checkpoints; empty when there is none).
    pub scene_text: String,
    /// The particles of a resumed run (empty for a fresh one: the scene's bodies are sampled).
    pub particles: Particles,
    /// Set when resuming a checkpoint.
    pub resume: Option<ResumeState>,
}

impl RunStart {
    /// The scene file `scene`, or the checkpoint `resume` (which holds its scene, checked
    /// against the checkpoint's state). A scene file given with a checkpoint must be the scene
    /// the checkpoint holds: a resumed run continues that scene, and an edited file (another
    /// transfer, material or collider) would otherwise be ignored without a word.
    pub fn load(scene: Option<&Path>, resume: Option<&Path>) -> Result<RunStart> {
        if let Some(ckpt_path) = resume {
            let start = Self::resume(ckpt_path)?;
            if let Some(path) = scene {
                let text = read_text_bounded(path, SCENE_MAX_BYTES, "scene file")
                    .with_context(|| format!("reading {}", path.display()))?;
                same_scene(path, &text, ckpt_path, &start.scene_text)?;
            }
            return Ok(start);
        }
        let Some(path) = scene else {
            bail!("no scene given: rtmpm run SCENE (or --resume CKPT)")
        };
        let scene = Scene::from_file(path)?;
        let scene_text = read_text_bounded(path, SCENE_MAX_BYTES, "scene file")
            .with_context(|| format!("reading {}", path.display()))?;
        Ok(RunStart {
            scene,
            scene_text,
            particles: Particles::default(),
            resume: None,
        })
    }

    /// The checkpoint `ckpt_path`: its scene, particles and state, checked
    /// ([`crate::resume::load`]).
    fn resume(ckpt_path: &Path) -> Result<RunStart> {
        let loaded = crate::resume::load(ckpt_path)?;
        Ok(RunStart {
            scene: loaded.scene,
            scene_text: loaded.scene_text,
            particles: loaded.particles,
            resume: Some(loaded.state),
        })
    }

    /// A resumed run's rows of `dir/bodies.csv` ([`KeptRows::read`]), checked now: before
    /// anything in the output folder changes. Nothing to do for a fresh run or a scene without
    /// rigid bodies.
    pub fn check_bodies_csv(&mut self, dir: &Path) -> Result<()> {
        if let Some(r) = self.resume.as_mut()
            && !self.scene.rigid_bodies.is_empty()
        {
            r.bodies_csv = Some(KeptRows::read(
                &dir.join("bodies.csv"),
                &self.scene,
                r.frame,
            )?);
        }
        Ok(())
    }
}

/// Refuse a scene file `path` (text `given`) that differs from the scene `stored` in the
/// checkpoint `ckpt`, naming the first line that differs (line endings and trailing spaces
/// aside).
fn same_scene(path: &Path, given: &str, ckpt: &Path, stored: &str) -> Result<()> {
    let lines = |t: &str| -> Vec<String> {
        let mut v: Vec<String> = t.lines().map(|l| l.trim_end().to_string()).collect();
        while v.last().is_some_and(|l| l.is_empty()) {
            v.pop();
        }
        v
    };
    let (a, b) = (lines(given), lines(stored));
    if a == b {
        return Ok(());
    }
    let i = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let show = |v: &[String]| {
        v.get(i)
            .map_or_else(|| "(the end of the file)".into(), |l| format!("`{l}`"))
    };
    bail!(
        "{}:{}: the scene file differs from the scene stored in the checkpoint {} (its line {} \
         is {}, the checkpoint's {}); a resumed run continues the checkpoint's scene, so the \
         file's changes would be ignored\n  fix: leave the scene file out (`rtmpm run --resume \
         {}`), or run the edited scene afresh (`rtmpm run {}`)",
        path.display(),
        i + 1,
        ckpt.display(),
        i + 1,
        show(&a),
        show(&b),
        ckpt.display(),
        path.display()
    )
}

/// How a run goes.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Frames to simulate to (default: the scene's duration x fps).
    pub frames: Option<u64>,
    /// Stop after this many steps (a partial last frame is not written).
    pub steps: Option<u64>,
    /// Write a checkpoint every this many frames.
    pub checkpoint_every: Option<u64>,
    /// The output folder.
    pub out_dir: PathBuf,
    /// This process writes the files (the only process, or rank 0 of several).
    pub writer: bool,
    /// Write the frame files (the scene's formats).
    pub write_frames: bool,
    /// Every process reads each frame's particles (the writer writes them; across processes
    /// the read is a collective); false when no frame is written (`--no-output`).
    pub read_frames: bool,
    /// Stream PLY and BGEO frames from the backend in chunks when the scene's formats allow
    /// (not across processes, where every rank reads the particles: a collective).
    pub stream: bool,
    /// Particles per streamed chunk.
    pub frame_chunk: usize,
    /// Frames written in the background while the simulation steps on.
    pub frames_in_flight: usize,
    /// The hooks want the particles of every frame on the host ([`RunHooks::frame_written`]).
    pub collect: bool,
    /// Steps per chunk whatever the clock says (multi-process runs: every rank the same).
    pub fixed_chunk: Option<u64>,
}

/// What the caller does while a run goes on.
pub trait RunHooks {
    /// After every chunk of steps of [`Run::execute`] (and the frame it completed, if any);
    /// an error stops the run.
    fn chunk_done(&mut self, _sim: &Simulation) -> Result<()> {
        Ok(())
    }
    /// When a frame is complete, before its files are written; `rate` is the run's
    /// particle-steps per second so far.
    fn frame_done(&mut self, _sim: &Simulation, _rate: f64) {}
    /// After the last frame, before the frames still being written are waited for.
    fn run_done(&mut self) {}
    /// Once the steps of a [`Run::advance`] are queued, before the host first waits for the
    /// device ([`Simulation::advance_with`]): host work done here overlaps the steps (a live
    /// view finishes its last picture with the backend).
    fn steps_queued(&mut self, _backend: &mut dyn Backend) {}
    /// After a frame's files are written (frame 0 of a fresh run too): the particles on the
    /// host when [`RunOptions::collect`] asked for them (else empty), and the fluid surface
    /// written with the frame, if any.
    fn frame_written(
        &mut self,
        _sim: &Simulation,
        _host: &Particles,
        _surface: Option<TriMesh>,
    ) -> Result<()> {
        Ok(())
    }
}

/// What a run did.
#[derive(Debug)]
pub struct RunStats {
    /// Steps taken in this run.
    pub steps: u64,
    /// When the steps began (the run's wall time is from here).
    pub started: Instant,
    /// The run ended at `steps`, before its last frame.
    pub stopped_by_steps: bool,
    /// The streamed frame files, when frames were streamed.
    pub stream: Option<StreamStats>,
}

/// A run: the simulation and where its frames go.
pub struct Run {
    /// The simulation.
    pub sim: Simulation,
    /// The frame files, when written.
    pub output: Option<FrameOutput>,
    streamer: Option<FrameStreamer>,
    bodies: BodiesCsv,
    options: RunOptions,
    scene_text: String,
    host: Particles,
    particles: usize,
    /// When [`Run::begin`] was called, and the step count then.
    started: Instant,
    start_step: u64,
}

impl Run {
    /// A run of `sim` with `particles` particles (at the state of `resume` when given: the
    /// simulation's clock and rigid bodies are set here); `identity` names the run in the frame
    /// files' comments.
    pub fn new(
        mut sim: Simulation,
        particles: usize,
        scene_text: String,
        identity: &str,
        resume: Option<&ResumeState>,
        options: RunOptions,
    ) -> Result<Run> {
        // Entries of frames.pvd up to the checkpoint's own frame are kept: half a frame later.
        let resume_time = resume.map(|r| r.time + 0.5 / sim.scene.time.fps as f64);
        let output = if options.write_frames {
            Some(FrameOutput::new(
                &options.out_dir,
                &sim.scene,
                identity,
                resume_time,
            )?)
        } else {
            None
        };
        if let Some(r) = resume {
            sim.time = r.time;
            sim.step = r.step;
            sim.frame = r.frame;
            // The rigid bodies' poses and velocities (the checkpoint holds one per body of its
            // scene, checked when it was loaded).
            sim.backend
                .set_rigid_poses(&r.bodies)
                .context("cannot restore the checkpoint's rigid bodies")?;
        }
        // A resumed run's rows of bodies.csv: as checked by the caller, else read now.
        let kept = match resume {
            Some(r) if options.write_frames && !sim.scene.rigid_bodies.is_empty() => {
                match &r.bodies_csv {
                    Some(k) => Some(k.clone()),
                    None => Some(KeptRows::read(
                        &options.out_dir.join("bodies.csv"),
                        &sim.scene,
                        r.frame,
                    )?),
                }
            }
            _ => None,
        };
        let bodies = BodiesCsv::new(options.write_frames, &options.out_dir, &sim, kept)?;
        let streamer = match output.as_ref() {
            Some(out) if options.stream && FrameOutput::streamable(&sim.scene) => {
                let settings = StreamSettings {
                    chunk: options.frame_chunk,
                    frames_in_flight: options.frames_in_flight,
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
        Ok(Run {
            sim,
            output,
            streamer,
            bodies,
            options,
            scene_text,
            host: Particles::default(),
            particles,
            started: Instant::now(),
            start_step: 0,
        })
    }

    /// The frames the run goes to.
    pub fn total_frames(&self) -> u64 {
        self.options
            .frames
            .unwrap_or_else(|| self.sim.scene.time.frames())
    }

    /// Frames are read whole onto the host: for the files (when not streamed) or the hooks.
    fn collects(&self) -> bool {
        (self.options.read_frames && self.streamer.is_none()) || self.options.collect
    }

    /// The run has reached its last frame.
    pub fn at_end(&self) -> bool {
        self.sim.frame >= self.total_frames()
    }

    /// Start: frame 0's files when the run is fresh. Call once, before [`Run::advance`].
    pub fn begin(&mut self, hooks: &mut dyn RunHooks) -> Result<()> {
        if self.sim.frame == 0 && (self.collects() || self.streamer.is_some()) {
            self.write_frame(hooks)?;
        }
        // The run's wall time and rate are from here.
        self.started = Instant::now();
        self.start_step = self.sim.step;
        Ok(())
    }

    /// Take at most `max_steps` steps, stopping at the end of the current frame; when the frame
    /// is complete, write it (and a checkpoint when one is due). Returns true when a frame was
    /// completed. For a caller that paces the steps itself (a live view); [`Run::execute`]
    /// calls it in chunks of about a second.
    pub fn advance(&mut self, max_steps: u64, hooks: &mut dyn RunHooks) -> Result<bool> {
        let done = self
            .sim
            .advance_with(max_steps, &mut |b| hooks.steps_queued(b))?;
        if done {
            self.frame_complete(hooks)?;
        }
        Ok(done)
    }

    /// The frame just completed: the hooks told, its files, a checkpoint when one is due.
    fn frame_complete(&mut self, hooks: &mut dyn RunHooks) -> Result<()> {
        let elapsed = self.started.elapsed().as_secs_f64();
        let rate = self.steps() as f64 * self.particles as f64 / elapsed.max(1e-9);
        hooks.frame_done(&self.sim, rate);
        self.write_frame(hooks)?;
        if self
            .options
            .checkpoint_every
            .is_some_and(|every| every > 0 && self.sim.frame.is_multiple_of(every))
        {
            self.checkpoint()?;
        }
        Ok(())
    }

    /// Steps taken since [`Run::begin`].
    pub fn steps(&self) -> u64 {
        self.sim.step - self.start_step
    }

    /// End: every frame still being written waited for (or the error of one, naming the
    /// file); the streamed files' totals.
    pub fn finish(&mut self) -> Result<Option<StreamStats>> {
        self.streamer.take().map(FrameStreamer::finish).transpose()
    }

    /// Run to the last frame (or [`RunOptions::steps`]): [`Run::begin`], [`Run::advance`] in
    /// chunks of about a second (progress shows inside long frames), [`Run::finish`].
    pub fn execute(&mut self, hooks: &mut dyn RunHooks) -> Result<RunStats> {
        self.begin(hooks)?;
        let max_steps = self.options.steps.unwrap_or(u64::MAX);
        let mut stopped_by_steps = false;
        let mut progress = Progress::new(
            self.particles,
            self.total_frames(),
            self.options.fixed_chunk,
        );
        while !self.at_end() {
            let left = max_steps.saturating_sub(self.steps());
            // Steps in chunks of about a second, so that progress shows inside long frames.
            let chunk = progress.chunk();
            let t0 = Instant::now();
            let done = self.sim.advance(left.min(chunk))?;
            progress.chunk_took(t0.elapsed().as_secs_f64());
            progress.tick(&self.sim, self.start_step);
            if done {
                self.frame_complete(hooks)?;
            }
            hooks.chunk_done(&self.sim)?;
            if !done && self.steps() >= max_steps {
                stopped_by_steps = true;
                break;
            }
        }
        hooks.run_done();
        let stream = self.finish()?;
        Ok(RunStats {
            steps: self.steps(),
            started: self.started,
            stopped_by_steps,
            stream,
        })
    }

    /// The current frame: its files (streamed from the backend, or written from the particles
    /// read onto the host), its rows of `bodies.csv`, then the hooks.
    fn write_frame(&mut self, hooks: &mut dyn RunHooks) -> Result<()> {
        let collects = self.collects();
        let sim = &mut self.sim;
        if collects {
            sim.backend.read_particles(&mut self.host)?;
        }
        let mut surface = None;
        if let Some(out) = self.output.as_mut() {
            match self.streamer.as_mut() {
                Some(s) => {
                    let files = out.stream_files(sim.frame, &sim.scene);
                    s.write_frame(sim.backend.as_mut(), files, sim.frame)?
                }
                None => {
                    let bodies = sim.backend.rigid_poses();
                    surface =
                        out.write_frame(sim.frame, sim.time, &self.host, &bodies, &sim.scene)?
                }
            }
            self.bodies.write(sim.frame, sim.time, sim)?;
        }
        hooks.frame_written(sim, &self.host, surface)
    }

    /// A checkpoint of the current frame, `checkpoint_NNNNN.ckpt` in the output folder (by the
    /// writing process; every process reads its particles, a collective across processes).
    fn checkpoint(&mut self) -> Result<()> {
        let sim = &mut self.sim;
        sim.backend.read_particles(&mut self.host)?;
        if !self.options.writer {
            return Ok(());
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
            scene_toml: self.scene_text.clone(),
            scene_origin: sim
                .scene
                .source
                .as_ref()
                .map_or("<checkpoint>".into(), |p| p.display().to_string()),
            time: sim.time,
            step: sim.step,
            frame: sim.frame,
            bodies: poses,
            files: sim.scene.file_hashes(),
            particles: self.host.clone(),
        };
        let out_dir = &self.options.out_dir;
        std::fs::create_dir_all(out_dir)
            .with_context(|| format!("cannot create output folder {}", out_dir.display()))?;
        let path = out_dir.join(format!("checkpoint_{:05}.ckpt", sim.frame));
        ckpt.save(&path)
            .with_context(|| format!("writing checkpoint {}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rtmpm_rigid::{BodyPose, BodyState};
    use rtmpm_sim::{BadParticle, SimError};
    use std::sync::Arc;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// A backend whose particles and one rigid body stay where the scene put them; it counts
    /// the reads of the particles (a collective across processes).
    struct Still {
        p: Particles,
        body: BodyState,
        reads: Arc<AtomicU32>,
    }

    impl Backend for Still {
        fn name(&self) -> String {
            "still".into()
        }
        fn num_particles(&self) -> usize {
            self.p.len()
        }
        fn step(&mut self, _dt: f32, _t: f32) -> Result<(), SimError> {
            Ok(())
        }
        fn max_speed(&mut self) -> Result<f32, SimError> {
            Ok(0.0)
        }
        fn check(&mut self) -> Result<Option<BadParticle>, SimError> {
            Ok(None)
        }
        fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError> {
            self.reads.fetch_add(1, Ordering::SeqCst);
            *out = self.p.clone();
            Ok(())
        }
        fn rigid_bodies(&self) -> Vec<BodyState> {
            vec![self.body.clone()]
        }
        fn rigid_poses(&self) -> Vec<BodyPose> {
            vec![BodyPose {
                position: self.body.center,
                rotation: glam::Quat::IDENTITY,
                velocity: self.body.velocity,
                angular_velocity: self.body.angular_velocity,
            }]
        }
    }

    /// The processes of a multi-process run: rank 0 writes (`writer`) the frames, bodies.csv
    /// and checkpoints; another rank (`rtmpm run` gives it `writer: false`) writes nothing in
    /// its folder, yet reads the particles at the same points as rank 0 (every frame and
    /// checkpoint: a collective, which every rank must call alike).
    #[test]
    fn only_the_writing_process_writes_bodies_csv_and_every_one_reads_alike() {
        let text = "name = \"ranks\"\n[domain]\nmin = [0, 0, 0]\nmax = [1, 1, 1]\ndx = 0.05\n\
                    [time]\nduration = 0.2\nfps = 10\ndt = 0.01\n\
                    [[material]]\nname = \"w\"\ntype = \"fluid\"\ndensity = 1000.0\n\
                    bulk_modulus = 1e4\n[[body]]\nmaterial = \"w\"\nshape = \"box\"\n\
                    min = [0.3, 0.3, 0.3]\nmax = [0.45, 0.45, 0.45]\n\
                    [[rigid_body]]\nname = \"ball\"\nshape = \"sphere\"\n\
                    center = [0.65, 0.65, 0.65]\nradius = 0.08\ndensity = 500\n\
                    [output]\nformats = [\"ply\"]\n";
        let scene = Scene::from_toml(text, "ranks").unwrap_or_else(|e| panic!("{e}"));
        let root = std::env::temp_dir().join(format!("rtmpm-run-ranks-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let mut reads = Vec::new();
        for (rank, writer) in [(0, true), (1, false)] {
            let p = scene.sample_particles().expect("particles");
            let n = p.len();
            let body = BodyState {
                shape: scene.rigid_bodies[0].shape.clone(),
                rotation: glam::Mat3::IDENTITY,
                center: scene.rigid_bodies[0].position,
                velocity: glam::Vec3::ZERO,
                angular_velocity: glam::Vec3::ZERO,
                dynamic: true,
                condition: rtmpm_physics::boundary::Condition::Slip,
                friction: 0.0,
            };
            let count = Arc::new(AtomicU32::new(0));
            let backend = Still {
                p,
                body,
                reads: count.clone(),
            };
            let out_dir = root.join(format!("rank{rank}"));
            // As `rtmpm run --rendezvous` sets them for this rank.
            let options = RunOptions {
                frames: None,
                steps: None,
                checkpoint_every: Some(1),
                out_dir: out_dir.clone(),
                writer,
                write_frames: writer,
                read_frames: true,
                stream: false,
                frame_chunk: 1 << 16,
                frames_in_flight: 1,
                collect: false,
                fixed_chunk: Some(128),
            };
            let sim = Simulation::new(scene.clone(), Box::new(backend));
            let mut run = Run::new(sim, n, text.into(), "ranks", None, options).expect("run");
            struct Quiet;
            impl RunHooks for Quiet {}
            run.execute(&mut Quiet).expect("the run");
            assert_eq!(run.sim.frame, 2);
            reads.push(count.load(Ordering::SeqCst));
            let files: Vec<String> = std::fs::read_dir(&out_dir)
                .map(|d| {
                    d.filter_map(|e| e.ok())
                        .map(|e| e.file_name().to_string_lossy().into_owned())
                        .collect()
                })
                .unwrap_or_default();
            if writer {
                let csv = std::fs::read_to_string(out_dir.join("bodies.csv")).expect("bodies.csv");
                // The header and a row per frame (0, 1, 2).
                assert_eq!(csv.lines().count(), 4, "{csv}");
                for f in ["frame_00002.ply", "checkpoint_00002.ckpt"] {
                    assert!(files.iter().any(|x| x == f), "{f} missing: {files:?}");
                }
            } else {
                assert!(files.is_empty(), "rank {rank} wrote {files:?}");
            }
        }
        // Frames 0, 1, 2 and the checkpoints of frames 1 and 2, on both ranks.
        assert_eq!(reads, vec![5, 5]);
        let _ = std::fs::remove_dir_all(&root);
    }
}

//! Many worlds run together: the worlds of a scene's `[batch]` ([`rtmpm_scene::BatchScene`]),
//! each a [`Simulation`] of its own (own particles, grid, colliders and rigid bodies, so no world
//! can touch another's state), stepped frame by frame in lockstep. A world that blows up is
//! reported and frozen at its last good frame; the others go on exactly as they would alone.
//!
//! Files: the output folder holds `batch.csv` (one row per world: its swept values and how it
//! ended) and one folder per world, `world_000/`, `world_001/`, ..., each laid out as the folder
//! of a single run (`frame_NNNNN.*`, `frames.pvd`), so that ParaView opens a world's
//! `frames.pvd` and Houdini a world's `frame_$F5.bgeo` as they would any run.

pub mod checkpoint;
pub mod chunk;
pub mod lockstep;

use crate::outdir::{OutDir, scene_identity};
use crate::output::FrameOutput;
use crate::simulation::Simulation;
use anyhow::{Context, Result};
use rtmpm_physics::Particles;
use rtmpm_scene::{BatchScene, Scene};
use rtmpm_sim::{Backend, SimError};
use std::path::{Path, PathBuf};

/// Where a world stands.
#[derive(Clone, Debug, PartialEq)]
pub enum WorldStatus {
    /// Stepping on.
    Running,
    /// Stopped by a blow-up (or a stalled time step) during frame `frame + 1`: its state and
    /// files stay those of frame `frame`.
    Frozen {
        /// The last frame completed (and written).
        frame: u64,
        /// What went wrong, as the single run would report it.
        reason: String,
    },
}

/// One world of a batch.
pub struct World {
    /// Its simulation.
    pub sim: Simulation,
    /// What sets it apart (`material[0].yield_stress = 150`).
    pub label: String,
    /// Running or frozen.
    pub status: WorldStatus,
    output: Option<FrameOutput>,
    /// The particles at the last completed frame (what a frozen world keeps: the backend's
    /// state after a failed step is the broken one).
    kept: Particles,
}

/// The name of world `w`'s folder in a batch of `count` (`world_007`; zero-padded to the
/// widest index, at least 3 digits, so that the folders sort in order).
pub fn world_dir_name(w: usize, count: usize) -> String {
    let width = count.saturating_sub(1).to_string().len().max(3);
    format!("world_{w:0width$}")
}

/// The folder of a batch checkpoint of frame `frame` in a batch run's output folder
/// (`checkpoint_00020`).
pub fn checkpoint_dir_name(frame: u64) -> String {
    format!("checkpoint_{frame:05}")
}

/// A batch run: the worlds and where their frames go.
pub struct BatchRun {
    /// The worlds, in order.
    pub worlds: Vec<World>,
    /// The frames the run goes to.
    pub frames: u64,
    out: Option<OutDir>,
    /// Taken up from a checkpoint (its current frame's files are already written).
    resumed: bool,
    /// Called after each world has advanced inside a frame ([`BatchRun::on_world_done`]).
    world_done: Option<WorldDone>,
}

/// A callback with (worlds advanced so far, worlds running at the start) inside a frame.
type WorldDone = Box<dyn FnMut(usize, usize) + Send>;

/// How a batch run goes.
#[derive(Clone, Debug, Default)]
pub struct BatchOptions {
    /// Frames to simulate to (default: the scene's duration x fps).
    pub frames: Option<u64>,
    /// The output folder; `None` writes no files.
    pub out_dir: Option<PathBuf>,
    /// Remove the files of a previous run from the folders first (as `rtmpm run --overwrite`).
    pub overwrite: bool,
}

impl BatchRun {
    /// The worlds of `batch`, each on the backend `backend(scene, w)` builds (with its
    /// particles); `text` is the scene file's text (it names the run in the output folders).
    pub fn new(
        batch: &BatchScene,
        text: &str,
        backend: impl FnMut(&Scene, usize) -> Result<Box<dyn Backend>>,
        options: &BatchOptions,
    ) -> Result<BatchRun> {
        Self::build(batch, text, backend, options, None)
    }

    /// [`BatchRun::new`], or, with `resumed` (each world's frame and time in a checkpoint), a
    /// run whose folders are taken up after those frames (later frames removed, `frames.pvd`
    /// kept up to them) rather than started afresh.
    fn build(
        batch: &BatchScene,
        text: &str,
        mut backend: impl FnMut(&Scene, usize) -> Result<Box<dyn Backend>>,
        options: &BatchOptions,
        resumed: Option<&[(u64, f64)]>,
    ) -> Result<BatchRun> {
        let count = batch.count();
        let last = resumed.map(|r| r.iter().map(|s| s.0).max().unwrap_or(0));
        let out = open_out(batch, text, options, last)?;
        let mut worlds = Vec::with_capacity(count);
        for (w, scene) in batch.worlds.iter().enumerate() {
            let label = batch.label(w);
            let output = match &out {
                Some(o) => Some(world_output(
                    &o.dir,
                    (w, count),
                    scene,
                    (text, &label),
                    options,
                    resumed.map(|r| r[w]),
                )?),
                None => None,
            };
            let b = backend(scene, w).with_context(|| format!("world {w} ({label})"))?;
            worlds.push(World {
                sim: Simulation::new(scene.clone(), b),
                label,
                status: WorldStatus::Running,
                output,
                kept: Particles::default(),
            });
        }
        let frames = options.frames.unwrap_or_else(|| batch.base.time.frames());
        let run = BatchRun {
            worlds,
            frames,
            out,
            resumed: resumed.is_some(),
            world_done: None,
        };
        run.write_summary()?;
        Ok(run)
    }

    /// Call `f(done, of)` after each world has advanced inside a frame: `done` worlds of the
    /// `of` running at the frame's start (progress inside the long frames of many worlds).
    pub fn on_world_done(&mut self, f: impl FnMut(usize, usize) + Send + 'static) {
        self.world_done = Some(Box::new(f));
    }

    /// Worlds still running.
    pub fn running(&self) -> usize {
        self.worlds
            .iter()
            .filter(|w| w.status == WorldStatus::Running)
            .count()
    }

    /// The frame every running world has completed.
    pub fn frame(&self) -> u64 {
        self.worlds
            .iter()
            .filter(|w| w.status == WorldStatus::Running)
            .map(|w| w.sim.frame)
            .max()
            .unwrap_or(self.frames)
    }

    /// Write frame 0 of every world (before the first step).
    pub fn write_first_frame(&mut self) -> Result<()> {
        for w in 0..self.worlds.len() {
            self.write_frame(w)?;
        }
        Ok(())
    }

    /// Advance every running world by one frame and write it; a world whose step fails with a
    /// blow-up or a stall is frozen at its last frame (returned, with its reason); an error of
    /// the backend itself ends the run.
    pub fn advance_frame(&mut self) -> Result<Vec<usize>> {
        self.advance_each(|sim| sim.advance_frame().map(drop))
    }

    /// Advance every running world by `steps` steps of its own time step (crossing frame ends as
    /// `rtmpm run --steps` does), for runs that write no files (a file is a whole frame's);
    /// blow-ups freeze a world as in [`BatchRun::advance_frame`], at the state of the last call.
    pub fn advance_steps(&mut self, steps: u64) -> Result<Vec<usize>> {
        if self.out.is_some() {
            anyhow::bail!("a batch run that writes frame files advances by whole frames");
        }
        self.advance_each(|sim| {
            let target = sim.step.saturating_add(steps);
            while sim.step < target {
                sim.advance(target - sim.step)?;
            }
            Ok(())
        })
    }

    /// Advance every running world with `advance`, then read (and write) its state; a world
    /// whose `advance` fails with a blow-up or a stall is frozen.
    fn advance_each(
        &mut self,
        mut advance: impl FnMut(&mut Simulation) -> Result<(), SimError>,
    ) -> Result<Vec<usize>> {
        let mut frozen = Vec::new();
        let (mut done, of) = (0, self.running());
        for w in 0..self.worlds.len() {
            let world = &mut self.worlds[w];
            if world.status != WorldStatus::Running {
                continue;
            }
            match advance(&mut world.sim) {
                Ok(()) => self.write_frame(w)?,
                Err(e @ (SimError::Blowup(_) | SimError::Stall(_))) => {
                    world.status = WorldStatus::Frozen {
                        frame: world.sim.frame,
                        reason: e.to_string(),
                    };
                    frozen.push(w);
                }
                Err(e) => {
                    return Err(anyhow::Error::new(e))
                        .with_context(|| format!("world {w} ({})", world.label));
                }
            }
            done += 1;
            if let Some(f) = self.world_done.as_mut() {
                f(done, of);
            }
        }
        if !frozen.is_empty() {
            self.write_summary()?;
        }
        Ok(frozen)
    }

    /// Put world `w` back to its initial state (time 0, frame 0, running), on the backend
    /// `backend` builds for its scene as at the start; the other worlds are not touched. For
    /// runs that write no files (a world's frames would start again over its folder's).
    pub fn reset_world(
        &mut self,
        w: usize,
        backend: impl FnOnce(&Scene) -> Result<Box<dyn Backend>>,
    ) -> Result<()> {
        if self.out.is_some() {
            anyhow::bail!("a batch run that writes frame files cannot reset a world");
        }
        let count = self.worlds.len();
        let world = self
            .worlds
            .get_mut(w)
            .with_context(|| format!("no world {w}: the batch has {count} (0 to {})", count - 1))?;
        let scene = world.sim.scene.clone();
        let b = backend(&scene).with_context(|| format!("world {w} ({})", world.label))?;
        world.sim = Simulation::new(scene, b);
        world.status = WorldStatus::Running;
        self.write_frame(w)
    }

    /// Run every world to the last frame (frame 0 written first); `frame_done` is called after
    /// each frame with the worlds frozen in it.
    pub fn execute(&mut self, frame_done: impl FnMut(&BatchRun, &[usize])) -> Result<()> {
        self.execute_checkpointed(None, frame_done)
    }

    /// [`BatchRun::execute`], with a checkpoint of every world ([`BatchRun::checkpoint`]) into
    /// the output folder's `checkpoint_NNNNN/` ([`checkpoint_dir_name`]) after every frame
    /// that is a multiple of `every.0`; `every.1` is the scene file's text and `every.2` where
    /// it came from, as stored with each world. A resumed run starts at its checkpoint's frame
    /// (whose files are already written).
    pub fn execute_checkpointed(
        &mut self,
        every: Option<(u64, &str, &str)>,
        mut frame_done: impl FnMut(&BatchRun, &[usize]),
    ) -> Result<()> {
        if !self.resumed {
            self.write_first_frame()?;
        }
        while self.running() > 0 && self.frame() < self.frames {
            let frozen = self.advance_frame()?;
            frame_done(self, &frozen);
            if let Some((dir, text, origin)) =
                checkpoint_due(self.out.as_ref(), every, self.frame())?
            {
                self.checkpoint(&dir, text, origin)?;
            }
        }
        self.write_summary()
    }

    /// World `w`'s current frame: read (kept in case it blows up later) and written.
    fn write_frame(&mut self, w: usize) -> Result<()> {
        let world = &mut self.worlds[w];
        let sim = &mut world.sim;
        sim.backend.read_particles(&mut world.kept)?;
        if let Some(out) = world.output.as_mut() {
            let bodies = sim.backend.rigid_poses();
            out.write_frame(sim.frame, sim.time, &world.kept, &bodies, &sim.scene)?;
        }
        Ok(())
    }

    /// `batch.csv`: one row per world: its index, folder, swept values, and status.
    fn write_summary(&self) -> Result<()> {
        let Some(out) = &self.out else {
            return Ok(());
        };
        let count = self.worlds.len();
        let mut csv = String::from(SUMMARY_HEADER);
        for (w, world) in self.worlds.iter().enumerate() {
            csv.push_str(&summary_row(
                w,
                count,
                &world.label,
                &world.status,
                (world.sim.frame, self.frames),
                world.sim.step,
            ));
        }
        let path = out.dir.join("batch.csv");
        rtmpm_io::write_atomic(&path, csv.as_bytes())
            .with_context(|| format!("writing {}", path.display()))
    }
}

/// The checkpoint folder due after frame `frame` of a run writing into `out` with a checkpoint
/// every `every.0` frames (`every.1`, `every.2`: the scene file's text and where it came from,
/// handed back with it), if one is due.
fn checkpoint_due<'a>(
    out: Option<&OutDir>,
    every: Option<(u64, &'a str, &'a str)>,
    frame: u64,
) -> Result<Option<(PathBuf, &'a str, &'a str)>> {
    let Some((k, text, origin)) = every else {
        return Ok(None);
    };
    if k == 0 || !frame.is_multiple_of(k) {
        return Ok(None);
    }
    let Some(out) = out else {
        anyhow::bail!("checkpoints of a batch run go into its output folder: it has none");
    };
    Ok(Some((
        out.dir.join(checkpoint_dir_name(frame)),
        text,
        origin,
    )))
}

/// The header of `batch.csv`.
const SUMMARY_HEADER: &str = "world,folder,label,status,frames,steps\n";

/// World `w`'s row of `batch.csv` (of `count` worlds): index, folder, label, status (`done`,
/// `running` or `frozen: why`), the frames it completed (`frames.0` while running, of
/// `frames.1` in all; a frozen world's last) and the steps taken.
fn summary_row(
    w: usize,
    count: usize,
    label: &str,
    status: &WorldStatus,
    frames: (u64, u64),
    steps: u64,
) -> String {
    let (status, frame) = match status {
        WorldStatus::Running if frames.0 >= frames.1 => ("done".to_string(), frames.0),
        WorldStatus::Running => ("running".to_string(), frames.0),
        WorldStatus::Frozen { frame, reason } => {
            (format!("frozen: {}", reason.replace('\n', " ")), *frame)
        }
    };
    format!(
        "{w},{},{},{},{frame},{steps}\n",
        world_dir_name(w, count),
        quote(label),
        quote(&status)
    )
}

impl World {
    /// The particles of the last completed frame (of the frame it froze at, for a frozen
    /// world), as written to its files.
    pub fn particles(&self) -> &Particles {
        &self.kept
    }
}

/// The batch's output folder, when `options` names one, locked and made ready: for a fresh run,
/// or, with `resumed_to` (the last frame a checkpoint holds), taken up after that frame.
fn open_out(
    batch: &BatchScene,
    text: &str,
    options: &BatchOptions,
    resumed_to: Option<u64>,
) -> Result<Option<OutDir>> {
    let Some(dir) = &options.out_dir else {
        return Ok(None);
    };
    let out = OutDir::lock(dir, "rtmpm run (batch)")?;
    let identity = scene_identity(&batch.base.name, text);
    match resumed_to {
        Some(last) => out.start_resume(&identity, last, options.overwrite)?,
        None => out.start_fresh(&identity, options.overwrite)?,
    }
    Ok(Some(out))
}

/// World `w`'s folder made ready for a fresh run (another run's files refused unless
/// `overwrite`), and its frame files.
/// World `w` of `count`'s folder, for the scene file's text `text.0` and the world's label
/// `text.1`, made ready for a fresh run (another run's files refused unless `overwrite`), or,
/// with `resumed` (the frame and time of its checkpoint), taken up after that frame; and its
/// frame files.
fn world_output(
    top: &Path,
    (w, count): (usize, usize),
    scene: &Scene,
    (text, label): (&str, &str),
    options: &BatchOptions,
    resumed: Option<(u64, f64)>,
) -> Result<FrameOutput> {
    let dir = top.join(world_dir_name(w, count));
    let identity = scene_identity(
        &format!("{} world {w}", scene.name),
        &format!("{text}\n{label}"),
    );
    {
        let lock = OutDir::lock(&dir, "rtmpm run (batch world)")?;
        match resumed {
            Some((frame, _)) => lock.start_resume(&identity, frame, options.overwrite)?,
            None => lock.start_fresh(&identity, options.overwrite)?,
        }
    }
    // frames.pvd keeps its entries up to the checkpoint's frame: half a frame later.
    let keep_to = resumed.map(|(_, t)| t + 0.5 / scene.time.fps as f64);
    FrameOutput::new(&dir, scene, &identity, keep_to)
}

/// A CSV field, quoted when it holds a comma or a quote.
fn quote(s: &str) -> String {
    if s.contains([',', '"']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

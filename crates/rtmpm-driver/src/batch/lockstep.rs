//! The worlds of a batch held by one backend ([`Worlds`]: on the GPU every world in the same
//! kernels, `rtmpm_cuda::batch::CudaBatch`), stepped together by one [`Simulation`]: one time
//! step for every world (the CFL bound of the fastest particle of any world, the stiffest
//! material, the strongest gravity), each world's frames written to its own folder as
//! [`super::BatchRun`] writes them (`batch.csv`, `world_000/`, ...).
//!
//! A world that blows up (or stalls the time step) is frozen at its last frame: every world is
//! put back to its state at that frame, the frozen one parked (its particles where they were,
//! at rest, unstressed: it can neither bound the time step nor blow up again), and the frame
//! is run again. Its files stay those of its last frame; the others go on.
//!
//! A run without files (Python's `BatchSimulation` on the GPU) also advances by steps
//! ([`LockstepRun::advance_steps`]) and resets chosen worlds ([`LockstepRun::reset_worlds`]):
//! the worlds share one clock, so a world's time, steps and frames count from its last reset.
//!
//! The rewind point: a backend that keeps it itself ([`Worlds::save_point`]: the GPU, a copy of
//! its particle state on the device) is saved as every advance begins and put back
//! ([`Worlds::restore_point`]) when a world blows up, and its worlds are read to the host only
//! when something needs their particles: frame files, a checkpoint, a rewind that freezes a
//! world (its last good state is what it keeps), or a caller's [`LockstepRun::sync`] (Python's
//! `x` and `v`). Otherwise (the default, the CPU) every world is read after every advance and
//! put back world by world, as the point.
//!
//! Rigid bodies: each world's are the backend's ([`Worlds::world_rigid_poses`]); the driver
//! keeps them with the world's particles (at the start of each advance, and at each state read)
//! and puts them back with them: a rewind puts every world's bodies back (a frozen world's
//! parked, at rest where they were), a reset puts a world's back to their poses at its start.

mod checkpoint;
mod deferred;
mod freeze;
mod parked;
mod pipeline;
mod reset;

use super::{BatchOptions, WorldStatus, checkpoint_due, open_out, summary_row, world_output};
use crate::outdir::OutDir;
use crate::output::FrameOutput;
use crate::simulation::Simulation;
use anyhow::{Context, Result, bail};
use parked::parked_bodies;
use rtmpm_physics::Particles;
use rtmpm_rigid::BodyPose;
use rtmpm_scene::{BatchScene, Scene, StepMode};
use rtmpm_sim::{SimError, Worlds};
use std::sync::Arc;

/// `RTMPM_STEP_TIMING=1`: where an advance of the worlds (a call of Python's `step` on the GPU,
/// with checks made at once) spends the host's time, printed to stderr every 100 advances (the
/// means of keeping every world's bodies, keeping the rewind point, the steps with their check
/// (the wait for the device among them), and noting the worlds after, rewinds included); off
/// by default (one check of a flag an advance). The deferred checks' advance has its own
/// (`deferred.rs`).
pub(crate) static ADVANCE_TIMING: rtmpm_sim::timing::PartTimes<4> =
    rtmpm_sim::timing::PartTimes::new(
        "RTMPM_STEP_TIMING",
        "advance",
        "advances",
        ["bodies kept", "point kept", "steps and check", "after"],
    );

/// One world of a lockstep batch: what sets it apart, where it stands, its files.
pub struct LockWorld {
    /// What sets it apart (`material[0].yield_stress = 150`).
    pub label: String,
    /// Running or frozen.
    pub status: WorldStatus,
    /// Its own scene (its files are written with it).
    scene: Scene,
    output: Option<FrameOutput>,
    /// Its particles at the last completed frame (of the frame it froze at, once frozen); of a
    /// running world, at the last read of the backend (see [`LockstepRun::sync`]); shared with
    /// the caller's copy where a reset put it to its initial particles
    /// ([`LockstepRun::reset_worlds_initial`]: no copy a reset).
    kept: Arc<Particles>,
    /// Its rigid bodies with `kept` (as the last advance began, or at the last state read).
    bodies: Vec<BodyPose>,
    /// Its rigid bodies at its time 0 (what a reset puts back).
    start_bodies: Vec<BodyPose>,
    /// The shared clock at that state.
    at: Clock,
    /// The shared clock at the world's time 0 (its last reset; zero without one).
    origin: Clock,
}

/// A reading of the shared clock: time (s), steps, frames.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Clock {
    time: f64,
    step: u64,
    frame: u64,
}

impl LockWorld {
    /// The particles of the last completed frame (as written to its files), or of the end of
    /// the last [`LockstepRun::advance_steps`]; a frozen world's last good state. On a backend
    /// that keeps its own rewind point (the GPU) a run without files reads the worlds only when
    /// something needs them: there, a running world's particles are those of the last
    /// [`LockstepRun::sync`] (call it first; [`LockstepRun::execute`] ends with it).
    pub fn particles(&self) -> &Particles {
        &self.kept
    }

    /// Its rigid bodies' poses and velocities with [`LockWorld::particles`] (empty without
    /// rigid bodies).
    pub fn bodies(&self) -> &[BodyPose] {
        &self.bodies
    }

    /// Its own scene (its swept values).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The world's time (s) at that state, from its last reset.
    pub fn time(&self) -> f64 {
        self.at.time - self.origin.time
    }

    /// Steps the world has taken to that state, from its last reset.
    pub fn steps(&self) -> u64 {
        self.at.step - self.origin.step
    }

    /// Frames the world has completed to that state, from its last reset (the shared clock's
    /// frames: a world reset within a frame counts that frame when the others end it).
    pub fn frame(&self) -> u64 {
        self.at.frame - self.origin.frame
    }
}

/// A batch whose worlds one backend steps together.
pub struct LockstepRun<B: Worlds + ?Sized> {
    /// The simulation of every world at once (its scene: the backend's, with every world's
    /// materials).
    pub sim: Simulation<B>,
    /// The worlds, in order.
    pub worlds: Vec<LockWorld>,
    /// The frames the run goes to.
    pub frames: u64,
    out: Option<OutDir>,
    /// Taken up from a checkpoint (its current frame's files are already written).
    resumed: bool,
    /// The running worlds' particles (`kept`) lag the backend's: the last advance kept its
    /// rewind point on the backend and read nothing back ([`LockstepRun::sync`] reads them).
    stale: bool,
    /// Steps queued without their last health check ([`LockstepRun::set_deferred_checks`]).
    defer: bool,
    pending: Option<Box<Pending>>,
    /// The last pending advance's record once its check passed, kept for the next (its
    /// vectors' memory reused: no allocation a world a call).
    spare: Option<Box<Pending>>,
    /// Worlds frozen by a deferred check made outside an advance (the next advance returns
    /// them).
    found: Vec<usize>,
    /// Queue a call's steps before the last call's check where it can (`pipeline.rs`).
    pipeline: bool,
}

/// An advance whose steps were queued and returned before their last health check
/// ([`LockstepRun::set_deferred_checks`]): what putting the worlds back needs when that check
/// finds a blow-up ([`LockstepRun::settle`]), and what was done to the worlds since.
#[derive(Default)]
struct Pending {
    /// The shared clock as the advance began (the rewind point's) and as it ended, and its
    /// steps.
    clock: Clock,
    end: Clock,
    /// The clock at each frame end inside the advance whose check the backend queued
    /// ([`Worlds::queue_check`]), in order: checked first.
    marks: Vec<Clock>,
    steps: u64,
    /// Each world's status, bodies (as the advance began), clock and origin then.
    statuses: Vec<WorldStatus>,
    bodies: Vec<Vec<BodyPose>>,
    at: Vec<Clock>,
    origin: Vec<Clock>,
    /// Resets and poses made since, in order: made again after the rewind.
    since: Vec<Since>,
}

/// A change made to the worlds while a check was pending.
enum Since {
    /// These worlds reset (to the particles they then kept).
    Reset(Vec<usize>),
    /// Rigid body `.0` of each world listed put at its pose.
    Poses(usize, Vec<(usize, BodyPose)>),
}

impl<B: Worlds + ?Sized> LockstepRun<B> {
    /// The worlds of `batch` held by `backend`, whose kernels run `scene` (world 0's with every
    /// world's materials and the strongest gravity: what bounds the shared time step); `text`
    /// is the scene file's text (it names the run in the output folders).
    pub fn new(
        batch: &BatchScene,
        text: &str,
        scene: Scene,
        backend: Box<B>,
        options: &BatchOptions,
    ) -> Result<LockstepRun<B>> {
        Self::build(batch, text, (scene, backend), options, None)
    }

    /// [`LockstepRun::new`], or, with `resumed` (each world's frame and time in a checkpoint),
    /// a run whose folders are taken up after those frames rather than started afresh.
    fn build(
        batch: &BatchScene,
        text: &str,
        (scene, backend): (Scene, Box<B>),
        options: &BatchOptions,
        resumed: Option<&[(u64, f64)]>,
    ) -> Result<LockstepRun<B>> {
        let count = batch.count();
        if backend.worlds() != count {
            bail!(
                "the backend holds {} worlds, the batch has {count}",
                backend.worlds()
            );
        }
        let last = resumed.map(|r| r.iter().map(|s| s.0).max().unwrap_or(0));
        let out = open_out(batch, text, options, last)?;
        let mut worlds = Vec::with_capacity(count);
        for (w, s) in batch.worlds.iter().enumerate() {
            let label = batch.label(w);
            let output = match &out {
                Some(o) => Some(world_output(
                    &o.dir,
                    (w, count),
                    s,
                    (text, &label),
                    options,
                    resumed.map(|r| r[w]),
                )?),
                None => None,
            };
            let start_bodies = backend.world_rigid_poses(w);
            worlds.push(LockWorld {
                label,
                status: WorldStatus::Running,
                scene: s.clone(),
                output,
                kept: Arc::default(),
                bodies: start_bodies.clone(),
                start_bodies,
                at: Clock::default(),
                origin: Clock::default(),
            });
        }
        let run = LockstepRun {
            sim: Simulation::with_backend(scene, backend),
            worlds,
            frames: options.frames.unwrap_or_else(|| batch.base.time.frames()),
            out,
            resumed: resumed.is_some(),
            stale: false,
            defer: false,
            pending: None,
            spare: None,
            found: Vec::new(),
            pipeline: pipeline_default(),
        };
        run.write_summary()?;
        Ok(run)
    }

    /// Worlds still running.
    pub fn running(&self) -> usize {
        self.worlds
            .iter()
            .filter(|w| w.status == WorldStatus::Running)
            .count()
    }

    /// Read every world's state at the start (and write frame 0 of each, with an output
    /// folder): what a blown-up world is put back to.
    pub fn write_first_frame(&mut self) -> Result<()> {
        self.read_and_write_frame()
    }

    /// Run every world to the last frame (frame 0 written first); `frame_done` is called after
    /// each frame with the worlds frozen in it.
    pub fn execute(&mut self, frame_done: impl FnMut(&Self, &[usize])) -> Result<()> {
        self.execute_checkpointed(None, frame_done)
    }

    /// [`LockstepRun::execute`], with a checkpoint of every world
    /// ([`LockstepRun::checkpoint`]) into the output folder's `checkpoint_NNNNN/` after every
    /// frame that is a multiple of `every.0`; `every.1` is the scene file's text and `every.2`
    /// where it came from. A resumed run starts at its checkpoint's frame (whose files are
    /// already written).
    pub fn execute_checkpointed(
        &mut self,
        every: Option<(u64, &str, &str)>,
        mut frame_done: impl FnMut(&Self, &[usize]),
    ) -> Result<()> {
        if !self.resumed {
            self.read_and_write_frame()?;
        }
        while self.running() > 0 && self.sim.frame < self.frames {
            let frozen = self.advance_frame()?;
            frame_done(self, &frozen);
            if let Some((dir, text, origin)) =
                checkpoint_due(self.out.as_ref(), every, self.sim.frame)?
            {
                self.checkpoint(&dir, text, origin)?;
            }
        }
        self.sync()?;
        self.write_summary()
    }

    /// Advance every running world by one frame and write it; a world that blows up or stalls
    /// is frozen at its last frame (returned) and the frame run again without it; an error of
    /// the backend itself ends the run.
    pub fn advance_frame(&mut self) -> Result<Vec<usize>> {
        self.settle()?;
        let mut frozen = std::mem::take(&mut self.found);
        if self.running() > 0 {
            frozen.extend(self.advance_by(|sim| sim.advance_frame().map(drop))?);
        }
        Ok(frozen)
    }

    /// Advance every running world by `steps` steps of the shared time step (crossing frame
    /// ends as `rtmpm run --steps` does), for runs that write no files (a file is a whole
    /// frame's); a world that blows up or stalls is frozen at its state of the last call and
    /// the steps taken again without it.
    pub fn advance_steps(&mut self, steps: u64) -> Result<Vec<usize>> {
        if self.out.is_some() {
            bail!("a batch run that writes frame files advances by whole frames");
        }
        let fixed = matches!(self.sim.scene.time.step, StepMode::Fixed { .. });
        if self.defer && fixed && self.can_pipeline() {
            // This call's steps queued before the last call's check (`pipeline.rs`).
            return self.advance_pipelined(steps);
        }
        // The host's own work for these steps while the device ends the last call's, then that
        // call's check (its wait); the work done ahead is done again after a rewind.
        let ahead = self.start_deferred_call()?;
        let mut frozen = std::mem::take(&mut self.found);
        if self.running() == 0 {
            return Ok(frozen);
        }
        if self.defer && fixed {
            frozen.extend(self.advance_deferred(steps, ahead)?);
        } else {
            frozen.extend(self.advance_by(steps_of(steps))?);
        }
        Ok(frozen)
    }

    /// Advance with `advance` from the state now (the rewind point: kept by the backend when it
    /// can, else the last state read); a blow-up or stall freezes its world, puts every world
    /// back to that point and advances again; then write the frame's files (reading the worlds
    /// for them), or, where the backend keeps the point, read nothing.
    fn advance_by(
        &mut self,
        mut advance: impl FnMut(&mut Simulation<B>) -> Result<(), SimError>,
    ) -> Result<Vec<usize>> {
        let t0 = std::time::Instant::now();
        let clock = self.clock();
        self.keep_bodies()?;
        let t1 = std::time::Instant::now();
        let on_backend = self
            .sim
            .backend
            .save_point()
            .context("keeping the worlds' rewind point")?;
        if !on_backend {
            // The point is the particles read last: they must be the state now.
            self.sync()?;
        }
        let t2 = std::time::Instant::now();
        let result = advance(&mut self.sim);
        let t3 = std::time::Instant::now();
        let frozen = match result {
            Ok(()) => Vec::new(),
            Err(e @ (SimError::Blowup(_) | SimError::Stall(_))) => {
                self.rewinds(clock, on_backend, e, advance)?
            }
            Err(e) => return Err(e.into()),
        };
        self.after_advance(on_backend, &frozen)?;
        ADVANCE_TIMING.record(1, [t0, t1, t2, t3], std::time::Instant::now());
        Ok(frozen)
    }

    /// After an advance's failure `e`: freeze its world, put every world back to the point
    /// (at `clock`) and advance again with `advance`, until it passes or no world runs; the
    /// worlds frozen.
    fn rewinds(
        &mut self,
        clock: Clock,
        on_backend: bool,
        mut e: SimError,
        mut advance: impl FnMut(&mut Simulation<B>) -> Result<(), SimError>,
    ) -> Result<Vec<usize>> {
        let mut frozen = Vec::new();
        loop {
            let w = self.freeze(&e, clock.frame)?;
            frozen.push(w);
            if on_backend {
                self.rewind_on_backend(clock, &frozen)?;
            } else {
                self.rewind(clock)?;
            }
            if self.running() == 0 {
                return Ok(frozen);
            }
            e = match advance(&mut self.sim) {
                Ok(()) => return Ok(frozen),
                Err(e @ (SimError::Blowup(_) | SimError::Stall(_))) => e,
                Err(e) => return Err(e.into()),
            };
        }
    }

    /// The end of an advance: the running worlds' clocks and bodies noted, their particles
    /// left on the backend (or read, and a frame written, where the point is on the host or
    /// the run writes files); the summary written when a world froze.
    fn after_advance(&mut self, on_backend: bool, frozen: &[usize]) -> Result<()> {
        if self.running() > 0 {
            if on_backend && self.out.is_none() {
                self.note_running();
                self.stale = true;
            } else {
                self.read_and_write_frame()?;
            }
        }
        if !frozen.is_empty() {
            self.write_summary()?;
        }
        Ok(())
    }

    /// As an advance begins: keep each running world's bodies as they are now (a script may
    /// have posed them since the last read), what a rewind puts back; a frozen world's are
    /// parked again (a script posing every world's tool does not move a frozen world's).
    fn keep_bodies(&mut self) -> Result<()> {
        let worlds = &mut self.worlds;
        self.sim.backend.each_world_rigid_poses(&mut |w, poses| {
            let world = &mut worlds[w];
            if !world.bodies.is_empty() && world.status == WorldStatus::Running {
                world.bodies.clear();
                world.bodies.extend_from_slice(poses);
            }
        });
        for (w, world) in self.worlds.iter().enumerate() {
            if !world.bodies.is_empty() && world.status != WorldStatus::Running {
                self.sim
                    .backend
                    .set_world_rigid_poses(w, &parked_bodies(&world.bodies))
                    .with_context(|| format!("parking frozen world {w}'s rigid bodies"))?;
            }
        }
        Ok(())
    }

    /// Set the shared clock to `c`.
    fn set_clock(&mut self, c: Clock) {
        (self.sim.time, self.sim.step, self.sim.frame) = (c.time, c.step, c.frame);
    }

    /// The shared clock now.
    fn clock(&self) -> Clock {
        Clock {
            time: self.sim.time,
            step: self.sim.step,
            frame: self.sim.frame,
        }
    }

    /// Read every running world's particles where the last advance left them on the backend
    /// only (it kept its rewind point itself and nothing needed them: [`Worlds::save_point`]);
    /// then [`LockWorld::particles`] is each world's state now. Nothing to do otherwise.
    pub fn sync(&mut self) -> Result<()> {
        self.settle()?;
        if !self.stale {
            return Ok(());
        }
        let all = self.sim.backend.read_worlds()?;
        for (world, p) in self.worlds.iter_mut().zip(all) {
            if world.status == WorldStatus::Running {
                world.kept = Arc::new(p);
            }
        }
        self.stale = false;
        Ok(())
    }

    /// The running worlds' clock and bodies now, their particles left on the backend (a run
    /// without files on a backend that keeps its own rewind point).
    fn note_running(&mut self) {
        let now = self.clock();
        let worlds = &mut self.worlds;
        self.sim.backend.each_world_rigid_poses(&mut |w, poses| {
            let world = &mut worlds[w];
            if world.status == WorldStatus::Running {
                world.bodies.clear();
                world.bodies.extend_from_slice(poses);
                world.at = now;
            }
        });
    }

    /// Read every world; keep and write the running ones' frame.
    fn read_and_write_frame(&mut self) -> Result<()> {
        let all = self.sim.backend.read_worlds()?;
        self.stale = false;
        let now = self.clock();
        for (w, (world, p)) in self.worlds.iter_mut().zip(all).enumerate() {
            if world.status != WorldStatus::Running {
                continue;
            }
            world.kept = Arc::new(p);
            self.sim
                .backend
                .world_rigid_poses_into(w, &mut world.bodies);
            world.at = now;
            if let Some(out) = world.output.as_mut() {
                out.write_frame(
                    now.frame,
                    now.time,
                    &world.kept,
                    &world.bodies,
                    &world.scene,
                )?;
            }
        }
        Ok(())
    }

    /// `batch.csv`, as [`super::BatchRun`] writes it.
    fn write_summary(&self) -> Result<()> {
        let Some(out) = &self.out else {
            return Ok(());
        };
        let count = self.worlds.len();
        let mut csv = String::from(super::SUMMARY_HEADER);
        for (w, world) in self.worlds.iter().enumerate() {
            csv.push_str(&summary_row(
                w,
                count,
                &world.label,
                &world.status,
                (self.sim.frame, self.frames),
                world.steps(),
            ));
        }
        let path = out.dir.join("batch.csv");
        rtmpm_io::write_atomic(&path, csv.as_bytes())
            .with_context(|| format!("writing {}", path.display()))
    }
}

/// Whether deferred calls are pipelined by default (`lockstep/pipeline.rs`): not with
/// `RTMPM_BATCH_PIPELINE=off` (read once).
fn pipeline_default() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("RTMPM_BATCH_PIPELINE").map_or(true, |v| v.trim() != "off"))
}

/// An advance of `steps` steps of the shared time step (crossing frame ends).
fn steps_of<B: Worlds + ?Sized>(
    steps: u64,
) -> impl FnMut(&mut Simulation<B>) -> Result<(), SimError> {
    move |sim| {
        let target = sim.step.saturating_add(steps);
        while sim.step < target {
            sim.advance(target - sim.step)?;
        }
        Ok(())
    }
}

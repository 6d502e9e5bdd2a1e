//! The backend trait and the frame/step driver shared by every backend.
//!
//! A [`Backend`] advances particle state by explicit steps; [`Simulation`] chooses the time steps
//! (fixed, or CFL-adaptive with a cap), lands every frame exactly on its time, and reports
//! blow-ups with the particle, its material and advice.

/// The user's tool of a live view ([`Backend::set_tool`]).
pub use crate::boundary::{Tool, ToolShape};
pub use crate::io::chunks::{
    ChunkSink, FrameChunk, FrameColumns, HostBuffer, ParticleRow, fill_chunks, invert_ids,
};
/// What a live view asks a backend to draw ([`Backend::render_view`]).
pub use crate::render::ViewRequest;
use crate::scene::{Scene, StepMode};
/// The particles of the backend interface: f32 whatever precision a backend computes in.
pub use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use std::fmt;

/// Why a simulation stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum SimError {
    /// A particle's state became non-finite or its speed exploded.
    Blowup(Box<Blowup>),
    /// The CFL time step fell below `time.min_dt`: the run would crawl without end. The
    /// [`Blowup`] names the fastest particle.
    Stall(Box<Blowup>),
    /// The backend failed (device error, out of capacity, ...).
    Backend(String),
}

/// Where and why a simulation blew up.
#[derive(Debug, Clone, PartialEq)]
pub struct Blowup {
    pub step: u64,
    pub time: f64,
    pub particle: usize,
    pub position: Vec3,
    pub velocity: Vec3,
    /// Name of the particle's material.
    pub material: String,
    /// What was detected, e.g. "velocity is NaN".
    pub reason: String,
    /// The time step in use.
    pub dt: f32,
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Backend(m) => write!(f, "backend error: {m}"),
            SimError::Stall(b) => write!(
                f,
                "the time step collapsed at step {} (t = {:.6} s): {}\n  \
                 fastest: particle {} of material `{}` at ({:.4}, {:.4}, {:.4}), velocity \
                 ({:.4e}, {:.4e}, {:.4e})\n  \
                 advice: this speed is far above the material's sound speed (a blow-up under way, \
                 or an initial velocity too large): lower the body's velocity, use a fixed \
                 `time.dt` or a softer material; or, if the speed is intended, lower \
                 `time.min_dt`",
                b.step,
                b.time,
                b.reason,
                b.particle,
                b.material,
                b.position.x,
                b.position.y,
                b.position.z,
                b.velocity.x,
                b.velocity.y,
                b.velocity.z
            ),
            SimError::Blowup(b) => write!(
                f,
                "simulation blew up at step {} (t = {:.6} s, dt = {:.3e} s): particle {} of material `{}`: {}\n  \
                 position ({:.4}, {:.4}, {:.4}), velocity ({:.4e}, {:.4e}, {:.4e})\n  \
                 advice: use a smaller time step (lower `time.dt`, or `time.cfl` / `time.max_dt`), \
                 or a softer material (lower stiffness) at this resolution",
                b.step,
                b.time,
                b.dt,
                b.particle,
                b.material,
                b.reason,
                b.position.x,
                b.position.y,
                b.position.z,
                b.velocity.x,
                b.velocity.y,
                b.velocity.z
            ),
        }
    }
}

impl std::error::Error for SimError {}

/// A particle whose state is not sane after a step: non-finite, or faster than
/// [`MAX_CELLS_PER_STEP`] cells per step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadParticle {
    pub index: usize,
    pub reason: BadReason,
}

/// A particle moving more than this many cells in one step is taken as a blow-up
/// ([`BadReason::TooFast`]).
pub const MAX_CELLS_PER_STEP: f32 = 2.0;

/// What was wrong with a [`BadParticle`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BadReason {
    NonFinite,
    TooFast,
}

/// A compute backend: CPU reference or CUDA.
pub trait Backend {
    /// Human-readable name, e.g. "cpu (2 threads)".
    fn name(&self) -> String;
    /// Number of particles.
    fn num_particles(&self) -> usize;
    /// Advance one explicit step of size `dt` from time `t` (colliders move with `t`).
    /// Backends may detect blow-ups lazily (see [`Backend::check`]).
    fn step(&mut self, dt: f32, t: f32) -> Result<(), SimError>;
    /// Largest particle speed after the last step (for the CFL condition).
    fn max_speed(&mut self) -> Result<f32, SimError>;
    /// Wait for queued work and report the first bad particle since the last check, if any.
    fn check(&mut self) -> Result<Option<BadParticle>, SimError>;
    /// Copy the particle state to the host.
    fn read_particles(&mut self, out: &mut Particles) -> Result<(), SimError>;
    /// True when [`Backend::check`] costs nothing (no device round trip), so the driver checks
    /// after every step and stops at the very step that blew up.
    fn cheap_check(&self) -> bool {
        false
    }
    /// Time spent per pipeline stage so far, as (stage name, seconds), where the backend measures it.
    fn stage_times(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }
    /// Bytes of the backend's own arrays, as (host, device): particle state, grid, layout and
    /// scratch (capacities), for the bytes-per-particle figures of `rtmpm bench`. None where the
    /// backend does not count them.
    fn memory_bytes(&self) -> Option<(u64, u64)> {
        None
    }
    /// Append particles that appear during the run (emitters, see [`crate::emitter`]), in the
    /// interface's f32; they take the next original indices. Called by [`Simulation`] before
    /// the step they appear in. A backend that cannot grow answers a clear error.
    fn add_particles(&mut self, particles: &Particles) -> Result<(), SimError> {
        let _ = particles;
        Err(SimError::Backend(format!(
            "the backend `{}` cannot add particles during a run, which the scene's [[emitter]] \
             tables need: use the CPU or the single-GPU CUDA backend, or remove the emitters",
            self.name()
        )))
    }
    /// The rigid bodies' states (`[[rigid_body]]`) at the current time, where the backend
    /// couples them (the CPU backend with the cargo feature `rigid`); empty otherwise.
    fn rigid_bodies(&self) -> Vec<crate::rigid::BodyState> {
        Vec::new()
    }
    /// The columns `sink.columns()` of every particle in original order, chunk by chunk (see
    /// [`crate::io::chunks`]): the frame writers' read, without the whole state on the host.
    /// The default reads every particle ([`Backend::read_particles`]) and cuts that into chunks.
    fn export_frame(&mut self, sink: &mut dyn ChunkSink) -> Result<(), SimError> {
        let mut p = Particles::default();
        self.read_particles(&mut p)?;
        crate::io::chunks::export_particles(&p, sink)
    }
    /// Host memory of `words` 32-bit words for the chunks of [`Backend::export_frame`]
    /// (page-locked on a GPU, for copies at the bus's full rate).
    fn chunk_memory(&self, words: usize) -> Result<Box<dyn HostBuffer>, SimError> {
        let mut v: Vec<u32> = Vec::new();
        v.try_reserve_exact(words).map_err(|_| {
            SimError::Backend(format!(
                "cannot allocate {:.1} MB for frame chunks",
                words as f64 * 4e-6
            ))
        })?;
        v.resize(words, 0);
        Ok(Box::new(v))
    }
    /// Where the time of building the backend went, phase by phase, in words (the CUDA
    /// backend: probe, layout, kernels, packing, upload, device fill); `None` where it is not
    /// broken down.
    fn setup_details(&self) -> Option<String> {
        None
    }
    /// The rigid bodies' poses and velocities as the backend's rigid-body engine holds them
    /// (what a checkpoint stores); empty where [`Backend::rigid_bodies`] is.
    fn rigid_poses(&self) -> Vec<crate::rigid::BodyPose> {
        Vec::new()
    }
    /// Give the rigid bodies every impulse the grid has sent them, so that
    /// [`Backend::rigid_poses`] is their state at the current time: a backend that moves them
    /// a step late (the CUDA backend's `rigid_overlap`) takes the last step's now. Others have
    /// nothing to do.
    fn flush_rigid(&mut self) -> Result<(), SimError> {
        Ok(())
    }
    /// Put the rigid bodies at `poses` (from [`Backend::rigid_poses`]: resuming a checkpoint,
    /// or a script moving them; call [`Backend::flush_rigid`] before reading the poses to
    /// change). A backend that couples no bodies accepts only none.
    fn set_rigid_poses(&mut self, poses: &[crate::rigid::BodyPose]) -> Result<(), SimError> {
        if poses.is_empty() {
            return Ok(());
        }
        Err(SimError::Backend(format!(
            "the backend `{}` cannot restore the {} rigid bodies of a checkpoint",
            self.name(),
            poses.len()
        )))
    }
    /// Called by [`Simulation`] after every frame (after the check): a place for work that may
    /// synchronise, e.g. rebalancing particles between GPUs.
    fn end_of_frame(&mut self) -> Result<(), SimError> {
        Ok(())
    }
    /// Draw the current state as `req` asks into `out` (resized to `req.width` x
    /// `req.height`, 8-bit RGB, top row first) from the backend's own arrays, the picture of
    /// [`crate::render::render`] with [`ViewRequest::options`]. `Ok(false)`: this backend does
    /// not draw; the caller reads the particles and uses the CPU renderer.
    fn render_view(
        &mut self,
        req: &ViewRequest,
        out: &mut crate::render::Image,
    ) -> Result<bool, SimError> {
        let _ = (req, out);
        Ok(false)
    }
    /// Change gravity (m/s^2) from the next step on (the rigid bodies' too).
    fn set_gravity(&mut self, gravity: Vec3) -> Result<(), SimError> {
        let _ = gravity;
        Err(SimError::Backend(format!(
            "the backend `{}` cannot change gravity during a run: use the CPU or the \
             single-GPU CUDA backend",
            self.name()
        )))
    }
    /// Put the user's tool (or none) into the grid update from the next step on: a moving
    /// collider with the separating rule and no friction (see [`Tool`]). The backend holds it
    /// at `tool.center`; the caller moves it between steps.
    fn set_tool(&mut self, tool: Option<Tool>) -> Result<(), SimError> {
        if tool.is_none() {
            return Ok(());
        }
        Err(SimError::Backend(format!(
            "the backend `{}` has no user tool: use the CPU or the single-GPU CUDA backend",
            self.name()
        )))
    }
}

/// Drives a backend through frames of a scene. The backend is a `Box<dyn Backend>` by default;
/// a caller that needs the concrete type (or `Send`) names it, e.g. `Simulation<MyBackend>`.
pub struct Simulation<B: Backend + ?Sized = dyn Backend> {
    pub scene: Scene,
    pub backend: Box<B>,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken so far.
    pub step: u64,
    /// Frames completed so far.
    pub frame: u64,
    /// Time step of the last step.
    pub last_dt: f32,
    max_sound_speed: f32,
    /// Particles each emitter has emitted so far; set at the first step from the time then
    /// (a resumed run starts with those of its checkpoint).
    emitted: Option<Vec<u64>>,
}

impl Simulation {
    /// A simulation at time 0 (or at the given state when resuming).
    pub fn new(scene: Scene, backend: Box<dyn Backend>) -> Simulation {
        Simulation::with_backend(scene, backend)
    }
}

impl<B: Backend + ?Sized> Simulation<B> {
    /// A simulation of a backend of type `B` (see [`Simulation::new`] for the usual
    /// `Box<dyn Backend>`).
    pub fn with_backend(scene: Scene, backend: Box<B>) -> Simulation<B> {
        let max_sound_speed = scene
            .materials
            .iter()
            .map(|m| m.model.sound_speed(m.density))
            .fold(0.0f32, f32::max);
        Simulation {
            scene,
            backend,
            time: 0.0,
            step: 0,
            frame: 0,
            last_dt: 0.0,
            max_sound_speed,
            emitted: None,
        }
    }

    /// Change gravity from the next step on: the backend's and the scene's
    /// ([`Backend::set_gravity`]); a non-finite vector is refused.
    pub fn set_gravity(&mut self, gravity: Vec3) -> Result<(), SimError> {
        if !gravity.is_finite() {
            return Err(SimError::Backend(format!(
                "gravity must be finite, got {gravity}"
            )));
        }
        self.backend.set_gravity(gravity)?;
        self.scene.gravity = gravity;
        Ok(())
    }

    /// Duration of one frame (s).
    pub fn frame_duration(&self) -> f64 {
        1.0 / self.scene.time.fps as f64
    }

    /// Time step for the next step, before clipping to the frame end.
    pub fn next_dt(&mut self) -> Result<f32, SimError> {
        Ok(match self.scene.time.step {
            StepMode::Fixed { dt } => dt,
            StepMode::Cfl {
                cfl,
                max_dt,
                min_dt,
            } => {
                let speed = self.backend.max_speed()? + self.max_sound_speed;
                let dt = if speed > 0.0 {
                    (cfl * self.scene.dx / speed).min(max_dt)
                } else {
                    max_dt
                };
                // NaN speeds are the health check's (a blow-up); a finite collapse is a stall.
                if dt < min_dt {
                    return Err(self.stall(dt, min_dt));
                }
                dt
            }
        })
    }

    /// The error of a CFL step `dt` below `min_dt`, naming the fastest particle.
    fn stall(&mut self, dt: f32, min_dt: f32) -> SimError {
        let mut p = Particles::default();
        if let Err(e) = self.backend.read_particles(&mut p) {
            return e;
        }
        let (i, speed) =
            p.v.iter()
                .map(|v| v.length())
                .enumerate()
                .fold((0, f32::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
        let material = p
            .material
            .get(i)
            .and_then(|&m| self.scene.materials.get(m as usize))
            .map(|m| m.name.clone())
            .unwrap_or_else(|| "?".into());
        SimError::Stall(Box::new(Blowup {
            step: self.step,
            time: self.time,
            particle: i,
            position: p.x.get(i).copied().unwrap_or(Vec3::NAN),
            velocity: p.v.get(i).copied().unwrap_or(Vec3::NAN),
            material,
            reason: format!(
                "the CFL step is {dt:.3e} s, below time.min_dt = {min_dt:.3e} s (fastest \
                 particle at {speed:.4e} m/s, sound speed {:.4e} m/s)",
                self.max_sound_speed
            ),
            dt,
        }))
    }

    /// One step of size `dt`; the emitters' particles due by its end appear first.
    pub fn step_once(&mut self, dt: f32) -> Result<(), SimError> {
        self.emit(self.time + dt as f64)?;
        self.backend.step(dt, self.time as f32)?;
        self.time += dt as f64;
        self.step += 1;
        self.last_dt = dt;
        if self.backend.cheap_check() {
            self.check()?;
        }
        Ok(())
    }

    /// Advance to the end of the next frame; returns the number of steps taken.
    ///
    /// With a fixed dt that divides the frame duration, exactly that many equal steps are taken;
    /// otherwise the last step is shortened to land on the frame time.
    pub fn advance_frame(&mut self) -> Result<u64, SimError> {
        let start = self.step;
        self.advance(u64::MAX)?;
        Ok(self.step - start)
    }

    /// Advance towards the end of the current frame, taking at most `max_steps` steps. Returns
    /// true when the frame was completed (then [`Simulation::frame`] has moved on).
    pub fn advance(&mut self, max_steps: u64) -> Result<bool, SimError> {
        let frame_start = self.frame as f64 * self.frame_duration();
        let frame_end = (self.frame + 1) as f64 * self.frame_duration();
        let mut taken = 0;
        if let StepMode::Fixed { dt } = self.scene.time.step {
            let per_frame = self.frame_duration() / dt as f64;
            if (per_frame - per_frame.round()).abs() < 1e-6 * per_frame.max(1.0) {
                // Whole number of equal steps per frame: count them, so time never drifts.
                let per_frame = per_frame.round() as u64;
                let done = ((self.time - frame_start) / dt as f64).round() as u64;
                while done + taken < per_frame {
                    if taken == max_steps {
                        self.check()?;
                        return Ok(false);
                    }
                    self.step_once(dt)?;
                    taken += 1;
                    self.time = frame_start + (done + taken) as f64 * dt as f64;
                }
                self.time = frame_end;
                self.finish_frame()?;
                return Ok(true);
            }
        }
        let eps = 1e-9 * self.frame_duration();
        while self.time < frame_end - eps {
            if taken == max_steps {
                self.check()?;
                return Ok(false);
            }
            let dt = self.next_dt()?;
            let remaining = (frame_end - self.time) as f32;
            self.step_once(dt.min(remaining))?;
            taken += 1;
        }
        self.time = frame_end;
        self.finish_frame()?;
        Ok(true)
    }

    /// Hand the backend the particles the emitters emit by time `t_end`.
    fn emit(&mut self, t_end: f64) -> Result<(), SimError> {
        let emitters = &self.scene.emitters;
        if emitters.is_empty() {
            return Ok(());
        }
        let time = self.time;
        let emitted = self
            .emitted
            .get_or_insert_with(|| emitters.iter().map(|e| e.count_at(time)).collect());
        let p = crate::emitter::emit_between(emitters, &self.scene.materials, emitted, t_end);
        if p.is_empty() {
            return Ok(());
        }
        self.backend.add_particles(&p)
    }

    /// Particles emitted so far by each emitter of the scene (empty before the first step).
    pub fn emitted(&self) -> &[u64] {
        self.emitted.as_deref().unwrap_or(&[])
    }

    fn finish_frame(&mut self) -> Result<(), SimError> {
        self.frame += 1;
        self.check()?;
        self.backend.end_of_frame()
    }

    /// Check the backend for a bad particle and turn it into a [`SimError::Blowup`].
    pub fn check(&mut self) -> Result<(), SimError> {
        if let Some(bad) = self.backend.check()? {
            let mut p = Particles::default();
            self.backend.read_particles(&mut p)?;
            let i = bad.index.min(p.len().saturating_sub(1));
            let material = p
                .material
                .get(i)
                .and_then(|&m| self.scene.materials.get(m as usize))
                .map(|m| m.name.clone())
                .unwrap_or_else(|| "?".into());
            let reason = match bad.reason {
                BadReason::NonFinite => {
                    "position or velocity is not finite (NaN or infinity)".into()
                }
                BadReason::TooFast => format!(
                    "speed exceeds {MAX_CELLS_PER_STEP} cells per step (|v| dt > {MAX_CELLS_PER_STEP} dx)"
                ),
            };
            return Err(SimError::Blowup(Box::new(Blowup {
                step: self.step,
                time: self.time,
                particle: bad.index,
                position: p.x.get(i).copied().unwrap_or(Vec3::NAN),
                velocity: p.v.get(i).copied().unwrap_or(Vec3::NAN),
                material,
                reason,
                dt: self.last_dt,
            })));
        }
        Ok(())
    }
}

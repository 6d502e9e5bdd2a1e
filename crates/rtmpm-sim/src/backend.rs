//! The trait every compute backend implements.

use crate::chunks::{ChunkSink, export_particles};
use crate::error::{BadParticle, SimError};
use rtmpm_geometry::Tool;
use rtmpm_io::chunks::HostBuffer;
use rtmpm_physics::Particles;
use rtmpm_physics::math::Vec3;
use rtmpm_render::{Image, ViewRequest};
use rtmpm_rigid::{BodyLoad, BodyPose, BodyState};

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
    /// Append particles that appear during the run (emitters, see `rtmpm_scene::emitter`), in the
    /// interface's f32; they take the next original indices. Called by `rtmpm_driver::Simulation` before
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
    fn rigid_bodies(&self) -> Vec<BodyState> {
        Vec::new()
    }
    /// The columns `sink.columns()` of every particle in original order, chunk by chunk (see
    /// [`rtmpm_io::chunks`]): the frame writers' read, without the whole state on the host.
    /// The default reads every particle ([`Backend::read_particles`]) and cuts that into chunks.
    fn export_frame(&mut self, sink: &mut dyn ChunkSink) -> Result<(), SimError> {
        let mut p = Particles::default();
        self.read_particles(&mut p)?;
        export_particles(&p, sink)
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
    fn rigid_poses(&self) -> Vec<BodyPose> {
        Vec::new()
    }
    /// The load (force and torque) the material put on each rigid body over the last step, in
    /// the order of [`Backend::rigid_poses`], for every kind of body (a kinematic tool's too);
    /// zeros before the first step. A backend that gives the bodies a step's impulses a step
    /// late (the CUDA backend's `rigid_overlap`) reports the last step's after
    /// [`Backend::flush_rigid`]. `None`: this backend does not report loads.
    fn rigid_loads(&self) -> Option<Vec<BodyLoad>> {
        None
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
    fn set_rigid_poses(&mut self, poses: &[BodyPose]) -> Result<(), SimError> {
        if poses.is_empty() {
            return Ok(());
        }
        Err(SimError::Backend(format!(
            "the backend `{}` cannot restore the {} rigid bodies of a checkpoint",
            self.name(),
            poses.len()
        )))
    }
    /// Called by `rtmpm_driver::Simulation` after every frame (after the check): a place for work that may
    /// synchronise, e.g. rebalancing particles between GPUs.
    fn end_of_frame(&mut self) -> Result<(), SimError> {
        Ok(())
    }
    /// Draw the current state as `req` asks into `out` (resized to `req.width` x
    /// `req.height`, 8-bit RGB, top row first) from the backend's own arrays, the picture of
    /// [`rtmpm_render::render`] with [`ViewRequest::options`]. `Ok(false)`: this backend does
    /// not draw; the caller reads the particles and uses the CPU renderer.
    fn render_view(&mut self, req: &ViewRequest, out: &mut Image) -> Result<bool, SimError> {
        let _ = (req, out);
        Ok(false)
    }
    /// Begin the picture of the current state that [`Backend::render_view`] would draw, to be
    /// collected by [`Backend::finish_view`]: a backend that draws on a device queues the
    /// picture and its copy to the host and returns at once, so that the caller can queue the
    /// next steps before it waits for the picture (a live view keeps the device busy while the
    /// host finishes the last picture). `Ok(false)`: not begun (the caller uses
    /// [`Backend::render_view`], or the CPU renderer).
    fn begin_view(&mut self, req: &ViewRequest) -> Result<bool, SimError> {
        let _ = req;
        Ok(false)
    }
    /// The picture begun by [`Backend::begin_view`] into `out` (as [`Backend::render_view`]
    /// fills it): waits for that picture only, not for steps queued after it.
    fn finish_view(&mut self, out: &mut Image) -> Result<(), SimError> {
        let _ = out;
        Err(SimError::Backend(format!(
            "the backend `{}` has no picture begun to finish",
            self.name()
        )))
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

//! Backends that hold the worlds of a batch in one set of arrays, stepped together (one launch
//! per stage for every world): the driver steps them as one [`Backend`] and reads, freezes and
//! writes them world by world through [`Worlds`].

use crate::backend::Backend;
use crate::error::SimError;
use rtmpm_physics::Particles;
use rtmpm_rigid::{BodyLoad, BodyPose};

/// A backend holding several independent worlds: particles of world `w` never touch another
/// world's grid, each world keeps its own coordinates and material indices.
pub trait Worlds: Backend {
    /// Number of worlds.
    fn worlds(&self) -> usize;

    /// Every world's particles, in its own coordinates and material indices, world by world.
    fn read_worlds(&mut self) -> Result<Vec<Particles>, SimError>;

    /// Put world `w`'s particles to `particles` (as many as it has, in its own material
    /// indices); the other worlds are not touched.
    fn put_world(&mut self, w: usize, particles: &Particles) -> Result<(), SimError>;

    /// Put each world `w` of `worlds` to its particles, as [`Worlds::put_world`] one after
    /// another (a world listed twice ends with its last); the other worlds are not touched.
    /// The default is that loop; a backend may do it at once (the GPU batch: one upload and
    /// one launch for each run of consecutive worlds, every world checked before any changes).
    fn put_worlds(&mut self, worlds: &[(usize, &Particles)]) -> Result<(), SimError> {
        for (w, p) in worlds {
            self.put_world(*w, p)?;
        }
        Ok(())
    }

    /// Put each world of `worlds` back to the particles it was given for its time 0, by the
    /// backend's own means, as [`Worlds::put_worlds`] of those particles would leave it, bit for
    /// bit (the GPU batch: from an image of them kept on the device, no packing and no upload);
    /// the other worlds are not touched. `Ok(false)`: the backend keeps no such state (the
    /// default), nothing changed, and the caller puts the particles with
    /// [`Worlds::put_worlds`].
    fn put_initial(&mut self, worlds: &[usize]) -> Result<bool, SimError> {
        let _ = worlds;
        Ok(false)
    }

    /// Do now the host's work the next step would do first where it changes nothing of what
    /// the worlds are (the GPU batch: the rigid-body poses a script gave, kept until then, put
    /// into their worlds), so that it runs while the device still works on the steps queued
    /// before (the lockstep driver calls it before it waits for them, as a call with deferred
    /// checks begins). The same state as doing it then; a rewind after it is still correct
    /// (the next step does again whatever the rewind changed). Nothing by default.
    fn prepare_steps(&mut self) -> Result<(), SimError> {
        Ok(())
    }

    /// Whether [`Worlds::queue_check`] queues anything (then a caller checking steps later may
    /// leave the checks of the frame ends it crosses to then as well). `false` by default.
    fn queues_checks(&self) -> bool {
        false
    }

    /// The steps queued so far will be checked later (the lockstep driver's deferred checks):
    /// a backend that runs them asynchronously may queue the read of what a check reads now
    /// (`Ok(true)`), and the next [`Backend::check`] then reads the oldest read queued, waiting
    /// for the steps before it alone, not for work queued after them (the GPU batch: its control
    /// words copied to page-locked memory behind the steps). A check that finds a bad particle
    /// or an error drops the later reads. Nothing by default (`Ok(false)`: the check reads the
    /// state when made).
    fn queue_check(&mut self) -> Result<bool, SimError> {
        Ok(false)
    }

    /// Keep every world's state as it is now as the point [`Worlds::restore_point`] puts the
    /// worlds back to (the rewind after a world blows up), held by the backend itself (a GPU:
    /// a device-to-device copy of its particle state). `Ok(true)`: kept; `Ok(false)`: this
    /// backend keeps no such point (the default), and the driver keeps each world's particles
    /// on the host instead, read after every advance and put back world by world with
    /// [`Worlds::put_world`]. Rigid bodies are not part of the point: the driver keeps and puts
    /// back their poses ([`Worlds::set_world_rigid_poses`]).
    fn save_point(&mut self) -> Result<bool, SimError> {
        Ok(false)
    }

    /// Put every world's particles back to the last point [`Worlds::save_point`] kept (`true`),
    /// exactly as they were (what a step derives from them, the grid and its mapping, made
    /// again at the next step). An error where no point was kept.
    fn restore_point(&mut self) -> Result<(), SimError> {
        Err(SimError::Backend(format!(
            "the backend `{}` keeps no rewind point of its worlds",
            self.name()
        )))
    }

    /// Keep the state the worlds will have once everything queued so far has run (the GPU:
    /// a device-to-device copy queued behind it) as the *next* rewind point, in a second slot,
    /// leaving the point [`Worlds::restore_point`] puts back untouched (`Ok(true)`): the
    /// lockstep driver keeps the next call's point while the last call's check, which may
    /// still need the last point, is pending. [`Worlds::use_next_point`] then makes it the
    /// point. `Ok(false)`: no second slot (the default), nothing kept.
    fn save_next_point(&mut self) -> Result<bool, SimError> {
        Ok(false)
    }

    /// Make the point the last [`Worlds::save_next_point`] kept the one
    /// [`Worlds::restore_point`] puts back (the state it was kept at, not the state now); the
    /// point before is dropped. An error where no next point was kept.
    fn use_next_point(&mut self) -> Result<(), SimError> {
        Err(SimError::Backend(format!(
            "the backend `{}` keeps no second rewind point of its worlds",
            self.name()
        )))
    }

    /// The steps queued after the copy a check just found a failure in are being dropped (the
    /// lockstep driver's pipelined calls: the next call's steps, queued before the last call's
    /// check, which found a blow-up): undo what they did that [`Worlds::restore_point`] does not
    /// put back (the GPU batch: the error word of its control words cleared, which steps from a
    /// blown-up state may set; the state, its mapping and the check's words are put back or
    /// reset already). Called before the rewind. Nothing by default.
    fn drop_queued_steps(&mut self) -> Result<(), SimError> {
        Ok(())
    }

    /// The world of particle `index` (original order over all worlds, as
    /// [`crate::BadParticle::index`] and [`crate::Blowup::particle`] give it) and its index in
    /// that world.
    fn world_of_particle(&self, index: usize) -> Option<(usize, usize)>;

    /// World `w`'s rigid bodies' poses and velocities now (one per `[[rigid_body]]` of its
    /// scene, in order), as [`Backend::rigid_poses`] gives a single run's; empty where the
    /// backend holds none.
    fn world_rigid_poses(&self, _w: usize) -> Vec<BodyPose> {
        Vec::new()
    }

    /// Put world `w`'s rigid bodies at `poses` (from [`Worlds::world_rigid_poses`]: a script
    /// posing a tool, a reset, a rewind), from the next step on; the other worlds' are not
    /// touched. A backend that holds no bodies accepts only none.
    fn set_world_rigid_poses(&mut self, w: usize, poses: &[BodyPose]) -> Result<(), SimError> {
        if poses.is_empty() {
            return Ok(());
        }
        Err(SimError::Backend(format!(
            "the backend `{}` holds no rigid bodies for world {w} ({} poses given)",
            self.name(),
            poses.len()
        )))
    }

    /// World `w`'s rigid bodies' poses into `out` (emptied first): what
    /// [`Worlds::world_rigid_poses`] gives, without a new vector where the backend can (the
    /// driver keeps every world's poses at every call).
    fn world_rigid_poses_into(&self, w: usize, out: &mut Vec<BodyPose>) {
        *out = self.world_rigid_poses(w);
    }

    /// Every world's rigid bodies' poses, handed to `each(w, poses)` world after world (what
    /// [`Worlds::world_rigid_poses_into`] gives of each): the default asks world by world; a
    /// backend may hand them all at once (the GPU batch: from its rows, under one lock, where
    /// world by world took a lock a world; the driver keeps every running world's poses twice
    /// a call).
    fn each_world_rigid_poses(&self, each: &mut dyn FnMut(usize, &[BodyPose])) {
        let mut out = Vec::new();
        for w in 0..self.worlds() {
            self.world_rigid_poses_into(w, &mut out);
            each(w, &out);
        }
    }

    /// Put rigid body `body` of each world `w` of `poses` at its pose, the world's other bodies
    /// where they are, from the next step on: [`Worlds::set_world_rigid_poses`] of each world's
    /// [`Worlds::world_rigid_poses`] with row `body` replaced (the default, world after world;
    /// an error leaves the worlds before it posed). A backend may pose them all at once (the
    /// GPU batch: every world checked first, then posed with no vector per world), with the same
    /// result.
    fn set_body_poses(&mut self, body: usize, poses: &[(usize, BodyPose)]) -> Result<(), SimError> {
        for (w, pose) in poses {
            let mut all = self.world_rigid_poses(*w);
            let count = all.len();
            let row = all.get_mut(body).ok_or_else(|| {
                SimError::Backend(format!(
                    "rigid body {body} of world {w}: the backend holds {count} for it"
                ))
            })?;
            *row = *pose;
            self.set_world_rigid_poses(*w, &all)?;
        }
        Ok(())
    }

    /// The load (force and torque) the material put on each of world `w`'s rigid bodies over
    /// the last step, as [`Backend::rigid_loads`] gives a single run's (zeros before the first
    /// step); `None`: this backend does not report loads. An error: the backend failed while
    /// reading them (e.g. waiting for the step that made them).
    fn world_rigid_loads(&self, _w: usize) -> Result<Option<Vec<BodyLoad>>, SimError> {
        Ok(None)
    }
}

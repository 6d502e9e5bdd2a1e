//! Resets of chosen worlds of a lockstep batch ([`LockstepRun::reset_worlds`],
//! [`LockstepRun::reset_worlds_initial`]): each listed world put to given particles (or to its
//! initial ones, which the backend may keep) at its time 0, running again, the other worlds not
//! touched; refused where the worlds' shared clock would make a reset world meet a moving
//! collider where it is now.

use super::{LockstepRun, WorldStatus};
use anyhow::{Context, Result, bail};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::Worlds;
use std::sync::Arc;

impl<B: Worlds + ?Sized> LockstepRun<B> {
    /// Put each world `w` of `starts` to its particles `p` (its initial ones, or any state of as
    /// many particles) at its time 0, running again (a frozen one too); the other worlds are not
    /// touched. For runs that write no files. The worlds share one clock: when every world is
    /// reset it goes back to 0; otherwise the reset worlds count their time from now, refused
    /// when the scene's colliders move with the clock (a reset world would meet them where they
    /// are now, not where they were at time 0). Checked before any world changes.
    pub fn reset_worlds(&mut self, starts: Vec<(usize, Particles)>) -> Result<()> {
        let starts = starts.into_iter().map(|(w, p)| (w, Arc::new(p))).collect();
        self.reset_with(starts, false)
    }

    /// [`LockstepRun::reset_worlds`] to each world's particles at its time 0 (`starts[i].1`:
    /// the particles the batch's worlds were made with, which the backend may keep; shared, not
    /// copied, as the world's particles): the backend puts them back by its own means where it
    /// keeps them ([`Worlds::put_initial`]: the GPU batch's image on the device, no packing and
    /// no upload), else as [`LockstepRun::reset_worlds`] does; the same state either way.
    pub fn reset_worlds_initial(&mut self, starts: Vec<(usize, Arc<Particles>)>) -> Result<()> {
        self.reset_with(starts, true)
    }

    /// [`LockstepRun::reset_worlds`], the particles put by [`Worlds::put_initial`] first when
    /// `initial`.
    pub(super) fn reset_with(
        &mut self,
        starts: Vec<(usize, Arc<Particles>)>,
        initial: bool,
    ) -> Result<()> {
        if self.out.is_some() {
            bail!("a batch run that writes frame files cannot reset a world");
        }
        let count = self.worlds.len();
        let mut listed = vec![false; count];
        for (w, p) in &starts {
            let Some(world) = self.worlds.get(*w) else {
                bail!("no world {w}: the batch has {count} (0 to {})", count - 1);
            };
            if p.len() != world.kept.len() {
                bail!(
                    "world {w} has {} particles, {} given",
                    world.kept.len(),
                    p.len()
                );
            }
            listed[*w] = true;
        }
        let all = listed.iter().all(|&l| l);
        if !all && let Some(k) = moving_collider(&self.sim.scene) {
            bail!(
                "resetting some worlds of a batch whose worlds share one clock (all worlds in the \
                 same kernels): collider {k} moves with that clock, so a reset world would meet \
                 it where it is now (t = {:.6} s), not where it was at time 0\n  fix: reset every \
                 world at once (the clock goes back to 0), or run the batch on the CPU backend \
                 (each world has its own clock)",
                self.sim.time
            );
        }
        if all {
            (self.sim.time, self.sim.step, self.sim.frame) = (0.0, 0, 0);
        }
        let now = self.clock();
        // Every world's particles at once (on the GPU one upload, no wait per world; to the
        // initial state, from the image the backend keeps, without it).
        let listed_now = || starts.iter().map(|s| s.0).collect::<Vec<usize>>();
        let kept = initial
            && self
                .sim
                .backend
                .put_initial(&listed_now())
                .with_context(|| format!("resetting worlds {:?}", listed_now()))?;
        if !kept {
            let refs: Vec<(usize, &Particles)> = starts.iter().map(|(w, p)| (*w, &**p)).collect();
            self.sim
                .backend
                .put_worlds(&refs)
                .with_context(|| format!("resetting worlds {:?}", listed_now()))?;
        }
        for (w, p) in starts {
            let start = self.worlds[w].start_bodies.clone();
            self.sim
                .backend
                .set_world_rigid_poses(w, &start)
                .with_context(|| format!("resetting world {w}'s rigid bodies"))?;
            let world = &mut self.worlds[w];
            world.bodies = start;
            world.kept = p;
            world.status = WorldStatus::Running;
            (world.at, world.origin) = (now, now);
        }
        self.note_reset(listed_worlds(&listed));
        Ok(())
    }
}

/// The worlds marked in `listed`.
fn listed_worlds(listed: &[bool]) -> Vec<usize> {
    (0..listed.len()).filter(|&w| listed[w]).collect()
}

/// The first collider of `scene` that moves with time (a velocity, an angular velocity or
/// keyframes), if any.
fn moving_collider(scene: &Scene) -> Option<usize> {
    scene.colliders.iter().position(|c| {
        c.keyframes.is_some()
            || c.velocity != rtmpm_physics::math::Vec3::ZERO
            || c.angular_velocity != rtmpm_physics::math::Vec3::ZERO
    })
}

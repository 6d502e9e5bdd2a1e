//! Checkpoints of a lockstep batch, in the folder layout of every batch checkpoint
//! (`batch.toml` and one `world_NNN.ckpt` per world: `super::super::checkpoint`): each world's
//! particles at its last state (a frozen world's last good one), its own clock, its status.
//! Resuming builds the backend from the saved particles (a frozen world parked, as the run that
//! wrote it left it) and puts the shared clock back. On a backend that is bit-reproducible the
//! resumed run goes on bit for bit as the one that wrote the checkpoint
//! (`crates/rtmpm-cpu/tests/lockstep_files.rs`); on the GPU within what its atomic sums allow.

use super::parked::{parked, parked_bodies};
use super::{Clock, LockstepRun};
use crate::batch::checkpoint::{Saved, prepare_dir, read_folder, write_folder};
use crate::batch::{BatchOptions, WorldStatus};
use anyhow::{Context, Result, bail};
use rtmpm_io::checkpoint::Checkpoint;
use rtmpm_physics::Particles;
use rtmpm_scene::{BatchScene, Scene};
use rtmpm_sim::Worlds;
use std::path::Path;

impl<B: Worlds + ?Sized> LockstepRun<B> {
    /// Save every world into the folder `dir` (made if missing; a folder holding other files
    /// than a batch checkpoint's is refused): `text` is the batch scene file's text and
    /// `origin` where it came from, both stored with each world.
    pub fn checkpoint(&mut self, dir: &Path, text: &str, origin: &str) -> Result<()> {
        prepare_dir(dir)?;
        self.sync()?;
        let backend = &self.sim.backend;
        let saved: Vec<Saved> = self
            .worlds
            .iter()
            .enumerate()
            .map(|(w, world)| Saved {
                label: world.label.clone(),
                status: world.status.clone(),
                ckpt: Checkpoint {
                    scene_toml: text.to_string(),
                    scene_origin: origin.to_string(),
                    time: world.time(),
                    step: world.steps(),
                    frame: world.frame(),
                    // A running world's bodies now (posed since its last step too); a
                    // frozen world's as it froze.
                    bodies: match world.status {
                        WorldStatus::Running => backend.world_rigid_poses(w),
                        WorldStatus::Frozen { .. } => world.bodies.clone(),
                    },
                    files: world.scene.file_hashes(),
                    // A running world's state now; a frozen world's last good one.
                    particles: rtmpm_physics::Particles::clone(&world.kept),
                },
            })
            .collect();
        write_folder(dir, &saved)
    }

    /// The batch `batch` (read from the scene file whose text is `text`) at the state saved in
    /// the folder `dir` ([`LockstepRun::checkpoint`], or a CPU batch's checkpoint whose running
    /// worlds share one clock), on the backend `backend` builds from every world's particles
    /// (it returns the scene its kernels run and itself, as for [`LockstepRun::new`]); with an
    /// output folder each world's folder is taken up after its checkpoint's frame. Refused with
    /// the reason and the fix, before any folder changes, as a CPU batch's resume is, and when
    /// the running worlds' clocks differ (worlds reset at different times).
    pub fn resume(
        batch: &BatchScene,
        text: &str,
        dir: &Path,
        backend: impl FnOnce(&[Particles]) -> Result<(Scene, Box<B>)>,
        options: &BatchOptions,
    ) -> Result<LockstepRun<B>> {
        let saved = read_folder(batch, text, dir)?;
        let clock = shared_clock(&saved, dir)?;
        let particles: Vec<Particles> = saved
            .iter()
            .map(|s| match s.status {
                WorldStatus::Running => s.ckpt.particles.clone(),
                WorldStatus::Frozen { .. } => parked(&s.ckpt.particles),
            })
            .collect();
        let made = backend(&particles)?;
        drop(particles);
        let states: Vec<(u64, f64)> = saved.iter().map(|s| (s.ckpt.frame, s.ckpt.time)).collect();
        let mut run = Self::build(batch, text, made, options, Some(&states))?;
        (run.sim.time, run.sim.step, run.sim.frame) = (clock.time, clock.step, clock.frame);
        for (w, (world, s)) in run.worlds.iter_mut().zip(saved).enumerate() {
            // Its rigid bodies as saved (a frozen world's parked, as its particles).
            let bodies = match s.status {
                WorldStatus::Running => s.ckpt.bodies.clone(),
                WorldStatus::Frozen { .. } => parked_bodies(&s.ckpt.bodies),
            };
            if bodies.len() != world.start_bodies.len() {
                bail!(
                    "cannot resume the batch from {}: world {w}'s checkpoint holds {} rigid \
                     bodies, its scene has {}",
                    dir.display(),
                    bodies.len(),
                    world.start_bodies.len()
                );
            }
            run.sim
                .backend
                .set_world_rigid_poses(w, &bodies)
                .with_context(|| format!("resuming world {w}'s rigid bodies"))?;
            world.bodies = s.ckpt.bodies.clone();
            world.at = Clock {
                time: s.ckpt.time,
                step: s.ckpt.step,
                frame: s.ckpt.frame,
            };
            world.origin = Clock::default();
            world.kept = std::sync::Arc::new(s.ckpt.particles);
            world.status = s.status;
        }
        run.write_summary()?;
        Ok(run)
    }
}

/// The clock every running world of `saved` is at (they step together), or, when every world
/// is frozen, the latest; refused when running worlds are at different clocks.
fn shared_clock(saved: &[Saved], dir: &Path) -> Result<Clock> {
    let clock = |s: &Saved| Clock {
        time: s.ckpt.time,
        step: s.ckpt.step,
        frame: s.ckpt.frame,
    };
    let mut running = saved
        .iter()
        .enumerate()
        .filter(|(_, s)| s.status == WorldStatus::Running);
    let Some((first, s0)) = running.next() else {
        let latest = saved.iter().map(clock).max_by_key(|c| c.step);
        return Ok(latest.unwrap_or_default());
    };
    let c0 = clock(s0);
    for (w, s) in running {
        let c = clock(s);
        if (c.step, c.frame) != (c0.step, c0.frame) || c.time.to_bits() != c0.time.to_bits() {
            bail!(
                "cannot resume the batch from {}: its worlds are at different times (world \
                 {first} at step {} of frame {}, world {w} at step {} of frame {}); worlds stepped \
                 together in one backend share one clock\n  fix: resume it on the CPU backend \
                 (--backend cpu; in Python backend=\"cpu\"), where each world has its own",
                dir.display(),
                c0.step,
                c0.frame,
                c.step,
                c.frame
            );
        }
    }
    Ok(c0)
}

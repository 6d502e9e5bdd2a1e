//! A world that blows up in a lockstep batch: frozen at its last frame ([`LockstepRun::freeze`]),
//! every world put back to that frame ([`LockstepRun::rewind`], or to the rewind point the
//! backend kept, [`LockstepRun::rewind_on_backend`]), the frozen one parked: its particles where
//! they were, at rest and unstressed ([`super::parked::parked`]), its rigid bodies at rest
//! ([`super::parked::parked_bodies`]).

use super::parked::{parked, parked_bodies};
use super::{Clock, LockstepRun, WorldStatus};
use anyhow::{Context, Result, bail};
use rtmpm_sim::{Blowup, SimError, Worlds};
use std::sync::Arc;

impl<B: Worlds + ?Sized> LockstepRun<B> {
    /// Freeze the world of the particle `e` names at `frame`, its last. An error that names no
    /// particle of any world cannot be pinned on one and ends the run; so does a world frozen
    /// before that blows up again (parked, it should not): rewinding for it would step the
    /// same blow-up again. Each rewind of an advance thus freezes another running world, and
    /// an advance rewinds at most as many times as there are worlds.
    pub(super) fn freeze(&mut self, e: &SimError, frame: u64) -> Result<usize> {
        let particle = match e {
            SimError::Blowup(b) | SimError::Stall(b) => b.particle,
            _ => unreachable!("only blow-ups and stalls freeze a world"),
        };
        let Some((w, i)) = self.sim.backend.world_of_particle(particle) else {
            return Err(anyhow::anyhow!("{e}"))
                .context("a batch's step failed and names no particle of any world");
        };
        if let WorldStatus::Frozen { frame: at, .. } = &self.worlds[w].status {
            bail!(
                "world {w} (its particle {i}), frozen at frame {at} and parked (at rest, \
                 unstressed), failed again, so the batch's run stops rather than rewind and step \
                 the same failure again: {e}\n  a parked world should not fail: its own moving \
                 colliders or rigid bodies driven into it, or a backend that did not put it back \
                 at rest (`Worlds::put_world`, `Worlds::restore_point`)\n  fix: leave world {w} \
                 out of the batch, or run the batch with --backend cpu"
            );
        }
        // Said as the world's own run would say it: its particle, its step and time.
        let origin = self.worlds[w].origin;
        let own = |b: &Blowup| {
            Box::new(Blowup {
                particle: i,
                step: b.step - origin.step,
                time: b.time - origin.time,
                ..b.clone()
            })
        };
        let reason = match e {
            SimError::Blowup(b) => SimError::Blowup(own(b)),
            SimError::Stall(b) => SimError::Stall(own(b)),
            other => other.clone(),
        };
        self.worlds[w].status = WorldStatus::Frozen {
            frame,
            reason: reason.to_string(),
        };
        Ok(w)
    }

    /// Every world back to its particles of the last frame (a frozen one parked), and the clock
    /// back to that frame.
    pub(super) fn rewind(&mut self, clock: Clock) -> Result<()> {
        let frame = clock.frame;
        for (w, world) in self.worlds.iter().enumerate() {
            let (p, bodies) = match world.status {
                WorldStatus::Running => (world.kept.clone(), world.bodies.clone()),
                WorldStatus::Frozen { .. } => {
                    (Arc::new(parked(&world.kept)), parked_bodies(&world.bodies))
                }
            };
            self.sim
                .backend
                .put_world(w, &p)
                .with_context(|| format!("putting world {w} back to frame {frame}"))?;
            self.sim
                .backend
                .set_world_rigid_poses(w, &bodies)
                .with_context(|| {
                    format!("putting world {w}'s rigid bodies back to frame {frame}")
                })?;
        }
        (self.sim.time, self.sim.step, self.sim.frame) = (clock.time, clock.step, clock.frame);
        Ok(())
    }

    /// Every world back to the rewind point the backend kept as this advance began (at `clock`),
    /// the worlds of `frozen` (frozen in this advance) with the others frozen before parked, as
    /// [`LockstepRun::rewind`] puts them: the running worlds exactly at the point, each frozen
    /// world at its last good state, at rest; every world's bodies as the advance began (a
    /// frozen world's parked). The particles of the worlds frozen now are read at the point
    /// first, when the host's copy lags it (their last good state, which they keep).
    pub(super) fn rewind_on_backend(&mut self, clock: Clock, frozen: &[usize]) -> Result<()> {
        let frame = clock.frame;
        self.sim
            .backend
            .restore_point()
            .with_context(|| format!("putting every world back to frame {frame}"))?;
        if self.stale {
            let all = self.sim.backend.read_worlds()?;
            for (w, (world, p)) in self.worlds.iter_mut().zip(all).enumerate() {
                if world.status == WorldStatus::Running || frozen.contains(&w) {
                    world.kept = Arc::new(p);
                }
            }
            self.stale = false;
        }
        for (w, world) in self.worlds.iter().enumerate() {
            let bodies = match world.status {
                WorldStatus::Running => world.bodies.clone(),
                WorldStatus::Frozen { .. } => {
                    self.sim
                        .backend
                        .put_world(w, &parked(&world.kept))
                        .with_context(|| format!("parking world {w} at frame {frame}"))?;
                    parked_bodies(&world.bodies)
                }
            };
            self.sim
                .backend
                .set_world_rigid_poses(w, &bodies)
                .with_context(|| {
                    format!("putting world {w}'s rigid bodies back to frame {frame}")
                })?;
        }
        (self.sim.time, self.sim.step, self.sim.frame) = (clock.time, clock.step, clock.frame);
        Ok(())
    }
}

//! The worlds as they run: on the CPU backend each world is a simulation of its own
//! (rtmpm-driver's `BatchRun`); on one GPU every world is in the same kernels
//! (rtmpm-cuda's `CudaBatch`), stepped together at one time step by rtmpm-driver's
//! `LockstepRun`. What `BatchSimulation` reads and does, for either.

use anyhow::Result;
use rtmpm_cuda::batch::CudaBatch;
use rtmpm_driver::batch::lockstep::LockstepRun;
use rtmpm_driver::batch::{BatchRun, WorldStatus};
use rtmpm_physics::Particles;
use rtmpm_scene::Scene;
use rtmpm_sim::Backend;

/// A batch's worlds, on the CPU backend or on one GPU.
pub(super) enum Run {
    /// Each world its own simulation on the CPU backend.
    Each(BatchRun),
    /// Every world in the same CUDA kernels, one clock and time step for all.
    Lockstep(Box<LockstepRun<CudaBatch>>),
}

impl Run {
    /// Number of worlds.
    pub fn count(&self) -> usize {
        match self {
            Run::Each(r) => r.worlds.len(),
            Run::Lockstep(r) => r.worlds.len(),
        }
    }

    /// "cpu" or "cuda".
    pub fn kind(&self) -> &'static str {
        match self {
            Run::Each(_) => "cpu",
            Run::Lockstep(_) => "cuda",
        }
    }

    /// The backend's name (world 0's on the CPU).
    pub fn backend_name(&self) -> String {
        match self {
            Run::Each(r) => r
                .worlds
                .first()
                .map(|w| w.sim.backend.name())
                .unwrap_or_default(),
            Run::Lockstep(r) => r.sim.backend.name(),
        }
    }

    /// What sets world `w` apart.
    pub fn label(&self, w: usize) -> &str {
        match self {
            Run::Each(r) => &r.worlds[w].label,
            Run::Lockstep(r) => &r.worlds[w].label,
        }
    }

    /// World `w`'s status.
    pub fn status(&self, w: usize) -> &WorldStatus {
        match self {
            Run::Each(r) => &r.worlds[w].status,
            Run::Lockstep(r) => &r.worlds[w].status,
        }
    }

    /// Every world's particles on the host as they are now: on the GPU the driver reads the
    /// worlds only when something needs them (`LockstepRun::sync`); nothing to do on the CPU.
    pub fn sync(&mut self) -> Result<()> {
        match self {
            Run::Each(_) => Ok(()),
            Run::Lockstep(r) => r.sync(),
        }
    }

    /// Make the health check a GPU step call left pending, if any (see
    /// [`Run::set_overlap`]; nothing to do on the CPU).
    pub fn settle(&mut self) -> Result<()> {
        match self {
            Run::Each(_) => Ok(()),
            Run::Lockstep(r) => r.settle(),
        }
    }

    /// On the GPU, return from a step call with its steps queued, before its health check
    /// (`LockstepRun::set_deferred_checks`); refused on the CPU, whose calls end with their
    /// work done.
    pub fn set_overlap(&mut self, on: bool) -> Result<()> {
        match self {
            Run::Each(_) if on => {
                anyhow::bail!("overlap is for a batch on the GPU (this one runs on the CPU)")
            }
            Run::Each(_) => Ok(()),
            Run::Lockstep(r) => r.set_deferred_checks(on),
        }
    }

    /// Whether step calls return before their health check.
    pub fn overlap(&self) -> bool {
        match self {
            Run::Each(_) => false,
            Run::Lockstep(r) => r.deferred_checks(),
        }
    }

    /// Wait until the device has done everything queued so far, every stream of the batch's
    /// context (on the GPU; nothing to do on the CPU, whose calls end with their work done).
    pub fn synchronize(&mut self) -> Result<()> {
        match self {
            Run::Each(_) => Ok(()),
            Run::Lockstep(r) => Ok(r.sim.backend.backend().wait_for_device()?),
        }
    }

    /// Rebuilds of the particle-to-block mapping so far (on the GPU, read from the device after
    /// its queued work; `None` on the CPU, which rebuilds its grid every step).
    pub fn rebuilds(&mut self) -> Result<Option<u32>> {
        match self {
            Run::Each(_) => Ok(None),
            Run::Lockstep(r) => Ok(Some(r.sim.backend.backend().rebuild_count()?)),
        }
    }

    /// How the P2G after resets was redone so far (on the GPU: the redos of the worlds put
    /// alone, and of every world; `None` on the CPU, whose every step does its P2G).
    pub fn p2g_redos(&self) -> Option<(u64, u64)> {
        match self {
            Run::Each(_) => None,
            Run::Lockstep(r) => {
                let c = r.sim.backend.redo_counts();
                Some((c.partial, c.full))
            }
        }
    }

    /// The host's waits for the device so far, by reason (on the GPU; `None` on the CPU,
    /// whose calls do their work on the host).
    pub fn host_waits(&self) -> Option<rtmpm_cuda::WaitCounts> {
        match self {
            Run::Each(_) => None,
            Run::Lockstep(r) => Some(r.sim.backend.host_waits()),
        }
    }

    /// World `w`'s particles after the last call (a frozen world's last good state); on the
    /// GPU as of the last [`Run::sync`] (their number is always right).
    pub fn particles(&self, w: usize) -> &Particles {
        match self {
            Run::Each(r) => r.worlds[w].particles(),
            Run::Lockstep(r) => r.worlds[w].particles(),
        }
    }

    /// World `w`'s scene.
    pub fn scene(&self, w: usize) -> &Scene {
        match self {
            Run::Each(r) => &r.worlds[w].sim.scene,
            Run::Lockstep(r) => r.worlds[w].scene(),
        }
    }

    /// World `w`'s time (s), frames completed and steps taken (on the GPU: from its last reset).
    pub fn clock(&self, w: usize) -> (f64, u64, u64) {
        match self {
            Run::Each(r) => {
                let s = &r.worlds[w].sim;
                (s.time, s.frame, s.step)
            }
            Run::Lockstep(r) => {
                let x = &r.worlds[w];
                (x.time(), x.frame(), x.steps())
            }
        }
    }

    /// Worlds still running.
    pub fn running(&self) -> usize {
        match self {
            Run::Each(r) => r.running(),
            Run::Lockstep(r) => r.running(),
        }
    }

    /// Frames left to the end of the scene's duration (of the furthest world on the CPU; of
    /// the shared clock on the GPU).
    pub fn frames_left(&self) -> u64 {
        match self {
            Run::Each(r) => {
                let max = r.worlds.iter().map(|w| w.sim.frame).max();
                r.frames.saturating_sub(max.unwrap_or(0))
            }
            Run::Lockstep(r) => r.frames.saturating_sub(r.sim.frame),
        }
    }

    /// Every running world to the end of its current frame; the worlds frozen.
    pub fn advance_frame(&mut self) -> Result<Vec<usize>> {
        match self {
            Run::Each(r) => r.advance_frame(),
            Run::Lockstep(r) => r.advance_frame(),
        }
    }

    /// Every running world `steps` steps on; the worlds frozen.
    pub fn advance_steps(&mut self, steps: u64) -> Result<Vec<usize>> {
        match self {
            Run::Each(r) => r.advance_steps(steps),
            Run::Lockstep(r) => r.advance_steps(steps),
        }
    }
}

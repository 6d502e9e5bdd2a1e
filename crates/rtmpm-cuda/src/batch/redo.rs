//! The P2G of the worlds put since the last step, redone for those worlds only (host side of
//! `kernels/redo.cu`). With G2P2G the grid the coming step reads holds the last fused scatter,
//! of the particles as they were: a world put since (a reset, a state given:
//! [`CudaBatch::put_worlds`], [`CudaBatch::put_initial`]) needs its P2G again, every other
//! world's is still right. The puts list their worlds ([`plan::PutWorlds`]); before the next step,
//! [`CudaBatch::redo_puts`] clears those worlds' pblocks and scatters their particles again
//! (`redo_clear_lanes`, then `redo_p2g_lanes`; `redo_clear`, `redo_p2g` with
//! `RTMPM_BATCH_REDO=wave`), the other worlds' nodes untouched, where
//! the step used to redo the P2G of every world (`CTL_P2G_PENDING`).
//!
//! The full redo stays where the partial one would not pay or does not apply ([`Redo::Full`]):
//! more than half of the worlds put ([`plan::PutWorlds::plan`]), more runs of consecutive
//! worlds than a kernel argument holds ([`crate::contract::REDO_RANGES`]),
//! [`CudaBatch::restore_point`] (every world, and a rebuild), `RTMPM_BATCH_REDO=old`
//! ([`plan::old_redo`]). The kernels themselves do nothing when the step redoes every world
//! anyway: a rebuild is due (a put particle left its gblock's free zone), the full P2G was asked
//! for (first step, new dt), an error stopped the run.

pub(super) mod plan;

use plan::{Redo, RedoCounts};

use super::CudaBatch;
use crate::contract::{CTL_P2G_PENDING, REDO_ENTRIES_PER_WARP, RedoWorlds};
use crate::error::err;
use crate::kernels::Kernel;
use cudarc::driver::PushKernelArg;
use rtmpm_physics::transfer::Transfer;
use rtmpm_sim::SimError;

impl CudaBatch {
    /// Worlds `worlds` were put: with G2P2G the next step needs their P2G again, listed for
    /// [`CudaBatch::redo_puts`], or, with the full redo ([`CudaBatch::set_full_redo`]), the
    /// P2G of every world asked of the step at once.
    pub(super) fn note_put(&mut self, worlds: impl Iterator<Item = usize>) -> Result<(), SimError> {
        if !self.backend.g2p2g() {
            return Ok(());
        }
        if self.full_redo {
            self.redo_counts.full += 1;
            return self.backend.set_ctl_word(CTL_P2G_PENDING, 1);
        }
        worlds.for_each(|w| self.put_since.add(w));
        Ok(())
    }

    /// Queue the P2G of the worlds put since the last step ([`plan::PutWorlds::plan`]): their
    /// pblocks cleared and their particles scattered again into the grid the coming step reads,
    /// or the full redo asked of the step. [`CudaBatch::step`] calls it first; for a test, it may be
    /// called before (nothing is left for the step then).
    pub fn redo_puts(&mut self) -> Result<Redo, SimError> {
        let plan = self.put_since.plan(self.worlds());
        match &plan {
            Redo::Nothing => {}
            Redo::Full => {
                self.redo_counts.full += 1;
                self.backend.set_ctl_word(CTL_P2G_PENDING, 1)?;
            }
            // The redo scatters MLS-MPM's P2G only; a batch takes no CK-MPM scene
            // (batch/accept.rs), but were it to, its step redoes every world.
            Redo::Worlds(_) if self.backend.ctx.transfer != Transfer::Mls.code() => {
                self.redo_counts.full += 1;
                self.backend.set_ctl_word(CTL_P2G_PENDING, 1)?;
                return Ok(Redo::Full);
            }
            Redo::Worlds(r) => {
                self.redo_counts.partial += 1;
                self.launch_redo(r)?;
            }
        }
        Ok(plan)
    }

    /// `redo_clear_lanes` then `redo_p2g_lanes` of the runs `r` (a thread a pblock, a warp a
    /// warp-list entry: [`REDO_ENTRIES_PER_WARP`]), or with [`CudaBatch::set_wave_redo`]
    /// `redo_clear` then `redo_p2g` (a warp each, a full wave), on the stream, into the grid the
    /// coming step reads.
    fn launch_redo(&mut self, r: &RedoWorlds) -> Result<(), SimError> {
        let b = &self.backend;
        let c = b.step_ctx();
        let k = &b.kernels;
        let (pblocks, entries) = (c.pblock_cap as usize, c.warp_cap as usize);
        let (clear, p2g) = if self.wave_redo {
            (
                (Kernel::RedoClear, k.wave(pblocks * 32, 256)),
                (Kernel::RedoP2g, k.wave(entries * 32, 128)),
            )
        } else {
            (
                (Kernel::RedoClearLanes, k.wave(pblocks, 256)),
                (
                    Kernel::RedoP2gLanes,
                    k.wave(entries * 32 / REDO_ENTRIES_PER_WARP, 128),
                ),
            )
        };
        // SAFETY: the kernels bound every index by the device counters and capacities
        // (pblocks, warps) and read `r` by value.
        unsafe {
            b.stream
                .launch_builder(&k[clear.0])
                .arg(&c)
                .arg(r)
                .launch(clear.1)
                .map_err(err("redo the P2G of the worlds put (clear)"))?;
            b.stream
                .launch_builder(&k[p2g.0])
                .arg(&c)
                .arg(r)
                .launch(p2g.1)
                .map_err(err("redo the P2G of the worlds put"))?;
        }
        Ok(())
    }

    /// Launch the partial redo's kernels of a warp an item over a full wave (`redo_clear`,
    /// `redo_p2g`: `true`, the default with `RTMPM_BATCH_REDO=wave`) or of a lane an item
    /// (`redo_clear_lanes`, `redo_p2g_lanes`: `false`, the default otherwise); for comparisons
    /// of the two in one process.
    pub fn set_wave_redo(&mut self, on: bool) {
        self.wave_redo = on;
    }

    /// Redo the P2G of every world after a put (`true`: as with `RTMPM_BATCH_REDO=old`, the
    /// default then) or of the worlds put alone (`false`, the default otherwise); for
    /// comparisons of the two in one process. Worlds listed already keep their redo.
    pub fn set_full_redo(&mut self, on: bool) {
        self.full_redo = on;
    }

    /// How the P2G after puts was redone so far.
    pub fn redo_counts(&self) -> RedoCounts {
        self.redo_counts
    }
}

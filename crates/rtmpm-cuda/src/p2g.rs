//! Host side of `kernels/p2g.cu` (the scatter P2G of seed 000 and the shared-memory ablation), and
//! [`P2gPlan`]: the P2G strategy of a backend with the buffers it owns, including the two gather
//! strategies of seed 001 ([`crate::p2g_reverse_map`], [`crate::p2g_sort`]).

use crate::P2gMode;
use crate::backend::{Kernels, cfg_wave};
use crate::layout::Ctx;
use crate::p2g_reverse_map::ReverseMap;
use crate::p2g_sort::SortMap;
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};
use rtmpm_core::transfer::Transfer;

/// The P2G strategy of a backend, with the device buffers of the gather strategies.
pub(crate) enum P2gPlan {
    /// Scatter with warp-level reduction and global atomics (seed 000).
    Warp,
    /// Scatter into a shared-memory tile per gblock (ablation).
    Shared,
    /// Gather through replicated node-to-particle reverse maps (seed 001).
    ReverseMap(ReverseMap),
    /// Gather through a per-step sort of the particle-node contributions (seed 001).
    Sort(SortMap),
}

impl P2gPlan {
    /// The mode this plan implements.
    pub(crate) fn mode(&self) -> P2gMode {
        match self {
            P2gPlan::Warp => P2gMode::Warp,
            P2gPlan::Shared => P2gMode::Shared,
            P2gPlan::ReverseMap(_) => P2gMode::ReverseMap,
            P2gPlan::Sort(_) => P2gMode::Sort,
        }
    }

    /// Names of the phases that [`P2gPlan::enqueue_phase`] enqueues (timed separately by the
    /// benchmark).
    pub(crate) fn phases(&self) -> &'static [&'static str] {
        match self {
            P2gPlan::Warp => &["scatter"],
            P2gPlan::Shared => &["scatter_shared"],
            P2gPlan::ReverseMap(_) => ReverseMap::PHASES,
            P2gPlan::Sort(_) => SortMap::PHASES,
        }
    }

    /// Enqueue phase `i` of [`P2gPlan::phases`].
    pub(crate) fn enqueue_phase(
        &self,
        i: usize,
        k: &Kernels,
        s: &CudaStream,
        c: &Ctx,
    ) -> Result<(), DriverError> {
        match self {
            P2gPlan::Warp | P2gPlan::Shared => enqueue_scatter(k, s, c, self.mode(), 0),
            P2gPlan::ReverseMap(r) => r.enqueue_phase(i, k, s, c),
            P2gPlan::Sort(m) => m.enqueue_phase(i, k, s, c),
        }
    }

    /// Enqueue the whole P2G.
    pub(crate) fn enqueue(&self, k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), DriverError> {
        for i in 0..self.phases().len() {
            self.enqueue_phase(i, k, s, c)?;
        }
        Ok(())
    }

    /// Device buffers this strategy adds to the pipeline: (what, bytes).
    pub(crate) fn memory(&self) -> Vec<(&'static str, usize)> {
        match self {
            P2gPlan::Warp | P2gPlan::Shared => Vec::new(),
            P2gPlan::ReverseMap(r) => r.memory.clone(),
            P2gPlan::Sort(m) => m.memory.clone(),
        }
    }
}

/// Enqueue the scatter P2G: for MLS the warp variant (4 warps per CUDA block) or the
/// shared-memory ablation; for the classic MPM transfers `p2g_mpm` (whatever `mode`). `part`: 0
/// every particle; multi-GPU (MLS only): 1 the gblocks next to a shared block, 2 the others
/// (`p2g.cu`).
pub(crate) fn enqueue_scatter(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    mode: P2gMode,
    part: u32,
) -> Result<(), DriverError> {
    let wave = cfg_wave(c.warp_cap as usize * 32, 128, k.wave_threads);
    // SAFETY: the kernels bounds-check against the device counters and capacities.
    unsafe {
        if c.transfer != Transfer::Mls.code() {
            s.launch_builder(&k.p2g_mpm).arg(c).launch(wave)?;
            return Ok(());
        }
        match mode {
            P2gMode::Shared => {
                s.launch_builder(&k.p2g_shared)
                    .arg(c)
                    .arg(&part)
                    .launch(LaunchConfig {
                        grid_dim: (c.gblock_cap, 1, 1),
                        block_dim: (256, 1, 1),
                        shared_mem_bytes: 0,
                    })?
            }
            _ => s.launch_builder(&k.p2g).arg(c).arg(&part).launch(wave)?,
        };
    }
    Ok(())
}

/// Enqueue the MUSL re-map: clear `grid_aux`, then scatter the updated particle momenta into it.
pub(crate) fn enqueue_musl(k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), DriverError> {
    // SAFETY: the kernels bounds-check against the device counters.
    unsafe {
        s.launch_builder(&k.grid_clear_aux).arg(c).launch(cfg_wave(
            c.pblock_cap as usize * 256,
            256,
            k.wave_threads,
        ))?;
        s.launch_builder(&k.p2g_musl).arg(c).launch(cfg_wave(
            c.warp_cap as usize * 32,
            128,
            k.wave_threads,
        ))?;
    }
    Ok(())
}

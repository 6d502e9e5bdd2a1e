//! Host side of `kernels/p2g.cu`.

use crate::P2gMode;
use crate::backend::{Kernels, cfg_wave};
use crate::layout::Ctx;
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};
use rtmpm_core::transfer::Transfer;

/// Enqueue P2G: for MLS the warp variant (4 warps per CUDA block) or the shared-memory
/// ablation; for the classic MPM transfers `p2g_mpm` (whatever `mode`).
pub(crate) fn enqueue(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    mode: P2gMode,
) -> Result<(), DriverError> {
    let wave = cfg_wave(c.warp_cap as usize * 32, 128, k.wave_threads);
    // SAFETY: the kernels bounds-check against the device counters and capacities.
    unsafe {
        if c.transfer != Transfer::Mls.code() {
            s.launch_builder(&k.p2g_mpm).arg(c).launch(wave)?;
            return Ok(());
        }
        match mode {
            P2gMode::Warp => s.launch_builder(&k.p2g).arg(c).launch(wave)?,
            P2gMode::Shared => s
                .launch_builder(&k.p2g_shared)
                .arg(c)
                .launch(LaunchConfig {
                    grid_dim: (c.gblock_cap, 1, 1),
                    block_dim: (256, 1, 1),
                    shared_mem_bytes: 0,
                })?,
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

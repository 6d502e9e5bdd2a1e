//! Host side of `kernels/p2g.cu`.

use crate::P2gMode;
use crate::backend::{Kernels, cfg_wave};
use crate::layout::Ctx;
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};

/// Enqueue P2G: warp variant (4 warps per CUDA block) or the shared-memory ablation. `part`: 0
/// every particle; multi-GPU: 1 the gblocks next to a shared block, 2 the others (`p2g.cu`).
pub(crate) fn enqueue(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    mode: P2gMode,
    part: u32,
) -> Result<(), DriverError> {
    // SAFETY: the kernels bounds-check against the device counters and capacities.
    unsafe {
        match mode {
            P2gMode::Warp => s.launch_builder(&k.p2g).arg(c).arg(&part).launch(cfg_wave(
                c.warp_cap as usize * 32,
                128,
                k.wave_threads,
            ))?,
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
        };
    }
    Ok(())
}

//! Host side of `kernels/p2g/scatter.cu`: the scatter P2G (warps with segmented reduction and
//! atomics, or the shared-memory tile of the ablation) and that of the classic MPM transfers.

use crate::contract::Ctx;
use crate::kernels::{Kernel, Kernels};
use crate::options::{CkP2g, P2gMode};
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};
use rtmpm_physics::transfer::Transfer;

/// Enqueue the scatter P2G: for MLS the warp variant (4 warps per CUDA block) or the
/// shared-memory ablation; for CK-MPM `p2g_ck` (direct atomics) or `p2g_ck_warp` (warp
/// reduction; also with G2P2G, after a rebuild) into its two grids as `ck` says, for the classic MPM transfers `p2g_mpm` (both
/// whatever `mode`). `part`: 0 every particle; several GPUs (MLS only): 1 the
/// gblocks next to a shared block, 2 the others.
pub(crate) fn enqueue(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    mode: P2gMode,
    ck: CkP2g,
    part: u32,
) -> Result<(), DriverError> {
    let wave = k.wave(c.warp_cap as usize * 32, 128);
    // SAFETY: the kernels bounds-check against the device counters and capacities.
    unsafe {
        if c.transfer == Transfer::CkMpm.code() {
            let f = match ck {
                CkP2g::Direct => Kernel::P2gCk,
                CkP2g::Warp | CkP2g::Fused => Kernel::P2gCkWarp,
            };
            k.launch_step(s, f, wave, c, None)?;
            return Ok(());
        }
        if c.transfer != Transfer::Mls.code() {
            k.launch_step(s, Kernel::P2gMpm, wave, c, None)?;
            return Ok(());
        }
        match mode {
            P2gMode::Shared => {
                s.launch_builder(&k[Kernel::P2gShared])
                    .arg(c)
                    .arg(&part)
                    .launch(LaunchConfig {
                        grid_dim: (c.gblock_cap, 1, 1),
                        block_dim: (256, 1, 1),
                        shared_mem_bytes: 0,
                    })?;
            }
            _ => k.launch_step(s, Kernel::P2g, wave, c, Some(part))?,
        }
    }
    Ok(())
}

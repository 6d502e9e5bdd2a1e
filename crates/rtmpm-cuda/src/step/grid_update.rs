//! Host side of `kernels/grid_update.cu`.

use crate::contract::Ctx;
use crate::kernels::{Kernel, Kernels};
use cudarc::driver::{CudaStream, DriverError, PushKernelArg};

/// Enqueue the merged grid update (velocity, gravity, walls, colliders) of every pblock
/// (`part` 0), or, several GPUs, of the pblocks no other GPU shares (1) or of the shared ones (2).
pub(crate) fn enqueue(k: &Kernels, s: &CudaStream, c: &Ctx, part: u32) -> Result<(), DriverError> {
    let cfg = k.wave(c.pblock_cap as usize * 64, 128);
    // SAFETY: the kernel bounds-checks against the pblock count.
    unsafe { k.launch_step(s, Kernel::GridUpdate, cfg, c, Some(part)) }
}

/// Enqueue the MUSL re-mapped momentum to velocity (with the boundary conditions).
pub(crate) fn enqueue_musl(k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), DriverError> {
    // SAFETY: the kernel bounds-checks against the pblock count.
    unsafe {
        s.launch_builder(&k[Kernel::GridUpdateMusl])
            .arg(c)
            .launch(k.wave(c.pblock_cap as usize * 64, 128))?
    };
    Ok(())
}

//! Host side of `kernels/g2p.cu`.

use crate::backend::{Kernels, cfg_wave};
use crate::layout::Ctx;
use cudarc::driver::{CudaStream, DriverError, PushKernelArg};

/// Enqueue the merged G2P (interpolation, F, plasticity, advection, free-zone and health checks).
pub(crate) fn enqueue(k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), DriverError> {
    // SAFETY: the kernel bounds-checks against the warp count.
    unsafe {
        s.launch_builder(&k.g2p).arg(c).launch(cfg_wave(
            c.warp_cap as usize * 32,
            128,
            k.wave_threads,
        ))?
    };
    Ok(())
}

//! Host side of `kernels/g2p/`: the G2P kernels (`g2p.cu`) and the fused G2P2G (`g2p2g.cu`).

use crate::contract::Ctx;
use crate::kernels::{Kernel, Kernels};
use cudarc::driver::{CudaStream, DriverError, PushKernelArg};
use rtmpm_physics::transfer::Transfer;

/// Enqueue the merged G2P (interpolation, F, plasticity, advection, free-zone and health checks):
/// `g2p2g` with G2P2G (the next step's P2G in the same kernel; `g2p2g_ck` for CK-MPM), else `g2p`
/// for MLS, `g2p_ck` for CK-MPM (from its two grids), `g2p_mpm` for the classic MPM transfers. `all_fluid`: every material is a fluid (G2P2G then runs
/// `g2p2g_fluid`, which moves one word of F in and three out).
pub(crate) fn enqueue(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    all_fluid: bool,
) -> Result<(), DriverError> {
    let f = if c.grid_next != 0 && c.transfer == Transfer::CkMpm.code() {
        Kernel::G2p2gCk
    } else if c.grid_next != 0 && all_fluid {
        Kernel::G2p2gFluid
    } else if c.grid_next != 0 {
        Kernel::G2p2g
    } else if c.transfer == Transfer::Mls.code() {
        Kernel::G2p
    } else if c.transfer == Transfer::CkMpm.code() {
        Kernel::G2pCk
    } else {
        Kernel::G2pMpm
    };
    let threads = c.warp_cap as usize * 32;
    let launch = match (f, k.g2p2g_resident, k.g2p2g_ck_resident) {
        (Kernel::G2p2g, Some([blocks, _]), _)
        | (Kernel::G2p2gFluid, Some([_, blocks]), _)
        | (Kernel::G2p2gCk, _, Some(blocks))
            if blocks > 0 =>
        {
            crate::kernels::cfg(threads.min(blocks as usize * 128), 128)
        }
        _ => k.wave(threads, 128),
    };
    // SAFETY: the kernel bounds-checks against the warp count (grid-stride over the warp list).
    unsafe { k.launch_step(s, f, launch, c, None) }
}

/// Enqueue the first MUSL pass: PIC/FLIP blend of the particle velocities only.
pub(crate) fn enqueue_velocity(k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), DriverError> {
    // SAFETY: the kernel bounds-checks against the warp count.
    unsafe {
        s.launch_builder(&k[Kernel::G2pMpmVelocity])
            .arg(c)
            .launch(k.wave(c.warp_cap as usize * 32, 128))?
    };
    Ok(())
}

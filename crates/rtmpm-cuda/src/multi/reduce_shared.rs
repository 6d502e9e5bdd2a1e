//! Host side of `kernels/multi/reduce_shared.cu`: the sum of the grid blocks several GPUs share
//! (Fei, Huang & Gao, GTC 2022: job splitting by particles, reduce-sum of shared blocks). The
//! NCCL calls (transport=nccl) or barriers (transport=p2p, [`super::barrier`]) between these
//! launches are made by [`super::exchange`].

use crate::contract::Ctx;
pub use crate::contract::{MAX_PEER_GPUS, PeerCtx, SharedCtx};
use crate::kernels::{Kernel, Kernels, cfg};
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};

/// Dimensions of the dense array of every block a particle's stencil can reach in the domain:
/// pblock coordinates -1 ..= ((n_cells + 3) >> 2) + 1 per axis (the grid origin is 4 cells below
/// the domain minimum, particles are clamped into the domain).
pub fn dense_dims(n_cells: [u32; 3]) -> [i32; 3] {
    n_cells.map(|c| ((c as i32 + 3) >> 2) + 3)
}

/// Enqueue the occupancy mask of this GPU's pblocks (redone only after a rebuild).
pub(crate) fn enqueue_mask(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
) -> Result<(), DriverError> {
    // SAFETY: the kernels bound every index by `sc.d` and the pblock count.
    unsafe {
        s.launch_builder(&k[Kernel::SbClearMask])
            .arg(c)
            .arg(sc)
            .launch(k.wave(sc.d as usize, 256))?;
        s.launch_builder(&k[Kernel::SbMark])
            .arg(c)
            .arg(sc)
            .launch(k.wave(c.pblock_cap as usize, 256))?;
    }
    Ok(())
}

/// Enqueue the shared-block list and the boundary gblocks (return at once unless a GPU rebuilt).
pub(crate) fn enqueue_list(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
) -> Result<(), DriverError> {
    let chunks = (sc.d as usize).div_ceil(1024);
    let per_chunk = LaunchConfig {
        grid_dim: (chunks.min(k.wave_threads / 1024).max(1) as u32, 1, 1),
        block_dim: (1024, 1, 1),
        shared_mem_bytes: 0,
    };
    // SAFETY: as above; the scan runs in one block of 1024 threads.
    unsafe {
        s.launch_builder(&k[Kernel::SbChunkCount])
            .arg(c)
            .arg(sc)
            .launch(per_chunk)?;
        s.launch_builder(&k[Kernel::SbChunkScan])
            .arg(c)
            .arg(sc)
            .launch(cfg(1024, 1024))?;
        s.launch_builder(&k[Kernel::SbList])
            .arg(c)
            .arg(sc)
            .launch(per_chunk)?;
        s.launch_builder(&k[Kernel::SbBoundary])
            .arg(c)
            .arg(sc)
            .launch(k.wave(c.pblock_cap.max(c.gblock_cap) as usize, 256))?;
    }
    Ok(())
}

/// Enqueue the copy of the shared blocks' nodes into the reduction buffer (`pack = true`) or back.
pub(crate) fn enqueue_copy(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
    pack: bool,
) -> Result<(), DriverError> {
    let f = if pack {
        &k[Kernel::SbPack]
    } else {
        &k[Kernel::SbUnpack]
    };
    // SAFETY: bounded by the device shared count and `sc.cap`.
    unsafe {
        s.launch_builder(f)
            .arg(c)
            .arg(sc)
            .launch(k.wave(sc.cap as usize * 256, 256))?;
    }
    Ok(())
}

/// transport=p2p: enqueue the sum of every GPU's mask into `counts` (after the mask barrier).
pub(crate) fn enqueue_counts_peers(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
    pc: &PeerCtx,
) -> Result<(), DriverError> {
    // SAFETY: every pointer of `pc` holds d + 1 bytes on a GPU this one has peer access to.
    unsafe {
        s.launch_builder(&k[Kernel::SbCountsPeers])
            .arg(c)
            .arg(sc)
            .arg(pc)
            .launch(k.wave(sc.d as usize, 256))?;
    }
    Ok(())
}

/// transport=p2p: enqueue the sum of every GPU's packed buffer into this GPU's shared blocks
/// (after the barrier that follows every GPU's pack).
pub(crate) fn enqueue_sum_peers(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
    pc: &PeerCtx,
) -> Result<(), DriverError> {
    // SAFETY: every buffer of `pc` holds cap * 256 reals (every GPU has the same cap).
    unsafe {
        s.launch_builder(&k[Kernel::SbSumPeers])
            .arg(c)
            .arg(sc)
            .arg(pc)
            .launch(k.wave(sc.cap as usize * 256, 256))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_dims_cover_every_pblock() {
        // 48 cells: bases 3..=51, gblocks 0..=12, pblocks -1..=13: 15 blocks.
        assert_eq!(dense_dims([48, 48, 48]), [15, 15, 15]);
        assert_eq!(dense_dims([1, 2, 5]), [4, 4, 5]);
    }
}

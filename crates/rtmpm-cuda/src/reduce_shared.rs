//! Host side of `kernels/reduce_shared.cu`: the multi-GPU reduce-sum of shared grid blocks (seed
//! 000, job splitting by particles). The NCCL calls (transport=nccl) or barriers (transport=p2p,
//! [`crate::barrier`]) between these launches are made by [`crate::multi_gpu::GpuRank`].

use crate::backend::{Kernels, cfg, cfg_wave};
use crate::layout::Ctx;
use cudarc::driver::{CudaStream, DeviceRepr, DriverError, LaunchConfig, PushKernelArg};

/// Mirror of `SharedCtx` in `kernels/reduce_shared.cu`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct SharedCtx {
    /// u8 per dense block + 1: this GPU's pblocks; last byte: rebuilt this step.
    pub mask: u64,
    /// u8 per dense block + 1: the masks summed over the GPUs.
    pub counts: u64,
    /// u32 per chunk of 1024 dense blocks.
    pub chunk: u64,
    /// u32 per shared block: this GPU's pblock id.
    pub shared_local: u64,
    /// 256 reals per shared block.
    pub buf: u64,
    /// Dense block array dimensions (see [`dense_dims`]).
    pub dims: [i32; 3],
    /// Number of dense blocks.
    pub d: u32,
    /// Shared blocks the reduction holds.
    pub cap: u32,
    /// Padding.
    pub pad: u32,
}

// SAFETY: plain old data with the C layout of the kernel struct.
unsafe impl DeviceRepr for SharedCtx {}

/// Most GPUs of transport=p2p (`SB_MAX_GPUS` in the kernel).
pub const MAX_PEER_GPUS: usize = 8;

/// Mirror of `PeerCtx` in `kernels/reduce_shared.cu`: every GPU's mask and packed buffer (this
/// GPU's included, rank order), as pointers this GPU can dereference through peer access.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct PeerCtx {
    /// `SharedCtx::mask` of every GPU.
    pub mask: [u64; MAX_PEER_GPUS],
    /// `SharedCtx::buf` of every GPU.
    pub buf: [u64; MAX_PEER_GPUS],
    /// Number of GPUs.
    pub n: u32,
    /// This GPU's rank.
    pub me: u32,
}

// SAFETY: plain old data with the C layout of the kernel struct.
unsafe impl DeviceRepr for PeerCtx {}

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
        s.launch_builder(&k.sb_clear_mask)
            .arg(c)
            .arg(sc)
            .launch(cfg_wave(sc.d as usize, 256, k.wave_threads))?;
        s.launch_builder(&k.sb_mark)
            .arg(c)
            .arg(sc)
            .launch(cfg_wave(c.pblock_cap as usize, 256, k.wave_threads))?;
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
        s.launch_builder(&k.sb_chunk_count)
            .arg(c)
            .arg(sc)
            .launch(per_chunk)?;
        s.launch_builder(&k.sb_chunk_scan)
            .arg(c)
            .arg(sc)
            .launch(cfg(1024, 1024))?;
        s.launch_builder(&k.sb_list)
            .arg(c)
            .arg(sc)
            .launch(per_chunk)?;
        s.launch_builder(&k.sb_boundary)
            .arg(c)
            .arg(sc)
            .launch(cfg_wave(c.gblock_cap as usize, 256, k.wave_threads))?;
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
    let f = if pack { &k.sb_pack } else { &k.sb_unpack };
    // SAFETY: bounded by the device shared count and `sc.cap`.
    unsafe {
        s.launch_builder(f).arg(c).arg(sc).launch(cfg_wave(
            sc.cap as usize * 256,
            256,
            k.wave_threads,
        ))?;
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
        s.launch_builder(&k.sb_counts_peers)
            .arg(c)
            .arg(sc)
            .arg(pc)
            .launch(cfg_wave(sc.d as usize, 256, k.wave_threads))?;
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
        s.launch_builder(&k.sb_sum_peers)
            .arg(c)
            .arg(sc)
            .arg(pc)
            .launch(cfg_wave(sc.cap as usize * 256, 256, k.wave_threads))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_ctx_matches_the_kernel_struct() {
        // 5 pointers, int dims[3], unsigned d, cap: 60 bytes, aligned to 8.
        assert_eq!(std::mem::size_of::<SharedCtx>(), 64);
        // 16 pointers, unsigned n, me.
        assert_eq!(std::mem::size_of::<PeerCtx>(), 136);
    }

    #[test]
    fn dense_dims_cover_every_pblock() {
        // 48 cells: bases 3..=51, gblocks 0..=12, pblocks -1..=13: 15 blocks.
        assert_eq!(dense_dims([48, 48, 48]), [15, 15, 15]);
        assert_eq!(dense_dims([1, 2, 5]), [4, 4, 5]);
    }
}

//! Host side of `kernels/multi/reduce_shared.cu`: the sum of the grid blocks several GPUs share
//! (Fei, Huang & Gao, GTC 2022: job splitting by particles, reduce-sum of shared blocks). The
//! NCCL calls (transport=nccl) or barriers (transport=p2p, [`super::barrier`]) between these
//! launches are made by [`super::exchange`].

use crate::contract::Ctx;
pub use crate::contract::{MAX_PEER_GPUS, PeerCtx, PushCtx, SharedCtx, SpinBarrier};
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

/// Streaming multiprocessors of the device (the kernels' wave is 2048 threads a SM).
fn sms(k: &Kernels) -> usize {
    (k.wave_threads / 2048).max(1)
}

/// `exchange=fused|push`: the grid of `sb_list_fused`, one block of 1024 threads a SM (every
/// block resident, for its grid barriers; one block where not even one a SM fits).
pub(crate) fn list_fused_blocks(k: &Kernels) -> Result<u32, DriverError> {
    let per_sm =
        k[Kernel::SbListFused].occupancy_max_active_blocks_per_multiprocessor(1024, 0, None)?;
    Ok((sms(k) as u32 * per_sm.min(1)).max(1))
}

/// `exchange=list_push_update`: the grid of `sb_list_push`, as [`list_fused_blocks`].
pub(crate) fn list_push_blocks(k: &Kernels) -> Result<u32, DriverError> {
    let per_sm =
        k[Kernel::SbListPush].occupancy_max_active_blocks_per_multiprocessor(1024, 0, None)?;
    Ok((sms(k) as u32 * per_sm.min(1)).max(1))
}

/// `exchange=list_push_update`: enqueue the shared-list stage of [`enqueue_list_fused`] and the
/// push of [`enqueue_push`] as one cooperative launch of `sb_list_push` on `blocks` blocks
/// ([`list_push_blocks`]), after the step's P2G.
#[allow(clippy::too_many_arguments)]
pub(crate) fn enqueue_list_push(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
    pc: &PeerCtx,
    b: &SpinBarrier,
    q: &PushCtx,
    blocks: u32,
) -> Result<(), DriverError> {
    let cfg = LaunchConfig {
        grid_dim: (blocks, 1, 1),
        block_dim: (1024, 1, 1),
        shared_mem_bytes: 0,
    };
    // SAFETY: as `enqueue_list_fused` and `enqueue_push`; the cooperative launch keeps every
    // block resident for the grid barriers.
    unsafe {
        s.launch_builder(&k[Kernel::SbListPush])
            .arg(c)
            .arg(sc)
            .arg(pc)
            .arg(b)
            .arg(q)
            .launch_cooperative(cfg)?;
    }
    Ok(())
}

/// `exchange=fused|push`: enqueue the whole shared-list stage (mask, inter-GPU barrier `b`, sum
/// of the masks, list, boundary gblocks) as one cooperative launch of `sb_list_fused` on
/// `blocks` blocks ([`list_fused_blocks`]).
pub(crate) fn enqueue_list_fused(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
    pc: &PeerCtx,
    b: &SpinBarrier,
    blocks: u32,
) -> Result<(), DriverError> {
    let f = &k[Kernel::SbListFused];
    let cfg = LaunchConfig {
        grid_dim: (blocks, 1, 1),
        block_dim: (1024, 1, 1),
        shared_mem_bytes: 0,
    };
    // SAFETY: the phases bound every index by `sc.d`, the chunk count, `sc.cap` and the block
    // counts; the peers' masks hold d + 1 bytes; the cooperative launch keeps every block
    // resident for the grid barriers.
    unsafe {
        s.launch_builder(f)
            .arg(c)
            .arg(sc)
            .arg(pc)
            .arg(b)
            .launch_cooperative(cfg)?;
    }
    Ok(())
}

/// `exchange=push`: reals of a shared block per 16-byte vector of `sb_push`/`sb_gather`.
fn vectors_per_block(f64: bool) -> usize {
    if f64 { 128 } else { 64 }
}

/// `exchange=push`: the launch of `sb_push` and `sb_gather` (grid-stride over the vectors of
/// the shared blocks; at most four blocks of 256 threads a SM, enough 16-byte accesses in
/// flight for the link).
fn push_cfg(k: &Kernels, sc: &SharedCtx, f64: bool) -> LaunchConfig {
    let n = (sc.cap as usize * vectors_per_block(f64)).min(sms(k) * 1024);
    cfg(n, 256)
}

/// `exchange=push`: enqueue the push of this GPU's shared nodes into the holders' inboxes and its
/// arrival (`sb_push`), then the wait for every GPU's arrival and the sum of the inbox
/// (`sb_gather`).
pub(crate) fn enqueue_push_gather(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
    q: &PushCtx,
    f64: bool,
) -> Result<(), DriverError> {
    enqueue_push(k, s, c, sc, q, f64)?;
    // SAFETY: as `enqueue_push`; `sb_gather` reads this GPU's inbox and counter and writes the
    // sums into this GPU's shared nodes, bounded by the device shared count and `sc.cap`.
    unsafe {
        s.launch_builder(&k[Kernel::SbGather])
            .arg(c)
            .arg(sc)
            .arg(q)
            .launch(push_cfg(k, sc, f64))?;
    }
    Ok(())
}

/// `exchange=push|push_update`: enqueue the push of this GPU's shared nodes into the holders'
/// inboxes and its arrival at every GPU's counter (`sb_push`).
pub(crate) fn enqueue_push(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
    q: &PushCtx,
    f64: bool,
) -> Result<(), DriverError> {
    // SAFETY: every inbox of `q` holds 2 x n x cap x 256 reals on a GPU this one has peer
    // access to (every GPU has the same cap), the counters are live u64 (the done word a u32);
    // the kernel bounds its work by the device shared count and `sc.cap`.
    unsafe {
        s.launch_builder(&k[Kernel::SbPush])
            .arg(c)
            .arg(sc)
            .arg(q)
            .launch(push_cfg(k, sc, f64))?;
    }
    Ok(())
}

/// `exchange=push_update`: enqueue the grid update with the sum of the inbox inside it
/// (`grid_update_gather`, after [`enqueue_push`] on the same stream): the pblocks no other GPU
/// holds first, then the wait on this GPU's counter, then every shared node summed and updated.
/// The grid update's launch (one wave of blocks of 128 threads over the pblocks' nodes).
pub(crate) fn enqueue_grid_update_gather(
    k: &Kernels,
    s: &CudaStream,
    c: &Ctx,
    sc: &SharedCtx,
    q: &PushCtx,
) -> Result<(), DriverError> {
    // SAFETY: the kernel bounds the nodes by the pblock count, the shared blocks by the device
    // shared count and `sc.cap`; the inbox and counter are this GPU's (as `sb_gather`).
    unsafe {
        s.launch_builder(&k[Kernel::GridUpdateGather])
            .arg(c)
            .arg(sc)
            .arg(q)
            .launch(k.wave(c.pblock_cap as usize * 64, 128))?;
    }
    Ok(())
}

/// `exchange=push`: bytes of one GPU's inbox for `gpus` GPUs and `cap` shared blocks (double
/// buffered: 2 x gpus x cap x 256 reals).
pub fn inbox_bytes(gpus: usize, cap: usize, f64: bool) -> usize {
    2 * gpus * cap * 256 * if f64 { 8 } else { 4 }
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

    #[test]
    fn a_push_inbox_holds_both_parities_of_every_gpu() {
        // 2 GPUs, 5,344 blocks (the weak benchmark's capacity), f32: 21.9 MB.
        assert_eq!(inbox_bytes(2, 5344, false), 2 * 2 * 5344 * 1024);
        assert_eq!(inbox_bytes(8, 10, true), 2 * 8 * 10 * 2048);
        // 16 bytes a thread: a block of 256 reals is 64 vectors in f32, 128 in f64.
        assert_eq!(vectors_per_block(false) * 4, 256);
        assert_eq!(vectors_per_block(true) * 2, 256);
    }
}

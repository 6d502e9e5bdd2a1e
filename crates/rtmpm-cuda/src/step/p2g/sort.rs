//! Host side of `kernels/p2g/sort.cu`: P2G as a gather through one sort per step of the
//! particle-node contributions (Chiang et al., "GPU Acceleration of the Generalized
//! Interpolation Material Point Method", SAAHPC 2009). Every buffer is allocated here, once; the number of
//! radix passes enqueued follows from the node capacity (passes above the node indices in use
//! return at once on the device), so a step is the same launch sequence every time and can be
//! captured in a CUDA graph.

use super::reverse_map::entry_bytes;
use crate::contract::{Ctx, SortCtx};
use crate::kernels::{Kernel, Kernels, cfg};
use cudarc::driver::{CudaSlice, CudaStream, DevicePtr, DriverError, PushKernelArg};
use rtmpm_sim::SimError;
use std::sync::Arc;

/// Bits per radix pass (`SORT_BITS`).
const SORT_BITS: u32 = 8;
/// Digits per pass = threads of the count and scatter kernels (`SORT_DIGITS`).
const SORT_DIGITS: usize = 256;
/// Pairs per tile (`SORT_TILE`).
const SORT_TILE: usize = SORT_DIGITS * 8;

/// The sort-based P2G of one backend: its kernels and buffers.
pub struct SortMap {
    ctx: SortCtx,
    /// Radix passes enqueued per step.
    pub passes: u32,
    _bufs: Vec<CudaSlice<u8>>,
    /// (buffer, bytes) of the extra device memory.
    pub memory: Vec<(&'static str, usize)>,
}

impl SortMap {
    /// Timed phases.
    pub const PHASES: &'static [&'static str] = &["emit", "sort", "segments", "gather"];

    /// Allocate the buffers.
    pub(crate) fn new(
        stream: &Arc<CudaStream>,
        c: &Ctx,
        real_bytes: usize,
    ) -> Result<SortMap, SimError> {
        let n_items = c.n as u64 * 27;
        let node_cap = c.pblock_cap as u64 * 64;
        if n_items > u32::MAX as u64 || node_cap > u32::MAX as u64 {
            return Err(SimError::Backend(format!(
                "p2g=sort: {} particles x 27 contributions or {node_cap} nodes exceed 32-bit indices",
                c.n
            )));
        }
        let n_items = n_items as usize;
        let n_tiles = n_items.div_ceil(SORT_TILE);
        let bits = 32 - ((node_cap.max(2) - 1) as u32).leading_zeros();
        let passes = bits.div_ceil(SORT_BITS).max(1);
        let memory = vec![
            ("entry values", entry_bytes(c.cap as usize, real_bytes)),
            ("keys x2", 2 * n_items * 4),
            ("values x2", 2 * n_items * 4),
            ("tile histograms", SORT_DIGITS * n_tiles * 4),
            ("scan sums", (SORT_DIGITS * n_tiles).div_ceil(1024) * 4),
            ("node runs", 2 * node_cap as usize * 4),
        ];
        let alloc = |what: &str, bytes: usize| {
            stream.alloc_zeros::<u8>(bytes.max(16)).map_err(|e| {
                SimError::Backend(format!(
                    "CUDA: p2g=sort: cannot allocate the {what} ({:.1} MB): {e:?}",
                    bytes as f64 / 1e6
                ))
            })
        };
        let contrib = alloc("entry values", memory[0].1)?;
        let keys = [alloc("keys", n_items * 4)?, alloc("keys", n_items * 4)?];
        let vals = [alloc("values", n_items * 4)?, alloc("values", n_items * 4)?];
        let tile_counts = alloc("tile histograms", memory[3].1)?;
        let scan_sums = alloc("scan sums", memory[4].1)?;
        let seg_start = alloc("node runs", node_cap as usize * 4)?;
        let seg_end = alloc("node runs", node_cap as usize * 4)?;
        let p = |b: &CudaSlice<u8>| b.device_ptr(stream).0;
        let ctx = SortCtx {
            contrib: p(&contrib),
            keys: [p(&keys[0]), p(&keys[1])],
            vals: [p(&vals[0]), p(&vals[1])],
            tile_counts: p(&tile_counts),
            scan_sums: p(&scan_sums),
            seg_start: p(&seg_start),
            seg_end: p(&seg_end),
            n_items: n_items as u32,
            n_tiles: n_tiles as u32,
            node_cap: node_cap as u32,
            pad: 0,
        };
        let [k0, k1] = keys;
        let [v0, v1] = vals;
        Ok(SortMap {
            ctx,
            passes,
            _bufs: vec![
                contrib,
                k0,
                k1,
                v0,
                v1,
                tile_counts,
                scan_sums,
                seg_start,
                seg_end,
            ],
            memory,
        })
    }

    /// Enqueue phase `i` of [`SortMap::PHASES`].
    pub(crate) fn enqueue_phase(
        &self,
        i: usize,
        k: &Kernels,
        s: &CudaStream,
        c: &Ctx,
    ) -> Result<(), DriverError> {
        let sc = &self.ctx;
        let wave = |n: usize, block: u32| k.wave(n, block);
        let tiles = sc.n_tiles as usize * SORT_DIGITS;
        let scan = SORT_DIGITS * sc.n_tiles as usize;
        // SAFETY: the kernels bounds-check against the device counters and the capacities.
        unsafe {
            match i {
                0 => {
                    s.launch_builder(&k[Kernel::P2gSortEmit])
                        .arg(c)
                        .arg(sc)
                        .launch(wave(c.warp_cap as usize * 32, 128))?;
                }
                1 => {
                    for pass in 0..self.passes {
                        s.launch_builder(&k[Kernel::P2gSortCount])
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(wave(tiles, SORT_DIGITS as u32))?;
                        s.launch_builder(&k[Kernel::P2gSortScanBlocks])
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(wave(scan.div_ceil(1024) * 1024, 1024))?;
                        s.launch_builder(&k[Kernel::P2gSortScanSums])
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(cfg(1024, 1024))?;
                        s.launch_builder(&k[Kernel::P2gSortScanAdd])
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(wave(scan.div_ceil(1024) * 1024, 1024))?;
                        s.launch_builder(&k[Kernel::P2gSortScatter])
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(wave(tiles, SORT_DIGITS as u32))?;
                    }
                }
                2 => {
                    s.launch_builder(&k[Kernel::P2gSortSegments])
                        .arg(c)
                        .arg(sc)
                        .launch(wave(sc.n_items as usize, 256))?;
                }
                _ => {
                    s.launch_builder(&k[Kernel::P2gSortGather])
                        .arg(c)
                        .arg(sc)
                        .launch(wave(sc.node_cap as usize, 256))?;
                }
            }
        }
        Ok(())
    }
}

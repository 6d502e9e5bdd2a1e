//! Host side of `kernels/p2g_sort.cu`: P2G as a gather through one sort per step of the
//! particle-node contributions (seed 001). Every buffer is allocated here, once; the number of
//! radix passes enqueued follows from the node capacity (passes above the node indices in use
//! return at once on the device), so a step is the same launch sequence every time and can be
//! captured in a CUDA graph.

use crate::backend::{Kernels, cfg, cfg_wave};
use crate::layout::Ctx;
use crate::p2g_reverse_map::entry_bytes;
use cudarc::driver::{
    CudaFunction, CudaModule, CudaSlice, CudaStream, DevicePtr, DeviceRepr, DriverError,
    PushKernelArg,
};
use rtmpm_core::sim::SimError;
use std::sync::Arc;

/// Bits per radix pass (`SORT_BITS`).
const SORT_BITS: u32 = 8;
/// Digits per pass = threads of the count and scatter kernels (`SORT_DIGITS`).
const SORT_DIGITS: usize = 256;
/// Pairs per tile (`SORT_TILE`).
const SORT_TILE: usize = SORT_DIGITS * 8;

/// Mirror of `SortCtx` in `kernels/p2g_sort.cu`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SortCtx {
    contrib: u64,
    keys: [u64; 2],
    vals: [u64; 2],
    tile_counts: u64,
    scan_sums: u64,
    seg_start: u64,
    seg_end: u64,
    n_items: u32,
    n_tiles: u32,
    node_cap: u32,
    pad: u32,
}

// SAFETY: plain old data with the C layout of the kernel struct.
unsafe impl DeviceRepr for SortCtx {}

struct Fns {
    emit: CudaFunction,
    count: CudaFunction,
    scan_blocks: CudaFunction,
    scan_sums: CudaFunction,
    scan_add: CudaFunction,
    scatter: CudaFunction,
    segments: CudaFunction,
    gather: CudaFunction,
}

/// The sort-based P2G of one backend: its kernels and buffers.
pub(crate) struct SortMap {
    fns: Fns,
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

    /// Allocate the buffers and load the kernels.
    pub(crate) fn new(
        module: &Arc<CudaModule>,
        stream: &Arc<CudaStream>,
        c: &Ctx,
        real_bytes: usize,
    ) -> Result<SortMap, SimError> {
        let f = |name: &str| {
            module
                .load_function(name)
                .map_err(|e| SimError::Backend(format!("CUDA: kernel {name}: {e:?}")))
        };
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
            fns: Fns {
                emit: f("p2g_sort_emit")?,
                count: f("p2g_sort_count")?,
                scan_blocks: f("p2g_sort_scan_blocks")?,
                scan_sums: f("p2g_sort_scan_sums")?,
                scan_add: f("p2g_sort_scan_add")?,
                scatter: f("p2g_sort_scatter")?,
                segments: f("p2g_sort_segments")?,
                gather: f("p2g_sort_gather")?,
            },
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
        let f = &self.fns;
        let sc = &self.ctx;
        let wave = |n: usize, block: u32| cfg_wave(n, block, k.wave_threads);
        let tiles = sc.n_tiles as usize * SORT_DIGITS;
        let scan = SORT_DIGITS * sc.n_tiles as usize;
        // SAFETY: the kernels bounds-check against the device counters and the capacities.
        unsafe {
            match i {
                0 => {
                    s.launch_builder(&f.emit)
                        .arg(c)
                        .arg(sc)
                        .launch(wave(c.warp_cap as usize * 32, 128))?;
                }
                1 => {
                    for pass in 0..self.passes {
                        s.launch_builder(&f.count)
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(wave(tiles, SORT_DIGITS as u32))?;
                        s.launch_builder(&f.scan_blocks)
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(wave(scan.div_ceil(1024) * 1024, 1024))?;
                        s.launch_builder(&f.scan_sums)
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(cfg(1024, 1024))?;
                        s.launch_builder(&f.scan_add)
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(wave(scan.div_ceil(1024) * 1024, 1024))?;
                        s.launch_builder(&f.scatter)
                            .arg(c)
                            .arg(sc)
                            .arg(&pass)
                            .launch(wave(tiles, SORT_DIGITS as u32))?;
                    }
                }
                2 => {
                    s.launch_builder(&f.segments)
                        .arg(c)
                        .arg(sc)
                        .launch(wave(sc.n_items as usize, 256))?;
                }
                _ => {
                    s.launch_builder(&f.gather)
                        .arg(c)
                        .arg(sc)
                        .launch(wave(sc.node_cap as usize, 256))?;
                }
            }
        }
        Ok(())
    }
}

//! Host side of `kernels/rebuild.cu`: the rebuild of the mapping, enqueued every step (it does
//! nothing on the device unless the free-zone flag asks for a rebuild), and the grid clear.
//! Default: one cooperative launch of the persistent kernel `rb_fused`; `rebuild=kernels`: the
//! fifteen phase kernels, each returning at once when nothing is rebuilt.

use crate::backend::{Kernels, cfg, cfg_wave};
use crate::layout::{Ctx, NFIELDS};
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};

/// Enqueue the rebuild and the grid clear.
pub(crate) fn enqueue(k: &Kernels, s: &CudaStream, c: &Ctx) -> Result<(), DriverError> {
    if let Some(grid) = k.rb_fused_grid {
        let cfg = LaunchConfig {
            grid_dim: (grid, 1, 1),
            block_dim: (1024, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: every phase bounds-checks against the capacities in `c`; the cooperative
        // launch keeps all `grid` blocks resident for the grid barrier.
        unsafe {
            s.launch_builder(&k.rb_fused)
                .arg(c)
                .launch_cooperative(cfg)?
        };
        return Ok(());
    }
    let one = cfg(1, 32);
    // At most one full wave: the kernels loop over their items (grid-stride).
    let cfg = |n: usize, block: u32| cfg_wave(n, block, k.wave_threads);
    let n = c.n as usize;
    let hc = (c.hash_cap as usize).max(c.n_buckets as usize);
    let g27 = c.gblock_cap as usize * 27;
    let scan_blocks = (c.n_buckets as usize).div_ceil(1024);
    let (first, second) = (1u32, 0u32);
    // SAFETY: every kernel bounds-checks against the capacities in `c`.
    unsafe {
        s.launch_builder(&k.rb_begin).arg(c).launch(one)?;
        s.launch_builder(&k.rb_clear).arg(c).launch(cfg(hc, 256))?;
        s.launch_builder(&k.rb_insert_gblocks)
            .arg(c)
            .launch(cfg(n, 256))?;
        s.launch_builder(&k.rb_assign)
            .arg(c)
            .arg(&first)
            .launch(cfg(c.hash_cap as usize, 256))?;
        s.launch_builder(&k.rb_insert_neighbors)
            .arg(c)
            .launch(cfg(g27, 256))?;
        s.launch_builder(&k.rb_assign)
            .arg(c)
            .arg(&second)
            .launch(cfg(c.hash_cap as usize, 256))?;
        s.launch_builder(&k.rb_neighbor_lists)
            .arg(c)
            .launch(cfg(g27, 256))?;
        s.launch_builder(&k.rb_histogram)
            .arg(c)
            .launch(cfg(n, 256))?;
        s.launch_builder(&k.rb_scan_blocks)
            .arg(c)
            .launch(cfg(scan_blocks * 1024, 1024))?;
        s.launch_builder(&k.rb_scan_sums)
            .arg(c)
            .launch(cfg(1024, 1024))?;
        s.launch_builder(&k.rb_scan_add)
            .arg(c)
            .launch(cfg(scan_blocks * 1024, 1024))?;
        s.launch_builder(&k.rb_scatter).arg(c).launch(cfg(n, 256))?;
        s.launch_builder(&k.rb_copy_back)
            .arg(c)
            .launch(cfg(n * NFIELDS, 256))?;
        s.launch_builder(&k.rb_end).arg(c).launch(one)?;
        s.launch_builder(&k.grid_clear)
            .arg(c)
            .launch(cfg(c.pblock_cap as usize * 256, 256))?;
    }
    Ok(())
}

//! Host side of `kernels/rebuild.cu`: the rebuild of the mapping, enqueued every step (it does
//! nothing on the device unless the free-zone flag asks for a rebuild), and the grid clear.
//! Default: one cooperative launch of the persistent kernel `rb_fused`; `rebuild=kernels`: the
//! fifteen phase kernels, each returning at once when nothing is rebuilt.

use crate::contract::{Ctx, NFIELDS};
use crate::kernels::{Kernel, Kernels, cfg};
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
            s.launch_builder(&k[Kernel::RbFused])
                .arg(c)
                .launch_cooperative(cfg)?
        };
        return Ok(());
    }
    let one = cfg(1, 32);
    // At most one full wave: the kernels loop over their items (grid-stride).
    let cfg = |n: usize, block: u32| k.wave(n, block);
    let n = c.n as usize;
    let hc = (c.hash_cap as usize).max(c.n_buckets as usize);
    let g27 = c.gblock_cap as usize * 27;
    let scan_blocks = (c.n_buckets as usize).div_ceil(1024);
    let (first, second) = (1u32, 0u32);
    // SAFETY: every kernel bounds-checks against the capacities in `c`.
    unsafe {
        s.launch_builder(&k[Kernel::RbBegin]).arg(c).launch(one)?;
        s.launch_builder(&k[Kernel::RbClear])
            .arg(c)
            .launch(cfg(hc, 256))?;
        s.launch_builder(&k[Kernel::RbInsertGblocks])
            .arg(c)
            .launch(cfg(n, 256))?;
        s.launch_builder(&k[Kernel::RbAssign])
            .arg(c)
            .arg(&first)
            .launch(cfg(c.hash_cap as usize, 256))?;
        s.launch_builder(&k[Kernel::RbInsertNeighbors])
            .arg(c)
            .launch(cfg(g27, 256))?;
        s.launch_builder(&k[Kernel::RbAssign])
            .arg(c)
            .arg(&second)
            .launch(cfg(c.hash_cap as usize, 256))?;
        s.launch_builder(&k[Kernel::RbNeighborLists])
            .arg(c)
            .launch(cfg(g27, 256))?;
        s.launch_builder(&k[Kernel::RbHistogram])
            .arg(c)
            .launch(cfg(n, 256))?;
        s.launch_builder(&k[Kernel::RbScanBlocks])
            .arg(c)
            .launch(cfg(scan_blocks * 1024, 1024))?;
        s.launch_builder(&k[Kernel::RbScanSums])
            .arg(c)
            .launch(cfg(1024, 1024))?;
        s.launch_builder(&k[Kernel::RbScanAdd])
            .arg(c)
            .launch(cfg(scan_blocks * 1024, 1024))?;
        s.launch_builder(&k[Kernel::RbScatter])
            .arg(c)
            .launch(cfg(n, 256))?;
        s.launch_builder(&k[Kernel::RbCopyBack])
            .arg(c)
            .launch(cfg(n * NFIELDS, 256))?;
        s.launch_builder(&k[Kernel::RbEnd]).arg(c).launch(one)?;
        s.launch_builder(&k[Kernel::GridClear])
            .arg(c)
            .launch(cfg(c.pblock_cap as usize * 256, 256))?;
    }
    Ok(())
}

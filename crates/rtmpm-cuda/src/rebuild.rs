//! Host side of `kernels/rebuild.cu`: the rebuild of the mapping, enqueued every step (it does
//! nothing on the device unless the free-zone flag asks for a rebuild), and the grid clear.
//! Default: one cooperative launch of the persistent kernel `rb_fused`; `rebuild=kernels`: the
//! phase kernels (a scatter and a copy back per chunk of `Kernels::sort_fields` fields), each
//! returning at once when nothing is rebuilt.

use crate::contract::{Ctx, NFIELDS};
use crate::kernels::{Kernel, Kernels, cfg};
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};

/// The chunks `[f0, f1)` of the state's fields that the sort permutes one after the other with a
/// scratch of `fields` fields (the loop of `rb_fused`, kernels/rebuild.cu).
pub(crate) fn chunks(fields: usize) -> impl Iterator<Item = (i32, i32)> {
    let k = fields.clamp(1, NFIELDS);
    (0..NFIELDS)
        .step_by(k)
        .map(move |f0| (f0 as i32, (f0 + k).min(NFIELDS) as i32))
}

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
        let chunk = k.sort_fields as i32;
        unsafe {
            s.launch_builder(&k[Kernel::RbFused])
                .arg(c)
                .arg(&chunk)
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
        s.launch_builder(&k[Kernel::RbRank])
            .arg(c)
            .launch(cfg(n, 256))?;
        for (f0, f1) in chunks(k.sort_fields as usize) {
            s.launch_builder(&k[Kernel::RbScatter])
                .arg(c)
                .arg(&f0)
                .arg(&f1)
                .launch(cfg(n, 256))?;
            s.launch_builder(&k[Kernel::RbCopyBack])
                .arg(c)
                .arg(&f0)
                .arg(&f1)
                .launch(cfg(n, 256))?;
        }
        s.launch_builder(&k[Kernel::RbEnd]).arg(c).launch(one)?;
        s.launch_builder(&k[Kernel::GridClear])
            .arg(c)
            .launch(cfg(c.pblock_cap as usize * 256, 256))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_chunks_cover_every_field_once_in_order() {
        for k in 1..=NFIELDS {
            let c: Vec<_> = chunks(k).collect();
            assert_eq!(c.len(), NFIELDS.div_ceil(k), "k = {k}");
            assert_eq!(c[0].0, 0);
            assert_eq!(c[c.len() - 1].1, NFIELDS as i32);
            for w in c.windows(2) {
                assert_eq!(w[0].1, w[1].0);
            }
            assert!(c.iter().all(|&(a, b)| b > a && (b - a) as usize <= k));
        }
        assert_eq!(chunks(0).count(), NFIELDS);
        assert_eq!(chunks(99).collect::<Vec<_>>(), vec![(0, NFIELDS as i32)]);
        assert_eq!(chunks(4).count(), 8);
    }
}

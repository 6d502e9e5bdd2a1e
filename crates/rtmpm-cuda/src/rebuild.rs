//! Host side of `kernels/rebuild.cu`: the rebuild of the mapping, enqueued every step (it does
//! nothing on the device unless the free-zone flag asks for a rebuild), and the grid clear.
//! Default: one cooperative launch of the persistent kernel `rb_fused`; `rebuild=kernels`: the
//! phase kernels (a scatter and a copy back per chunk of `Kernels::sort_fields` fields), each
//! returning at once when nothing is rebuilt.

use crate::contract::{Ctx, F_F, NFIELDS};
use crate::kernels::{Kernel, Kernels, cfg};
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};

/// Every field of the state (bit f: field f).
pub const ALL_FIELDS: u32 = (1 << NFIELDS) - 1;

/// The fields the sort permutes: every field, except, when every material is a fluid
/// (`all_fluid`), the six off-diagonal words of F, which are then zero in every particle (a
/// fluid's F is J^(1/3) I: `state::pack` writes it so, the kernels keep it so), so the sort moves
/// 23 words per particle instead of 29 and the state is the same.
pub fn sorted_fields(all_fluid: bool) -> u32 {
    if !all_fluid {
        return ALL_FIELDS;
    }
    let off_diagonal = [1, 2, 3, 5, 6, 7]
        .iter()
        .fold(0u32, |m, e| m | 1 << (F_F + e));
    ALL_FIELDS & !off_diagonal
}

/// The chunks of the fields of `mask` (bit f: field f) that the sort permutes one after the
/// other with a scratch of `fields` fields: each the next (at most) `fields` fields of the mask,
/// in order (the loop of `rb_fused`, kernels/rebuild.cu).
pub fn chunks(fields: usize, mask: u32) -> Vec<u32> {
    let k = fields.clamp(1, NFIELDS);
    let mut rest = mask & ALL_FIELDS;
    let mut out = Vec::new();
    while rest != 0 {
        let mut chunk = 0;
        for _ in 0..k {
            let low = rest & rest.wrapping_neg();
            chunk |= low;
            rest &= !low;
        }
        out.push(chunk);
    }
    out
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
                .arg(&k.sort_mask)
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
        for m in chunks(k.sort_fields as usize, k.sort_mask) {
            s.launch_builder(&k[Kernel::RbScatter])
                .arg(c)
                .arg(&m)
                .launch(cfg(n, 256))?;
            s.launch_builder(&k[Kernel::RbCopyBack])
                .arg(c)
                .arg(&m)
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
    fn the_chunks_cover_every_sorted_field_once_in_order() {
        for all_fluid in [false, true] {
            let mask = sorted_fields(all_fluid);
            let fields: Vec<usize> = (0..NFIELDS).filter(|f| mask >> f & 1 == 1).collect();
            assert_eq!(fields.len(), if all_fluid { 23 } else { NFIELDS });
            for k in 1..=NFIELDS {
                let c = chunks(k, mask);
                assert_eq!(c.len(), fields.len().div_ceil(k), "k = {k}");
                // The chunks' fields, in order, are the mask's fields, each once.
                let flat: Vec<usize> = c
                    .iter()
                    .flat_map(|m| (0..NFIELDS).filter(move |f| m >> f & 1 == 1))
                    .collect();
                assert_eq!(flat, fields, "k = {k}");
                assert!(c.iter().all(|m| *m != 0 && m.count_ones() as usize <= k));
                // Every chunk but the last is full.
                assert!(
                    c[..c.len() - 1]
                        .iter()
                        .all(|m| m.count_ones() as usize == k)
                );
            }
        }
        assert_eq!(chunks(4, ALL_FIELDS).len(), 8);
        assert_eq!(chunks(4, sorted_fields(true)).len(), 6);
        assert_eq!(chunks(0, ALL_FIELDS).len(), NFIELDS);
        assert_eq!(chunks(99, ALL_FIELDS), vec![ALL_FIELDS]);
        // Position, velocity, C, F's diagonal, the scalars, the material and the id are sorted.
        let fluid = sorted_fields(true);
        for f in [
            0,
            1,
            2,
            3,
            4,
            5,
            6,
            14,
            F_F,
            F_F + 4,
            F_F + 8,
            24,
            25,
            26,
            27,
            28,
        ] {
            assert_eq!(fluid >> f & 1, 1, "field {f}");
        }
    }
}

//! Host side of `kernels/rebuild.cu`: the rebuild of the mapping, enqueued every step (it does
//! nothing on the device unless the free-zone flag asks for a rebuild), and the grid clear.
//! Default: one cooperative launch of the persistent kernel `rb_fused`; `rebuild=kernels`: the
//! phase kernels (a scatter and a copy back per chunk of `Kernels::sort_fields` fields), each
//! returning at once when nothing is rebuilt.

use crate::contract::{Ctx, MAX_FIELDS, StateLayout};
use crate::kernels::{Kernel, Kernels, cfg};
use cudarc::driver::{CudaStream, DriverError, LaunchConfig, PushKernelArg};

/// The words the sort permutes (bit w: word w of the `layout`): every word, except, when every
/// material is a fluid (`all_fluid`) in a layout with nine words of F (`fluid_state=off`), the
/// six off-diagonal words of F, which are then zero in every particle (a fluid's F is J^(1/3) I:
/// `state::pack` writes it so, the kernels keep it so), so the sort moves 23 words per particle
/// instead of 29 and the state is the same. A fluid layout has no such words.
pub fn sorted_fields(layout: StateLayout, all_fluid: bool) -> u32 {
    let all = layout.all_words();
    if !all_fluid || layout.fluid() {
        return all;
    }
    let off_diagonal = [1, 2, 3, 5, 6, 7]
        .iter()
        .fold(0u32, |m, e| m | 1 << (layout.f() + e));
    all & !off_diagonal
}

/// The chunks of the fields of `mask` (bit f: field f) that the sort permutes one after the
/// other with a scratch of `fields` fields: each the next (at most) `fields` fields of the mask,
/// in order (the loop of `rb_fused`, kernels/rebuild.cu).
pub fn chunks(fields: usize, mask: u32) -> Vec<u32> {
    let k = fields.clamp(1, MAX_FIELDS);
    let mut rest = mask;
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

    const NFIELDS: usize = MAX_FIELDS;
    const ALL_FIELDS: u32 = (1 << NFIELDS) - 1;
    fn sorted_full(all_fluid: bool) -> u32 {
        sorted_fields(StateLayout::Full, all_fluid)
    }

    #[test]
    fn every_layout_sorts_all_its_words_but_a_fluid_s_zeros() {
        for l in StateLayout::ALL {
            assert_eq!(sorted_fields(l, false), l.all_words());
            let fluid = sorted_fields(l, true);
            let expect = if l.fluid() { l.words() } else { l.words() - 6 };
            assert_eq!(fluid.count_ones() as usize, expect, "{l:?}");
            assert_eq!(fluid & !l.all_words(), 0);
        }
        // The fluid layout's 20 words: 5 chunks at K = 4 (the 29-word fluid sort: 6).
        assert_eq!(chunks(4, sorted_fields(StateLayout::Fluid, true)).len(), 5);
        assert_eq!(
            chunks(4, sorted_fields(StateLayout::CompactFluid, true)).len(),
            4
        );
    }

    #[test]
    fn the_chunks_cover_every_sorted_field_once_in_order() {
        let f_f = StateLayout::Full.f();
        for all_fluid in [false, true] {
            let mask = sorted_full(all_fluid);
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
        assert_eq!(chunks(4, sorted_full(true)).len(), 6);
        assert_eq!(chunks(0, ALL_FIELDS).len(), NFIELDS);
        assert_eq!(chunks(99, ALL_FIELDS), vec![ALL_FIELDS]);
        // Position, velocity, C, F's diagonal, the scalars, the material and the id are sorted.
        let fluid = sorted_full(true);
        for f in [
            0,
            1,
            2,
            3,
            4,
            5,
            6,
            14,
            f_f,
            f_f + 4,
            f_f + 8,
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

//! Stage 1: particle stencil bases, block layout and particle order.

use super::CpuBackend;
use crate::shape::Stencil;
use rayon::prelude::*;

/// Recompute every particle's stencil base, the block layout and the colour lists.
pub fn rebuild(b: &mut CpuBackend) {
    let c = &b.consts;
    let (origin, inv_dx) = (c.origin, c.inv_dx);
    b.particles
        .x
        .par_iter()
        .map(|&x| Stencil::new((x - origin) * inv_dx).base)
        .collect_into_vec(&mut b.bases);
    b.layout.rebuild(&b.bases);
    for list in b.colours.iter_mut() {
        list.clear();
    }
    for g in 0..b.layout.gblock_count {
        let bc = b.layout.block_coords[g];
        let colour = ((bc.x & 1) << 2 | (bc.y & 1) << 1 | (bc.z & 1)) as usize;
        b.colours[colour].push(g as u32);
    }
}

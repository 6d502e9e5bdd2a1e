//! Stage 1: particle stencil bases, block layout, and the particle storage order.
//!
//! Particles are stored sorted by (gblock, cell, original index), re-sorted at every rebuild
//! (the CPU rebuilds every step). The order depends only on the particle state, so a run resumed
//! from a checkpoint continues bit for bit, and P2G/G2P read particles in memory order.

use super::CpuBackend;
use crate::shape::Stencil;
use rayon::prelude::*;

/// Recompute every particle's stencil base, the block layout, the storage order and the colour
/// lists.
pub fn rebuild(b: &mut CpuBackend) {
    let c = &b.consts;
    let (origin, inv_dx) = (c.origin, c.inv_dx);
    b.particles
        .x
        .par_iter()
        .map(|&x| Stencil::new((x - origin) * inv_dx).base)
        .collect_into_vec(&mut b.bases);
    b.layout.rebuild_with_ties(&b.bases, Some(&b.ids));
    permute(b);
    for list in b.colours.iter_mut() {
        list.clear();
    }
    for g in 0..b.layout.gblock_count {
        let bc = b.layout.block_coords[g];
        let colour = ((bc.x & 1) << 2 | (bc.y & 1) << 1 | (bc.z & 1)) as usize;
        b.colours[colour].push(g as u32);
    }
}

/// Store the particles in the layout's order (a parallel gather into the spare buffers).
fn permute(b: &mut CpuBackend) {
    let order = &b.layout.order;
    let (src, dst) = (&b.particles, &mut b.spare);
    fn gather<T: Copy + Send + Sync>(src: &[T], order: &[u32], dst: &mut Vec<T>) {
        order
            .par_iter()
            .map(|&i| src[i as usize])
            .collect_into_vec(dst);
    }
    rayon::scope(|s| {
        s.spawn(|_| gather(&src.x, order, &mut dst.x));
        s.spawn(|_| gather(&src.v, order, &mut dst.v));
        s.spawn(|_| gather(&src.c, order, &mut dst.c));
        s.spawn(|_| gather(&src.f, order, &mut dst.f));
        s.spawn(|_| gather(&src.plastic, order, &mut dst.plastic));
        s.spawn(|_| gather(&src.mass, order, &mut dst.mass));
        s.spawn(|_| gather(&src.vol0, order, &mut dst.vol0));
        s.spawn(|_| gather(&src.material, order, &mut dst.material));
        s.spawn(|_| gather(&b.ids, order, &mut b.spare_ids));
    });
    std::mem::swap(&mut b.particles, &mut b.spare);
    std::mem::swap(&mut b.ids, &mut b.spare_ids);
    gather(&b.bases, order, &mut b.spare_bases);
    std::mem::swap(&mut b.bases, &mut b.spare_bases);
    b.layout.adopt_order();
}

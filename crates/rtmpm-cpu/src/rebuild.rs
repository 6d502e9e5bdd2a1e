//! Stage 1: particle stencil bases, block layout, and the particle storage order.
//!
//! The layout is rebuilt every step (the CPU has no free zone), in parallel
//! ([`physics::grid::BlockLayout::rebuild_with_ties`]): particles of each gblock listed by (cell,
//! original index). That order fixes the order in which P2G sums each node's contributions, so
//! the result depends only on the particle state, whatever the thread count and however the
//! particles are stored. The storage itself is re-sorted into that order every [`RESORT_EVERY`]
//! steps only, for locality: in between, particles move little, the stored order stays nearly
//! sorted and P2G reads them through `layout.order`.

use crate::state::CpuBackend;
use physics::shape_function::Stencil;
use rayon::prelude::*;

/// Steps between two re-sorts of the particle storage (the first step always re-sorts).
pub const RESORT_EVERY: u32 = 16;

/// Recompute every particle's stencil base, the block layout, the colour lists and, every
/// [`RESORT_EVERY`] steps, the storage order.
pub fn rebuild(b: &mut CpuBackend) {
    compute_bases(b);
    b.layout.rebuild_with_ties(&b.bases, Some(&b.ids));
    if b.since_sort >= RESORT_EVERY {
        permute(b);
        b.since_sort = 0;
    } else {
        b.since_sort += 1;
    }
    for list in b.colours.iter_mut() {
        list.clear();
    }
    for g in 0..b.layout.gblock_count {
        let bc = b.layout.block_coords[g];
        let colour = ((bc.x & 1) << 2 | (bc.y & 1) << 1 | (bc.z & 1)) as usize;
        b.colours[colour].push(g as u32);
    }
}

/// Stencil base node of every stored particle.
fn compute_bases(b: &mut CpuBackend) {
    let (origin, inv_dx) = (b.consts.origin, b.consts.inv_dx);
    b.particles
        .x
        .par_iter()
        .map(|&x| Stencil::base_of((x - origin) * inv_dx))
        .collect_into_vec(&mut b.bases);
}

/// `v = v[order]`, through `scratch` (which then holds the old array: one spare array per type).
fn gather<T: Copy + Send + Sync>(v: &mut Vec<T>, order: &[u32], scratch: &mut Vec<T>) {
    order
        .par_iter()
        .map(|&i| v[i as usize])
        .collect_into_vec(scratch);
    std::mem::swap(v, scratch);
}

/// Store the particles in the layout's order, one array after the other (each a parallel
/// gather), then renumber the layout.
fn permute(b: &mut CpuBackend) {
    let order = &b.layout.order;
    let (p, s) = (&mut b.particles, &mut b.scratch);
    gather(&mut p.x, order, &mut s.vec3);
    gather(&mut p.v, order, &mut s.vec3);
    gather(&mut p.c, order, &mut s.mat3);
    gather(&mut p.f, order, &mut s.mat3);
    gather(&mut p.plastic, order, &mut s.real);
    gather(&mut p.mass, order, &mut s.real);
    gather(&mut p.vol0, order, &mut s.real);
    gather(&mut p.material, order, &mut s.word);
    gather(&mut b.ids, order, &mut s.word);
    b.layout.adopt_order();
    compute_bases(b);
}

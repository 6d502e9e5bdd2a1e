//! Stage 2: particle to grid (MLS-MPM, Hu et al. 2018, eq. 29: stress folded into the affine
//! momentum), scattered without atomics.
//!
//! A particle of gblock B (stencil base in `[4B, 4B+3]`) writes nodes of blocks B and B+1 per
//! axis only. gblocks of one colour `(bx & 1, by & 1, bz & 1)` differ by at least 2 blocks along
//! some axis, so their footprints are disjoint: each colour pass runs its gblocks in parallel,
//! each gblock's particles in sorted order. Every node therefore sums its contributions in a
//! fixed order, whatever the number of threads.

use super::{CpuBackend, Node};
use crate::math::{Mat3, Real};
use crate::shape::{Stencil, inv_d};
use rayon::prelude::*;

/// Shared pointer to the grid nodes, written by disjoint gblocks of one colour.
#[derive(Clone, Copy)]
struct GridPtr(*mut Node);
// SAFETY: used only inside one colour pass, where no two gblocks write the same node (see the
// module documentation); every node is written by one thread at a time.
unsafe impl Send for GridPtr {}
unsafe impl Sync for GridPtr {}

impl GridPtr {
    /// # Safety
    /// `idx` is in bounds and no other thread accesses node `idx` concurrently.
    #[allow(clippy::mut_from_ref)]
    #[inline]
    unsafe fn node(&self, idx: usize) -> &mut Node {
        // SAFETY: guaranteed by the caller.
        unsafe { &mut *self.0.add(idx) }
    }
}

/// Scatter particle mass and momentum to the grid.
pub fn p2g(b: &mut CpuBackend, dt: Real) {
    let n_nodes = b.layout.node_count();
    b.grid.clear();
    b.grid.resize(n_nodes, [0.0; 4]);
    let grid = GridPtr(b.grid.as_mut_ptr());
    let (c, p, layout, bases) = (&b.consts, &b.particles, &b.layout, &b.bases);
    let dx = c.dx;
    let inv_d = inv_d(dx);
    for colour in &b.colours {
        colour.par_iter().for_each(|&g| {
            let g = g as usize;
            for &pi in layout.particles_of(g) {
                let pi = pi as usize;
                let s = Stencil::with_base((p.x[pi] - c.origin) * c.inv_dx, bases[pi]);
                let nodes = layout.stencil_nodes(g, s.base);
                let m = p.mass[pi];
                let model = &c.materials[p.material[pi] as usize].model;
                // tau = P F^T (Kirchhoff); MLS-MPM force term -dt V0 D^-1 tau.
                let tau = model.kirchhoff(p.f[pi], p.plastic[pi], p.c[pi]);
                let affine: Mat3 = tau * (-dt * p.vol0[pi] * inv_d) + p.c[pi] * m;
                let affine_dx = affine * dx;
                let mv = p.v[pi] * m;
                for i in 0..3 {
                    for j in 0..3 {
                        for k in 0..3 {
                            let w = s.weight(i, j, k);
                            let idx = nodes[i * 9 + j * 3 + k] as usize;
                            let mom = w * (mv + affine_dx * s.dpos(i, j, k));
                            // SAFETY: idx < n_nodes (neighbour lists point at allocated
                            // pblocks) and no other thread writes this node in this pass.
                            let n = unsafe { grid.node(idx) };
                            n[0] += w * m;
                            n[1] += mom.x;
                            n[2] += mom.y;
                            n[3] += mom.z;
                        }
                    }
                }
            }
        });
    }
}

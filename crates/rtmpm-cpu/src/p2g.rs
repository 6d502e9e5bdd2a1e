//! Stage 2: particle to grid (MLS-MPM, Hu et al. 2018, eq. 29: stress folded into the affine
//! momentum), scattered without atomics.
//!
//! A particle of gblock B (stencil base in `[4B, 4B+3]`) writes nodes of blocks B and B+1 per
//! axis only. gblocks of one colour `(bx & 1, by & 1, bz & 1)` differ by at least 2 blocks along
//! some axis, so their footprints are disjoint: each colour pass runs its gblocks in parallel,
//! each gblock's particles in sorted order. Every node therefore sums its contributions in a
//! fixed order, whatever the number of threads.

use crate::state::CpuBackend;
use physics::compact_kernel::CkStencil;
use physics::math::{Mat3, Real, ToReal, Vec3};
use physics::shape_function::{Stencil, inv_d};
use rayon::prelude::*;

/// Shared pointer to the grid nodes (or the auxiliary node values), written by disjoint gblocks
/// of one colour.
struct GridPtr<T>(*mut T);
impl<T> Clone for GridPtr<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for GridPtr<T> {}
// SAFETY: used only inside one colour pass, where no two gblocks write the same node (see the
// module documentation); every node is written by one thread at a time.
unsafe impl<T> Send for GridPtr<T> {}
unsafe impl<T> Sync for GridPtr<T> {}

impl<T> GridPtr<T> {
    /// # Safety
    /// `idx` is in bounds and no other thread accesses node `idx` concurrently.
    #[allow(clippy::mut_from_ref)]
    #[inline]
    unsafe fn node(&self, idx: usize) -> &mut T {
        // SAFETY: guaranteed by the caller.
        unsafe { &mut *self.0.add(idx) }
    }
}

/// `v` becomes `n` copies of `zero`, written in parallel (no allocation once the capacity is
/// reached).
fn zeroed<T: Copy + Send + Sync>(v: &mut Vec<T>, n: usize, zero: T) {
    v.clear();
    v.par_extend(rayon::iter::repeat_n(zero, n));
}

/// Scatter particle mass and momentum to the grid.
pub fn p2g(b: &mut CpuBackend, dt: Real) {
    zeroed(&mut b.grid, b.layout.node_count(), [0.0; 4]);
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

/// P2G of CK-MPM (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material Point Method"): each
/// of the two staggered grids (`grid`: nodes at `n - 1/4`, `grid_dual`: at `n + 1/4` cells)
/// receives the particle's full mass and MLS-MPM momentum through its 2x2x2 compact-kernel
/// stencil, with the particle's own `D_p^-1` ([`physics::compact_kernel`]). The two stencils lie
/// inside the particle's 3x3x3 B-spline stencil, so the colour passes stay race-free.
pub fn p2g_ck(b: &mut CpuBackend, dt: Real) {
    let n_nodes = b.layout.node_count();
    zeroed(&mut b.grid, n_nodes, [0.0; 4]);
    zeroed(&mut b.grid_dual, n_nodes, [0.0; 4]);
    let grids = [
        GridPtr(b.grid.as_mut_ptr()),
        GridPtr(b.grid_dual.as_mut_ptr()),
    ];
    let (c, p, layout, bases) = (&b.consts, &b.particles, &b.layout, &b.bases);
    let (dx, inv_dx2) = (c.dx, c.inv_dx * c.inv_dx);
    for colour in &b.colours {
        colour.par_iter().for_each(|&g| {
            let g = g as usize;
            for &pi in layout.particles_of(g) {
                let pi = pi as usize;
                let base = bases[pi];
                let s = CkStencil::new((p.x[pi] - c.origin) * c.inv_dx - base.to_real());
                let nodes = layout.stencil_nodes(g, base);
                let m = p.mass[pi];
                let model = &c.materials[p.material[pi] as usize].model;
                let tau = model.kirchhoff(p.f[pi], p.plastic[pi], p.c[pi]);
                // A_p = m C - dt V0 tau D_p^-1 (D_p^-1 in world units: cells^-2 / dx^2): the force
                // -V0 tau grad w_ip with MLS's grad w_ip = w_ip D_p^-1 (x_i - x_p), which keeps
                // the torque on the nodes zero (tau symmetric).
                let inv_d = s.inv_moment() * inv_dx2;
                let affine: Mat3 = tau * inv_d * (-dt * p.vol0[pi]) + p.c[pi] * m;
                let affine_dx = affine * dx;
                let mv = p.v[pi] * m;
                for (stencil, grid) in s.grids.iter().zip(&grids) {
                    for i in 0..2 {
                        for j in 0..2 {
                            for k in 0..2 {
                                let w = stencil.weight(i, j, k);
                                let idx = nodes[stencil.stencil_index(i, j, k)] as usize;
                                let mom = w * (mv + affine_dx * stencil.dpos(i, j, k));
                                // SAFETY: as in `p2g`: idx < n_nodes (both grids have the
                                // layout's node count), one writer per node per pass.
                                let n = unsafe { grid.node(idx) };
                                n[0] += w * m;
                                n[1] += mom.x;
                                n[2] += mom.y;
                                n[3] += mom.z;
                            }
                        }
                    }
                }
            }
        });
    }
}

/// P2G of the classic MPM transfers (uGIMP, linear hats): mass and momentum into the nodes,
/// `dt f_i = -dt sum_p V0_p tau_p grad w_ip` (`V sigma = V0 tau`) into `grid_aux`, kept apart so
/// that the grid update can keep the velocity before the update for FLIP.
pub fn p2g_mpm(b: &mut CpuBackend, dt: Real) {
    let n_nodes = b.layout.node_count();
    zeroed(&mut b.grid, n_nodes, [0.0; 4]);
    zeroed(&mut b.grid_aux, n_nodes, Vec3::ZERO);
    let grid = GridPtr(b.grid.as_mut_ptr());
    let aux = GridPtr(b.grid_aux.as_mut_ptr());
    let (c, p, layout, bases) = (&b.consts, &b.particles, &b.layout, &b.bases);
    let transfer = c.solver.transfer;
    for colour in &b.colours {
        colour.par_iter().for_each(|&g| {
            let g = g as usize;
            for &pi in layout.particles_of(g) {
                let pi = pi as usize;
                let xg = (p.x[pi] - c.origin) * c.inv_dx;
                let s = Stencil::for_transfer(transfer, xg, bases[pi]);
                let nodes = layout.stencil_nodes(g, s.base);
                let m = p.mass[pi];
                let model = &c.materials[p.material[pi] as usize].model;
                let tau = model.kirchhoff(p.f[pi], p.plastic[pi], p.c[pi]);
                // grad w in world units is s.grad / dx.
                let stress: Mat3 = tau * (-dt * p.vol0[pi] * c.inv_dx);
                let mv = p.v[pi] * m;
                for i in 0..3 {
                    for j in 0..3 {
                        for k in 0..3 {
                            let w = s.weight(i, j, k);
                            let idx = nodes[i * 9 + j * 3 + k] as usize;
                            // SAFETY: as in `p2g`: idx < n_nodes, one writer per node per pass.
                            let n = unsafe { grid.node(idx) };
                            n[0] += w * m;
                            n[1] += w * mv.x;
                            n[2] += w * mv.y;
                            n[3] += w * mv.z;
                            // SAFETY: grid_aux has the grid's length; same exclusivity.
                            let a = unsafe { aux.node(idx) };
                            *a += stress * s.grad(i, j, k);
                        }
                    }
                }
            }
        });
    }
}

/// MUSL re-map (Sulsky et al. 1995): the updated particle momenta `sum_p w_ip m_p v_p` into
/// `grid_aux` (weights at the positions of the start of the step; node masses from [`p2g_mpm`]).
pub fn p2g_musl(b: &mut CpuBackend) {
    let aux_len = b.grid_aux.len();
    zeroed(&mut b.grid_aux, aux_len, Vec3::ZERO);
    let aux = GridPtr(b.grid_aux.as_mut_ptr());
    let (c, p, layout, bases) = (&b.consts, &b.particles, &b.layout, &b.bases);
    let transfer = c.solver.transfer;
    for colour in &b.colours {
        colour.par_iter().for_each(|&g| {
            let g = g as usize;
            for &pi in layout.particles_of(g) {
                let pi = pi as usize;
                let xg = (p.x[pi] - c.origin) * c.inv_dx;
                let s = Stencil::for_transfer(transfer, xg, bases[pi]);
                let nodes = layout.stencil_nodes(g, s.base);
                let mv = p.v[pi] * p.mass[pi];
                for i in 0..3 {
                    for j in 0..3 {
                        for k in 0..3 {
                            let idx = nodes[i * 9 + j * 3 + k] as usize;
                            // SAFETY: as in `p2g_mpm`.
                            let a = unsafe { aux.node(idx) };
                            *a += s.weight(i, j, k) * mv;
                        }
                    }
                }
            }
        });
    }
}

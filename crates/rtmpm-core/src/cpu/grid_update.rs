//! Stage 3: grid velocities, gravity, domain walls and colliders.

use super::{CpuBackend, GRID_PAD, StepConstants};
use crate::grid::codes::{BLOCK_NODES, BLOCK_SIZE};
use crate::math::{IVec3, Real, ToReal, Vec3};
use crate::real;
use crate::transfer::Transfer;
use rayon::prelude::*;

/// Grid index of node `cell` of the block at `corner` (inverse of cell_code: `(i1 i0 j1 j0 k1 k0)`).
#[inline]
fn node_index(corner: IVec3, cell: usize) -> IVec3 {
    corner
        + IVec3::new(
            (cell >> 4) as i32,
            (cell >> 2 & 3) as i32,
            (cell & 3) as i32,
        )
}

/// Boundary conditions of node `idx` at time `t`: domain walls, then colliders.
#[inline]
fn boundary(c: &StepConstants, idx: IVec3, mut v: Vec3, t: f32) -> Vec3 {
    let rel = idx - IVec3::splat(GRID_PAD);
    v = c.walls.apply([rel.x, rel.y, rel.z], c.n_cells, v);
    if !c.colliders.is_empty() {
        let xw = c.origin + idx.to_real() * c.dx;
        for col in &c.colliders {
            if let Some((n, vc)) = col.query(xw, t) {
                v = vc + col.rule.apply(v - vc, n);
            }
        }
    }
    v
}

/// Turn node momentum into velocity, add gravity, damp (settling) and apply boundary conditions. For the classic
/// MPM transfers the internal force (times dt) comes from `grid_aux`, which then keeps the
/// velocity before the update, `v_old = p / m` (no force, no boundary condition), for FLIP.
pub fn grid_update(b: &mut CpuBackend, dt: Real, t: f32) {
    let c = &b.consts;
    let damp = real::real(c.damping.factor(real::to_f32(dt), t));
    let coords = &b.layout.block_coords;
    if c.solver.transfer == Transfer::Mls {
        b.grid
            .par_chunks_mut(BLOCK_NODES)
            .enumerate()
            .for_each(|(id, block)| {
                let corner = coords[id] * BLOCK_SIZE;
                for (cell, node) in block.iter_mut().enumerate() {
                    let m = node[0];
                    if m <= 0.0 {
                        continue;
                    }
                    let v = (Vec3::new(node[1], node[2], node[3]) / m + dt * c.gravity) * damp;
                    let v = boundary(c, node_index(corner, cell), v, t);
                    node[1] = v.x;
                    node[2] = v.y;
                    node[3] = v.z;
                }
            });
        return;
    }
    b.grid
        .par_chunks_mut(BLOCK_NODES)
        .zip(b.grid_aux.par_chunks_mut(BLOCK_NODES))
        .enumerate()
        .for_each(|(id, (block, aux))| {
            let corner = coords[id] * BLOCK_SIZE;
            for (cell, (node, a)) in block.iter_mut().zip(aux.iter_mut()).enumerate() {
                let m = node[0];
                if m <= 0.0 {
                    continue;
                }
                let p = Vec3::new(node[1], node[2], node[3]);
                let v_old = p / m;
                // v_new = (p + dt f) / m + dt g, then the boundary conditions.
                let v = ((p + *a) / m + dt * c.gravity) * damp;
                let v = boundary(c, node_index(corner, cell), v, t);
                node[1] = v.x;
                node[2] = v.y;
                node[3] = v.z;
                *a = v_old;
            }
        });
}

/// MUSL re-map: re-mapped momentum in `grid_aux` to velocity, with the same boundary conditions
/// (gravity is already in the particle velocities).
pub fn grid_update_musl(b: &mut CpuBackend, t: f32) {
    let c = &b.consts;
    let coords = &b.layout.block_coords;
    b.grid
        .par_chunks(BLOCK_NODES)
        .zip(b.grid_aux.par_chunks_mut(BLOCK_NODES))
        .enumerate()
        .for_each(|(id, (block, aux))| {
            let corner = coords[id] * BLOCK_SIZE;
            for (cell, (node, a)) in block.iter().zip(aux.iter_mut()).enumerate() {
                let m = node[0];
                if m <= 0.0 {
                    continue;
                }
                *a = boundary(c, node_index(corner, cell), *a / m, t);
            }
        });
}

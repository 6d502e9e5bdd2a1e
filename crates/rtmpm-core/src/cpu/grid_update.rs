//! Stage 3: grid velocities, gravity, domain walls and colliders.

use super::{CpuBackend, GRID_PAD};
use crate::grid::codes::{BLOCK_NODES, BLOCK_SIZE};
use crate::math::{Real, ToReal, Vec3};
use rayon::prelude::*;

/// Turn node momentum into velocity, add gravity and apply boundary conditions.
pub fn grid_update(b: &mut CpuBackend, dt: Real, t: f32) {
    let c = &b.consts;
    let coords = &b.layout.block_coords;
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
                // Inverse of cell_code: (i1 i0 j1 j0 k1 k0).
                let idx = corner
                    + crate::math::IVec3::new(
                        (cell >> 4) as i32,
                        (cell >> 2 & 3) as i32,
                        (cell & 3) as i32,
                    );
                let mut v = Vec3::new(node[1], node[2], node[3]) / m + dt * c.gravity;
                let rel = idx - crate::math::IVec3::splat(GRID_PAD);
                v = c.walls.apply([rel.x, rel.y, rel.z], c.n_cells, v);
                if !c.colliders.is_empty() {
                    let xw = c.origin + idx.to_real() * c.dx;
                    for col in &c.colliders {
                        if let Some((n, vc)) = col.query(xw, t) {
                            v = vc + col.rule.apply(v - vc, n);
                        }
                    }
                }
                node[1] = v.x;
                node[2] = v.y;
                node[3] = v.z;
            }
        });
}

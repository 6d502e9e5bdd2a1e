//! Host side of `kernels/p2g/reverse_map.cu`: P2G as a gather through replicated node-to-particle
//! reverse maps (Chiang et al., "GPU Acceleration of the Generalized Interpolation Material Point
//! Method", SAAHPC 2009; the paper uses nine replicas). Every buffer is allocated here, once: a
//! step allocates nothing and never waits for the host, so it can be captured in a CUDA graph.

use crate::contract::{Ctx, RmapCtx};
use crate::kernels::{Kernel, Kernels};
use cudarc::driver::{CudaSlice, CudaStream, DevicePtr, DriverError, PushKernelArg};
use rtmpm_physics::math::IVec3;
use rtmpm_sim::SimError;
use std::collections::HashMap;
use std::sync::Arc;

/// Bytes of the entry array of the gather strategies: 27 (particle, node) values of 4 reals per
/// particle (`kernels/p2g/particle.cuh`).
pub(crate) fn entry_bytes(cap: usize, real_bytes: usize) -> usize {
    27 * cap * 4 * real_bytes
}

/// Sizes of the reverse map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReverseMapSize {
    /// Independent maps (a particle p writes to map p % replicas).
    pub replicas: usize,
    /// Entries per node and map.
    pub slots: usize,
    /// Pblocks covered (64 nodes each).
    pub pblocks: usize,
}

/// Largest number of particles whose 3x3x3 stencil contains one node, for stencil bases `bases`.
pub fn max_node_contributions(bases: &[IVec3]) -> usize {
    let Some(&first) = bases.first() else {
        return 0;
    };
    let (lo, hi) = bases
        .iter()
        .fold((first, first), |(a, b), &x| (a.min(x), b.max(x)));
    // Nodes lo ..= hi + 2 per axis; node n receives from bases n - 2 ..= n.
    let d = (hi - lo + 3).as_uvec3();
    let len = d.x as usize * d.y as usize * d.z as usize;
    if len > 1 << 26 {
        // Too large to count densely: bound by the fullest cell.
        let mut cells: HashMap<IVec3, usize> = HashMap::new();
        for b in bases {
            *cells.entry(*b).or_default() += 1;
        }
        return 27 * cells.values().copied().max().unwrap_or(0);
    }
    let (nx, ny, nz) = (d.x as usize, d.y as usize, d.z as usize);
    let at = |i: usize, j: usize, k: usize| (i * ny + j) * nz + k;
    let mut count = vec![0u32; len];
    for b in bases {
        let r = (*b - lo).as_uvec3();
        count[at(r.x as usize, r.y as usize, r.z as usize)] += 1;
    }
    // Separable 3-wide box sum (n - 2 ..= n) along each axis.
    let mut sum_axis = |stride: usize, extent: usize, outer: &dyn Fn(usize) -> usize| {
        let mut out = vec![0u32; len];
        for o in 0..len / extent {
            let start = outer(o);
            for n in 0..extent {
                let mut s = 0;
                for back in 0..3 {
                    if n >= back {
                        s += count[start + (n - back) * stride];
                    }
                }
                out[start + n * stride] = s;
            }
        }
        count = out;
    };
    sum_axis(1, nz, &|o| o * nz);
    sum_axis(nz, ny, &|o| (o / nz) * ny * nz + o % nz);
    sum_axis(ny * nz, nx, &|o| o);
    count.into_iter().max().unwrap_or(0) as usize
}

impl ReverseMapSize {
    /// Default sizes: `replicas` maps, twice the initial largest node load spread over them (at
    /// least 8 slots), and four times the initial pblocks (at most the grid's capacity).
    pub fn for_particles(
        bases: &[IVec3],
        replicas: usize,
        initial_pblocks: usize,
        pblock_cap: usize,
    ) -> ReverseMapSize {
        let replicas = replicas.max(1);
        ReverseMapSize {
            replicas,
            slots: (2 * max_node_contributions(bases))
                .div_ceil(replicas)
                .max(8),
            pblocks: (4 * initial_pblocks).max(64).min(pblock_cap),
        }
    }
}

/// The reverse-map P2G of one backend: its kernels and buffers.
pub struct ReverseMap {
    ctx: RmapCtx,
    /// Sizes.
    pub size: ReverseMapSize,
    _bufs: Vec<CudaSlice<u8>>,
    /// (buffer, bytes) of the extra device memory.
    pub memory: Vec<(&'static str, usize)>,
}

impl ReverseMap {
    /// Timed phases.
    pub const PHASES: &'static [&'static str] = &["build", "gather"];

    /// Allocate the maps.
    pub(crate) fn new(
        stream: &Arc<CudaStream>,
        c: &Ctx,
        real_bytes: usize,
        size: ReverseMapSize,
    ) -> Result<ReverseMap, SimError> {
        let nodes = size.pblocks * 64;
        if (c.n as u64) * 27 > u32::MAX as u64
            || (nodes as u64) * (size.replicas * size.slots) as u64 > u32::MAX as u64
        {
            return Err(SimError::Backend(format!(
                "p2g=reverse_map: {} particles x 27 or {nodes} nodes x {} entries exceed 32-bit indices",
                c.n,
                size.replicas * size.slots
            )));
        }
        let memory = vec![
            ("entry values", entry_bytes(c.cap as usize, real_bytes)),
            ("map counters", size.replicas * nodes * 4),
            ("maps", size.replicas * size.slots * nodes * 4),
        ];
        let mut bufs = Vec::new();
        let mut ptrs = Vec::new();
        for (what, bytes) in &memory {
            let b = stream.alloc_zeros::<u8>((*bytes).max(16)).map_err(|e| {
                SimError::Backend(format!(
                    "CUDA: p2g=reverse_map: cannot allocate the {what} ({:.1} MB): {e:?}; \
                     lower rmap_slots= or rmap_pblocks=",
                    *bytes as f64 / 1e6
                ))
            })?;
            ptrs.push(b.device_ptr(stream).0);
            bufs.push(b);
        }
        Ok(ReverseMap {
            ctx: RmapCtx {
                contrib: ptrs[0],
                counts: ptrs[1],
                entries: ptrs[2],
                node_cap: nodes as u32,
                replicas: size.replicas as u32,
                slots: size.slots as u32,
                pad: 0,
            },
            size,
            _bufs: bufs,
            memory,
        })
    }

    /// Enqueue phase `i` of [`ReverseMap::PHASES`].
    pub(crate) fn enqueue_phase(
        &self,
        i: usize,
        k: &Kernels,
        s: &CudaStream,
        c: &Ctx,
    ) -> Result<(), DriverError> {
        // SAFETY: the kernels bounds-check against the device counters and the capacities.
        unsafe {
            if i == 0 {
                s.launch_builder(&k[Kernel::P2gRmapBuild])
                    .arg(c)
                    .arg(&self.ctx)
                    .launch(k.wave(c.warp_cap as usize * 32, 128))?;
            } else {
                s.launch_builder(&k[Kernel::P2gRmapGather])
                    .arg(c)
                    .arg(&self.ctx)
                    .launch(k.wave(self.ctx.node_cap as usize, 256))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_load_counts_every_particle_whose_stencil_holds_the_node() {
        // One particle: each of its 27 nodes receives once.
        assert_eq!(max_node_contributions(&[IVec3::new(5, -2, 7)]), 1);
        // Two particles one cell apart along x share 2 x 3 x 3 nodes.
        let b = [IVec3::new(0, 0, 0), IVec3::new(1, 0, 0)];
        assert_eq!(max_node_contributions(&b), 2);
        // Two particles 3 cells apart share none.
        let b = [IVec3::new(0, 0, 0), IVec3::new(3, 0, 0)];
        assert_eq!(max_node_contributions(&b), 1);
        // A full 3x3x3 block of cells with 2 particles each: the corner node (2, 2, 2) sees all.
        let mut b = Vec::new();
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    b.push(IVec3::new(i, j, k));
                    b.push(IVec3::new(i, j, k));
                }
            }
        }
        assert_eq!(max_node_contributions(&b), 54);
        let s = ReverseMapSize::for_particles(&b, 9, 10, 1000);
        assert_eq!((s.replicas, s.slots, s.pblocks), (9, 12, 64));
    }
}

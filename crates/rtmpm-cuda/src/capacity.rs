//! How big each buffer of a GPU is. Nothing is reallocated inside a step, so the capacities are
//! fixed when the backend is built: by default every block the domain can hold (particles are
//! clamped into the domain, so the mapping can never outgrow it), unless that grid would exceed
//! [`GRID_BUDGET_BYTES`]; then 8x the initial layout, and an overflow stops the run with an
//! error that names the option to raise.

use crate::CudaOptions;
use rtmpm_core::grid::BlockLayout;
use rtmpm_core::math::IVec3;
use rtmpm_core::{Particles, Scene};

/// Largest grid allocated by default for the whole domain (bytes).
pub const GRID_BUDGET_BYTES: usize = 4 << 30;

/// The capacities of one GPU's buffers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capacity {
    /// Particles the state arrays hold (their stride).
    pub particles: usize,
    /// Gblocks (blocks holding particles).
    pub gblocks: usize,
    /// Pblocks (blocks a particle's stencil reaches).
    pub pblocks: usize,
    /// Slots of the block hash table (a power of two).
    pub hash: usize,
    /// Warps of the warp list.
    pub warps: usize,
    /// Buckets of the block+cell sort.
    pub buckets: usize,
}

/// The stencil base node of every particle (grid coordinates, origin 4 cells below the domain).
pub fn bases(scene: &Scene, particles: &Particles) -> Vec<IVec3> {
    let dx = scene.dx;
    let origin = scene.domain_min - 4.0 * dx;
    particles
        .x
        .iter()
        .map(|x| ((*x - origin) / dx - 0.5).floor().as_ivec3())
        .collect()
}

impl Capacity {
    /// The capacities for `n` particles (state arrays of at least `min_particles`) whose initial
    /// mapping is `layout`, with the overrides of `options`.
    pub fn plan(
        scene: &Scene,
        n: usize,
        min_particles: usize,
        layout: &BlockLayout,
        options: &CudaOptions,
    ) -> Capacity {
        let domain_blocks: usize = scene
            .n_cells()
            .iter()
            .map(|&c| (c as usize + 8).div_ceil(4) + 1)
            .product();
        let real_bytes = if options.f64 { 8 } else { 4 };
        // Every capacity that scales with the particle count is planned for the state arrays'
        // count (emitters add particles during the run), not the initial one.
        let np = min_particles.max(n);
        let fits = domain_blocks * 64 * 4 * real_bytes <= GRID_BUDGET_BYTES;
        let gblocks = options.gblock_capacity.unwrap_or(if fits {
            domain_blocks.min(np.max(64))
        } else {
            (8 * layout.gblock_count).max(64)
        });
        let pblocks = options.pblock_capacity.unwrap_or(if fits {
            domain_blocks
        } else {
            (8 * layout.pblock_count()).max(4 * gblocks).max(256)
        });
        Capacity {
            particles: np,
            gblocks,
            pblocks,
            hash: (2 * pblocks).next_power_of_two(),
            warps: np.div_ceil(32) + gblocks + 1,
            buckets: gblocks * 64 + 1,
        }
    }
}

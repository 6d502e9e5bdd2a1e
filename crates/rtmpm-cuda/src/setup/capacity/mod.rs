//! How big each buffer of a GPU is. Nothing is reallocated inside a step, so the capacities are
//! fixed when the backend is built: by default every block the domain can hold (particles are
//! clamped into the domain, so the mapping can never outgrow it), unless that grid would exceed
//! [`GRID_BUDGET_BYTES`]; then 8x the initial layout, and an overflow stops the run with an
//! error that names the option to raise.

use crate::options::CudaOptions;
use rtmpm_physics::Particles;
use rtmpm_physics::grid::BlockLayout;
use rtmpm_physics::math::{IVec3, Vec3};
use rtmpm_scene::Scene;
use rtmpm_scene::sampling::SampledBody;

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

/// Which optional grids a GPU allocates besides the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GridCopies {
    /// G2P2G: the grid of the next step (and, with `aux`, its second grid).
    pub next: bool,
    /// Classic (non-MLS) transfers: a second value per node; CK-MPM: its second grid.
    pub aux: bool,
}

/// Bytes of every device buffer of one GPU's pipeline, planned from its [`Capacity`]: what
/// `buffers::allocate` allocates (each at least 16 bytes). `docs/memory.md` lists the formulas.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BufferBytes {
    /// Particle state: the layout's words (`StateLayout::words`) per particle slot.
    pub state: usize,
    /// Sort scratch: `sort_scratch_fields` reals per particle slot (its first field also holds
    /// the sort keys, so it is at least 4 bytes per slot).
    pub scratch: usize,
    /// Sort ranks, then sorted slots: 4 bytes per particle slot.
    pub prank: usize,
    /// Sort buckets: 4 bytes per bucket (64 per gblock, plus one).
    pub hist: usize,
    /// Block sums of the bucket scan.
    pub scan_sums: usize,
    /// Grid: 4 reals per node, 64 nodes per pblock.
    pub grid: usize,
    /// G2P2G's grid of the next step (0 without; CK-MPM: its two grids, one after the other).
    pub grid_next: usize,
    /// Classic transfers' second node values, CK-MPM's second grid (0 for MLS).
    pub grid_aux: usize,
    /// Block hash: 8-byte key and 4-byte value per slot.
    pub hash: usize,
    /// 27 neighbour ids (4 bytes) per gblock.
    pub neighbors: usize,
    /// 3 ints per pblock.
    pub block_coords: usize,
    /// 3 words per warp.
    pub warps: usize,
    /// One word per gblock (several GPUs: next to a shared block).
    pub boundary: usize,
    /// One word per pblock (several GPUs: shared).
    pub shared_pblock: usize,
}

impl BufferBytes {
    /// Every buffer, in groups: (group, bytes): state, sort scratch, grid (every grid copy),
    /// sort (ranks, buckets, scan), mapping (hash, neighbour lists, block coordinates, warp
    /// list, sharing flags).
    pub fn groups(&self) -> [(&'static str, usize); 5] {
        [
            ("state", self.state),
            ("scratch", self.scratch),
            ("grid", self.grid + self.grid_next + self.grid_aux),
            ("sort", self.prank + self.hist + self.scan_sums),
            (
                "hash/lists",
                self.hash
                    + self.neighbors
                    + self.block_coords
                    + self.warps
                    + self.boundary
                    + self.shared_pblock,
            ),
        ]
    }

    /// Bytes of every buffer.
    pub fn total(&self) -> usize {
        self.groups().iter().map(|g| g.1).sum()
    }
}

/// Device memory kept free besides the planned buffers: the context's own, the module, the
/// tables, the P2G strategies' extras and the readback buffers (bytes).
pub const DEVICE_RESERVE_BYTES: usize = 512 << 20;

/// The refusal of a plan that does not fit the `free` bytes of a GPU, before anything is
/// allocated, with the estimate and the largest size that fits, or `None` when it fits with
/// [`DEVICE_RESERVE_BYTES`] to spare. `bytes` is [`Capacity::bytes`] for `particles` particle
/// slots; `gpu` names the device; `hint` is what
/// else the user can change (the compact state, say). The particles that fit: the free bytes
/// less the reserve and the plan's fixed part (grid, hash, lists), over its bytes a particle
/// (state, sort scratch, ranks, warp list).
pub fn refusal(
    bytes: &BufferBytes,
    particles: usize,
    free: usize,
    gpu: &str,
    hint: &str,
) -> Option<String> {
    use rtmpm_io::limits::human_bytes;
    let total = bytes.total();
    if total.saturating_add(DEVICE_RESERVE_BYTES) <= free {
        return None;
    }
    let per_particle = bytes.state + bytes.scratch + bytes.prank + bytes.warps;
    let fixed = total - per_particle;
    let per = per_particle as f64 / particles.max(1) as f64;
    let room = free.saturating_sub(DEVICE_RESERVE_BYTES + fixed);
    let fits = (room as f64 / per.max(1.0)).floor() as u64;
    Some(format!(
        "CUDA backend: the run needs {} of GPU memory on {gpu} ({per:.1} bytes a particle for \
         {particles} particle slots, {} of grid, block hash and lists) and {} more for the \
         context, kernels and tables; {} is free there. About {fits} particles fit \
         (with this dx). Fix: use fewer particles (a coarser dx, a lower particles_per_cell, \
         smaller bodies or emitter totals){hint}, several GPUs (--gpus N), or --backend cpu",
        human_bytes(total as u64),
        human_bytes(fixed as u64),
        human_bytes(DEVICE_RESERVE_BYTES as u64),
        human_bytes(free as u64),
    ))
}

/// The stencil base node of every particle (grid coordinates, origin 4 cells below the domain).
pub fn bases(scene: &Scene, particles: &Particles) -> Vec<IVec3> {
    use rayon::prelude::*;
    let base = base_of(scene);
    particles.x.par_iter().map(|&x| base(x)).collect()
}

/// The stencil base node of a particle at `x`, as [`bases`] computes it.
pub fn base_of(scene: &Scene) -> impl Fn(rtmpm_physics::math::Vec3) -> IVec3 + Sync + Send + use<> {
    let dx = scene.dx;
    let origin = scene.domain_min - 4.0 * dx;
    move |x| ((x - origin) / dx - 0.5).floor().as_ivec3()
}

/// The block counts of the initial mapping of sampled bodies: (gblocks, pblocks), what
/// [`BlockLayout::rebuild`] counts from their stencil bases ([`base_of`]), without a per-particle
/// array: each chunk of positions lists the blocks it sees, and the pblocks are the union of the
/// gblocks' 3x3x3 neighbourhoods (a pass over the positions and a sort of block codes).
pub fn block_counts(scene: &Scene, bodies: &[SampledBody]) -> (usize, usize) {
    use rayon::prelude::*;
    let base = base_of(scene);
    let mut codes: Vec<u64> = Vec::new();
    for body in bodies {
        match body {
            SampledBody::Shape(b) => codes.par_extend(
                b.chunks
                    .par_iter()
                    .flat_map_iter(|c| chunk_blocks(&base, c)),
            ),
            SampledBody::Points(p) => codes.par_extend(
                p.x.par_chunks(1 << 16)
                    .flat_map_iter(|c| chunk_blocks(&base, c)),
            ),
            // Walked chunk by chunk on the host, no position kept.
            SampledBody::Deferred(d) => {
                for c in d.map_chunks(|c| chunk_blocks(&base, c)) {
                    codes.extend(c);
                }
            }
        }
    }
    count_blocks(codes)
}

/// [`block_counts`] of the particles at the positions `chunks` (concatenated), e.g.
/// `particles.x.chunks(..)`.
pub fn block_counts_of(scene: &Scene, chunks: &[&[Vec3]]) -> (usize, usize) {
    use rayon::prelude::*;
    let base = base_of(scene);
    count_blocks(
        chunks
            .par_iter()
            .flat_map_iter(|xs| chunk_blocks(&base, xs))
            .collect(),
    )
}

/// The codes of the blocks that the positions `xs` fall in (stencil bases by `base`), sorted,
/// each once.
fn chunk_blocks(base: &(impl Fn(Vec3) -> IVec3 + Sync), xs: &[Vec3]) -> Vec<u64> {
    use rtmpm_physics::grid::codes::block_code;
    use rtmpm_physics::grid::layout::block_of;
    let mut run = Vec::new();
    let mut last = None;
    for &x in xs {
        let b = block_of(base(x));
        if last != Some(b) {
            run.push(block_code(b));
            last = Some(b);
        }
    }
    run.sort_unstable();
    run.dedup();
    run
}

/// (gblocks, pblocks) of the occupied blocks `codes` (in any order, repeated or not): the
/// pblocks are the union of the gblocks' 3x3x3 neighbourhoods.
fn count_blocks(mut codes: Vec<u64>) -> (usize, usize) {
    use rayon::prelude::*;
    use rtmpm_physics::grid::codes::{block_code, decode_block};
    codes.par_sort_unstable();
    codes.dedup();
    // As BlockLayout's neighbours: coordinates + offset in i32, then as u32.
    let mut all: Vec<u64> = codes
        .par_iter()
        .flat_map_iter(|&code| {
            let c = decode_block(code).map(|v| v as i32);
            (0..27).map(move |s| {
                let d = [s / 9 - 1, (s / 3) % 3 - 1, s % 3 - 1];
                block_code(std::array::from_fn(|a| (c[a] + d[a]) as u32))
            })
        })
        .collect();
    all.par_sort_unstable();
    all.dedup();
    (codes.len(), all.len())
}

/// Blocks of the whole domain (with the margin of the grid's origin).
fn domain_blocks(scene: &Scene) -> usize {
    scene
        .n_cells()
        .iter()
        .map(|&c| (c as usize + 8).div_ceil(4) + 1)
        .product()
}

/// True when the whole domain's grid, `real_bytes` a value, fits in [`GRID_BUDGET_BYTES`]: the
/// capacities are then the domain's, whatever the particles.
fn domain_grid_fits(scene: &Scene, real_bytes: usize) -> bool {
    domain_blocks(scene) * 64 * 4 * real_bytes <= GRID_BUDGET_BYTES
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
        let blocks = (layout.gblock_count, layout.pblock_count());
        Self::plan_blocks(scene, n, min_particles, blocks, options)
    }

    /// True when [`Capacity::plan_blocks`] reads the block counts: the whole domain's grid
    /// exceeds [`GRID_BUDGET_BYTES`] and `options` does not set both capacities (else the
    /// counts need not be found).
    pub fn needs_block_counts(scene: &Scene, options: &CudaOptions) -> bool {
        let real_bytes = if options.f64 { 8 } else { 4 };
        !domain_grid_fits(scene, real_bytes)
            && (options.gblock_capacity.is_none() || options.pblock_capacity.is_none())
    }

    /// [`Capacity::plan`] from the initial mapping's (gblocks, pblocks) counts alone.
    pub fn plan_blocks(
        scene: &Scene,
        n: usize,
        min_particles: usize,
        (gblock_count, pblock_count): (usize, usize),
        options: &CudaOptions,
    ) -> Capacity {
        let domain_blocks = domain_blocks(scene);
        let real_bytes = if options.f64 { 8 } else { 4 };
        // Every capacity that scales with the particle count is planned for the state arrays'
        // count (emitters add particles during the run), not the initial one.
        let np = min_particles.max(n);
        let fits = domain_grid_fits(scene, real_bytes);
        let gblocks = options.gblock_capacity.unwrap_or(if fits {
            domain_blocks.min(np.max(64))
        } else {
            (8 * gblock_count).max(64)
        });
        let pblocks = options.pblock_capacity.unwrap_or(if fits {
            domain_blocks
        } else {
            (8 * pblock_count).max(4 * gblocks).max(256)
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

    /// The bytes of every buffer for `real_bytes` per real (4 or 8), a state of `words` words
    /// per particle (`StateLayout::words`), a sort scratch of `sort_fields` fields (clamped to
    /// 1..=`words`) and the optional grids `grids`.
    pub fn bytes(
        &self,
        real_bytes: usize,
        words: usize,
        sort_fields: usize,
        grids: GridCopies,
    ) -> BufferBytes {
        let np = self.particles;
        let grid = self.pblocks * 64 * 4 * real_bytes;
        BufferBytes {
            state: words * np * real_bytes,
            // The sort keys (4 bytes) live in its first field.
            scratch: (sort_fields.clamp(1, words.max(1)) * real_bytes).max(4) * np,
            prank: np * 4,
            hist: self.buckets * 4,
            scan_sums: self.buckets.div_ceil(1024) * 4,
            grid,
            // With a second grid (CK-MPM) the next step's two grids, one after the other.
            grid_next: if grids.next {
                grid * (1 + grids.aux as usize)
            } else {
                0
            },
            grid_aux: if grids.aux { grid } else { 0 },
            hash: self.hash * 12,
            neighbors: self.gblocks * 27 * 4,
            block_coords: self.pblocks * 12,
            warps: self.warps * 12,
            boundary: self.gblocks * 4,
            shared_pblock: self.pblocks * 4,
        }
    }
}

#[cfg(test)]
mod tests;

//! How big each buffer of a GPU is. Nothing is reallocated inside a step, so the capacities are
//! fixed when the backend is built: by default every block the domain can hold (particles are
//! clamped into the domain, so the mapping can never outgrow it), unless that grid would exceed
//! [`GRID_BUDGET_BYTES`]; then 8x the initial layout, and an overflow stops the run with an
//! error that names the option to raise.

use crate::CudaOptions;
use rtmpm_core::grid::BlockLayout;
use rtmpm_core::math::{IVec3, Vec3};
use rtmpm_core::scene::sampling::SampledBody;
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

/// Which optional grids a GPU allocates besides the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GridCopies {
    /// G2P2G: the grid of the next step.
    pub next: bool,
    /// Classic (non-MLS) transfers: a second value per node.
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
    /// G2P2G's second grid (0 without).
    pub grid_next: usize,
    /// Classic transfers' second node values (0 for MLS).
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
/// allocated (issue 19: "refused before any allocation, with the estimate and the largest size
/// that fits"), or `None` when it fits with [`DEVICE_RESERVE_BYTES`] to spare. `bytes` is
/// [`Capacity::bytes`] for `particles` particle slots; `gpu` names the device; `hint` is what
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
    use rtmpm_core::io::limits::human_bytes;
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
pub fn base_of(scene: &Scene) -> impl Fn(rtmpm_core::math::Vec3) -> IVec3 + Sync + Send + use<> {
    let dx = scene.dx;
    let origin = scene.domain_min - 4.0 * dx;
    move |x| ((x - origin) / dx - 0.5).floor().as_ivec3()
}

/// The block counts of the initial mapping of sampled bodies: (gblocks, pblocks), what
/// [`BlockLayout::rebuild`] counts from their stencil bases ([`base_of`]), without a per-particle
/// array: each chunk of positions lists the blocks it sees, and the pblocks are the union of the
/// gblocks' 3x3x3 neighbourhoods (a pass over the positions and a sort of block codes).
pub fn block_counts(scene: &Scene, bodies: &[SampledBody]) -> (usize, usize) {
    let mut chunks: Vec<&[Vec3]> = Vec::new();
    for body in bodies {
        match body {
            SampledBody::Shape(b) => chunks.extend(b.chunks.iter().map(|c| c.as_slice())),
            SampledBody::Points(p) => chunks.extend(p.x.chunks(1 << 16)),
        }
    }
    block_counts_of(scene, &chunks)
}

/// [`block_counts`] of the particles at the positions `chunks` (concatenated), e.g.
/// `particles.x.chunks(..)`.
pub fn block_counts_of(scene: &Scene, chunks: &[&[Vec3]]) -> (usize, usize) {
    use rayon::prelude::*;
    use rtmpm_core::grid::codes::{block_code, decode_block};
    use rtmpm_core::grid::layout::block_of;
    let base = base_of(scene);
    let mut codes: Vec<u64> = chunks
        .par_iter()
        .flat_map_iter(|xs| {
            let mut run = Vec::new();
            let mut last = None;
            for &x in xs.iter() {
                let b = block_of(base(x));
                if last != Some(b) {
                    run.push(block_code(b));
                    last = Some(b);
                }
            }
            run.sort_unstable();
            run.dedup();
            run
        })
        .collect();
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
            grid_next: if grids.next { grid } else { 0 },
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
mod tests {
    use super::*;
    use rtmpm_core::scene::Budget;

    /// Water at dx = 1/512, 8 particles per cell (regular), in the unit cube with slip walls:
    /// `boxes` boxes along x (min, max of each), the scenes of issue 19.
    fn water(boxes: &[([f32; 3], [f32; 3])]) -> Scene {
        water_at(512, boxes)
    }

    /// The same at dx = 1/`cells`.
    fn water_at(cells: u32, boxes: &[([f32; 3], [f32; 3])]) -> Scene {
        let mut text = format!(
            "name = \"water\"\n[domain]\nmin = [0,0,0]\nmax = [1,1,1]\ndx = {}\n\
             [time]\nduration = 0.01\nfps = 100\ndt = 1e-4\n\
             [walls]\nthickness = 3\ncondition = \"slip\"\n\
             [[material]]\nname = \"water\"\ntype = \"fluid\"\ndensity = 1000\n\
             bulk_modulus = 4e4\ngamma = 7.15\n",
            1.0 / cells as f64
        );
        for (lo, hi) in boxes {
            text += &format!(
                "[[body]]\nmaterial = \"water\"\nshape = \"box\"\nmin = {lo:?}\nmax = {hi:?}\n\
                 sampling = \"regular\"\nparticles_per_cell = 8\n"
            );
        }
        Scene::from_toml(&text, "<test>").expect("water scene")
    }

    /// The planned device bytes of `scene` (its precision, options `o` otherwise, G2P2G) with
    /// a sort scratch of `fields` fields, and the estimate of its budget.
    fn planned_with(scene: &Scene, fields: usize, o: CudaOptions) -> (usize, BufferBytes, u64) {
        let budget = Budget::estimate(scene, Some(1));
        let n = budget.particles as usize;
        let f64 = scene.precision == rtmpm_core::scene::Precision::F64;
        let o = CudaOptions { f64, ..o };
        let words = crate::state::layout_for(scene, &o).expect("layout").words();
        let cap = Capacity::plan(scene, n, n, &BlockLayout::default(), &o);
        let grids = GridCopies {
            next: true,
            aux: false,
        };
        let rb = if f64 { 8 } else { 4 };
        (n, cap.bytes(rb, words, fields, grids), budget.gpu_bytes)
    }

    /// [`planned_with`] the default options (the fluid layout for water).
    fn planned(scene: &Scene, fields: usize) -> (usize, BufferBytes, u64) {
        planned_with(scene, fields, CudaOptions::default())
    }

    #[test]
    fn the_budget_covers_the_plan_in_f64() {
        // dx = 1/256: the grid of the whole domain fits in GRID_BUDGET_BYTES in f64 (at 1/512
        // it does not, the plan follows the initial layout and the budget, which counts every
        // node of the domain, overestimates).
        let mut scene = water_at(256, &[([0.1, 0.02, 0.25], [0.4, 0.485, 0.75])]);
        scene.precision = rtmpm_core::scene::Precision::F64;
        let (n, b, estimate) = planned(&scene, crate::options::DEFAULT_SORT_SCRATCH_FIELDS);
        assert!(n > 9_000_000, "{n}");
        // The fluid layout: 20 words of 8 bytes.
        assert_eq!((b.state, b.scratch, b.prank), (160 * n, 32 * n, 4 * n));
        let plan = b.total() as f64;
        assert!(
            estimate as f64 >= plan && estimate as f64 <= 1.15 * plan,
            "estimate {estimate} for a plan of {plan}"
        );
    }

    #[test]
    fn bytes_per_particle_of_the_big_water_scenes() {
        // 125M: four boxes 0.125 m wide (issue 19's scene, measured 276 B/particle before).
        let four: Vec<_> = (0..4)
            .map(|i| {
                let x = 0.125 + 0.125 * i as f32;
                ([x, 0.02, 0.25], [x + 0.125, 0.485, 0.75])
            })
            .collect();
        // About 500M: most of the floor, half the height, in 16 boxes (at most 50M per body).
        let big: Vec<_> = (0..16)
            .map(|i| {
                let x = 0.01 + 0.06125 * i as f32;
                ([x, 0.01, 0.01], [x + 0.06125, 0.495, 0.99])
            })
            .collect();
        let default = crate::options::DEFAULT_SORT_SCRATCH_FIELDS;
        let full_layout = CudaOptions {
            fluid_state: false,
            ..Default::default()
        };
        // (scene, particle count, bytes per particle in the 29-word layout, bound, in the
        // 20-word fluid layout (the default for water), bound)
        for (scene, particles, expect, new_bound, expect_fluid, fluid_bound) in [
            (
                water(&four),
                124_000_000..126_000_000,
                181.2,
                185.0,
                145.2,
                148.0,
            ),
            (
                water(&big),
                499_000_000..502_000_000,
                147.6,
                150.0,
                111.6,
                114.0,
            ),
        ] {
            let (n, now, _) = planned_with(&scene, default, full_layout.clone());
            assert!(particles.contains(&n), "{n} particles");
            // Before: a second full copy of the state as the sort's scratch, and the sort keys
            // in their own array.
            let (_, full, _) = planned_with(&scene, 29, full_layout.clone());
            let before = full.total() + 4 * n;
            let per = |b: usize| b as f64 / n as f64;
            // Per particle: state 116, scratch 16, ranks 4, warp list 12/32 (+ gblocks).
            assert_eq!(now.state, 116 * n);
            assert_eq!(now.scratch, 16 * n);
            assert_eq!(now.prank, 4 * n);
            assert_eq!(full.scratch, 116 * n);
            assert!(
                per(now.total()) <= new_bound,
                "{} B/particle",
                per(now.total())
            );
            assert!(
                (per(now.total()) - expect).abs() < 0.05,
                "{}",
                per(now.total())
            );
            assert!(
                per(before) - per(now.total()) >= 104.0,
                "{} -> {}",
                per(before),
                per(now.total())
            );
            // The default for water: the fluid layout, 20 words (80 bytes) instead of 29.
            let (n2, fluid, estimate) = planned(&scene, default);
            assert_eq!(n2, n);
            assert_eq!(fluid.state, 80 * n);
            assert_eq!(fluid.scratch, 16 * n);
            assert_eq!(fluid.total() + 36 * n, now.total());
            assert!(
                per(fluid.total()) <= fluid_bound
                    && (per(fluid.total()) - expect_fluid).abs() < 0.05,
                "{} B/particle",
                per(fluid.total())
            );
            // The budget's estimate (rtmpm check, the refusal before allocating) covers the
            // plan, without refusing what fits by far.
            let e = estimate as f64;
            assert!(
                e >= fluid.total() as f64 && e <= 1.15 * fluid.total() as f64,
                "estimate {e:.3e} B for a plan of {:.3e} B",
                fluid.total() as f64
            );
            eprintln!(
                "{n} particles: {:.1} B/particle before, {:.1} in 29 words ({:?}), {:.1} in the \
                 fluid layout, estimate {:.1}",
                per(before),
                per(now.total()),
                now.groups()
                    .map(|(g, b)| (g, (per(b) * 10.0).round() / 10.0)),
                per(fluid.total()),
                e / n as f64
            );
        }
    }

    #[test]
    fn a_plan_past_the_free_memory_is_refused_with_what_fits() {
        let cap = Capacity {
            particles: 1_000_000,
            gblocks: 1000,
            pblocks: 2000,
            hash: 4096,
            warps: 1_000_000 / 32 + 1001,
            buckets: 64_001,
        };
        let b = cap.bytes(4, 20, 4, GridCopies::default());
        let total = b.total();
        // Fits with the reserve to spare; refused one byte short of it.
        assert_eq!(
            refusal(&b, cap.particles, total + DEVICE_RESERVE_BYTES, "GPU 0", ""),
            None
        );
        let why = refusal(
            &b,
            cap.particles,
            total + DEVICE_RESERVE_BYTES - 1,
            "GPU 0",
            "",
        )
        .expect("refused");
        assert!(why.contains("GPU 0") && why.contains("--gpus N"), "{why}");
        // The particles that fit: (free - reserve - fixed) / bytes a particle, here about half.
        let per = (b.state + b.scratch + b.prank + b.warps) as f64 / cap.particles as f64;
        let fixed = total - (b.state + b.scratch + b.prank + b.warps);
        let free = DEVICE_RESERVE_BYTES + fixed + (per * 500_000.0) as usize;
        let why =
            refusal(&b, cap.particles, free, "GPU 0", ", the compact state").expect("refused");
        let fits: u64 = why
            .split("About ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|n| n.parse().ok())
            .expect("a count");
        assert!((499_990..=500_000).contains(&fits), "{fits}: {why}");
        assert!(why.contains("the compact state"), "{why}");
        // Nothing free: none fit, no underflow.
        let why = refusal(&b, cap.particles, 0, "GPU 0", "").expect("refused");
        assert!(why.contains("About 0 particles fit"), "{why}");
    }

    #[test]
    fn the_scratch_holds_the_sort_keys_in_every_precision() {
        let cap = Capacity {
            particles: 1000,
            gblocks: 10,
            pblocks: 20,
            hash: 64,
            warps: 50,
            buckets: 641,
        };
        for rb in [4, 8] {
            for k in [0, 1, 4, 29, 99] {
                let b = cap.bytes(rb, 29, k, GridCopies::default());
                assert!(b.scratch >= 4 * cap.particles);
                assert_eq!(b.scratch, k.clamp(1, 29) * rb * cap.particles);
                let fluid = cap.bytes(rb, 20, k, GridCopies::default());
                assert_eq!(fluid.state, 20 * rb * cap.particles);
                assert_eq!(fluid.scratch, k.clamp(1, 20) * rb * cap.particles);
                assert_eq!(b.grid_next + b.grid_aux, 0);
                assert_eq!(b.total(), b.groups().iter().map(|g| g.1).sum::<usize>());
            }
        }
    }

    /// The block counts found from the positions alone are the layout's, for bodies of shapes
    /// (several chunks each), a body of points (from chunks of another size) and particles at
    /// the domain's corner (blocks whose neighbours have negative coordinates).
    #[test]
    fn block_counts_are_the_layouts() {
        use rtmpm_core::scene::sampling::sample_bodies;
        let scene = water_at(
            64,
            &[
                ([0.05, 0.05, 0.05], [0.3, 0.6, 0.4]),
                ([0.5, 0.1, 0.5], [0.9, 0.3, 0.95]),
            ],
        );
        let mut bodies = sample_bodies(&scene, &|_| {}).expect("sample");
        let mut p = Particles::default();
        for i in 0..200_000 {
            let t = i as f32 * 1e-3;
            let x = Vec3::new(
                0.5 + 0.45 * t.sin(),
                0.5 + 0.45 * (0.7 * t).cos(),
                (t * 0.37).fract(),
            );
            p.push(x, Vec3::ZERO, 1.0, 1.0, 0, 0.0);
        }
        p.push(Vec3::ZERO, Vec3::ZERO, 1.0, 1.0, 0, 0.0);
        bodies.insert(1, SampledBody::Points(p));
        let bases = crate::state::map_positions(&bodies, base_of(&scene));
        let mut layout = BlockLayout::default();
        layout.rebuild(&bases);
        let got = block_counts(&scene, &bodies);
        assert_eq!(got, (layout.gblock_count, layout.pblock_count()));
        assert!(got.0 > 100 && got.1 > got.0, "{got:?}");
    }

    /// The block counts are found only where the plan reads them: a domain whose grid exceeds
    /// the budget, without both capacities given.
    #[test]
    fn block_counts_only_when_the_domain_grid_does_not_fit() {
        let small = water_at(512, &[([0.1, 0.1, 0.1], [0.2, 0.2, 0.2])]);
        let big = water_at(1024, &[([0.1, 0.1, 0.1], [0.2, 0.2, 0.2])]);
        let o = CudaOptions::default();
        assert!(!Capacity::needs_block_counts(&small, &o));
        assert!(Capacity::needs_block_counts(&big, &o));
        let given = CudaOptions {
            gblock_capacity: Some(100),
            pblock_capacity: Some(1000),
            ..CudaOptions::default()
        };
        assert!(!Capacity::needs_block_counts(&big, &given));
        // Whatever the counts, the small domain's plan is the domain's.
        let a = Capacity::plan_blocks(&small, 1000, 0, (0, 0), &o);
        let b = Capacity::plan_blocks(&small, 1000, 0, (5, 50), &o);
        assert_eq!(a, b);
        let c = Capacity::plan_blocks(&big, 1000, 0, (5, 50), &o);
        assert_ne!(c, Capacity::plan_blocks(&big, 1000, 0, (6, 60), &o));
    }
}

//! Block layout: sorted block codes to dense ids, gblocks, pblocks and neighbour lists, and the
//! particle order (particles sorted by block, then by cell).
//!
//! Built in parallel and deterministically: every step that depends on the thread count or on
//! timing (per-chunk distinct codes, the counting of particles per gblock, the scatter of
//! particles into their gblock's range) is followed by a sort or a sum whose result does not:
//! the layout depends only on the stencil bases (and the tie-breaking ids).

use super::codes::{BLOCK_BITS, BLOCK_NODES, block_code, cell_code, neighbor_slot};
use crate::math::IVec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

/// Particles per parallel chunk of the layout's passes over particles (at least).
const MIN_CHUNK: usize = 4096;

/// A shared pointer into an index array, written at disjoint positions by different threads.
struct SharedSlice(*mut u32, usize);
// SAFETY: every user writes positions that no other thread writes in the same pass (slots claimed
// with an atomic counter, or disjoint gblock ranges), and nobody reads them during the pass.
unsafe impl Send for SharedSlice {}
unsafe impl Sync for SharedSlice {}
impl SharedSlice {
    fn new(v: &mut [u32]) -> Self {
        SharedSlice(v.as_mut_ptr(), v.len())
    }
    /// # Safety
    /// `range` lies in the slice and no other thread accesses it during the pass.
    #[allow(clippy::mut_from_ref)]
    #[inline]
    unsafe fn range(&self, start: usize, end: usize) -> &mut [u32] {
        assert!(start <= end && end <= self.1, "range outside the slice");
        // SAFETY: in bounds (checked); exclusive by the caller's guarantee.
        unsafe { std::slice::from_raw_parts_mut(self.0.add(start), end - start) }
    }
}

/// The sparse block structure for one particle configuration.
///
/// Ids `0..gblock_count` are the gblocks (blocks holding particles), sorted by block code;
/// the remaining ids are their neighbours, also sorted by block code. Every container is
/// reused from one rebuild to the next (no reallocation once sizes settle).
#[derive(Default, Debug)]
pub struct BlockLayout {
    /// Block coordinates of each pblock (in blocks).
    pub block_coords: Vec<IVec3>,
    /// Number of gblocks.
    pub gblock_count: usize,
    /// For each gblock, the ids of its 3x3x3 neighbour pblocks, see [`neighbor_slot`].
    pub neighbors: Vec<[u32; 27]>,
    /// Particle indices sorted by (gblock, cell code, tie: original id or particle index).
    pub order: Vec<u32>,
    /// `order[particle_start[g]..particle_start[g + 1]]` are the particles of gblock `g`.
    pub particle_start: Vec<u32>,
    /// Sorted block codes of the gblocks.
    codes: Vec<u64>,
    /// Sorted block codes of the other pblocks (neighbours only).
    extra_codes: Vec<u64>,
    /// Per particle: gblock * 64 + cell code.
    keys: Vec<u32>,
    scratch: Vec<u32>,
    /// Per gblock: particle count, then the next free slot of the scatter.
    counts: Vec<AtomicU32>,
    /// Per parallel chunk: the distinct codes it saw.
    runs: Vec<Vec<u64>>,
}

impl Clone for BlockLayout {
    fn clone(&self) -> Self {
        BlockLayout {
            block_coords: self.block_coords.clone(),
            gblock_count: self.gblock_count,
            neighbors: self.neighbors.clone(),
            order: self.order.clone(),
            particle_start: self.particle_start.clone(),
            codes: self.codes.clone(),
            extra_codes: self.extra_codes.clone(),
            keys: self.keys.clone(),
            scratch: Vec::new(),
            counts: Vec::new(),
            runs: Vec::new(),
        }
    }
}

/// Chunk length of the parallel passes over `n` items: about 4 chunks per thread.
fn chunk_len(n: usize) -> usize {
    n.div_ceil(4 * rayon::current_num_threads()).max(MIN_CHUNK)
}

/// Sort and deduplicate each run, then gather them into `out`, sorted and deduplicated.
fn merge_runs(runs: &mut [Vec<u64>], out: &mut Vec<u64>) {
    out.clear();
    for r in runs.iter() {
        out.extend_from_slice(r);
    }
    out.par_sort_unstable();
    out.dedup();
}

/// Index of `code` in the sorted `codes` (which holds it).
#[inline]
fn find(codes: &[u64], code: u64) -> usize {
    codes.partition_point(|&c| c < code)
}

impl BlockLayout {
    /// Number of pblocks (blocks with memory).
    pub fn pblock_count(&self) -> usize {
        self.block_coords.len()
    }

    /// Number of grid nodes in memory.
    pub fn node_count(&self) -> usize {
        self.pblock_count() * BLOCK_NODES
    }

    /// Bytes held by the layout's arrays (capacities).
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of;
        self.block_coords.capacity() * size_of::<IVec3>()
            + self.neighbors.capacity() * size_of::<[u32; 27]>()
            + (self.order.capacity()
                + self.particle_start.capacity()
                + self.keys.capacity()
                + self.scratch.capacity()
                + self.counts.capacity())
                * 4
            + (self.codes.capacity() + self.extra_codes.capacity()) * 8
            + self.runs.iter().map(|r| r.capacity() * 8).sum::<usize>()
    }

    /// Rebuild from the stencil base node of every particle (grid indices, all non-negative).
    ///
    /// Deterministic: the result depends only on `bases`, never on thread count or timing.
    pub fn rebuild(&mut self, bases: &[IVec3]) {
        self.rebuild_with_ties(bases, None);
    }

    /// [`BlockLayout::rebuild`], with particles of one cell ordered by `ids` (their original
    /// indices) instead of by storage index, so that the order is a function of the particle
    /// state alone, whatever order they are stored in.
    pub fn rebuild_with_ties(&mut self, bases: &[IVec3], ids: Option<&[u32]>) {
        let chunk = chunk_len(bases.len());
        self.find_gblocks(bases, chunk);
        self.add_pblocks();
        self.key_and_count_particles(bases, chunk);
        self.order_particles(chunk, ids);
    }

    /// Step 1 of a rebuild, gblocks: the distinct block codes of `bases`, sorted. Each chunk
    /// lists the codes it sees (few runs: particles are stored sorted by block); the merged
    /// list is sorted.
    fn find_gblocks(&mut self, bases: &[IVec3], chunk: usize) {
        let n = bases.len();
        self.runs.resize_with(n.div_ceil(chunk), Vec::new);
        bases
            .par_chunks(chunk)
            .zip(self.runs.par_iter_mut())
            .for_each(|(b, run)| {
                run.clear();
                // Compare block coordinates (cheap); the code only where the block changes.
                let mut last = None;
                for &x in b {
                    let block = block_of(x);
                    if last != Some(block) {
                        run.push(block_code(block));
                        last = Some(block);
                    }
                }
                run.sort_unstable();
                run.dedup();
            });
        merge_runs(&mut self.runs, &mut self.codes);
        let g_count = self.codes.len();
        self.gblock_count = g_count;
    }

    /// Step 2 of a rebuild, pblocks: the gblocks' neighbours that are not gblocks, sorted, after
    /// the gblocks; the coordinates of every pblock and the 27 neighbours of every gblock.
    fn add_pblocks(&mut self) {
        let g_count = self.gblock_count;
        let g_chunk = g_count.div_ceil(4 * rayon::current_num_threads()).max(64);
        self.runs.resize_with(g_count.div_ceil(g_chunk), Vec::new);
        let codes = &self.codes;
        codes
            .par_chunks(g_chunk)
            .zip(self.runs.par_iter_mut())
            .for_each(|(cs, run)| {
                run.clear();
                for &code in cs {
                    let bc = decode(code);
                    for_each_neighbor(bc, |_, nb| {
                        if codes.binary_search(&nb).is_err() {
                            run.push(nb);
                        }
                    });
                }
                run.sort_unstable();
                run.dedup();
            });
        merge_runs(&mut self.runs, &mut self.extra_codes);
        let extra = &self.extra_codes;
        self.block_coords.clear();
        self.block_coords.resize(g_count + extra.len(), IVec3::ZERO);
        let (gc, ec) = self.block_coords.split_at_mut(g_count);
        gc.par_iter_mut()
            .zip(codes.par_iter())
            .for_each(|(c, &code)| *c = decode(code));
        ec.par_iter_mut()
            .zip(extra.par_iter())
            .for_each(|(c, &code)| *c = decode(code));
        self.neighbors.clear();
        self.neighbors.resize(g_count, [0; 27]);
        self.neighbors
            .par_iter_mut()
            .zip(codes.par_iter())
            .for_each(|(list, &code)| {
                for_each_neighbor(decode(code), |slot, nb| {
                    list[slot] = match codes.binary_search(&nb) {
                        Ok(id) => id as u32,
                        Err(_) => (g_count + find(extra, nb)) as u32,
                    };
                });
            });
    }

    /// Step 3 of a rebuild, particles: the key (gblock, cell) of each, counted per gblock; the
    /// start of each gblock's range, and the counters set to the next free slot of each.
    fn key_and_count_particles(&mut self, bases: &[IVec3], chunk: usize) {
        let (n, g_count) = (bases.len(), self.gblock_count);
        let codes = &self.codes;
        self.keys.resize(n, 0);
        self.counts.resize_with(g_count, || AtomicU32::new(0));
        self.counts.par_iter().for_each(|c| c.store(0, Relaxed));
        let counts = &self.counts;
        bases
            .par_chunks(chunk)
            .zip(self.keys.par_chunks_mut(chunk))
            .for_each(|(b, keys)| {
                let (mut last, mut g, mut run) = (None, 0usize, 0u32);
                for (&x, key) in b.iter().zip(keys.iter_mut()) {
                    let block = block_of(x);
                    if last != Some(block) {
                        if run > 0 {
                            counts[g].fetch_add(run, Relaxed);
                        }
                        (g, run, last) = (find(codes, block_code(block)), 0, Some(block));
                    }
                    run += 1;
                    *key = g as u32 * BLOCK_NODES as u32 + cell_code(x.x, x.y, x.z) as u32;
                }
                if run > 0 {
                    counts[g].fetch_add(run, Relaxed);
                }
            });
        // Start of each gblock's range; the counters become the next free slot.
        self.particle_start.clear();
        self.particle_start.reserve(g_count + 1);
        let mut sum = 0u32;
        for c in counts.iter() {
            self.particle_start.push(sum);
            sum += c.swap(sum, Relaxed);
        }
        self.particle_start.push(sum);
    }

    /// Step 4 of a rebuild: scatter each particle into its gblock's range (in an order that
    /// depends on timing), then sort every range by (cell, tie): a total order, so the result
    /// does not.
    fn order_particles(&mut self, chunk: usize, ids: Option<&[u32]>) {
        let (n, g_count) = (self.keys.len(), self.gblock_count);
        let counts = &self.counts;
        self.scratch.resize(n, 0);
        self.order.resize(n, 0);
        let keys = &self.keys;
        let scratch = SharedSlice::new(&mut self.scratch);
        keys.par_chunks(chunk).enumerate().for_each(|(c, ks)| {
            let first = c * chunk;
            let mut i = 0;
            while i < ks.len() {
                let g = ks[i] as usize / BLOCK_NODES;
                let mut j = i + 1;
                while j < ks.len() && ks[j] as usize / BLOCK_NODES == g {
                    j += 1;
                }
                let len = (j - i) as u32;
                let at = counts[g].fetch_add(len, Relaxed) as usize;
                // SAFETY: slots at..at+len were claimed by this thread alone (atomic counter,
                // bounded by the gblock's count, so inside the array).
                let out = unsafe { scratch.range(at, at + len as usize) };
                for (k, o) in out.iter_mut().enumerate() {
                    *o = (first + i + k) as u32;
                }
                i = j;
            }
        });
        let starts = &self.particle_start;
        let scattered = &self.scratch;
        let order = SharedSlice::new(&mut self.order);
        (0..g_count).into_par_iter().for_each(|g| {
            let (s, e) = (starts[g] as usize, starts[g + 1] as usize);
            // SAFETY: gblock ranges are disjoint; each is written by one task.
            let out = unsafe { order.range(s, e) };
            sort_by_cell(&scattered[s..e], out, keys, ids);
        });
    }

    /// After the caller has stored the particles in `order` (particle `order[i]` moved to slot
    /// `i`), renumber the layout accordingly: `order` becomes the identity.
    pub fn adopt_order(&mut self) {
        let (order, keys) = (&self.order, &self.keys);
        order
            .par_iter()
            .map(|&p| keys[p as usize])
            .collect_into_vec(&mut self.scratch);
        std::mem::swap(&mut self.keys, &mut self.scratch);
        self.order
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, o)| *o = i as u32);
    }

    /// Particles of gblock `g`.
    #[inline]
    pub fn particles_of(&self, g: usize) -> &[u32] {
        &self.order[self.particle_start[g] as usize..self.particle_start[g + 1] as usize]
    }

    /// gblock of particle `p` (as stored when the layout was last built or adopted).
    #[inline]
    pub fn gblock_of(&self, p: usize) -> usize {
        self.keys[p] as usize / BLOCK_NODES
    }

    /// Memory indices of the 3x3x3 stencil starting at node `base`, for a particle of gblock `g`
    /// (so `base` lies in block `g`), in the order `i * 9 + j * 3 + k`. Same result as
    /// [`BlockLayout::node_index`] per node: the stencil reaches blocks `g` and `g + 1` per axis
    /// only, so 8 neighbour ids are read, and the block/cell split is done once per axis.
    #[inline]
    pub fn stencil_nodes(&self, g: usize, base: IVec3) -> [u32; 27] {
        let r = base - (self.block_coords[g] << BLOCK_BITS);
        debug_assert!(
            r.min_element() >= 0 && r.max_element() < 4,
            "base {base} outside gblock {g}"
        );
        // Per axis and stencil node: block step (0 or 1) and cell-code contribution.
        let axis = |r: i32, cell_shift: i32| -> [(usize, u32); 3] {
            std::array::from_fn(|n| {
                let rn = r + n as i32;
                (
                    ((rn >> BLOCK_BITS) & 1) as usize,
                    ((rn & 3) << cell_shift) as u32,
                )
            })
        };
        let (ax, ay, az) = (axis(r.x, 4), axis(r.y, 2), axis(r.z, 0));
        let nb = &self.neighbors[g];
        // First node of the 8 blocks (+0 or +1 per axis): neighbour slot (1 + step) per axis.
        let first: [u32; 8] = std::array::from_fn(|b| {
            let slot = neighbor_slot((b >> 2) as i32, (b >> 1 & 1) as i32, (b & 1) as i32);
            nb[slot] * BLOCK_NODES as u32
        });
        let mut out = [0u32; 27];
        for (i, &(bx, cx)) in ax.iter().enumerate() {
            for (j, &(by, cy)) in ay.iter().enumerate() {
                for (k, &(bz, cz)) in az.iter().enumerate() {
                    out[i * 9 + j * 3 + k] = first[bx << 2 | by << 1 | bz] + (cx | cy | cz);
                }
            }
        }
        out
    }

    /// Memory index of node `node` for a particle of gblock `g` (the node must lie in the
    /// gblock's 3x3x3 neighbourhood).
    #[inline]
    pub fn node_index(&self, g: usize, node: IVec3) -> usize {
        let rel = IVec3::new(
            node.x >> BLOCK_BITS,
            node.y >> BLOCK_BITS,
            node.z >> BLOCK_BITS,
        ) - self.block_coords[g];
        let id = self.neighbors[g][neighbor_slot(rel.x, rel.y, rel.z)];
        id as usize * BLOCK_NODES + cell_code(node.x, node.y, node.z)
    }
}

/// Block coordinates of a node.
#[inline]
pub fn block_of(node: IVec3) -> [u32; 3] {
    [
        (node.x >> BLOCK_BITS) as u32,
        (node.y >> BLOCK_BITS) as u32,
        (node.z >> BLOCK_BITS) as u32,
    ]
}

/// Block coordinates of a block code.
#[inline]
fn decode(code: u64) -> IVec3 {
    let c = super::codes::decode_block(code);
    IVec3::new(c[0] as i32, c[1] as i32, c[2] as i32)
}

/// Call `f(slot, code)` for the 27 blocks of the 3x3x3 neighbourhood of block `bc`.
#[inline]
fn for_each_neighbor(bc: IVec3, mut f: impl FnMut(usize, u64)) {
    for di in -1..=1 {
        for dj in -1..=1 {
            for dk in -1..=1 {
                let nb = bc + IVec3::new(di, dj, dk);
                let code = block_code([nb.x as u32, nb.y as u32, nb.z as u32]);
                f(neighbor_slot(di, dj, dk), code);
            }
        }
    }
}

/// Write the particles `src` of one gblock into `out`, sorted by cell code, then by tie (`ids`
/// of the particles, else their index): a counting sort by cell, then a sort of each cell.
fn sort_by_cell(src: &[u32], out: &mut [u32], keys: &[u32], ids: Option<&[u32]>) {
    let cell = |p: u32| keys[p as usize] as usize % BLOCK_NODES;
    let mut start = [0u32; BLOCK_NODES + 1];
    for &p in src {
        start[cell(p) + 1] += 1;
    }
    for c in 0..BLOCK_NODES {
        start[c + 1] += start[c];
    }
    let mut next = start;
    for &p in src {
        let c = cell(p);
        out[next[c] as usize] = p;
        next[c] += 1;
    }
    let tie = |p: u32| ids.map_or(p, |ids| ids[p as usize]);
    for c in 0..BLOCK_NODES {
        let bucket = &mut out[start[c] as usize..start[c + 1] as usize];
        if bucket.len() > 24 {
            bucket.sort_unstable_by_key(|&p| tie(p));
            continue;
        }
        // A few particles per cell, usually already in order: insertion sort.
        for i in 1..bucket.len() {
            let mut j = i;
            while j > 0 && tie(bucket[j - 1]) > tie(bucket[j]) {
                bucket.swap(j - 1, j);
                j -= 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_groups_and_sorts_particles() {
        let bases = vec![
            IVec3::new(9, 4, 4), // block (2,1,1)
            IVec3::new(4, 4, 4), // block (1,1,1), cell 0
            IVec3::new(7, 7, 7), // block (1,1,1), cell 63
            IVec3::new(4, 4, 4), // block (1,1,1), cell 0, later index
        ];
        let mut l = BlockLayout::default();
        l.rebuild(&bases);
        assert_eq!(l.gblock_count, 2);
        // gblock 0 has the smaller code: (1,1,1) < (2,1,1).
        assert_eq!(l.block_coords[0], IVec3::new(1, 1, 1));
        assert_eq!(l.particles_of(0), &[1, 3, 2]);
        assert_eq!(l.particles_of(1), &[0]);
        // Neighbours: the union of two adjacent 3x3x3 neighbourhoods = 4*3*3 blocks.
        assert_eq!(l.pblock_count(), 36);
        for g in 0..2 {
            for di in -1..=1 {
                for dj in -1..=1 {
                    for dk in -1..=1 {
                        let id = l.neighbors[g][neighbor_slot(di, dj, dk)] as usize;
                        assert_eq!(
                            l.block_coords[id],
                            l.block_coords[g] + IVec3::new(di, dj, dk)
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn stencil_nodes_match_node_index() {
        let bases: Vec<IVec3> = (0..60)
            .map(|i| IVec3::new(4 + i % 11, 5 + i % 7, 6 + i % 13))
            .collect();
        let mut l = BlockLayout::default();
        l.rebuild(&bases);
        for g in 0..l.gblock_count {
            for &p in l.particles_of(g) {
                let b = bases[p as usize];
                let s = l.stencil_nodes(g, b);
                for i in 0..3 {
                    for j in 0..3 {
                        for k in 0..3 {
                            let n = b + IVec3::new(i, j, k);
                            assert_eq!(
                                s[(i * 9 + j * 3 + k) as usize] as usize,
                                l.node_index(g, n)
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn node_index_is_unique_per_node() {
        let bases: Vec<IVec3> = (0..40)
            .map(|i| IVec3::new(4 + i % 9, 5 + i % 7, 6 + i % 5))
            .collect();
        let mut l = BlockLayout::default();
        l.rebuild(&bases);
        let mut seen = std::collections::HashMap::new();
        for g in 0..l.gblock_count {
            for &p in l.particles_of(g) {
                let b = bases[p as usize];
                for n in [b, b + IVec3::splat(2), b + IVec3::new(2, 0, 1)] {
                    let idx = l.node_index(g, n);
                    if let Some(prev) = seen.insert(idx, n) {
                        assert_eq!(prev, n, "two nodes share memory slot {idx}");
                    }
                }
            }
        }
    }

    /// Pseudo-random stencil bases in a box of 6 blocks per axis, many per cell.
    fn random_bases(n: usize, salt: u32) -> Vec<IVec3> {
        (0..n as u32)
            .map(|i| {
                let mut x = i.wrapping_mul(0x9E37_79B9) ^ salt.wrapping_mul(0x85EB_CA6B);
                let mut next = || {
                    x ^= x >> 15;
                    x = x.wrapping_mul(0x2C1B_3C6D);
                    x ^= x >> 12;
                    4 + (x % 24) as i32
                };
                IVec3::new(next(), next(), next())
            })
            .collect()
    }

    #[test]
    fn parallel_rebuild_matches_a_plain_sort_whatever_the_threads() {
        // More particles than one chunk, so that the passes really split.
        let n = 40_000;
        let bases = random_bases(n, 7);
        // Ties by ids: a permutation (reversed index), not the storage index.
        let ids: Vec<u32> = (0..n as u32).rev().collect();
        let key = |p: usize, tie: u32| {
            let b = bases[p];
            (block_code(block_of(b)), cell_code(b.x, b.y, b.z), tie)
        };
        for with_ids in [false, true] {
            let mut want: Vec<u32> = (0..n as u32).collect();
            want.sort_by_key(|&p| key(p as usize, if with_ids { ids[p as usize] } else { p }));
            let mut first: Option<BlockLayout> = None;
            for threads in [1, 3, 8] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .expect("pool");
                let mut l = BlockLayout::default();
                // Twice: the second rebuild reuses the containers of the first.
                for _ in 0..2 {
                    pool.install(|| l.rebuild_with_ties(&bases, with_ids.then_some(&ids[..])));
                }
                assert_eq!(l.order, want, "{threads} threads, ids {with_ids}");
                for g in 0..l.gblock_count {
                    for &p in l.particles_of(g) {
                        assert_eq!(block_of(bases[p as usize]), {
                            let c = l.block_coords[g];
                            [c.x as u32, c.y as u32, c.z as u32]
                        });
                        assert_eq!(l.gblock_of(p as usize), g);
                    }
                }
                if let Some(f) = &first {
                    assert_eq!(f.block_coords, l.block_coords, "{threads} threads");
                    assert_eq!(f.neighbors, l.neighbors, "{threads} threads");
                    assert_eq!(f.particle_start, l.particle_start, "{threads} threads");
                } else {
                    first = Some(l);
                }
            }
        }
    }
}

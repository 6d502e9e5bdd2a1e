//! Block layout: hash from block code to dense id, gblocks, pblocks and neighbour lists, and the
//! particle order (particles sorted by block, then by cell).

use super::codes::{BLOCK_BITS, BLOCK_NODES, block_code, cell_code, neighbor_slot};
use crate::math::IVec3;
use rustc_hash::FxHashMap;

/// The sparse block structure for one particle configuration.
///
/// Ids `0..gblock_count` are the gblocks (blocks holding particles), sorted by block code;
/// the remaining ids are their neighbours, in order of first appearance. Every container is
/// reused from one rebuild to the next (no reallocation once sizes settle).
#[derive(Default, Debug, Clone)]
pub struct BlockLayout {
    /// Block code -> dense pblock id.
    pub map: FxHashMap<u64, u32>,
    /// Block coordinates of each pblock (in blocks).
    pub block_coords: Vec<IVec3>,
    /// Number of gblocks.
    pub gblock_count: usize,
    /// For each gblock, the ids of its 3x3x3 neighbour pblocks, see [`neighbor_slot`].
    pub neighbors: Vec<[u32; 27]>,
    /// Particle indices sorted by (gblock, cell code, particle index).
    pub order: Vec<u32>,
    /// `order[particle_start[g]..particle_start[g + 1]]` are the particles of gblock `g`.
    pub particle_start: Vec<u32>,
    codes: Vec<u64>,
    keys: Vec<u32>,
    scratch: Vec<u32>,
    counts: Vec<u32>,
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
        // 1. gblocks: the distinct blocks of the base nodes, sorted by block code.
        self.map.clear();
        self.codes.clear();
        let mut last = u64::MAX;
        for b in bases {
            let code = block_code(block_of(*b));
            if code != last && !self.map.contains_key(&code) {
                self.map.insert(code, 0);
                self.codes.push(code);
            }
            last = code;
        }
        self.codes.sort_unstable();
        self.gblock_count = self.codes.len();
        self.block_coords.clear();
        for (id, &code) in self.codes.iter().enumerate() {
            self.map.insert(code, id as u32);
            let c = super::codes::decode_block(code);
            self.block_coords
                .push(IVec3::new(c[0] as i32, c[1] as i32, c[2] as i32));
        }

        // 2. pblocks: every gblock's 3x3x3 neighbours, with explicit neighbour lists.
        self.neighbors.clear();
        for g in 0..self.gblock_count {
            let bc = self.block_coords[g];
            let mut list = [0u32; 27];
            for di in -1..=1 {
                for dj in -1..=1 {
                    for dk in -1..=1 {
                        let nb = bc + IVec3::new(di, dj, dk);
                        let code = block_code([nb.x as u32, nb.y as u32, nb.z as u32]);
                        let next = self.block_coords.len() as u32;
                        let id = *self.map.entry(code).or_insert(next);
                        if id == next {
                            self.block_coords.push(nb);
                        }
                        list[neighbor_slot(di, dj, dk)] = id;
                    }
                }
            }
            self.neighbors.push(list);
        }

        // 3. Counting sort of the particles by (gblock, cell code); stable in particle index.
        let buckets = self.gblock_count * BLOCK_NODES;
        self.keys.clear();
        self.keys.reserve(bases.len());
        let mut last_code = u64::MAX;
        let mut last_id = 0u32;
        for b in bases {
            let code = block_code(block_of(*b));
            if code != last_code {
                last_id = self.map[&code];
                last_code = code;
            }
            self.keys
                .push(last_id * BLOCK_NODES as u32 + cell_code(b.x, b.y, b.z) as u32);
        }
        self.counts.clear();
        self.counts.resize(buckets + 1, 0);
        for &k in &self.keys {
            self.counts[k as usize + 1] += 1;
        }
        for i in 0..buckets {
            self.counts[i + 1] += self.counts[i];
        }
        self.particle_start.clear();
        self.particle_start
            .extend((0..=self.gblock_count).map(|g| self.counts[g * BLOCK_NODES]));
        self.order.clear();
        self.order.resize(bases.len(), 0);
        for (p, &k) in self.keys.iter().enumerate() {
            let slot = &mut self.counts[k as usize];
            self.order[*slot as usize] = p as u32;
            *slot += 1;
        }
        if let Some(ids) = ids {
            // counts[k] is now the end of bucket k. Buckets (cells) hold a few particles: insertion sort.
            let mut start = 0usize;
            for k in 0..buckets {
                let end = self.counts[k] as usize;
                let bucket = &mut self.order[start..end];
                for i in 1..bucket.len() {
                    let mut j = i;
                    while j > 0 && ids[bucket[j - 1] as usize] > ids[bucket[j] as usize] {
                        bucket.swap(j - 1, j);
                        j -= 1;
                    }
                }
                start = end;
            }
        }
    }

    /// After the caller has stored the particles in `order` (particle `order[i]` moved to slot
    /// `i`), renumber the layout accordingly: `order` becomes the identity.
    pub fn adopt_order(&mut self) {
        self.scratch.clear();
        self.scratch
            .extend(self.order.iter().map(|&p| self.keys[p as usize]));
        std::mem::swap(&mut self.keys, &mut self.scratch);
        for (i, o) in self.order.iter_mut().enumerate() {
            *o = i as u32;
        }
    }

    /// Particles of gblock `g`.
    #[inline]
    pub fn particles_of(&self, g: usize) -> &[u32] {
        &self.order[self.particle_start[g] as usize..self.particle_start[g + 1] as usize]
    }

    /// gblock of particle `p` (as sorted by the last rebuild).
    #[inline]
    pub fn gblock_of(&self, p: usize) -> usize {
        self.keys[p] as usize / BLOCK_NODES
    }

    /// Memory indices of the 3x3x3 stencil starting at node `base`, for a particle of gblock `g`,
    /// in the order `i * 9 + j * 3 + k`. Same result as [`BlockLayout::node_index`] per node, with
    /// the block/cell split done once per axis.
    #[inline]
    pub fn stencil_nodes(&self, g: usize, base: IVec3) -> [u32; 27] {
        let corner = self.block_coords[g] << BLOCK_BITS;
        let r = base - corner;
        // Per axis and stencil node: neighbour-slot contribution and cell-code contribution.
        let axis = |r: i32, slot_stride: i32, cell_shift: i32| -> [(i32, u32); 3] {
            std::array::from_fn(|n| {
                let rn = r + n as i32;
                (
                    ((rn >> BLOCK_BITS) + 1) * slot_stride,
                    ((rn & 3) << cell_shift) as u32,
                )
            })
        };
        let (ax, ay, az) = (axis(r.x, 9, 4), axis(r.y, 3, 2), axis(r.z, 1, 0));
        let nb = &self.neighbors[g];
        let mut out = [0u32; 27];
        for (i, &(sx, cx)) in ax.iter().enumerate() {
            for (j, &(sy, cy)) in ay.iter().enumerate() {
                for (k, &(sz, cz)) in az.iter().enumerate() {
                    let id = nb[(sx + sy + sz) as usize];
                    out[i * 9 + j * 3 + k] = id * BLOCK_NODES as u32 + (cx | cy | cz);
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
}

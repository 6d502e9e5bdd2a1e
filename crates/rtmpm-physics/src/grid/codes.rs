//! 64-bit node codes: interleaved block code plus a 6-bit cell code.
//!
//! Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022): the code of node `(i, j, k)` is `(i20..i2, j20..j2, k20..k2)` followed by
//! `(i1, i0, j1, j0, k1, k0)`. We interleave the block bits (Morton order) so that sorting by code
//! also sorts blocks along a space-filling curve: block coordinates may use 19 bits per axis.

/// Nodes per block edge.
pub const BLOCK_SIZE: i32 = 4;
/// log2 of [`BLOCK_SIZE`].
pub const BLOCK_BITS: i32 = 2;
/// Nodes per block.
pub const BLOCK_NODES: usize = 64;
/// Bits per axis of a block coordinate.
pub const BLOCK_COORD_BITS: u32 = 19;

/// Spread the low 19 bits of `v` so that bit `n` moves to bit `3n`.
#[inline]
fn spread3(v: u32) -> u64 {
    let mut x = (v as u64) & 0x7_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// Inverse of [`spread3`].
#[inline]
fn compact3(code: u64) -> u32 {
    let mut x = code & 0x1249_2492_4924_9249;
    x = (x | (x >> 2)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x >> 4)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x >> 8)) & 0x001f_0000_ff00_00ff;
    x = (x | (x >> 16)) & 0x001f_0000_0000_ffff;
    x = (x | (x >> 32)) & 0x7_ffff;
    x as u32
}

/// Block code of block coordinates `(bi, bj, bk)` (each < 2^19): bits `... bi_n bj_n bk_n ...`.
#[inline]
pub fn block_code(b: [u32; 3]) -> u64 {
    (spread3(b[0]) << 2) | (spread3(b[1]) << 1) | spread3(b[2])
}

/// Block coordinates of a block code.
#[inline]
pub fn decode_block(code: u64) -> [u32; 3] {
    [compact3(code >> 2), compact3(code >> 1), compact3(code)]
}

/// Cell code `(i1 i0 j1 j0 k1 k0)` of a node inside its block: also its slot in the block's 64 nodes.
#[inline]
pub fn cell_code(i: i32, j: i32, k: i32) -> usize {
    (((i & 3) << 4) | ((j & 3) << 2) | (k & 3)) as usize
}

/// Full 64-bit code of node `(i, j, k)` (non-negative grid indices).
#[inline]
pub fn node_code(i: i32, j: i32, k: i32) -> u64 {
    let b = [
        (i >> BLOCK_BITS) as u32,
        (j >> BLOCK_BITS) as u32,
        (k >> BLOCK_BITS) as u32,
    ];
    (block_code(b) << 6) | cell_code(i, j, k) as u64
}

/// Index `0..27` of neighbour offset `(di, dj, dk)` in `{-1, 0, 1}^3`.
#[inline]
pub fn neighbor_slot(di: i32, dj: i32, dk: i32) -> usize {
    ((di + 1) * 9 + (dj + 1) * 3 + (dk + 1)) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_code_round_trips() {
        for b in [
            [0, 0, 0],
            [1, 2, 3],
            [524_287, 0, 17],
            [12345, 54321, 99999],
            [524_287; 3],
        ] {
            assert_eq!(decode_block(block_code(b)), b);
        }
    }

    #[test]
    fn codes_interleave_i_highest() {
        assert_eq!(block_code([1, 0, 0]), 0b100);
        assert_eq!(block_code([0, 1, 0]), 0b010);
        assert_eq!(block_code([0, 0, 1]), 0b001);
        assert_eq!(block_code([2, 0, 0]), 0b100_000);
        // Node (5, 2, 7): block (1, 0, 1), cell (1, 2, 3) -> (01 10 11).
        assert_eq!(node_code(5, 2, 7), (0b101 << 6) | 0b01_10_11);
    }

    #[test]
    fn nodes_of_one_block_share_the_block_code() {
        let c = node_code(8, 12, 4) >> 6;
        for i in 8..12 {
            for j in 12..16 {
                for k in 4..8 {
                    assert_eq!(node_code(i, j, k) >> 6, c);
                }
            }
        }
        let mut seen = [false; 64];
        for i in 0..4 {
            for j in 0..4 {
                for k in 0..4 {
                    seen[cell_code(i, j, k)] = true;
                }
            }
        }
        assert!(seen.iter().all(|&s| s), "cell codes cover 0..64 exactly");
    }
}

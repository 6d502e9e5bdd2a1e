// The node addressing of a particle's 3x3x3 stencil in the block layout (pblocks of 4x4x4 nodes,
// memory index pblock id * 64 + cell; a gblock's 27 neighbour pblock ids in `neighbors`), for
// every P2G and G2P variant. Plain integer code with no other dependency, so that
// scripts/stencil_twin.cpp compiles it for the CPU and checks the variants against each other.
#pragma once

// Node addressing of one particle's 3x3x3 stencil, split per axis once (rtmpm_physics's
// BlockLayout::stencil_nodes): node (i, j, k) lives at
// neighbors[27 g + slot[0][i] + slot[1][j] + slot[2][k]] * 64 + (cell[0][i] | cell[1][j] | cell[2][k]).
struct StencilIdx { int slot[3][3]; unsigned cell[3][3]; };
__device__ __forceinline__ StencilIdx stencil_idx(const int* bc, const int base[3]) {
    StencilIdx s;
    const int stride[3] = {9, 3, 1}, shift[3] = {4, 2, 0};
    for (int a = 0; a < 3; ++a)
        for (int n = 0; n < 3; ++n) {
            int r = base[a] + n - 4 * bc[a];
            s.slot[a][n] = ((r >> 2) + 1) * stride[a];
            s.cell[a][n] = (unsigned)(r & 3) << shift[a];
        }
    return s;
}

// The same addressing with the pblocks loaded once (RTMPM_G2P_GATHER, RTMPM_P2G_NODES): along each
// axis a particle's three stencil nodes lie in at most two consecutive neighbour slots, so its
// 27 nodes lie in at most eight pblocks. Their ids are read from the gblock's neighbour list at
// eight fixed offsets from one address (instead of one computed address and load per node), and
// node n of axis a takes the pair's second block when hi[a][n]: node (i, j, k) lives at
// id[4 hi[0][i] + 2 hi[1][j] + hi[2][k]] * 64 + (cell[0][i] | cell[1][j] | cell[2][k]).
// When the stencil starts in the last slot of an axis (base - 4 bc >= 4, allowed by the free
// zone) the pair is taken one slot back, so that every load stays in the list.
struct StencilBlocks {
    unsigned id[8];
    unsigned cell[3][3];
    bool hi[3][3];
};
__device__ __forceinline__ StencilBlocks stencil_blocks(const unsigned* nbs, const int* bc, const int base[3]) {
    StencilBlocks s;
    const int stride[3] = {9, 3, 1}, shift[3] = {4, 2, 0};
    int first = 0;
#pragma unroll
    for (int a = 0; a < 3; ++a) {
        int r = base[a] - 4 * bc[a];   // the stencil's first node from the gblock's origin
        int p = min((r >> 2) + 1, 1);  // the pair's first neighbour slot along a (0 or 1)
        first += p * stride[a];
#pragma unroll
        for (int n = 0; n < 3; ++n) {
            s.hi[a][n] = ((r + n) >> 2) + 1 != p;
            s.cell[a][n] = (unsigned)((r + n) & 3) << shift[a];
        }
    }
    const unsigned* q = nbs + first;
#pragma unroll
    for (int t = 0; t < 8; ++t) s.id[t] = q[9 * (t >> 2) + 3 * ((t >> 1) & 1) + (t & 1)];
    return s;
}
// The two pblocks (z pair) of stencil row (i, j): row[0] and row[1].
__device__ __forceinline__ void stencil_row_blocks(const StencilBlocks& s, bool hi_i, bool hi_j, unsigned row[2]) {
    unsigned y0 = hi_i ? s.id[4] : s.id[0], y0z1 = hi_i ? s.id[5] : s.id[1];
    unsigned y1 = hi_i ? s.id[6] : s.id[2], y1z1 = hi_i ? s.id[7] : s.id[3];
    row[0] = hi_j ? y1 : y0;
    row[1] = hi_j ? y1z1 : y0z1;
}

// Pair addressing (RTMPM_G2P_GATHER 2, RTMPM_P2G_NODES 2): the eight pblocks of stencil_blocks
// and, per axis, the stencil's first node counted from the start of its pair, r in 0..5 (node n
// of the axis is in the pair's second block iff r + n >= 4, at cell (r + n) & 3). Along z the
// pair is taken one block on when every node is in its second block (r >= 4): then the even ids
// are the odd ones and r is 0..3, so that node k of a row is in the row's first block at
// k < 4 - r and in its second one from there. A row's three nodes then lie at memory indices
// n + k (stencil_pair_row): the node index arithmetic and the selects are per row, not per node,
// and the k offsets become the loads' and atomics' immediate offsets. Same nodes as
// stencil_blocks, bit for bit the same sums.
struct StencilPairs {
    unsigned id[8];
    int r[3];
};
__device__ __forceinline__ StencilPairs stencil_pairs(const unsigned* nbs, const int* bc, const int base[3]) {
    StencilPairs s;
    const int stride[3] = {9, 3, 1};
    int first = 0;
#pragma unroll
    for (int a = 0; a < 3; ++a) {
        int r = base[a] - 4 * bc[a];   // the stencil's first node from the gblock's origin
        int p = min((r >> 2) + 1, 1);  // the pair's first neighbour slot along a (0 or 1)
        first += p * stride[a];
        s.r[a] = r + 4 - 4 * p;
    }
    const unsigned* q = nbs + first;
#pragma unroll
    for (int t = 0; t < 8; ++t) s.id[t] = q[9 * (t >> 2) + 3 * ((t >> 1) & 1) + (t & 1)];
    bool z_second = s.r[2] >= 4;
#pragma unroll
    for (int t = 0; t < 8; t += 2) s.id[t] = z_second ? s.id[t + 1] : s.id[t];
    s.r[2] &= 3;
    return s;
}
// The four pblocks (y, z pairs) of the x plane i whose node is in the x pair's second block iff hi_x.
__device__ __forceinline__ void stencil_pair_plane(const StencilPairs& s, bool hi_x, unsigned plane[4]) {
#pragma unroll
    for (int t = 0; t < 4; ++t) plane[t] = hi_x ? s.id[4 + t] : s.id[t];
}
// Row (i, j) of a plane: node k of the row lies at memory index (pblock id * 64 + cell) n[k] + k.
// `hi_y`: the row's y node is in the y pair's second block; `cell_xy`: its cell bits of x and y.
// The indices are signed: n[k] is below the row's first node when node k is in the second
// block (by at most 4 - k, so n[k] + k >= 0), and a pblock id * 64 + cell fits in 31 bits.
struct PairRow {
    int n[3];
};
__device__ __forceinline__ PairRow stencil_pair_row(const StencilPairs& s, const unsigned plane[4], bool hi_y, unsigned cell_xy) {
    unsigned first = hi_y ? plane[2] : plane[0], second = hi_y ? plane[3] : plane[1];
    int cell = (int)cell_xy + s.r[2];
    int n_first = (int)(first * 64u) + cell, n_second = (int)(second * 64u) + cell - 4;
    PairRow row;
    row.n[0] = n_first;
    row.n[1] = s.r[2] >= 3 ? n_second : n_first;
    row.n[2] = s.r[2] >= 2 ? n_second : n_first;
    return row;
}

// The stencil base whose nodes the warp scatter addresses for a lane (RTMPM_P2G_NODES 1 and 2
// read a row's pblock ids for every lane, its atomics only by segment heads): its particle's
// base when the lane scatters, else the gblock's own first node (base - 4 bc = 0 on each axis),
// so that the neighbour-list reads of a lane that does not scatter stay in the gblock's 27
// entries. Such a lane's base is whatever it was given (0 from p2g_particle_zero and with
// RTMPM_G2P2G_LEAN_LANES): with base 0 and a gblock away from the origin the reads fell in other
// gblocks' entries (never used: such a lane is no head). The same sums: only heads add.
// scripts/stencil_twin.cpp checks that the reads stay in the 27 entries.
__device__ __forceinline__ void scatter_base(const int* bc, const int base[3], bool active, int out[3]) {
#pragma unroll
    for (int a = 0; a < 3; ++a) out[a] = active ? base[a] : 4 * bc[a];
}

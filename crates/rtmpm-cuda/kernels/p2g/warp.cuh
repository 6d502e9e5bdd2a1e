// The warp scatter of Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022), shared by the P2G kernel (p2g.cu) and the fused G2P2G
// (g2p2g.cu): the cheap in-warp cell sort of mixed sorting, the segmented warp reduction of lanes
// that write the same nodes (Gao et al. 2018) and direct global atomics by segment heads.
#pragma once
#include "particle.cuh"

// The shuffle rounds of the segmented reduction (compile-time, default 1): 0 a loop up to the
// warp's longest segment; 1 the five possible rounds unrolled, each skipped past that length. Same
// arithmetic in the same order; unrolled, ptxas keeps the 12 values of a row in place instead of
// copying them back for the next trip (12 moves a round). Measured (bench/RESULTS.md): 1 is 5-8 %
// faster than 0 on the claymore scenes on the H100 and the H200; the GPU tests and the whole
// validation pass with it (and with RTMPM_G2P_GATHER=1, RTMPM_P2G_NODES=1) on the H200.
//
// 4: the rounds' count fixed per warp: one copy of the row loop per count (0 to 5), picked by a
// warp-uniform switch, its rounds unrolled with no test or divergence check between them.
#ifndef RTMPM_P2G_REDUCE
#define RTMPM_P2G_REDUCE 1
#endif
// At most 2^RTMPM_P2G_ROUNDS_MAX lanes summed by shuffles (default 5: a whole warp): a longer
// segment is cut into pieces of that length whose first lanes each issue the atomics. Fewer
// shuffle rounds for more atomics; the same sums in another order.
#ifndef RTMPM_P2G_ROUNDS_MAX
#define RTMPM_P2G_ROUNDS_MAX 5
#endif
// Node addresses of the scatter (compile-time, default 2): 0 each node's pblock id read from
// the neighbour list at a computed address; 1 the stencil's eight pblocks read once
// (stencil_blocks in stencil.cuh) and each node's id picked from them; 2 the pair addressing
// (stencil_pairs: the row's node indices once, the node's offset in the atomic's immediate
// offset; the same nodes as 1, a row's head block 25 instructions instead of 40 in ptxas 13.0).
// The CUDA option `addressing=blocks` compiles 1 (compile.rs).
#ifndef RTMPM_P2G_NODES
#define RTMPM_P2G_NODES 2
#endif
// 1: the nine rows unrolled (compile-time i, j: no selects of the row's weights, pblocks and
// cells; a larger kernel); 2: the three rows of a plane unrolled (compile-time j).
#ifndef RTMPM_P2G_UNROLL
#define RTMPM_P2G_UNROLL 0
#endif

// The reduction's bookkeeping (compile-time, default 0; the CUDA option `seg_clamp=on`): each
// round's shuffle of a row's first value clamped to this lane's segment (its last lane given as
// the shuffle's clamp operand), so that the shuffle's own in-range predicate says whether the value
// comes from the same segment, instead of a comparison of the round with the segment length in
// every round of every row. The same additions in the same order.
#ifndef RTMPM_P2G_SEG_CLAMP
#define RTMPM_P2G_SEG_CLAMP 0
#endif
#if RTMPM_P2G_SEG_CLAMP
// The value `s` lanes down (all lanes of the warp call it) and whether that lane is at most lane
// `last` (PTX shfl.sync.down with clamp `last`, no sub-segments: in range iff lane + s <= last).
__device__ __forceinline__ float shfl_down_clamped(float v, unsigned s, unsigned last, bool* in_range) {
    float o;
    unsigned in;
    asm("{\n\t.reg .pred p;\n\tshfl.sync.down.b32 %0|p, %2, %3, %4, 0xffffffff;\n\tselp.u32 %1, 1, 0, p;\n\t}"
        : "=f"(o), "=r"(in)
        : "f"(v), "r"(s), "r"(last));
    *in_range = in != 0;
    return o;
}
__device__ __forceinline__ double shfl_down_clamped(double v, unsigned s, unsigned last, bool* in_range) {
    float lo = shfl_down_clamped(__int_as_float(__double2loint(v)), s, last, in_range);
    int hi = __shfl_down_sync(0xffffffffu, __double2hiint(v), s);
    return __hiloint2double(hi, __float_as_int(lo));
}
#endif

// Add (mass, momentum) to a node: one 16-byte vector atomic on sm_90 (f32), else four.
__device__ __forceinline__ void atomic_add_node(real* node, const real val[4]) {
#if !defined(RTMPM_F64) && defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 900
    atomicAdd(reinterpret_cast<float4*>(node), make_float4(val[0], val[1], val[2], val[3]));
#else
    for (int q = 0; q < 4; ++q) atomicAdd(node + q, val[q]);
#endif
}

// Mixed sorting, the cheap part (Fei et al.): the key of a particle for the in-warp sort is the
// neighbour slot of its stencil base's block and the base's cell code (lanes with equal keys
// write the same 27 nodes); P2G_KEY_NONE for inactive lanes (sorted last).
#define P2G_KEY_NONE 0xffffu
__device__ __forceinline__ unsigned p2g_sort_key(const Ctx& c, unsigned g, const int base[3]) {
    const int* bc = c.block_coords + 3 * g;
    return (unsigned)(nb_slot((base[0] >> 2) - bc[0], (base[1] >> 2) - bc[1], (base[2] >> 2) - bc[2]) << 6)
        | (unsigned)cell_code(base[0], base[1], base[2]);
}

// Bitonic sort of the 32 keys of the warp (via __shfl_xor_sync); returns the lane whose particle
// this lane takes, and whether that lane is active. Skipped when the warp is already in order
// (most warps between rebuilds). Every lane of the warp calls it.
__device__ __forceinline__ unsigned p2g_warp_sort(unsigned key, unsigned lane, bool* active) {
    unsigned kv = (key << 5) | lane;  // unique keys; payload = source lane
    unsigned prev = __shfl_up_sync(0xffffffffu, kv, 1);
    if (!__all_sync(0xffffffffu, lane == 0 || prev < kv)) {
        for (unsigned size = 2; size <= 32; size <<= 1) {
            for (unsigned stride = size >> 1; stride > 0; stride >>= 1) {
                unsigned other = __shfl_xor_sync(0xffffffffu, kv, stride);
                bool up = ((lane & size) == 0);
                bool lower = (lane & stride) == 0;
                unsigned lo = min(kv, other), hi = max(kv, other);
                kv = (lower == up) ? lo : hi;
            }
        }
    }
    *active = (kv >> 5) != P2G_KEY_NONE;
    return kv & 31u;
}

// Addresses of the stencil nodes of the scatter, per row (i, j): node k of the row lives at
// row_node(...) (memory index pblock id * 64 + cell).
struct ScatterNodes {
#if RTMPM_P2G_NODES == 2
    StencilPairs sp;
#elif RTMPM_P2G_NODES == 1
    StencilBlocks sb;
#else
    const unsigned* nbs;
    int r0, r1, r2;  // base - 4 bc: the node offset from the gblock origin (r >> 2: its neighbour block)
#endif
};
__device__ __forceinline__ ScatterNodes scatter_nodes(const Ctx& c, unsigned g, const int base[3]) {
    ScatterNodes s;
    const int* bc = c.block_coords + 3 * g;
#if RTMPM_P2G_NODES == 2
    s.sp = stencil_pairs(c.neighbors + 27 * g, bc, base);
#elif RTMPM_P2G_NODES == 1
    s.sb = stencil_blocks(c.neighbors + 27 * g, bc, base);
#else
    s.r0 = base[0] - 4 * bc[0];
    s.r1 = base[1] - 4 * bc[1];
    s.r2 = base[2] - 4 * bc[2];
    s.nbs = c.neighbors + 27 * g;
#endif
    return s;
}
// The row's part of the addresses: (slot, cell) of node (i, j, 0) as in stencil_idx, the row's
// two pblocks and cell bits, or (pair addressing) the row's node indices.
struct ScatterRow {
#if RTMPM_P2G_NODES == 2
    PairRow pr;
#elif RTMPM_P2G_NODES == 1
    unsigned id[2];
    unsigned cell;
#else
    int slot;
    unsigned cell;
#endif
};
__device__ __forceinline__ bool pick3b(const bool a[3], int i) { return i == 0 ? a[0] : (i == 1 ? a[1] : a[2]); }
__device__ __forceinline__ unsigned pick3u(const unsigned a[3], int i) { return i == 0 ? a[0] : (i == 1 ? a[1] : a[2]); }
__device__ __forceinline__ ScatterRow scatter_row(const ScatterNodes& s, int i, int j) {
    ScatterRow r;
#if RTMPM_P2G_NODES == 2
    int tx = s.sp.r[0] + i, ty = s.sp.r[1] + j;
    unsigned plane[4];
    stencil_pair_plane(s.sp, tx >= 4, plane);
    r.pr = stencil_pair_row(s.sp, plane, ty >= 4, ((unsigned)(tx & 3) << 4) | ((unsigned)(ty & 3) << 2));
#elif RTMPM_P2G_NODES == 1
    stencil_row_blocks(s.sb, pick3b(s.sb.hi[0], i), pick3b(s.sb.hi[1], j), r.id);
    r.cell = pick3u(s.sb.cell[0], i) | pick3u(s.sb.cell[1], j);
#else
    int ri = s.r0 + i, rj = s.r1 + j;
    r.slot = ((ri >> 2) + 1) * 9 + ((rj >> 2) + 1) * 3 + 1;
    r.cell = (unsigned)(((ri & 3) << 4) | ((rj & 3) << 2));
#endif
    return r;
}
#if RTMPM_P2G_NODES != 2
__device__ __forceinline__ unsigned scatter_node(const ScatterNodes& s, const ScatterRow& r, int k) {
#if RTMPM_P2G_NODES == 1
    return (s.sb.hi[2][k] ? r.id[1] : r.id[0]) * 64u + (r.cell | s.sb.cell[2][k]);
#else
    int rk = s.r2 + k;
    return s.nbs[r.slot + (rk >> 2)] * 64u + (r.cell | (unsigned)(rk & 3));
#endif
}
#endif
// The (mass, momentum) words of node k of the row in `grid`.
__device__ __forceinline__ real* scatter_node_words(real* grid, const ScatterNodes& s, const ScatterRow& r, int k) {
#if RTMPM_P2G_NODES == 2
    (void)s;
    return grid + 4ll * r.pr.n[k] + 4 * k;  // the k in the atomic's immediate offset
#else
    return grid + 4u * scatter_node(s, r, k);
#endif
}

// The 27 nodes row by row: row (i, j) holds nodes k = 0, 1, 2, whose 12 values are reduced
// together (one shuffle round serves three nodes), then added by the heads. ROUNDS >= 0: exactly
// that many rounds (RTMPM_P2G_REDUCE 4); -1: up to the longest segment (max_seg).
template <int ROUNDS>
__device__ __forceinline__ void p2g_scatter_rows(const ScatterNodes& nodes, const P2gParticle& q, unsigned seg_len,
                                                 unsigned max_seg, bool head, real* grid) {
#if RTMPM_P2G_UNROLL == 1
#pragma unroll
#endif
    for (int i = 0; i < 3; ++i)
#if RTMPM_P2G_UNROLL
#pragma unroll
#endif
        for (int j = 0; j < 3; ++j) {
            ScatterRow row = scatter_row(nodes, i, j);
            real w_ij = p2g_row_weight(q, i, j);
            vec3 mom_ij = p2g_row_momentum(q, i, j);
            real val[3][4];
#pragma unroll
            for (int k = 0; k < 3; ++k) p2g_row_node_value(q, w_ij, mom_ij, k, val[k]);
#if RTMPM_P2G_REDUCE == 1 || RTMPM_P2G_REDUCE == 4
#pragma unroll
            for (unsigned s = 1; s < (1u << RTMPM_P2G_ROUNDS_MAX); s <<= 1) {
                if (ROUNDS >= 0 ? s >= (1u << (ROUNDS < 0 ? 0 : ROUNDS)) : s > max_seg) break;
#else
            for (unsigned s = 1; s <= max_seg; s <<= 1) {
#endif
#if RTMPM_P2G_SEG_CLAMP
                // seg_len is the segment's last lane here (p2g_scatter_warp).
                bool take;
                real o0 = shfl_down_clamped(val[0][0], s, seg_len, &take);
#else
                bool take = s <= seg_len;
#endif
#pragma unroll
                for (int k = 0; k < 3; ++k)
#pragma unroll
                    for (int e = 0; e < 4; ++e) {
#if RTMPM_P2G_SEG_CLAMP
                        real o = k == 0 && e == 0 ? o0 : __shfl_down_sync(0xffffffffu, val[k][e], s);
#else
                        real o = __shfl_down_sync(0xffffffffu, val[k][e], s);
#endif
                        if (take) val[k][e] += o;
                    }
            }
            if (head) {
#pragma unroll
                for (int k = 0; k < 3; ++k) atomic_add_node(scatter_node_words(grid, nodes, row, k), val[k]);
            }
        }
}

// The segments of the warp's reduction: runs of adjacent active lanes with the same stencil base
// (after the sort, lanes with equal bases are adjacent). seg_len: the lanes after this one in its
// segment; max_seg: the longest seg_len of the warp (the shuffle rounds it needs); head: this
// lane issues the segment's atomics. Without the warp reduction every active lane is a head of
// a segment of one. Every lane of the warp calls it.
struct WarpSegments {
    unsigned seg_len, max_seg;
    bool head;
};
__device__ __forceinline__ WarpSegments warp_segments(const Ctx& c, const int base[3], bool active, unsigned lane) {
    unsigned seg_len = 0;
    bool head = active;
    if (c.warp_reduce) {
        int pb0 = __shfl_up_sync(0xffffffffu, base[0], 1);
        int pb1 = __shfl_up_sync(0xffffffffu, base[1], 1);
        int pb2 = __shfl_up_sync(0xffffffffu, base[2], 1);
        unsigned pact = __shfl_up_sync(0xffffffffu, (unsigned)active, 1);
        bool boundary = lane == 0 || !pact || !active || pb0 != base[0] || pb1 != base[1] || pb2 != base[2];
        unsigned mark = __ballot_sync(0xffffffffu, boundary);
        unsigned rest = lane < 31 ? (mark & ~((2u << lane) - 1u)) : 0u;
        unsigned end = rest ? (unsigned)(__ffs(rest) - 1) : 32u;
        seg_len = end - lane - 1;
        head = boundary && active;
#if RTMPM_P2G_ROUNDS_MAX < 5
        // Pieces of 2^RTMPM_P2G_ROUNDS_MAX lanes from the segment's start: their first lanes are heads.
        unsigned start = 31u - (unsigned)__clz(mark & ((2u << lane) - 1u));
        head = active && ((lane - start) & ((1u << RTMPM_P2G_ROUNDS_MAX) - 1u)) == 0;
#endif
    }
    // Reduction rounds needed: up to the longest segment of this warp.
    unsigned max_seg = c.warp_reduce ? __reduce_max_sync(0xffffffffu, seg_len) : 0u;
    WarpSegments s;
    s.seg_len = seg_len;
    s.max_seg = max_seg;
    s.head = head;
    return s;
}

// The scatter of one warp's particles (one per lane, in sorted order; q of an inactive lane is
// p2g_particle_zero, its base replaced by its gblock's first node) into `grid`: segmented warp
// reduction (Gao et al. 2018), then global atomics by segment heads. Every lane of the warp
// calls it.
__device__ __forceinline__ void p2g_scatter_warp(const Ctx& c, unsigned g, const P2gParticle& q, bool active, unsigned lane,
                                                 real* grid) {
    const int* base = q.base;
    WarpSegments seg = warp_segments(c, base, active, lane);
    unsigned seg_len = seg.seg_len, max_seg = seg.max_seg;
#if RTMPM_P2G_SEG_CLAMP
    seg_len += lane;  // the segment's last lane: the rounds' shuffle clamp
#endif
    bool head = seg.head;
    // A lane that does not scatter addresses its gblock's own nodes (stencil.cuh: scatter_base).
    int at[3];
    scatter_base(c.block_coords + 3 * g, base, active, at);
    ScatterNodes nodes = scatter_nodes(c, g, at);
#if RTMPM_P2G_REDUCE == 4
    // Rounds s = 1, 2, 4, ... up to the longest segment, at most RTMPM_P2G_ROUNDS_MAX.
    int rounds = min(max_seg ? 32 - __clz(max_seg) : 0, RTMPM_P2G_ROUNDS_MAX);
    switch (rounds) {
        case 0: p2g_scatter_rows<0>(nodes, q, seg_len, max_seg, head, grid); break;
        case 1: p2g_scatter_rows<1>(nodes, q, seg_len, max_seg, head, grid); break;
        case 2: p2g_scatter_rows<2>(nodes, q, seg_len, max_seg, head, grid); break;
#if RTMPM_P2G_ROUNDS_MAX > 2
        case 3: p2g_scatter_rows<3>(nodes, q, seg_len, max_seg, head, grid); break;
#endif
#if RTMPM_P2G_ROUNDS_MAX > 3
        case 4: p2g_scatter_rows<4>(nodes, q, seg_len, max_seg, head, grid); break;
#endif
        default: p2g_scatter_rows<RTMPM_P2G_ROUNDS_MAX>(nodes, q, seg_len, max_seg, head, grid); break;
    }
#else
#if RTMPM_P2G_ROUNDS_MAX < 5
    max_seg = min(max_seg, (1u << RTMPM_P2G_ROUNDS_MAX) - 1u);
#endif
    p2g_scatter_rows<-1>(nodes, q, seg_len, max_seg, head, grid);
#endif
}

// One entry of the warp list into c.grid: the `count` (at most 32) particles of gblock g from
// slot `first`, sorted in the warp by stencil key (c.warp_sort), summed by segments and scattered.
// Every lane of the warp calls it (the sort and the sums shuffle). The P2G kernel `p2g`
// (scatter.cu) and the batch's redo of some worlds' P2G (`redo_p2g`, kernels/redo.cu).
__device__ __forceinline__ void p2g_warp_entry(const Ctx& c, unsigned g, unsigned first, unsigned count,
                                               unsigned lane) {
    bool active = lane < count;
    unsigned src = lane;
    if (c.warp_sort) {
        unsigned key = P2G_KEY_NONE;
        if (active) {
            int base[3]; real fx[3];
            stencil_of(c, load_v3(c.state, c.cap, F_X, first + lane), particle_world(c, first + lane), base, fx);
            key = p2g_sort_key(c, g, base);
        }
        src = p2g_warp_sort(key, lane, &active);
    }
    P2gParticle q = p2g_particle_zero();
    if (active) q = p2g_particle(c, first + src);
    p2g_scatter_warp(c, g, q, active, lane, c.grid);
}

// The warp scatter of Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022), shared by the P2G kernel (p2g.cu) and the fused G2P2G
// (g2p2g.cu): the cheap in-warp cell sort of mixed sorting, the segmented warp reduction of lanes
// that write the same nodes (Gao et al. 2018) and direct global atomics by segment heads.
#pragma once
#include "particle.cuh"

// The shuffle rounds of the segmented reduction (compile-time, off by default): 0 a loop up to the
// warp's longest segment; 1 the five possible rounds unrolled, each skipped past that length. Same
// arithmetic in the same order; unrolled, ptxas keeps the 12 values of a row in place instead of
// copying them back for the next trip (12 moves a round). Measured on the H100 (bench/RESULTS.md,
// "The fused kernel's warp reduction"): 1 is 5-8 % faster on the claymore scenes. Off until the
// whole GPU validation has run with it (RTMPM_KERNEL_DEFINES=-DRTMPM_P2G_REDUCE=1).
#ifndef RTMPM_P2G_REDUCE
#define RTMPM_P2G_REDUCE 0
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

// The scatter of one warp's particles (one per lane, in sorted order; q of an inactive lane is
// p2g_particle_zero) into `grid`: segmented warp reduction (Gao et al. 2018), then global
// atomics by segment heads. Every lane of the warp calls it.
__device__ __forceinline__ void p2g_scatter_warp(const Ctx& c, unsigned g, const P2gParticle& q, bool active, unsigned lane,
                                                 real* grid) {
    const int* base = q.base;
    // Segments: lanes with equal stencil base (after the sort they are adjacent).
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
    }
    // Reduction rounds needed: up to the longest segment of this warp.
    unsigned max_seg = c.warp_reduce ? __reduce_max_sync(0xffffffffu, seg_len) : 0u;
    // The 27 nodes row by row: row (i, j) holds nodes k = 0, 1, 2, whose 12 values are reduced
    // together (one shuffle round serves three nodes). Addresses as in stencil_idx, per row:
    // r = base - 4 bc is the node offset from the gblock origin, r >> 2 its neighbour block.
    const int* bc = c.block_coords + 3 * g;
    int r0 = base[0] - 4 * bc[0], r1 = base[1] - 4 * bc[1], r2 = base[2] - 4 * bc[2];
    const unsigned* nbs = c.neighbors + 27 * g;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            int ri = r0 + i, rj = r1 + j;
            int slot_ij = ((ri >> 2) + 1) * 9 + ((rj >> 2) + 1) * 3 + 1;
            unsigned cell_ij = (unsigned)(((ri & 3) << 4) | ((rj & 3) << 2));
            real w_ij = p2g_row_weight(q, i, j);
            vec3 mom_ij = p2g_row_momentum(q, i, j);
            real val[3][4];
#pragma unroll
            for (int k = 0; k < 3; ++k) p2g_row_node_value(q, w_ij, mom_ij, k, val[k]);
#if RTMPM_P2G_REDUCE == 1
#pragma unroll
            for (unsigned s = 1; s < 32; s <<= 1) {
                if (s > max_seg) break;
#else
            for (unsigned s = 1; s <= max_seg; s <<= 1) {
#endif
                bool take = s <= seg_len;
#pragma unroll
                for (int k = 0; k < 3; ++k)
#pragma unroll
                    for (int e = 0; e < 4; ++e) {
                        real o = __shfl_down_sync(0xffffffffu, val[k][e], s);
                        if (take) val[k][e] += o;
                    }
            }
            if (head) {
#pragma unroll
                for (int k = 0; k < 3; ++k) {
                    int rk = r2 + k;
                    unsigned node = nbs[slot_ij + (rk >> 2)] * 64u + (cell_ij | (unsigned)(rk & 3));
                    atomic_add_node(grid + 4u * node, val[k]);
                }
            }
        }
}

// The warp scatter of Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022), shared by the P2G kernel (p2g.cu) and the fused G2P2G
// (g2p2g.cu): the cheap in-warp cell sort of mixed sorting, the segmented warp reduction of lanes
// that write the same nodes (Gao et al. 2018) and direct global atomics by segment heads.
#pragma once
#include "particle.cuh"

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

// How a warp sums the lanes of a segment before its atomics (compile-time, RTMPM_P2G_REDUCE):
// 0: shuffles, the 27 nodes row by row (12 values per round; rounds up to the warp's longest
// segment, a loop); 1: the same with the rounds unrolled; 2 (f32): through a per-warp
// shared-memory tile, one slab of 9 nodes at a time (p2g_scatter_warp_tile); 3 (f32): the same
// tile in groups of 8 nodes (p2g_scatter_warp_tile8). The warp_reduce=off ablation always takes
// the shuffle path (with one-lane segments: an atomic per lane).
#ifndef RTMPM_P2G_REDUCE
#define RTMPM_P2G_REDUCE 0
#endif
#if RTMPM_P2G_REDUCE >= 2 && defined(RTMPM_F64)
#undef RTMPM_P2G_REDUCE
#define RTMPM_P2G_REDUCE 1
#endif

// Segments of the warp: lanes with equal stencil base (after the sort they are adjacent).
// `end`: one past this lane's segment; `head`: an active lane that starts one.
struct WarpSegments {
    unsigned end;
    bool head;
};
__device__ __forceinline__ WarpSegments p2g_segments(const int base[3], bool active, unsigned lane) {
    int pb0 = __shfl_up_sync(0xffffffffu, base[0], 1);
    int pb1 = __shfl_up_sync(0xffffffffu, base[1], 1);
    int pb2 = __shfl_up_sync(0xffffffffu, base[2], 1);
    unsigned pact = __shfl_up_sync(0xffffffffu, (unsigned)active, 1);
    bool boundary = lane == 0 || !pact || !active || pb0 != base[0] || pb1 != base[1] || pb2 != base[2];
    unsigned mark = __ballot_sync(0xffffffffu, boundary);
    unsigned rest = lane < 31 ? (mark & ~((2u << lane) - 1u)) : 0u;
    WarpSegments s;
    s.end = rest ? (unsigned)(__ffs(rest) - 1) : 32u;
    s.head = boundary && active;
    return s;
}

#if RTMPM_P2G_REDUCE >= 2
// The per-warp shared memory of p2g_scatter_warp_tile: the 9 node values of one slab of every
// lane (node-major, a row of 33 lanes so that lanes reading different nodes of one segment fall
// in different banks) and the segment table.
#define P2G_TILE_ROW 33
#define P2G_WARPS_PER_BLOCK 4
struct P2gWarpTile {
    float4 v[9 * P2G_TILE_ROW];
    unsigned seg[32];
};

// Sum the segments through shared memory instead of shuffles: each lane stores its 9 node values
// of slab i (base + (i, j, k)); then lane t of the warp takes the pair (segment t / 9, node t % 9),
// sums that node's values over the segment's lanes from the tile and issues the atomic. The
// segment table (head lane, length, base relative to the gblock) is written once per warp.
// Per slab: 9 stores and, per 32 (segment, node) pairs, a loop of one 16-byte load per lane of
// the segment; against the shuffles' 3 x 12 values per round.
__device__ __forceinline__ void p2g_scatter_warp_tile(const Ctx& c, unsigned g, const P2gParticle& q, bool active,
                                                      unsigned lane, real* grid) {
    __shared__ P2gWarpTile tiles[P2G_WARPS_PER_BLOCK];
    P2gWarpTile& t = tiles[threadIdx.x >> 5];
    const int* base = q.base;
    WarpSegments sg = p2g_segments(base, active, lane);
    unsigned heads = __ballot_sync(0xffffffffu, sg.head);
    unsigned n_seg = __popc(heads);
    unsigned max_len = __reduce_max_sync(0xffffffffu, sg.head ? sg.end - lane : 0u);
    const int* bc = c.block_coords + 3 * g;
    // Relative base r = base - 4 bc lies in [-4, 5] (free zone): 4 bits each with +4.
    if (sg.head) {
        unsigned r0 = (unsigned)(base[0] - 4 * bc[0] + 4), r1 = (unsigned)(base[1] - 4 * bc[1] + 4),
                 r2 = (unsigned)(base[2] - 4 * bc[2] + 4);
        t.seg[__popc(heads & ((1u << lane) - 1u))] = lane | ((sg.end - lane) << 5) | (r0 << 11) | (r1 << 15) | (r2 << 19);
    }
    // The gblock's 27 neighbour pblocks, one per lane (read by shuffle per pair).
    unsigned nb = lane < 27 ? c.neighbors[27 * g + lane] : 0u;
    unsigned n_pairs = n_seg * 9u;
    for (int i = 0; i < 3; ++i) {
        __syncwarp();
#pragma unroll
        for (int j = 0; j < 3; ++j) {
            real w_ij = p2g_row_weight(q, i, j);
            vec3 mom_ij = p2g_row_momentum(q, i, j);
#pragma unroll
            for (int k = 0; k < 3; ++k) {
                real val[4];
                p2g_row_node_value(q, w_ij, mom_ij, k, val);
                t.v[(j * 3 + k) * P2G_TILE_ROW + lane] = make_float4(val[0], val[1], val[2], val[3]);
            }
        }
        __syncwarp();
        for (unsigned t0 = 0; t0 < n_pairs; t0 += 32) {
            unsigned pair = t0 + lane;
            bool on = pair < n_pairs;
            unsigned s = on ? pair / 9u : 0u, n = on ? pair - 9u * s : 0u;
            unsigned d = t.seg[s];
            unsigned start = d & 31u, len = on ? (d >> 5) & 63u : 0u;
            unsigned j = n / 3u, k = n - 3u * j;
            int ri = (int)((d >> 11) & 15u) - 4 + i, rj = (int)((d >> 15) & 15u) - 4 + (int)j,
                rk = (int)((d >> 19) & 15u) - 4 + (int)k;
            int slot = ((ri >> 2) + 1) * 9 + ((rj >> 2) + 1) * 3 + ((rk >> 2) + 1);
            unsigned pb = __shfl_sync(0xffffffffu, nb, (unsigned)slot & 31u);
            const float4* src = t.v + n * P2G_TILE_ROW + start;
            float4 acc = make_float4(0.f, 0.f, 0.f, 0.f);
            for (unsigned u = 0; u < max_len; ++u) {
                if (u < len) {
                    float4 o = src[u];
                    acc.x += o.x; acc.y += o.y; acc.z += o.z; acc.w += o.w;
                }
            }
            if (on) {
                unsigned node = pb * 64u + (unsigned)(((ri & 3) << 4) | ((rj & 3) << 2) | (rk & 3));
                real val[4] = {acc.x, acc.y, acc.z, acc.w};
                atomic_add_node(grid + 4u * node, val);
            }
        }
    }
    __syncwarp();
}

// The tile in groups of 8 nodes (node n = 9 i + 3 j + k; groups 0-7, 8-15, 16-23, 24-26): lane
// l takes segment 4 it + l / 8 and node l % 8 of the group, so a warp of up to 4 segments (32
// particles at 8 a cell) sums a group in one pass: 4 passes for the 27 nodes instead of 6.
__device__ __forceinline__ void p2g_scatter_warp_tile8(const Ctx& c, unsigned g, const P2gParticle& q, bool active,
                                                       unsigned lane, real* grid) {
    __shared__ P2gWarpTile tiles[P2G_WARPS_PER_BLOCK];
    P2gWarpTile& t = tiles[threadIdx.x >> 5];
    const int* base = q.base;
    WarpSegments sg = p2g_segments(base, active, lane);
    unsigned heads = __ballot_sync(0xffffffffu, sg.head);
    unsigned n_seg = __popc(heads);
    unsigned max_len = __reduce_max_sync(0xffffffffu, sg.head ? sg.end - lane : 0u);
    const int* bc = c.block_coords + 3 * g;
    if (sg.head) {
        unsigned r0 = (unsigned)(base[0] - 4 * bc[0] + 4), r1 = (unsigned)(base[1] - 4 * bc[1] + 4),
                 r2 = (unsigned)(base[2] - 4 * bc[2] + 4);
        t.seg[__popc(heads & ((1u << lane) - 1u))] = lane | ((sg.end - lane) << 5) | (r0 << 11) | (r1 << 15) | (r2 << 19);
    }
    unsigned nb = lane < 27 ? c.neighbors[27 * g + lane] : 0u;
    __syncwarp();
    unsigned d0 = t.seg[lane >> 3];
    unsigned nn = lane & 7u;
#pragma unroll
    for (int gi = 0; gi < 4; ++gi) {
        __syncwarp();
#pragma unroll
        for (int m = 0; m < 8; ++m) {
            const int n = 8 * gi + m;
            if (n < 27) {
                real val[4];
                p2g_node_value(q, n / 9, (n / 3) % 3, n % 3, val);
                t.v[m * P2G_TILE_ROW + lane] = make_float4(val[0], val[1], val[2], val[3]);
            }
        }
        __syncwarp();
        unsigned n = 8u * gi + nn;
        unsigned ni = n / 9u, nj = (n / 3u) % 3u, nk = n % 3u;
        for (unsigned it = 0; 4u * it < n_seg; ++it) {
            unsigned s = 4u * it + (lane >> 3);
            bool on = s < n_seg && n < 27u;
            unsigned d = it == 0 ? d0 : t.seg[s & 31u];
            unsigned start = d & 31u, len = on ? (d >> 5) & 63u : 0u;
            int ri = (int)((d >> 11) & 15u) - 4 + (int)ni, rj = (int)((d >> 15) & 15u) - 4 + (int)nj,
                rk = (int)((d >> 19) & 15u) - 4 + (int)nk;
            int slot = ((ri >> 2) + 1) * 9 + ((rj >> 2) + 1) * 3 + ((rk >> 2) + 1);
            unsigned pb = __shfl_sync(0xffffffffu, nb, (unsigned)slot & 31u);
            const float4* src = t.v + nn * P2G_TILE_ROW + start;
            float4 acc = make_float4(0.f, 0.f, 0.f, 0.f);
            for (unsigned u = 0; u < max_len; ++u) {
                if (u < len) {
                    float4 o = src[u];
                    acc.x += o.x; acc.y += o.y; acc.z += o.z; acc.w += o.w;
                }
            }
            if (on) {
                unsigned node = pb * 64u + (unsigned)(((ri & 3) << 4) | ((rj & 3) << 2) | (rk & 3));
                real val[4] = {acc.x, acc.y, acc.z, acc.w};
                atomic_add_node(grid + 4u * node, val);
            }
        }
    }
    __syncwarp();
}
#endif

// The scatter of one warp's particles (one per lane, in sorted order; q of an inactive lane is
// p2g_particle_zero) into `grid`: segmented warp reduction (Gao et al. 2018), then global
// atomics by segment heads. Every lane of the warp calls it.
__device__ __forceinline__ void p2g_scatter_warp(const Ctx& c, unsigned g, const P2gParticle& q, bool active, unsigned lane,
                                                 real* grid) {
#if RTMPM_P2G_REDUCE == 2
    if (c.warp_reduce) {
        p2g_scatter_warp_tile(c, g, q, active, lane, grid);
        return;
    }
#elif RTMPM_P2G_REDUCE == 3
    if (c.warp_reduce) {
        p2g_scatter_warp_tile8(c, g, q, active, lane, grid);
        return;
    }
#endif
    const int* base = q.base;
    unsigned seg_len = 0;
    bool head = active;
    if (c.warp_reduce) {
        WarpSegments sg = p2g_segments(base, active, lane);
        seg_len = sg.end - lane - 1;
        head = sg.head;
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

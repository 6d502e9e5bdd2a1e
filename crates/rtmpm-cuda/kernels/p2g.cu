// P2G (MLS-MPM, Hu et al. 2018) with the Kirchhoff stress computed inline (merged kernel).
// One warp per warp-list entry, 4 warps per CUDA block, no shared memory, no __syncthreads.
// Mixed sorting (seed 000): the 32 particles of a warp are sorted by their current stencil key
// (bitonic sort via __shfl_xor_sync), then lanes writing the same nodes are reduced with
// segmented __shfl_down_sync sums (Gao et al. 2018) and only segment heads issue atomicAdd.
// The per-particle quantities (stencil, weights, stress, affine momentum) come from p2g_particle.cuh,
// shared with the gather strategies (p2g_reverse_map.cu, p2g_sort.cu).
#include "p2g_particle.cuh"

// Add (mass, momentum) to a node: one 16-byte vector atomic on sm_90 (f32), else four.
__device__ __forceinline__ void atomic_add_node(real* node, const real val[4]) {
#if !defined(RTMPM_F64) && defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 900
    atomicAdd(reinterpret_cast<float4*>(node), make_float4(val[0], val[1], val[2], val[3]));
#else
    for (int q = 0; q < 4; ++q) atomicAdd(node + q, val[q]);
#endif
}

// Memory index of node base + (i, j, k) for a particle of gblock g.
__device__ __forceinline__ unsigned node_index(const Ctx& c, unsigned g, const int base[3], int i, int j, int k) {
    const int* bc = c.block_coords + 3 * g;
    int n0 = base[0] + i, n1 = base[1] + j, n2 = base[2] + k;
    int s = nb_slot((n0 >> 2) - bc[0], (n1 >> 2) - bc[1], (n2 >> 2) - bc[2]);
    return c.neighbors[27 * g + s] * 64u + (unsigned)cell_code(n0, n1, n2);
}

#ifndef P2G_MIN_BLOCKS
#define P2G_MIN_BLOCKS 1
#endif

__device__ __forceinline__ void p2g_warp(const Ctx& c, unsigned w, unsigned lane);

// Multi-GPU split of P2G (reduce_shared.cu): part 0 = every warp; part 1 = warps of boundary
// gblocks (those next to a block shared with another GPU), run first so that the reduction of the
// shared blocks overlaps part 2 = the other warps, which never touch a shared block.
__device__ __forceinline__ bool in_part(const Ctx& c, unsigned g, unsigned part) {
    return part == 0 || ((c.boundary[g] != 0) == (part == 1));
}

// Warps loop over the warp list (grid-stride, launched with about one wave of blocks).
extern "C" __global__ void __launch_bounds__(128, P2G_MIN_BLOCKS) p2g(Ctx c, unsigned part) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride)
        if (in_part(c, c.warps[3 * w], part)) p2g_warp(c, w, threadIdx.x & 31);
}

__device__ __forceinline__ void p2g_warp(const Ctx& c, unsigned w, unsigned lane) {
    unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
    bool active = lane < count;
    unsigned src = lane;
    if (c.warp_sort) {
        // Cheap in-warp sort: key = (neighbour slot of the base block, cell code of the base).
        unsigned key = 0xffffu;
        if (active) {
            int base[3]; real fx[3];
            stencil_of(c, load_v3(c.state, c.cap, F_X, first + lane), base, fx);
            const int* bc = c.block_coords + 3 * g;
            key = (unsigned)(nb_slot((base[0] >> 2) - bc[0], (base[1] >> 2) - bc[1], (base[2] >> 2) - bc[2]) << 6)
                | (unsigned)cell_code(base[0], base[1], base[2]);
        }
        unsigned kv = (key << 5) | lane;  // unique keys; payload = source lane
        // Between rebuilds most warps are still in order: skip the sort when they are.
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
        src = kv & 31u;
        active = (kv >> 5) != 0xffffu;
    }
    unsigned p = first + src;
    P2gParticle q = p2g_particle_zero();
    if (active) q = p2g_particle(c, p);
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
            for (unsigned s = 1; s <= max_seg; s <<= 1) {
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
                    atomic_add_node(c.grid + 4u * node, val[k]);
                }
            }
        }
}

// Ablation: shared-memory P2G like earlier work. One CUDA block per gblock (looping over its
// particles); nodes are accumulated into a shared 12x12x12 tile covering the gblock's 3x3x3
// neighbourhood with shared atomics, then written out after __syncthreads.
#define TILE 12
extern "C" __global__ void p2g_shared(Ctx c, unsigned part) {
    __shared__ float tile[TILE * TILE * TILE * 4];
    if (c.ctl[CTL_ERROR]) return;
    unsigned g = blockIdx.x;
    if (g >= c.ctl[CTL_GBLOCKS] || g >= c.gblock_cap) return;  // uniform per block
    if (!in_part(c, g, part)) return;
    for (unsigned t = threadIdx.x; t < TILE * TILE * TILE * 4; t += blockDim.x) tile[t] = 0;
    __syncthreads();
    const int* bc = c.block_coords + 3 * g;
    int lo[3] = {4 * bc[0] - 4, 4 * bc[1] - 4, 4 * bc[2] - 4};
    // Particles of gblock g are contiguous (sorted): find them from the warp list is not needed;
    // the bucket offsets give the range.
    unsigned start = c.hist[g * 64u];
    unsigned end = (g + 1 < c.ctl[CTL_GBLOCKS]) ? c.hist[(g + 1) * 64u] : c.n;
    for (unsigned p = start + threadIdx.x; p < end; p += blockDim.x) {
        P2gParticle q = p2g_particle(c, p);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k) {
                    real val[4];
                    p2g_node_value(q, i, j, k, val);
                    int t = ((q.base[0] + i - lo[0]) * TILE + (q.base[1] + j - lo[1])) * TILE + (q.base[2] + k - lo[2]);
                    for (int e = 0; e < 4; ++e) atomicAdd(&tile[4 * t + e], (float)val[e]);
                }
    }
    __syncthreads();
    for (unsigned t = threadIdx.x; t < TILE * TILE * TILE; t += blockDim.x) {
        if (tile[4 * t] == 0.0f) continue;
        int n[3] = {lo[0] + (int)(t / (TILE * TILE)), lo[1] + (int)(t / TILE % TILE), lo[2] + (int)(t % TILE)};
        int base[3] = {n[0], n[1], n[2]};
        real* node = c.grid + 4u * node_index(c, g, base, 0, 0, 0);
        for (int q = 0; q < 4; ++q) atomicAdd(node + q, (real)tile[4 * t + q]);
    }
}

// P2G of the classic MPM transfers (uGIMP, linear hats; cpu/p2g.rs: p2g_mpm): mass and momentum
// into the grid, dt f_i = -dt sum_p V0_p tau_p grad w_ip into grid_aux (kept apart for FLIP's
// v_old). One lane per particle of the warp list, direct atomics (no in-warp reduction).
extern "C" __global__ void p2g_mpm(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        int base[3]; real fx[3]; real wt[3][3]; real dw[3][3];
        particle_stencil(c, load_v3(c.state, c.cap, F_X, p), base, fx, wt, dw);
        real m = c.state[F_MASS * c.cap + p];
        real vol0 = c.state[F_VOL0 * c.cap + p];
        vec3 mv = load_v3(c.state, c.cap, F_V, p) * m;
        mat3 C = load_m3(c.state, c.cap, F_C, p);
        mat3 F = load_m3(c.state, c.cap, F_F, p);
        const GpuMaterial& mat = material_at(c, state_bits(c.state[F_MAT * c.cap + p]));
        mat3 tau = material_kirchhoff(mat, F, c.state[F_PLASTIC * c.cap + p], C);
        // grad w in world units is shape_grad / dx.
        mat3 stress = tau * (-(real)step_params(c).dt * vol0 * c.inv_dx);
        StencilIdx si = stencil_idx(c.block_coords + 3 * g, base);
        const unsigned* nbs = c.neighbors + 27 * g;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k) {
                    real weight = wt[0][i] * wt[1][j] * wt[2][k];
                    vec3 f = stress * shape_grad(wt, dw, i, j, k);
                    real val[4] = {weight * m, weight * mv.x, weight * mv.y, weight * mv.z};
                    real aux[4] = {0, f.x, f.y, f.z};
                    unsigned node = nbs[si.slot[0][i] + si.slot[1][j] + si.slot[2][k]] * 64u
                        + (si.cell[0][i] | si.cell[1][j] | si.cell[2][k]);
                    atomic_add_node(c.grid + 4u * node, val);
                    atomic_add_node(c.grid_aux + 4u * node, aux);
                }
    }
}

// MUSL re-map (Sulsky et al. 1995; cpu/p2g.rs: p2g_musl): the updated particle momenta
// sum_p w_ip m_p v_p into grid_aux (cleared before), weights at the start-of-step positions.
extern "C" __global__ void p2g_musl(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        int base[3]; real fx[3]; real wt[3][3]; real dw[3][3];
        particle_stencil(c, load_v3(c.state, c.cap, F_X, p), base, fx, wt, dw);
        vec3 mv = load_v3(c.state, c.cap, F_V, p) * (real)c.state[F_MASS * c.cap + p];
        StencilIdx si = stencil_idx(c.block_coords + 3 * g, base);
        const unsigned* nbs = c.neighbors + 27 * g;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k) {
                    real weight = wt[0][i] * wt[1][j] * wt[2][k];
                    real aux[4] = {0, weight * mv.x, weight * mv.y, weight * mv.z};
                    unsigned node = nbs[si.slot[0][i] + si.slot[1][j] + si.slot[2][k]] * 64u
                        + (si.cell[0][i] | si.cell[1][j] | si.cell[2][k]);
                    atomic_add_node(c.grid_aux + 4u * node, aux);
                }
    }
}

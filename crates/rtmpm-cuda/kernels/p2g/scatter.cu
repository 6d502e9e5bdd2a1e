// P2G (MLS-MPM, Hu et al. 2018) with the Kirchhoff stress computed inline (merged kernel).
// One warp per warp-list entry, 4 warps per CUDA block, no shared memory, no __syncthreads.
// Mixed sorting (Fei, Huang & Gao, "Real-Time Simulation of MPM on Modern GPUs" (GTC 2022)): the 32 particles of a warp are sorted by their current stencil key
// (bitonic sort via __shfl_xor_sync), then lanes writing the same nodes are reduced with
// segmented __shfl_down_sync sums (Gao et al. 2018) and only segment heads issue atomicAdd.
// The per-particle quantities (stencil, weights, stress, affine momentum) come from p2g_particle.cuh,
// shared with the gather strategies (p2g_reverse_map.cu, p2g_sort.cu); the sort, the reduction and
// the atomics from p2g_warp.cuh, shared with the fused G2P2G (g2p2g.cu).
#include "warp.cuh"

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

// Multi-GPU split of P2G (reduce_shared.cu): part 0 = every warp; part 1 = warps of boundary
// gblocks (those next to a block shared with another GPU), run first so that the reduction of the
// shared blocks overlaps part 2 = the other warps, which never touch a shared block.
__device__ __forceinline__ bool in_part(const Ctx& c, unsigned g, unsigned part) {
    return part == 0 || ((c.boundary[g] != 0) == (part == 1));
}

// Warps loop over the warp list (grid-stride, launched with about one wave of blocks). With
// G2P2G (g2p2g.cu) the previous step's fused kernel has already scattered the particles, and this
// kernel only runs after a rebuild or when the host asks (grid_needs_p2g).
extern "C" __global__ void __launch_bounds__(128, P2G_MIN_BLOCKS) p2g(Ctx c, unsigned part) {
    step_kernel_entry();
    if (c.ctl[CTL_ERROR] || !grid_needs_p2g(c)) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (!in_part(c, g, part)) continue;
        p2g_warp_entry(c, g, first, count, lane);
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
    step_kernel_entry();
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        int base[3]; real fx[3]; real wt[3][3]; real dw[3][3];
        particle_stencil(c, load_v3(c.state, c.cap, F_X, p), particle_world(c, p), base, fx, wt, dw);
        real m = c.state[sidx(c.cap, F_MASS, p)];
        real vol0 = c.state[sidx(c.cap, F_VOL0, p)];
        vec3 mv = load_vel(c.state, c.cap, p) * m;
        mat3 C = load_affine(c.state, c.cap, p);
        mat3 F = load_deformation(c.state, c.cap, p, false);
        const MaterialGpu& mat = material_at(c, state_bits(c.state[sidx(c.cap, F_MAT, p)]));
        mat3 tau = material_kirchhoff(mat, F, load_plastic(c.state, c.cap, p), C);
        // grad w in world units is shape_grad / dx.
        mat3 stress = tau * (-step_params(c).dt * vol0 * scalars(c).inv_dx);
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
        particle_stencil(c, load_v3(c.state, c.cap, F_X, p), particle_world(c, p), base, fx, wt, dw);
        vec3 mv = load_vel(c.state, c.cap, p) * (real)c.state[sidx(c.cap, F_MASS, p)];
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

// P2G of CK-MPM (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material Point Method", ACM TOG 2025;
// cpu/p2g.rs: p2g_ck), the formulas in ck_scatter.cuh: each of the two staggered grids receives
// the particle's mass and MLS-MPM momentum through its 2x2x2 compact-kernel stencil. Two kernels
// of the same sums (CudaOptions::ck_p2g): `p2g_ck`, one lane per particle with direct atomics
// (16 a particle), and `p2g_ck_warp`, the warp scatter of ck_scatter.cuh (in-warp sort per grid,
// segmented shuffles, one lane's atomics per segment).
#include "ck_scatter.cuh"

extern "C" __global__ void p2g_ck(Ctx c) {
    step_kernel_entry();
    if (c.ctl[CTL_ERROR] || !grid_needs_p2g(c)) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        int base[3]; real fx[3];
        stencil_of(c, load_v3(c.state, c.cap, F_X, p), particle_world(c, p), base, fx);
        CkGrid s[2] = {ck_grid(fx, 0), ck_grid(fx, 1)};
        CkP2gTerms t = ck_p2g_terms(c, p, s);
        StencilIdx si = stencil_idx(c.block_coords + 3 * g, base);
        const unsigned* nbs = c.neighbors + 27 * g;
        for (int q = 0; q < 2; ++q) {
            const CkGrid& sq = s[q];
            real* grid = ck_nodes(c, q);
            for (int i = 0; i < 2; ++i)
                for (int j = 0; j < 2; ++j)
                    for (int k = 0; k < 2; ++k) {
                        real weight = ck_weight(sq, i, j, k);
                        vec3 mom = (t.mv + t.affine_dx * ck_dpos(sq, i, j, k)) * weight;
                        real val[4] = {weight * t.m, mom.x, mom.y, mom.z};
                        int a = sq.offset[0] + i, b = sq.offset[1] + j, e = sq.offset[2] + k;
                        atomic_add_node(grid + 4u * stencil_node(si, nbs, a, b, e), val);
                    }
        }
    }
}

// Warps loop over the warp list (grid-stride, launched with about one wave of blocks); both
// grids' contributions of a particle are computed once, then each grid's are sorted and scattered.
// With G2P2G (ck_p2g=fused; g2p/ck.cu: g2p2g_ck) the previous step's fused kernel has already
// scattered the particles, and this kernel only runs after a rebuild or when the host asks
// (grid_needs_p2g: always without G2P2G).
extern "C" __global__ void __launch_bounds__(CK_BOUNDS) p2g_ck_warp(Ctx c) {
    step_kernel_entry();
    if (c.ctl[CTL_ERROR] || !grid_needs_p2g(c)) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        bool active = lane < count;
        CkScatter q[2] = {ck_scatter_zero(), ck_scatter_zero()};
        if (active) {
            unsigned p = first + lane;
            int base[3]; real fx[3];
            stencil_of(c, load_v3(c.state, c.cap, F_X, p), particle_world(c, p), base, fx);
            CkGrid s[2] = {ck_grid(fx, 0), ck_grid(fx, 1)};
            CkP2gTerms t = ck_p2g_terms(c, p, s);
            q[0] = ck_scatter_of(base, s[0], t);
            q[1] = ck_scatter_of(base, s[1], t);
        }
        ck_scatter_sorted(c, g, q[0], active, lane, ck_nodes(c, 0));
        ck_scatter_sorted(c, g, q[1], active, lane, ck_nodes(c, 1));
    }
}

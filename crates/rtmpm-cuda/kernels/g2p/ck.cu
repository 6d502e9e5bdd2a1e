// G2P of CK-MPM (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material Point Method", ACM TOG 2025;
// cpu/g2p.rs: g2p_ck): the mean of the two staggered grids' interpolations
// v_p = 1/2 sum_g sum_i w_ip v_i and APIC's least-squares affine matrix over both,
// C_p = (1/2 sum_g sum_i w_ip v_i (x_i - x_p)^T) D_p^-1 (ck.cuh), then F, plasticity, advection
// and the checks of every G2P (g2p_finish). Two kernels: `g2p_ck`, and `g2p2g_ck`, the G2P2G of
// CK-MPM (ck_p2g=fused; the MLS-MPM one is g2p2g.cu, whose caveats hold here too).
#include "particle.cuh"
#include "../ck.cuh"
#include "../p2g/ck_scatter.cuh"  // stencil_node, the warp scatter of g2p2g_ck

// Velocity of node `node` of a grid of 4 reals per node.
__device__ __forceinline__ vec3 ck_node_velocity(const real* grid, unsigned node) {
    const real* n = grid + 4u * node;
    return make_v3(n[1], n[2], n[3]);
}

// CK-MPM G2P of particle p of gblock g from the grids c.grid and c.grid_aux: the gather of v
// and C, then g2p_finish. The new state is stored and returned.
__device__ __forceinline__ G2pResult g2p_ck_particle(const Ctx& c, unsigned g, unsigned p) {
    vec3 x = load_v3(c.state, c.cap, F_X, p);
    G2pState st = g2p_load_state<false>(c, p);
    int base[3]; real fx[3];
    stencil_of(c, x, material_world(st.material), base, fx);
    CkGrid s[2] = {ck_grid(fx, 0), ck_grid(fx, 1)};
    const int* bc = c.block_coords + 3 * g;
    const unsigned* nbs = c.neighbors + 27 * g;
    // Sums over both grids; B in cells (x_i - x_p = dx dpos). Each grid's nodes are addressed from
    // its first node (compile-time indices into the addressing, which stays in registers).
    vec3 sum_v = make_v3(0, 0, 0);
    mat3 sum_b = mat3_zero();
#pragma unroll
    for (int q = 0; q < 2; ++q) {
        const CkGrid& sq = s[q];
        const real* grid = q == 0 ? c.grid : c.grid_aux;
        int first[3] = {base[0] + sq.offset[0], base[1] + sq.offset[1], base[2] + sq.offset[2]};
        StencilIdx si = stencil_idx(bc, first);
#pragma unroll
        for (int i = 0; i < 2; ++i)
#pragma unroll
            for (int j = 0; j < 2; ++j)
#pragma unroll
                for (int k = 0; k < 2; ++k) {
                    vec3 wv = ck_node_velocity(grid, stencil_node(si, nbs, i, j, k)) * ck_weight(sq, i, j, k);
                    sum_v = sum_v + wv;
                    sum_b = sum_b + outer(wv, ck_dpos(sq, i, j, k));
                }
    }
    vec3 v = sum_v * (real)0.5;
    // C = (1/2 B dx) (D dx^2)^-1 with B, D in cells.
    mat3 C = sum_b * ck_inv_moment(s) * ((real)0.5 * scalars(c).inv_dx);
    return g2p_finish<false>(c, bc, p, st, x + v * step_params(c).dt, v, C);
}

extern "C" __global__ void g2p_ck(Ctx c) {
    step_kernel_entry();
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane < count) speed = max(speed, g2p_ck_particle(c, g, first + lane).speed);
    }
    report_max_speed(c, speed);
}

// G2P2G of CK-MPM: the G2P of step n from both grids (c.grid, c.grid_aux) and, while the new
// state is still in registers, the P2G of step n+1 into both of the next step's grids
// (c.grid_next, c.grid_aux_next; cleared by this step's grid update) with the warp scatter of
// p2g_ck_warp. A particle that left its free zone is not scattered (it has set the rebuild flag;
// the next step rebuilds and redoes the P2G from the stored state). Warps loop over the warp list
// (grid-stride, launched with about one wave of blocks, or with ck_grid=resident the blocks resident
// at once). Register bound: CK_FUSED_BOUNDS (ck.cuh, the CUDA option ck_bound=N; 5 blocks in f32 by
// default).
extern "C" __global__ void __launch_bounds__(CK_FUSED_BOUNDS) g2p2g_ck(Ctx c) {
    step_kernel_entry();
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        bool scatter = false;
        CkScatter q[2] = {ck_scatter_zero(), ck_scatter_zero()};
        if (lane < count) {
            unsigned p = first + lane;
            real m = state_ld(c.state, sidx(c.cap, F_MASS, p)), vol0 = state_ld(c.state, sidx(c.cap, F_VOL0, p));
            G2pResult r = g2p_ck_particle(c, g, p);
            speed = max(speed, r.speed);
            if (!r.leave) {
                int base[3]; real fx[3];
                stencil_of(c, r.x, material_world(r.material), base, fx);
                CkGrid s[2] = {ck_grid(fx, 0), ck_grid(fx, 1)};
                CkP2gTerms t = ck_p2g_terms_of(c, s, m, vol0, r.v, r.C, r.F, r.plastic, r.material);
                q[0] = ck_scatter_of(base, s[0], t);
                q[1] = ck_scatter_of(base, s[1], t);
                scatter = true;
            }
        }
        ck_scatter_sorted(c, g, q[0], scatter, lane, c.grid_next);
        ck_scatter_sorted(c, g, q[1], scatter, lane, c.grid_aux_next);
    }
    report_max_speed(c, speed);
}

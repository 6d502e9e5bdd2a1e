// G2P of CK-MPM (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material Point Method", ACM TOG 2025;
// cpu/g2p.rs: g2p_ck): the mean of the two staggered grids' interpolations
// v_p = 1/2 sum_g sum_i w_ip v_i and APIC's least-squares affine matrix over both,
// C_p = (1/2 sum_g sum_i w_ip v_i (x_i - x_p)^T) D_p^-1 (ck.cuh), then F, plasticity, advection
// and the checks of every G2P (g2p_finish).
#include "particle.cuh"
#include "../ck.cuh"
#include "../p2g/particle.cuh"  // stencil_node

// Velocity of node `node` of a grid of 4 reals per node.
__device__ __forceinline__ vec3 ck_node_velocity(const real* grid, unsigned node) {
    const real* n = grid + 4u * node;
    return make_v3(n[1], n[2], n[3]);
}

extern "C" __global__ void g2p_ck(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        vec3 x = load_v3(c.state, c.cap, F_X, p);
        G2pState st = g2p_load_state<false>(c, p);
        int base[3]; real fx[3];
        stencil_of(c, x, material_world(st.material), base, fx);
        CkGrid s[2] = {ck_grid(fx, 0), ck_grid(fx, 1)};
        const int* bc = c.block_coords + 3 * g;
        StencilIdx si = stencil_idx(bc, base);
        const unsigned* nbs = c.neighbors + 27 * g;
        // Sums over both grids; B in cells (x_i - x_p = dx dpos).
        vec3 sum_v = make_v3(0, 0, 0);
        mat3 sum_b = mat3_zero();
        for (int q = 0; q < 2; ++q) {
            const CkGrid& sq = s[q];
            const real* grid = q == 0 ? c.grid : c.grid_aux;
            for (int i = 0; i < 2; ++i)
                for (int j = 0; j < 2; ++j)
                    for (int k = 0; k < 2; ++k) {
                        int a = sq.offset[0] + i, b = sq.offset[1] + j, e = sq.offset[2] + k;
                        vec3 wv = ck_node_velocity(grid, stencil_node(si, nbs, a, b, e)) * ck_weight(sq, i, j, k);
                        sum_v = sum_v + wv;
                        sum_b = sum_b + outer(wv, ck_dpos(sq, i, j, k));
                    }
        }
        vec3 v = sum_v * (real)0.5;
        // C = (1/2 B dx) (D dx^2)^-1 with B, D in cells.
        mat3 C = sum_b * ck_inv_moment(s) * ((real)0.5 * scalars(c).inv_dx);
        speed = max(speed, g2p_finish<false>(c, bc, p, st, x + v * step_params(c).dt, v, C).speed);
    }
    report_max_speed(c, speed);
}

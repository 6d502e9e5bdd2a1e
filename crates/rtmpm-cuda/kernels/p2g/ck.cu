// P2G of CK-MPM (Liu, Wang & Li, "CK-MPM: A Compact-Kernel Material Point Method", ACM TOG 2025;
// cpu/p2g.rs: p2g_ck): each of the two staggered grids (grid 0 in c.grid, grid 1 in c.grid_aux)
// receives the particle's full mass w_ip m_p and MLS-MPM momentum w_ip (m_p v_p + A_p (x_i - x_p))
// through its 2x2x2 compact-kernel stencil, A_p = m_p C_p - dt V0_p tau_p D_p^-1 with the
// particle's own D_p (ck.cuh). One lane per particle of the warp list, direct atomics.
#include "warp.cuh"
#include "../ck.cuh"

// The grid of node values of CK-MPM grid g.
__device__ __forceinline__ real* ck_nodes(const Ctx& c, int g) { return g == 0 ? c.grid : c.grid_aux; }

extern "C" __global__ void p2g_ck(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        int base[3]; real fx[3];
        stencil_of(c, load_v3(c.state, c.cap, F_X, p), particle_world(c, p), base, fx);
        CkGrid s[2] = {ck_grid(fx, 0), ck_grid(fx, 1)};
        real m = c.state[sidx(c.cap, F_MASS, p)];
        real vol0 = c.state[sidx(c.cap, F_VOL0, p)];
        vec3 mv = load_vel(c.state, c.cap, p) * m;
        mat3 C = load_affine(c.state, c.cap, p);
        mat3 F = load_deformation(c.state, c.cap, p, false);
        const MaterialGpu& mat = material_at(c, state_bits(c.state[sidx(c.cap, F_MAT, p)]));
        mat3 tau = material_kirchhoff(mat, F, load_plastic(c.state, c.cap, p), C);
        // A_p = m C - dt V0 tau D_p^-1 (D_p^-1 in world units: cells^-2 / dx^2), applied to
        // x_i - x_p = dx dpos.
        const Scalars& sc = scalars(c);
        mat3 inv_d = ck_inv_moment(s) * (sc.inv_dx * sc.inv_dx);
        mat3 affine_dx = (tau * inv_d * (-step_params(c).dt * vol0) + C * m) * sc.dx;
        StencilIdx si = stencil_idx(c.block_coords + 3 * g, base);
        const unsigned* nbs = c.neighbors + 27 * g;
        for (int q = 0; q < 2; ++q) {
            const CkGrid& sq = s[q];
            real* grid = ck_nodes(c, q);
            for (int i = 0; i < 2; ++i)
                for (int j = 0; j < 2; ++j)
                    for (int k = 0; k < 2; ++k) {
                        real weight = ck_weight(sq, i, j, k);
                        vec3 mom = (mv + affine_dx * ck_dpos(sq, i, j, k)) * weight;
                        real val[4] = {weight * m, mom.x, mom.y, mom.z};
                        int a = sq.offset[0] + i, b = sq.offset[1] + j, e = sq.offset[2] + k;
                        atomic_add_node(grid + 4u * stencil_node(si, nbs, a, b, e), val);
                    }
        }
    }
}

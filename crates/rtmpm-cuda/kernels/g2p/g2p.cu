// G2P kernels (merged): the MLS-MPM G2P and those of the classic MPM transfers. The per-particle
// work is in g2p_particle.cuh (shared with the fused G2P2G of g2p2g.cu).
#include "particle.cuh"

#ifndef G2P_MIN_BLOCKS
#define G2P_MIN_BLOCKS 1
#endif

// Warps loop over the warp list (grid-stride, launched with about one wave of blocks).
extern "C" __global__ void __launch_bounds__(128, G2P_MIN_BLOCKS) g2p(Ctx c) {
    step_kernel_entry();
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane < count) speed = max(speed, g2p_particle<false>(c, g, first + lane).speed);
    }
    report_max_speed(c, speed);
}

// Interpolation of the classic MPM transfers at one particle (cpu/g2p.rs: g2p_mpm): v_pic =
// sum w v_i, the FLIP increment dv = sum w (v_i - v_old_i) (USL: grid_aux = v_old) and the
// velocity gradient L = sum v_i (x) grad w (MUSL: of the re-mapped velocities in grid_aux).
__device__ __forceinline__ void g2p_mpm_gather(const Ctx& c, unsigned g, vec3 x, unsigned world, const int** bc_out,
                                               vec3* v_pic, vec3* dv, mat3* L, bool musl_gradient) {
    int base[3]; real fx[3]; real wt[3][3]; real dw[3][3];
    particle_stencil(c, x, world, base, fx, wt, dw);
    const int* bc = c.block_coords + 3 * g;
    *bc_out = bc;
    const unsigned* nbs = c.neighbors + 27 * g;
    StencilIdx si = stencil_idx(bc, base);
    *v_pic = make_v3(0, 0, 0);
    *dv = make_v3(0, 0, 0);
    *L = mat3_zero();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k) {
                unsigned node = nbs[si.slot[0][i] + si.slot[1][j] + si.slot[2][k]] * 64u
                    + (si.cell[0][i] | si.cell[1][j] | si.cell[2][k]);
                const real* n = c.grid + 4u * node;
                const real* a = c.grid_aux + 4u * node;
                vec3 vi = make_v3(n[1], n[2], n[3]);
                vec3 ai = make_v3(a[1], a[2], a[3]);
                real weight = wt[0][i] * wt[1][j] * wt[2][k];
                vec3 grad = shape_grad(wt, dw, i, j, k) * scalars(c).inv_dx;
                *v_pic = *v_pic + vi * weight;
                if (musl_gradient) {
                    *L = *L + outer(ai, grad);
                } else {
                    *dv = *dv + (vi - ai) * weight;
                    *L = *L + outer(vi, grad);
                }
            }
}

// G2P of the classic MPM transfers: USL (PIC/FLIP blend here, L from the updated grid) or the
// final MUSL pass (v already blended by g2p_mpm_velocity, L from the re-mapped grid). Positions
// move with v_pic; L is kept in the particle's C.
extern "C" __global__ void g2p_mpm(Ctx c) {
    step_kernel_entry();
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    bool musl = c.update == UPDATE_MUSL;
    unsigned speed = 0;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        vec3 x = load_v3(c.state, c.cap, F_X, p);
        vec3 v = load_vel(c.state, c.cap, p);
        G2pState st = g2p_load_state<false>(c, p);
        const int* bc; vec3 v_pic, dv; mat3 L;
        g2p_mpm_gather(c, g, x, material_world(st.material), &bc, &v_pic, &dv, &L, musl);
        if (!musl) v = flip_blend(scalars(c).flip, v, v_pic, dv);
        speed = max(speed, g2p_finish<false>(c, bc, p, st, x + v_pic * step_params(c).dt, v, L).speed);
    }
    report_max_speed(c, speed);
}

// MUSL, first pass (cpu/g2p.rs: g2p_mpm_velocity): the PIC/FLIP blend of the particle velocities
// only; positions and F wait for the re-map.
extern "C" __global__ void g2p_mpm_velocity(Ctx c) {
    if (c.ctl[CTL_ERROR]) return;
    unsigned n_warps = c.ctl[CTL_WARPS], stride = (gridDim.x * blockDim.x) >> 5;
    unsigned lane = threadIdx.x & 31;
    for (unsigned w = thread_index() >> 5; w < n_warps; w += stride) {
        unsigned g = c.warps[3 * w], first = c.warps[3 * w + 1], count = c.warps[3 * w + 2];
        if (lane >= count) continue;
        unsigned p = first + lane;
        vec3 x = load_v3(c.state, c.cap, F_X, p);
        vec3 v = load_vel(c.state, c.cap, p);
        const int* bc; vec3 v_pic, dv; mat3 L;
        g2p_mpm_gather(c, g, x, particle_world(c, p), &bc, &v_pic, &dv, &L, false);
        store_vel(c.state, c.cap, p, flip_blend(scalars(c).flip, v, v_pic, dv));
    }
}
